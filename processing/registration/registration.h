// Fusing the turntable views of one scan into one consistent set of poses in the world
// (= turntable) frame, in two stages:
//  1. Pairwise: every pair of views that overlaps at the turntable prior (neighbours, the loop
//     closure last → first, and any other pair with enough overlap) is refined by point-to-plane
//     ICP — plus a photometric term where the views carry colour — on downsampled clouds with
//     trimmed correspondences. Directions the pair's equations cannot constrain (the rotation of a
//     wheel-made pot about its own axis) keep the prior instead of drifting.
//  2. Global: all views in one pose graph — each pair's result as a relative-pose edge weighted by
//     its information matrix, each view's turntable prior as a unary factor weighted by the prior's
//     uncertainty — solved by Gauss-Newton, so the error is spread over the loop rather than
//     accumulated; edges inconsistent with the rest are dropped.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "core/types.h"

namespace sherd::registration {

// The prior pose (scanner frame → world frame at turntable angle 0) of a view captured with the
// plate at `turntable_angle_rad`: p_world = Rz(−angle) · scanner_to_world · p_scanner.
Pose turntable_prior(const Pose& scanner_to_world, double turntable_angle_rad);

struct ViewInput {
  const OrganisedView* view = nullptr;
  Pose prior = Pose::Identity();
};

// How well the turntable prior places a view (standard deviations): the encoder for the rotation
// about the turntable axis, the turntable calibration for the axis's direction and position.
// Where the geometry cannot see a direction, the prior holds it with this weight.
struct PriorUncertainty {
  double angle_sd_deg = 0.1;       // rotation about the turntable (world z) axis
  double tilt_sd_deg = 0.05;       // rotation about the horizontal world axes
  double translation_sd_mm = 0.2;  // position
};

struct Params {
  bool refine_with_icp = true;
  // Add a photometric term where both views of a neighbouring pair have colour (Park, Zhou &
  // Koltun, ICCV 2017), restricted to the directions the geometry cannot constrain: the clay's
  // texture can fix the rotation about a pot's axis that its shape cannot, and leaves alone what
  // the shape sees. A pair whose colour moves it about a silent axis further than three standard
  // deviations of the priors' difference is a false texture match: that pair is refined without
  // colour. The texture's grains are a few millimetres across: the term needs voxel_mm ≈ 0.5 to
  // see them (measured, bench_registration --seeds 2 --scenes vessel, textured simulated vessels:
  // median rotation error 0.07° at 1 mm, 0.015° at 0.5 mm; the prior's 0.31°).
  bool use_colour = true;
  // The colour sees a direction the geometry cannot when its equations alone pin the view there
  // to this standard deviation (a rotation's as the displacement at the view's RMS radius); else
  // the prior holds it. Measured on simulated vessels: ~0.04 mm from a pair of textured views.
  double colour_max_sd_mm = 0.1;
  // A pair of views becomes an edge when this share of the source's points has a neighbour in the
  // target at the prior (within the coarse correspondence distance).
  double min_edge_overlap = 0.1;
  // Besides its neighbours, each view keeps at most this many further edges (the best overlaps).
  int max_extra_edges_per_view = 2;
  double voxel_mm = 1.0;
  double max_correspondence_mm = 3.0;
  int max_iterations = 40;
  double max_correction_deg = 3.0;  // correction from the prior beyond these is flagged
  double max_correction_mm = 5.0;
  // ICP iterates on a fixed random sample of at most this many of the view's voxel points
  // (point-to-plane needs far fewer than a full view to pin six degrees of freedom); the
  // figures in ViewResult are measured on all of them.
  int icp_max_points = 4000;
  // Directions of the point-to-plane normal equations whose eigenvalue is below
  // degenerate_eigenvalue_ratio × the largest (rotations scaled by the view's RMS radius, so that
  // 1 rad ≈ that many mm) are degenerate: each update leaves the view's rotation about such a
  // direction's axis (or translation along it) as the prior has it. Off: plain point-to-plane ICP,
  // free to slide. Measured: a surface of revolution ~3e-5, an asymmetric box whose sliding
  // along a face only two bumps fix ~0.012 (it must stay refined).
  bool keep_prior_in_degenerate_directions = true;
  double degenerate_eigenvalue_ratio = 0.005;
  // In the final ICP stage each pair of points pulls with weight (cos θ_source · cos θ_target)²,
  // θ the angle between the surface normal and the ray to the scanner, where the scanner measures
  // grazing surfaces worse (a triangulating scanner's pattern loses contrast and smears over a
  // wider footprint there; its normals rest on sparser points). Measured (bench_registration):
  // the Stanford bunny's median 0.136° → 0.096° (over seven ICP samples 0.136° → 0.096°, every one
  // better), the station's simulated vessels 0.015° → 0.010°. Off by default: on an idealised
  // scanner whose noise along the ray does not grow (SyntheticTurntable.RecoversPerturbedPriors),
  // it weakens the grazing faces' hold and costs accuracy (worst view 0.024° → 0.078°); the
  // station turns it on ([registration] weight_by_incidence). Only the final stage: in the coarse
  // ones it cost the bunny's 10°-off bun045 its alignment on one sample of seven.
  bool weight_by_incidence = false;
  // Where the scanner saw each view's points from, in the view's own frame: by default along each
  // point's ray to the frame's origin, the camera's optical centre (the station's scanner frame is
  // its camera's). A scanner whose rays are parallel (a laser stripe swept along a line, as the
  // Cyberware of the Stanford scans) gives the direction towards it instead.
  std::optional<Vec3d> parallel_rays_towards_scanner;
};

// A direction of a pose that the geometry could not constrain, in the last ICP iteration.
struct DegenerateDirection {
  // The world axis this direction mostly is: "rot_x", "rot_y", "rot_z" (rotation about an axis
  // through the view's centroid) or "trans_x", "trans_y", "trans_z".
  std::string name;
  // Unit twist (rotation in rad × rms_radius_mm, translation in mm), world axes, about the view's
  // centroid at its prior.
  // A plain array keeps Eigen's alignment rules out of this public struct.
  std::array<double, 6> twist{};
  double eigenvalue_ratio = 0.0;  // its eigenvalue over the largest one
};

// One pair of views: `source` registered onto `target` (both at their priors).
struct EdgeResult {
  int target = 0, source = 0;
  bool neighbours = false;  // consecutive turntable stops (or the loop closure last → first)
  double overlap_at_prior = 0.0;
  // "accepted", "implausible_correction" (ICP's relative correction beyond the limits),
  // "not_converged" (ICP lost its correspondences), "inconsistent" (dropped by the global solve:
  // it disagrees with the other edges and the priors)
  std::string status;
  double rms_mm = 0.0;   // point-to-plane RMS at the pair's ICP result
  double overlap = 0.0;  // share of the source's points with a correspondence there
  int iterations = 0;
  bool used_colour = false;
  double correction_deg = 0.0;  // the source's correction relative to the target, from the prior
  double correction_mm = 0.0;   // (at the source's centroid)
  // The pair's result: source's scanner frame → target's scanner frame.
  Pose relative = Pose::Identity();
  std::vector<DegenerateDirection> degenerate;
};

struct ViewResult {
  Pose pose = Pose::Identity();  // final scanner → world
  // Measured at the final poses against the views it shares accepted edges with.
  double rms_mm = 0.0;          // point-to-plane RMS over the correspondences
  double overlap = 0.0;         // share of the view's points with a correspondence
  int iterations = 0;           // ICP iterations over the view's edges
  double correction_deg = 0.0;  // rotation between prior and final pose
  double correction_mm = 0.0;   // displacement of the view's centroid between prior and final pose
  double about_z_deg = 0.0;     // the correction's part about the world z (turntable) axis, signed
  // Standard deviations of the final pose from the global solve: rotation about the turntable
  // axis, tilt, translation of the view's centroid.
  double angle_sd_deg = 0.0, tilt_sd_deg = 0.0, translation_sd_mm = 0.0;
  double rms_radius_mm = 0.0;  // RMS distance of the view's points from their centroid
  int edges = 0;               // accepted edges
  // The fused model takes this view: false for "empty", "no_overlap", "implausible_correction" and
  // "not_converged" views, which stay at their prior and are left out rather than merged blindly.
  bool merged = false;
  // Directions that none of the view's accepted edges constrains: held by the turntable prior.
  std::vector<DegenerateDirection> degenerate;
  // "empty" (no valid cell), "no_overlap" (no other view overlaps it at the prior),
  // "implausible_correction" (every edge's correction beyond max_correction_deg/mm, or the global
  // solve moved it that far from its prior), "not_converged" (ICP lost its correspondences on all
  // its edges), "degenerate:<name>" for each degenerate direction (refined in the others only).
  std::vector<std::string> flags;
};

struct Result {
  std::vector<ViewResult> views;
  std::vector<EdgeResult> edges;
  int graph_iterations = 0;
};

// Views are in turntable order (view i and i + 1 are neighbours, the last closes the loop onto the
// first). Throws sherd::InputError for a malformed view (sizes that do not match width × height, a
// valid cell that is not finite), a non-finite prior, non-positive parameters or uncertainties.
Result register_views(const std::vector<ViewInput>& views,
                      const PriorUncertainty& prior_uncertainty, const Params& params);

}  // namespace sherd::registration
