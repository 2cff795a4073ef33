// The fused model of a registered scan: the posed turntable views become ONE merged cloud and ONE
// mesh in the world frame, flying pixels removed, one layer of surface where views overlap.
//
// How: every valid cell goes into a voxel grid (world frame). A voxel is owned by the view that
// saw it most frontally (largest |cos| between the voxel's mean normal and the ray to that view's
// scanner). Each view's organised-grid triangulation (its isolated one-cell dropouts bridged)
// keeps the triangles with at least one vertex in a voxel it owns (a one-triangle overlap at
// seams, so no crack shows in a render) or in a voxel where the owner's own surface ends (its
// image border, an occlusion, a larger dropout: there the others fill in), minus those touching
// an outlier voxel. Outliers are found by PCL's RadiusOutlierRemoval on the voxel centroids.
#pragma once

#include "core/types.h"

#include <cstddef>
#include <vector>

namespace sherd::fusion {

struct PosedView {
  const OrganisedView* view = nullptr;
  // Scanner → world. The scanner frame's origin is the optical centre: outward normals and the
  // ownership of overlaps are judged by the rays towards it.
  Pose pose = Pose::Identity();
};

struct Params {
  // Edge of the voxels that average the cloud and decide which view owns each patch of surface.
  // About two scanner pixels at the station's working distance (0.5 mm per pixel at 420 mm,
  // fx = 800): small enough that a seam is sharp, large enough that each voxel averages a few
  // points of every view that saw it.
  double voxel_mm = 1.0;
  // Outliers: a voxel with fewer than `outlier_min_neighbours` occupied voxels whose centroids lie
  // within `outlier_radius_voxels` × voxel_mm of its own. A flying pixel at a depth edge has
  // none, a one-pixel veil of them a few along its line, a surface about 19 (half that along its
  // border). Measured on a sphere with a 130-pixel veil and 200 flying pixels: 2.5 / 8 removes
  // all of them and 0.3 % of the genuine points; 2.5 / 6 leaves 7 veil voxels.
  // Why not statistical outlier removal: its threshold (mean + k sd of all neighbour distances)
  // is inflated by the outliers themselves, and it always cuts the tail of a clean surface.
  double outlier_radius_voxels = 2.5;
  int outlier_min_neighbours = 8;
  // Organised triangulation: neighbouring cells further apart than this straddle a depth jump
  // (an occlusion boundary), not surface. Same meaning as registration::Params::mesh_max_edge_mm.
  float max_edge_mm = 3.0f;
};

struct Result {
  // World frame. Vertices are measured points (not averaged, so the mesh keeps the scanner's
  // resolution), with the voxel-averaged unit normal (outward: towards the scanners that saw
  // them) and the colour of the view that measured them: mostly the owner, which saw the patch
  // most frontally (best lit); averaging would blur painted decoration to the voxel size.
  Mesh mesh;
  // One point per voxel: averaged position, unit normal and colour; outlier voxels left out.
  Cloud cloud;
  std::size_t views_used = 0;        // views with at least one valid cell
  std::size_t input_points = 0;      // valid cells of all views
  std::size_t outliers_removed = 0;  // input points in outlier voxels
  // Input points left out of the mesh because another view saw their patch more frontally.
  std::size_t overlap_points_dropped = 0;
};

// Views with no valid cell are skipped. Throws sherd::InputError for a null view, a grid whose
// arrays do not match width × height, a valid cell that is not finite, a non-finite pose or
// parameters out of range; sherd::ProcessingError when no view has a valid cell.
Result fuse_views(const std::vector<PosedView>& views, const Params& params);

}  // namespace sherd::fusion
