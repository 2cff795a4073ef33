// The plates' material chosen per scan and per sherd (`--material`, `--sherd-material ID=NAME`):
// the colour of each plate's shaded view follows the preset asked for (the diffuse colours of
// ../shared/data/lafortune-pbrt.md: blue paint is blue, skin is red over blue), and an unknown
// preset is one message before anything is scanned or processed. Through `sherdctl process` and
// through sherdd (`sherdctl scan` on the simulated station).
#include "harness.h"

#include "db/store.h"
#include "processing/io/model_io.h"

#include <gtest/gtest.h>
#include <png.h>

#include <cmath>
#include <fstream>
#include <sstream>

namespace sherd::testing {
namespace {

std::filesystem::path write_config(const TempDir& dir,
                                   const std::map<std::string, std::string>& overrides) {
  const auto file = dir.path() / "station.toml";
  std::ofstream(file) << station_config_with(overrides);
  std::filesystem::copy_file(std::filesystem::path(SHERD_SOURCE_DIR) / "config" / "materials.xml",
                             dir.path() / "materials.xml");
  return file;
}

// Points and outward normals on a grid of (u, v) through `surface`.
template <class Surface>
Cloud sampled(int nu, int nv, Surface surface) {
  Cloud cloud;
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j) {
      const auto [p, n] = surface((i + 0.5) / nu, (j + 0.5) / nv);
      cloud.points.push_back(p);
      cloud.normals.push_back(n);
    }
  return cloud;
}

// Two wall pieces in one file, each one surface (the renderer needs no wall): 90° of a 160 mm
// wide pot, 60 mm high, and 200 mm away 90° of a 120 mm wide one, 40 mm high.
Mesh two_sherds() {
  Mesh tray;
  for (const auto& [radius, height, x] : {std::tuple{80.0f, 60.0f, 0.0f}, {60.0f, 40.0f, 200.0f}})
    tray.vertices.append(sampled(180, 60, [&](double u, double v) {
      const double phi = M_PI / 2 * u;
      const Vec3f n(std::cos(phi), std::sin(phi), 0.0);
      return std::pair{Vec3f(radius * n + Vec3f(x, 0, height * v)), n};
    }));
  return tray;
}

// Pixels of a plate whose colour leans clearly to blue, and clearly to red (differences of more
// than 20 levels out of 255); the ink is black and the paper white, so only the view counts.
std::pair<int, int> blue_and_red_pixels(const std::filesystem::path& plate) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&image, plate.c_str()))
    ADD_FAILURE() << plate << ": " << image.message;
  image.format = PNG_FORMAT_RGB;
  std::vector<png_byte> rgb(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, rgb.data(), 0, nullptr))
    ADD_FAILURE() << plate << ": " << image.message;
  int blue = 0, red = 0;
  for (std::size_t i = 0; i + 2 < rgb.size(); i += 3) {
    blue += rgb[i + 2] > rgb[i] + 20;
    red += rgb[i] > rgb[i + 2] + 20;
  }
  return {blue, red};
}

TEST(Materials, ProcessTakesAMaterialPerScanAndAnotherForOneSherd) {
  TempDir dir;
  const auto config = write_config(dir, {});
  const auto file = dir.path() / "tray.ply";
  io::write_ply(file, two_sherds());
  const auto result = run({binary("sherdctl").string(), "--config", config.string(), "process",
                           file.string(), "--out", (dir.path() / "out").string(), "--material",
                           "bluepaint", "--sherd-material", "s02=skin"});
  ASSERT_EQ(result.exit_code, 0) << result.err;
  int plates = 0;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(dir.path() / "out")) {
    if (entry.path().filename() != "plate.png") continue;
    ++plates;
    const std::string sherd_id = entry.path().parent_path().filename();
    const auto [blue, red] = blue_and_red_pixels(entry.path());
    if (sherd_id == "s02") {
      EXPECT_GT(red, 1000) << sherd_id << " (skin) blue " << blue << " red " << red;
      EXPECT_EQ(blue, 0) << sherd_id << " (skin)";
    } else {
      EXPECT_GT(blue, 1000) << sherd_id << " (blue paint) blue " << blue << " red " << red;
      EXPECT_EQ(red, 0) << sherd_id << " (blue paint)";
    }
  }
  EXPECT_EQ(plates, 2) << result.err;
}

TEST(Materials, UnknownPresetIsOneMessageBeforeProcessing) {
  TempDir dir;
  const auto config = write_config(dir, {});
  const auto file = dir.path() / "tray.ply";
  io::write_ply(file, two_sherds());
  const auto out = dir.path() / "out";
  const auto result = run({binary("sherdctl").string(), "--config", config.string(), "process",
                           file.string(), "--out", out.string(), "--sherd-material", "s01=marble"});
  EXPECT_NE(result.exit_code, 0);
  EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << result.err;
  for (const char* named : {"marble", "s01", "clay", "skin", "materials.xml"})
    EXPECT_NE(result.err.find(named), std::string::npos) << named << " not in: " << result.err;
  EXPECT_FALSE(std::filesystem::exists(out / "sherdscan.db")) << "processing began";
}

TEST(Materials, SherddScanTakesAMaterialPerScanAndAnotherForOneSherd) {
  // Felt is a dark neutral grey (diffuse 0.026 in every channel), blue paint is blue.
  TempDir dir;
  const auto config = write_config(dir, {{"turntable.time_scale", "0.05"}});
  Daemon daemon(config, dir.path() / "data");
  daemon.start();
  const auto scan = run({binary("sherdctl").string(), "--socket", daemon.socket().string(), "scan",
                         "--material", "felt", "--sherd-material", "s01=bluepaint"});
  ASSERT_EQ(scan.exit_code, 0) << scan.err << daemon.log();
  int plates = 0;
  std::istringstream lines(scan.out);
  for (std::string plate; std::getline(lines, plate);) {
    if (plate.empty()) continue;
    ++plates;
    const std::string sherd_id = std::filesystem::path(plate).parent_path().filename();
    const auto [blue, red] = blue_and_red_pixels(plate);
    if (sherd_id == "s01")
      EXPECT_GT(blue, 1000) << sherd_id << " (blue paint)";
    else
      EXPECT_EQ(blue + red, 0) << sherd_id << " (felt) blue " << blue << " red " << red;
  }
  EXPECT_GE(plates, 2) << scan.out;
  // Kept with the scan, for a resume after a restart.
  const auto scans = db::Store(dir.path() / "data" / "sherdscan.db").scans();
  ASSERT_EQ(scans.size(), 1u);
  EXPECT_EQ(scans[0].settings["material"], "felt");
  EXPECT_EQ(scans[0].settings["sherd_materials"]["s01"], "bluepaint");
}

TEST(Materials, SherddRefusesAScanWithAnUnknownPresetAndCreatesNoScan) {
  TempDir dir;
  const auto config = write_config(dir, {{"turntable.time_scale", "0"}});
  Daemon daemon(config, dir.path() / "data");
  daemon.start();
  const auto scan = run({binary("sherdctl").string(), "--socket", daemon.socket().string(), "scan",
                         "--material", "marble"});
  EXPECT_NE(scan.exit_code, 0);
  EXPECT_EQ(std::count(scan.err.begin(), scan.err.end(), '\n'), 1) << scan.err;
  for (const char* named : {"marble", "--material", "clay"})
    EXPECT_NE(scan.err.find(named), std::string::npos) << named << " not in: " << scan.err;
  EXPECT_TRUE(db::Store(dir.path() / "data" / "sherdscan.db").scans().empty());
  const auto status =
      run({binary("sherdctl").string(), "--socket", daemon.socket().string(), "status"});
  EXPECT_EQ(status.exit_code, 0) << status.err;
}

}  // namespace
}  // namespace sherd::testing
