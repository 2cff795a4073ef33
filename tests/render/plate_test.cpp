// Whole plates of hand-built sherds: the PNG read back with libpng (size, pHYs, scale, layout)
// and profile.svg read back with libxml2 (mm units, viewBox, section polygon).
#include "render/plate.h"

#include "core/errors.h"
#include "test_meshes.h"

#include <gtest/gtest.h>
#include <libxml/parser.h>
#include <libxml/tree.h>
#include <png.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>

namespace sherd::render {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

struct Png {
  int width = 0, height = 0;
  png_uint_32 x_pixels_per_unit = 0, y_pixels_per_unit = 0;
  int unit = -1;
  std::vector<std::uint8_t> rgb;
  const std::uint8_t* at(int column, int row) const {
    return &rgb[(static_cast<std::size_t>(row) * width + column) * 3];
  }
  bool white(int column, int row) const {
    const std::uint8_t* p = at(column, row);
    return p[0] > 250 && p[1] > 250 && p[2] > 250;
  }
  bool black(int column, int row) const {
    const std::uint8_t* p = at(column, row);
    return p[0] < 40 && p[1] < 40 && p[2] < 40;
  }
};

Png read_png(const std::filesystem::path& file) {
  Png png;
  std::FILE* in = std::fopen(file.c_str(), "rb");
  if (!in) throw std::runtime_error("cannot open " + file.string());
  png_structp reader = png_create_read_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(reader);
  png_init_io(reader, in);
  png_read_info(reader, info);
  png.width = static_cast<int>(png_get_image_width(reader, info));
  png.height = static_cast<int>(png_get_image_height(reader, info));
  EXPECT_EQ(png_get_color_type(reader, info), PNG_COLOR_TYPE_RGB);
  EXPECT_EQ(png_get_bit_depth(reader, info), 8);
  png_get_pHYs(reader, info, &png.x_pixels_per_unit, &png.y_pixels_per_unit, &png.unit);
  png.rgb.resize(static_cast<std::size_t>(png.width) * png.height * 3);
  for (int row = 0; row < png.height; ++row)
    png_read_row(reader, &png.rgb[static_cast<std::size_t>(row) * png.width * 3], nullptr);
  png_destroy_read_struct(&reader, &info, nullptr);
  std::fclose(in);
  return png;
}

std::filesystem::path fresh_dir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("sherd_render_" + name);
  std::filesystem::remove_all(dir);
  return dir;
}

PlateSettings settings_at(int dpi) {
  PlateSettings settings;
  settings.dpi = dpi;
  settings.materials_file = std::filesystem::path(SHERD_SOURCE_DIR) / "config/materials.xml";
  return settings;
}

// Longest run of non-white pixels in a row.
int longest_ink_run(const Png& png, int row) {
  int best = 0, run = 0;
  for (int i = 0; i < png.width; ++i) {
    run = png.white(i, row) ? 0 : run + 1;
    best = std::max(best, run);
  }
  return best;
}

TEST(Plate, BodySherdIsAtExactScaleWithPhys) {
  // No axis: front and back of a 100 × 30 × 5 mm slab side by side at 600 dpi.
  const Mesh slab = test::box(100.0, 30.0, 5.0);
  const auto dir = fresh_dir("body");
  const PlateFiles files =
      render_plate({"scan-1", "sherd-1", &slab, nullptr}, settings_at(600), dir);
  const Png png = read_png(files.png);
  EXPECT_EQ(png.width, files.width_px);
  EXPECT_EQ(png.height, files.height_px);
  EXPECT_EQ(png.unit, PNG_RESOLUTION_METER);
  EXPECT_EQ(png.x_pixels_per_unit, 23622u);  // 600 / 0.0254 = 23622.05
  EXPECT_EQ(png.y_pixels_per_unit, 23622u);
  int widest = 0;
  for (int row = 0; row < png.height; ++row) widest = std::max(widest, longest_ink_run(png, row));
  EXPECT_NEAR(widest, 2362, 1);  // 100 mm at 600 dpi; the two views are 10 mm apart
  EXPECT_TRUE(std::filesystem::exists(files.svg));
}

// A wall patch of outer radius 50, inner 45, 40 mm high, `arc_deg` of arc, posed in the world by
// an arbitrary rigid motion; the analysis a perfect profile step would give.
struct WallSherd {
  Mesh mesh;
  profile::Analysis analysis;
};

WallSherd wall_sherd(double arc_deg) {
  WallSherd sherd;
  sherd.mesh = test::cylinder_wall(50.0, 45.0, 40.0, 200.0 * kDeg, (200.0 + arc_deg) * kDeg);
  const Pose sherd_to_world = Eigen::Translation3d(120.0, -30.0, 15.0) *
                              Eigen::AngleAxisd(0.7, Vec3d(1.0, 2.0, 0.5).normalized());
  sherd.mesh.vertices.transform(sherd_to_world);
  profile::Analysis& a = sherd.analysis;
  a.axis.found = true;
  a.axis.point = sherd_to_world.translation();
  a.axis.direction = sherd_to_world.linear().col(2);
  a.sherd_to_world = sherd_to_world;
  a.has_rim = true;
  a.arc_deg = arc_deg;
  a.profile.outer = {{50.0, 0.0}, {50.0, 20.0}, {50.0, 40.0}};
  a.profile.inner = {{45.0, 0.0}, {45.0, 20.0}, {45.0, 40.0}};
  a.measurements.rim_diameter_mm = 100.0;
  a.measurements.rim_percent = arc_deg / 3.6;
  a.measurements.max_diameter_mm = 100.0;
  a.measurements.height_mm = 40.0;
  a.measurements.wall_thickness_mm = {5.0, 5.0, 5.0};
  return sherd;
}

struct Svg {
  double width_mm = 0, height_mm = 0;
  std::array<double, 4> view_box{};
  std::vector<std::array<double, 2>> section;
  std::vector<std::array<double, 2>> scale_cells;  // x, width of each <rect> of the scale bar
};

double mm_attribute(const std::string& value) {
  EXPECT_EQ(value.substr(value.size() - 2), "mm") << value;
  return std::stod(value);
}

Svg read_svg(const std::filesystem::path& file) {
  Svg svg;
  xmlDoc* doc = xmlReadFile(file.c_str(), nullptr, XML_PARSE_NONET);
  if (!doc) throw std::runtime_error("profile.svg is not well-formed XML");
  const auto attribute = [](xmlNode* node, const char* name) {
    xmlChar* value = xmlGetProp(node, reinterpret_cast<const xmlChar*>(name));
    std::string text = value ? reinterpret_cast<const char*>(value) : "";
    xmlFree(value);
    return text;
  };
  xmlNode* root = xmlDocGetRootElement(doc);
  EXPECT_STREQ(reinterpret_cast<const char*>(root->name), "svg");
  svg.width_mm = mm_attribute(attribute(root, "width"));
  svg.height_mm = mm_attribute(attribute(root, "height"));
  std::istringstream(attribute(root, "viewBox")) >> svg.view_box[0] >> svg.view_box[1] >>
      svg.view_box[2] >> svg.view_box[3];
  for (xmlNode* node = root->children; node; node = node->next)
    if (node->type == XML_ELEMENT_NODE && attribute(node, "id") == "section") {
      EXPECT_STREQ(reinterpret_cast<const char*>(node->name), "polygon");
      EXPECT_EQ(attribute(node, "fill"), "black");
      std::istringstream points(attribute(node, "points"));
      double x, y;
      char comma;
      while (points >> x >> comma >> y) svg.section.push_back({x, y});
    } else if (node->type == XML_ELEMENT_NODE && attribute(node, "id") == "scale-bar") {
      for (xmlNode* cell = node->children; cell; cell = cell->next)
        if (cell->type == XML_ELEMENT_NODE)
          svg.scale_cells.push_back(
              {std::stod(attribute(cell, "x")), std::stod(attribute(cell, "width"))});
    }
  xmlFreeDoc(doc);
  return svg;
}

void expect_section_extent(const Svg& svg, double x_min, double x_max) {
  ASSERT_FALSE(svg.section.empty());
  double lo_x = 1e9, hi_x = -1e9, lo_y = 1e9, hi_y = -1e9;
  for (const auto& [x, y] : svg.section) {
    lo_x = std::min(lo_x, x);
    hi_x = std::max(hi_x, x);
    lo_y = std::min(lo_y, y);
    hi_y = std::max(hi_y, y);
  }
  EXPECT_NEAR(lo_x, x_min, 1e-3);
  EXPECT_NEAR(hi_x, x_max, 1e-3);
  EXPECT_NEAR(lo_y, -40.0, 1e-3);  // SVG y runs down: heights 0…40 mm are y −40…0
  EXPECT_NEAR(hi_y, 0.0, 1e-3);
  // 1 user unit = 1 mm, and the view box holds the whole vessel outline (radius 50).
  EXPECT_DOUBLE_EQ(svg.view_box[2], svg.width_mm);
  EXPECT_DOUBLE_EQ(svg.view_box[3], svg.height_mm);
  EXPECT_LE(svg.view_box[0], -50.0);
  EXPECT_GE(svg.view_box[0] + svg.view_box[2], 50.0);
  EXPECT_LE(svg.view_box[1], -40.0);
  EXPECT_GE(svg.view_box[1] + svg.view_box[3], 0.0);
  EXPECT_LT(svg.width_mm, 100.0 + 40.0) << "no more than a margin around the drawing";
  // A 5 cm scale bar of 1 cm cells, end to end: 50 user units = 50 mm.
  ASSERT_EQ(svg.scale_cells.size(), 5u);
  for (std::size_t i = 0; i < 5; ++i) {
    EXPECT_DOUBLE_EQ(svg.scale_cells[i][1], 10.0);
    EXPECT_NEAR(svg.scale_cells[i][0], svg.scale_cells[0][0] + 10.0 * i, 1e-3);
  }
}

TEST(Plate, SectionOnTheRightInSvg) {
  const WallSherd sherd = wall_sherd(120.0);
  const auto dir = fresh_dir("right");
  const PlateFiles files =
      render_plate({"scan-1", "sherd-2", &sherd.mesh, &sherd.analysis}, settings_at(150), dir);
  expect_section_extent(read_svg(files.svg), 45.0, 50.0);
}

TEST(Plate, BritishConventionMirrorsTheSection) {
  const WallSherd sherd = wall_sherd(120.0);
  PlateSettings settings = settings_at(150);
  settings.section_on_right = false;
  const PlateFiles files = render_plate({"scan-1", "sherd-3", &sherd.mesh, &sherd.analysis},
                                        settings, fresh_dir("left"));
  expect_section_extent(read_svg(files.svg), -50.0, -45.0);
}

// Where the black section of a wall sherd of outer radius 50 and inner 45 lies on a plate: the
// rows it spans (the rightmost black run 5 mm plus the pen wide) and, from its centre
// (u = 47.5 mm), the column of the axis.
struct SectionOnPlate {
  int rows = 0, middle_row = 0;
  double axis_column = 0.0;
};

SectionOnPlate find_section(const Png& png, double pixel) {
  SectionOnPlate found;
  int row_sum = 0, section_first = -1, section_last = -1;
  for (int j = 0; j < png.height; ++j) {
    int last = png.width - 1;
    while (last >= 0 && !png.black(last, j)) --last;
    int first = last;
    while (first > 0 && png.black(first - 1, j)) --first;
    const double run_mm = (last - first + 1) * pixel;
    if (last >= 0 && run_mm > 5.0 && run_mm < 5.8) {
      ++found.rows;
      row_sum += j;
      section_first = first;
      section_last = last;
    }
  }
  if (found.rows == 0) return found;
  found.middle_row = row_sum / found.rows;
  found.axis_column = (section_first + section_last + 1) / 2.0 - 47.5 / pixel;
  return found;
}

TEST(Plate, ExteriorViewStartsAtTheFacingMeridian) {
  // A 60° arc turned to start at the meridian facing the viewer and extend to the left spans
  // u ∈ [−50 sin 60°, 0] = [−43.3, 0]; the section (black) spans u ∈ [45, 50].
  const WallSherd sherd = wall_sherd(60.0);
  const int dpi = 300;
  const double pixel = 25.4 / dpi;
  const PlateFiles files = render_plate({"scan-1", "sherd-4", &sherd.mesh, &sherd.analysis},
                                        settings_at(dpi), fresh_dir("arc"));
  const Png png = read_png(files.png);
  const SectionOnPlate section = find_section(png, pixel);
  ASSERT_NEAR(section.rows * pixel, 40.0, 1.0) << "the section is 40 mm tall";
  const int row = section.middle_row;
  const auto column = [&](double u) { return static_cast<int>(section.axis_column + u / pixel); };
  EXPECT_FALSE(png.white(column(-40.0), row)) << "inside the rendered arc";
  EXPECT_FALSE(png.white(column(-20.0), row));
  EXPECT_FALSE(png.black(column(-20.0), row)) << "shaded, not black";
  EXPECT_TRUE(png.white(column(-46.5), row)) << "between the arc's end and the outline";
  EXPECT_TRUE(png.white(column(20.0), row)) << "between the axis and the section";
  EXPECT_FALSE(png.white(column(-50.0), row)) << "the vessel outline";
}

TEST(Plate, CompleteVesselShowsItsWholeExteriorHalfBesideTheSection) {
  // A whole 360° vessel: the exterior half is shaded from the axis to the outline at every
  // height, the other half is the section at u ∈ [45, 50] and paper inside it.
  WallSherd vessel = wall_sherd(360.0);
  vessel.analysis.measurements.volume_ml = std::numbers::pi * 45.0 * 45.0 * 40.0 / 1000.0;
  const int dpi = 300;
  const double pixel = 25.4 / dpi;
  const PlateFiles files = render_plate({"scan-1", "vessel-1", &vessel.mesh, &vessel.analysis},
                                        settings_at(dpi), fresh_dir("vessel"));
  const Png png = read_png(files.png);
  const SectionOnPlate section = find_section(png, pixel);
  ASSERT_NEAR(section.rows * pixel, 40.0, 1.0) << "the section is 40 mm tall";
  const auto column = [&](double u) { return static_cast<int>(section.axis_column + u / pixel); };
  for (const double v_mm : {-15.0, 0.0, 15.0}) {  // heights 5, 20 and 35 mm
    const int row = section.middle_row + static_cast<int>(v_mm / pixel);
    int shaded = 0, paper = 0;
    for (int i = column(-49.0); i <= column(-1.0); ++i)
      shaded += !png.white(i, row) && !png.black(i, row);
    for (int i = column(1.0); i <= column(44.0); ++i) paper += png.white(i, row);
    EXPECT_EQ(shaded, column(-1.0) - column(-49.0) + 1) << "row " << row << ": exterior half";
    EXPECT_EQ(paper, column(44.0) - column(1.0) + 1) << "row " << row << ": inside the section";
    EXPECT_TRUE(png.black(column(47.5), row)) << "row " << row << ": the section";
  }
}

// Runs of non-white pixels in a row: [first, last] columns.
std::vector<std::pair<int, int>> ink_runs(const Png& png, int row) {
  std::vector<std::pair<int, int>> runs;
  for (int i = 0; i < png.width; ++i) {
    if (png.white(i, row)) continue;
    if (runs.empty() || runs.back().second != i - 1) runs.push_back({i, i});
    runs.back().second = i;
  }
  return runs;
}

TEST(Plate, BodySherdShowsFrontAndBackAndNoSection) {
  // No axis: a 100 × 30 × 5 mm slab with a 10 × 10 mm tab at one end (x 50…60 mm, y −5…5).
  // Front and back views side by side, 10 mm apart; the back is the front turned over about the
  // vertical, so the tab is at the other end; profile.svg has no section but says why.
  const Mesh sherd =
      test::merged(test::box(100.0, 30.0, 5.0), test::box(10.0, 10.0, 5.0, {55, 0, 0}));
  const int dpi = 300;
  const double pixel = 25.4 / dpi;
  const PlateFiles files = render_plate({"scan-1", "body-1", &sherd, nullptr}, settings_at(dpi),
                                        fresh_dir("body_front_back"));
  const Png png = read_png(files.png);
  // Rows through both views, with the tab (110 mm long) and without (100 mm).
  std::vector<std::pair<int, int>> with_tab, without_tab;
  for (int row = 0; row < png.height; ++row) {
    const auto runs = ink_runs(png, row);
    if (runs.size() != 2) continue;
    const double a = (runs[0].second - runs[0].first + 1) * pixel;
    const double b = (runs[1].second - runs[1].first + 1) * pixel;
    if (std::abs(a - 110.0) < 0.2 && std::abs(b - 110.0) < 0.2) with_tab = runs;
    if (std::abs(a - 100.0) < 0.2 && std::abs(b - 100.0) < 0.2) without_tab = runs;
  }
  ASSERT_FALSE(with_tab.empty()) << "no row through both views and the tab";
  ASSERT_FALSE(without_tab.empty()) << "no row through both views beside the tab";
  EXPECT_NEAR((with_tab[1].first - with_tab[0].second - 1) * pixel, 10.0, 2 * pixel)
      << "the gap between the views";
  // Which end carries the tab in each view: the end whose column moves by 10 mm.
  const auto tab_on_the_right = [&](int view) {
    return std::abs(with_tab[view].first - without_tab[view].first) <= 1;
  };
  EXPECT_NE(tab_on_the_right(0), tab_on_the_right(1)) << "the back is the front turned over";
  for (int view = 0; view < 2; ++view) {
    const int row_shift = tab_on_the_right(view) ? 0 : static_cast<int>(10.0 / pixel);
    EXPECT_NEAR(without_tab[view].first - with_tab[view].first, row_shift, 1) << "view " << view;
  }
  const Svg svg = read_svg(files.svg);
  EXPECT_TRUE(svg.section.empty()) << "no section without an axis";
  std::ifstream in(files.svg);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("no axis of rotation"), std::string::npos) << text;
}

TEST(Plate, CompositionInBandsEqualsOneBand) {
  // The same plate composed 71 rows at a time (views rendered per band, ink drawn per band)
  // and in one band.
  const WallSherd sherd = wall_sherd(120.0);
  PlateSettings settings = settings_at(200);
  settings.band_rows = 71;
  const Png banded = read_png(render_plate({"scan-1", "sherd-7", &sherd.mesh, &sherd.analysis},
                                           settings, fresh_dir("banded"))
                                  .png);
  settings.band_rows = 1 << 20;
  const Png whole = read_png(render_plate({"scan-1", "sherd-7", &sherd.mesh, &sherd.analysis},
                                          settings, fresh_dir("whole"))
                                 .png);
  ASSERT_EQ(banded.width, whole.width);
  ASSERT_EQ(banded.height, whole.height);
  ASSERT_GT(banded.height, 4 * 71);
  int different = 0, largest = 0;
  for (std::size_t i = 0; i < whole.rgb.size(); ++i) {
    const int d = std::abs(whole.rgb[i] - banded.rgb[i]);
    different += d > 0;
    largest = std::max(largest, d);
  }
  EXPECT_EQ(different, 0) << "largest difference " << largest;
}

TEST(Plate, Grey16At1200DpiHasPhysAndExactScale) {
  // The body-sherd plate of a 100.000 mm slab as 16-bit grey at 1200 dpi: the PNG says 16-bit
  // grey and 1200 dpi (47244 px/m), and the slab spans 4724 ± 1 px.
  const Mesh slab = test::box(100.0, 30.0, 5.0);
  PlateSettings settings = settings_at(1200);
  settings.grey16 = true;
  const PlateFiles files =
      render_plate({"scan-1", "sherd-8", &slab, nullptr}, settings, fresh_dir("grey16"));
  std::FILE* in = std::fopen(files.png.c_str(), "rb");
  ASSERT_NE(in, nullptr);
  png_structp reader = png_create_read_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(reader);
  png_init_io(reader, in);
  png_read_info(reader, info);
  png_set_swap(reader);  // to native (little-endian) order
  EXPECT_EQ(png_get_color_type(reader, info), PNG_COLOR_TYPE_GRAY);
  EXPECT_EQ(png_get_bit_depth(reader, info), 16);
  png_uint_32 x_ppu = 0, y_ppu = 0;
  int unit = -1;
  png_get_pHYs(reader, info, &x_ppu, &y_ppu, &unit);
  EXPECT_EQ(unit, PNG_RESOLUTION_METER);
  EXPECT_EQ(x_ppu, 47244u);  // 1200 / 0.0254 = 47244.09
  EXPECT_EQ(y_ppu, 47244u);
  const int width = static_cast<int>(png_get_image_width(reader, info));
  const int height = static_cast<int>(png_get_image_height(reader, info));
  std::vector<std::uint16_t> row(width);
  int widest = 0, distinct_levels = 0;
  std::vector<bool> seen(65536, false);
  for (int j = 0; j < height; ++j) {
    png_read_row(reader, reinterpret_cast<png_bytep>(row.data()), nullptr);
    int run = 0;
    for (int i = 0; i < width; ++i) {
      run = row[i] >= 65280 ? 0 : run + 1;  // 65280 = 255 · 256: whiter than any 8-bit grey
      widest = std::max(widest, run);
      if (!seen[row[i]]) {
        seen[row[i]] = true;
        ++distinct_levels;
      }
    }
  }
  png_destroy_read_struct(&reader, &info, nullptr);
  std::fclose(in);
  EXPECT_NEAR(widest, 4724, 1);
  EXPECT_GT(distinct_levels, 256) << "more grey levels than 8 bits hold";
}

TEST(Plate, UnknownMaterialIsAnInputErrorBeforeRendering) {
  const WallSherd sherd = wall_sherd(90.0);
  PlateSettings settings = settings_at(150);
  settings.material = "marble";
  try {
    render_plate({"scan-1", "sherd-5", &sherd.mesh, &sherd.analysis}, settings, fresh_dir("bad"));
    FAIL() << "no InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("unknown material preset 'marble'"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("clay"), std::string::npos);
  }
}

TEST(Plate, MissingMeshIsAnInputError) {
  EXPECT_THROW(
      render_plate({"scan-1", "sherd-6", nullptr, nullptr}, settings_at(150), fresh_dir("none")),
      InputError);
}

}  // namespace
}  // namespace sherd::render
