// `sherdctl calibrate turntable` end to end: sherdd on a simulated station whose scanner is
// mounted off its configured pose; after the calibration the daemon's station must hold the
// simulator's TRUE turntable axis (not the configured one), keep it in the file and the database,
// and load it again at the next start. A corrupt file and a failed calibration say so clearly.
#include "harness.h"

#include "config/station_config.h"
#include "daemon/station.h"
#include "db/store.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <numbers>

namespace sherd::testing {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

Vec3d vec(const nlohmann::json& a) { return {a[0].get<double>(), a[1].get<double>(), a[2].get<double>()}; }

// A station whose simulated scanner is mounted 1.2° and 4 mm off its configured pose.
TestStation calibration_station(std::map<std::string, std::string> overrides) {
  overrides.emplace("turntable.time_scale", "0");
  overrides.emplace("simulation.scanner_tilt_error_deg", "1.2");
  overrides.emplace("simulation.scanner_offset_error_mm", "4.0");
  return TestStation(overrides);
}

nlohmann::json status(const Daemon& daemon) {
  const auto result = run({binary("sherdctl").string(), "--socket", daemon.socket().string(), "--json", "status"});
  EXPECT_EQ(result.exit_code, 0) << result.err;
  return nlohmann::json::parse(result.out)["turntable_calibration"];
}

// Angle (degrees) and distance (mm) of the reported axis from the simulator's true one.
std::pair<double, double> error_from_truth(const nlohmann::json& calibration, const config::StationConfig& config) {
  const Pose truth = sherd::station::simulated_scanner_pose(config);
  const Vec3d direction = truth.linear().transpose().col(2);   // world z in the scanner frame
  const Vec3d point = truth.inverse().translation();           // world origin in the scanner frame
  const double angle = std::acos(std::min(1.0, vec(calibration["axis_direction"]).dot(direction))) / kDeg;
  return {angle, (vec(calibration["axis_point_mm"]) - point).norm()};
}

TEST(Calibration, CalibrateTurntableFindsTheTrueAxisAndEveryLaterStartUsesIt) {
  TestStation station = calibration_station({});
  {
    Daemon daemon(station.config_file, station.data);
    daemon.start();
    const auto before = status(daemon);
    EXPECT_FALSE(before["calibrated"].get<bool>());
    EXPECT_NE(before["note"].get<std::string>().find("run sherdctl calibrate turntable"), std::string::npos);
    EXPECT_DOUBLE_EQ(before["prior_uncertainty"]["tilt_sd_deg"].get<double>(), 0.5);

    const auto calibrated = run({binary("sherdctl").string(), "--socket", daemon.socket().string(), "calibrate",
                                 "turntable"});
    ASSERT_EQ(calibrated.exit_code, 0) << calibrated.err << daemon.log();
    EXPECT_NE(calibrated.out.find(station.config.calibration.turntable_file.string()), std::string::npos)
        << calibrated.out;

    // The station now holds the simulator's true axis, and a prior as tight as the fit allows.
    const auto after = status(daemon);
    ASSERT_TRUE(after["calibrated"].get<bool>()) << after;
    const auto [angle, distance] = error_from_truth(after, station.config);
    EXPECT_LT(angle, 0.05);
    EXPECT_LT(distance, 0.2);
    // …where the configured (nominal) pose is well off: the calibration, not the config, is used.
    const Pose nominal = sherd::station::calibrated_scanner_pose(station.config.scanner);
    EXPECT_GT(std::acos(nominal.linear().transpose().col(2).dot(vec(after["axis_direction"]))) / kDeg, 0.5);
    EXPECT_LE(after["prior_uncertainty"]["tilt_sd_deg"].get<double>(), 0.05);
    EXPECT_DOUBLE_EQ(after["prior_uncertainty"]["angle_sd_deg"].get<double>(), station.config.turntable.angle_sd_deg);

    // Stored in the database with its raw views on disk.
    db::Store store(station.config.paths.database);
    const auto record = store.latest_calibration("turntable");
    ASSERT_TRUE(record.has_value());
    const auto views = store.views(record->scan_id);
    EXPECT_EQ(static_cast<int>(views.size()), station.config.calibration.views);
    for (const auto& v : views) EXPECT_TRUE(std::filesystem::exists(v.raw_path)) << v.raw_path;
    EXPECT_EQ(store.scan(record->scan_id)->state, db::ScanState::Done);
    EXPECT_EQ(daemon.terminate(), 0) << daemon.log();
  }
  // The next start loads the file.
  {
    Daemon daemon(station.config_file, station.data);
    daemon.start();
    const auto loaded = status(daemon);
    ASSERT_TRUE(loaded["calibrated"].get<bool>()) << loaded;
    EXPECT_LT(error_from_truth(loaded, station.config).first, 0.05);
    EXPECT_EQ(daemon.terminate(), 0) << daemon.log();
  }
  // A corrupt file: the daemon still starts (to be calibrated again), uncalibrated, and says why.
  std::ofstream(station.config.calibration.turntable_file) << "{\"schema\": \"sherdscan.turntable_calib";
  Daemon daemon(station.config_file, station.data);
  daemon.start();
  const auto corrupt = status(daemon);
  EXPECT_FALSE(corrupt["calibrated"].get<bool>());
  const std::string note = corrupt["note"];
  EXPECT_NE(note.find(station.config.calibration.turntable_file.string()), std::string::npos) << note;
  EXPECT_NE(note.find("re-run `sherdctl calibrate turntable`"), std::string::npos) << note;
  EXPECT_EQ(daemon.terminate(), 0);
  EXPECT_NE(daemon.log().find(note), std::string::npos) << daemon.log();
}

TEST(Calibration, AFailedCalibrationIsAFailedJobWithItsReason) {
  TestStation station = calibration_station({{"turntable.fault", "\"stall\""}, {"turntable.fault_at_move", "3"}});
  Daemon daemon(station.config_file, station.data);
  daemon.start();
  const auto result = run({binary("sherdctl").string(), "--socket", daemon.socket().string(), "calibrate",
                           "turntable"});
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.err.find("failed"), std::string::npos) << result.err;
  EXPECT_NE(result.err.find("stays uncalibrated"), std::string::npos) << result.err;
  EXPECT_FALSE(status(daemon)["calibrated"].get<bool>());
  EXPECT_FALSE(std::filesystem::exists(station.config.calibration.turntable_file));

  const auto scanner = run({binary("sherdctl").string(), "--socket", daemon.socket().string(), "calibrate",
                            "scanner"});
  EXPECT_NE(scanner.exit_code, 0);
  EXPECT_NE(scanner.err.find("not available yet"), std::string::npos) << scanner.err;
  EXPECT_EQ(daemon.terminate(), 0) << daemon.log();
}

}  // namespace
}  // namespace sherd::testing
