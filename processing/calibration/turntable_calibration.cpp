#include "processing/calibration/turntable_calibration.h"

#include "core/errors.h"
#include "core/files.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <pcl/ModelCoefficients.h>
#include <pcl/console/print.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/extract_clusters.h>
#include <pcl/segmentation/sac_segmentation.h>
#include <Eigen/Eigenvalues>
#include <unsupported/Eigen/NonLinearOptimization>
#include <unsupported/Eigen/NumericalDiff>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <numbers>
#include <optional>
#include <set>
#include <tuple>

namespace sherd::calibration {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

using Cloud3 = pcl::PointCloud<pcl::PointXYZ>;

// Per-view detection settings, in millimetres. The plate and disc tops are removed as planes
// (the spheres' lowest points stand ≥ 15 mm above them); what is left falls apart into one
// cluster per sphere-on-post, plus bits of the plate's and disc's edges.
constexpr double kPlaneDistanceMm = 1.0;
constexpr double kParallelPlanesDeg = 10.0;
constexpr double kClusterToleranceMm = 2.0;
constexpr int kMinClusterPoints = 150;
constexpr double kSphereRansacDistanceMm = 0.4;
constexpr double kMaxSphereRmsMm = 0.25;  // a good sphere fit: a few times the scanner's noise

// One sphere's centre as found in one view.
struct Observation {
  int view = 0;        // index into the input views
  int sphere = 0;      // index into CalibrationObject::spheres
  double angle = 0.0;  // encoder, radians
  Vec3d centre;        // scanner frame
};

struct SphereFit {
  Vec3d centre = Vec3d::Zero();
  double radius = 0.0;
  double rms = 0.0;
  int inliers = 0;
};

// Geometric least-squares sphere (Gauss–Newton on |p − c| − r), started from `start` and run on
// the points within `band` of the current sphere, re-selected each pass so that the posts and
// stray edge points drop out. PCL's SampleConsensusModelSphere::optimizeModelCoefficients does
// the same minimisation but without re-selecting inliers, which is what makes it robust here.
SphereFit refine_sphere(const std::vector<Vec3d>& points, SphereFit fit, double band) {
  for (int pass = 0; pass < 4; ++pass) {
    std::vector<const Vec3d*> inliers;
    for (const auto& p : points) {
      if (std::abs((p - fit.centre).norm() - fit.radius) < band) inliers.push_back(&p);
    }
    if (inliers.size() < 10) return {};
    for (int iteration = 0; iteration < 10; ++iteration) {
      Eigen::Matrix4d JtJ = Eigen::Matrix4d::Zero();
      Eigen::Vector4d Jtr = Eigen::Vector4d::Zero();
      for (const Vec3d* p : inliers) {
        const Vec3d offset = *p - fit.centre;
        const double distance = offset.norm();
        if (distance < 1e-9) continue;
        Eigen::Vector4d J;
        J << -offset / distance, -1.0;
        const double residual = distance - fit.radius;
        JtJ += J * J.transpose();
        Jtr += J * residual;
      }
      const Eigen::Vector4d step = JtJ.ldlt().solve(-Jtr);
      if (!step.allFinite()) return {};
      fit.centre += step.head<3>();
      fit.radius += step[3];
      if (step.norm() < 1e-7) break;
    }
    double sum = 0.0;
    for (const Vec3d* p : inliers) sum += std::pow((*p - fit.centre).norm() - fit.radius, 2);
    fit.rms = std::sqrt(sum / static_cast<double>(inliers.size()));
    fit.inliers = static_cast<int>(inliers.size());
    band = std::max(3.0 * fit.rms, 0.15);
  }
  return fit;
}

// The spheres of the calibration object found in one view: (sphere index, fit).
std::vector<std::pair<int, SphereFit>> find_spheres(const OrganisedView& view,
                                                    const CalibrationObject& object,
                                                    const EstimatorParams& params) {
  auto cloud = std::make_shared<Cloud3>();
  for (std::size_t i = 0; i < view.points.size(); ++i) {
    const Vec3f& p = view.points[i];
    if ((view.valid.empty() || view.valid[i]) && p.allFinite()) {
      cloud->push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
    }
  }
  if (cloud->size() < static_cast<std::size_t>(kMinClusterPoints)) return {};

  // The plate's top and the disc's top: the largest plane, then a second one parallel to it.
  std::optional<Eigen::Vector3f> first_normal;
  for (int plane = 0; plane < 2 && cloud->size() > 1000; ++plane) {
    pcl::SACSegmentation<pcl::PointXYZ> segmentation;
    segmentation.setModelType(pcl::SACMODEL_PLANE);
    segmentation.setMethodType(pcl::SAC_RANSAC);
    segmentation.setDistanceThreshold(kPlaneDistanceMm);
    segmentation.setMaxIterations(300);
    segmentation.setInputCloud(cloud);
    pcl::PointIndices inliers;
    pcl::ModelCoefficients coefficients;
    segmentation.segment(inliers, coefficients);
    if (inliers.indices.size() < cloud->size() / 20) break;
    const Eigen::Vector3f normal(coefficients.values[0], coefficients.values[1], coefficients.values[2]);
    if (first_normal &&
        std::abs(normal.normalized().dot(*first_normal)) < std::cos(kParallelPlanesDeg * kDeg)) {
      break;  // not the disc's top: leave it
    }
    first_normal = normal.normalized();
    std::vector<char> drop(cloud->size(), 0);
    for (int i : inliers.indices) drop[i] = 1;
    auto rest = std::make_shared<Cloud3>();
    for (std::size_t i = 0; i < cloud->size(); ++i) {
      if (!drop[i]) rest->push_back((*cloud)[i]);
    }
    cloud = rest;
  }
  if (cloud->size() < static_cast<std::size_t>(kMinClusterPoints)) return {};

  auto tree = std::make_shared<pcl::search::KdTree<pcl::PointXYZ>>();
  tree->setInputCloud(cloud);
  std::vector<pcl::PointIndices> clusters;
  pcl::EuclideanClusterExtraction<pcl::PointXYZ> extraction;
  extraction.setClusterTolerance(kClusterToleranceMm);
  extraction.setMinClusterSize(kMinClusterPoints);
  extraction.setSearchMethod(tree);
  extraction.setInputCloud(cloud);
  extraction.extract(clusters);

  double min_radius = 1e9, max_radius = 0.0;
  for (const auto& s : object.spheres) {
    min_radius = std::min(min_radius, s.radius_mm);
    max_radius = std::max(max_radius, s.radius_mm);
  }
  std::map<int, SphereFit> found;  // the best fit of each sphere
  // A cluster that is no sphere (an edge of the plate or disc) is expected: PCL would print an
  // error for each one.
  const auto verbosity = pcl::console::getVerbosityLevel();
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);
  for (const auto& cluster : clusters) {
    auto part = std::make_shared<Cloud3>();
    std::vector<Vec3d> points;
    for (int i : cluster.indices) {
      part->push_back((*cloud)[i]);
      points.push_back((*cloud)[i].getVector3fMap().cast<double>());
    }
    pcl::SACSegmentation<pcl::PointXYZ> segmentation;
    segmentation.setModelType(pcl::SACMODEL_SPHERE);
    segmentation.setMethodType(pcl::SAC_RANSAC);
    segmentation.setDistanceThreshold(kSphereRansacDistanceMm);
    segmentation.setRadiusLimits(min_radius - params.sphere_tolerance_mm,
                                 max_radius + params.sphere_tolerance_mm);
    segmentation.setMaxIterations(500);
    segmentation.setOptimizeCoefficients(false);  // refine_sphere does it
    segmentation.setInputCloud(part);
    pcl::PointIndices inliers;
    pcl::ModelCoefficients coefficients;
    segmentation.segment(inliers, coefficients);
    if (inliers.indices.size() < 50 || coefficients.values.size() != 4) continue;
    SphereFit start;
    start.centre = Vec3d(coefficients.values[0], coefficients.values[1], coefficients.values[2]);
    start.radius = coefficients.values[3];
    const SphereFit fit = refine_sphere(points, start, 3 * kSphereRansacDistanceMm);
    if (fit.inliers < 50 || fit.rms > kMaxSphereRmsMm) continue;
    // Recognised by its radius alone (the object's radii differ by more than twice the tolerance).
    for (std::size_t k = 0; k < object.spheres.size(); ++k) {
      if (std::abs(fit.radius - object.spheres[k].radius_mm) > params.sphere_tolerance_mm) continue;
      auto [it, inserted] = found.emplace(static_cast<int>(k), fit);
      if (!inserted && fit.inliers > it->second.inliers) it->second = fit;
    }
  }
  pcl::console::setVerbosityLevel(verbosity);
  return {found.begin(), found.end()};
}

Eigen::Matrix3d rotation(const Vec3d& axis, double angle) {
  return Eigen::AngleAxisd(angle, axis).toRotationMatrix();
}

// Two unit vectors completing `d` to an orthonormal basis.
std::pair<Vec3d, Vec3d> perpendiculars(const Vec3d& d) {
  const Vec3d e1 = d.unitOrthogonal();
  return {e1, d.cross(e1)};
}

// The joint model of the turntable's motion: sphere k, at θ = 0 at p + q_k, is seen at encoder
// angle θ_i at  p + R(d, θ_i) q_k.  Parameters x = [a, b, u, v, q_0, q_1, …]: the direction
// d = normalise(d0 + a e1 + b e2) and the point p = p0 + u e1 + v e2 in a chart about the
// starting guess (so the least-squares problem is unconstrained and has no gauge freedom: p only
// moves across the axis, the rotation about d is fixed by the encoder).
struct AxisModel {
  Vec3d d0, p0, e1, e2;
  std::vector<Observation> observations;
  std::map<int, int> slot;  // sphere index → position of its q in x

  int parameters() const { return 4 + 3 * static_cast<int>(slot.size()); }
  Vec3d direction(const Eigen::VectorXd& x) const { return (d0 + x[0] * e1 + x[1] * e2).normalized(); }
  Vec3d point(const Eigen::VectorXd& x) const { return p0 + x[2] * e1 + x[3] * e2; }
  Vec3d q(const Eigen::VectorXd& x, int sphere) const { return x.segment<3>(4 + 3 * slot.at(sphere)); }
  Vec3d predicted(const Eigen::VectorXd& x, const Observation& o) const {
    return point(x) + rotation(direction(x), o.angle) * q(x, o.sphere);
  }
};

// Eigen's Levenberg–Marquardt functor over the model (residuals: predicted − observed centres).
struct AxisFunctor {
  using Scalar = double;
  enum { InputsAtCompileTime = Eigen::Dynamic, ValuesAtCompileTime = Eigen::Dynamic };
  using InputType = Eigen::VectorXd;
  using ValueType = Eigen::VectorXd;
  using JacobianType = Eigen::MatrixXd;

  const AxisModel* model = nullptr;
  int inputs() const { return model->parameters(); }
  int values() const { return 3 * static_cast<int>(model->observations.size()); }
  int operator()(const Eigen::VectorXd& x, Eigen::VectorXd& residuals) const {
    for (std::size_t i = 0; i < model->observations.size(); ++i) {
      const auto& o = model->observations[i];
      residuals.segment<3>(3 * static_cast<Eigen::Index>(i)) = model->predicted(x, o) - o.centre;
    }
    return 0;
  }
};

// Starting guess: each sphere seen at ≥ 3 angles moves on a circle whose plane is ⊥ the axis;
// the orbit's sense (counter-clockwise for increasing encoder angle) orients the normal.
AxisModel initial_model(const std::vector<Observation>& observations) {
  std::map<int, std::vector<const Observation*>> by_sphere;
  for (const auto& o : observations) by_sphere[o.sphere].push_back(&o);
  Vec3d normal_sum = Vec3d::Zero();
  const std::vector<const Observation*>* most = nullptr;
  for (const auto& [sphere, seen] : by_sphere) {
    if (seen.size() < 3) continue;
    Vec3d mean = Vec3d::Zero();
    for (const auto* o : seen) mean += o->centre;
    mean /= static_cast<double>(seen.size());
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (const auto* o : seen) scatter += (o->centre - mean) * (o->centre - mean).transpose();
    Vec3d normal = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvectors().col(0);
    double sense = 0.0;
    for (const auto* a : seen) {
      for (const auto* b : seen) {
        sense += std::sin(b->angle - a->angle) * (a->centre - mean).cross(b->centre - mean).dot(normal);
      }
    }
    if (sense < 0) normal = -normal;
    normal_sum += static_cast<double>(seen.size()) * normal;
    if (!most || seen.size() > most->size()) most = &seen;
  }
  if (!most || !(normal_sum.norm() > 0)) {
    throw ProcessingError("turntable calibration: no sphere of the calibration object was found in "
                          "3 or more views, so its orbit (and the turntable axis) cannot be fitted: "
                          "check that the object stands on the plate, in the scanner's view");
  }
  AxisModel model;
  model.d0 = normal_sum.normalized();
  std::tie(model.e1, model.e2) = perpendiculars(model.d0);
  // The orbit's centre: an algebraic circle fit (x² + y² + D x + E y + F = 0) in the plane.
  Eigen::MatrixXd A(most->size(), 3);
  Eigen::VectorXd rhs(most->size());
  double height = 0.0;
  for (std::size_t i = 0; i < most->size(); ++i) {
    const Vec3d& c = (*most)[i]->centre;
    const double x = c.dot(model.e1), y = c.dot(model.e2);
    A.row(static_cast<Eigen::Index>(i)) << x, y, 1.0;
    rhs[static_cast<Eigen::Index>(i)] = -(x * x + y * y);
    height += c.dot(model.d0);
  }
  const Eigen::Vector3d circle = A.colPivHouseholderQr().solve(rhs);
  model.p0 = -0.5 * circle[0] * model.e1 - 0.5 * circle[1] * model.e2 +
             height / static_cast<double>(most->size()) * model.d0;
  model.observations = observations;
  return model;
}

// Fits the model (with the observations in `model`); returns x.
Eigen::VectorXd fit(AxisModel& model) {
  model.slot.clear();
  for (const auto& o : model.observations) model.slot.emplace(o.sphere, 0);
  int next = 0;
  for (auto& [sphere, slot] : model.slot) slot = next++;
  Eigen::VectorXd x = Eigen::VectorXd::Zero(model.parameters());
  std::map<int, int> count;
  for (const auto& o : model.observations) {
    x.segment<3>(4 + 3 * model.slot.at(o.sphere)) += rotation(model.d0, -o.angle) * (o.centre - model.p0);
    ++count[o.sphere];
  }
  for (const auto& [sphere, n] : count) x.segment<3>(4 + 3 * model.slot.at(sphere)) /= n;

  AxisFunctor functor;
  functor.model = &model;
  Eigen::NumericalDiff<AxisFunctor> numerical(functor);
  Eigen::LevenbergMarquardt<Eigen::NumericalDiff<AxisFunctor>> solver(numerical);
  solver.parameters.maxfev = 4000;
  solver.parameters.xtol = 1e-12;
  solver.parameters.ftol = 1e-12;
  solver.minimize(x);
  return x;
}

double median(std::vector<double> values) {
  const auto mid = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

std::vector<double> vec(const Vec3d& v) { return {v.x(), v.y(), v.z()}; }

Vec3d vec3(const nlohmann::json& value) {
  const auto a = value.get<std::vector<double>>();
  if (a.size() != 3) throw std::invalid_argument("expected an array of 3 numbers");
  return {a[0], a[1], a[2]};
}

}  // namespace

Pose TurntableCalibration::scanner_to_world() const {
  const Vec3d z = axis_direction.normalized();
  // The optical centre (scanner origin) seen from the world origin, across the axis, is world −y.
  Vec3d towards_scanner = -axis_point_mm;
  towards_scanner -= z * z.dot(towards_scanner);
  if (!(towards_scanner.norm() > 1e-6)) {
    throw ProcessingError("turntable calibration: the scanner's optical centre lies on the turntable "
                          "axis, so the world azimuth is undefined: the scanner must look at the "
                          "plate from the side");
  }
  const Vec3d y = -towards_scanner.normalized();
  const Vec3d x = y.cross(z);
  Pose pose = Pose::Identity();
  pose.linear().row(0) = x.transpose();
  pose.linear().row(1) = y.transpose();
  pose.linear().row(2) = z.transpose();
  pose.translation() = -(pose.linear() * axis_point_mm);
  return pose;
}

TurntableCalibration estimate_turntable_axis(const std::vector<CalibrationView>& views,
                                             const CalibrationObject& object,
                                             const EstimatorParams& params) {
  std::vector<double> angles;
  for (std::size_t i = 0; i < views.size(); ++i) {
    if (!views[i].view || views[i].view->points.empty()) {
      throw InputError(fmt::format("turntable calibration: view {} is empty: re-run the calibration "
                                   "scan with the calibration object on the plate", i));
    }
    if (!std::isfinite(views[i].angle_rad)) {
      throw InputError(fmt::format("turntable calibration: view {} has no valid encoder angle ({}): "
                                   "check the turntable and re-run the calibration", i, views[i].angle_rad));
    }
    const double wrapped = std::remainder(views[i].angle_rad, 2 * std::numbers::pi);
    const bool distinct = std::none_of(angles.begin(), angles.end(), [&](double a) {
      return std::abs(std::remainder(a - wrapped, 2 * std::numbers::pi)) < 0.1 * kDeg;
    });
    if (distinct) angles.push_back(wrapped);
  }
  if (static_cast<int>(angles.size()) < params.min_views) {
    throw InputError(fmt::format(
        "turntable calibration: {} view(s) at {} distinct turntable angle(s); at least {} distinct "
        "angles are needed to see the axis: scan the calibration object at several angles "
        "(calibration.views)", views.size(), angles.size(), params.min_views));
  }

  std::vector<Observation> observations;
  std::set<int> views_with_spheres;
  for (std::size_t i = 0; i < views.size(); ++i) {
    for (const auto& [sphere, found] : find_spheres(*views[i].view, object, params)) {
      observations.push_back({static_cast<int>(i), sphere, views[i].angle_rad, found.centre});
      views_with_spheres.insert(static_cast<int>(i));
    }
  }
  if (static_cast<int>(views_with_spheres.size()) < params.min_views) {
    throw ProcessingError(fmt::format(
        "turntable calibration: spheres of the calibration object found in {} of {} views, at least "
        "{} needed: put the calibration object on the plate (spheres up, in the scanner's view) "
        "and run it again", views_with_spheres.size(), views.size(), params.min_views));
  }

  AxisModel model = initial_model(observations);
  const int found_centres = static_cast<int>(observations.size());
  Eigen::VectorXd x;
  // Fit, drop centres far off the fit (a sphere partly hidden or mis-fitted in one view), refit.
  for (int round = 0; round < 3; ++round) {
    x = fit(model);
    std::vector<double> errors;
    for (const auto& o : model.observations) errors.push_back((model.predicted(x, o) - o.centre).norm());
    const double limit = std::max(params.outlier_factor * median(errors), 0.05);
    std::vector<Observation> kept;
    for (std::size_t i = 0; i < errors.size(); ++i) {
      if (errors[i] <= limit) kept.push_back(model.observations[i]);
    }
    if (kept.size() == model.observations.size()) break;
    model.observations = std::move(kept);
  }

  const int m = 3 * static_cast<int>(model.observations.size()), n = model.parameters();
  if (m <= n) {
    throw ProcessingError(fmt::format(
        "turntable calibration: {} sphere centres are too few to fit the axis ({} unknowns): scan "
        "more views of the calibration object", model.observations.size(), n));
  }
  AxisFunctor functor;
  functor.model = &model;
  Eigen::VectorXd residuals(m);
  functor(x, residuals);
  Eigen::MatrixXd J(m, n);
  Eigen::NumericalDiff<AxisFunctor, Eigen::Central>(functor).df(x, J);
  const Eigen::MatrixXd JtJ = J.transpose() * J;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(JtJ);
  if (eigen.eigenvalues()[0] <= 1e-10 * eigen.eigenvalues()[n - 1]) {
    throw ProcessingError("turntable calibration: the views do not determine the axis (angles too "
                          "close together or too few spheres): scan the calibration object all "
                          "round the turntable");
  }
  const double variance = residuals.squaredNorm() / (m - n);
  const Eigen::MatrixXd covariance = variance * JtJ.inverse();

  // The outputs as functions of x: the direction, and the axis point at the plate's top surface
  // (each sphere's centre stands disc thickness + its height above it).
  auto outputs = [&](const Eigen::VectorXd& at) {
    const Vec3d d = model.direction(at), p = model.point(at);
    double shift = 0.0;
    for (const auto& [sphere, slot] : model.slot) {
      const auto& s = object.spheres[static_cast<std::size_t>(sphere)];
      shift += d.dot(model.q(at, sphere)) - (object.disc_thickness_mm + s.height_mm);
    }
    shift /= static_cast<double>(model.slot.size());
    Eigen::Matrix<double, 6, 1> out;
    out << d, p + shift * d;
    return out;
  };
  const Eigen::Matrix<double, 6, 1> value = outputs(x);
  Eigen::MatrixXd G(6, n);
  for (int j = 0; j < n; ++j) {
    constexpr double h = 1e-6;
    Eigen::VectorXd plus = x, minus = x;
    plus[j] += h;
    minus[j] -= h;
    G.col(j) = (outputs(plus) - outputs(minus)) / (2 * h);
  }
  const Eigen::MatrixXd output_covariance = G * covariance * G.transpose();

  TurntableCalibration result;
  result.axis_direction = value.head<3>();
  result.axis_point_mm = value.tail<3>();
  const Vec3d& d = result.axis_direction;
  const Eigen::Matrix3d across = Eigen::Matrix3d::Identity() - d * d.transpose();
  result.direction_sd_deg =
      std::sqrt((across * output_covariance.topLeftCorner<3, 3>() * across).trace()) / kDeg;
  result.point_sd_mm = std::sqrt((across * output_covariance.bottomRightCorner<3, 3>() * across).trace());
  result.height_sd_mm = std::sqrt(d.dot(output_covariance.bottomRightCorner<3, 3>() * d));
  result.rms_residual_mm = std::sqrt(residuals.squaredNorm() / static_cast<double>(model.observations.size()));
  std::set<int> views_used;
  for (const auto& o : model.observations) views_used.insert(o.view);
  result.views_used = static_cast<int>(views_used.size());
  result.spheres_used = static_cast<int>(model.slot.size());
  result.centres_used = static_cast<int>(model.observations.size());
  result.centres_rejected = found_centres - result.centres_used;
  return result;
}

nlohmann::json to_json(const TurntableCalibration& c) {
  const Pose pose = c.scanner_to_world();
  nlohmann::json matrix = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) {
    matrix.push_back({pose.matrix()(r, 0), pose.matrix()(r, 1), pose.matrix()(r, 2), pose.matrix()(r, 3)});
  }
  return {{"schema", "sherdscan.turntable_calibration/1"},
          {"frame", "scanner"},
          {"axis_direction", vec(c.axis_direction)},
          {"axis_point_mm", vec(c.axis_point_mm)},
          {"direction_sd_deg", c.direction_sd_deg},
          {"point_sd_mm", c.point_sd_mm},
          {"height_sd_mm", c.height_sd_mm},
          {"rms_residual_mm", c.rms_residual_mm},
          {"views_used", c.views_used},
          {"spheres_used", c.spheres_used},
          {"centres_used", c.centres_used},
          {"centres_rejected", c.centres_rejected},
          {"scanner_to_world", matrix}};
}

TurntableCalibration turntable_calibration_from_json(const nlohmann::json& document,
                                                     const std::string& where) {
  auto invalid = [&](const std::string& why) {
    return InputError(fmt::format("{}: not a valid turntable calibration ({}) — re-run `sherdctl "
                                  "calibrate turntable`", where, why));
  };
  try {
    if (!document.is_object() || document.value("schema", "") != "sherdscan.turntable_calibration/1") {
      throw invalid("schema \"sherdscan.turntable_calibration/1\" expected");
    }
    TurntableCalibration c;
    c.axis_direction = vec3(document.at("axis_direction"));
    c.axis_point_mm = vec3(document.at("axis_point_mm"));
    c.direction_sd_deg = document.at("direction_sd_deg").get<double>();
    c.point_sd_mm = document.at("point_sd_mm").get<double>();
    c.height_sd_mm = document.at("height_sd_mm").get<double>();
    c.rms_residual_mm = document.at("rms_residual_mm").get<double>();
    c.views_used = document.at("views_used").get<int>();
    c.spheres_used = document.at("spheres_used").get<int>();
    c.centres_used = document.at("centres_used").get<int>();
    c.centres_rejected = document.at("centres_rejected").get<int>();
    if (!c.axis_point_mm.allFinite() || !c.axis_direction.allFinite() ||
        std::abs(c.axis_direction.norm() - 1.0) > 1e-6) {
      throw invalid("axis_direction must be a unit vector and axis_point_mm finite");
    }
    for (double sd : {c.direction_sd_deg, c.point_sd_mm, c.height_sd_mm, c.rms_residual_mm}) {
      if (!(sd >= 0 && std::isfinite(sd))) throw invalid("standard deviations must be finite and ≥ 0");
    }
    c.scanner_to_world();  // throws when the axis passes through the scanner
    return c;
  } catch (const nlohmann::json::exception& e) {
    throw invalid(e.what());
  } catch (const std::invalid_argument& e) {
    throw invalid(e.what());
  } catch (const ProcessingError& e) {
    throw invalid(e.what());
  }
}

void write_turntable_calibration(const std::filesystem::path& file,
                                 const TurntableCalibration& calibration,
                                 const nlohmann::json& extra) {
  nlohmann::json document = to_json(calibration);
  if (extra.is_object()) document.update(extra);
  std::error_code error;
  if (file.has_parent_path()) std::filesystem::create_directories(file.parent_path(), error);
  write_file_atomically(file, document.dump(2) + '\n');
}

TurntableCalibration read_turntable_calibration(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) {
    throw InputError(fmt::format("{}: cannot read the turntable calibration — check the file's "
                                 "permissions, or re-run `sherdctl calibrate turntable`", file.string()));
  }
  nlohmann::json document;
  try {
    document = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(fmt::format("{}: the turntable calibration is corrupt ({}) — re-run `sherdctl "
                                 "calibrate turntable`", file.string(), e.what()));
  }
  return turntable_calibration_from_json(document, file.string());
}

}  // namespace sherd::calibration
