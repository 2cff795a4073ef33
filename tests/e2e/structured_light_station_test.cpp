// The station with [scanner] driver = "structured-light-simulated": sherdd drives the
// structured-light scanner (Aravis driver on Aravis's simulated GigE camera, UDP 3956, decoder,
// triangulation) over the turntable; the sherds found must be where the scene put them. Low
// resolution and few views keep it short. And driver = "structured-light" without a calibration
// or a camera: sherdd stops with one clear line.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <sstream>

#include "daemon/station.h"
#include "processing/structured_light/calibration.h"
#include "simulators/pottery.h"
#include "tests/e2e/harness.h"

namespace sherd::testing {
namespace {

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);)
    if (!line.empty()) out.push_back(line);
  return out;
}

Vec3d vec(const nlohmann::json& a) {
  return {a[0].get<double>(), a[1].get<double>(), a[2].get<double>()};
}

// The scene's plate and frame are white so the projector's light comes back from them (a black
// plate returns none: structured light sees only the sherds then).
const std::map<std::string, std::string> kSimulatedStructuredLight = {
    {"scanner.driver", "\"structured-light-simulated\""},
    {"scanner.width", "400"},
    {"scanner.height", "300"},
    {"scanner.fx", "500.0"},
    {"scanner.fy", "500.0"},
    {"scanner.cx", "199.5"},
    {"scanner.cy", "149.5"},
    {"scanner.projector_width", "640"},
    {"scanner.projector_height", "480"},
    {"scanner.patterns", "\"phase\""},
    {"scan.views", "4"},
    {"simulation.sherds", "2"},
    {"simulation.background", "\"white\""},
    {"segmentation.background", "\"white\""},
    {"turntable.time_scale", "0.0"},
};

}  // namespace

TEST(StructuredLightStation, ScanFindsEveryTruthSherdWhereTheSceneHasIt) {
  TestStation station(kSimulatedStructuredLight);
  Daemon daemon(station.config_file, station.data);
  daemon.start();
  const auto status =
      run({binary("sherdctl").string(), "--socket", daemon.socket().string(), "status"});
  EXPECT_NE(status.out.find("structured light"), std::string::npos) << status.out;

  const auto scan =
      run({binary("sherdctl").string(), "--socket", daemon.socket().string(), "scan"});
  ASSERT_EQ(scan.exit_code, 0) << scan.err << daemon.log();
  const auto plates = lines(scan.out);
  const auto scene = sim::make_scene(station::scene_spec(station.config.simulation));
  // Every truth sherd must be found. Extra pieces are possible: the mono camera's grey colour
  // (from the white frame, shaded by incidence) lets dim bits of the white frame through the
  // segmentation's colour test.
  ASSERT_GE(plates.size(), scene.truth.size()) << scan.out << daemon.log();
  std::vector<Vec3d> centres;
  for (const auto& plate : plates) {
    std::ifstream in(std::filesystem::path(plate).parent_path() / "sherd.json");
    const auto doc = nlohmann::json::parse(in);
    centres.push_back(0.5 * (vec(doc["bbox_mm"][0]) + vec(doc["bbox_mm"][1])));
  }
  for (const auto& truth : scene.truth) {
    double nearest = 1e9;
    for (const auto& c : centres) nearest = std::min(nearest, (c - truth.centroid).norm());
    EXPECT_LT(nearest, 25.0) << truth.id << " has no detected sherd near it";
  }
  EXPECT_EQ(daemon.terminate(), 0) << daemon.log();
}

TEST(StructuredLightStation, MissingCalibrationStopsSherddWithOneClearLine) {
  TestStation station(
      std::map<std::string, std::string>{{"scanner.driver", "\"structured-light\""}});
  const auto result = run({binary("sherdd").string(), "--config", station.config_file.string(),
                           "--data-dir", station.data.string()});
  EXPECT_NE(result.exit_code, 0);
  EXPECT_NE(result.err.find("calibration_file"), std::string::npos) << result.err;
  EXPECT_NE(result.err.find("sherdctl calibrate scanner"), std::string::npos) << result.err;
}

TEST(StructuredLightStation, MissingCameraStopsSherddWithOneClearLine) {
  TestStation station(
      std::map<std::string, std::string>{{"scanner.driver", "\"structured-light\""}});
  structured_light::ProCamCalibration calibration;
  calibration.camera.width = 640;
  calibration.camera.height = 480;
  calibration.projector.width = 1024;
  calibration.projector.height = 768;
  std::filesystem::create_directories(station.data / "calibration");
  structured_light::write_calibration(station.data / "calibration" / "scanner.xml", calibration);
  const auto result = run({binary("sherdd").string(), "--config", station.config_file.string(),
                           "--data-dir", station.data.string()});
  EXPECT_NE(result.exit_code, 0);
  EXPECT_NE(result.err.find("camera not found"), std::string::npos) << result.err;
}

}  // namespace sherd::testing
