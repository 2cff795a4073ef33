#include "processing/registration/registration.h"

#include "core/errors.h"

#include <fmt/format.h>
#include <pcl/features/normal_3d.h>
#include <pcl/filters/random_sample.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>

#include <Eigen/Eigenvalues>
#include <Eigen/QR>

#include <algorithm>
#include <array>
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
      params.icp_max_points < 1 ||
      !(params.degenerate_eigenvalue_ratio >= 0 && params.degenerate_eigenvalue_ratio < 1)) {
    throw InputError(
        "registration: parameters out of range (voxel, distances, limits and iterations must be "
        "positive, min_overlap in [0, 1], degenerate_eigenvalue_ratio in [0, 1)); fix the "
        "registration parameters");
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

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

struct Pair {
  int source = 0, target = 0;
  float distance_sq = 0.f;
};

// Nearest-neighbour pairs of `source` in the tree's cloud within `max_distance_mm` and with
// compatible normals.
std::vector<Pair> nearest_pairs(const CloudT& source, const pcl::search::KdTree<PointT>& target_tree,
                                double max_distance_mm) {
  std::vector<Pair> pairs;
  const CloudT& target = *target_tree.getInputCloud();
  const double max_sq = max_distance_mm * max_distance_mm;
  std::vector<int> index(1);
  std::vector<float> distance_sq(1);
  for (std::size_t i = 0; i < source.size(); ++i) {
    const auto& p = source[i];
    if (target_tree.nearestKSearch(p, 1, index, distance_sq) < 1 || distance_sq[0] > max_sq) {
      continue;
    }
    if (p.getNormalVector3fMap().dot(target[index[0]].getNormalVector3fMap()) < kMinNormalCosine) {
      continue;
    }
    pairs.push_back({static_cast<int>(i), index[0], distance_sq[0]});
  }
  return pairs;
}

// Distance of a source point from the plane of its target point.
double along_target_normal(const PointT& source, const PointT& target) {
  return (source.getVector3fMap() - target.getVector3fMap())
      .cast<double>()
      .dot(target.getNormalVector3fMap().cast<double>());
}

struct Fit {
  std::size_t correspondences = 0;
  double rms_mm = 0.0;  // point-to-plane, over the correspondences
  double overlap = 0.0;
};

Fit measure_fit(const CloudT& source, const pcl::search::KdTree<PointT>& target_tree,
                double max_distance_mm) {
  Fit fit;
  if (source.empty()) return fit;
  const CloudT& target = *target_tree.getInputCloud();
  double sum_sq = 0.0;
  const std::vector<Pair> pairs = nearest_pairs(source, target_tree, max_distance_mm);
  for (const Pair& pair : pairs) {
    const double d = along_target_normal(source[pair.source], target[pair.target]);
    sum_sq += d * d;
  }
  fit.correspondences = pairs.size();
  if (!pairs.empty()) fit.rms_mm = std::sqrt(sum_sq / pairs.size());
  fit.overlap = static_cast<double>(pairs.size()) / source.size();
  return fit;
}

const std::array<const char*, 6> kTwistAxisNames = {"rot_x",   "rot_y",   "rot_z",
                                                    "trans_x", "trans_y", "trans_z"};

// Names the degenerate subspace (columns of `basis`, orthonormal) by world axes: greedily the
// axis that lies most in it, then the next one after removing what is already named (Gram-Schmidt)
// — eigenvectors of equal (near-zero) eigenvalues are arbitrary mixtures, the axes are not.
std::vector<DegenerateDirection> named_directions(const Eigen::Matrix<double, 6, Eigen::Dynamic>& basis,
                                                  const Matrix6d& jtj, double largest_eigenvalue) {
  std::vector<DegenerateDirection> named;
  std::vector<Vector6d> twists;
  std::array<bool, 6> used{};
  for (Eigen::Index k = 0; k < basis.cols(); ++k) {
    int best_axis = -1;
    Vector6d best = Vector6d::Zero();
    for (int axis = 0; axis < 6; ++axis) {
      if (used[axis]) continue;
      Vector6d v = basis * basis.transpose() * Vector6d::Unit(axis);
      for (const Vector6d& twist : twists) v -= twist.dot(v) * twist;
      if (best_axis < 0 || v.norm() > best.norm()) {
        best_axis = axis;
        best = v;
      }
    }
    used[best_axis] = true;
    DegenerateDirection direction;
    direction.name = kTwistAxisNames[best_axis];
    twists.push_back(best.normalized());
    Vector6d::Map(direction.twist.data()) = twists.back();
    direction.eigenvalue_ratio = twists.back().dot(jtj * twists.back()) / largest_eigenvalue;
    named.push_back(direction);
  }
  return named;
}

struct Step {
  Vector6d twist = Vector6d::Zero();  // (rotation × scale, translation)
  std::vector<DegenerateDirection> degenerate;
};

// The Gauss-Newton step of JᵀJ x = −Jᵀr, with degenerate directions found from the eigenvalues.
// With the handling on, the step is solved under the constraint that it does not move the view
// in what names each degenerate direction: for a "rot_*" one, the rotation about that
// direction's rotation axis; for a "trans_*" one, the translation along it. The view keeps the
// prior there exactly, and the constraint is metric-free: constraining the whole eigenvector
// instead (truncating the eigen-solution, Zhang, Kaess & Singh, ICRA 2016) keeps a blend of
// rotation and translation that depends on the scaling, so part of a prior's translation error
// would be turned into a rotation about the pot's axis. A prior term would need a weight to tune
// and still let noise pull the view by an amount that weight sets.
Step constrained_step(const Matrix6d& jtj, const Vector6d& jtr, const Params& params) {
  const Eigen::SelfAdjointEigenSolver<Matrix6d> eigen(jtj);
  const double largest = eigen.eigenvalues()(5);
  Step step;
  if (!(largest > 0)) return step;
  Eigen::Matrix<double, 6, Eigen::Dynamic> degenerate(6, 0);
  for (int i = 0; i < 6; ++i) {
    if (eigen.eigenvalues()(i) > params.degenerate_eigenvalue_ratio * largest) continue;
    degenerate.conservativeResize(Eigen::NoChange, degenerate.cols() + 1);
    degenerate.rightCols<1>() = eigen.eigenvectors().col(i);
  }
  step.degenerate = named_directions(degenerate, jtj, largest);

  Eigen::Matrix<double, 6, Eigen::Dynamic> held(6, 0);  // the step must be orthogonal to these
  if (params.keep_prior_in_degenerate_directions) {
    for (const auto& direction : step.degenerate) {
      Vector6d part = Vector6d::Map(direction.twist.data());
      (direction.name.starts_with("rot") ? part.tail<3>() : part.head<3>()).setZero();
      held.conservativeResize(Eigen::NoChange, held.cols() + 1);
      held.rightCols<1>() = part.normalized();
    }
  }
  // Solved in a basis of the directions left free (null-space method); the complete orthogonal
  // decomposition gives the least-norm step should the free system still be singular.
  Eigen::Matrix<double, 6, Eigen::Dynamic> free = Matrix6d::Identity();
  if (held.cols() > 0) {
    const Matrix6d q = Eigen::HouseholderQR<Eigen::Matrix<double, 6, Eigen::Dynamic>>(held)
                           .householderQ();
    free = q.rightCols(6 - held.cols());
  }
  const Eigen::MatrixXd reduced = free.transpose() * jtj * free;
  step.twist = free * Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(reduced).solve(
                          -(free.transpose() * jtr));
  return step;
}

struct Refinement {
  Eigen::Isometry3d correction = Eigen::Isometry3d::Identity();  // in the clouds' frame
  int iterations = 0;
  bool converged = false;
  std::vector<DegenerateDirection> degenerate;  // of the last iteration
};

// Point-to-plane ICP on `source` (centred on its centroid, RMS radius `scale_mm`), our own
// Gauss-Newton loop rather than PCL's IterativeClosestPointWithNormals: the degeneracy handling
// must act on every step's normal equations, which PCL's transformation estimators do not
// expose, and projecting only PCL's final result would come after ICP has already slid.
// Coarse then fine: the first pass accepts pairs as far apart as a plausible prior error (so a
// prior off by up to max_correction_mm still finds its surface), the second tightens to
// max_correspondence_mm so that the final pose is set by close, reliable pairs only.
Refinement refine(const CloudT::Ptr& source, const pcl::search::KdTree<PointT>& target_tree,
                  double coarse_mm, double scale_mm, const Params& params) {
  CloudT::Ptr icp_source = source;
  if (source->size() > static_cast<std::size_t>(params.icp_max_points)) {
    icp_source = std::make_shared<CloudT>();
    pcl::RandomSample<PointT> sample;
    sample.setInputCloud(source);
    sample.setSample(static_cast<unsigned>(params.icp_max_points));
    sample.setSeed(kSampleSeed);
    sample.filter(*icp_source);
  }
  const CloudT& target = *target_tree.getInputCloud();

  Refinement result;
  for (double distance : {coarse_mm, params.max_correspondence_mm}) {
    for (int iteration = 0; iteration < params.max_iterations; ++iteration) {
      const CloudT::Ptr moved = transformed(*icp_source, result.correction);
      std::vector<Pair> pairs = nearest_pairs(*moved, target_tree, distance);
      if (pairs.size() < kMinCorrespondences) return result;  // lost its surface: not converged
      // Trimmed: only the closest share of the pairs pulls.
      const std::size_t kept = std::min(
          pairs.size(), std::max(kMinCorrespondences, static_cast<std::size_t>(
                                                          kTrimmedOverlapRatio * pairs.size())));
      std::nth_element(pairs.begin(), pairs.begin() + (kept - 1), pairs.end(),
                       [](const Pair& a, const Pair& b) { return a.distance_sq < b.distance_sq; });
      pairs.resize(kept);

      Matrix6d jtj = Matrix6d::Zero();
      Vector6d jtr = Vector6d::Zero();
      for (const Pair& pair : pairs) {
        const PointT& p = (*moved)[pair.source];
        const PointT& q = target[pair.target];
        const Vec3d normal = q.getNormalVector3fMap().cast<double>();
        Vector6d row;
        row << p.getVector3fMap().cast<double>().cross(normal) / scale_mm, normal;
        jtj.selfadjointView<Eigen::Lower>().rankUpdate(row);
        jtr += row * along_target_normal(p, q);
      }
      jtj = jtj.selfadjointView<Eigen::Lower>();

      Step step = constrained_step(jtj, jtr, params);
      const Vec3d rotation = step.twist.head<3>() / scale_mm;
      const Vec3d translation = step.twist.tail<3>();
      const double angle = rotation.norm();
      Eigen::Isometry3d delta{Eigen::Translation3d(translation)};
      if (angle > 0) delta.rotate(Eigen::AngleAxisd(angle, rotation / angle));
      result.correction = delta * result.correction;
      result.degenerate = std::move(step.degenerate);
      ++result.iterations;
      // Converged when an iteration moves the view by less than 1e-4 mm and 1e-5 rad (1e-3 mm
      // at 100 mm): far below the scanner's noise, yet reachable on real data, where the trimmed
      // pair set keeps changing by a few pairs and ICP never becomes exactly stationary.
      if (translation.norm() < 1e-4 && angle < 1e-5) break;
    }
  }
  // Like PCL's default criteria, running out of iterations still counts as converged.
  result.converged = true;
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
    double sum_sq_radius = 0.0;
    for (const auto& p : *source) sum_sq_radius += p.getVector3fMap().cast<double>().squaredNorm();
    if (!source->empty()) out.rms_radius_mm = std::sqrt(sum_sq_radius / source->size());
    const CloudT::Ptr target = transformed(*placed, to_centred);
    auto target_tree = std::make_shared<pcl::search::KdTree<PointT>>();
    target_tree->setInputCloud(target);

    const Fit at_start = measure_fit(*source, *target_tree, coarse_mm);
    const bool overlaps =
        at_start.correspondences >= kMinCorrespondences && at_start.overlap >= params.min_overlap;
    if (!overlaps) out.flags.emplace_back("no_overlap");

    Eigen::Isometry3d correction = Eigen::Isometry3d::Identity();  // centred frame
    if (overlaps && params.refine_with_icp) {
      const Refinement refinement =
          refine(source, *target_tree, coarse_mm, out.rms_radius_mm, params);
      out.iterations = refinement.iterations;
      out.degenerate = refinement.degenerate;
      for (const auto& direction : out.degenerate) out.flags.push_back("degenerate:" + direction.name);
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
