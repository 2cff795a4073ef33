// PCL does the plane fit (SACSegmentation) and the frame top's normals (NormalEstimation).
#include "processing/segmentation/background.h"

#include <pcl/ModelCoefficients.h>
#include <pcl/PointIndices.h>
#include <pcl/features/normal_3d.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "processing/segmentation/voxel_graph.h"

namespace sherd::segmentation::detail {

namespace {

constexpr std::size_t kPlaneSampleSize = 100'000;  // RANSAC sees at most this many points

// On a black plate, clay in deep shade comes near black too, while the plate itself is darker
// still: so black is held to what the plate shows in this scan, kPlateValueMargin × the 99th
// percentile of its points' value (HSV value, 0–1), below Params::black_max_value. A white plate
// needs no such bound: shade moves clay away from white. Measured on bench_segmentation (black
// trays 1013, 1043, 1053, 71, 85): the plate's value 21 (median) and 26 (99th percentile) of
// 255, the clay points lost as black 33 and more (5th percentile), in deep shade. Pooled recall
// of seeds 1 / 1001 / 5001 / 7001 0.9976 / 0.9968 / 0.9948 / 0.9977 → 0.9982 / 0.9975 / 0.9956 /
// 0.9980, precision and counts unchanged.
constexpr double kPlateValueMargin = 1.2;

// The holding frame by its geometry (see Params::frame_height_mm): points below the plinths' top
// go, and points on the top plane (within plane_distance_mm above it) whose surface faces up
// (normal within kFrameTopMaxTiltDeg of vertical, by PCL's PCA normals over the clustering
// radius). A standing sherd's faces meet the top plane steeply and stay.
constexpr double kFrameTopMaxTiltDeg = 30.0;

bool background_colour(Rgb8 c, const Params& params) {
  if (params.background == BackgroundColour::None) return false;
  const double max = std::max({c.r, c.g, c.b}) / 255.0;
  const double min = std::min({c.r, c.g, c.b}) / 255.0;
  const double saturation = max > 0.0 ? (max - min) / max : 0.0;
  const bool grey =
      saturation < params.background_max_saturation || max - min < params.background_max_chroma;
  if (!grey) return false;
  return params.background == BackgroundColour::Black ? max <= params.black_max_value
                                                      : max >= params.white_min_value;
}

}  // namespace

double largest_side(const std::vector<Vec3f>& points, const std::vector<std::uint32_t>& indices) {
  if (indices.empty()) return 0.0;
  Vec3f lo = points[indices[0]], hi = lo;
  for (auto i : indices) lo = lo.cwiseMin(points[i]), hi = hi.cwiseMax(points[i]);
  return static_cast<double>((hi - lo).maxCoeff());
}

std::vector<std::uint32_t> remove_support_plane(const std::vector<Vec3f>& points,
                                                const Params& params,
                                                std::vector<std::uint8_t>& keep) {
  std::vector<std::uint32_t> candidates;
  for (std::uint32_t i = 0; i < points.size(); ++i) {
    if (keep[i]) candidates.push_back(i);
  }
  if (candidates.size() < 3) return {};
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
  if (sample_inliers.indices.empty() || plane.values.size() != 4) return {};

  const Vec3f normal(plane.values[0], plane.values[1], plane.values[2]);
  const float offset = plane.values[3];
  std::vector<std::uint32_t> inliers;
  for (auto i : candidates) {
    if (std::abs(normal.dot(points[i]) + offset) <= params.plane_distance_mm) inliers.push_back(i);
  }
  if (largest_side(points, inliers) < params.plane_min_extent_mm) return {};
  for (auto i : inliers) keep[i] = 0;
  return inliers;
}

double black_bound_of_plate(const std::vector<Rgb8>& colours,
                            const std::vector<std::uint32_t>& plate, double black_max_value) {
  std::vector<std::uint8_t> value;
  value.reserve(plate.size());
  for (auto i : plate) value.push_back(std::max({colours[i].r, colours[i].g, colours[i].b}));
  return std::min(black_max_value, kPlateValueMargin * quantile_of(value, 0.99) / 255.0);
}

void remove_frame(const std::vector<Vec3f>& points, const Params& params,
                  std::vector<std::uint8_t>& keep) {
  if (params.frame_height_mm <= 0.0) return;
  const double top = params.frame_height_mm;
  const double band_top = top + params.plane_distance_mm;
  // The top band's points are judged; their neighbours up to one radius above it are the surface.
  auto surface = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  auto judged = std::make_shared<pcl::Indices>();
  std::vector<std::uint32_t> judged_points;
  for (std::uint32_t i = 0; i < points.size(); ++i) {
    if (!keep[i]) continue;
    const double z = points[i].z();
    if (z < top) {
      keep[i] = 0;
      continue;
    }
    if (z > band_top + params.cluster_tolerance_mm) continue;
    if (z <= band_top) {
      judged->push_back(static_cast<int>(surface->size()));
      judged_points.push_back(i);
    }
    surface->push_back({points[i].x(), points[i].y(), points[i].z()});
  }
  if (judged->empty()) return;
  pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> estimation;
  estimation.setInputCloud(surface);
  estimation.setIndices(judged);
  estimation.setSearchMethod(std::make_shared<pcl::search::KdTree<pcl::PointXYZ>>(false));
  estimation.setRadiusSearch(params.cluster_tolerance_mm);
  pcl::PointCloud<pcl::Normal> normals;
  estimation.compute(normals);
  const float min_up = static_cast<float>(std::cos(kFrameTopMaxTiltDeg * std::numbers::pi / 180.0));
  for (std::size_t k = 0; k < judged_points.size(); ++k) {
    const float nz = normals[k].normal_z;
    if (std::isfinite(nz) && std::abs(nz) >= min_up) keep[judged_points[k]] = 0;
  }
}

bool outside_volume(const Vec3f& p, const Params& params) {
  if (params.volume_radius_mm <= 0.0) return false;
  const double r2 = static_cast<double>(p.x()) * p.x() + static_cast<double>(p.y()) * p.y();
  return r2 > params.volume_radius_mm * params.volume_radius_mm || p.z() < params.volume_min_z_mm ||
         p.z() > params.volume_max_z_mm;
}

std::vector<std::uint32_t> without_background_colour(const Mesh& fused,
                                                     const std::vector<std::uint32_t>& candidates,
                                                     const Params& params) {
  const auto& points = fused.vertices.points;
  const Voxels voxels =
      voxelise(points, candidates, params.cluster_tolerance_mm / kVoxelsPerTolerance);
  std::vector<std::uint8_t> object_voxel(voxels.centres.size());
  for (std::size_t v = 0; v < voxels.centres.size(); ++v) {
    std::size_t background = 0;
    for (std::size_t k = voxels.begin[v]; k < voxels.begin[v + 1]; ++k)
      background += background_colour(fused.vertices.colours[voxels.keyed[k].second], params);
    object_voxel[v] = 2 * background < voxels.points(v);
  }
  const Graph near = neighbourhoods(voxels, params.cluster_tolerance_mm);
  std::vector<std::uint32_t> result;
  for (std::size_t v = 0; v < voxels.centres.size(); ++v) {
    std::size_t object_neighbours = 0;
    for (auto n : near[v]) object_neighbours += object_voxel[n];
    if (!object_voxel[v] && 2 * object_neighbours <= near[v].size()) continue;
    for (std::size_t k = voxels.begin[v]; k < voxels.begin[v + 1]; ++k)
      result.push_back(voxels.keyed[k].second);
  }
  std::sort(result.begin(), result.end());
  return result;
}

}  // namespace sherd::segmentation::detail
