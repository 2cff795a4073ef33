#include "render/profile_drawing.h"

#include "core/errors.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>

namespace sherd::render {
namespace {

constexpr double kAxisOverhangMm = 4.0;   // the axis line reaches a little past the drawing
constexpr double kScaleBarMm = 50.0;      // the SVG's scale bar, below the drawing
constexpr double kScaleBarSpaceMm = 6.0;  // room for it

void check_polyline(const profile::Polyline2& line, const char* which) {
  if (line.size() < 2)
    throw InputError(
        fmt::format("render: the {} profile has {} points; a section needs at least "
                    "2 (was the profile extracted?)",
                    which, line.size()));
  for (const auto& [r, z] : line)
    if (!std::isfinite(r) || !std::isfinite(z))
      throw InputError(fmt::format("render: the {} profile has a non-finite point", which));
}

// The profile point with the highest (or lowest) z: the rim (or base) end of the outer profile.
std::array<double, 2> extreme_z(const profile::Polyline2& line, bool highest) {
  return *std::max_element(line.begin(), line.end(), [&](const auto& a, const auto& b) {
    return highest ? a[1] < b[1] : a[1] > b[1];
  });
}

std::string svg_points(const profile::Polyline2& line) {
  std::string points;
  for (const auto& [u, v] : line)
    points += fmt::format("{}{:.4f},{:.4f}", points.empty() ? "" : " ", u, -v);
  return points;
}

void write_text(const std::filesystem::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
  out.close();
  if (!out)
    throw ProcessingError(
        fmt::format("{}: cannot write the profile SVG; check the output "
                    "directory",
                    file.string()));
}

}  // namespace

void DrawingBounds::include(double u, double v) {
  u_min = std::min(u_min, u);
  u_max = std::max(u_max, u);
  v_min = std::min(v_min, v);
  v_max = std::max(v_max, v);
}

void DrawingBounds::include(const DrawingBounds& other) {
  include(other.u_min, other.v_min);
  include(other.u_max, other.v_max);
}

ProfileDrawing make_profile_drawing(const profile::Analysis& analysis, bool section_on_right) {
  const profile::Profile& profile = analysis.profile;
  check_polyline(profile.outer, "outer");
  check_polyline(profile.inner, "inner");
  const double side = section_on_right ? 1.0 : -1.0;

  ProfileDrawing drawing;
  for (const auto& [r, z] : profile.outer) drawing.section.push_back({side * r, z});
  for (auto it = profile.inner.rbegin(); it != profile.inner.rend(); ++it)
    drawing.section.push_back({side * (*it)[0], (*it)[1]});
  for (const auto& [r, z] : profile.outer) drawing.exterior_outline.push_back({-side * r, z});

  const auto [first_u, first_v] = drawing.section.front();
  drawing.bounds = {first_u, first_u, first_v, first_v};
  for (const auto& [u, v] : drawing.section) drawing.bounds.include(u, v);
  for (const auto& [u, v] : drawing.exterior_outline) drawing.bounds.include(u, v);
  drawing.bounds.include(0.0, drawing.bounds.v_min);

  if (analysis.has_rim) {
    const auto [r, z] = extreme_z(profile.outer, true);
    drawing.rim_line = HorizontalLine{z, -r, r};
  }
  if (analysis.has_base) {
    const auto [r, z] = extreme_z(profile.outer, false);
    drawing.base_line = HorizontalLine{z, -r, r};
  }
  drawing.axis_v_min = drawing.bounds.v_min - kAxisOverhangMm;
  drawing.axis_v_max = drawing.bounds.v_max + kAxisOverhangMm;
  drawing.bounds.include(0.0, drawing.axis_v_min);
  drawing.bounds.include(0.0, drawing.axis_v_max);
  return drawing;
}

void write_profile_svg(const std::filesystem::path& file, const ProfileDrawing& drawing,
                       double margin_mm) {
  const DrawingBounds& b = drawing.bounds;
  const double width = std::max(b.u_max - b.u_min, kScaleBarMm) + 2 * margin_mm;
  const double height = b.v_max - b.v_min + kScaleBarSpaceMm + 2 * margin_mm;
  std::string svg = fmt::format(
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0:.4f}mm\" height=\"{1:.4f}mm\" "
      "viewBox=\"{2:.4f} {3:.4f} {0:.4f} {1:.4f}\">\n"
      "  <desc>sherdscan profile: 1 user unit = 1 mm; x = radius side, y = -height along the "
      "axis</desc>\n",
      width, height, b.u_min - margin_mm, -(b.v_max + margin_mm));
  svg += fmt::format(
      "  <line id=\"axis\" x1=\"0\" y1=\"{:.4f}\" x2=\"0\" y2=\"{:.4f}\" stroke=\"black\" "
      "stroke-width=\"0.25\" stroke-dasharray=\"6 1.5 0.8 1.5\"/>\n",
      -drawing.axis_v_max, -drawing.axis_v_min);
  for (const auto& [id, line] : {std::pair{"rim", drawing.rim_line}, {"base", drawing.base_line}})
    if (line)
      svg += fmt::format(
          "  <line id=\"{}\" x1=\"{:.4f}\" y1=\"{:.4f}\" x2=\"{:.4f}\" y2=\"{:.4f}\" "
          "stroke=\"black\" stroke-width=\"0.35\"/>\n",
          id, line->u_from, -line->v, line->u_to, -line->v);
  svg += fmt::format(
      "  <polyline id=\"outline\" points=\"{}\" fill=\"none\" stroke=\"black\" "
      "stroke-width=\"0.35\"/>\n",
      svg_points(drawing.exterior_outline));
  svg += fmt::format(
      "  <polygon id=\"section\" points=\"{}\" fill=\"black\" stroke=\"black\" "
      "stroke-width=\"0.35\" stroke-linejoin=\"round\"/>\n",
      svg_points(drawing.section));
  // Scale bar below the drawing: 1 cm cells, alternately filled.
  svg += "  <g id=\"scale-bar\" stroke=\"black\" stroke-width=\"0.2\">\n";
  for (int cm = 0; cm < static_cast<int>(kScaleBarMm / 10.0); ++cm)
    svg += fmt::format(
        "    <rect x=\"{:.4f}\" y=\"{:.4f}\" width=\"10\" height=\"1.5\" fill=\"{}\"/>\n",
        b.u_min + 10.0 * cm, -b.v_min + kScaleBarSpaceMm - 1.5, cm % 2 == 0 ? "black" : "white");
  svg += "  </g>\n</svg>\n";
  write_text(file, svg);
}

void write_no_section_svg(const std::filesystem::path& file, const std::string& reason) {
  std::string escaped;
  for (char c : reason) {
    if (c == '<')
      escaped += "&lt;";
    else if (c == '>')
      escaped += "&gt;";
    else if (c == '&')
      escaped += "&amp;";
    else
      escaped += c;
  }
  write_text(
      file,
      fmt::format(
          "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
          "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"120mm\" height=\"10mm\" "
          "viewBox=\"0 0 120 10\">\n"
          "  <desc>sherdscan profile: 1 user unit = 1 mm; no section: {0}</desc>\n"
          "  <text x=\"2\" y=\"6\" font-size=\"3.5\" font-family=\"sans-serif\">no section: {0}"
          "</text>\n</svg>\n",
          escaped));
}

}  // namespace sherd::render
