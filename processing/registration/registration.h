// Fusing the turntable views of one scan into one model in the world (= turntable) frame.
// Each view is placed by the turntable prior (calibrated scanner pose and encoder angle) and
// refined by point-to-plane ICP against the union of the views already placed.
#pragma once

#include "core/types.h"

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
  // "reference" (first non-empty view: it anchors the world frame, kept at its prior),
  // "empty" (no valid cell), "no_overlap" (too few correspondences with the placed views),
  // "implausible_correction" (ICP's correction beyond max_correction_deg/mm: prior kept),
  // "not_converged" (ICP lost its correspondences on the way: prior kept).
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
