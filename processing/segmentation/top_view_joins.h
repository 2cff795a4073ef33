// Joining the parts of one sherd that the top view shows together: narrow strips, levels in
// separate clusters, folds and the pieces of a sherd another lies across. Internal to
// processing/segmentation.
#pragma once

#include <cstdint>
#include <vector>

#include "core/types.h"
#include "processing/segmentation/voxel_graph.h"

namespace sherd::segmentation::detail {

// `parts` (voxel lists) with those narrower in the top view than a sherd can be (strips of a
// sherd: a fracture face, a band seen edge-on) joined to the part of their clay beside them, or,
// where none is, to the strips of their clay beside them (a sherd standing steeply). The rules and
// their measurements: at kSherdMinTopViewWidthMm and join_strips_of_one_clay in top_view_joins.cpp.
std::vector<std::vector<std::uint32_t>> join_narrow_parts(
    std::vector<std::vector<std::uint32_t>> parts, const Graph& near,
    const std::vector<Vec3f>& centres, const std::vector<Vec3f>& voxel_rgb, double radius,
    double leaf);

// `parts` (each inside one cluster; `cluster_of`: each voxel's cluster) with the levels of one
// sherd that lie in different clusters joined: side by side in the top view across an even step,
// the narrower a band and both of one clay, or both of one hue; or of one clay with the surface
// bending down across the border. The rules and their measurements: at kLevelApartMaxWidthMm and
// kBendingLevelApartMaxOffClayLine in top_view_joins.cpp.
std::vector<std::vector<std::uint32_t>> join_levels_across_clusters(
    std::vector<std::vector<std::uint32_t>> parts, const std::vector<Vec3f>& centres,
    const std::vector<Vec3f>& voxel_rgb, const std::vector<int>& cluster_of, double radius,
    double leaf);

// `parts` (voxel lists) with the parts of each sherd folded over itself, or of a ring-footed base
// lying upside down, joined: two levels meeting in the top view along a step, hardly in 3-D.
// The rule and its measurements: at kFoldMinBorderShare in top_view_joins.cpp.
std::vector<std::vector<std::uint32_t>> join_folded_parts(
    std::vector<std::vector<std::uint32_t>> parts, const std::vector<Vec3f>& centres,
    const std::vector<Vec3f>& voxel_rgb, double radius, double leaf);

// `parts` with the pieces of a sherd that another lies across joined: parts lying under one part
// (above them across their top-view border, apart in 3-D, along kLevelMinStepPairs pairs or more),
// of one hue and clay line, the smaller of them under `max_piece_voxels` (a sherd's area, as
// contact_own_basin_mm2). The rule and its measurements: at join_pieces_under_one_sherd in
// top_view_joins.cpp.
std::vector<std::vector<std::uint32_t>> join_pieces_under_one_sherd(
    std::vector<std::vector<std::uint32_t>> parts, const std::vector<Vec3f>& centres,
    const std::vector<Vec3f>& voxel_rgb, double radius, double leaf, std::size_t max_piece_voxels);

}  // namespace sherd::segmentation::detail
