// Presets parsed from config/materials.xml against the numbers of the pbrt-v1 sources as listed
// in ../shared/data/lafortune-pbrt.md; malformed files and unknown presets give clear messages.
#include "render/materials.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "core/errors.h"

namespace sherd::render {
namespace {

const std::filesystem::path kMaterials =
    std::filesystem::path(SHERD_SOURCE_DIR) / "config/materials.xml";

std::filesystem::path write_temp(const std::string& name, const std::string& text) {
  const auto path = std::filesystem::temp_directory_path() / name;
  std::ofstream(path) << text;
  return path;
}

template <typename F>
std::string input_error_of(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no InputError";
  return {};
}

TEST(Materials, ClayHasThePbrtNumbers) {
  const LafortuneMaterial clay = find_material(kMaterials, "clay");
  EXPECT_EQ(clay.diffuse, (RgbCoefficients{0.383626, 0.260749, 0.274207}));
  ASSERT_EQ(clay.lobes.size(), 3u);
  EXPECT_EQ(clay.lobes[0].cxy, (RgbCoefficients{-1.089701, -1.102701, -1.107603}));
  EXPECT_EQ(clay.lobes[0].cz, (RgbCoefficients{-1.354682, -2.714801, -1.569866}));
  EXPECT_EQ(clay.lobes[0].exponent, (RgbCoefficients{17.968505, 11.024489, 21.270282}));
  EXPECT_EQ(clay.lobes[1].cxy, (RgbCoefficients{-0.733381, -0.793320, -0.848206}));
  EXPECT_EQ(clay.lobes[1].cz, (RgbCoefficients{0.676108, 0.679314, 0.726031}));
  EXPECT_EQ(clay.lobes[1].exponent, (RgbCoefficients{8.219745, 9.055139, 11.261951}));
  EXPECT_EQ(clay.lobes[2].cxy, (RgbCoefficients{-1.010548, -1.012378, -1.011263}));
  EXPECT_EQ(clay.lobes[2].cz, (RgbCoefficients{0.910783, 0.885239, 0.892451}));
  EXPECT_EQ(clay.lobes[2].exponent, (RgbCoefficients{152.912795, 141.937171, 201.046802}));
}

TEST(Materials, BrushedMetalAndPrimerHaveThePbrtNumbers) {
  const LafortuneMaterial metal = find_material(kMaterials, "brushedmetal");
  EXPECT_EQ(metal.diffuse, (RgbCoefficients{0, 0, 0}));
  ASSERT_EQ(metal.lobes.size(), 3u);
  EXPECT_EQ(metal.lobes[0].cxy, (RgbCoefficients{-1.11854, -1.11845, -1.11999}));
  EXPECT_EQ(metal.lobes[1].exponent, (RgbCoefficients{111.267, 88.9222, 65.2179}));
  EXPECT_EQ(metal.lobes[2].cz, (RgbCoefficients{1.00132, 1.00112, 1.00108}));
  const LafortuneMaterial primer = find_material(kMaterials, "primer");
  EXPECT_EQ(primer.diffuse, (RgbCoefficients{0.118230, 0.121218, 0.133209}));
  EXPECT_EQ(primer.lobes[2].cxy, (RgbCoefficients{-1.098605, -0.379883, -0.449038}));
  EXPECT_EQ(primer.lobes[2].exponent, (RgbCoefficients{31.899719, 2.372852, 2.636161}));
}

TEST(Materials, AllSixPresetsInTheirOrder) {
  std::string names;
  for (const LafortuneMaterial& m : load_materials(kMaterials)) names += m.name + " ";
  EXPECT_EQ(names, "bluepaint brushedmetal clay felt primer skin ");
}

TEST(Materials, UnknownPresetListsTheAvailableOnes) {
  const std::string message = input_error_of([] { find_material(kMaterials, "porcelain"); });
  EXPECT_NE(message.find("'porcelain'"), std::string::npos) << message;
  EXPECT_NE(message.find("materials.xml"), std::string::npos) << message;
  EXPECT_NE(message.find("bluepaint, brushedmetal, clay, felt, primer, skin"), std::string::npos)
      << message;
}

TEST(Materials, MalformedXmlNamesFileAndLine) {
  const auto path = write_temp("sherd_render_bad.xml",
                               "<materials>\n  <material name=\"a\">\n"
                               "    <diffuse r=\"1\" g=\"1\" b=\"1\"/>\n"
                               "  </materiall>\n</materials>\n");
  const std::string message = input_error_of([&] { load_materials(path); });
  EXPECT_NE(message.find(path.string() + ":4:"), std::string::npos) << message;
  EXPECT_NE(message.find("malformed XML"), std::string::npos) << message;
}

TEST(Materials, NonNumericCoefficientNamesLineAndValue) {
  const auto path = write_temp("sherd_render_nan.xml",
                               "<materials>\n  <material name=\"a\">\n"
                               "    <diffuse r=\"0.5\" g=\"half\" b=\"1\"/>\n"
                               "  </material>\n</materials>\n");
  const std::string message = input_error_of([&] { load_materials(path); });
  EXPECT_NE(message.find(path.string() + ":3:"), std::string::npos) << message;
  EXPECT_NE(message.find("g=\"half\""), std::string::npos) << message;
}

TEST(Materials, MissingFileSaysSo) {
  const std::string message = input_error_of([] { load_materials("/nonexistent/materials.xml"); });
  EXPECT_NE(message.find("/nonexistent/materials.xml: materials file not found"), std::string::npos)
      << message;
}

}  // namespace
}  // namespace sherd::render
