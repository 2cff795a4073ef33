// Voxels and their neighbour graph, the parts of it that segment() works with, and the top view
// (the voxels flattened onto the plate). Internal to processing/segmentation.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <numeric>
#include <utility>
#include <vector>

#include "core/types.h"

namespace sherd::segmentation::detail {

// Clustering runs on one representative (centroid) per voxel of tolerance / this: a scan holds
// many points per tolerance radius, and searching all of them is what makes 1M points slow.
// A point lies within √3·leaf of its representative, so two point sets are split for certain
// when their gap exceeds tolerance + 2√3·leaf (≈ 2.2 × tolerance) and joined for certain when
// it is below tolerance − 2√3·leaf; in between it depends on where the voxels fall. Measured
// (bench_segmentation --million): a 1 M-point tray of 20 sherds ≈ 0.5–0.75 s on the loaded
// 2-core machine, as fast as plain Euclidean clustering in the same run.
inline constexpr double kVoxelsPerTolerance = 3.0;
// The clustering distance is at least this many point spacings (a gap of one missing row of
// points must not split a sherd).
inline constexpr double kSpacingsPerTolerance = 4.0;

// The q-quantile (0…1) of `values` (not empty), which it reorders.
template <typename T>
T quantile_of(std::vector<T>& values, double q) {
  const auto at = values.begin() + static_cast<std::ptrdiff_t>(q * (values.size() - 1));
  std::nth_element(values.begin(), at, values.end());
  return *at;
}

// The candidates as one representative (centroid) per voxel of side `leaf`, with the voxel's
// points: searching a few voxel centroids instead of every point is what keeps 1 M points fast.
struct Voxels {
  std::vector<Vec3f> centres;
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed;  // (voxel key, point), sorted
  std::vector<std::size_t> begin;  // voxel v holds keyed[begin[v] .. begin[v + 1])
  std::size_t points(std::size_t v) const { return begin[v + 1] - begin[v]; }
};

Voxels voxelise(const std::vector<Vec3f>& points, const std::vector<std::uint32_t>& candidates,
                double leaf);

// The sampling distance of the surface, from how many points share a voxel: a surface sampled
// every s mm puts about (leaf / s)² points into a voxel it crosses (more where it runs
// diagonally through it, so this errs towards a smaller s).
double point_spacing(const Voxels& voxels, double leaf);

// Voxels within `radius` of each voxel (itself excluded), by one k-d tree search each.
std::vector<std::vector<std::uint32_t>> neighbourhoods(const Voxels& voxels, double radius);

using Graph = std::vector<std::vector<std::uint32_t>>;

// Connected components of the voxels with allowed[v] (all when empty), as lists of voxels.
std::vector<std::vector<std::uint32_t>> components(const Graph& near,
                                                   const std::vector<std::uint32_t>& among,
                                                   const std::vector<std::uint8_t>& allowed);

// Multi-source Dijkstra over the neighbour graph (edge length = distance between centroids),
// within `cluster`: for every voxel of it, its distance from the nearest source and that source's
// tag. With `region` given, paths stay among voxels of one region (region[v] alike). `inside` is
// scratch space, all zero, sized for all voxels.
void geodesic_from(const Graph& near, const std::vector<Vec3f>& centres,
                   const std::vector<std::uint32_t>& cluster,
                   const std::vector<std::pair<std::uint32_t, int>>& sources,
                   std::vector<float>& distance, std::vector<int>& tag,
                   std::vector<std::uint8_t>& inside, const std::vector<int>* region = nullptr);

// The voxels of `region` on its boundary: those whose neighbours within the region lie to one
// side (their mean more than a quarter of `radius` off), or that have hardly any. `inside` is
// scratch space, all zero, sized for all voxels.
std::vector<std::pair<std::uint32_t, int>> boundary_of(const Graph& near,
                                                       const std::vector<Vec3f>& centres,
                                                       const std::vector<std::uint32_t>& region,
                                                       double radius,
                                                       std::vector<std::uint8_t>& inside);

// How wide a strip `region` is: twice its deepest voxel's distance from the region's boundary,
// along the surface. `inside` is scratch space, all zero, sized for all voxels.
double width_of(const Graph& near, const std::vector<Vec3f>& centres,
                const std::vector<std::uint32_t>& region, double radius,
                std::vector<std::uint8_t>& inside);

// Watershed on the distance from the boundary: the cores grow in order of decreasing `depth`,
// so two of them meet where the surface is narrowest between them — at the contact of two
// sherds, not halfway between their cores.
void flood_from_cores(const Graph& near, const std::vector<std::uint32_t>& cluster,
                      const std::vector<std::pair<std::uint32_t, int>>& cores,
                      const std::vector<float>& depth, std::vector<int>& tag);

// Parts joined into groups (union-find), each group named by one of its parts.
class Groups {
 public:
  explicit Groups(int parts) : parent_(parts) { std::iota(parent_.begin(), parent_.end(), 0); }
  int root(int p) {
    while (parent_[p] != p) p = parent_[p] = parent_[parent_[p]];
    return p;
  }
  void join(int a, int b) { parent_[root(a)] = root(b); }

 private:
  std::vector<int> parent_;
};

// Adds part `part` to `parts` unless it is there (a voxel borders few parts: a linear search).
void add_once(std::vector<int>& parts, int part);

// Voxels flattened onto the plate, for searches in the top view: found[k] of a search is voxel
// voxel_at[found[k]] (of part part_of[that voxel] when built from parts).
struct TopView {
  TopView(const std::vector<Vec3f>& centres, std::vector<std::uint32_t> voxels);
  // The voxels of the parts marked in `chosen`.
  TopView(const std::vector<std::vector<std::uint32_t>>& parts, const std::vector<Vec3f>& centres,
          const std::vector<std::uint8_t>& chosen);
  ~TopView();
  bool empty() const { return voxel_at.empty(); }
  // Voxels within `radius` of `centre` in the top view, into `found` (indices into voxel_at).
  void search(const Vec3f& centre, double radius, std::vector<int>& found);

  std::vector<std::uint32_t> voxel_at;
  std::vector<int> part_of;

 private:
  void build(const std::vector<Vec3f>& centres);

  struct Tree;  // PCL's k-d tree, kept out of this header
  std::unique_ptr<Tree> tree_;
};

// A border's length (mm) from the bands along it: `band_ab` voxels of one part and `band_ba` of the
// other within `radius` of it, each band about `radius` wide.
double border_length_mm(std::size_t band_ab, std::size_t band_ba, double radius);

// `parts` with each part p that has joins[p] >= 0 appended to part joins[p], which joins none.
std::vector<std::vector<std::uint32_t>> with_joined(std::vector<std::vector<std::uint32_t>> parts,
                                                    const std::vector<int>& joins);

// `parts` with the parts of each group in `group` joined into one.
std::vector<std::vector<std::uint32_t>> with_joined(std::vector<std::vector<std::uint32_t>> parts,
                                                    Groups& group);

// Parts given as voxels, as their points' indices (sorted).
std::vector<std::vector<std::uint32_t>> points_of(
    const Voxels& voxels, const std::vector<std::vector<std::uint32_t>>& parts);

}  // namespace sherd::segmentation::detail
