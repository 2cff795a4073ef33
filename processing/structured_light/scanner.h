// The structured-light scanner as the station sees it (drivers::Scanner): the projector shows the
// Gray-code sequence, the camera captures each pattern, the frames are decoded and triangulated
// into one organised view in the camera frame (mm), grey colour from the white frame.
#pragma once

#include <memory>

#include "drivers/camera.h"
#include "drivers/projector.h"
#include "drivers/scanner.h"
#include "processing/structured_light/calibration.h"
#include "processing/structured_light/gray_code.h"
#include "processing/structured_light/triangulation.h"

namespace sherd::structured_light {

class StructuredLightScanner : public drivers::Scanner {
 public:
  // Camera and projector must outlive the scanner. Throws InputError when the projector's size
  // is not the calibrated one.
  StructuredLightScanner(drivers::Camera& camera, drivers::Projector& projector,
                         const ProCamCalibration& calibration, DecodeThresholds thresholds = {},
                         int threads = 2);

  std::string describe() const override;
  // Throws DeviceError when the camera fails or delivers frames of another size than calibrated.
  OrganisedView capture() override;

 private:
  drivers::Camera& camera_;
  drivers::Projector& projector_;
  GrayCodePatterns patterns_;
  std::vector<GreyImage> pattern_frames_;  // made once: the same sequence every capture
  DecodeThresholds thresholds_;
  int threads_;
  Triangulator triangulator_;
  int camera_width_, camera_height_;
};

}  // namespace sherd::structured_light
