// A GigE Vision / USB3 Vision camera through Aravis 0.8: Mono8, software or hardware (line)
// trigger per pattern, a
// pool of stream buffers, packet resend and an automatically sized socket buffer (GigE); frames
// with missing packets are dropped and the trigger repeated.
#pragma once

#include <memory>
#include <string>

#include "drivers/camera.h"

namespace sherd::drivers {

struct AravisCameraSettings {
  std::string id;             // Aravis device id ("Vendor-Model-Serial") or IP address; "" = first
  int width = 0, height = 0;  // region; 0 = the whole sensor
  int offset_x = 0, offset_y = 0;
  double exposure_us = 10000;
  double gain_db = 0;
  int buffers = 8;         // stream buffer pool
  int timeout_ms = 2000;   // per frame
  int max_recaptures = 3;  // incomplete frames tolerated per capture before failing
  // Per-frame trigger: kSoftware (capture() triggers) or kLine (a hardware line, e.g. the
  // projector's sync output, starts each frame: TriggerSource = trigger_line, TriggerActivation =
  // trigger_activation; capture() waits for the frame).
  enum class Trigger { kSoftware, kLine };
  Trigger trigger = Trigger::kSoftware;
  std::string trigger_line = "Line1";
  std::string trigger_activation = "RisingEdge";
};

class AravisCamera : public Camera {
 public:
  // Throws DeviceError naming the id when the camera cannot be found or configured.
  explicit AravisCamera(const AravisCameraSettings& settings);
  ~AravisCamera() override;
  AravisCamera(const AravisCamera&) = delete;
  AravisCamera& operator=(const AravisCamera&) = delete;

  std::string describe() const override;
  void arm() override;
  // Under a hardware trigger an incomplete frame cannot be triggered again: DeviceError.
  CameraFrame capture() override;
  // The current value of a GenICam string or enumeration feature ("TriggerSource", …), for
  // checks and diagnostics. Throws DeviceError when the camera has no such feature.
  std::string feature(const std::string& name) const;
  // Frames dropped so far because packets were missing (each was recaptured).
  int incomplete_frames() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace sherd::drivers
