// Profile-consistency refinement of an axis. About the true axis every azimuth of a wheel-made
// sherd shows the same profile: its points, mapped to (radius, height), lie on one thin curve per
// skin. About a tilted or shifted axis the azimuths map to curves shifted against each other, and
// the points spread. The spread is measured, point by point, as the distance of the point from the
// line fitted (PCA) through its neighbours in the half-plane that come from other azimuths (a
// neighbour at the same azimuth agrees about any axis). The neighbourhoods are fixed within a round
// so that the cost is smooth in the 4 axis parameters; Levenberg-Marquardt (Eigen) minimises it with
// Cauchy weights (iteratively reweighted: lips and breaks that wander are outliers), and the next
// round re-finds neighbourhoods about the new axis with a smaller radius.
#include "processing/axis/axis.h"

#include <Eigen/Eigenvalues>
#include <unsupported/Eigen/NonLinearOptimization>
#include <unsupported/Eigen/NumericalDiff>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <unordered_map>

namespace sherd::axis {
namespace {

constexpr double kDegToRad = M_PI / 180.0;
using Vec2 = Eigen::Vector2d;

struct Axis4 {
  Vec3d point, direction;
};

Vec3d perpendicular_to(const Vec3d& v) {
  const Vec3d helper = std::abs(v.x()) < 0.9 ? Vec3d::UnitX() : Vec3d::UnitY();
  return v.cross(helper).normalized();
}

// A point in the half-plane of an axis: (r, h), azimuth, and its normal's (radial, axial) part.
struct HalfPlanePoint {
  Vec2 rh;
  double phi;
  Vec2 normal;  // not normalised: its length is the share of the normal within the half-plane
};

void to_half_plane(const std::vector<Vec3d>& points, const std::vector<Vec3d>& normals, const Axis4& axis,
                   std::vector<HalfPlanePoint>& out) {
  const Vec3d x = perpendicular_to(axis.direction), y = axis.direction.cross(x);
  out.resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3d d = points[i] - axis.point;
    const double px = d.dot(x), py = d.dot(y);
    const double r = std::hypot(px, py);
    const Vec3d radial = r > 1e-9 ? Vec3d((px * x + py * y) / r) : x;
    out[i] = {{r, d.dot(axis.direction)}, std::atan2(py, px), {normals[i].dot(radial), normals[i].dot(axis.direction)}};
  }
}

// Distance of point i from the PCA line of its neighbours, signed along its own half-plane normal.
double local_line_distance(const std::vector<HalfPlanePoint>& hp, std::uint32_t i,
                           const std::vector<std::uint32_t>& neighbours) {
  Vec2 mean = Vec2::Zero();
  for (auto j : neighbours) mean += hp[j].rh;
  mean /= static_cast<double>(neighbours.size());
  Eigen::Matrix2d c = Eigen::Matrix2d::Zero();
  for (auto j : neighbours) c += (hp[j].rh - mean) * (hp[j].rh - mean).transpose();
  Vec2 n = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(c).eigenvectors().col(0);
  if (n.dot(hp[i].normal) < 0.0) n = -n;
  return n.dot(hp[i].rh - mean);
}

struct Problem {
  std::vector<Vec3d> points, normals;  // centred on the sherd's centroid
  std::vector<std::uint32_t> used;     // points with a neighbourhood this round
  std::vector<std::vector<std::uint32_t>> neighbours;  // per used point
  std::vector<double> sqrt_weight;                      // per used point
};

struct ConsistencyFunctor {
  using Scalar = double;
  using InputType = Eigen::VectorXd;
  using ValueType = Eigen::VectorXd;
  using JacobianType = Eigen::MatrixXd;
  enum { InputsAtCompileTime = Eigen::Dynamic, ValuesAtCompileTime = Eigen::Dynamic };

  const Problem* problem = nullptr;
  Axis4 start;
  Vec3d e1, e2;
  mutable std::vector<HalfPlanePoint> hp;

  int inputs() const { return 4; }
  int values() const { return static_cast<int>(problem->used.size()); }
  Axis4 axis_at(const Eigen::VectorXd& x) const {
    return {start.point + x[2] * e1 + x[3] * e2, (start.direction + x[0] * e1 + x[1] * e2).normalized()};
  }
  int operator()(const Eigen::VectorXd& x, Eigen::VectorXd& residuals) const {
    to_half_plane(problem->points, problem->normals, axis_at(x), hp);
    for (std::size_t k = 0; k < problem->used.size(); ++k) {
      residuals[static_cast<Eigen::Index>(k)] =
          problem->sqrt_weight[k] * local_line_distance(hp, problem->used[k], problem->neighbours[k]);
    }
    return 0;
  }
};

// Neighbourhoods in the half-plane about `axis`: for each point with a normal mostly within the
// half-plane (a skin or a lip, not a side break), up to max_neighbours nearest points within
// `radius` whose half-plane normals agree (the same skin) and whose azimuth differs by at least
// `min_dphi` (another part of the sherd).
void find_neighbourhoods(Problem& problem, const std::vector<HalfPlanePoint>& hp, double radius, double min_dphi,
                         int max_neighbours) {
  // A uniform grid over the half-plane: one fixed radius per round (the same reasoning as the
  // normal-line method's grid).
  auto key = [radius](const Vec2& p) {
    const auto cx = static_cast<std::int64_t>(std::floor(p.x() / radius));
    const auto cy = static_cast<std::int64_t>(std::floor(p.y() / radius));
    return (cx << 32) ^ (cy & 0xffffffff);
  };
  std::unordered_map<std::int64_t, std::vector<std::uint32_t>> grid;
  for (std::uint32_t i = 0; i < hp.size(); ++i) grid[key(hp[i].rh)].push_back(i);
  problem.used.clear();
  problem.neighbours.clear();
  std::vector<std::pair<double, std::uint32_t>> found;
  for (std::uint32_t i = 0; i < hp.size(); ++i) {
    if (hp[i].normal.norm() < 0.7) continue;
    const Vec2 ni = hp[i].normal.normalized();
    found.clear();
    const auto cx = static_cast<std::int64_t>(std::floor(hp[i].rh.x() / radius));
    const auto cy = static_cast<std::int64_t>(std::floor(hp[i].rh.y() / radius));
    for (std::int64_t dx = -1; dx <= 1; ++dx)
      for (std::int64_t dy = -1; dy <= 1; ++dy) {
        const auto it = grid.find(((cx + dx) << 32) ^ ((cy + dy) & 0xffffffff));
        if (it == grid.end()) continue;
        for (auto j : it->second) {
          const double d2 = (hp[j].rh - hp[i].rh).squaredNorm();
          if (d2 > radius * radius || hp[j].normal.norm() < 0.7) continue;
          if (hp[j].normal.normalized().dot(ni) < 0.7) continue;
          if (std::abs(std::remainder(hp[j].phi - hp[i].phi, 2 * M_PI)) < min_dphi) continue;
          found.push_back({d2, j});
        }
      }
    constexpr std::size_t kMinNeighbours = 5;
    if (found.size() < kMinNeighbours) continue;
    const std::size_t keep = std::min<std::size_t>(found.size(), max_neighbours);
    std::partial_sort(found.begin(), found.begin() + keep, found.end());
    std::vector<std::uint32_t> nb(keep);
    for (std::size_t k = 0; k < keep; ++k) nb[k] = found[k].second;
    problem.used.push_back(i);
    problem.neighbours.push_back(std::move(nb));
  }
}

double median_of(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

}  // namespace

AxisEstimate refine_axis(const Cloud& sherd, const AxisEstimate& start, const RefineParams& params) {
  if (!start.found) return start;
  AxisEstimate estimate = start;
  estimate.method = start.method + "+profile-consistency";

  Problem problem;
  std::vector<std::uint32_t> chosen(sherd.size());
  std::iota(chosen.begin(), chosen.end(), 0u);
  std::mt19937_64 rng(params.seed);
  if (chosen.size() > params.max_points) {
    std::shuffle(chosen.begin(), chosen.end(), rng);
    chosen.resize(params.max_points);
  }
  Vec3d centroid = Vec3d::Zero();
  for (auto i : chosen) centroid += sherd.points[i].cast<double>();
  centroid /= static_cast<double>(chosen.size());
  for (auto i : chosen) {
    problem.points.push_back(sherd.points[i].cast<double>() - centroid);
    problem.normals.push_back(sherd.normals[i].cast<double>().normalized());
  }
  const Vec3d start_direction = start.direction.normalized();
  Axis4 axis{start.point - centroid, start_direction};
  axis.point -= axis.point.dot(axis.direction) * axis.direction;

  std::vector<HalfPlanePoint> hp;
  Eigen::Matrix4d covariance = Eigen::Matrix4d::Zero();
  double sigma_mm = 0.0;
  for (int round = 0; round < params.rounds; ++round) {
    const double t = params.rounds > 1 ? static_cast<double>(round) / (params.rounds - 1) : 1.0;
    const double radius = params.first_radius_mm * std::pow(params.last_radius_mm / params.first_radius_mm, t);
    to_half_plane(problem.points, problem.normals, axis, hp);
    // The sherd's arc about the axis, from its circular mean (the azimuths may wrap at ±pi).
    double sum_sin = 0.0, sum_cos = 0.0;
    for (const auto& p : hp) sum_sin += std::sin(p.phi), sum_cos += std::cos(p.phi);
    const double phi_mid = std::atan2(sum_sin, sum_cos);
    double phi_lo = M_PI, phi_hi = -M_PI;
    for (const auto& p : hp) {
      const double a = std::remainder(p.phi - phi_mid, 2 * M_PI);
      phi_lo = std::min(phi_lo, a);
      phi_hi = std::max(phi_hi, a);
    }
    // Neighbours from at least 1/8 of the sherd's arc away.
    find_neighbourhoods(problem, hp, radius, (phi_hi - phi_lo) / 8.0, params.max_neighbours);
    constexpr std::size_t kMinUsed = 100;
    if (problem.used.size() < kMinUsed) {
      estimate.method = start.method;  // nothing to refine with: the start stands
      return estimate;
    }
    // Cauchy weights from the residuals about the current axis, at a robust scale (MAD).
    std::vector<double> residual(problem.used.size()), absolute(problem.used.size());
    for (std::size_t k = 0; k < problem.used.size(); ++k) {
      residual[k] = local_line_distance(hp, problem.used[k], problem.neighbours[k]);
      absolute[k] = std::abs(residual[k]);
    }
    const double scale = std::max(2.385 * 1.4826 * median_of(absolute), 0.01);  // Cauchy's 95 % constant
    problem.sqrt_weight.resize(problem.used.size());
    for (std::size_t k = 0; k < problem.used.size(); ++k) {
      problem.sqrt_weight[k] = 1.0 / std::sqrt(1.0 + std::pow(residual[k] / scale, 2));
    }

    ConsistencyFunctor functor;
    functor.problem = &problem;
    functor.start = axis;
    functor.e1 = perpendicular_to(axis.direction);
    functor.e2 = axis.direction.cross(functor.e1);
    Eigen::NumericalDiff<ConsistencyFunctor> numeric(functor);
    Eigen::LevenbergMarquardt<Eigen::NumericalDiff<ConsistencyFunctor>> solver(numeric);
    solver.parameters.maxfev = 100;
    Eigen::VectorXd x = Eigen::VectorXd::Zero(4);
    solver.minimize(x);
    axis = functor.axis_at(x);
    axis.point -= axis.point.dot(axis.direction) * axis.direction;

    if (round + 1 == params.rounds) {
      // Covariance of the 4 parameters, Gauss-Newton: σ² (JᵀWJ)⁻¹, at the solution.
      Eigen::VectorXd fx(functor.values());
      functor(x, fx);
      Eigen::MatrixXd jacobian(functor.values(), 4);
      numeric.df(x, jacobian);
      const double dof = std::max(1, functor.values() - 4);
      sigma_mm = std::sqrt(fx.squaredNorm() / dof);
      covariance = sigma_mm * sigma_mm * (jacobian.transpose() * jacobian).inverse();
    }
  }

  const double moved_deg = std::acos(std::min(1.0, std::abs(axis.direction.dot(start_direction)))) / kDegToRad;
  if (!(moved_deg <= params.max_move_deg) || !covariance.allFinite()) {
    estimate.method = start.method;
    estimate.reason = fmt::format("profile-consistency refinement diverged ({:.1f} deg from the start); the start stands",
                                  moved_deg);
    return estimate;
  }
  if (axis.direction.dot(start_direction) < 0.0) axis.direction = -axis.direction;
  estimate.direction = axis.direction;
  estimate.point = centroid + axis.point;
  estimate.rms_mm = sigma_mm;
  // Tilt parameters are tangents of the direction change: their sds are radians. The covariance
  // treats the residuals as independent; sd_inflation accounts for what it misses (see RefineParams).
  estimate.angle_sd_deg = params.sd_inflation * std::sqrt(covariance(0, 0) + covariance(1, 1)) / kDegToRad;
  estimate.offset_sd_mm = params.sd_inflation * std::sqrt(covariance(2, 2) + covariance(3, 3));
  return estimate;
}

}  // namespace sherd::axis
