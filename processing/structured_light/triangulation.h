// Triangulation of decoded camera pixels into an organised point grid in the camera frame (mm).
// The camera and projector rays depend only on the calibration, so they are undistorted once per
// calibration (Triangulator's constructor); each scan then costs one ray–ray intersection per
// decoded pixel.
#pragma once

#include <vector>

#include "core/types.h"
#include "processing/structured_light/calibration.h"
#include "processing/structured_light/gray_code.h"

namespace sherd::structured_light {

struct TriangulatedView {
  OrganisedView view;                  // camera frame, mm; colour from the white frame
  std::vector<float> ray_gap_mm;       // per cell: distance between camera and projector rays
};

class Triangulator {
 public:
  // Throws InputError when the calibration has no image sizes.
  explicit Triangulator(const ProCamCalibration& calibration);

  // `white` (optional, same size as the map) colours the points grey.
  TriangulatedView triangulate(const DecodedMap& map, const GreyImage* white = nullptr,
                               int threads = 2) const;

 private:
  ProCamCalibration calibration_;
  Eigen::Vector3d projector_centre_;  // in the camera frame
  // Unit-free ray directions (x, y, 1) per camera pixel (camera frame) and per projector pixel
  // (rotated into the camera frame), row-major.
  std::vector<Eigen::Vector3f> camera_rays_, projector_rays_;
};

}  // namespace sherd::structured_light
