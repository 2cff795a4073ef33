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

// Points and outward normals on a grid of (u, v) through `surface`.
template <class Surface>
Mesh sampled(int nu, int nv, Surface surface) {
  Mesh mesh;
  for (int i = 0; i < nu; ++i) {
    for (int j = 0; j < nv; ++j) {
      const auto [p, n] = surface((i + 0.5) / nu, (j + 0.5) / nv);
      mesh.vertices.points.push_back(p);
      mesh.vertices.normals.push_back(n);
      mesh.vertices.colours.push_back({180, 120, 90});
    }
  }
  return mesh;
}

// A sphere (every line through its centre is an axis) and a flat stone (a slab: no curvature)
// are no pottery: each gets its mesh and views, and a sherd.json saying why there is no axis.
TEST(BadInput, NonPotteryObjectsGetNoAxisWithAReason) {
  TempDir dir;
  const auto config = write_config(dir, {});
  const auto sphere = sampled(90, 180, [](double u, double v) {
    const double theta = M_PI * u, phi = 2 * M_PI * v;
    const Vec3f n(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
    return std::pair{Vec3f(30.0f * n), n};
  });
  // Two faces of a 60 × 40 × 8 mm slab.
  auto slab = sampled(120, 80, [](double u, double v) {
    return std::pair{Vec3f(60 * u, 40 * v, 8), Vec3f(0, 0, 1)};
  });
  slab.vertices.append(sampled(120, 80, [](double u, double v) {
    return std::pair{Vec3f(60 * u, 40 * v, 0), Vec3f(0, 0, -1)};
  }).vertices);

  for (const auto& [name, mesh] : {std::pair<const char*, const Mesh*>{"sphere", &sphere}, {"slab", &slab}}) {
    const auto file = dir.path() / (std::string(name) + ".ply");
    io::write_ply(file, *mesh);
    const auto result = run({binary("sherdctl").string(), "--config", config.string(), "process", file.string(),
                             "--out", (dir.path() / "out").string()});
    ASSERT_EQ(result.exit_code, 0) << name << ": " << result.err;
    ASSERT_FALSE(result.out.empty()) << name;
    const auto plate = std::filesystem::path(result.out.substr(0, result.out.find('\n')));
    EXPECT_TRUE(std::filesystem::exists(plate)) << name;
    std::ifstream in(plate.parent_path() / "sherd.json");
    const auto doc = nlohmann::json::parse(in);
    EXPECT_FALSE(doc["axis"]["found"].get<bool>()) << name;
    EXPECT_TRUE(doc["axis"]["reason"].is_string() && !doc["axis"]["reason"].get<std::string>().empty()) << name;
  }
}

}  // namespace
}  // namespace sherd::testing
