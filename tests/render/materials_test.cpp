// Presets parsed from config/materials.xml against the numbers of the pbrt-v1 sources as listed
// in ../shared/data/lafortune-pbrt.md; malformed files and unknown presets give clear messages.
#include "render/materials.h"

#include "core/errors.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

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

// The coefficient table of ../shared/data/lafortune-pbrt.md (transcribed from the pbrt-v1
// sources), keyed by the preset name without spaces ("blue paint" → "bluepaint").
std::map<std::string, LafortuneMaterial> reference_presets() {
  std::ifstream in(std::filesystem::path(SHERD_SHARED_DATA) / "lafortune-pbrt.md");
  EXPECT_TRUE(in) << "lafortune-pbrt.md missing from the shared data";
  std::map<std::string, LafortuneMaterial> presets;
  std::string line, current;
  while (std::getline(in, line)) {
    if (line.rfind("| ", 0) != 0 || line.find("---") != std::string::npos) continue;
    std::vector<std::string> cells;
    std::stringstream row(line.substr(1));
    for (std::string cell; std::getline(row, cell, '|');) {
      cell.erase(0, cell.find_first_not_of(' '));
      cell.erase(cell.find_last_not_of(' ') + 1);
      cells.push_back(cell);
    }
    if (cells.size() < 5 || cells[1] == "term") continue;
    if (!cells[0].empty()) {
      current = cells[0];
      std::erase(current, ' ');
    }
    const RgbCoefficients rgb{std::stod(cells[2]), std::stod(cells[3]), std::stod(cells[4])};
    LafortuneMaterial& m = presets[current];
    if (cells[1] == "diffuse") {
      m.diffuse = rgb;
      continue;
    }
    std::istringstream term(cells[1]);  // "lobe 1 Cz"
    std::string word, which;
    std::size_t lobe = 0;
    term >> word >> lobe >> which;
    if (m.lobes.size() <= lobe) m.lobes.resize(lobe + 1);
    (which == "Cxy"  ? m.lobes[lobe].cxy
     : which == "Cz" ? m.lobes[lobe].cz
                     : m.lobes[lobe].exponent) = rgb;
  }
  return presets;
}

TEST(Materials, EveryPresetHasTheNumbersOfThePbrtSources) {
  const std::map<std::string, LafortuneMaterial> reference = reference_presets();
  ASSERT_EQ(reference.size(), 6u);
  for (const LafortuneMaterial& m : load_materials(kMaterials)) {
    SCOPED_TRACE(m.name);
    ASSERT_TRUE(reference.contains(m.name));
    const LafortuneMaterial& r = reference.at(m.name);
    EXPECT_EQ(m.diffuse, r.diffuse);
    ASSERT_EQ(m.lobes.size(), r.lobes.size());
    for (std::size_t i = 0; i < r.lobes.size(); ++i) {
      EXPECT_EQ(m.lobes[i].cxy, r.lobes[i].cxy) << "lobe " << i;
      EXPECT_EQ(m.lobes[i].cz, r.lobes[i].cz) << "lobe " << i;
      EXPECT_EQ(m.lobes[i].exponent, r.lobes[i].exponent) << "lobe " << i;
    }
  }
}

TEST(Materials, UserPresetIsReadWithoutRecompiling) {
  // A user's file: the shipped presets replaced by one of their own, with two lobes.
  const auto path = write_temp("sherd_render_user.xml",
                               "<materials>\n  <material name=\"terra sigillata\">\n"
                               "    <diffuse r=\"0.6\" g=\"0.25\" b=\"0.15\"/>\n"
                               "    <lobe><cxy r=\"-1\" g=\"-1\" b=\"-1\"/>"
                               "<cz r=\"0.9\" g=\"0.9\" b=\"0.9\"/><n r=\"30\" g=\"30\" "
                               "b=\"30\"/></lobe>\n"
                               "    <lobe><cxy r=\"0.2\" g=\"0.2\" b=\"0.2\"/>"
                               "<cz r=\"0.1\" g=\"0.1\" b=\"0.1\"/><n r=\"2\" g=\"2\" "
                               "b=\"2.5\"/></lobe>\n"
                               "  </material>\n</materials>\n");
  const LafortuneMaterial m = find_material(path, "terra sigillata");
  EXPECT_EQ(m.diffuse, (RgbCoefficients{0.6, 0.25, 0.15}));
  ASSERT_EQ(m.lobes.size(), 2u);
  EXPECT_EQ(m.lobes[0].cz, (RgbCoefficients{0.9, 0.9, 0.9}));
  EXPECT_EQ(m.lobes[1].exponent, (RgbCoefficients{2, 2, 2.5}));
  const std::string message = input_error_of([&] { find_material(path, "clay"); });
  EXPECT_NE(message.find("available presets: terra sigillata"), std::string::npos) << message;
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
