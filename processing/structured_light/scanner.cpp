#include "processing/structured_light/scanner.h"

#include <fmt/format.h>

#include <chrono>

#include "core/errors.h"

namespace sherd::structured_light {

StructuredLightScanner::StructuredLightScanner(drivers::Camera& camera,
                                               drivers::Projector& projector,
                                               const ProCamCalibration& calibration,
                                               DecodeThresholds thresholds, int threads)
    : camera_(camera),
      projector_(projector),
      patterns_{projector.width(), projector.height()},
      thresholds_(thresholds),
      threads_(threads),
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
  for (int f = 0; f < patterns_.frame_count(); ++f) pattern_frames_.push_back(patterns_.frame(f));
}

std::string StructuredLightScanner::describe() const {
  return fmt::format("structured light: {} + {}", camera_.describe(), projector_.describe());
}

OrganisedView StructuredLightScanner::capture() {
  std::vector<GreyImage> frames;
  frames.reserve(pattern_frames_.size());
  for (const GreyImage& pattern : pattern_frames_) {
    projector_.show(pattern.pixels);
    drivers::CameraFrame frame = camera_.capture();
    if (frame.width != camera_width_ || frame.height != camera_height_)
      throw DeviceError(
          fmt::format("structured-light scanner: the camera delivers {}x{} frames, "
                      "the calibration is for {}x{}; set the camera region",
                      frame.width, frame.height, camera_width_, camera_height_));
    frames.push_back({frame.width, frame.height, std::move(frame.pixels)});
  }
  const DecodedMap map = decode(patterns_, frames, thresholds_, threads_);
  TriangulatedView view =
      triangulator_.triangulate(map, &frames[patterns_.white_frame()], threads_);
  view.view.timestamp_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                               std::chrono::system_clock::now().time_since_epoch())
                               .count();
  return std::move(view.view);
}

}  // namespace sherd::structured_light
