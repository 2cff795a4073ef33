// Bad input end to end: each gives one clear message or a job failed with its reason, nothing
// acquired is lost, and the daemon keeps serving.
#include "harness.h"

#include "db/store.h"
#include "processing/io/model_io.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>

namespace sherd::testing {
namespace {

std::size_t count_lines(const std::string& text) {
  std::size_t n = 0;
  for (char c : text) n += c == '\n';
  return n;
}

std::filesystem::path write_config(const TempDir& dir, const std::map<std::string, std::string>& overrides) {
  const auto file = dir.path() / "station.toml";
  std::ofstream(file) << station_config_with(overrides);
  std::filesystem::copy_file(std::filesystem::path(SHERD_SOURCE_DIR) / "config" / "materials.xml",
                             dir.path() / "materials.xml");
  return file;
}

TEST(BadInput, ConfigErrorStopsSherddWithOneLineNamingFileLineAndKey) {
  TempDir dir;
  const auto config = write_config(dir, {{"scan.views", "\"eight\""}});
  const auto result = run({binary("sherdd").string(), "--config", config.string(), "--data-dir",
                           (dir.path() / "data").string()});
  EXPECT_NE(result.exit_code, 0);
  EXPECT_EQ(count_lines(result.err), 1u) << result.err;
  EXPECT_NE(result.err.find("station.toml:"), std::string::npos) << result.err;
  EXPECT_NE(result.err.find("views"), std::string::npos) << result.err;
}

TEST(BadInput, EmptyTrayIsNoSherdsFoundNotAFailure) {
  TempDir dir;
  const auto config = write_config(dir, {{"simulation.scene", "\"empty\""}, {"turntable.time_scale", "0"}});
  Daemon daemon(config, dir.path() / "data");
  daemon.start();
  const auto scan = run({binary("sherdctl").string(), "--socket", daemon.socket().string(), "scan"});
  EXPECT_EQ(scan.exit_code, 0) << scan.err;
  EXPECT_TRUE(scan.out.empty()) << scan.out;
  EXPECT_NE(scan.err.find("no sherds found"), std::string::npos) << scan.err;
}

TEST(BadInput, TurntableStallFailsTheScanKeepsItsViewsAndTheDaemonServes) {
  TempDir dir;
  const auto config = write_config(dir, {{"turntable.fault", "\"stall\""}, {"turntable.fault_at_move", "3"},
                                         {"turntable.time_scale", "0"}});
  Daemon daemon(config, dir.path() / "data");
  daemon.start();
  const auto scan = run({binary("sherdctl").string(), "--socket", daemon.socket().string(), "scan"});
  EXPECT_EQ(scan.exit_code, 1);
  EXPECT_NE(scan.err.find("stall"), std::string::npos) << scan.err;

  db::Store store(dir.path() / "data" / "sherdscan.db");
  const auto scans = store.scans();
  ASSERT_EQ(scans.size(), 1u);
  EXPECT_EQ(scans[0].state, db::ScanState::Failed);
  EXPECT_NE(scans[0].reason.find("stall"), std::string::npos) << scans[0].reason;
  const auto views = store.views(scans[0].id);
  EXPECT_EQ(views.size(), 2u);  // the two moves before the stall
  for (const auto& v : views) EXPECT_TRUE(std::filesystem::exists(v.raw_path));

  const auto status = run({binary("sherdctl").string(), "--socket", daemon.socket().string(), "status"});
  EXPECT_EQ(status.exit_code, 0) << status.err;
}

TEST(BadInput, CorruptFileIsNamedAndOtherFilesStillProcessed) {
  TempDir dir;
  const auto config = write_config(dir, {});
  const auto corrupt = dir.path() / "broken.ply";
  std::ofstream(corrupt) << "ply\nformat binary_little_endian 1.0\nelement vertex 1000\nproperty float x\n"
                            "property float y\nproperty float z\nend_header\n\x01\x02";
  const auto result = run({binary("sherdctl").string(), "--config", config.string(), "process", corrupt.string(),
                           "--out", (dir.path() / "out").string()});
  EXPECT_NE(result.exit_code, 0);
  EXPECT_NE(result.err.find("broken.ply"), std::string::npos) << result.err;
}

// A sphere (every line through its centre is an axis) and a flat slab (a stone) are no pottery:
// each gets its mesh and views, and a sherd.json saying why there is no axis.
TEST(BadInput, NonPotteryObjectsGetNoAxisWithAReason) {
  TempDir dir;
  const auto config = write_config(dir, {});
  Mesh sphere;
  const int rings = 90, segments = 180;
  for (int i = 1; i < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      const double theta = M_PI * i / rings, phi = 2 * M_PI * j / segments;
      const Vec3f n(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
      sphere.vertices.points.push_back(30.0f * n);
      sphere.vertices.normals.push_back(n);
      sphere.vertices.colours.push_back({180, 120, 90});
    }
  }
  const auto file = dir.path() / "sphere.ply";
  io::write_ply(file, sphere);
  const auto out = dir.path() / "out";
  const auto result = run({binary("sherdctl").string(), "--config", config.string(), "process", file.string(),
                           "--out", out.string()});
  ASSERT_EQ(result.exit_code, 0) << result.err;
  ASSERT_FALSE(result.out.empty());
  const auto plate = std::filesystem::path(result.out.substr(0, result.out.find('\n')));
  EXPECT_TRUE(std::filesystem::exists(plate));
  std::ifstream in(plate.parent_path() / "sherd.json");
  const auto doc = nlohmann::json::parse(in);
  EXPECT_FALSE(doc["axis"]["found"].get<bool>());
  EXPECT_TRUE(doc["axis"]["reason"].is_string() && !doc["axis"]["reason"].get<std::string>().empty());
}

}  // namespace
}  // namespace sherd::testing
