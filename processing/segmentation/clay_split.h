// Splitting parts by their clay colour, and handing pieces and fracture faces back to the sherd
// they belong to. Internal to processing/segmentation.
#pragma once

#include <cstdint>
#include <vector>

#include "core/types.h"
#include "processing/segmentation/voxel_graph.h"

namespace sherd::segmentation::detail {

// `parts` (voxel lists), each split where it holds several clays; split_from[k] is, for the
// result's part k, the index in `parts` of the part it was cut from (−1 for a part left whole).
// `distance` and `tag` are scratch space sized for all voxels.
std::vector<std::vector<std::uint32_t>> split_by_clay(
    std::vector<std::vector<std::uint32_t>> parts, const Graph& near,
    const std::vector<Vec3f>& centres, const std::vector<Vec3f>& voxel_rgb, double radius,
    double leaf, std::vector<float>& distance, std::vector<int>& tag, std::vector<int>& split_from);

// `parts` with each piece that split_by_clay cut off a part (split_from) joined to the part of its
// sherd: the lobe or level of a sherd that the watershed handed to the sherd it touches. The rule
// and its measurements: at kPieceMaxOffClayLine in clay_split.cpp.
std::vector<std::vector<std::uint32_t>> pieces_to_their_sherd(
    std::vector<std::vector<std::uint32_t>> parts, const std::vector<int>& split_from,
    const Graph& near, const std::vector<Vec3f>& centres, const std::vector<Vec3f>& voxel_rgb,
    double radius);

// `parts` with each piece of a part that lies apart from the rest of it in 3-D but joined all along
// to another part, hanging from it (or of its clay and nearer its clay's line), moved to that part:
// a sherd's face strip that the watershed or a join along the top view left with the part it lay
// beside. The rule and its measurements: at kDetachedMinPairsPerVoxel in clay_split.cpp.
std::vector<std::vector<std::uint32_t>> detached_pieces_to_their_sherd(
    std::vector<std::vector<std::uint32_t>> parts, const Graph& near,
    const std::vector<Vec3f>& centres, const std::vector<Vec3f>& voxel_rgb, double radius,
    double leaf);

// `parts` with the regions that are another part's fracture face (its clay mixed with grey, by hue,
// by where they lie in the top view and by the side their slope faces) moved to that part, also
// where two sherds' faces meet as one region. The rules and their measurements: at
// kRegionMaxPairsPerVoxel, kSteepSlope and pieces_hanging_from_others in clay_split.cpp.
std::vector<std::vector<std::uint32_t>> faces_to_their_clay(
    std::vector<std::vector<std::uint32_t>> parts, const Graph& near,
    const std::vector<Vec3f>& centres, const std::vector<Vec3f>& voxel_rgb, double radius,
    double leaf);

}  // namespace sherd::segmentation::detail
