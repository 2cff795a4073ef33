// A GigE Vision / USB3 Vision camera through Aravis 0.8: Mono8, software trigger per pattern, a
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
};

class AravisCamera : public Camera {
 public:
  // Throws DeviceError naming the id when the camera cannot be found or configured.
  explicit AravisCamera(const AravisCameraSettings& settings);
  ~AravisCamera() override;
  AravisCamera(const AravisCamera&) = delete;
  AravisCamera& operator=(const AravisCamera&) = delete;

  std::string describe() const override;
  CameraFrame capture() override;
  // Frames dropped so far because packets were missing (each was recaptured).
  int incomplete_frames() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace sherd::drivers
