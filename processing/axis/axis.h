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

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/types.h"

namespace sherd::axis {

struct AxisEstimate {
  bool found = false;
  Vec3d point = Vec3d::Zero();       // on the axis, closest to the sherd's centroid (world frame)
  Vec3d direction = Vec3d::UnitZ();  // unit; sign not yet decided (see profile::orient)
  std::string method;                // e.g. "normal-line-complex+ransac"
  double angle_sd_deg = 0.0;
  double offset_sd_mm = 0.0;
  double rms_mm = 0.0;        // RMS distance of inlier normal lines to the axis
  double inlier_share = 0.0;  // among the normal lines not near-parallel to the axis
  // Refined method: robust sd (mm) of the skin points about the one profile all azimuths share
  // (each point against its neighbours in the (r, z) half-plane from other azimuths).
  double profile_spread_mm = 0.0;
  // … and against neighbours from the same azimuths: the scan's noise and the surface's roughness.
  double local_scatter_mm = 0.0;
  std::string reason;  // when !found: too few points, too flat, not rotational, …
};

struct Params {
  int ransac_iterations = 400;
  // A normal line is an inlier when it misses the axis by at most
  //   inlier_distance_mm + inlier_angle_deg (as a slope) × its point's distance along it to the
  //   axis:
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
  // The bounding box diagonal below which a piece is too small for an axis (the smallest sherd
  // bench_axis breaks is 30 mm across).
  double min_extent_mm = 20.0;
  int bootstrap_resamples = 30;
  double max_angle_sd_deg = 5.0;  // beyond: the axis is too poorly constrained to report
  std::size_t max_lines = 20000;  // larger clouds are subsampled (deterministically) first
};

// Needs normals (sherd.has_normals()).
AxisEstimate estimate_axis(const Cloud& sherd, const Params& params = {});

// The reference method: circle templates fitted into the sections of the sherd with sets of
// parallel planes; the axis is the line perpendicular to the planes through the circle centres,
// found where the centres align best (the least spread of the centres across the planes).
enum class ReferenceVariant {
  // Planes start perpendicular to the world z axis: the sherd stands upright within ~20°.
  SemiAutomatic,
  // Two stages from the balancing plane (best-fit plane of the inner side): the in-plane direction
  // whose sections' centres align best lies in the plane of symmetry; the plane set is then
  // turned within that plane until the centres align best.
  Automatic,
};
struct ReferenceParams {
  ReferenceVariant variant = ReferenceVariant::Automatic;
  int sections = 9;                 // planes across the sherd's extent along the plane normal
  double slab_half_width_mm = 0.4;  // points this close to a plane belong to its section
  int min_section_points = 20;
};
AxisEstimate estimate_axis_reference(const Cloud& sherd, const ReferenceParams& params = {});

// Profile-consistency refinement: the 4-DOF axis for which the points of all azimuths, mapped into
// the (radius, height) half-plane, fall onto one thin profile curve (inner and outer skin), by
// Levenberg-Marquardt with a robust (Cauchy) loss on each point's distance to the mean of its
// neighbours in that half-plane from other azimuths (along its normal). Fracture faces (normals out
// of the half-plane) are down-weighted. angle_sd_deg / offset_sd_mm from a delete-a-group
// jackknife over azimuth sectors × height bands (each replica refits without one group's points),
// scaled so that ±2 sd is a 95 % interval (Student's t for the jackknife's few degrees of freedom).
struct RefineParams {
  std::size_t max_points = 4000;  // subsampled (deterministically) above this
  // Neighbourhoods are re-found from the axis of each round: at least min_rounds, then until a
  // round's step is below both settled_* (a hundredth of a degree, a hundredth of a millimetre),
  // at most max_rounds.
  int min_rounds = 3;
  int max_rounds = 8;
  double settled_tilt_rad = 1.7e-4;
  double settled_shift_mm = 0.01;
  // Neighbourhood window in the half-plane: along the profile; across it, first round, then
  // 6 robust sds of the spread about the last round's axis, but no less than min_across_mm.
  double along_mm = 1.0;
  double first_across_mm = 3.0;
  double min_across_mm = 0.5;
  int max_neighbours = 30;
  // A skin point has an opposite-facing partner straight through the wall within max_wall_mm;
  // points without one (fracture faces, the lip) weigh fracture_weight.
  double max_wall_mm = 15.0;
  double fracture_weight = 0.1;
  double max_move_deg = 10.0;  // a refinement that turns the axis further diverged
  // Groups left out in turn for the sds: azimuth sectors × height bands. Residuals are correlated
  // along the arc and along the profile (a wandering lip, a pulling break), so both are cut.
  int jackknife_sectors = 4;
  int jackknife_bands = 2;
  double max_angle_sd_deg = 5.0;  // beyond: the axis is too poorly constrained to report
  // Not wheel-made (refine.cpp, judge_wheel_made): the points spread about the profile common to
  // all azimuths more than max_spread_ratio × their scatter about their own azimuth's, and more
  // than max_excess_spread_mm beyond it — 1.5 × the largest depth noise the station is specified
  // for (0.1 mm). Simulated wheel-made sherds stay below ratio 1.2; ±4 mm lobes give 1.9–4.3.
  double max_spread_ratio = 1.5;
  double max_excess_spread_mm = 0.15;
  std::uint64_t seed = 11;
};
AxisEstimate refine_axis(const Cloud& sherd, const AxisEstimate& start,
                         const RefineParams& params = {});

// The methods, selectable by name (config, bench): normal-lines (estimate_axis), reference-semi /
// reference-auto (estimate_axis_reference), refined (normal lines, then refine_axis; the default).
enum class Method { NormalLines, ReferenceSemiAutomatic, ReferenceAutomatic, Refined };
AxisEstimate estimate(const Cloud& sherd, Method method);
const char* to_string(Method method);
std::optional<Method> method_from_string(const std::string& name);
std::vector<Method> all_methods();
std::string method_names();  // "normal-lines, reference-semi, …" for messages

}  // namespace sherd::axis
