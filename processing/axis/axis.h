// The axis of rotation of a sherd. All normals of a surface of revolution meet its axis, so the
// axis is the line complex that the normal lines fit best (Pottmann & Wallner), inside RANSAC
// (fracture faces and noise are outliers), refined by Levenberg-Marquardt.
//
// A normal that is off by an angle e misses the axis by about R·sin(e) (R: the local radius), so
// scanner normals (a few degrees off at 0.05 mm depth noise and 0.5 mm spacing) miss a 100 mm
// axis by many millimetres. The input normals are therefore re-estimated first, by PCA over a
// neighbourhood a few point spacings wide (only neighbours whose input normals agree, so that the
// two skins of a thin wall never mix), and a normal line is judged by a tolerance that grows with
// the distance from its point to the axis (an angular tolerance plus a small distance floor).
#pragma once

#include "core/types.h"

#include <cstdint>
#include <string>

namespace sherd::axis {

struct AxisEstimate {
  bool found = false;
  Vec3d point = Vec3d::Zero();      // on the axis, closest to the sherd's centroid (world frame)
  Vec3d direction = Vec3d::UnitZ(); // unit; sign not yet decided (see profile::orient)
  std::string method;               // e.g. "normal-line-complex+ransac"
  double angle_sd_deg = 0.0;
  double offset_sd_mm = 0.0;
  double rms_mm = 0.0;              // RMS distance of inlier normal lines to the axis
  double inlier_share = 0.0;        // among the normal lines not near-parallel to the axis
  std::string reason;               // when !found: too few points, too flat, not rotational, …
};

struct Params {
  int ransac_iterations = 400;
  // A normal line is an inlier when it misses the axis by at most
  //   inlier_distance_mm + inlier_angle_deg (as a slope) × its point's distance along it to the axis:
  // the floor covers point noise, the angular part the residual normal error. On the simulated
  // station (bench_accuracy, 10 seeds) 0.5° drops good sherds, 1° leaves a 90th-percentile axis
  // error of 1.05°, 2° one of 0.48°.
  double inlier_distance_mm = 0.3;
  double inlier_angle_deg = 2.0;
  // Normal re-estimation: PCA radius (0 = from the data: normal_radius_spacings × the median
  // nearest-neighbour spacing, clamped to [1, 5] mm) and the largest angle between the input
  // normals of a point and of a neighbour that is used (the other skin is ~180° away).
  double normal_radius_mm = 0.0;
  double normal_radius_spacings = 6.0;
  double normal_agreement_deg = 40.0;
  double min_inlier_share = 0.5;
  std::uint64_t seed = 7;
  // A normal within this angle of the axis meets it only far away (flat lip, base underside,
  // horizontal break): its line distance says nothing about the axis position, so it is no inlier.
  double min_normal_axis_angle_deg = 10.0;
  // Normals that all lie within this RMS angle of one direction: a flat object, no axis.
  double flat_normal_spread_deg = 8.0;
  // A point fits the normal lines nearly as well as the axis (ratio of RMS distances below this):
  // sphere-like, every line through that point is an equally good axis.
  double sphere_rms_ratio = 2.0;
  int bootstrap_resamples = 30;
  double max_angle_sd_deg = 5.0;  // beyond: the axis is too poorly constrained to report
  std::size_t max_lines = 20000;  // larger clouds are subsampled (deterministically) first
};

// Needs normals (sherd.has_normals()).
AxisEstimate estimate_axis(const Cloud& sherd, const Params& params = {});

}  // namespace sherd::axis
