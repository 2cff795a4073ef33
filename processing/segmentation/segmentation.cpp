// Fused scan → sherds. PCL does the plane fit (SACSegmentation) and the clustering
// (EuclideanClusterExtraction); the rest is per-point bookkeeping on index lists.
#include "processing/segmentation/segmentation.h"

#include "core/errors.h"

#include <fmt/format.h>
#include <pcl/ModelCoefficients.h>
#include <pcl/PointIndices.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/extract_clusters.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <algorithm>
#include <cmath>
#include <numeric>

namespace sherd::segmentation {
namespace {

constexpr std::size_t kPlaneSampleSize = 100'000;  // RANSAC sees at most this many points
// Clustering runs on one representative (centroid) per voxel of tolerance / this: a scan holds
// many points per tolerance radius, and searching all of them is what makes 1M points slow.
// A point lies within √3·leaf of its representative, so two point sets are split for certain
// when their gap exceeds tolerance + 2√3·leaf (≈ 2.2 × tolerance) and joined for certain when
// it is below tolerance − 2√3·leaf; in between it depends on where the voxels fall. Measured:
// 1M points all foreground ≈ 1.0 s, 1M with 80 % background ≈ 0.2 s (2-core machine).
constexpr double kVoxelsPerTolerance = 3.0;

void check_params(const Params& p) {
  auto bad = [](const std::string& what) {
    throw InputError(fmt::format("segmentation parameters: {}; fix the [segmentation] settings", what));
  };
  if (!(p.cluster_tolerance_mm > 0.0)) bad(fmt::format("cluster_tolerance_mm = {} must be > 0", p.cluster_tolerance_mm));
  if (p.min_points < 1) bad(fmt::format("min_points = {} must be >= 1", p.min_points));
  if (!(p.min_extent_mm <= p.max_extent_mm)) {
    bad(fmt::format("min_extent_mm = {} must not exceed max_extent_mm = {}", p.min_extent_mm, p.max_extent_mm));
  }
  if (!(p.plane_distance_mm > 0.0)) bad(fmt::format("plane_distance_mm = {} must be > 0", p.plane_distance_mm));
}

double largest_side(const std::vector<Vec3f>& points, const std::vector<std::uint32_t>& indices) {
  if (indices.empty()) return 0.0;
  Vec3f lo = points[indices[0]], hi = lo;
  for (auto i : indices) lo = lo.cwiseMin(points[i]), hi = hi.cwiseMax(points[i]);
  return static_cast<double>((hi - lo).maxCoeff());
}

// Fits the dominant plane by RANSAC on a regular subsample, then takes every point within the
// distance of it. Accepted as support only when its inliers span plane_min_extent_mm.
void remove_support_plane(const std::vector<Vec3f>& points, const Params& params, std::vector<std::uint8_t>& keep) {
  std::vector<std::uint32_t> candidates;
  for (std::uint32_t i = 0; i < points.size(); ++i) {
    if (keep[i]) candidates.push_back(i);
  }
  if (candidates.size() < 3) return;
  auto sample = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  const std::size_t stride = (candidates.size() + kPlaneSampleSize - 1) / kPlaneSampleSize;
  for (std::size_t k = 0; k < candidates.size(); k += stride) {
    const Vec3f& p = points[candidates[k]];
    sample->push_back({p.x(), p.y(), p.z()});
  }
  pcl::SACSegmentation<pcl::PointXYZ> ransac;  // fixed seed: the same scan gives the same plane
  ransac.setModelType(pcl::SACMODEL_PLANE);
  ransac.setMethodType(pcl::SAC_RANSAC);
  ransac.setDistanceThreshold(params.plane_distance_mm);
  ransac.setMaxIterations(500);
  ransac.setOptimizeCoefficients(true);
  ransac.setInputCloud(sample);
  pcl::PointIndices sample_inliers;
  pcl::ModelCoefficients plane;
  ransac.segment(sample_inliers, plane);
  if (sample_inliers.indices.empty() || plane.values.size() != 4) return;

  const Vec3f normal(plane.values[0], plane.values[1], plane.values[2]);
  const float offset = plane.values[3];
  std::vector<std::uint32_t> inliers;
  for (auto i : candidates) {
    if (std::abs(normal.dot(points[i]) + offset) <= params.plane_distance_mm) inliers.push_back(i);
  }
  if (largest_side(points, inliers) < params.plane_min_extent_mm) return;
  for (auto i : inliers) keep[i] = 0;
}

bool outside_volume(const Vec3f& p, const Params& params) {
  if (params.volume_radius_mm <= 0.0) return false;
  const double r2 = static_cast<double>(p.x()) * p.x() + static_cast<double>(p.y()) * p.y();
  return r2 > params.volume_radius_mm * params.volume_radius_mm || p.z() < params.volume_min_z_mm ||
         p.z() > params.volume_max_z_mm;
}

bool background_colour(Rgb8 c, const Params& params) {
  if (params.background == BackgroundColour::None) return false;
  const double max = std::max({c.r, c.g, c.b}) / 255.0;
  const double min = std::min({c.r, c.g, c.b}) / 255.0;
  const double saturation = max > 0.0 ? (max - min) / max : 0.0;
  const bool grey = saturation < params.background_max_saturation || max - min < params.background_max_chroma;
  if (!grey) return false;
  return params.background == BackgroundColour::Black ? max <= params.black_max_value : max >= params.white_min_value;
}

// Euclidean clusters of `candidates` (indices into `points`), each sorted ascending.
std::vector<std::vector<std::uint32_t>> euclidean_clusters(const std::vector<Vec3f>& points,
                                                           const std::vector<std::uint32_t>& candidates,
                                                           double tolerance) {
  // Voxel key per candidate (21 bits per axis, offset to stay positive), then runs of equal keys.
  const double leaf = tolerance / kVoxelsPerTolerance;
  auto key_of = [&](const Vec3f& p) {
    auto cell = [&](float v) {
      return static_cast<std::uint64_t>(std::clamp<long long>(std::llround(std::floor(v / leaf)) + (1 << 20), 0, (1 << 21) - 1));
    };
    return cell(p.x()) << 42 | cell(p.y()) << 21 | cell(p.z());
  };
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed;
  keyed.reserve(candidates.size());
  for (auto i : candidates) keyed.emplace_back(key_of(points[i]), i);
  std::sort(keyed.begin(), keyed.end());

  auto voxels = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  std::vector<std::size_t> voxel_begin;  // voxel v holds keyed[voxel_begin[v] .. voxel_begin[v+1])
  for (std::size_t k = 0; k < keyed.size();) {
    std::size_t end = k;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (; end < keyed.size() && keyed[end].first == keyed[k].first; ++end) sum += points[keyed[end].second].cast<double>();
    const Eigen::Vector3f centroid = (sum / static_cast<double>(end - k)).cast<float>();
    voxels->push_back({centroid.x(), centroid.y(), centroid.z()});
    voxel_begin.push_back(k);
    k = end;
  }
  voxel_begin.push_back(keyed.size());
  if (voxels->empty()) return {};

  auto tree = std::make_shared<pcl::search::KdTree<pcl::PointXYZ>>();
  pcl::EuclideanClusterExtraction<pcl::PointXYZ> extraction;
  extraction.setClusterTolerance(tolerance);
  extraction.setMinClusterSize(1);  // size filters come later, with reasons
  extraction.setMaxClusterSize(std::numeric_limits<int>::max());
  extraction.setSearchMethod(tree);
  extraction.setInputCloud(voxels);
  std::vector<pcl::PointIndices> voxel_clusters;
  extraction.extract(voxel_clusters);

  std::vector<std::vector<std::uint32_t>> clusters;
  clusters.reserve(voxel_clusters.size());
  for (const auto& voxel_cluster : voxel_clusters) {
    std::vector<std::uint32_t> members;
    for (auto v : voxel_cluster.indices) {
      for (std::size_t k = voxel_begin[v]; k < voxel_begin[v + 1]; ++k) members.push_back(keyed[k].second);
    }
    std::sort(members.begin(), members.end());
    clusters.push_back(std::move(members));
  }
  return clusters;
}

Vec3d centroid_of(const std::vector<Vec3f>& points, const std::vector<std::uint32_t>& indices) {
  Vec3d sum = Vec3d::Zero();
  for (auto i : indices) sum += points[i].cast<double>();
  return sum / static_cast<double>(indices.size());
}

}  // namespace

Result segment(const Mesh& fused, const Params& params) {
  check_params(params);
  Result result;
  const auto& points = fused.vertices.points;
  if (points.empty()) return result;

  std::vector<std::uint8_t> keep(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) keep[i] = points[i].allFinite() ? 1 : 0;
  remove_support_plane(points, params, keep);
  const bool by_colour = params.background != BackgroundColour::None && fused.vertices.has_colours();
  std::vector<std::uint32_t> candidates;
  for (std::uint32_t i = 0; i < points.size(); ++i) {
    if (!keep[i] || outside_volume(points[i], params)) continue;
    if (by_colour && background_colour(fused.vertices.colours[i], params)) continue;
    candidates.push_back(i);
  }
  result.background_points = points.size() - candidates.size();

  for (auto& cluster : euclidean_clusters(points, candidates, params.cluster_tolerance_mm)) {
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
    return std::pair(centroids[a].x(), centroids[a].y()) < std::pair(centroids[b].x(), centroids[b].y());
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
