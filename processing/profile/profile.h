// From a sherd and its axis to what an archaeologist records: the upright orientation, the
// outer and inner profile in the (radius, height) half-plane, and the measurements of sherd.json.
#pragma once

#include "core/types.h"
#include "processing/axis/axis.h"

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace sherd::profile {

using Polyline2 = std::vector<std::array<double, 2>>;  // (r, z) in mm, sherd frame

struct Profile {
  Polyline2 outer;  // from base end towards rim end
  Polyline2 inner;
  // The closed section: outer from base to rim end, then inner back from rim to base end (the
  // last vertex joins the first, across the lower end).
  Polyline2 section;
  double section_angle_rad =
      0.0;  // azimuth (about the axis, sherd frame) of the section half-plane
  // The aggregate profile: the skins' mean curves over the points of every azimuth (what the
  // axis refinement makes thin), from base end towards rim end; longer and less noisy than one
  // section. Its spread is the robust sd (1.4826 × median absolute distance) of the skin points
  // about these curves: the scanner's noise plus how far the sherd is from a surface of
  // revolution.
  Polyline2 aggregate_outer, aggregate_inner;
  double aggregate_spread_mm = 0.0;
};

struct WallThickness {
  double min = 0.0, mean = 0.0, max = 0.0;
};

struct Measurements {
  // Twice the largest outer-skin radius within Params::rim_band_mm below the highest profile
  // point: the outer diameter where the outer wall meets the lip (the simulator's truth, and what
  // a rim chart reads). Only for a sherd whose top end is a lip.
  std::optional<double> rim_diameter_mm;
  std::optional<double> base_diameter_mm;
  double max_diameter_mm = 0.0;
  double height_mm = 0.0;  // preserved height along the axis
  WallThickness wall_thickness_mm;
  std::optional<double> rim_percent;  // preserved rim arc / 360° × 100
  std::optional<double> rim_inclination_deg;
  std::optional<double> volume_ml;
};

// Standard deviations of the measurements that the axis's uncertainty causes: each measurement
// is taken again about the axis tilted by its angle sd and shifted by its offset sd (each in two
// perpendicular directions, sd/√2 apiece: the sds are of 2-D quantities), and the squared
// changes are summed (first-order propagation, the four parameters taken as independent). Null
// where the measurement is.
struct MeasurementSds {
  std::optional<double> rim_diameter_mm, base_diameter_mm, rim_percent, rim_inclination_deg;
  double max_diameter_mm = 0.0, height_mm = 0.0, wall_thickness_mean_mm = 0.0;
};

struct Analysis {
  axis::AxisEstimate axis;  // direction now points from base towards rim
  bool rim_up_certain = false;
  bool has_rim = false;   // the top end is a lip (never claimed for a break)
  bool has_base = false;  // the bottom end closes towards the axis or is a level underside / foot
  // Sherd frame → world: z along the axis (base → rim), origin = axis.point, x towards the section
  // half-plane.
  Pose sherd_to_world = Pose::Identity();
  double arc_deg = 0.0;  // angular extent of the sherd about the axis
  Profile profile;
  Measurements measurements;
  MeasurementSds measurement_sds;  // all zero when the axis has no sds or propagate_sds is off
};

struct Params {
  double section_half_width_deg = 2.0;  // slab of points around the section half-plane
  double rim_band_mm = 2.0;             // points this close below the rim height count as rim
  bool propagate_sds = true;            // measurement_sds (four more analyses about perturbed axes)
};

// Orients the axis (rim up), extracts the profile and measures. `axis.found` must be true.
Analysis analyse(const Cloud& sherd, const axis::AxisEstimate& axis, const Params& params = {});

}  // namespace sherd::profile
