#include "processing/structured_light/scanner.h"

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <span>

#include "core/errors.h"

namespace sherd::structured_light {
namespace {
// Grid neighbours further apart than this lie across a depth jump, not on one surface (a camera
// pixel spans well under a millimetre at a scanner's working distance).
constexpr float kMaxNormalEdgeMm = 3.0f;
}  // namespace

StructuredLightScanner::StructuredLightScanner(drivers::Camera& camera,
                                               drivers::Projector& projector,
                                               const ProCamCalibration& calibration,
                                               const ScannerOptions& options)
    : camera_(camera),
      projector_(projector),
      options_(options),
      gray_{projector.width(), projector.height()},
      phase_{projector.width(), projector.height(), options.phase_period_px, options.phase_steps},
      triangulator_(calibration),
      camera_width_(calibration.camera.width),
      camera_height_(calibration.camera.height) {
  if (projector.width() != calibration.projector.width ||
      projector.height() != calibration.projector.height)
    throw InputError(
        fmt::format("structured-light scanner: the projector is {}x{}, the "
                    "calibration is for {}x{}; calibrate this projector",
                    projector.width(), projector.height(), calibration.projector.width,
                    calibration.projector.height));
  if (options.patterns == PatternSet::kPhase &&
      (options.phase_period_px < 4 || options.phase_steps < 3))
    throw InputError(fmt::format(
        "structured-light scanner: phase period {} px and {} steps; use a period of at least 4 "
        "projector pixels and at least 3 steps",
        options.phase_period_px, options.phase_steps));
  for (int f = 0; f < gray_.frame_count(); ++f) pattern_frames_.push_back(gray_.frame(f));
  if (options.patterns == PatternSet::kPhase)
    for (int k = 0; k < phase_.steps; ++k) pattern_frames_.push_back(phase_.frame(k));
}

std::string StructuredLightScanner::describe() const {
  return fmt::format(
      "structured light ({}): {} + {}",
      options_.patterns == PatternSet::kPhase ? "Gray code + phase shift" : "Gray code",
      camera_.describe(), projector_.describe());
}

OrganisedView StructuredLightScanner::capture() {
  std::vector<GreyImage> frames;
  frames.reserve(pattern_frames_.size());
  for (const GreyImage& pattern : pattern_frames_) {
    camera_.arm();
    projector_.show(pattern.pixels);
    drivers::CameraFrame frame = camera_.capture();
    if (frame.width != camera_width_ || frame.height != camera_height_)
      throw DeviceError(
          fmt::format("structured-light scanner: the camera delivers {}x{} frames, "
                      "the calibration is for {}x{}; set the camera region",
                      frame.width, frame.height, camera_width_, camera_height_));
    frames.push_back({frame.width, frame.height, std::move(frame.pixels)});
  }
  const std::span<const GreyImage> all(frames);
  DecodedMap map =
      decode(gray_, all.first(gray_.frame_count()), options_.thresholds, options_.threads);
  // Stripe edges first: with phase shifting they stand where the fringes are too faint.
  refine_columns_at_edges(gray_, all.first(gray_.frame_count()), map);
  if (options_.patterns == PatternSet::kPhase)
    refine_columns(phase_, all.subspan(gray_.frame_count()), options_.min_modulation, map);
  TriangulatedView view =
      triangulator_.triangulate(map, &frames[gray_.white_frame()], options_.threads);
  if (options_.max_ray_gap_mm > 0)
    for (std::size_t i = 0; i < view.view.cells(); ++i)
      if (view.view.valid[i] && !(view.ray_gap_mm[i] <= options_.max_ray_gap_mm)) {
        view.view.valid[i] = 0;
        view.view.points[i] = Vec3f::Constant(std::nanf(""));
      }
  estimate_grid_normals(view.view, kMaxNormalEdgeMm);
  view.view.timestamp_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                               std::chrono::system_clock::now().time_since_epoch())
                               .count();
  return std::move(view.view);
}

}  // namespace sherd::structured_light
