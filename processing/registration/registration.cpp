#include "processing/registration/registration.h"

#include "core/errors.h"

#include <fmt/format.h>
#include <pcl/features/normal_3d.h>
#include <pcl/filters/random_sample.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/correspondence_rejection_surface_normal.h>
#include <pcl/registration/correspondence_rejection_trimmed.h>
#include <pcl/registration/icp.h>
#include <pcl/search/kdtree.h>

#include <cmath>
#include <numbers>

namespace sherd::registration {

namespace {

using PointT = pcl::PointNormal;
using CloudT = pcl::PointCloud<PointT>;

// Fewer correspondences than this cannot pin six degrees of freedom against noise.
constexpr std::size_t kMinCorrespondences = 50;
// Share of the best correspondences ICP keeps each iteration: the worst tenth (background,
// surface the other views did not see, edges) must not pull.
constexpr float kTrimmedOverlapRatio = 0.9f;
// A pair whose normals differ by more than 45° is not the same patch of surface: near an edge
// the nearest neighbour may sit on the adjoining face, and its plane would pull the view sideways.
const double kMinNormalCosine = std::cos(std::numbers::pi / 4);
// Neighbours for normals where the scanner gave none.
constexpr int kNormalNeighbours = 16;
// Fixed so that registering the same views twice gives the same poses.
constexpr unsigned kSampleSeed = 20240601;

double to_deg(double rad) { return rad * 180.0 / std::numbers::pi; }

void check_input(const std::vector<ViewInput>& views, const Params& params) {
  if (!(params.voxel_mm > 0) || !(params.max_correspondence_mm > 0) || params.max_iterations < 1 ||
      !(params.max_correction_deg > 0) || !(params.max_correction_mm > 0) ||
      !(params.mesh_max_edge_mm > 0) || !(params.min_overlap >= 0 && params.min_overlap <= 1) ||
      params.icp_max_points < 1) {
    throw InputError(
        "registration: parameters out of range (voxel, distances, limits and iterations must be "
        "positive, min_overlap in [0, 1]); fix the registration parameters");
  }
  for (std::size_t i = 0; i < views.size(); ++i) {
    const OrganisedView* view = views[i].view;
    if (view == nullptr) {
      throw InputError(
          fmt::format("registration: view {} has no data; pass every captured view", i));
    }
    if (!views[i].prior.matrix().allFinite()) {
      throw InputError(fmt::format(
          "registration: view {} has a non-finite prior pose; check the scanner calibration and "
          "the turntable angle",
          i));
    }
    const std::size_t cells = view->cells();
    const bool sizes_ok = view->width >= 0 && view->height >= 0 && view->points.size() == cells &&
                          view->valid.size() == cells &&
                          (view->normals.empty() || view->normals.size() == cells) &&
                          (view->colours.empty() || view->colours.size() == cells);
    if (!sizes_ok) {
      throw InputError(fmt::format(
          "registration: view {} is corrupt ({}x{} grid but {} points, {} validity flags, {} "
          "normals, {} colours); re-capture or re-read the raw view",
          i, view->width, view->height, view->points.size(), view->valid.size(),
          view->normals.size(), view->colours.size()));
    }
    for (std::size_t c = 0; c < cells; ++c) {
      if (view->valid[c] && !view->points[c].allFinite()) {
        throw InputError(fmt::format(
            "registration: view {} cell {} (row {}, column {}) is marked valid but its point is "
            "not finite; re-capture or re-read the raw view",
            i, c, c / view->width, c % view->width));
      }
    }
  }
}

// Points with non-finite or zero normals are dropped; the others get unit normals.
void keep_unit_normals(CloudT& cloud) {
  std::size_t kept = 0;
  for (auto& p : cloud.points) {
    Eigen::Vector3f n = p.getNormalVector3fMap();
    const float length = n.norm();
    if (!std::isfinite(length) || length < 1e-6f) continue;
    p.getNormalVector3fMap() = n / length;
    cloud.points[kept++] = p;
  }
  cloud.resize(kept);
}

// One point per occupied voxel: the average of its points (and of their normals).
CloudT::Ptr voxel_averaged(const CloudT::ConstPtr& cloud, double voxel_mm) {
  auto out = std::make_shared<CloudT>();
  pcl::VoxelGrid<PointT> grid;
  grid.setInputCloud(cloud);
  const auto leaf = static_cast<float>(voxel_mm);
  grid.setLeafSize(leaf, leaf, leaf);
  grid.filter(*out);
  return out;
}

// The view's valid cells, voxel-averaged, with unit normals, in the scanner frame. Normals come
// from the scanner where it gave them, else are estimated from neighbours and turned towards the
// scanner (the origin of its frame).
CloudT::Ptr view_cloud(const OrganisedView& view, double voxel_mm) {
  const bool has_normals = view.normals.size() == view.cells();
  auto raw = std::make_shared<CloudT>();
  raw->reserve(view.valid_count());
  for (std::size_t c = 0; c < view.cells(); ++c) {
    if (!view.valid[c]) continue;
    PointT p;
    p.getVector3fMap() = view.points[c];
    p.getNormalVector3fMap() =
        has_normals ? view.normals[c] : Eigen::Vector3f(std::nanf(""), 0.f, 0.f);
    p.curvature = 0.f;
    raw->push_back(p);
  }
  CloudT::Ptr points = voxel_averaged(raw, voxel_mm);
  if (!has_normals) {
    if (points->size() <= static_cast<std::size_t>(kNormalNeighbours))
      return std::make_shared<CloudT>();
    pcl::NormalEstimation<PointT, PointT> estimation;
    estimation.setInputCloud(points);
    estimation.setKSearch(kNormalNeighbours);
    estimation.setViewPoint(0.f, 0.f, 0.f);
    estimation.compute(*points);  // fills the normal fields in place, keeps xyz
  }
  keep_unit_normals(*points);
  return points;
}

CloudT::Ptr transformed(const CloudT& cloud, const Eigen::Isometry3d& pose) {
  auto out = std::make_shared<CloudT>();
  out->resize(cloud.size());
  const Eigen::Matrix3f rotation = pose.linear().cast<float>();
  const Eigen::Vector3f translation = pose.translation().cast<float>();
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    (*out)[i].getVector3fMap() = rotation * cloud[i].getVector3fMap() + translation;
    (*out)[i].getNormalVector3fMap() = rotation * cloud[i].getNormalVector3fMap();
    (*out)[i].curvature = cloud[i].curvature;
  }
  return out;
}

struct Fit {
  std::size_t correspondences = 0;
  double rms_mm = 0.0;  // point-to-plane, over the correspondences
  double overlap = 0.0;
};

// Nearest-neighbour correspondences of `source` in the tree's cloud within `max_distance_mm`
// and with compatible normals.
Fit measure_fit(const CloudT& source, const pcl::search::KdTree<PointT>& target_tree,
                double max_distance_mm) {
  Fit fit;
  if (source.empty()) return fit;
  const CloudT& target = *target_tree.getInputCloud();
  const double max_sq = max_distance_mm * max_distance_mm;
  std::vector<int> index(1);
  std::vector<float> distance_sq(1);
  double sum_sq = 0.0;
  for (const auto& p : source) {
    if (target_tree.nearestKSearch(p, 1, index, distance_sq) < 1 || distance_sq[0] > max_sq) {
      continue;
    }
    const auto& q = target[index[0]];
    if (p.getNormalVector3fMap().dot(q.getNormalVector3fMap()) < kMinNormalCosine) continue;
    const double along_normal = (p.getVector3fMap() - q.getVector3fMap())
                                    .cast<double>()
                                    .dot(q.getNormalVector3fMap().cast<double>());
    sum_sq += along_normal * along_normal;
    ++fit.correspondences;
  }
  if (fit.correspondences > 0) fit.rms_mm = std::sqrt(sum_sq / fit.correspondences);
  fit.overlap = static_cast<double>(fit.correspondences) / source.size();
  return fit;
}

// PCL's point-to-plane ICP (linearised least squares on the target's normals), in double
// precision, exposing how many iterations it ran.
class PointToPlaneIcp : public pcl::IterativeClosestPointWithNormals<PointT, PointT, double> {
 public:
  int iterations() const { return nr_iterations_; }
};

struct Refinement {
  Eigen::Isometry3d correction = Eigen::Isometry3d::Identity();  // in the clouds' frame
  int iterations = 0;
  bool converged = false;
};

// Coarse then fine: the first pass accepts pairs as far apart as a plausible prior error
// (so a prior off by up to max_correction_mm still finds its surface), the second tightens to
// max_correspondence_mm so that the final pose is set by close, reliable pairs only.
Refinement refine(const CloudT::Ptr& source, const CloudT::Ptr& target,
                  const pcl::search::KdTree<PointT>::Ptr& target_tree, double coarse_mm,
                  const Params& params) {
  CloudT::Ptr icp_source = source;
  if (source->size() > static_cast<std::size_t>(params.icp_max_points)) {
    icp_source = std::make_shared<CloudT>();
    pcl::RandomSample<PointT> sample;
    sample.setInputCloud(source);
    sample.setSample(static_cast<unsigned>(params.icp_max_points));
    sample.setSeed(kSampleSeed);
    sample.filter(*icp_source);
  }

  PointToPlaneIcp icp;
  icp.setInputSource(icp_source);
  icp.setInputTarget(target);
  icp.setSearchMethodTarget(target_tree, true);  // the tree is already built on `target`
  icp.setMaximumIterations(params.max_iterations);
  // Converged when an iteration moves the view by less than 1e-4 mm and 1e-5 rad (1e-3 mm at
  // 100 mm): far below the scanner's noise, yet reachable on real data, where the trimmed
  // correspondence set keeps changing by a few pairs and ICP never becomes exactly stationary.
  icp.setTransformationEpsilon(1e-8);                    // squared mm per iteration
  icp.setTransformationRotationEpsilon(std::cos(1e-5));  // cosine of the angle per iteration
  auto same_surface = std::make_shared<pcl::registration::CorrespondenceRejectorSurfaceNormal>();
  same_surface->setThreshold(kMinNormalCosine);
  icp.addCorrespondenceRejector(same_surface);
  auto trimmed = std::make_shared<pcl::registration::CorrespondenceRejectorTrimmed>();
  trimmed->setOverlapRatio(kTrimmedOverlapRatio);
  trimmed->setMinCorrespondences(kMinCorrespondences);
  icp.addCorrespondenceRejector(trimmed);

  Refinement result;
  CloudT aligned;
  Eigen::Matrix4d guess = Eigen::Matrix4d::Identity();
  for (double distance : {coarse_mm, params.max_correspondence_mm}) {
    icp.setMaxCorrespondenceDistance(distance);
    icp.align(aligned, guess);
    result.iterations += icp.iterations();
    result.converged = icp.hasConverged();
    if (!result.converged) return result;
    guess = icp.getFinalTransformation();
  }
  result.correction.matrix() = guess;
  return result;
}

// The part of a rotation about the z axis (swing-twist decomposition), signed, in degrees.
double twist_about_z_deg(const Eigen::Matrix3d& rotation) {
  const Eigen::Quaterniond q(rotation);
  return to_deg(2.0 * std::atan2(q.z(), q.w()));
}

double wrapped_deg(double deg) { return std::remainder(deg, 360.0); }

Mesh fused_mesh(const std::vector<ViewInput>& views, const std::vector<ViewResult>& results,
                float max_edge_mm) {
  Mesh fused;
  for (std::size_t i = 0; i < views.size(); ++i) {
    // Skipped, not appended: an empty part would make Cloud::append drop everyone's normals.
    if (views[i].view->valid_count() == 0) continue;
    Mesh mesh = views[i].view->to_mesh(max_edge_mm);
    mesh.vertices.transform(results[i].pose);
    const auto offset = static_cast<std::uint32_t>(fused.vertices.size());
    fused.vertices.append(mesh.vertices);
    for (const auto& t : mesh.triangles) {
      fused.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
    }
  }
  return fused;
}

}  // namespace

Pose turntable_prior(const Pose& scanner_to_world, double turntable_angle_rad) {
  return Pose(Eigen::AngleAxisd(-turntable_angle_rad, Eigen::Vector3d::UnitZ())) * scanner_to_world;
}

Result register_views(const std::vector<ViewInput>& views, const Params& params) {
  check_input(views, params);
  Result result;
  result.views.resize(views.size());
  // Registering each view against the union of all views placed so far (not just its
  // neighbour) gives it every overlap available, and lets the last views close the loop onto
  // the first, so errors do not accumulate view by view.
  auto placed = std::make_shared<CloudT>();
  const double coarse_mm = params.max_correspondence_mm + params.max_correction_mm;

  for (std::size_t i = 0; i < views.size(); ++i) {
    ViewResult& out = result.views[i];
    out.pose = views[i].prior;
    if (views[i].view->valid_count() == 0) {
      out.flags.emplace_back("empty");
      continue;
    }
    const CloudT::Ptr view_points = view_cloud(*views[i].view, params.voxel_mm);
    if (placed->empty()) {
      out.flags.emplace_back("reference");
      *placed += *transformed(*view_points, out.pose);
      continue;
    }

    // Both clouds are expressed about the view's centroid at its prior: ICP's linearised
    // rotation is then about the data, not about a far-away origin (better conditioned).
    const CloudT::Ptr at_prior = transformed(*view_points, views[i].prior);
    Vec3d centroid = Vec3d::Zero();
    for (const auto& p : *at_prior) centroid += p.getVector3fMap().cast<double>();
    if (!at_prior->empty()) centroid /= static_cast<double>(at_prior->size());
    const Eigen::Isometry3d to_centred(Eigen::Translation3d(-centroid));
    const CloudT::Ptr source = transformed(*at_prior, to_centred);
    const CloudT::Ptr target = transformed(*placed, to_centred);
    auto target_tree = std::make_shared<pcl::search::KdTree<PointT>>();
    target_tree->setInputCloud(target);

    const Fit at_start = measure_fit(*source, *target_tree, coarse_mm);
    const bool overlaps =
        at_start.correspondences >= kMinCorrespondences && at_start.overlap >= params.min_overlap;
    if (!overlaps) out.flags.emplace_back("no_overlap");

    Eigen::Isometry3d correction = Eigen::Isometry3d::Identity();  // centred frame
    if (overlaps && params.refine_with_icp) {
      const Refinement refinement = refine(source, target, target_tree, coarse_mm, params);
      out.iterations = refinement.iterations;
      const Eigen::Isometry3d world_correction =
          to_centred.inverse() * refinement.correction * to_centred;
      out.proposed_correction_deg = to_deg(Eigen::AngleAxisd(world_correction.linear()).angle());
      out.proposed_about_z_deg = wrapped_deg(twist_about_z_deg(world_correction.linear()));
      out.proposed_correction_mm = world_correction.translation().norm();
      // The total angle bounds its twist about z (the slide a near-symmetric pot allows), so
      // this one limit also rejects ICP sliding round the turntable axis.
      const bool plausible = out.proposed_correction_deg <= params.max_correction_deg &&
                             out.proposed_correction_mm <= params.max_correction_mm;
      if (!refinement.converged) {
        out.flags.emplace_back("not_converged");
      } else if (plausible) {
        correction = refinement.correction;
        out.pose = world_correction * views[i].prior;
        out.correction_deg = out.proposed_correction_deg;
        out.correction_mm = out.proposed_correction_mm;
        out.refined = true;
      } else {
        out.flags.emplace_back("implausible_correction");
      }
    }

    const Fit final_fit =
        measure_fit(*transformed(*source, correction), *target_tree, params.max_correspondence_mm);
    out.rms_mm = final_fit.rms_mm;
    out.overlap = final_fit.overlap;

    // Views kept at their prior join too: the calibrated prior is the best pose there is.
    *placed += *transformed(*view_points, out.pose);
    placed = voxel_averaged(placed, params.voxel_mm);
    keep_unit_normals(*placed);
  }

  result.fused = fused_mesh(views, result.views, params.mesh_max_edge_mm);
  return result;
}

}  // namespace sherd::registration
