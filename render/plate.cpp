#include "render/plate.h"

#include "core/errors.h"
#include "render/materials.h"
#include "render/mesh_view.h"
#include "render/png_writer.h"
#include "render/profile_drawing.h"

#include <cairo.h>
#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <memory>
#include <numbers>
#include <vector>

namespace sherd::render {
namespace {

constexpr double kMarginMm = 8.0;
constexpr double kScaleBarMm = 50.0;  // 5 cm with 1 cm ticks
constexpr double kScaleBarHeightMm = 1.5;
constexpr double kFontMm = 3.0;
constexpr double kLineMm = 4.5;      // text line pitch
constexpr double kViewGapMm = 10.0;  // between the front and back views of a body sherd
constexpr double kPenMm = 0.35;      // technical-pen line width
constexpr int kMinDpi = 50, kMaxDpi = 4800;

using Surface = std::unique_ptr<cairo_surface_t, decltype(&cairo_surface_destroy)>;
using Cairo = std::unique_ptr<cairo_t, decltype(&cairo_destroy)>;

// The plate's pixel grid. Pixel (i, j counted from the top) covers drawing u ∈ [u0 + i·pixel,
// u0 + (i+1)·pixel) and v ∈ (v_top − (j+1)·pixel, v_top − j·pixel]. u0 and v_top are whole
// multiples of the pixel so that the axis (u = 0) runs along a pixel edge.
struct Canvas {
  double u0 = 0.0, v_top = 0.0, pixel_mm = 0.0;
  int width = 0, height = 0;
};

Canvas make_canvas(const DrawingBounds& content, double pixel_mm) {
  Canvas canvas;
  canvas.pixel_mm = pixel_mm;
  canvas.u0 = std::floor((content.u_min - kMarginMm) / pixel_mm) * pixel_mm;
  canvas.v_top = std::ceil((content.v_max + kMarginMm) / pixel_mm) * pixel_mm;
  canvas.width = static_cast<int>(std::ceil((content.u_max + kMarginMm - canvas.u0) / pixel_mm));
  canvas.height =
      static_cast<int>(std::ceil((canvas.v_top - (content.v_min - kMarginMm)) / pixel_mm));
  return canvas;
}

// A GL camera on the plate's pixel grid covering `region` (drawing mm), and where its image goes
// on the plate. Rendering only the region, not the whole plate, saves most of the GL work.
struct PlacedCamera {
  OrthoCamera camera;
  int column = 0, row = 0;  // the image's top-left pixel on the plate
};

PlacedCamera camera_on(const Canvas& canvas, const Pose& world_to_drawing,
                       const DrawingBounds& region) {
  const double pixel = canvas.pixel_mm;
  const int i0 = std::max(0, static_cast<int>(std::floor((region.u_min - canvas.u0) / pixel)) - 1);
  const int i1 =
      std::min(canvas.width, static_cast<int>(std::ceil((region.u_max - canvas.u0) / pixel)) + 1);
  const int j0 =
      std::max(0, static_cast<int>(std::floor((canvas.v_top - region.v_max) / pixel)) - 1);
  const int j1 = std::min(canvas.height,
                          static_cast<int>(std::ceil((canvas.v_top - region.v_min) / pixel)) + 1);
  PlacedCamera placed;
  placed.column = i0;
  placed.row = j0;
  OrthoCamera& camera = placed.camera;
  camera.world_to_view = world_to_drawing;
  camera.left_mm = canvas.u0 + i0 * pixel;
  camera.bottom_mm = canvas.v_top - j1 * pixel;
  camera.pixel_mm = pixel;
  camera.width_px = i1 - i0;
  camera.height_px = j1 - j0;
  return placed;
}

DrawingBounds mesh_bounds(const Mesh& mesh, const Pose& world_to_drawing) {
  const Vec3d first = world_to_drawing * mesh.vertices.points.front().cast<double>();
  DrawingBounds bounds{first.x(), first.x(), first.y(), first.y()};
  for (const Vec3f& p : mesh.vertices.points) {
    const Vec3d q = world_to_drawing * p.cast<double>();
    bounds.include(q.x(), q.y());
  }
  return bounds;
}

// The footer below the drawing: scale bar, then the text lines.
double footer_height_mm(std::size_t lines) { return 12.0 + kLineMm * lines; }

double text_width_mm(const std::vector<std::string>& lines) {
  Surface scratch(cairo_image_surface_create(CAIRO_FORMAT_ARGB32, 1, 1), cairo_surface_destroy);
  Cairo cr(cairo_create(scratch.get()), cairo_destroy);
  cairo_select_font_face(cr.get(), "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr.get(), kFontMm);
  double width = kScaleBarMm + 35.0;  // room for the rim-percent diagram
  for (const std::string& line : lines) {
    cairo_text_extents_t extents;
    cairo_text_extents(cr.get(), line.c_str(), &extents);
    width = std::max(width, extents.x_advance);
  }
  return width;
}

// Grows `content` downwards and rightwards for the footer.
void reserve_footer(DrawingBounds& content, const std::vector<std::string>& lines) {
  content.v_min -= footer_height_mm(lines.size());
  content.u_max = std::max(content.u_max, content.u_min + text_width_mm(lines));
}

// A cairo context whose user space is drawing millimetres (u right, v up).
Cairo drawing_context(cairo_surface_t* surface, const Canvas& canvas) {
  Cairo cr(cairo_create(surface), cairo_destroy);
  cairo_matrix_t matrix;
  cairo_matrix_init(&matrix, 1.0 / canvas.pixel_mm, 0.0, 0.0, -1.0 / canvas.pixel_mm,
                    -canvas.u0 / canvas.pixel_mm, canvas.v_top / canvas.pixel_mm);
  cairo_set_matrix(cr.get(), &matrix);
  return cr;
}

void polyline(cairo_t* cr, const profile::Polyline2& line) {
  cairo_move_to(cr, line.front()[0], line.front()[1]);
  for (const auto& [u, v] : line) cairo_line_to(cr, u, v);
}

void draw_profile(cairo_t* cr, const ProfileDrawing& drawing) {
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_set_line_join(cr, CAIRO_LINE_JOIN_ROUND);
  cairo_set_line_width(cr, kPenMm);
  polyline(cr, drawing.section);
  cairo_close_path(cr);
  cairo_fill_preserve(cr);
  cairo_stroke(cr);
  polyline(cr, drawing.exterior_outline);
  cairo_stroke(cr);
  for (const auto& line : {drawing.rim_line, drawing.base_line})
    if (line) {
      cairo_move_to(cr, line->u_from, line->v);
      cairo_line_to(cr, line->u_to, line->v);
      cairo_stroke(cr);
    }
  const double dash_dot[] = {6.0, 1.5, 0.8, 1.5};
  cairo_set_line_width(cr, 0.25);
  cairo_set_dash(cr, dash_dot, 4, 0.0);
  cairo_move_to(cr, 0.0, drawing.axis_v_min);
  cairo_line_to(cr, 0.0, drawing.axis_v_max);
  cairo_stroke(cr);
  cairo_set_dash(cr, nullptr, 0, 0.0);
}

// Text at drawing position (u, v) = left end of the baseline; drawn upright in pixel space.
void text(cairo_t* cr, const Canvas& canvas, double u, double v, const std::string& line) {
  cairo_save(cr);
  cairo_identity_matrix(cr);
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr, kFontMm / canvas.pixel_mm);
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_move_to(cr, (u - canvas.u0) / canvas.pixel_mm, (canvas.v_top - v) / canvas.pixel_mm);
  cairo_show_text(cr, line.c_str());
  cairo_restore(cr);
}

// Scale bar (alternate centimetres filled) and text lines, from the top-left corner (u, v).
void draw_footer(cairo_t* cr, const Canvas& canvas, double u, double v,
                 const std::vector<std::string>& lines) {
  const double bar_v = v - 6.0;  // clear of the axis line's end
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_set_line_width(cr, 0.2);
  for (int cm = 0; cm < static_cast<int>(kScaleBarMm / 10.0); ++cm) {
    cairo_rectangle(cr, u + 10.0 * cm, bar_v - kScaleBarHeightMm, 10.0, kScaleBarHeightMm);
    if (cm % 2 == 0) cairo_fill_preserve(cr);
    cairo_stroke(cr);
  }
  text(cr, canvas, u - 0.8, bar_v + 1.0, "0");
  text(cr, canvas, u + kScaleBarMm - 2.0, bar_v + 1.0, fmt::format("{} cm", kScaleBarMm / 10.0));
  for (std::size_t i = 0; i < lines.size(); ++i)
    text(cr, canvas, u, bar_v - kScaleBarHeightMm - 4.0 - kLineMm * static_cast<double>(i),
         lines[i]);
}

// The preserved share of the rim as an arc on a thin circle (clockwise from the top) with its
// percentage, right of the scale bar's end, from the footer's top-left corner (u, v).
void draw_rim_diagram(cairo_t* cr, const Canvas& canvas, double u, double v, double percent) {
  const double radius = 3.0, cu = u + kScaleBarMm + 12.0, cv = v - 6.0;
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_new_path(cr);
  cairo_set_line_width(cr, 0.2);
  cairo_arc(cr, cu, cv, radius, 0.0, 2 * std::numbers::pi);
  cairo_stroke(cr);
  cairo_set_line_width(cr, 0.9);
  // User space has v up, so clockwise on paper is decreasing angle.
  const double top = std::numbers::pi / 2;
  cairo_arc_negative(cr, cu, cv, radius, top,
                     top - 2 * std::numbers::pi * std::clamp(percent, 0.0, 100.0) / 100.0);
  cairo_stroke(cr);
  text(cr, canvas, cu + radius + 1.5, cv - 1.0, fmt::format("rim {:.0f} %", percent));
}

// A rendered view and where it goes on the plate.
struct PlacedView {
  MeshRenderer* renderer = nullptr;
  PlacedCamera placed;
};

// Draws the plate's ink (all of it black: lines, section, text) into an A8 mask in drawing mm.
using InkPainter = std::function<void(cairo_t*, const Canvas&)>;

// Composes the plate band by band: the views' pixels over white, then the ink over them, each
// band written to the PNG before the next is drawn, so that memory is bounded by the band, not
// the plate. Composition is in 16 bits per channel for both output formats.
PlateFiles compose_plate(const Canvas& canvas, const std::vector<PlacedView>& views,
                         const InkPainter& paint_ink, const PlateSettings& settings,
                         const std::filesystem::path& dir) {
  PlateFiles files{dir / "plate.png", dir / "profile.svg", canvas.width, canvas.height};
  const bool grey16 = settings.grey16;
  PngStream png(files.png, canvas.width, canvas.height, settings.dpi,
                grey16 ? PngFormat::kGrey16 : PngFormat::kRgb8);
  const auto width = static_cast<std::size_t>(canvas.width);
  const int band_rows =
      settings.band_rows > 0
          ? settings.band_rows
          : std::max(1, static_cast<int>((std::size_t{128} << 20) / (width * 16)));
  std::vector<std::uint16_t> rgb(width * 3 * band_rows);
  std::vector<std::uint8_t> row8(width * 3);
  std::vector<std::uint16_t> row16(width);
  for (int r0 = 0; r0 < canvas.height; r0 += band_rows) {
    const int rows = std::min(band_rows, canvas.height - r0);
    std::fill(rgb.begin(), rgb.end(), std::uint16_t{65535});
    for (const PlacedView& view : views) {
      const OrthoCamera& full = view.placed.camera;
      const int from = std::max(r0, view.placed.row);
      const int to = std::min(r0 + rows, view.placed.row + full.height_px);
      if (from >= to) continue;
      OrthoCamera part = full;  // the view's plate rows [from, to): whole pixels off its bottom
      part.bottom_mm = full.bottom_mm + (view.placed.row + full.height_px - to) * full.pixel_mm;
      part.height_px = to - from;
      const RgbaImage image = view.renderer->render(part, 0, grey16);
      const auto sample = [&](std::size_t k) -> std::uint32_t {
        return grey16 ? image.rgba16[k] : image.rgba[k] * 257u;
      };
      for (int j = 0; j < part.height_px; ++j)
        for (int i = 0; i < part.width_px; ++i) {
          const std::size_t src = (static_cast<std::size_t>(j) * part.width_px + i) * 4;
          const std::uint32_t a = sample(src + 3);
          if (a == 0) continue;
          std::uint16_t* out = &rgb[((from - r0 + j) * width + view.placed.column + i) * 3];
          for (int c = 0; c < 3; ++c)
            out[c] = static_cast<std::uint16_t>(
                (sample(src + c) * a + out[c] * (65535u - a) + 32767u) / 65535u);
        }
    }
    Canvas band = canvas;
    band.v_top = canvas.v_top - r0 * canvas.pixel_mm;
    band.height = rows;
    Surface ink(cairo_image_surface_create(CAIRO_FORMAT_A8, canvas.width, rows),
                cairo_surface_destroy);
    if (cairo_surface_status(ink.get()) != CAIRO_STATUS_SUCCESS)
      throw ProcessingError(fmt::format("render: cannot allocate a {}×{} px band; lower the dpi",
                                        canvas.width, rows));
    paint_ink(drawing_context(ink.get(), band).get(), band);
    cairo_surface_flush(ink.get());
    const unsigned char* mask = cairo_image_surface_get_data(ink.get());
    const int stride = cairo_image_surface_get_stride(ink.get());
    for (int j = 0; j < rows; ++j) {
      for (std::size_t i = 0; i < width; ++i) {
        const std::uint32_t keep = 255u - mask[static_cast<std::size_t>(j) * stride + i];
        std::uint16_t* px = &rgb[(j * width + i) * 3];
        for (int c = 0; c < 3; ++c) px[c] = static_cast<std::uint16_t>((px[c] * keep + 127) / 255);
        if (grey16)  // Rec. 709 luma of the display-encoded colour
          row16[i] = static_cast<std::uint16_t>(
              std::lround(0.2126 * px[0] + 0.7152 * px[1] + 0.0722 * px[2]));
        else
          for (int c = 0; c < 3; ++c)
            row8[i * 3 + c] = static_cast<std::uint8_t>((px[c] + 128) / 257);
      }
      png.write_row(grey16 ? static_cast<const void*>(row16.data()) : row8.data());
    }
  }
  png.finish();
  return files;
}

// Azimuth (sherd frame, radians) where the sherd's arc starts, going counter-clockwise, and its
// extent: the complement of the largest angular gap between vertices.
std::pair<double, double> arc_of(const Mesh& mesh, const Pose& world_to_sherd) {
  std::vector<double> azimuths;
  azimuths.reserve(mesh.vertices.size());
  for (const Vec3f& p : mesh.vertices.points) {
    const Vec3d q = world_to_sherd * p.cast<double>();
    if (q.head<2>().squaredNorm() > 1e-12) azimuths.push_back(std::atan2(q.y(), q.x()));
  }
  if (azimuths.size() < 2) return {0.0, 0.0};
  std::sort(azimuths.begin(), azimuths.end());
  double largest_gap = azimuths.front() + 2 * std::numbers::pi - azimuths.back();
  double start = azimuths.front();
  for (std::size_t i = 1; i < azimuths.size(); ++i)
    if (azimuths[i] - azimuths[i - 1] > largest_gap) {
      largest_gap = azimuths[i] - azimuths[i - 1];
      start = azimuths[i];
    }
  return {start, 2 * std::numbers::pi - largest_gap};
}

std::string header_line(const PlateInput& input) {
  return fmt::format("{}   scan {}", input.sherd_id, input.scan_id);
}

std::string scale_line(const PlateSettings& settings) {
  return fmt::format("1:1 at {} dpi   material {}", settings.dpi, settings.material);
}

std::vector<std::string> measurement_lines(const PlateInput& input, const PlateSettings& settings) {
  const profile::Measurements& m = input.analysis->measurements;
  std::string sizes;
  if (m.rim_diameter_mm) sizes += fmt::format("rim Ø {:.1f} mm   ", *m.rim_diameter_mm);
  if (m.rim_percent) sizes += fmt::format("rim {:.1f} %   ", *m.rim_percent);
  if (m.base_diameter_mm) sizes += fmt::format("base Ø {:.1f} mm   ", *m.base_diameter_mm);
  sizes += fmt::format("max Ø {:.1f} mm   height {:.1f} mm", m.max_diameter_mm, m.height_mm);
  if (m.volume_ml) sizes += fmt::format("   capacity {:.0f} ml", *m.volume_ml);  // complete vessels
  return {header_line(input), sizes,
          fmt::format("wall {:.1f}–{:.1f} mm (mean {:.1f})", m.wall_thickness_mm.min,
                      m.wall_thickness_mm.max, m.wall_thickness_mm.mean),
          scale_line(settings)};
}

// The sherd turned about its axis so that its arc starts at the meridian facing the viewer and
// extends to the exterior side, seen horizontally; the section on the other side.
PlateFiles axial_plate(const PlateInput& input, const PlateSettings& settings,
                       const LafortuneMaterial& material, const std::filesystem::path& dir) {
  const profile::Analysis& analysis = *input.analysis;
  const double exterior_side = settings.section_on_right ? -1.0 : 1.0;
  const Pose world_to_sherd = analysis.sherd_to_world.inverse();
  // The viewer looks along +y of the turned sherd frame, so the meridian facing it is at
  // azimuth −90°; the exterior half is x < 0 when the section is on the right.
  const auto [arc_start, arc_extent] = arc_of(*input.mesh, world_to_sherd);
  const double facing = -std::numbers::pi / 2;
  const double turn =
      settings.section_on_right ? facing - (arc_start + arc_extent) : facing - arc_start;
  Eigen::Matrix3d sherd_to_drawing;  // (x, y, z) → (u = x, v = z, towards viewer = −y)
  sherd_to_drawing << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  const Pose world_to_drawing =
      Pose(sherd_to_drawing) * Eigen::AngleAxisd(turn, Vec3d::UnitZ()) * world_to_sherd;

  const ProfileDrawing drawing = make_profile_drawing(analysis, settings.section_on_right);
  DrawingBounds content = drawing.bounds;
  DrawingBounds view = mesh_bounds(*input.mesh, world_to_drawing);
  if (exterior_side < 0)
    view.u_max = std::min(view.u_max, 0.0);
  else
    view.u_min = std::max(view.u_min, 0.0);
  content.include(view);
  const std::vector<std::string> lines = measurement_lines(input, settings);
  const double footer_v = content.v_min;
  reserve_footer(content, lines);
  const Canvas canvas = make_canvas(content, 25.4 / settings.dpi);

  PlacedCamera placed = camera_on(canvas, world_to_drawing, view);
  (exterior_side < 0 ? placed.camera.keep_x_max_mm : placed.camera.keep_x_min_mm) = 0.0;
  MeshRenderer exterior(*input.mesh, material, world_to_drawing, drawing_lighting());

  write_profile_svg(dir / "profile.svg", drawing, kMarginMm);
  return compose_plate(
      canvas, {{&exterior, placed}},
      [&](cairo_t* cr, const Canvas& band) {
        draw_profile(cr, drawing);
        draw_footer(cr, band, content.u_min, footer_v, lines);
        if (settings.rim_percent_diagram && analysis.measurements.rim_percent)
          draw_rim_diagram(cr, band, content.u_min, footer_v, *analysis.measurements.rim_percent);
      },
      settings, dir);
}

// No axis: the sherd seen square-on to its mean plane, front (the side its normals face) and
// back side by side.
PlateFiles body_plate(const PlateInput& input, const PlateSettings& settings,
                      const LafortuneMaterial& material, const std::filesystem::path& dir) {
  const Cloud& cloud = input.mesh->vertices;
  Vec3d centroid = Vec3d::Zero();
  for (const Vec3f& p : cloud.points) centroid += p.cast<double>();
  centroid /= static_cast<double>(cloud.size());
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (const Vec3f& p : cloud.points) {
    const Vec3d d = p.cast<double>() - centroid;
    covariance += d * d.transpose();
  }
  // Eigenvalues ascending: the last vector is the longest extent (drawn horizontally), the
  // first the mean-plane normal (the viewing direction).
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> pca(covariance);
  const Vec3d across = pca.eigenvectors().col(2);
  Vec3d towards_viewer = pca.eigenvectors().col(0);
  if (cloud.has_normals()) {
    Vec3d mean_normal = Vec3d::Zero();
    for (const Vec3f& n : cloud.normals) mean_normal += n.cast<double>();
    if (mean_normal.dot(towards_viewer) < 0) towards_viewer = -towards_viewer;
  }
  Eigen::Matrix3d front;
  front.row(0) = across.transpose();
  front.row(1) = towards_viewer.cross(across).transpose();
  front.row(2) = towards_viewer.transpose();
  const Eigen::Matrix3d back = Eigen::Vector3d(-1, 1, -1).asDiagonal() * front;  // turned about v

  Pose front_pose = Pose(front) * Eigen::Translation3d(-centroid);
  Pose back_pose = Pose(back) * Eigen::Translation3d(-centroid);
  const DrawingBounds front_bounds = mesh_bounds(*input.mesh, front_pose);
  // Place the back view to the right of the front view.
  const double shift = front_bounds.u_max + kViewGapMm - mesh_bounds(*input.mesh, back_pose).u_min;
  back_pose = Eigen::Translation3d(shift, 0, 0) * back_pose;
  const DrawingBounds back_bounds = mesh_bounds(*input.mesh, back_pose);
  DrawingBounds content = front_bounds;
  content.include(back_bounds);

  const std::string reason = input.analysis && !input.analysis->axis.reason.empty()
                                 ? input.analysis->axis.reason
                                 : "no axis of rotation";
  const std::vector<std::string> lines = {
      header_line(input), fmt::format("body sherd ({}): exterior front and back", reason),
      scale_line(settings)};
  const double caption_v = content.v_min - 4.0;  // baselines of "front" and "back"
  const double footer_v = content.v_min - 5.0;
  reserve_footer(content, lines);
  content.v_min -= 5.0;
  const Canvas canvas = make_canvas(content, 25.4 / settings.dpi);

  MeshRenderer front_view(*input.mesh, material, front_pose, drawing_lighting());
  MeshRenderer back_view(*input.mesh, material, back_pose, drawing_lighting());
  write_no_section_svg(dir / "profile.svg", reason);
  return compose_plate(
      canvas,
      {{&front_view, camera_on(canvas, front_pose, front_bounds)},
       {&back_view, camera_on(canvas, back_pose, back_bounds)}},
      [&](cairo_t* cr, const Canvas& band) {
        text(cr, band, front_bounds.u_min, caption_v, "front");
        text(cr, band, back_bounds.u_min, caption_v, "back");
        draw_footer(cr, band, content.u_min, footer_v, lines);
      },
      settings, dir);
}

}  // namespace

PlateFiles render_plate(const PlateInput& input, const PlateSettings& settings,
                        const std::filesystem::path& dir) {
  if (!input.mesh || input.mesh->empty())
    throw InputError(fmt::format("render: sherd '{}' of scan '{}' has no mesh to draw",
                                 input.sherd_id, input.scan_id));
  if (settings.dpi < kMinDpi || settings.dpi > kMaxDpi)
    throw InputError(fmt::format("render: dpi {} is outside {}…{}; set a plate dpi in that range",
                                 settings.dpi, kMinDpi, kMaxDpi));
  for (const Vec3f& p : input.mesh->vertices.points)
    if (!p.allFinite())
      throw InputError(
          fmt::format("render: sherd '{}' has a non-finite vertex; remove invalid "
                      "points first",
                      input.sherd_id));
  const LafortuneMaterial material = find_material(settings.materials_file, settings.material);
  std::error_code error;
  std::filesystem::create_directories(dir, error);
  if (error)
    throw ProcessingError(
        fmt::format("{}: cannot create the plate directory ({})", dir.string(), error.message()));
  if (input.analysis && input.analysis->axis.found)
    return axial_plate(input, settings, material, dir);
  return body_plate(input, settings, material, dir);
}

}  // namespace sherd::render
