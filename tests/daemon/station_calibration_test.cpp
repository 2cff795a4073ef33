// The station and its turntable calibration: which pose and prior are in force with no
// calibration, with a calibration file, and with a corrupt one; the simulated scanner's physical
// pose follows [simulation]'s mounting error.
#include "daemon/station.h"

#include "processing/calibration/turntable_calibration.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <numbers>

namespace sherd::station {
namespace {

namespace fs = std::filesystem;

class StationCalibration : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("sherd-station-calibration-" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    config_ = config::load_station_config(fs::path(SHERD_SOURCE_DIR) / "config" / "station.toml");
    config::set_data_dir(config_, dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
  config::StationConfig config_;
};

TEST_F(StationCalibration, UncalibratedStationUsesTheNominalPoseAndAWidePrior) {
  const Station station = make_station(config_);
  EXPECT_FALSE(station.turntable_calibration.has_value());
  EXPECT_TRUE(station.scanner_to_world.isApprox(calibrated_scanner_pose(config_.scanner), 1e-12));
  EXPECT_NE(station.calibration_note.find("run sherdctl calibrate turntable"), std::string::npos);
  EXPECT_DOUBLE_EQ(station.prior_uncertainty.tilt_sd_deg, 0.5);
  EXPECT_DOUBLE_EQ(station.prior_uncertainty.translation_sd_mm, 2.0);
  EXPECT_DOUBLE_EQ(station.prior_uncertainty.angle_sd_deg, config_.turntable.angle_sd_deg);
  EXPECT_TRUE(static_cast<bool>(station.place_calibration_object));
}

TEST_F(StationCalibration, ACalibrationFileIsPutInForceAtStart) {
  // A calibration that describes the true pose of a scanner mounted 1° and 3 mm off.
  config_.simulation.scanner_tilt_error_deg = 1.0;
  config_.simulation.scanner_offset_error_mm = 3.0;
  const Pose truth = simulated_scanner_pose(config_);
  ASSERT_FALSE(truth.isApprox(calibrated_scanner_pose(config_.scanner), 1e-3));
  calibration::TurntableCalibration c;
  c.axis_direction = truth.linear().transpose().col(2);
  c.axis_point_mm = truth.inverse().translation();
  c.direction_sd_deg = 0.02;
  c.point_sd_mm = 0.03;
  c.height_sd_mm = 0.04;
  calibration::write_turntable_calibration(config_.calibration.turntable_file, c, nlohmann::json::object());

  const Station station = make_station(config_);
  ASSERT_TRUE(station.turntable_calibration.has_value()) << station.calibration_note;
  // Same axis as the truth (the world azimuth is the calibration's convention: compare the axis).
  const Pose& believed = station.scanner_to_world;
  EXPECT_TRUE(believed.linear().row(2).transpose().isApprox(c.axis_direction, 1e-12));
  EXPECT_LT((believed.inverse().translation() - c.axis_point_mm).norm(), 1e-9);
  EXPECT_DOUBLE_EQ(station.prior_uncertainty.tilt_sd_deg, 0.02);
  EXPECT_DOUBLE_EQ(station.prior_uncertainty.translation_sd_mm, 0.05);  // hypot(0.03, 0.04)
}

TEST_F(StationCalibration, PriorHasFloorsUnderAVeryTightCalibration) {
  calibration::TurntableCalibration c;
  c.direction_sd_deg = 0.001;
  c.point_sd_mm = 0.002;
  c.height_sd_mm = 0.001;
  const auto prior = prior_uncertainty(c, config_.turntable);
  EXPECT_DOUBLE_EQ(prior.tilt_sd_deg, 0.01);
  EXPECT_DOUBLE_EQ(prior.translation_sd_mm, 0.05);
}

TEST_F(StationCalibration, ACorruptFileLeavesTheStationUncalibratedAndSaysWhy) {
  fs::create_directories(config_.calibration.turntable_file.parent_path());
  std::ofstream(config_.calibration.turntable_file) << "{\"schema\": 12}";
  const Station station = make_station(config_);
  EXPECT_FALSE(station.turntable_calibration.has_value());
  EXPECT_NE(station.calibration_note.find(config_.calibration.turntable_file.string()), std::string::npos)
      << station.calibration_note;
  EXPECT_NE(station.calibration_note.find("re-run `sherdctl calibrate turntable`"), std::string::npos)
      << station.calibration_note;
  EXPECT_DOUBLE_EQ(station.prior_uncertainty.tilt_sd_deg, 0.5);
}

}  // namespace
}  // namespace sherd::station
