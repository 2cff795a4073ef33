// Turntable calibration: the turntable's axis of rotation (direction and a point) in the scanner
// frame, from a scan of the calibration object — a printed disc carrying spheres of different
// diameters on posts. Per view each sphere is found and fitted; then one joint least-squares fit
// says where the axis must be so that every sphere's centres, turned back by their encoder angles,
// coincide. The result defines the world (= turntable) frame of every later scan.
#pragma once

#include "core/types.h"

#include <nlohmann/json_fwd.hpp>

#include <array>
#include <filesystem>
#include <string>
#include <vector>

namespace sherd::calibration {

// One sphere of the calibration object, on a post standing on the disc's top face.
struct CalibrationSphere {
  double radius_mm;
  double distance_mm;     // of the post's axis from the disc centre
  double azimuth_deg;     // of the post about the disc centre, counter-clockwise from the disc's +x
  double height_mm;       // of the sphere's centre above the disc's top face
};

// The calibration object. Every sphere has a different radius, so that each is recognised by its
// fitted radius alone; posts, radii and heights are chosen so that a scanner looking down at about
// 25–30° sees at least three spheres unoccluded at every turntable angle.
struct CalibrationObject {
  double disc_radius_mm;
  double disc_thickness_mm;  // the disc lies on the plate: sphere centres stand this much higher
  double post_radius_mm;
  std::array<CalibrationSphere, 4> spheres;
};

// The station's calibration object (see README, "Turntable calibration"): print it in matte,
// light grey material; the sphere diameters matter most (check them with a calliper).
inline constexpr CalibrationObject kCalibrationObject{
    80.0, 5.0, 4.0,
    {{{10.0, 62.0, 0.0, 25.0},
      {12.5, 30.0, 110.0, 60.0},
      {15.0, 58.0, 215.0, 40.0},
      {17.5, 45.0, 300.0, 85.0}}}};

// One capture of the calibration scan: the organised view (scanner frame) and the encoder angle
// of the plate when it was taken.
struct CalibrationView {
  const OrganisedView* view = nullptr;
  double angle_rad = 0.0;
};

struct TurntableCalibration {
  Vec3d axis_direction = Vec3d::UnitZ();  // unit, scanner frame, up (away from the plate)
  Vec3d axis_point_mm = Vec3d::Zero();    // the axis on the plate's top surface, scanner frame
  // 1σ from the least-squares covariance scaled by the residual variance: the direction's tilt
  // (both tilt angles together), the point across the axis (both directions together) and along it.
  double direction_sd_deg = 0.0;
  double point_sd_mm = 0.0;
  double height_sd_mm = 0.0;
  double rms_residual_mm = 0.0;  // of the sphere centres about the fitted motion
  int views_used = 0;
  int spheres_used = 0;          // distinct spheres of the object
  int centres_used = 0;          // sphere centres in the final fit
  int centres_rejected = 0;      // found but left out as outliers

  // World (= turntable) frame from the scanner frame: z along the axis, up; origin on the axis at
  // the plate's top surface; azimuth such that the scanner's optical centre lies in the plane
  // x = 0 at y < 0 (as the configured nominal pose has it).
  Pose scanner_to_world() const;
};

struct EstimatorParams {
  int min_views = 3;                 // with distinct angles
  double sphere_tolerance_mm = 1.0;  // |fitted − known radius| to recognise a sphere
  double outlier_factor = 5.0;       // a centre further than this × robust σ from the fit is dropped
};

// Throws InputError for missing/invalid views or angles (NaN, all at one angle, too few) and
// ProcessingError when too few spheres are found to fit the axis.
TurntableCalibration estimate_turntable_axis(const std::vector<CalibrationView>& views,
                                             const CalibrationObject& object = kCalibrationObject,
                                             const EstimatorParams& params = {});

// The result as a JSON document ("sherdscan.turntable_calibration/1") and back. from_json throws
// InputError naming `where` when a field is missing or invalid.
nlohmann::json to_json(const TurntableCalibration& calibration);
TurntableCalibration turntable_calibration_from_json(const nlohmann::json& document,
                                                     const std::string& where);

// Writes the document, with the fields of `extra` (an object: where and when it was made) added,
// atomically (a temporary file renamed over `file`, directories created).
void write_turntable_calibration(const std::filesystem::path& file,
                                 const TurntableCalibration& calibration,
                                 const nlohmann::json& extra);
// Reads a file written by write_turntable_calibration. InputError naming the file, and saying to
// re-run `sherdctl calibrate turntable`, when it is unreadable or corrupt.
TurntableCalibration read_turntable_calibration(const std::filesystem::path& file);

}  // namespace sherd::calibration
