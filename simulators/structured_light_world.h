// The structured-light world for the simulated station: what a calibrated camera films while a
// calibrated projector lights a scene (a table plane and pottery meshes). Each camera pixel's ray
// is cast into the scene once (StructuredLightWorld's constructor): the surface point it sees,
// where that point lands in the projector, whether the projector reaches it (shadows) and how much
// light it returns (albedo, incidence). Each frame then costs one pattern lookup per pixel:
//   grey = gain · albedo · (ambient + cos θ · blur_p(pattern)(projector position)) → blur_c + noise
// with projector defocus blur_p and camera blur blur_c (Gaussian), sensor noise Gaussian.
//
// SimulatedGigECamera serves those frames through Aravis's in-process simulated GigE Vision camera
// (127.0.0.1, UDP port 3956), so that the station's real camera driver, decoder and triangulation
// run on them.
#pragma once

#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <numbers>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "core/types.h"
#include "drivers/aravis_camera.h"
#include "drivers/projector.h"
#include "drivers/scanner.h"
#include "processing/structured_light/calibration.h"
#include "processing/structured_light/scanner.h"
#include "simulators/pottery.h"

namespace sherd::sim {

struct StructuredLightOptics {
  double gain = 230;               // grey level of a white surface fully lit head-on
  double ambient = 0.08;           // ambient light, as a share of the projector's full white
  double noise_grey = 1.0;         // sensor noise, standard deviation in grey levels
  double projector_blur_px = 0.4;  // projector defocus, Gaussian σ in projector pixels
  double camera_blur_px = 0.4;     // camera blur (optics, pixel area), Gaussian σ in camera pixels
  std::uint64_t seed = 1;          // sensor noise stream

  // The decoder's shadow threshold (DecodeThresholds::black) for this sensor. A pixel the
  // projector does not reach reads the same ambient light in the white and the black frame, so
  // its white − black is noise alone, σ = √2 · noise_grey; above 5.5 of those σ no such pixel
  // passes. A higher threshold drops lit surfaces at grazing incidence or of dark clay (white −
  // black = gain · albedo · cos θ), which decode: every bit still has to clear the `white`
  // threshold.
  int shadow_threshold() const {
    return static_cast<int>(std::ceil(5.5 * std::numbers::sqrt2 * noise_grey));
  }
};

// A plane n·X = d (camera frame, mm) of uniform albedo: the table or backdrop behind the objects.
struct BackgroundPlane {
  Vec3d normal = Vec3d::UnitZ();
  double offset_mm = 1000;
  double albedo = 0.6;
};

// Ground truth per camera pixel (row-major, camera size).
struct WorldTruth {
  std::vector<Vec3f> points;      // the surface point the pixel sees (camera frame); NaN: none
  std::vector<Vec3f> normals;     // its unit surface normal, towards the camera
  std::vector<std::uint8_t> lit;  // 1 where the projector reaches that point
};

class StructuredLightWorld {
 public:
  // `objects` in the camera frame (mm), vertex colours as albedo (grey = mean of r, g, b / 255);
  // without a background, rays that miss the objects see nothing (black).
  // Throws InputError when the calibration has no image sizes.
  StructuredLightWorld(const structured_light::ProCamCalibration& calibration,
                       const std::optional<BackgroundPlane>& background,
                       const std::vector<Mesh>& objects, const StructuredLightOptics& optics);

  int width() const { return calibration_.camera.width; }
  int height() const { return calibration_.camera.height; }
  const structured_light::ProCamCalibration& calibration() const { return calibration_; }
  const WorldTruth& truth() const { return truth_; }

  // The camera frame while the projector shows `pattern` (projector width × height, row-major);
  // `out` has width() × height() pixels. Thread-safe (the noise stream is locked).
  void render(std::span<const std::uint8_t> pattern, std::span<std::uint8_t> out) const;

 private:
  structured_light::ProCamCalibration calibration_;
  StructuredLightOptics optics_;
  WorldTruth truth_;
  // Per camera pixel: projector position (sub-pixel; x < 0 where unlit), and the grey levels the
  // ambient light and the full projector white give there.
  std::vector<float> projector_x_, projector_y_, ambient_grey_, lit_grey_;
  mutable std::mutex noise_mutex_;
  mutable std::uint64_t frames_rendered_ = 0;  // each frame its own noise stream
};

// A test and benchmark world: a vessel (simulators/vessel.h, from `seed`) standing on a table,
// seen by a camera of width × height pixels from 470 mm, 35° down, lit by a 1024 × 768 projector
// 250 mm to its right aimed at the same point. Camera and projector without lens distortion
// except a small radial k1 (−0.05 camera, −0.03 projector).
struct VesselOnTable {
  structured_light::ProCamCalibration calibration;
  BackgroundPlane table;
  std::vector<Mesh> objects;  // camera frame
};
VesselOnTable vessel_on_table(int camera_width, int camera_height, std::uint64_t seed);

// A camera + projector pair for a simulated station: the camera as given; the projector
// (width × height pixels, no distortion) at `projector_offset_mm` in the camera frame, aimed at
// `target_mm` (camera frame), its field `coverage` times the camera's across.
structured_light::ProCamCalibration procam_aimed_at(const structured_light::Intrinsics& camera,
                                                    const Vec3d& projector_offset_mm,
                                                    const Vec3d& target_mm, int projector_width,
                                                    int projector_height, double coverage = 1.5);

// Aravis's simulated GigE Vision camera on 127.0.0.1 (UDP 3956; one at a time per machine) whose
// frames are `world` under the pattern `projector` shows at the moment of the trigger. Open it
// with drivers::AravisCamera (id "127.0.0.1") at the world's size; the serial number names it.
class SimulatedGigECamera {
 public:
  // Throws DeviceError when port 3956 on 127.0.0.1 cannot be bound (another one running).
  SimulatedGigECamera(std::shared_ptr<const StructuredLightWorld> world,
                      const drivers::SimulatedProjector& projector,
                      const std::string& serial = "SHERDSL");
  ~SimulatedGigECamera();
  SimulatedGigECamera(const SimulatedGigECamera&) = delete;
  SimulatedGigECamera& operator=(const SimulatedGigECamera&) = delete;

  // Films `world` from the next frame on (same camera and projector sizes). Throws InputError
  // when the sizes differ.
  void set_world(std::shared_ptr<const StructuredLightWorld> world);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// The simulated station's structured-light scanner: the station's scene (simulators/pottery.h),
// with the plate turned to the turntable's physical angle, becomes a StructuredLightWorld at each
// capture (camera at `camera_to_world`, the true pose); the real scanner (Aravis driver on the
// simulated GigE camera, decoder, triangulation) captures it with `calibration` as its truth.
class SimulatedStructuredLightScanner : public drivers::Scanner {
 public:
  // Throws DeviceError when the simulated camera cannot start (UDP 3956 taken).
  SimulatedStructuredLightScanner(Scene scene, const Pose& camera_to_world,
                                  const structured_light::ProCamCalibration& calibration,
                                  const structured_light::ScannerOptions& options,
                                  const StructuredLightOptics& optics,
                                  std::function<double()> plate_angle);
  ~SimulatedStructuredLightScanner() override;
  std::string describe() const override;
  OrganisedView capture() override;
  // Replaces what lies on the plate. Not concurrently with capture().
  void set_scene(Scene scene) { scene_ = std::move(scene); }

 private:
  std::shared_ptr<const StructuredLightWorld> world_at(double plate_angle) const;

  Scene scene_;
  Pose camera_to_world_;
  structured_light::ProCamCalibration calibration_;
  StructuredLightOptics optics_;
  std::function<double()> plate_angle_;
  drivers::SimulatedProjector projector_;
  std::unique_ptr<SimulatedGigECamera> fake_;
  std::unique_ptr<drivers::AravisCamera> camera_;
  std::unique_ptr<structured_light::StructuredLightScanner> scanner_;
};

}  // namespace sherd::sim
