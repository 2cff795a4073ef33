// One golden image per preset: a relief dome rendered headlessly, compared by mean absolute
// difference with tests/render/golden/<preset>.png (viewed by a person when generated; small
// driver differences stay well inside the tolerance, a changed BRDF, light or preset does not).
// Regenerate with SHERD_UPDATE_GOLDENS=1 after a deliberate change, and look at the images.
#include "render/materials.h"
#include "render/mesh_view.h"
#include "render/png_writer.h"
#include "test_meshes.h"

#include <gtest/gtest.h>
#include <png.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <numbers>

namespace sherd::render {
namespace {

const std::filesystem::path kSource(SHERD_SOURCE_DIR);
constexpr double kTolerance = 2.0;  // mean absolute difference, 8-bit levels

// The dome tilted 35° towards the viewer under the drawing lights, white background.
std::vector<std::uint8_t> render_preset(const std::string& preset, int& width, int& height) {
  const Mesh dome = test::relief_dome(30.0, 90, 180);
  OrthoCamera camera;
  camera.world_to_view = Pose(Eigen::AngleAxisd(-35.0 * std::numbers::pi / 180.0, Vec3d::UnitX()));
  camera.pixel_mm = 0.4;
  camera.left_mm = -32.0;
  camera.bottom_mm = -15.0;
  camera.width_px = width = 160;
  camera.height_px = height = 120;
  const RgbaImage image = render_mesh(dome, find_material(kSource / "config/materials.xml", preset),
                                      camera, drawing_lighting());
  std::vector<std::uint8_t> rgb(static_cast<std::size_t>(width) * height * 3);
  for (std::size_t i = 0; i < rgb.size() / 3; ++i)
    for (int c = 0; c < 3; ++c) {
      const int a = image.rgba[i * 4 + 3];
      rgb[i * 3 + c] =
          static_cast<std::uint8_t>((image.rgba[i * 4 + c] * a + 255 * (255 - a)) / 255);
    }
  return rgb;
}

std::vector<std::uint8_t> read_rgb8(const std::filesystem::path& file, int& width, int& height) {
  std::FILE* in = std::fopen(file.c_str(), "rb");
  if (!in) return {};
  png_structp reader = png_create_read_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(reader);
  png_init_io(reader, in);
  png_read_info(reader, info);
  width = static_cast<int>(png_get_image_width(reader, info));
  height = static_cast<int>(png_get_image_height(reader, info));
  std::vector<std::uint8_t> rgb(static_cast<std::size_t>(width) * height * 3);
  for (int row = 0; row < height; ++row)
    png_read_row(reader, &rgb[static_cast<std::size_t>(row) * width * 3], nullptr);
  png_destroy_read_struct(&reader, &info, nullptr);
  std::fclose(in);
  return rgb;
}

class Golden : public testing::TestWithParam<std::string> {};

TEST_P(Golden, PresetMatchesItsGoldenImage) {
  const std::string preset = GetParam();
  const auto golden = kSource / "tests/render/golden" / (preset + ".png");
  int width = 0, height = 0;
  const std::vector<std::uint8_t> rendered = render_preset(preset, width, height);
  if (std::getenv("SHERD_UPDATE_GOLDENS")) {
    std::filesystem::create_directories(golden.parent_path());
    PngStream png(golden, width, height, 64, PngFormat::kRgb8);
    for (int row = 0; row < height; ++row)
      png.write_row(&rendered[static_cast<std::size_t>(row) * width * 3]);
    png.finish();
    GTEST_SKIP() << "wrote " << golden << "; look at it before committing";
  }
  int golden_width = 0, golden_height = 0;
  const std::vector<std::uint8_t> expected = read_rgb8(golden, golden_width, golden_height);
  ASSERT_FALSE(expected.empty()) << golden << " missing";
  ASSERT_EQ(golden_width, width);
  ASSERT_EQ(golden_height, height);
  double sum = 0.0;
  for (std::size_t i = 0; i < rendered.size(); ++i) sum += std::abs(rendered[i] - expected[i]);
  EXPECT_LT(sum / rendered.size(), kTolerance) << preset;
}

// The tolerance can fail: every preset's rendering lies farther than it from every other
// preset's golden image (clay and skin are the closest pair: 6.3 levels).
TEST(GoldenTolerance, SeparatesEveryPresetFromTheOthers) {
  const std::vector<std::string> presets = {"bluepaint", "brushedmetal", "clay",
                                            "felt",      "primer",       "skin"};
  for (const std::string& preset : presets) {
    int width = 0, height = 0;
    const std::vector<std::uint8_t> rendered = render_preset(preset, width, height);
    for (const std::string& other : presets) {
      if (other == preset) continue;
      const std::vector<std::uint8_t> golden =
          read_rgb8(kSource / "tests/render/golden" / (other + ".png"), width, height);
      ASSERT_EQ(golden.size(), rendered.size());
      double sum = 0.0;
      for (std::size_t i = 0; i < rendered.size(); ++i) sum += std::abs(rendered[i] - golden[i]);
      EXPECT_GT(sum / rendered.size(), kTolerance) << preset << " vs golden " << other;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Presets, Golden,
                         testing::Values("bluepaint", "brushedmetal", "clay", "felt", "primer",
                                         "skin"));

}  // namespace
}  // namespace sherd::render
