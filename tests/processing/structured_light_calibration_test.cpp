// Projector-camera calibration on the real captures, against the reference tool's result for the
// same frames (calibration_result.xml; a reference, not exact truth: its stereo RMS is 0.86 px).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <unistd.h>

#include "core/errors.h"
#include "processing/structured_light/calibration.h"

namespace sl = sherd::structured_light;

namespace {
const std::filesystem::path kSample =
    std::filesystem::path(SHERD_SHARED_DATA) / "procam-graycode-calib/sample_data";

std::vector<std::filesystem::path> capture_dirs() {
  std::vector<std::filesystem::path> dirs;
  for (int i = 0; i < 5; ++i) dirs.push_back(kSample / ("capture_" + std::to_string(i)));
  return dirs;
}

// One calibration shared by the tests below (it decodes 5 × 42 real frames).
const sl::CalibrationReport& our_calibration() {
  static const sl::CalibrationReport report = sl::calibrate(capture_dirs(), {});
  return report;
}
}  // namespace

TEST(ProCamCalibration, ReadsTheReferenceFile) {
  const sl::ProCamCalibration ref = sl::read_calibration(kSample / "calibration_result.xml");
  // Hand-copied from the XML text.
  EXPECT_NEAR(ref.camera.matrix(0, 0), 3452.39, 0.01);
  EXPECT_NEAR(ref.projector.matrix(1, 2), 1357.83, 0.01);
  EXPECT_NEAR(ref.translation_mm.y(), -630.457, 0.001);
  EXPECT_NEAR(ref.rotation(2, 1), -0.0787380, 1e-6);
  EXPECT_NEAR(ref.stereo_rms_px, 0.85657, 1e-5);
  EXPECT_EQ(ref.camera.width, 1280);
  EXPECT_EQ(ref.camera.height, 1024);
}

TEST(ProCamCalibration, AgreesWithTheReferenceOnTheRealCaptures) {
  const sl::CalibrationReport& report = our_calibration();
  const sl::ProCamCalibration& ours = report.calibration;
  const sl::ProCamCalibration ref = sl::read_calibration(kSample / "calibration_result.xml");
  EXPECT_EQ(report.poses_used, 5);
  EXPECT_GE(report.projector_corners, 5 * 63 * 9 / 10);  // most corners reach the projector
  // Tolerances: the reference is one estimate from the same 5 poses (focal lengths within 3 %,
  // principal point within 40 px — a few sigma for 5 poses); our corner refinement differs
  // (sub-pixel chessboard corners), so agreement, not equality.
  EXPECT_NEAR(ours.camera.matrix(0, 0), ref.camera.matrix(0, 0), 0.03 * ref.camera.matrix(0, 0));
  EXPECT_NEAR(ours.camera.matrix(1, 1), ref.camera.matrix(1, 1), 0.03 * ref.camera.matrix(1, 1));
  EXPECT_NEAR(ours.camera.matrix(0, 2), ref.camera.matrix(0, 2), 40);
  EXPECT_NEAR(ours.camera.matrix(1, 2), ref.camera.matrix(1, 2), 40);
  EXPECT_NEAR(ours.projector.matrix(0, 0), ref.projector.matrix(0, 0),
              0.03 * ref.projector.matrix(0, 0));
  EXPECT_NEAR(ours.projector.matrix(1, 1), ref.projector.matrix(1, 1),
              0.03 * ref.projector.matrix(1, 1));
  EXPECT_NEAR(ours.projector.matrix(0, 2), ref.projector.matrix(0, 2), 60);
  EXPECT_NEAR(ours.projector.matrix(1, 2), ref.projector.matrix(1, 2), 60);
  // Baseline: within 3 % of the reference's length, direction within 2°.
  EXPECT_NEAR(ours.translation_mm.norm(), ref.translation_mm.norm(),
              0.03 * ref.translation_mm.norm());
  EXPECT_GT(ours.translation_mm.normalized().dot(ref.translation_mm.normalized()),
            std::cos(2.0 * M_PI / 180));
  const double angle = Eigen::AngleAxisd(ours.rotation.transpose() * ref.rotation).angle();
  EXPECT_LT(angle * 180 / M_PI, 1.0);
  // Reprojection error: no worse than the reference's 0.86 px by more than a quarter.
  EXPECT_LT(ours.stereo_rms_px, 1.25 * ref.stereo_rms_px);
}

TEST(ProCamCalibration, WrittenFileReadsBackTheSameNumbers) {
  const sl::ProCamCalibration& ours = our_calibration().calibration;
  const auto file = std::filesystem::temp_directory_path() /
                    ("sherd_sl_calib_" + std::to_string(::getpid()) + ".xml");
  sl::write_calibration(file, ours);
  const sl::ProCamCalibration back = sl::read_calibration(file);
  std::filesystem::remove(file);
  EXPECT_TRUE(back.camera.matrix.isApprox(ours.camera.matrix, 1e-12));
  EXPECT_TRUE(back.rotation.isApprox(ours.rotation, 1e-12));
  EXPECT_EQ(back.projector.width, 1024);
  EXPECT_EQ(back.projector.height, 768);
  EXPECT_DOUBLE_EQ(back.stereo_rms_px, ours.stereo_rms_px);
}

TEST(ProCamCalibration, AMissingFileIsAClearInputError) {
  EXPECT_THROW(sl::read_calibration("/nonexistent/calibration.xml"), sherd::InputError);
}
