// Fused scan → sherds: segment() removes the background (background.h), then clusters() takes the
// rest through the clustering steps in order: Euclidean clusters, contacts split (contacts.h),
// clays split and pieces and faces handed back (clay_split.h), strips, levels and folds joined
// (top_view_joins.h). The Euclidean clusters are the connected components of the voxels'
// neighbour graph (voxel_graph.h), found here rather than by PCL's EuclideanClusterExtraction
// because the splitting of touching sherds (erosion and watershed) walks the same graph, and PCL's
// class does not hand it out.
#include "processing/segmentation/segmentation.h"

#include <fmt/format.h>

#include <numeric>

#include "core/errors.h"
#include "processing/segmentation/background.h"
#include "processing/segmentation/clay_split.h"
#include "processing/segmentation/contacts.h"
#include "processing/segmentation/top_view_joins.h"
#include "processing/segmentation/voxel_graph.h"

namespace sherd::segmentation {
using namespace detail;
namespace {

void check_params(const Params& p) {
  auto bad = [](const std::string& what) {
    throw InputError(
        fmt::format("segmentation parameters: {}; fix the [segmentation] settings", what));
  };
  if (!(p.cluster_tolerance_mm > 0.0))
    bad(fmt::format("cluster_tolerance_mm = {} must be > 0", p.cluster_tolerance_mm));
  if (p.min_points < 1) bad(fmt::format("min_points = {} must be >= 1", p.min_points));
  if (!(p.min_extent_mm <= p.max_extent_mm)) {
    bad(fmt::format("min_extent_mm = {} must not exceed max_extent_mm = {}", p.min_extent_mm,
                    p.max_extent_mm));
  }
  if (!(p.contact_erosion_mm >= 0.0))
    bad(fmt::format("contact_erosion_mm = {} must be >= 0", p.contact_erosion_mm));
  if (!(p.contact_min_core_mm2 >= 0.0))
    bad(fmt::format("contact_min_core_mm2 = {} must be >= 0", p.contact_min_core_mm2));
  if (!(p.contact_own_basin_mm2 >= 0.0))
    bad(fmt::format("contact_own_basin_mm2 = {} must be >= 0", p.contact_own_basin_mm2));
  if (!(p.frame_height_mm >= 0.0))
    bad(fmt::format("frame_height_mm = {} must be >= 0", p.frame_height_mm));
  if (!(p.plane_distance_mm > 0.0))
    bad(fmt::format("plane_distance_mm = {} must be > 0", p.plane_distance_mm));
}

// Euclidean clusters of the candidates, each split where sherds touch, as sorted point indices;
// the parts after each step kept in `steps` when given. The clustering distance is the
// configured one or, where the points lie sparser than that allows, kSpacingsPerTolerance point
// spacings: the scale comes from the data.
std::vector<std::vector<std::uint32_t>> clusters(const std::vector<Vec3f>& points,
                                                 const std::vector<Rgb8>& colours,
                                                 const std::vector<std::uint32_t>& candidates,
                                                 const Params& params,
                                                 std::vector<ClusteringStep>* steps) {
  double tolerance = params.cluster_tolerance_mm;
  Voxels voxels = voxelise(points, candidates, tolerance / kVoxelsPerTolerance);
  const double spacing = point_spacing(voxels, tolerance / kVoxelsPerTolerance);
  if (kSpacingsPerTolerance * spacing > tolerance) {
    tolerance = kSpacingsPerTolerance * spacing;
    voxels = voxelise(points, candidates, tolerance / kVoxelsPerTolerance);
  }
  const Graph near = neighbourhoods(voxels, tolerance);
  std::vector<std::uint32_t> all(voxels.centres.size());
  std::iota(all.begin(), all.end(), 0u);
  const double leaf = tolerance / kVoxelsPerTolerance;
  // A core must be as large as the smallest sherd's eroded footprint could be.
  const double core_side = std::max(params.min_extent_mm - 2.0 * params.contact_erosion_mm, leaf);
  CoreSizes sizes;
  sizes.min_core_voxels =
      static_cast<std::size_t>(std::max(4.0, 1.5 * core_side * core_side / (leaf * leaf)));
  sizes.min_own_core_voxels = std::max(
      sizes.min_core_voxels, static_cast<std::size_t>(params.contact_min_core_mm2 / (leaf * leaf)));
  sizes.min_own_basin_voxels =
      static_cast<std::size_t>(params.contact_own_basin_mm2 / (leaf * leaf));
  sizes.min_wide_core_voxels = static_cast<std::size_t>(kWideCoreMm2 / (leaf * leaf));
  sizes.max_small_sherd_step_band_voxels =
      static_cast<std::size_t>(kSmallSherdMaxStepBandMm2 / (leaf * leaf));
  sizes.min_own_clay_piece_voxels = static_cast<std::size_t>(kStripMinOwnPieceMm2 / (leaf * leaf));
  std::vector<float> distance(voxels.centres.size());
  std::vector<int> tag(voxels.centres.size());
  std::vector<Vec3f> voxel_rgb;  // colour sums per voxel, when the scan has colours
  if (!colours.empty()) {
    voxel_rgb.assign(voxels.centres.size(), Vec3f::Zero());
    for (std::size_t v = 0; v < voxels.centres.size(); ++v) {
      for (std::size_t k = voxels.begin[v]; k < voxels.begin[v + 1]; ++k) {
        const Rgb8 c = colours[voxels.keyed[k].second];
        voxel_rgb[v] += Vec3f(c.r, c.g, c.b);
      }
    }
  }

  auto keep = [&](const char* step, const std::vector<std::vector<std::uint32_t>>& parts) {
    if (steps != nullptr) steps->push_back({step, points_of(voxels, parts)});
  };
  const auto euclidean = components(near, all, {});
  keep("clusters", euclidean);
  std::vector<std::vector<std::uint32_t>> parts;
  ContactStages stages;
  for (const auto& cluster : euclidean) {
    auto split = params.contact_erosion_mm > 0.0
                     ? split_at_contacts(near, voxels.centres, voxel_rgb, cluster, tolerance,
                                         params.contact_erosion_mm, sizes, distance, tag,
                                         steps != nullptr ? &stages : nullptr)
                     : std::vector<std::vector<std::uint32_t>>{cluster};
    for (auto& part : split) parts.push_back(std::move(part));
  }
  if (params.contact_erosion_mm > 0.0) {
    keep("basins", stages.basins);
    keep("small cores", stages.small_cores);
    keep("contacts", parts);
  }
  if (params.contact_erosion_mm > 0.0 && !voxel_rgb.empty()) {
    // By clay first: a piece of a sherd cut off by colour from the neighbour it was flooded
    // with then joins its sherd, where it borders it in 3-D (pieces_to_their_sherd) or across
    // the unseen wall (tray 89 of seed 1: a rim band behind its step). join_across_unseen_walls
    // reads `distance`, so the colour split gets its own.
    std::vector<float> clay_distance(voxels.centres.size());
    std::vector<int> split_from;
    parts = split_by_clay(std::move(parts), near, voxels.centres, voxel_rgb, tolerance, leaf,
                          clay_distance, tag, split_from);
    parts = pieces_to_their_sherd(std::move(parts), split_from, near, voxels.centres, voxel_rgb,
                                  tolerance);
    keep("clay", parts);
    std::vector<int> cluster_of(voxels.centres.size(), -1);
    for (std::size_t c = 0; c < euclidean.size(); ++c) {
      for (auto v : euclidean[c]) cluster_of[v] = static_cast<int>(c);
    }
    parts = join_levels_across_clusters(std::move(parts), voxels.centres, voxel_rgb, cluster_of,
                                        tolerance, leaf);
    keep("levels", parts);
    parts = join_across_unseen_walls(std::move(parts), voxels.centres, voxel_rgb, distance,
                                     tolerance, params.contact_erosion_mm, sizes, leaf);
    keep("walls", parts);
    parts = faces_to_their_clay(std::move(parts), near, voxels.centres, voxel_rgb, tolerance, leaf);
    keep("faces", parts);
    parts = join_narrow_parts(std::move(parts), near, voxels.centres, voxel_rgb, tolerance, leaf);
    keep("narrow", parts);
    parts = join_folded_parts(std::move(parts), voxels.centres, voxel_rgb, tolerance, leaf);
    keep("folds", parts);
    parts = detached_pieces_to_their_sherd(std::move(parts), near, voxels.centres, voxel_rgb,
                                           tolerance, leaf);
    keep("detached", parts);
    parts = join_pieces_under_one_sherd(std::move(parts), voxels.centres, voxel_rgb, tolerance,
                                        leaf, sizes.min_own_basin_voxels);
    keep("under", parts);
  }
  return points_of(voxels, parts);
}

Vec3d centroid_of(const std::vector<Vec3f>& points, const std::vector<std::uint32_t>& indices) {
  Vec3d sum = Vec3d::Zero();
  for (auto i : indices) sum += points[i].cast<double>();
  return sum / static_cast<double>(indices.size());
}

}  // namespace

Result segment(const Mesh& fused, const Params& params, std::vector<ClusteringStep>* steps) {
  check_params(params);
  if (steps != nullptr) steps->clear();
  Result result;
  const auto& points = fused.vertices.points;
  if (points.empty()) return result;

  std::vector<std::uint8_t> keep(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) keep[i] = points[i].allFinite() ? 1 : 0;
  const auto plate = remove_support_plane(points, params, keep);
  remove_frame(points, params, keep);
  const bool by_colour =
      params.background != BackgroundColour::None && fused.vertices.has_colours();
  std::vector<std::uint32_t> candidates;
  for (std::uint32_t i = 0; i < points.size(); ++i) {
    if (keep[i] && !outside_volume(points[i], params)) candidates.push_back(i);
  }
  if (by_colour) {
    Params colour = params;
    if (params.background == BackgroundColour::Black && !plate.empty())
      colour.black_max_value =
          black_bound_of_plate(fused.vertices.colours, plate, params.black_max_value);
    candidates = without_background_colour(fused, candidates, colour);
  }
  result.background_points = points.size() - candidates.size();

  for (auto& cluster : clusters(points, fused.vertices.colours, candidates, params, steps)) {
    const double extent = largest_side(points, cluster);
    std::string reason;
    if (cluster.size() < static_cast<std::size_t>(params.min_points)) {
      reason = fmt::format("too small: {} points < {}", cluster.size(), params.min_points);
    } else if (extent < params.min_extent_mm) {
      reason = fmt::format("too small: extent {:.1f} mm < {:.1f} mm", extent, params.min_extent_mm);
    } else if (extent > params.max_extent_mm) {
      reason = fmt::format("too large: extent {:.1f} mm > {:.1f} mm", extent, params.max_extent_mm);
    }
    if (!reason.empty()) {
      result.rejected.push_back({std::move(cluster), std::move(reason)});
      continue;
    }
    Part part;
    part.indices = std::move(cluster);
    result.sherds.push_back(std::move(part));
  }

  // Stable ids: the same tray gives the same names, left to right, then front to back.
  std::vector<Vec3d> centroids;
  for (const auto& part : result.sherds) centroids.push_back(centroid_of(points, part.indices));
  std::vector<std::size_t> order(result.sherds.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](auto a, auto b) {
    return std::pair(centroids[a].x(), centroids[a].y()) <
           std::pair(centroids[b].x(), centroids[b].y());
  });
  std::vector<Part> sorted;
  for (std::size_t rank = 0; rank < order.size(); ++rank) {
    Part part = std::move(result.sherds[order[rank]]);
    part.id = fmt::format("s{:02d}", rank + 1);
    part.mesh = fused.subset(part.indices);
    part.bbox = Box3::of(part.mesh.vertices);
    sorted.push_back(std::move(part));
  }
  result.sherds = std::move(sorted);
  return result;
}

}  // namespace sherd::segmentation
