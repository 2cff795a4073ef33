// A projector attached as a display on a headless station, driven through DRM/KMS (libdrm): the
// connector's preferred mode is set on a CRTC, and each pattern is written (grey → XRGB8888) into
// one of two full-screen dumb buffers and page-flipped onto the screen; show() returns once the
// flip has happened (the next vertical blank), so a camera triggered after it sees the pattern.
//
// Limits: needs DRM master on the card (no X11/Wayland session on it); no EGL/GPU path (the
// dumb buffer is written by the CPU: ~3 MB per 1024×768 pattern, well within a frame time);
// the flip time is the vblank's, not the projector's own display latency (measure it with the
// camera once, and lengthen the exposure or delay the trigger by that much). Built and tested
// here only as far as a machine without /dev/dri allows: the clear "no display" failures.
#pragma once

#include <memory>
#include <string>

#include "drivers/projector.h"

namespace sherd::drivers {

struct DrmProjectorSettings {
  std::string device = "/dev/dri/card0";
  std::string connector;  // "HDMI-A-1", "DP-2", …; "" = the first connected one
};

class DrmProjector : public Projector {
 public:
  // Throws DeviceError naming the device when it cannot be opened, is not a KMS device, has no
  // such connected connector (listing those it has), or cannot be driven (another display server
  // is its master).
  explicit DrmProjector(const DrmProjectorSettings& settings);
  ~DrmProjector() override;
  DrmProjector(const DrmProjector&) = delete;
  DrmProjector& operator=(const DrmProjector&) = delete;

  std::string describe() const override;
  int width() const override;
  int height() const override;
  // Throws DeviceError when the flip does not complete within a second.
  void show(std::span<const std::uint8_t> pixels) override;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace sherd::drivers
