// Turntable calibration against the simulator's truth: the simulated scanner is mounted off its
// nominal pose by a known (seeded) error, and ray-casts the calibration object from its TRUE
// pose; the estimator, which sees only the views and their encoder angles, must find the true
// turntable axis in the scanner frame.
#include "processing/calibration/turntable_calibration.h"

#include "core/errors.h"
#include "simulators/pottery.h"
#include "simulators/sim_scanner.h"
#include "simulators/sim_turntable.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>

namespace sherd::calibration {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

struct SimulatedScan {
  std::vector<OrganisedView> captures;
  std::vector<double> encoder_rad;
  Pose true_scanner_to_world;

  std::vector<CalibrationView> views() const {
    std::vector<CalibrationView> out;
    for (std::size_t i = 0; i < captures.size(); ++i) out.push_back({&captures[i], encoder_rad[i]});
    return out;
  }
};

// `views` captures evenly over 360° of the scene, by a scanner mounted with `error` off the
// default station's pose; the angles are what the simulated encoder (3200 steps) reports.
SimulatedScan simulate(sim::SceneKind kind, std::uint64_t seed, const sim::MountingError& error,
                       int views) {
  sim::ScannerModel model = sim::default_station_scanner();
  model.scanner_to_world = sim::mounted_pose(model.scanner_to_world, error);
  model.seed = seed;
  sim::SimulatedTurntable turntable(sim::TurntableModel{.time_scale = 0.0});
  sim::SimulatedScanner scanner(sim::make_scene({.seed = seed, .kind = kind, .sherds = 0}), model,
                                [&turntable] { return turntable.physical_angle(); });
  SimulatedScan scan;
  scan.true_scanner_to_world = model.scanner_to_world;
  for (int i = 0; i < views; ++i) {
    scan.encoder_rad.push_back(turntable.move_to(2 * std::numbers::pi * i / views));
    scan.captures.push_back(scanner.capture());
  }
  return scan;
}

// The truth in the scanner frame: the world z axis and the world origin (axis ∩ plate top).
Vec3d true_direction(const Pose& scanner_to_world) { return scanner_to_world.linear().transpose().col(2); }
Vec3d true_point(const Pose& scanner_to_world) { return scanner_to_world.inverse().translation(); }

struct Errors {
  double direction_deg, across_mm, along_mm;
};
Errors errors(const TurntableCalibration& c, const Pose& truth) {
  const Vec3d d = true_direction(truth);
  const Vec3d delta = c.axis_point_mm - true_point(truth);
  return {std::acos(std::clamp(c.axis_direction.dot(d), -1.0, 1.0)) / kDeg,
          (delta - d * d.dot(delta)).norm(), std::abs(d.dot(delta))};
}

TEST(TurntableCalibration, RecoversTheTrueAxisOfAMisMountedScanner) {
  const auto scan = simulate(sim::SceneKind::Calibration, 7, {.tilt_deg = 1.5, .offset_mm = 4.0, .seed = 7}, 12);
  // The mounting error is real: the nominal pose is well off the truth.
  const Pose nominal = sim::default_station_scanner().scanner_to_world;
  ASSERT_GT(std::acos(true_direction(nominal).dot(true_direction(scan.true_scanner_to_world))) / kDeg, 0.5);

  const auto c = estimate_turntable_axis(scan.views());
  const auto e = errors(c, scan.true_scanner_to_world);
  EXPECT_LT(e.direction_deg, 0.05);
  EXPECT_LT(e.across_mm, 0.2);
  EXPECT_LT(e.along_mm, 0.2);
  // The reported σ is consistent with the actual error.
  EXPECT_LT(e.direction_deg, 3 * c.direction_sd_deg) << "σ " << c.direction_sd_deg;
  EXPECT_LT(e.across_mm, 3 * c.point_sd_mm) << "σ " << c.point_sd_mm;
  EXPECT_LT(e.along_mm, 3 * c.height_sd_mm) << "σ " << c.height_sd_mm;
  EXPECT_EQ(c.views_used, 12);
  EXPECT_EQ(c.spheres_used, 4);
  EXPECT_LT(c.rms_residual_mm, 0.2);
}

// One sphere badly placed in one view (its points moved 3 mm, as a mis-fit or a bumped object
// would give): that centre is left out, and the axis is as good as without it.
TEST(TurntableCalibration, ABadSphereCentreInOneViewIsLeftOut) {
  constexpr std::uint64_t kSeed = 9;
  auto scan = simulate(sim::SceneKind::Calibration, kSeed, {.tilt_deg = 1.0, .offset_mm = 3.0, .seed = kSeed}, 12);
  const auto scene = sim::make_scene({.seed = kSeed, .kind = sim::SceneKind::Calibration, .sherds = 0});
  const auto& sphere = kCalibrationObject.spheres[3];
  const double azimuth = sphere.azimuth_deg * kDeg;
  const Vec3d on_object(sphere.distance_mm * std::cos(azimuth), sphere.distance_mm * std::sin(azimuth),
                        kCalibrationObject.disc_thickness_mm + sphere.height_mm);
  constexpr int kView = 4;
  const double plate = 2 * std::numbers::pi * kView / 12;  // the physical angle of that view
  const Vec3d centre = scan.true_scanner_to_world.inverse() *
                       (Eigen::AngleAxisd(plate, Vec3d::UnitZ()) * (scene.calibration_placement * on_object));
  auto& view = scan.captures[kView];
  int moved = 0;
  for (std::size_t i = 0; i < view.points.size(); ++i) {
    if (view.valid[i] && (view.points[i].cast<double>() - centre).norm() < sphere.radius_mm + 0.5) {
      view.points[i] += Vec3f(3.0f, 0.0f, 0.0f);
      ++moved;
    }
  }
  ASSERT_GT(moved, 1000);

  const auto c = estimate_turntable_axis(scan.views());
  EXPECT_GE(c.centres_rejected, 1);
  const auto e = errors(c, scan.true_scanner_to_world);
  EXPECT_LT(e.direction_deg, 0.05);
  EXPECT_LT(e.across_mm, 0.2);
  EXPECT_LT(e.along_mm, 0.2);
}

// The world frame of a perfect calibration of the nominal station is the configured pose:
// z along the axis, origin on the plate top, the scanner in the plane x = 0 at y < 0.
TEST(TurntableCalibration, WorldFrameOfAPerfectCalibrationIsTheNominalPose) {
  const Pose nominal = sim::default_station_scanner().scanner_to_world;
  TurntableCalibration c;
  c.axis_direction = true_direction(nominal);
  c.axis_point_mm = true_point(nominal);
  EXPECT_TRUE(c.scanner_to_world().isApprox(nominal, 1e-9)) << c.scanner_to_world().matrix();
}

TEST(TurntableCalibration, NoCalibrationObjectIsAClearError) {
  const auto scan = simulate(sim::SceneKind::Empty, 3, {}, 4);
  try {
    estimate_turntable_axis(scan.views());
    FAIL() << "an empty plate gave a calibration";
  } catch (const ProcessingError& e) {
    EXPECT_NE(std::string(e.what()).find("put the calibration object on the plate"), std::string::npos) << e.what();
  }
}

TEST(TurntableCalibration, ViewsAtOneAngleAreRejected) {
  const auto scan = simulate(sim::SceneKind::Calibration, 3, {}, 1);
  std::vector<CalibrationView> same(5, scan.views()[0]);
  EXPECT_THROW(estimate_turntable_axis(same), InputError);
  std::vector<CalibrationView> nan = same;
  nan[1].angle_rad = std::nan("");
  EXPECT_THROW(estimate_turntable_axis(nan), InputError);
  EXPECT_THROW(estimate_turntable_axis({}), InputError);
}

TEST(TurntableCalibration, FileRoundTripAndCorruptFile) {
  const auto dir = std::filesystem::temp_directory_path() / ("sherd_calibration_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  TurntableCalibration c;
  c.axis_direction = Vec3d(0.01, -0.9, 0.4358898943540674).normalized();
  c.axis_point_mm = {1.5, 180.25, 380.125};
  c.direction_sd_deg = 0.004;
  c.point_sd_mm = 0.02;
  c.height_sd_mm = 0.03;
  c.rms_residual_mm = 0.025;
  c.views_used = 12;
  c.spheres_used = 4;
  c.centres_used = 47;
  c.centres_rejected = 1;
  const auto file = dir / "calibration" / "turntable.json";
  write_turntable_calibration(file, c, {{"scan_id", "x"}});
  const auto back = read_turntable_calibration(file);
  EXPECT_TRUE(back.axis_direction.isApprox(c.axis_direction, 1e-12));
  EXPECT_TRUE(back.axis_point_mm.isApprox(c.axis_point_mm, 1e-12));
  EXPECT_DOUBLE_EQ(back.direction_sd_deg, 0.004);
  EXPECT_DOUBLE_EQ(back.point_sd_mm, 0.02);
  EXPECT_EQ(back.centres_used, 47);
  EXPECT_FALSE(std::filesystem::exists(file.string() + ".tmp"));

  std::ofstream(file) << "{\"schema\": \"sherdscan.turntable_calibration/1\", \"axis_dire";
  try {
    read_turntable_calibration(file);
    FAIL() << "a corrupt file was read";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(file.string()), std::string::npos) << message;
    EXPECT_NE(message.find("sherdctl calibrate turntable"), std::string::npos) << message;
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace sherd::calibration
