// Top view drawn with cairo (points as small squares, ids as text), written by render's PNG
// writer so that the file records its scale.
#include "processing/segmentation/overview.h"

#include <cairo.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>

#include "render/png_writer.h"

namespace sherd::segmentation {
namespace {

constexpr int kMaxSidePx = 1600;
constexpr double kMarginMm = 10.0;

// Well-separated hues (Glasbey-like), cycled for more sherds than colours.
constexpr std::array<std::array<double, 3>, 12> kPalette{{{0.90, 0.10, 0.10},
                                                          {0.10, 0.45, 0.90},
                                                          {0.10, 0.65, 0.20},
                                                          {0.95, 0.55, 0.05},
                                                          {0.55, 0.20, 0.75},
                                                          {0.05, 0.70, 0.70},
                                                          {0.85, 0.25, 0.60},
                                                          {0.55, 0.45, 0.10},
                                                          {0.40, 0.75, 0.95},
                                                          {0.60, 0.85, 0.20},
                                                          {0.95, 0.75, 0.10},
                                                          {0.30, 0.30, 0.60}}};

}  // namespace

void write_overview_png(const Mesh& fused, const Result& result,
                        const std::filesystem::path& file) {
  const auto& points = fused.vertices.points;
  // The view spans every point that was kept or set aside, with a margin.
  Eigen::Vector2d lo(-kMarginMm, -kMarginMm), hi(kMarginMm, kMarginMm);
  bool any = false;
  auto extend = [&](const std::vector<std::uint32_t>& indices) {
    for (auto i : indices) {
      const Eigen::Vector2d p(points[i].x(), points[i].y());
      if (!any) lo = hi = p, any = true;
      lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    }
  };
  for (const auto& s : result.sherds) extend(s.indices);
  for (const auto& r : result.rejected) extend(r.indices);
  lo -= Eigen::Vector2d::Constant(kMarginMm);
  hi += Eigen::Vector2d::Constant(kMarginMm);
  const Eigen::Vector2d span = hi - lo;
  const double px_per_mm = std::min(4.0, kMaxSidePx / span.maxCoeff());
  const int width = std::max(1, static_cast<int>(std::ceil(span.x() * px_per_mm)));
  const int height = std::max(1, static_cast<int>(std::ceil(span.y() * px_per_mm)));

  std::unique_ptr<cairo_surface_t, decltype(&cairo_surface_destroy)> surface(
      cairo_image_surface_create(CAIRO_FORMAT_RGB24, width, height), cairo_surface_destroy);
  std::unique_ptr<cairo_t, decltype(&cairo_destroy)> cr(cairo_create(surface.get()), cairo_destroy);
  cairo_set_source_rgb(cr.get(), 1, 1, 1);
  cairo_paint(cr.get());
  const double dot = std::max(1.0, 0.5 * px_per_mm);  // about 0.5 mm, at least a pixel
  auto draw = [&](const std::vector<std::uint32_t>& indices) {
    for (auto i : indices) {
      const double x = (points[i].x() - lo.x()) * px_per_mm,
                   y = (hi.y() - points[i].y()) * px_per_mm;
      cairo_rectangle(cr.get(), x - dot / 2, y - dot / 2, dot, dot);
    }
    cairo_fill(cr.get());
  };
  cairo_set_source_rgb(cr.get(), 0.7, 0.7, 0.7);
  for (const auto& r : result.rejected) draw(r.indices);
  for (std::size_t k = 0; k < result.sherds.size(); ++k) {
    const auto& c = kPalette[k % kPalette.size()];
    cairo_set_source_rgb(cr.get(), c[0], c[1], c[2]);
    draw(result.sherds[k].indices);
  }
  // Ids at the centroids: black text on a white outline, readable on any colour.
  cairo_select_font_face(cr.get(), "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_BOLD);
  cairo_set_font_size(cr.get(), std::clamp(0.012 * std::max(width, height), 12.0, 32.0));
  for (const auto& sherd : result.sherds) {
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
    for (auto i : sherd.indices) sum += Eigen::Vector2d(points[i].x(), points[i].y());
    const Eigen::Vector2d c = sum / std::max<std::size_t>(1, sherd.indices.size());
    cairo_text_extents_t ext;
    cairo_text_extents(cr.get(), sherd.id.c_str(), &ext);
    cairo_move_to(cr.get(), (c.x() - lo.x()) * px_per_mm - ext.width / 2 - ext.x_bearing,
                  (hi.y() - c.y()) * px_per_mm - ext.height / 2 - ext.y_bearing);
    cairo_text_path(cr.get(), sherd.id.c_str());
    cairo_set_source_rgb(cr.get(), 1, 1, 1);
    cairo_set_line_width(cr.get(), 3.0);
    cairo_stroke_preserve(cr.get());
    cairo_set_source_rgb(cr.get(), 0, 0, 0);
    cairo_fill(cr.get());
  }
  cairo_surface_flush(surface.get());

  // CAIRO_FORMAT_RGB24: one native-endian 32-bit word per pixel, 0x00RRGGBB.
  const unsigned char* data = cairo_image_surface_get_data(surface.get());
  const int stride = cairo_image_surface_get_stride(surface.get());
  render::PngStream png(file, width, height, static_cast<int>(std::lround(px_per_mm * 25.4)),
                        render::PngFormat::kRgb8);
  std::vector<std::uint8_t> rgb(static_cast<std::size_t>(width) * 3);
  for (int y = 0; y < height; ++y) {
    const auto* row =
        reinterpret_cast<const std::uint32_t*>(data + static_cast<std::ptrdiff_t>(y) * stride);
    for (int x = 0; x < width; ++x) {
      rgb[3 * x] = static_cast<std::uint8_t>(row[x] >> 16);
      rgb[3 * x + 1] = static_cast<std::uint8_t>(row[x] >> 8);
      rgb[3 * x + 2] = static_cast<std::uint8_t>(row[x]);
    }
    png.write_row(rgb.data());
  }
  png.finish();
}

}  // namespace sherd::segmentation
