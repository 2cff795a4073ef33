// A machine-vision camera as the structured-light scanner sees it: one trigger, one 8-bit grey
// frame. Implementation: AravisCamera (GigE Vision / USB3 Vision through Aravis 0.8).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace sherd::drivers {

struct CameraFrame {
  int width = 0, height = 0;
  std::vector<std::uint8_t> pixels;  // Mono8, row-major
  std::uint64_t frame_id = 0;        // the camera's block id
  std::uint64_t timestamp_ns = 0;    // the camera's clock
};

class Camera {
 public:
  virtual ~Camera() = default;
  virtual std::string describe() const = 0;
  // Discards frames already queued: call before whatever starts the next frame (the projector
  // showing its pattern, whose sync output may trigger a hardware-triggered camera).
  virtual void arm() {}
  // Triggers (software trigger) or awaits (hardware trigger) and returns one complete frame. Throws
  // DeviceError (timeout, link lost, too many incomplete frames); never returns a partial or stale
  // frame.
  virtual CameraFrame capture() = 0;
};

}  // namespace sherd::drivers
