// Press scan on the simulated station and check every ground-truth sherd got a plate, a valid
// sherd.json and database rows, with measurements near the simulator's truth; and that a
// power cut (kill -9) mid-scan loses no view.
#include "harness.h"

#include "config/station_config.h"
#include "daemon/protocol.h"
#include "daemon/station.h"
#include "db/store.h"
#include "simulators/pottery.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <csignal>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>
#include <thread>

namespace sherd::testing {
namespace {

nlohmann::json read_json(const std::filesystem::path& file) {
  std::ifstream in(file);
  return nlohmann::json::parse(in);
}

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (!line.empty()) out.push_back(line);
  }
  return out;
}

// The pHYs chunk of a PNG file, in pixels per metre (x); 0 when absent.
unsigned png_pixels_per_metre(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (bytes.compare(1, 3, "PNG") != 0) return 0;
  const auto at = bytes.find("pHYs");
  if (at == std::string::npos || at + 8 > bytes.size()) return 0;
  unsigned v = 0;
  for (int i = 0; i < 4; ++i) v = (v << 8) | static_cast<unsigned char>(bytes[at + 4 + i]);
  return v;
}

Vec3d vec(const nlohmann::json& a) { return {a[0].get<double>(), a[1].get<double>(), a[2].get<double>()}; }

TEST(Station, ScanGivesEveryTruthSherdAPlateAndMeasurementsNearTruth) {
  TestStation station(std::map<std::string, std::string>{{"turntable.time_scale", "0.05"}});
  Daemon daemon(station.config_file, station.data);
  daemon.start();

  const auto scan = run({binary("sherdctl").string(), "--socket", daemon.socket().string(), "scan"});
  ASSERT_EQ(scan.exit_code, 0) << scan.err << daemon.log();
  const auto plates = lines(scan.out);

  const auto scene = sim::make_scene(sherd::station::scene_spec(station.config.simulation));
  ASSERT_FALSE(scene.truth.empty());
  ASSERT_EQ(plates.size(), scene.truth.size()) << scan.out << scan.err;

  // Detected sherds, by the centre of their bounding box.
  std::vector<nlohmann::json> detected;
  for (const auto& plate : plates) {
    ASSERT_TRUE(std::filesystem::exists(plate)) << plate;
    const auto dpm = png_pixels_per_metre(plate);
    EXPECT_NEAR(dpm, station.config.render.dpi / 0.0254, 1.0) << plate << ": pHYs";
    const auto dir = std::filesystem::path(plate).parent_path();
    for (const char* f : {"sherd.json", "profile.svg", "sherd.ply"}) EXPECT_TRUE(std::filesystem::exists(dir / f)) << f;
    auto doc = read_json(dir / "sherd.json");
    EXPECT_EQ(doc["schema"], "sherdscan.sherd/1");
    for (const char* key : {"scan_id", "sherd_id", "points", "bbox_mm", "axis", "orientation", "measurements",
                            "profile", "artifacts"}) {
      EXPECT_TRUE(doc.contains(key)) << key;
    }
    detected.push_back(doc);
  }
  const auto scan_dir = std::filesystem::path(plates.front()).parent_path().parent_path();
  EXPECT_TRUE(std::filesystem::exists(scan_dir / "scan.json"));

  std::set<std::size_t> used;
  std::cout << "sherd  truth  found  axis_err_deg  rim_truth_mm  rim_mm  rim_err_%  rim%_truth  rim%\n";
  for (std::size_t k = 0; k < scene.truth.size(); ++k) {
    const auto& truth = scene.truth[k];
    const Vec3d truth_centre = truth.centroid;
    std::size_t best = detected.size();
    double best_distance = 1e9;
    for (std::size_t i = 0; i < detected.size(); ++i) {
      const auto& box = detected[i]["bbox_mm"];
      const double d = (0.5 * (vec(box[0]) + vec(box[1])) - truth_centre).norm();
      if (d < best_distance) best_distance = d, best = i;
    }
    ASSERT_LT(best_distance, 25.0) << truth.id << " has no detected sherd near it";
    EXPECT_TRUE(used.insert(best).second) << truth.id << " matched a sherd already taken";
    const auto& doc = detected[best];

    ASSERT_TRUE(doc["axis"]["found"].get<bool>()) << truth.id << ": " << doc["axis"]["reason"];
    const Vec3d direction = vec(doc["axis"]["direction"]).normalized();
    const double axis_error = std::acos(std::min(1.0, std::abs(direction.dot(truth.axis_direction)))) * 180.0 / M_PI;
    EXPECT_LT(axis_error, 5.0) << truth.id;

    const auto& m = doc["measurements"];
    double rim = NAN, rim_error = NAN, rim_percent = NAN;
    if (truth.rim_diameter_mm && m["rim_diameter_mm"].is_number()) {
      rim = m["rim_diameter_mm"].get<double>();
      rim_error = 100.0 * (rim - *truth.rim_diameter_mm) / *truth.rim_diameter_mm;
      EXPECT_LT(std::abs(rim_error), 5.0) << truth.id;
    } else if (truth.rim_diameter_mm) {
      ADD_FAILURE() << truth.id << " has a rim but no rim diameter was measured";
    }
    if (m["rim_percent"].is_number()) rim_percent = m["rim_percent"].get<double>();
    std::cout << fmt::format("{:5}  {:5}  {:5}  {:12.2f}  {:12.1f}  {:6.1f}  {:9.2f}  {:10.1f}  {:4.1f}\n", truth.id,
                             truth.family, doc["sherd_id"].get<std::string>(), axis_error,
                             truth.rim_diameter_mm.value_or(NAN), rim, rim_error, truth.rim_percent.value_or(NAN),
                             rim_percent);
  }

  db::Store store(station.data / "sherdscan.db");
  const auto scans = store.scans();
  ASSERT_EQ(scans.size(), 1u);
  EXPECT_EQ(scans[0].state, db::ScanState::Done);
  EXPECT_EQ(static_cast<int>(store.views(scans[0].id).size()), station.config.scan.views);
  EXPECT_EQ(store.sherds(scans[0].id).size(), scene.truth.size());
  EXPECT_GT(store.event_count(scans[0].id), 0);
  EXPECT_EQ(daemon.terminate(), 0) << daemon.log();
}

// A power cut (SIGKILL) and an orderly stop (SIGTERM) in the middle of acquisition: both lose no
// view, and the scan finishes when sherdd starts again.
class Interrupted : public ::testing::TestWithParam<int> {};

TEST_P(Interrupted, MidAcquisitionLosesNoViewAndTheScanFinishesAfterRestart) {
  TestStation station(std::map<std::string, std::string>{{"turntable.time_scale", "1.0"}});
  auto daemon = std::make_unique<Daemon>(station.config_file, station.data);
  daemon->start();

  auto socket = sherd::station::connect_unix(daemon->socket());
  socket.send({{"cmd", "scan"}});
  const auto reply = socket.receive();
  ASSERT_TRUE(reply && (*reply)["ok"].get<bool>());
  const std::string scan_id = (*reply)["scan_id"];

  // Wait for a few views to be on record, then cut the power.
  {
    db::Store store(station.data / "sherdscan.db");
    for (int i = 0; i < 600 && store.views(scan_id).size() < 3; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    ASSERT_GE(store.views(scan_id).size(), 3u);
  }
  if (GetParam() == SIGKILL) {
    daemon->kill9();
  } else {
    EXPECT_EQ(daemon->terminate(), 0) << daemon->log();
  }
  // The client notices: the stream ends without a "finished" event.
  while (auto event = socket.receive()) EXPECT_NE((*event)["event"], "finished");

  daemon = std::make_unique<Daemon>(station.config_file, station.data);
  daemon->start();
  const auto shown = run({binary("sherdctl").string(), "--socket", daemon->socket().string(), "show", scan_id, "--wait"});
  EXPECT_EQ(shown.exit_code, 0) << shown.err << daemon->log();

  db::Store store(station.data / "sherdscan.db");
  const auto scan = store.scan(scan_id);
  ASSERT_TRUE(scan);
  EXPECT_EQ(scan->state, db::ScanState::Done) << scan->reason;
  const auto views = store.views(scan_id);
  ASSERT_EQ(static_cast<int>(views.size()), station.config.scan.views);
  for (int i = 0; i < static_cast<int>(views.size()); ++i) {
    EXPECT_EQ(views[i].index, i);
    EXPECT_TRUE(std::filesystem::exists(views[i].raw_path)) << views[i].raw_path;
    // Every view was taken where the turntable said it was (within one encoder step).
    EXPECT_NEAR(views[i].measured_angle_deg, 360.0 * i / views.size(), 360.0 / station.config.turntable.steps_per_revolution);
  }
  EXPECT_FALSE(store.sherds(scan_id).empty());
  EXPECT_EQ(daemon->terminate(), 0);
}

INSTANTIATE_TEST_SUITE_P(Station, Interrupted, ::testing::Values(SIGKILL, SIGTERM),
                         [](const auto& info) { return info.param == SIGKILL ? "Sigkill" : "Sigterm"; });

}  // namespace
}  // namespace sherd::testing
