// Fusing the turntable views of one scan into one model in the world (= turntable) frame.
// Each view is placed by the turntable prior (calibrated scanner pose and encoder angle) and
// refined by point-to-plane ICP against the views already placed.
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
  float mesh_max_edge_mm = 3.0f;    // organised triangulation: longer edges are depth jumps
};

struct ViewResult {
  Pose pose = Pose::Identity();  // final scanner → world
  double rms_mm = 0.0;           // point-to-plane RMS over accepted correspondences
  double overlap = 0.0;          // share of the view's points with a correspondence
  int iterations = 0;
  double correction_deg = 0.0;   // rotation between prior and final pose
  double correction_mm = 0.0;    // translation between prior and final pose
  bool refined = false;          // false: the prior was kept
  std::vector<std::string> flags;  // "empty", "no_overlap", "implausible_correction", …
};

struct Result {
  std::vector<ViewResult> views;
  Mesh fused;  // all views in the world frame: organised triangulations merged, normals, colours
};

Result register_views(const std::vector<ViewInput>& views, const Params& params);

}  // namespace sherd::registration
