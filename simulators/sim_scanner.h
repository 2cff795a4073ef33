// A simulated structured-light scanner: ray-casts the synthetic scene from its calibrated pose,
// with the plate turned to the simulated turntable's physical angle, and a structured-light noise
// model (depth noise, dropouts at grazing angles, projector shadowing and occlusion, finite
// resolution, colour per surface).
#pragma once

#include "core/types.h"
#include "drivers/scanner.h"
#include "simulators/pottery.h"

#include <cstdint>
#include <functional>
#include <vector>

namespace sherd::sim {

struct ScannerModel {
  int width = 640, height = 480;
  double fx = 800.0, fy = 800.0, cx = 319.5, cy = 239.5;
  Pose scanner_to_world = Pose::Identity();  // true pose of the scanner (camera) in the world
  Vec3d projector_offset_mm{120.0, 0.0, 0.0};  // projector centre in the scanner frame
  double depth_noise_mm = 0.05;
  double grazing_limit_deg = 78.0;
  double dropout_fraction = 0.01;
  std::uint64_t seed = 1;
};

// The camera pose from an optical centre and a look-at point, image "up" towards world +z.
// Throws InputError when eye == target or the view is straight up/down (no "up" then).
Pose look_at_pose(const Vec3d& eye, const Vec3d& target);

// How far a physically mounted scanner is off its nominal (configured) pose: a rotation of
// `tilt_deg` about an axis through its optical centre and a shift of `offset_mm` of that centre,
// both in directions drawn from `seed`. The station believes the nominal pose until calibrated.
struct MountingError {
  double tilt_deg = 0.0;
  double offset_mm = 0.0;
  std::uint64_t seed = 1;
};

// The physical pose of a scanner whose nominal pose is `nominal`. Zero error gives `nominal`.
Pose mounted_pose(const Pose& nominal, const MountingError& error);

// The default station's scanner (config defaults): 640×480, fx = fy = 800, camera at
// (0, −420, 260) mm looking at (0, 0, 50) mm; noise model as in ScannerModel.
ScannerModel default_station_scanner();

class SimulatedScanner : public drivers::Scanner {
 public:
  // `plate_angle` returns the turntable's physical angle in radians at capture time.
  SimulatedScanner(Scene scene, ScannerModel model, std::function<double()> plate_angle);
  std::string describe() const override;
  OrganisedView capture() override;

  // Replaces what lies on the plate (e.g. the calibration object for a calibration scan). Not
  // concurrently with capture().
  void set_scene(Scene scene) { scene_ = std::move(scene); }

  // Ground-truth label of every cell of the last capture: k = scene.truth[k-1] for a valid cell
  // on sherd (or vessel) k; 0 for the background and for cells without a measurement.
  const std::vector<int>& last_labels() const { return last_labels_; }

 private:
  Scene scene_;
  ScannerModel model_;
  std::function<double()> plate_angle_;
  std::vector<int> last_labels_;
  std::uint64_t captures_ = 0;
};

}  // namespace sherd::sim
