// Fusing the turntable views of one scan into one model in the world (= turntable) frame.
// Each view is placed by the turntable prior (calibrated scanner pose and encoder angle) and
// refined by point-to-plane ICP against the union of the views already placed. Directions the
// geometry cannot constrain (the rotation of a wheel-made pot about its own axis) keep the prior.
#pragma once

#include "core/types.h"

#include <array>
#include <string>
#include <vector>

namespace sherd::registration {

// The prior pose (scanner frame → world frame at turntable angle 0) of a view captured with the
// plate at `turntable_angle_rad`: p_world = Rz(−angle) · scanner_to_world · p_scanner.
Pose turntable_prior(const Pose& scanner_to_world, double turntable_angle_rad);

struct ViewInput {
  const OrganisedView* view = nullptr;
  Pose prior = Pose::Identity();
};

struct Params {
  bool refine_with_icp = true;
  double voxel_mm = 1.0;
  double max_correspondence_mm = 3.0;
  int max_iterations = 40;
  double max_correction_deg = 3.0;  // correction from the prior beyond these is flagged
  double max_correction_mm = 5.0;
  float mesh_max_edge_mm = 3.0f;  // organised triangulation: longer edges are depth jumps
  // A view whose share of points near the placed views (at its prior, within
  // max_correspondence_mm + max_correction_mm) is below this is flagged "no_overlap".
  double min_overlap = 0.1;
  // ICP iterates on a fixed random sample of at most this many of the view's voxel points
  // (point-to-plane needs far fewer than a full view to pin six degrees of freedom); the
  // figures in ViewResult are measured on all of them.
  int icp_max_points = 10000;
  // Directions of the point-to-plane normal equations whose eigenvalue is below
  // degenerate_eigenvalue_ratio × the largest (rotations scaled by the view's RMS radius, so that
  // 1 rad ≈ that many mm) are degenerate: each update leaves the view's rotation about such a
  // direction's axis (or translation along it) as the prior has it. Off: plain point-to-plane ICP,
  // free to slide. Measured: a surface of revolution ~3e-5, an asymmetric box whose sliding
  // along a face only two bumps fix ~0.012 (it must stay refined).
  bool keep_prior_in_degenerate_directions = true;
  double degenerate_eigenvalue_ratio = 0.005;
};

// A direction of a view's pose that the geometry could not constrain, in the last ICP iteration.
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

struct ViewResult {
  Pose pose = Pose::Identity();  // final scanner → world
  double rms_mm = 0.0;           // point-to-plane RMS over accepted correspondences
  double overlap = 0.0;          // share of the view's points with a correspondence
  int iterations = 0;
  double correction_deg = 0.0;  // rotation between prior and final pose
  double correction_mm = 0.0;   // translation between prior and final pose (world origin)
  // What ICP proposed, kept even when rejected ("implausible_correction"): total rotation,
  // its part about the world z axis (the turntable axis, where near-symmetric pots let ICP slide),
  // and the displacement of the world origin.
  double proposed_correction_deg = 0.0;
  double proposed_about_z_deg = 0.0;
  double proposed_correction_mm = 0.0;
  bool refined = false;  // false: the prior was kept
  double rms_radius_mm = 0.0;  // RMS distance of the view's points from their centroid
  // With the handling on, the view keeps the prior's rotation about each "rot_*" direction's axis
  // and its translation along each "trans_*" one.
  std::vector<DegenerateDirection> degenerate;
  // "reference" (first non-empty view: it anchors the world frame, kept at its prior),
  // "empty" (no valid cell), "no_overlap" (too few correspondences with the placed views),
  // "implausible_correction" (ICP's correction beyond max_correction_deg/mm: prior kept),
  // "not_converged" (ICP lost its correspondences on the way: prior kept),
  // "degenerate:<name>" for each degenerate direction (refined in the other directions only).
  std::vector<std::string> flags;
};

struct Result {
  std::vector<ViewResult> views;
  Mesh fused;  // all views in the world frame: organised triangulations merged, normals, colours
};

// Views are placed in the given order; rms_mm and overlap are measured at the final pose against
// the views placed before it (within max_correspondence_mm). Throws sherd::InputError for a
// malformed view (sizes that do not match width × height, a valid cell that is not finite), a
// non-finite prior or non-positive parameters.
Result register_views(const std::vector<ViewInput>& views, const Params& params);

}  // namespace sherd::registration
