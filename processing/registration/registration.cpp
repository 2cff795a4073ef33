#include "processing/registration/registration.h"

#include <fmt/format.h>
#include <pcl/features/normal_3d.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <random>
#include <set>

#include "core/errors.h"

namespace sherd::registration {

namespace {

// Colour rides along in the rgb field (averaged by the voxel grid) for the photometric term.
using PointT = pcl::PointXYZRGBNormal;
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
// The second round refines a pair again only where the first solve put it this far (at its
// centroid, or its rotation at its RMS radius) from its own first result: the scanner's noise.
constexpr double kRefineAgainMm = 0.05;
// Fixed so that registering the same views twice gives the same poses.
constexpr unsigned kSampleSeed = 20240601;
// Radius searches need no ordering (a nearest-within-radius search with max_nn = 1 keeps the best
// one either way); PCL's default sorts every result list by distance.
constexpr bool kUnsortedResults = false;

double to_deg(double rad) { return rad * 180.0 / std::numbers::pi; }

void check_input(const std::vector<ViewInput>& views, const PriorUncertainty& prior,
                 const Params& params) {
  if (!(params.voxel_mm > 0) || !(params.max_correspondence_mm > 0) || params.max_iterations < 1 ||
      !(params.max_correction_deg > 0) || !(params.max_correction_mm > 0) ||
      !(params.min_edge_overlap > 0 && params.min_edge_overlap <= 1) ||
      params.max_extra_edges_per_view < 0 || params.icp_max_points < 1 ||
      !(params.colour_max_sd_mm > 0) ||
      !(params.degenerate_eigenvalue_ratio >= 0 && params.degenerate_eigenvalue_ratio < 1)) {
    throw InputError(
        "registration: parameters out of range (voxel, distances, limits and iterations must be "
        "positive, as must colour_max_sd_mm; min_edge_overlap in (0, 1], "
        "degenerate_eigenvalue_ratio in [0, 1)); fix the "
        "registration parameters");
  }
  if (const auto& rays = params.parallel_rays_towards_scanner;
      rays && !(rays->allFinite() && rays->norm() > 0)) {
    throw InputError(fmt::format(
        "registration: parallel_rays_towards_scanner ({}, {}, {}) is not a direction; give the "
        "scanner's viewing direction in its own frame, or leave it unset for a camera",
        rays->x(), rays->y(), rays->z()));
  }
  if (!(prior.angle_sd_deg > 0) || !(prior.tilt_sd_deg > 0) || !(prior.translation_sd_mm > 0) ||
      !std::isfinite(prior.angle_sd_deg + prior.tilt_sd_deg + prior.translation_sd_mm)) {
    throw InputError(
        fmt::format("registration: the turntable prior's uncertainty must be positive and finite "
                    "(angle {} deg, "
                    "tilt {} deg, translation {} mm); check the turntable calibration and "
                    "turntable.angle_sd_deg",
                    prior.angle_sd_deg, prior.tilt_sd_deg, prior.translation_sd_mm));
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
    view->check("registration", i);
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

// The view's valid cells, voxel-averaged, with unit normals and colours, in the scanner frame.
// Normals come from the scanner where it gave them, else are estimated from neighbours and turned
// towards the scanner (the origin of its frame).
CloudT::Ptr view_cloud(const OrganisedView& view, double voxel_mm) {
  const bool has_normals = view.normals.size() == view.cells();
  const bool has_colours = view.colours.size() == view.cells();
  auto raw = std::make_shared<CloudT>();
  raw->reserve(view.valid_count());
  for (std::size_t c = 0; c < view.cells(); ++c) {
    if (!view.valid[c]) continue;
    PointT p;
    p.getVector3fMap() = view.points[c];
    p.getNormalVector3fMap() =
        has_normals ? view.normals[c] : Eigen::Vector3f(std::nanf(""), 0.f, 0.f);
    p.curvature = 0.f;
    if (has_colours) {
      p.r = view.colours[c].r;
      p.g = view.colours[c].g;
      p.b = view.colours[c].b;
    }
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
    (*out)[i].rgba = cloud[i].rgba;
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
std::vector<Pair> nearest_pairs(const CloudT& source,
                                const pcl::search::KdTree<PointT>& target_tree,
                                double max_distance_mm) {
  std::vector<Pair> pairs;
  const CloudT& target = *target_tree.getInputCloud();
  const double max_sq = max_distance_mm * max_distance_mm;
  std::vector<int> index(1);
  std::vector<float> distance_sq(1);
  for (std::size_t i = 0; i < source.size(); ++i) {
    const auto& p = source[i];
    // The nearest point within the distance, exactly: bounded by it, the tree prunes from the
    // start, where an unbounded nearest search for a point off the target's surface (outside the
    // overlap, or in the coarse stages) first descends to some far leaf and widens from there.
    // Measured on the bunny: 0.94 → 0.52 s per view, poses unchanged.
    if (target_tree.radiusSearch(p, max_distance_mm, index, distance_sq, 1) < 1 ||
        distance_sq[0] > max_sq) {
      continue;
    }
    if (p.getNormalVector3fMap().dot(target[index[0]].getNormalVector3fMap()) < kMinNormalCosine) {
      continue;
    }
    pairs.push_back({static_cast<int>(i), index[0], distance_sq[0]});
  }
  return pairs;
}

// A fingerprint of which source point pairs with which target point (FNV-1a over the indices).
std::uint64_t pairing_hash(const std::vector<Pair>& pairs) {
  std::uint64_t hash = 1469598103934665603ull;
  for (const Pair& pair : pairs) {
    for (const int index : {pair.source, pair.target}) {
      hash ^= static_cast<std::uint32_t>(index);
      hash *= 1099511628211ull;
    }
  }
  return hash;
}

// Distance of a source point from the plane of its target point.
double along_target_normal(const PointT& source, const PointT& target) {
  return (source.getVector3fMap() - target.getVector3fMap())
      .cast<double>()
      .dot(target.getNormalVector3fMap().cast<double>());
}

const std::array<const char*, 6> kTwistAxisNames = {"rot_x",   "rot_y",   "rot_z",
                                                    "trans_x", "trans_y", "trans_z"};

// Names the degenerate subspace (columns of `basis`, orthonormal) by world axes: greedily the
// axis that lies most in it, then the next one after removing what is already named (Gram-Schmidt)
// — eigenvectors of equal (near-zero) eigenvalues are arbitrary mixtures, the axes are not.
std::vector<DegenerateDirection> named_directions(
    const Eigen::Matrix<double, 6, Eigen::Dynamic>& basis, const Matrix6d& jtj,
    double largest_eigenvalue) {
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

// Weighted Gauss-Newton normal equations of residual rows in ICP's twist (rotation scaled by the
// source's RMS radius, about its centroid): a residual along `direction` at the scaled offset
// `arm` from the centroid.
struct NormalEquations {
  Matrix6d jtj = Matrix6d::Zero();
  Vector6d jtr = Vector6d::Zero();
  std::size_t rows = 0;

  void add(const Vec3d& arm, const Vec3d& direction, double residual, double weight) {
    Vector6d row;
    row << arm.cross(direction), direction;
    jtj.selfadjointView<Eigen::Lower>().rankUpdate(row, weight);
    jtr += weight * residual * row;
    ++rows;
  }
  void complete() { jtj = jtj.selfadjointView<Eigen::Lower>(); }
};

// The eigen-directions of JᵀJ whose eigenvalue is below degenerate_eigenvalue_ratio × the largest
// (orthonormal columns), named by world axes.
struct Degeneracy {
  Eigen::Matrix<double, 6, Eigen::Dynamic> basis{6, 0};
  std::vector<DegenerateDirection> named;
  double largest_eigenvalue = 0.0;  // of the JᵀJ it was found in

  Matrix6d projector() const { return basis * basis.transpose(); }
};

Degeneracy find_degeneracy(const Matrix6d& jtj, const Params& params) {
  const Eigen::SelfAdjointEigenSolver<Matrix6d> eigen(jtj);
  const double largest = eigen.eigenvalues()(5);
  Degeneracy degeneracy;
  degeneracy.largest_eigenvalue = largest;
  if (!(largest > 0)) return degeneracy;
  for (int i = 0; i < 6; ++i) {
    if (eigen.eigenvalues()(i) > params.degenerate_eigenvalue_ratio * largest) continue;
    degeneracy.basis.conservativeResize(Eigen::NoChange, degeneracy.basis.cols() + 1);
    degeneracy.basis.rightCols<1>() = eigen.eigenvectors().col(i);
  }
  degeneracy.named = named_directions(degeneracy.basis, jtj, largest);
  return degeneracy;
}

// The Gauss-Newton step of JᵀJ x = −Jᵀr that does not move the view in what names each `held`
// direction: for a "rot_*" one, the rotation about that direction's rotation axis; for a "trans_*"
// one, the translation along it. The view keeps the
// prior there exactly, and the constraint is metric-free: constraining the whole eigenvector
// instead (truncating the eigen-solution, Zhang, Kaess & Singh, ICRA 2016) keeps a blend of
// rotation and translation that depends on the scaling, so part of a prior's translation error
// would be turned into a rotation about the pot's axis. A prior term would need a weight to tune
// and still let noise pull the view by an amount that weight sets.
Vector6d constrained_step(const Matrix6d& jtj, const Vector6d& jtr,
                          const std::vector<DegenerateDirection>& held_directions) {
  if (!(jtj.diagonal().maxCoeff() > 0)) return Vector6d::Zero();
  Eigen::Matrix<double, 6, Eigen::Dynamic> held(6, 0);  // the step must be orthogonal to these
  for (const auto& direction : held_directions) {
    Vector6d part = Vector6d::Map(direction.twist.data());
    (direction.name.starts_with("rot") ? part.tail<3>() : part.head<3>()).setZero();
    held.conservativeResize(Eigen::NoChange, held.cols() + 1);
    held.rightCols<1>() = part.normalized();
  }
  // Solved in a basis of the directions left free (null-space method); the complete orthogonal
  // decomposition gives the least-norm step should the free system still be singular.
  Eigen::Matrix<double, 6, Eigen::Dynamic> free = Matrix6d::Identity();
  if (held.cols() > 0) {
    const Matrix6d q =
        Eigen::HouseholderQR<Eigen::Matrix<double, 6, Eigen::Dynamic>>(held).householderQ();
    free = q.rightCols(6 - held.cols());
  }
  const Eigen::MatrixXd reduced = free.transpose() * jtj * free;
  return free * Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(reduced).solve(
                    -(free.transpose() * jtr));
}

// The directions the geometry cannot see, split by what the colour sees among them: those where
// the photometric equations alone pin the view to params.colour_max_sd_mm (rotations measured at
// the view's RMS radius) are seen; the rest are held at the prior. The geometry's relative
// eigenvalue test cannot judge the colour: its information is of another kind, a few hundredths
// of the geometry's strongest direction yet worth hundredths of a degree.
struct ColourSplit {
  Eigen::Matrix<double, 6, Eigen::Dynamic> seen{6, 0};
  Degeneracy held;
};

ColourSplit split_by_colour(const Degeneracy& silent, const Matrix6d& photometric_jtj,
                            const Matrix6d& geometric_jtj, const Params& params) {
  ColourSplit split;
  if (silent.basis.cols() == 0) return split;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(silent.basis.transpose() *
                                                             photometric_jtj * silent.basis);
  const double min_information = 1.0 / (params.colour_max_sd_mm * params.colour_max_sd_mm);
  for (Eigen::Index i = 0; i < eigen.eigenvalues().size(); ++i) {
    auto& basis = eigen.eigenvalues()(i) >= min_information ? split.seen : split.held.basis;
    basis.conservativeResize(Eigen::NoChange, basis.cols() + 1);
    basis.rightCols<1>() = silent.basis * eigen.eigenvectors().col(i);
  }
  if (split.seen.cols() == 0) {
    split.held = silent;
  } else if (split.held.basis.cols() > 0) {
    split.held.largest_eigenvalue = silent.largest_eigenvalue;
    split.held.named = named_directions(split.held.basis, geometric_jtj, silent.largest_eigenvalue);
  }
  return split;
}

// ---------------------------------------------------------------------------------------------
// Colour for the photometric term

// The photometric term compares a local contrast, not raw colour: a point's intensity over the
// mean intensity within kContrastRadiusVoxels. The scanner's own light shades the same surface
// differently from every turntable stop, smoothly over centimetres; the clay's mottling varies over
// millimetres. The ratio keeps the mottling and cancels the shading. Its gradient on each target
// point's tangent plane is fitted over kGradientRadiusVoxels (Park, Zhou & Koltun, ICCV 2017).
constexpr double kContrastRadiusVoxels = 4.0;
constexpr double kGradientRadiusVoxels = 2.5;
// The smallest standard deviations the terms' weights assume: a scanner's depth noise is not below
// 0.01 mm, 8-bit intensity (0–1) not below half a level. Without a floor, a plain background
// (contrast exactly 0, residuals exactly 0) would give the photometric term an unbounded weight.
constexpr double kGeometricNoiseFloorMm = 0.01;
constexpr double kIntensityNoiseFloor = 0.5 / 255.0;
// The photometric rows' robust kernel (Huber's threshold in standard deviations; 1.345 keeps 95 %
// of least squares' efficiency on Gaussian noise). Measured (bench_registration --seeds 3 --scenes
// vessel): p95 rotation error 0.33° without it, 0.12° with it, 0.074° with the brightness scaling.
constexpr double kHuberThreshold = 1.345;
// Fewer neighbours than this give no usable contrast or gradient.
constexpr std::size_t kMinColourNeighbours = 6;

double intensity(const PointT& p) { return (p.r + p.g + p.b) / 765.0; }

bool has_colour(const OrganisedView& view) {
  if (view.colours.size() != view.cells()) return false;
  for (std::size_t c = 0; c < view.cells(); ++c) {
    if (view.valid[c] && (view.colours[c].r || view.colours[c].g || view.colours[c].b)) return true;
  }
  return false;
}

// Per point of a view: its contrast (intensity / local mean − 1; NaN where too few neighbours or
// too dark to tell), that local mean (brightness), and the contrast's gradient in its tangent plane
// (least squares over the neighbours projected onto that plane; zero where it cannot be fitted).
// Each is computed where the photometric term first asks for it: the source's sample and the
// target points it pairs with, and their neighbourhoods — about a quarter of a simulated vessel's
// view. Computed for every point up front, the radius searches took half of its registration time.
class ColourField {
 public:
  ColourField() = default;  // a view without colour
  ColourField(CloudT::ConstPtr cloud, std::shared_ptr<const pcl::search::KdTree<PointT>> tree,
              double voxel_mm)
      : cloud_(std::move(cloud)),
        tree_(std::move(tree)),
        contrast_radius_mm_(kContrastRadiusVoxels * voxel_mm),
        gradient_radius_mm_(kGradientRadiusVoxels * voxel_mm),
        point_(cloud_->size()) {}

  bool empty() const { return point_.empty(); }
  float contrast(std::size_t i) const { return with_contrast(i).contrast; }
  float brightness(std::size_t i) const { return with_contrast(i).brightness; }
  const Eigen::Vector3f& gradient(std::size_t i) const;

 private:
  struct PointColour {
    bool contrast_known = false, gradient_known = false;
    float contrast = std::numeric_limits<float>::quiet_NaN();
    float brightness = 0.0f;
    Eigen::Vector3f gradient = Eigen::Vector3f::Zero();
  };
  const PointColour& with_contrast(std::size_t i) const;

  CloudT::ConstPtr cloud_;
  std::shared_ptr<const pcl::search::KdTree<PointT>> tree_;
  double contrast_radius_mm_ = 0.0, gradient_radius_mm_ = 0.0;
  // Filled on first request; a view's field serves one registration, on one thread.
  mutable std::vector<PointColour> point_;
  mutable std::vector<int> index_;
  mutable std::vector<float> distance_sq_;
};

const ColourField::PointColour& ColourField::with_contrast(std::size_t i) const {
  PointColour& out = point_[i];
  if (out.contrast_known) return out;
  out.contrast_known = true;
  const CloudT& cloud = *cloud_;
  if (tree_->radiusSearch(cloud[i], contrast_radius_mm_, index_, distance_sq_) <
      static_cast<int>(kMinColourNeighbours)) {
    return out;
  }
  double sum = 0.0;
  for (int k : index_) sum += intensity(cloud[k]);
  const double mean = sum / static_cast<double>(index_.size());
  out.brightness = static_cast<float>(mean);
  if (mean > 0.02) out.contrast = static_cast<float>(intensity(cloud[i]) / mean - 1.0);
  return out;
}

const Eigen::Vector3f& ColourField::gradient(std::size_t i) const {
  PointColour& out = point_[i];
  if (out.gradient_known) return out.gradient;
  out.gradient_known = true;
  const float centre = contrast(i);
  const CloudT& cloud = *cloud_;
  if (!std::isfinite(centre) ||
      tree_->radiusSearch(cloud[i], gradient_radius_mm_, index_, distance_sq_) <
          static_cast<int>(kMinColourNeighbours)) {
    return out.gradient;
  }
  const std::vector<int> neighbours = index_;  // contrast() below reuses the search buffers
  const Eigen::Vector3f n = cloud[i].getNormalVector3fMap();
  const Eigen::Vector3f t1 = n.unitOrthogonal(), t2 = n.cross(t1);
  Eigen::Matrix2d a = Eigen::Matrix2d::Zero();
  Eigen::Vector2d b = Eigen::Vector2d::Zero();
  for (int k : neighbours) {
    if (k == static_cast<int>(i)) continue;
    const float other = contrast(static_cast<std::size_t>(k));
    if (!std::isfinite(other)) continue;
    const Eigen::Vector3f d = cloud[k].getVector3fMap() - cloud[i].getVector3fMap();
    const Eigen::Vector2d u(t1.dot(d), t2.dot(d));
    a += u * u.transpose();
    b += u * static_cast<double>(other - centre);
  }
  const Eigen::LDLT<Eigen::Matrix2d> solve(a);
  if (solve.info() != Eigen::Success || a.determinant() < 1e-6 * a.trace() * a.trace())
    return out.gradient;
  const Eigen::Vector2d g = solve.solve(b);
  out.gradient = static_cast<float>(g.x()) * t1 + static_cast<float>(g.y()) * t2;
  return out.gradient;
}

// ---------------------------------------------------------------------------------------------
// One view, prepared once and shared by all its edges

struct ViewData {
  CloudT::Ptr at_prior;  // voxel points in the world frame at the view's prior
  std::shared_ptr<pcl::search::KdTree<PointT>> tree;  // over at_prior
  ColourField colour;                                 // per point of at_prior; empty: no colour
  std::vector<int> sample;  // the points ICP iterates on (a fixed random subset of at_prior)
  Vec3d centroid = Vec3d::Zero();
  double rms_radius_mm = 0.0;  // about the centroid: scales rotations to millimetres
  // How far the prior's uncertainty may move a point of this view (1 σ, mm).
  double prior_displacement_sd_mm = 0.0;
  // Per point of at_prior: |cos| of the angle between its normal and its ray to the scanner
  // (filled only where Params::weight_by_incidence asks for it).
  std::vector<float> incidence;

  bool coloured() const { return !colour.empty(); }
};

ViewData prepare_view(const ViewInput& input, const PriorUncertainty& prior, const Params& params) {
  ViewData data;
  const CloudT::Ptr in_scanner_frame = view_cloud(*input.view, params.voxel_mm);
  if (params.weight_by_incidence) {
    const auto& parallel = params.parallel_rays_towards_scanner;
    const Eigen::Vector3f parallel_ray =
        parallel ? Eigen::Vector3f(parallel->cast<float>().normalized()) : Eigen::Vector3f::Zero();
    data.incidence.reserve(in_scanner_frame->size());
    for (const auto& p : *in_scanner_frame) {
      const Eigen::Vector3f towards_scanner =
          parallel ? parallel_ray : Eigen::Vector3f(-p.getVector3fMap().normalized());
      data.incidence.push_back(std::abs(p.getNormalVector3fMap().dot(towards_scanner)));
    }
  }
  data.at_prior = transformed(*in_scanner_frame, input.prior);
  const CloudT& cloud = *data.at_prior;
  if (cloud.empty()) return data;
  data.tree = std::make_shared<pcl::search::KdTree<PointT>>(kUnsortedResults);
  data.tree->setInputCloud(data.at_prior);
  if (params.use_colour && has_colour(*input.view)) {
    data.colour = ColourField(data.at_prior, data.tree, params.voxel_mm);
  }
  data.sample.resize(cloud.size());
  std::iota(data.sample.begin(), data.sample.end(), 0);
  if (data.sample.size() > static_cast<std::size_t>(params.icp_max_points)) {
    std::mt19937 rng(kSampleSeed);
    std::shuffle(data.sample.begin(), data.sample.end(), rng);
    data.sample.resize(static_cast<std::size_t>(params.icp_max_points));
  }
  double axis_sq = 0.0, origin_sq = 0.0;
  for (const auto& p : cloud) {
    const Vec3d x = p.getVector3fMap().cast<double>();
    data.centroid += x;
    axis_sq += x.head<2>().squaredNorm();
    origin_sq += x.squaredNorm();
  }
  const auto n = static_cast<double>(cloud.size());
  data.centroid /= n;
  double radius_sq = 0.0;
  for (const auto& p : cloud)
    radius_sq += (p.getVector3fMap().cast<double>() - data.centroid).squaredNorm();
  data.rms_radius_mm = std::sqrt(radius_sq / n);
  constexpr double kRad = std::numbers::pi / 180.0;
  data.prior_displacement_sd_mm = prior.translation_sd_mm +
                                  prior.angle_sd_deg * kRad * std::sqrt(axis_sq / n) +
                                  prior.tilt_sd_deg * kRad * std::sqrt(origin_sq / n);
  return data;
}

// ---------------------------------------------------------------------------------------------
// Pairwise refinement

// Twists are (rotation, translation) of x ↦ R(ω)·x + t in the world frame, about its origin
// ("origin twists"), unless said otherwise. ICP's own twists are about the source's centroid c
// with the rotation scaled by its RMS radius s (well conditioned); A maps an origin twist to that
// one: the rotation times s, and the displacement of c, ω × c + t.
Matrix6d centred_from_origin(const Vec3d& c, double s) {
  Matrix6d a = Matrix6d::Zero();
  a.topLeftCorner<3, 3>() = s * Eigen::Matrix3d::Identity();
  a.bottomLeftCorner<3, 3>() << 0, c.z(), -c.y(), -c.z(), 0, c.x(), c.y(), -c.x(), 0;  // −[c]×
  a.bottomRightCorner<3, 3>() = Eigen::Matrix3d::Identity();
  return a;
}

Eigen::Isometry3d exp_twist(const Vector6d& twist) {
  Eigen::Isometry3d t{Eigen::Translation3d(twist.tail<3>())};
  const double angle = twist.head<3>().norm();
  if (angle > 0) t.rotate(Eigen::AngleAxisd(angle, twist.head<3>() / angle));
  return t;
}

Vector6d log_twist(const Eigen::Isometry3d& t) {
  const Eigen::AngleAxisd rotation(t.linear());
  Vector6d twist;
  twist << rotation.angle() * rotation.axis(), t.translation();
  return twist;
}

// Robust standard deviation of residuals (1.4826 × median absolute value), at least `floor`.
double robust_sd(std::vector<double> residuals, double floor) {
  if (residuals.empty()) return floor;
  const auto middle = residuals.begin() + static_cast<std::ptrdiff_t>(residuals.size() / 2);
  for (auto& r : residuals) r = std::abs(r);
  std::nth_element(residuals.begin(), middle, residuals.end());
  return std::max(floor, 1.4826 * *middle);
}

struct PairRefinement {
  Eigen::Isometry3d correction = Eigen::Isometry3d::Identity();  // world frame, of the source
  int iterations = 0;
  bool converged = false;
  bool used_colour = false;  // the colour constrained what the geometry could not
  // What the geometry alone could not see in the last stage (colour may have seen it since).
  std::vector<DegenerateDirection> geometry_degenerate;
  std::vector<DegenerateDirection> degenerate;  // of the last iteration
  Matrix6d information = Matrix6d::Zero();  // origin twist of the source, degenerate part removed
  // Projector onto the directions the pair does see, in ICP's twist about the source's centroid.
  Matrix6d seen = Matrix6d::Zero();
};

// Point-to-plane ICP of `source` onto `target` (both at their priors) with, in the last stage and
// where both views have colour, the photometric term; our own Gauss-Newton loop rather than PCL's
// IterativeClosestPointWithNormals: the degeneracy handling must act on every step's normal
// equations, which PCL's transformation estimators do not expose, and PCL has no colour term.
// Coarse to fine: the correspondence distance starts at what the priors' uncertainty allows and
// halves down to max_correspondence_mm, so that the final pose is set by close pairs only. Each
// term is weighted by the inverse of its own robust residual variance (millimetres and contrast
// are different units; the data say how reliable each is).
PairRefinement refine_pair(const ViewData& target, const ViewData& source,
                           const Eigen::Isometry3d& initial, double coarse_mm, bool use_colour,
                           double max_colour_slide_rad, const Params& params) {
  std::vector<double> distances{coarse_mm};
  while (distances.back() > params.max_correspondence_mm * 1.5)
    distances.push_back(distances.back() / 2);
  distances.push_back(params.max_correspondence_mm);
  const CloudT& target_cloud = *target.at_prior;
  CloudT sample;
  sample.reserve(source.sample.size());
  for (int i : source.sample) sample.push_back((*source.at_prior)[i]);
  // The coarse stages only bring the pair within reach of the next: a sixth of the sample (the
  // sample is random, so a prefix is too) and a tolerance of 1 % of their distance.
  CloudT coarse_sample;
  const std::size_t coarse_count =
      std::min(sample.size(), std::max<std::size_t>(kMinCorrespondences * 10, sample.size() / 6));
  for (std::size_t k = 0; k < coarse_count; ++k) coarse_sample.push_back(sample[k]);
  const Vec3d& c = source.centroid;
  const double s = std::max(source.rms_radius_mm, 1.0);

  PairRefinement result;
  result.correction = initial;
  Matrix6d last_jtj = Matrix6d::Zero();
  Matrix6d last_held = Matrix6d::Zero();  // projector onto the held directions
  bool colour_allowed = use_colour && target.coloured() && source.coloured();
  const auto run_stages = [&](std::size_t first_stage) {
    for (std::size_t stage = first_stage; stage < distances.size(); ++stage) {
      const bool last_stage = stage + 1 == distances.size();
      const bool colour = last_stage && colour_allowed;
      const CloudT& points = last_stage ? sample : coarse_sample;
      const double tolerance_mm = last_stage ? 1e-3 : 0.01 * distances[stage];
      // ICP alternates pairing and solving; once a pairing comes back, the alternation has entered
      // a cycle (a few pairs toggling in and out of the trimmed set, each toggle moving the view
      // by ~0.01 mm) and further iterations only go round it. Measured on textured simulated
      // vessels: without this, half the coloured pairs ran into the iteration limit for the same
      // accuracy and twice the time.
      std::set<std::uint64_t> pairings_seen;
      for (int iteration = 0; iteration < params.max_iterations; ++iteration) {
        const CloudT::Ptr moved = transformed(points, result.correction);
        std::vector<Pair> pairs = nearest_pairs(*moved, *target.tree, distances[stage]);
        if (pairs.size() < kMinCorrespondences) return false;  // lost its surface: not converged
        if (!pairings_seen.insert(pairing_hash(pairs)).second) break;
        // Trimmed: only the closest share of the pairs pulls.
        const std::size_t kept = std::min(
            pairs.size(), std::max(kMinCorrespondences,
                                   static_cast<std::size_t>(kTrimmedOverlapRatio * pairs.size())));
        std::nth_element(
            pairs.begin(), pairs.begin() + (kept - 1), pairs.end(),
            [](const Pair& a, const Pair& b) { return a.distance_sq < b.distance_sq; });
        pairs.resize(kept);

        // Photometric rows in intensity units: the contrast is intensity over the local mean, so
        // its noise grows as the clay darkens; times the darker view's local mean, every row has
        // the camera's own noise again. Unscaled, a dark pot's rows (seed 3 of the bench: mean
        // intensity 0.17) outweighed its textured, bright rows and the pairs settled 0.3–0.5° off.
        std::vector<double> geometric(pairs.size()), photometric, brightness;
        for (std::size_t k = 0; k < pairs.size(); ++k) {
          geometric[k] =
              along_target_normal((*moved)[pairs[k].source], target_cloud[pairs[k].target]);
        }
        if (colour) {
          photometric.assign(pairs.size(), std::numeric_limits<double>::quiet_NaN());
          brightness.assign(pairs.size(), 0.0);
          for (std::size_t k = 0; k < pairs.size(); ++k) {
            const int q = pairs[k].target;
            const auto s_index = static_cast<std::size_t>(source.sample[pairs[k].source]);
            const float cs = source.colour.contrast(s_index);
            if (!std::isfinite(cs) || !std::isfinite(target.colour.contrast(q))) continue;
            const Eigen::Vector3f offset =
                (*moved)[pairs[k].source].getVector3fMap() - target_cloud[q].getVector3fMap();
            brightness[k] =
                std::min(target.colour.brightness(q), source.colour.brightness(s_index));
            photometric[k] = brightness[k] * (target.colour.contrast(q) +
                                              target.colour.gradient(q).dot(offset) - cs);
          }
        }
        const double geometric_weight =
            1.0 / std::pow(robust_sd(geometric, kGeometricNoiseFloorMm), 2);
        std::vector<double> finite;
        for (double r : photometric) {
          if (std::isfinite(r)) finite.push_back(r);
        }
        const double photometric_sd = robust_sd(finite, kIntensityNoiseFloor);
        const double photometric_weight = 1.0 / (photometric_sd * photometric_sd);

        NormalEquations geometry, photometry;
        const bool by_incidence = last_stage && params.weight_by_incidence;
        for (std::size_t k = 0; k < pairs.size(); ++k) {
          const Vec3d p = (*moved)[pairs[k].source].getVector3fMap().cast<double>();
          const double incidence = by_incidence
                                       ? static_cast<double>(target.incidence[pairs[k].target]) *
                                             source.incidence[source.sample[pairs[k].source]]
                                       : 1.0;
          geometry.add((p - c) / s,
                       target_cloud[pairs[k].target].getNormalVector3fMap().cast<double>(),
                       geometric[k], incidence * incidence * geometric_weight);
          if (colour && std::isfinite(photometric[k])) {
            // Huber: a row beyond kHuberThreshold standard deviations (a shadow's or an
            // occlusion's edge, which moves with the scanner, not with the clay) pulls with a
            // constant force instead of one growing with its residual.
            const double sds = std::abs(photometric[k]) / photometric_sd;
            const double huber = sds > kHuberThreshold ? kHuberThreshold / sds : 1.0;
            photometry.add((p - c) / s,
                           brightness[k] * target.colour.gradient(pairs[k].target).cast<double>(),
                           photometric[k], huber * photometric_weight);
          }
        }
        geometry.complete();
        photometry.complete();
        // The colour speaks only where the shape is silent: its equations enter projected onto
        // the directions the geometry cannot constrain and it can. Elsewhere geometry is the
        // better judge (shading and occlusion edges move the colour's apparent position by a
        // fraction of a millimetre between stops), so on a tray the result is the geometric one.
        Degeneracy silent;
        if (params.keep_prior_in_degenerate_directions) {
          silent = find_degeneracy(geometry.jtj, params);
        }
        ColourSplit split = split_by_colour(silent, photometry.jtj, geometry.jtj, params);
        const Matrix6d project = split.seen * split.seen.transpose();
        const Matrix6d jtj = geometry.jtj + project * photometry.jtj * project;
        const Vector6d jtr = geometry.jtr + project * photometry.jtr;
        last_jtj = jtj;
        last_held = split.held.projector();
        if (last_stage) result.geometry_degenerate = silent.named;
        result.used_colour = split.seen.cols() > 0;

        const Vector6d twist = constrained_step(jtj, jtr, split.held.named);
        const Vec3d rotation = twist.head<3>() / s;
        const Vec3d translation = twist.tail<3>();
        const double angle = rotation.norm();
        Eigen::Isometry3d delta{Eigen::Translation3d(c + translation)};
        if (angle > 0) delta.rotate(Eigen::AngleAxisd(angle, rotation / angle));
        delta.translate(-c);
        result.correction = delta * result.correction;
        result.degenerate = std::move(split.held.named);
        ++result.iterations;
        // The last stage has converged when an iteration moves the view by less than 1e-3 mm
        // (rotation measured at the RMS radius): far below the scanner's noise, yet reachable on
        // real data, where the trimmed pair set keeps changing by a few pairs and ICP never becomes
        // exactly stationary. Measured on the bunny: 1e-4 mm ran into the iteration limit on half
        // the pairs for the same result (0.136°) and 30 % more time.
        if (translation.norm() < tolerance_mm && angle * s < tolerance_mm) break;
      }
    }
    return true;
  };
  // Like PCL's default criteria, running out of iterations still counts as converged.
  result.converged = run_stages(0);
  if (!result.converged) return result;
  // The coarse stages' loose pairs can hold a direction the surface itself does not (a pot's
  // rotation about its axis) and slide along it before the final stage finds it degenerate. Such a
  // slide is undone — the rotation about the direction's axis put back to the prior's — and the
  // final stage run again: from there the prior holds the direction, or the colour, which sees it
  // only within a few millimetres (its texture's scale), takes it from the prior.
  // The rotation about each geometry-silent axis, relative to the priors.
  const auto silent_slides = [&] {
    std::vector<std::pair<Vec3d, double>> slides;
    for (const auto& direction : result.geometry_degenerate) {
      if (!direction.name.starts_with("rot")) continue;
      const Vec3d axis = Vector6d::Map(direction.twist.data()).head<3>().normalized();
      const Eigen::Quaterniond q(result.correction.linear());
      slides.emplace_back(axis, 2.0 * std::atan2(q.vec().dot(axis), q.w()));
    }
    return slides;
  };
  const auto undo_slides = [&] {
    bool undone = false;
    for (const auto& [axis, slide] : silent_slides()) {
      if (std::abs(slide) < 1e-7) continue;
      const Vec3d centre = result.correction * c;
      result.correction = Eigen::Translation3d(centre) * Eigen::AngleAxisd(-slide, axis) *
                          Eigen::Translation3d(-centre) * result.correction;
      undone = true;
    }
    return undone;
  };
  if (params.keep_prior_in_degenerate_directions) {
    const bool undone = undo_slides();
    if (undone) result.converged = run_stages(distances.size() - 1);
    if (!result.converged) return result;
    // A texture repeats, and its term converges to the nearest match: one further than the priors
    // plausibly allow is a false match. Then the colour is not used for this pair.
    if (result.used_colour) {
      bool implausible = false;
      for (const auto& [axis, slide] : silent_slides())
        implausible = implausible || std::abs(slide) > max_colour_slide_rad;
      if (implausible) {
        colour_allowed = false;
        undo_slides();
        result.converged = run_stages(distances.size() - 1);
        if (!result.converged) return result;
      }
    }
  }
  // The pair's information about the source's pose: its normal equations, with the directions it
  // could not see (held: neither the geometry nor the colour) removed — there the edge knows
  // nothing; the priors decide. With the handling off nothing is held: plain ICP's slide counts
  // as a measurement.
  result.seen = Matrix6d::Identity() - last_held;
  const Matrix6d centred = result.seen * last_jtj * result.seen;
  // The rows linearise a rotation about the fixed world point c (where the source's centroid was
  // at its prior), whatever the correction so far.
  const Matrix6d a = centred_from_origin(c, s);
  result.information = a.transpose() * centred * a;
  return result;
}

// Share of (a prefix of) the source's sample with a neighbour in the target within `distance_mm`,
// both at their current poses: `source_to_target` maps source points (at prior) into the target's
// cloud frame.
struct Coverage {
  std::vector<char> covered;      // per sample point
  std::vector<double> residuals;  // point-to-plane, per correspondence
};

void cover(const ViewData& source, std::size_t count, const ViewData& target,
           const Eigen::Isometry3d& source_to_target, double distance_mm, Coverage& coverage) {
  CloudT points;
  count = std::min(count, source.sample.size());
  for (std::size_t k = 0; k < count; ++k) points.push_back((*source.at_prior)[source.sample[k]]);
  const CloudT::Ptr moved = transformed(points, source_to_target);
  coverage.covered.resize(std::max(coverage.covered.size(), count), 0);
  for (const Pair& pair : nearest_pairs(*moved, *target.tree, distance_mm)) {
    coverage.covered[pair.source] = 1;
    coverage.residuals.push_back(
        along_target_normal((*moved)[pair.source], (*target.at_prior)[pair.target]));
  }
}

double root_mean_square(const std::vector<double>& values) {
  if (values.empty()) return 0.0;
  return std::sqrt(std::inner_product(values.begin(), values.end(), values.begin(), 0.0) /
                   static_cast<double>(values.size()));
}

double covered_share(const Coverage& coverage) {
  if (coverage.covered.empty()) return 0.0;
  return static_cast<double>(std::count(coverage.covered.begin(), coverage.covered.end(), 1)) /
         static_cast<double>(coverage.covered.size());
}

// ---------------------------------------------------------------------------------------------
// Global consistency: a pose graph over all views

// A small Gauss-Newton pose-graph solve with Eigen rather than PCL's LUM or ELCH: LUM fixes the
// first view and has no unary factors, ELCH only spreads a loop's error along a chain; neither can
// let the turntable prior hold, with its own weight, the directions a pair cannot see — which is
// the whole point on a wheel-made pot. A scan has tens of views, so the dense system is tiny.
struct GraphEdge {
  int target = 0, source = 0;  // view indices
  Eigen::Isometry3d measured;  // target pose⁻¹ · source pose, as the pair's ICP found it
  Matrix6d information;        // origin twist of the source
  Matrix6d seen;               // projector onto the directions it constrains (ICP's twist)
  std::size_t edge_index = 0;  // into Result::edges
};

// The adjoint of T for origin twists: T·exp(δ)·T⁻¹ = exp(Ad·δ).
Matrix6d adjoint(const Eigen::Isometry3d& t) {
  Matrix6d ad = Matrix6d::Zero();
  const Eigen::Matrix3d r = t.linear();
  const Vec3d p = t.translation();
  Eigen::Matrix3d skew;
  skew << 0, -p.z(), p.y(), p.z(), 0, -p.x(), -p.y(), p.x(), 0;
  ad.topLeftCorner<3, 3>() = r;
  ad.bottomLeftCorner<3, 3>() = skew * r;
  ad.bottomRightCorner<3, 3>() = r;
  return ad;
}

// The frame the edge was measured in: the world as it stood at the target's prior. K maps the
// world at the current poses into it.
Eigen::Isometry3d measurement_frame(const GraphEdge& e, const std::vector<Pose>& poses,
                                    const std::vector<ViewInput>& views) {
  return views[e.target].prior * poses[e.target].inverse();
}

// How far an edge's measured relation is from the poses: the source's misalignment, an origin
// twist in the edge's measurement frame (zero when the poses agree with the edge). Expressed
// there, not in the world, it is unchanged by a common motion of all views: world-frame residuals
// of slightly inconsistent edges would turn with such a motion and, weighted by the edges' large
// information, push the whole graph away from its priors.
Vector6d edge_residual(const GraphEdge& e, const std::vector<Pose>& poses,
                       const std::vector<ViewInput>& views) {
  const Eigen::Isometry3d k = measurement_frame(e, poses, views);
  return log_twist(k * poses[e.source] * e.measured.inverse() * poses[e.target].inverse() *
                   k.inverse());
}

// Information (per rad²) that holds a rotation no edge sees at the prior's value: far above any
// edge's, yet the dense solve stays well conditioned.
constexpr double kHoldInformation = 1e12;

// The scale of the priors' Cauchy loss, in standard deviations.
constexpr double kPriorCauchyScale = 2.0;

struct GraphSolution {
  int iterations = 0;
  Eigen::MatrixXd covariance;  // 6 × views, origin twists
};

double prior_weight(const Pose& pose, const Pose& prior, const Matrix6d& prior_information) {
  const Vector6d r = log_twist(pose * prior.inverse());
  return 1.0 / (1.0 + r.dot(prior_information * r) / (kPriorCauchyScale * kPriorCauchyScale));
}

// Starting poses for the solve that the edges agree with exactly: each connected part of the
// graph laid out along a spanning tree (breadth first) from the view whose layout agrees best
// with the priors. Gauss-Newton linearises; started from the priors it would have to bridge a
// view's whole prior error in one step (10° and 60 mm for the bunny's bun045), and fail.
std::vector<Pose> spanning_tree_poses(const std::vector<ViewInput>& views,
                                      const std::vector<char>& active,
                                      const std::vector<GraphEdge>& edges,
                                      const Matrix6d& prior_information) {
  const std::size_t n = views.size();
  std::vector<Pose> best;
  for (const auto& v : views) best.push_back(v.prior);
  std::vector<char> done(n, 0);
  for (std::size_t start = 0; start < n; ++start) {
    if (!active[start] || done[start]) continue;
    double best_score = -1.0;
    for (std::size_t root = 0; root < n; ++root) {
      std::vector<Pose> poses(n, Pose::Identity());
      std::vector<char> reached(n, 0);
      std::vector<std::size_t> queue{root};
      poses[root] = views[root].prior;
      reached[root] = 1;
      for (std::size_t q = 0; q < queue.size(); ++q) {
        const std::size_t at = queue[q];
        for (const GraphEdge& e : edges) {
          const auto t = static_cast<std::size_t>(e.target), s = static_cast<std::size_t>(e.source);
          if (t == at && !reached[s]) {
            poses[s] = poses[t] * e.measured;
            reached[s] = 1;
            queue.push_back(s);
          } else if (s == at && !reached[t]) {
            poses[t] = poses[s] * e.measured.inverse();
            reached[t] = 1;
            queue.push_back(t);
          }
        }
      }
      if (!reached[start]) continue;  // another part of the graph
      double score = 0.0;
      for (std::size_t k : queue)
        score += prior_weight(poses[k], views[k].prior, prior_information);
      if (score > best_score) {
        best_score = score;
        for (std::size_t k : queue) best[k] = poses[k], done[k] = 1;
      }
    }
  }
  return best;
}

// Minimises Σ priors ‖log(T_k·prior_k⁻¹)‖²_Λ + Σ edges ‖log(T_s·Z⁻¹·T_t⁻¹)‖²_I over the views in
// `active` (the others keep their poses).
GraphSolution solve_graph(std::vector<Pose>& poses, const std::vector<ViewInput>& views,
                          const std::vector<char>& active, const std::vector<GraphEdge>& edges,
                          const Matrix6d& prior_information, const std::vector<Matrix6d>& holds) {
  const auto n = static_cast<Eigen::Index>(poses.size());
  GraphSolution solution;
  Eigen::MatrixXd h(6 * n, 6 * n);
  for (int iteration = 0; iteration < 20; ++iteration) {
    h.setZero();
    Eigen::VectorXd b = Eigen::VectorXd::Zero(6 * n);
    for (Eigen::Index k = 0; k < n; ++k) {
      if (!active[k]) {
        h.block<6, 6>(6 * k, 6 * k).setIdentity();  // held: zero step
        continue;
      }
      const Vector6d r = log_twist(poses[k] * views[k].prior.inverse());
      // Cauchy weight (iteratively reweighted): a prior several σ from where the geometry puts
      // the view — a turntable that missed steps, an object moved between views — must not drag
      // every other view along with it.
      const double weight = prior_weight(poses[k], views[k].prior, prior_information);
      h.block<6, 6>(6 * k, 6 * k) += weight * prior_information + holds[k];
      b.segment<6>(6 * k) += (weight * prior_information + holds[k]) * r;
    }
    for (const GraphEdge& e : edges) {
      const Vector6d r = edge_residual(e, poses, views);
      // With M = K·T_s·Z⁻¹·T_t⁻¹·K⁻¹ and K = prior_t·T_t⁻¹: T_s → exp(δs)·T_s gives
      // exp(Ad(K)·δs)·M, T_t → exp(δt)·T_t gives exp(−Ad(K)·δt)·M.
      const Matrix6d js = adjoint(measurement_frame(e, poses, views));
      const Matrix6d jt = -js;
      const Eigen::Index s = 6 * e.source, t = 6 * e.target;
      h.block<6, 6>(s, s) += js.transpose() * e.information * js;
      h.block<6, 6>(t, t) += jt.transpose() * e.information * jt;
      h.block<6, 6>(s, t) += js.transpose() * e.information * jt;
      h.block<6, 6>(t, s) += jt.transpose() * e.information * js;
      b.segment<6>(s) += js.transpose() * e.information * r;
      b.segment<6>(t) += jt.transpose() * e.information * r;
    }
    const Eigen::VectorXd step = h.ldlt().solve(-b);
    double largest = 0.0;
    for (Eigen::Index k = 0; k < n; ++k) {
      if (!active[k]) continue;
      poses[k] = exp_twist(step.segment<6>(6 * k)) * poses[k];
      largest = std::max(largest, step.segment<6>(6 * k).cwiseAbs().maxCoeff());
    }
    ++solution.iterations;
    if (largest < 1e-9) break;
  }
  solution.covariance = h.ldlt().solve(Eigen::MatrixXd::Identity(6 * n, 6 * n));
  return solution;
}

// The part of a rotation about the z axis (swing-twist decomposition), signed, in degrees.
double twist_about_z_deg(const Eigen::Matrix3d& rotation) {
  const Eigen::Quaterniond q(rotation);
  return to_deg(2.0 * std::atan2(q.z(), q.w()));
}

double wrapped_deg(double deg) { return std::remainder(deg, 360.0); }

// The names every one of `sets` holds (the directions none of a view's edges constrains).
std::vector<DegenerateDirection> common_directions(
    const std::vector<const std::vector<DegenerateDirection>*>& sets) {
  std::vector<DegenerateDirection> common;
  if (sets.empty()) return common;
  for (const auto& direction : *sets.front()) {
    const bool everywhere = std::all_of(sets.begin(), sets.end(), [&](const auto* set) {
      return std::any_of(set->begin(), set->end(),
                         [&](const auto& d) { return d.name == direction.name; });
    });
    if (everywhere) common.push_back(direction);
  }
  return common;
}

}  // namespace

Pose turntable_prior(const Pose& scanner_to_world, double turntable_angle_rad) {
  return Pose(Eigen::AngleAxisd(-turntable_angle_rad, Eigen::Vector3d::UnitZ())) * scanner_to_world;
}

Result register_views(const std::vector<ViewInput>& views,
                      const PriorUncertainty& prior_uncertainty, const Params& params) {
  check_input(views, prior_uncertainty, params);
  const int n = static_cast<int>(views.size());
  Result result;
  result.views.resize(views.size());
  std::vector<ViewData> data;
  data.reserve(views.size());
  std::vector<int> present;  // views with points, in turntable order
  for (int i = 0; i < n; ++i) {
    result.views[i].pose = views[i].prior;
    data.push_back(prepare_view(views[i], prior_uncertainty, params));
    if (data[i].at_prior->empty()) {
      result.views[i].flags.emplace_back("empty");
    } else {
      present.push_back(i);
      result.views[i].rms_radius_mm = data[i].rms_radius_mm;
    }
  }
  // The largest correction that is still plausible bounds how far ICP searches.
  const auto coarse_distance = [&](const ViewData& a, const ViewData& b) {
    const double sd = std::hypot(a.prior_displacement_sd_mm, b.prior_displacement_sd_mm);
    const double plausible =
        params.max_correction_mm + params.max_correction_deg * std::numbers::pi / 180.0 *
                                       std::max(a.rms_radius_mm, b.rms_radius_mm);
    return params.max_correspondence_mm + std::min(3.0 * sd, plausible);
  };

  // Edges: turntable neighbours and the loop closure, then the best other overlaps.
  constexpr std::size_t kOverlapProbePoints = 2000;
  struct Candidate {
    int target, source;
    bool neighbours;
    double overlap;
  };
  const auto overlap_at_prior = [&](int target, int source) {
    Coverage coverage;
    cover(data[source], kOverlapProbePoints, data[target], Eigen::Isometry3d::Identity(),
          coarse_distance(data[target], data[source]), coverage);
    return covered_share(coverage);
  };
  std::vector<Candidate> candidates;
  const auto m = static_cast<int>(present.size());
  for (int k = 0; k + 1 < m || (m >= 3 && k + 1 == m); ++k) {
    const int a = present[k], b = present[(k + 1) % m];
    candidates.push_back({std::min(a, b), std::max(a, b), true, 0.0});
  }
  std::vector<Candidate> extra;
  for (int ka = 0; ka < m; ++ka) {
    for (int kb = ka + 2; kb < m; ++kb) {
      if (ka == 0 && kb == m - 1) continue;  // the loop closure, already a neighbour edge
      extra.push_back({present[ka], present[kb], false, 0.0});
    }
  }
  for (auto& c : candidates) c.overlap = overlap_at_prior(c.target, c.source);
  for (auto& c : extra) c.overlap = overlap_at_prior(c.target, c.source);
  std::sort(extra.begin(), extra.end(),
            [](const auto& a, const auto& b) { return a.overlap > b.overlap; });
  std::vector<int> extra_count(views.size(), 0);
  for (const auto& c : extra) {
    if (c.overlap < params.min_edge_overlap ||
        extra_count[c.target] >= params.max_extra_edges_per_view ||
        extra_count[c.source] >= params.max_extra_edges_per_view) {
      continue;
    }
    ++extra_count[c.target];
    ++extra_count[c.source];
    candidates.push_back(c);
  }

  // Pairwise refinement, then the global solve; twice: the second round refines every pair the
  // first solve moved off its own result again from the poses that solve found (closer than the
  // priors, so pairs that went astray from the priors can converge) and solves again.
  std::vector<int> candidate_edges(views.size(), 0);
  std::erase_if(candidates,
                [&](const Candidate& c) { return c.overlap < params.min_edge_overlap; });
  for (const auto& c : candidates) ++candidate_edges[c.target], ++candidate_edges[c.source];
  result.edges.resize(candidates.size());
  std::vector<GraphEdge> graph;
  // How far a pair's relative rotation about a silent axis may plausibly be from the priors': three
  // standard deviations of the difference of two views' prior rotations.
  const double max_colour_slide_rad =
      3.0 * std::sqrt(2.0) *
      std::hypot(prior_uncertainty.angle_sd_deg, prior_uncertainty.tilt_sd_deg) * std::numbers::pi /
      180.0;
  const auto refine_edge = [&](std::size_t k, const Eigen::Isometry3d& initial, double coarse_mm) {
    const Candidate& c = candidates[k];
    EdgeResult& edge = result.edges[k];
    edge = EdgeResult{};
    edge.target = c.target;
    edge.source = c.source;
    edge.neighbours = c.neighbours;
    edge.overlap_at_prior = c.overlap;
    const ViewData& target = data[c.target];
    const ViewData& source = data[c.source];
    // The colour only between turntable neighbours: views further apart light and occlude the
    // same surface differently, and their texture matches were measured to be false (frames lost
    // accuracy, 0.0045° → 0.012° median, from colour on their opposite-view edges).
    const PairRefinement pair =
        refine_pair(target, source, initial, coarse_mm, params.use_colour && c.neighbours,
                    max_colour_slide_rad, params);
    edge.iterations = pair.iterations;
    edge.used_colour = pair.used_colour;
    edge.degenerate = pair.degenerate;
    edge.correction_deg = to_deg(Eigen::AngleAxisd(pair.correction.linear()).angle());
    edge.correction_mm = (pair.correction * source.centroid - source.centroid).norm();
    edge.relative = views[c.target].prior.inverse() * pair.correction * views[c.source].prior;
    Coverage fit;
    cover(source, source.sample.size(), target, pair.correction, params.max_correspondence_mm, fit);
    edge.overlap = covered_share(fit);
    edge.rms_mm = root_mean_square(fit.residuals);
    if (!pair.converged) {
      edge.status = "not_converged";
    } else if (edge.correction_deg > params.max_correction_deg ||
               edge.correction_mm > params.max_correction_mm) {
      edge.status = "implausible_correction";
    } else {
      edge.status = "accepted";
      graph.push_back({c.target, c.source, edge.relative, pair.information, pair.seen, k});
    }
  };

  const double to_rad = std::numbers::pi / 180.0;
  Matrix6d prior_information = Matrix6d::Zero();
  prior_information.diagonal() << std::pow(prior_uncertainty.tilt_sd_deg * to_rad, -2),
      std::pow(prior_uncertainty.tilt_sd_deg * to_rad, -2),
      std::pow(prior_uncertainty.angle_sd_deg * to_rad, -2),
      Vec3d::Constant(std::pow(prior_uncertainty.translation_sd_mm, -2));
  std::vector<Pose> poses;
  for (const auto& v : views) poses.push_back(v.prior);
  std::vector<char> active(views.size(), 0);
  std::vector<char> implausible(views.size(), 0);
  GraphSolution solution;
  // Solves the graph; drops the edge that disagrees most with the rest until all agree, and the
  // views the solve would move implausibly far from their prior. An edge the solution leaves
  // misaligned by more than half the correspondence distance no longer describes the same
  // surfaces.
  const double consistency_mm = 0.5 * params.max_correspondence_mm;
  const auto solve_consistent = [&] {
    for (;;) {
      std::fill(active.begin(), active.end(), 0);
      for (const auto& e : graph) active[e.target] = active[e.source] = 1;
      poses = spanning_tree_poses(views, active, graph, prior_information);
      // A rotation that none of a view's edges sees stays at the prior's, exactly as in the pairs:
      // the edges' information is only nearly zero there (their null direction turns about the
      // pot's own axis, which the priors' small errors set a fraction of a millimetre off the
      // turntable's), and a fraction of a millimetre times their weight outweighs the encoder.
      std::vector<Matrix6d> holds(views.size(), Matrix6d::Zero());
      for (int i = 0; i < n && params.keep_prior_in_degenerate_directions; ++i) {
        std::vector<const std::vector<DegenerateDirection>*> seen_by;
        for (const auto& e : graph) {
          if (e.target == i || e.source == i)
            seen_by.push_back(&result.edges[e.edge_index].degenerate);
        }
        for (const auto& direction : common_directions(seen_by)) {
          if (!direction.name.starts_with("rot")) continue;
          const Vec3d axis = Vector6d::Map(direction.twist.data()).head<3>().normalized();
          holds[i].topLeftCorner<3, 3>() += kHoldInformation * axis * axis.transpose();
        }
      }
      solution = solve_graph(poses, views, active, graph, prior_information, holds);
      result.graph_iterations += solution.iterations;
      double worst = consistency_mm;
      std::size_t worst_edge = graph.size();
      for (std::size_t k = 0; k < graph.size(); ++k) {
        const ViewData& source = data[graph[k].source];
        // Only in the directions the edge constrains: elsewhere the priors decide, not the edge.
        const Vector6d xi =
            graph[k].seen *
            centred_from_origin(source.centroid, std::max(source.rms_radius_mm, 1.0)) *
            edge_residual(graph[k], poses, views);
        const double misalignment = xi.head<3>().norm() + xi.tail<3>().norm();
        if (misalignment > worst) worst = misalignment, worst_edge = k;
      }
      if (worst_edge < graph.size()) {
        result.edges[graph[worst_edge].edge_index].status = "inconsistent";
        graph.erase(graph.begin() + static_cast<std::ptrdiff_t>(worst_edge));
        continue;
      }
      bool dropped = false;
      for (int i = 0; i < n; ++i) {
        if (!active[i]) continue;
        const Eigen::Isometry3d correction = poses[i] * views[i].prior.inverse();
        const double deg = to_deg(Eigen::AngleAxisd(correction.linear()).angle());
        const double mm = (correction * data[i].centroid - data[i].centroid).norm();
        if (deg <= params.max_correction_deg && mm <= params.max_correction_mm) continue;
        implausible[i] = 1;
        for (auto& e : graph) {
          if (e.target == i || e.source == i)
            result.edges[e.edge_index].status = "implausible_correction";
        }
        std::erase_if(graph, [&](const GraphEdge& e) { return e.target == i || e.source == i; });
        dropped = true;
      }
      if (!dropped) return;
    }
  };

  if (params.refine_with_icp) {
    for (std::size_t k = 0; k < candidates.size(); ++k) {
      const Candidate& c = candidates[k];
      refine_edge(k, Eigen::Isometry3d::Identity(),
                  coarse_distance(data[c.target], data[c.source]));
    }
    solve_consistent();
    const std::vector<char> placed = active;
    const std::vector<Pose> first = poses;
    const std::vector<GraphEdge> first_graph = graph;
    graph.clear();
    std::fill(implausible.begin(), implausible.end(), 0);
    for (std::size_t k = 0; k < candidates.size(); ++k) {
      const Candidate& c = candidates[k];
      if (!placed[c.target] || !placed[c.source]) {
        // A view the first round could not place: its pairs start from the priors again.
        refine_edge(k, Eigen::Isometry3d::Identity(),
                    coarse_distance(data[c.target], data[c.source]));
        continue;
      }
      // The source where the first solve put it, relative to the target there, in the target's
      // prior frame; fine distances only.
      const Eigen::Isometry3d initial = views[c.target].prior * first[c.target].inverse() *
                                        first[c.source] * views[c.source].prior.inverse();
      // A pair the first solve left where its own ICP put it (within the scanner's noise) would
      // only converge back there: its first result stands. Measured (bench_registration): bunny
      // 1.00 → 0.82 s per view for the same errors; frames 0.0029° → 0.0035° median.
      const auto first_edge = std::find_if(first_graph.begin(), first_graph.end(),
                                           [&](const GraphEdge& e) { return e.edge_index == k; });
      if (first_edge != first_graph.end()) {
        const Eigen::Isometry3d gap =
            first_edge->measured.inverse() * first[c.target].inverse() * first[c.source];
        const Vec3d centre = views[c.source].prior.inverse() * data[c.source].centroid;
        const double turned_mm =
            Eigen::AngleAxisd(gap.linear()).angle() * data[c.source].rms_radius_mm;
        if ((gap * centre - centre).norm() < kRefineAgainMm && turned_mm < kRefineAgainMm) {
          graph.push_back(*first_edge);
          continue;
        }
      }
      refine_edge(k, initial, params.max_correspondence_mm);
    }
    solve_consistent();
  } else {
    for (std::size_t k = 0; k < candidates.size(); ++k) {
      EdgeResult& edge = result.edges[k];
      edge.target = candidates[k].target;
      edge.source = candidates[k].source;
      edge.neighbours = candidates[k].neighbours;
      edge.overlap_at_prior = candidates[k].overlap;
      edge.status = "accepted";
    }
  }

  // Figures and flags per view.
  for (int i = 0; i < n; ++i) {
    ViewResult& out = result.views[i];
    if (data[i].at_prior->empty()) continue;
    out.pose = active[i] ? poses[i] : views[i].prior;
    const Eigen::Isometry3d correction = out.pose * views[i].prior.inverse();
    out.correction_deg = to_deg(Eigen::AngleAxisd(correction.linear()).angle());
    out.correction_mm = (correction * data[i].centroid - data[i].centroid).norm();
    out.about_z_deg = wrapped_deg(twist_about_z_deg(correction.linear()));
    if (active[i]) {
      const Matrix6d origin = solution.covariance.block<6, 6>(6 * i, 6 * i);
      const Matrix6d a =
          centred_from_origin(out.pose * views[i].prior.inverse() * data[i].centroid, 1.0);
      const Matrix6d centred = a * origin * a.transpose();
      out.angle_sd_deg = to_deg(std::sqrt(std::max(0.0, centred(2, 2))));
      out.tilt_sd_deg = to_deg(std::sqrt(std::max({0.0, centred(0, 0), centred(1, 1)})));
      out.translation_sd_mm =
          std::sqrt(std::max({0.0, centred(3, 3), centred(4, 4), centred(5, 5)}));
    }
    Coverage fit;
    std::vector<const std::vector<DegenerateDirection>*> edge_directions;
    std::vector<std::string> reasons;
    for (const auto& edge : result.edges) {
      if (edge.target != i && edge.source != i) continue;
      reasons.push_back(edge.status);
      if (edge.status != "accepted") continue;
      ++out.edges;
      out.iterations += edge.iterations;
      edge_directions.push_back(&edge.degenerate);
      const int other = edge.target == i ? edge.source : edge.target;
      const Pose other_pose = active[other] ? poses[other] : views[other].prior;
      // This view's points at prior → world at its final pose → the other view's prior frame.
      cover(data[i], data[i].sample.size(), data[other],
            views[other].prior * other_pose.inverse() * out.pose * views[i].prior.inverse(),
            params.max_correspondence_mm, fit);
    }
    out.overlap = covered_share(fit);
    out.rms_mm = root_mean_square(fit.residuals);
    out.degenerate = common_directions(edge_directions);
    const auto any = [&](const char* status) {
      return std::find(reasons.begin(), reasons.end(), status) != reasons.end();
    };
    if (candidate_edges[i] == 0) {
      out.flags.emplace_back("no_overlap");
    } else if (implausible[i] || (out.edges == 0 && any("implausible_correction"))) {
      out.flags.emplace_back("implausible_correction");
    } else if (out.edges == 0 && any("inconsistent")) {
      out.flags.emplace_back("inconsistent");
    } else if (out.edges == 0 && any("not_converged")) {
      out.flags.emplace_back("not_converged");
    }
    for (const auto& direction : out.degenerate)
      out.flags.push_back("degenerate:" + direction.name);
    out.merged =
        out.edges > 0 || (!params.refine_with_icp && candidate_edges[i] > 0) || present.size() == 1;
    if (!out.merged || implausible[i]) out.pose = views[i].prior;
  }

  return result;
}

}  // namespace sherd::registration
