// Axis of rotation from normal lines. Every normal line of a surface of revolution meets the axis.
// With Plücker coordinates (n, p×n) of a normal line and (a, ā) of the axis, "meets" is the linear
// condition a·(p×n) + ā·n = 0 (Pottmann & Wallner, Computational Line Geometry). Minimising the sum
// of squares with |a| = 1 is a 6×6 quadratic form; ā is eliminated in closed form, leaving a 3×3
// eigenproblem for a. That linear fit is the RANSAC hypothesis and the start of a
// Levenberg-Marquardt refinement (Eigen) of the 4-DOF line against the line-to-line distances, each
// scaled by its tolerance (see axis.h: a distance floor plus an angle times the point's distance to
// the axis), so that a far point with a slightly tilted normal weighs no more than its normal
// deserves.
#include "processing/axis/axis.h"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <random>
#include <unordered_map>

#include "core/errors.h"
#include "processing/axis/fit_common.h"

namespace sherd::axis {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

struct NormalLine {
  Vec3d point;   // centred on the sherd's centroid
  Vec3d normal;  // unit
};

using detail::Line;

// Points binned into cubic cells of one size; a search within that size visits the 27 cells
// around the query. Hand-written: sherd_axis links no spatial index (PCL/FLANN would need their
// libraries), and every search here has one fixed radius, the case a uniform grid serves best.
class RadiusGrid {
 public:
  RadiusGrid(const std::vector<Vec3d>& points, double cell) : points_(points), cell_(cell) {
    for (std::uint32_t i = 0; i < points.size(); ++i) cells_[key(cell_of(points[i]))].push_back(i);
  }
  // Calls f(index, squared distance) for every point within `radius` (≤ the cell size) of q.
  template <class F>
  void for_each_within(const Vec3d& q, double radius, F&& f) const {
    const auto c = cell_of(q);
    const double r2 = radius * radius;
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const auto it = cells_.find(key({c[0] + dx, c[1] + dy, c[2] + dz}));
          if (it == cells_.end()) continue;
          for (auto j : it->second) {
            const double d2 = (points_[j] - q).squaredNorm();
            if (d2 <= r2) f(j, d2);
          }
        }
  }

 private:
  std::array<std::int64_t, 3> cell_of(const Vec3d& p) const {
    return {static_cast<std::int64_t>(std::floor(p.x() / cell_)),
            static_cast<std::int64_t>(std::floor(p.y() / cell_)),
            static_cast<std::int64_t>(std::floor(p.z() / cell_))};
  }
  static std::int64_t key(const std::array<std::int64_t, 3>& c) {
    constexpr std::int64_t kBias = 1 << 20;  // cells of a sherd-sized cloud stay far inside ±2^20
    return ((c[0] + kBias) << 42) | ((c[1] + kBias) << 21) | (c[2] + kBias);
  }
  const std::vector<Vec3d>& points_;
  double cell_;
  std::unordered_map<std::int64_t, std::vector<std::uint32_t>> cells_;
};

// Median distance to the nearest neighbour over a sample of points; `probe_mm` bounds the search
// (points with no neighbour that close do not count; if none has one, the probe size is returned).
double median_spacing(const std::vector<Vec3d>& points, std::mt19937_64& rng, double probe_mm) {
  const RadiusGrid grid(points, probe_mm);
  std::uniform_int_distribution<std::size_t> pick(0, points.size() - 1);
  std::vector<double> nearest;
  for (int k = 0; k < 1000; ++k) {
    const std::size_t i = pick(rng);
    double best = std::numeric_limits<double>::infinity();
    grid.for_each_within(points[i], probe_mm, [&](std::uint32_t j, double d2) {
      if (j != i && d2 > 0.0) best = std::min(best, d2);
    });
    if (std::isfinite(best)) nearest.push_back(std::sqrt(best));
  }
  if (nearest.empty()) return probe_mm;
  std::nth_element(nearest.begin(), nearest.begin() + nearest.size() / 2, nearest.end());
  return nearest[nearest.size() / 2];
}

// The normal of the plane fitted (PCA) to the neighbours of `at` within `radius` whose input
// normals agree with its own (the opposite skin of the wall, ~180° away, is left out), oriented
// like the input normal; nullopt where too few neighbours agree for a plane.
std::optional<Vec3d> pca_normal(const std::vector<Vec3d>& points, const std::vector<Vec3d>& normals,
                                const RadiusGrid& grid, std::uint32_t at, double radius,
                                double min_cos) {
  constexpr int kMinNeighbours = 8;
  Vec3d sum = Vec3d::Zero();
  Eigen::Matrix3d sum_outer = Eigen::Matrix3d::Zero();
  int count = 0;
  grid.for_each_within(points[at], radius, [&](std::uint32_t j, double) {
    if (normals[j].dot(normals[at]) < min_cos) return;
    const Vec3d d = points[j] - points[at];  // relative to the query: no loss of precision
    sum += d;
    sum_outer += d * d.transpose();
    ++count;
  });
  if (count < kMinNeighbours) return std::nullopt;
  const Vec3d mean = sum / count;
  const Eigen::Matrix3d covariance = sum_outer / count - mean * mean.transpose();
  const Vec3d n = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(covariance).eigenvectors().col(0);
  if (!n.allFinite()) return std::nullopt;
  return n.dot(normals[at]) < 0.0 ? Vec3d(-n) : n;
}

// How far a normal line may miss the axis: see Params::inlier_distance_mm / inlier_angle_deg.
struct Tolerance {
  double floor_mm;
  double slope;  // tan(inlier_angle)
};

// Distance between a normal line and the axis, signed and divided by the line's tolerance, or
// nullopt when they are too close to parallel for that distance to mean anything (see
// Params::min_normal_axis_angle_deg). `distance_mm`, if given, receives the unscaled distance.
std::optional<double> scaled_miss(const NormalLine& l, const Line& axis, double min_sin,
                                  const Tolerance& tol, double* distance_mm = nullptr) {
  const Vec3d common = axis.direction.cross(l.normal);
  const double sin_angle = common.norm();
  if (sin_angle < min_sin) return std::nullopt;
  const Vec3d w = l.point - axis.point;
  const double d = w.dot(common) / sin_angle;
  // Position along the normal line of its closest approach to the axis: the lever of the normal's
  // angular error.
  const double cos_angle = l.normal.dot(axis.direction);
  const double along =
      (w.dot(axis.direction) * cos_angle - w.dot(l.normal)) / (sin_angle * sin_angle);
  if (distance_mm) *distance_mm = d;
  return d / (tol.floor_mm + std::abs(along) * tol.slope);
}

// Linear line-complex fit of the axis to lines[indices]; nullopt if the system is degenerate.
std::optional<Line> fit_line_complex(const std::vector<NormalLine>& lines,
                                     const std::vector<std::uint32_t>& indices, double scale) {
  Eigen::Matrix3d mm = Eigen::Matrix3d::Zero(), mn = Eigen::Matrix3d::Zero(),
                  nn = Eigen::Matrix3d::Zero();
  for (auto i : indices) {
    // Positions scaled to ~unit size so that moments and directions weigh alike.
    const Vec3d moment = (lines[i].point / scale).cross(lines[i].normal);
    const Vec3d& n = lines[i].normal;
    mm += moment * moment.transpose();
    mn += moment * n.transpose();
    nn += n * n.transpose();
  }
  // Pseudo-inverse of Σ n nᵀ: for a cylinder all normals are perpendicular to the axis and the
  // matrix is singular; the missing component of ā is the complex's pitch, which does not move
  // the axis line a × ā.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> nn_eig(nn);
  const double cutoff = 1e-9 * std::max(nn_eig.eigenvalues().maxCoeff(), 1e-300);
  Eigen::Vector3d inverse_values;
  for (int k = 0; k < 3; ++k) {
    const double v = nn_eig.eigenvalues()[k];
    inverse_values[k] = v > cutoff ? 1.0 / v : 0.0;
  }
  const Eigen::Matrix3d nn_pinv =
      nn_eig.eigenvectors() * inverse_values.asDiagonal() * nn_eig.eigenvectors().transpose();
  const Eigen::Matrix3d reduced = mm - mn * nn_pinv * mn.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> reduced_eig(reduced);
  const Vec3d direction = reduced_eig.eigenvectors().col(0);  // smallest eigenvalue first
  if (!direction.allFinite()) return std::nullopt;
  const Vec3d moment_bar = -nn_pinv * mn.transpose() * direction;
  return Line{direction.cross(moment_bar) * scale, direction};
}

// Least squares of the line-to-line distances over the 4 DOF of the axis: two tilts of the
// direction and two shifts of the point, both in the plane perpendicular to the start direction.
struct AxisDistanceFunctor {
  using Scalar = double;
  using InputType = Eigen::VectorXd;
  using ValueType = Eigen::VectorXd;
  using JacobianType = Eigen::MatrixXd;
  enum { InputsAtCompileTime = Eigen::Dynamic, ValuesAtCompileTime = Eigen::Dynamic };

  const std::vector<NormalLine>* lines = nullptr;
  const std::vector<std::uint32_t>* indices = nullptr;
  Tolerance tolerance{};
  detail::LineAboutStart line;

  int inputs() const { return 4; }
  int values() const { return static_cast<int>(indices->size()); }

  int operator()(const Eigen::VectorXd& x, Eigen::VectorXd& residuals) const {
    const Line axis = line.at(x);
    for (std::size_t k = 0; k < indices->size(); ++k) {
      // Inliers were chosen away from parallel; a line that turns parallel during the refinement
      // is capped at the MSAC cap (1) rather than dropped, so the sum stays continuous.
      const auto miss = scaled_miss((*lines)[(*indices)[k]], axis, 1e-6, tolerance);
      residuals[static_cast<Eigen::Index>(k)] = miss ? *miss : 1.0;
    }
    return 0;
  }
};

Line refine(const std::vector<NormalLine>& lines, const std::vector<std::uint32_t>& indices,
            const Line& start, const Tolerance& tolerance) {
  const AxisDistanceFunctor functor{.lines = &lines,
                                    .indices = &indices,
                                    .tolerance = tolerance,
                                    .line = detail::LineAboutStart(start)};
  return functor.line.at(detail::minimise_line(functor, 200));
}

struct Scored {
  std::vector<std::uint32_t> inliers;
  std::size_t informative = 0;  // lines not near-parallel to the axis: those that can meet it
  double rms = 0.0;             // of the inliers' distances, mm
};

Scored score(const std::vector<NormalLine>& lines, const Line& axis, const Tolerance& tolerance,
             double min_sin) {
  Scored s;
  double sum_sq = 0.0;
  for (std::uint32_t i = 0; i < lines.size(); ++i) {
    double d = 0.0;
    const auto miss = scaled_miss(lines[i], axis, min_sin, tolerance, &d);
    if (miss) ++s.informative;
    if (miss && std::abs(*miss) <= 1.0) {
      s.inliers.push_back(i);
      sum_sq += d * d;
    }
  }
  if (!s.inliers.empty()) s.rms = std::sqrt(sum_sq / s.inliers.size());
  return s;
}

// MSAC cost: truncated squared scaled miss, so that a hypothesis is judged by how well its
// inliers fit, not only by how many there are.
double msac_cost(const std::vector<NormalLine>& lines, const Line& axis, const Tolerance& tolerance,
                 double min_sin) {
  double cost = 0.0;
  for (const auto& l : lines) {
    const auto miss = scaled_miss(l, axis, min_sin, tolerance);
    cost += miss ? std::min(*miss * *miss, 1.0) : 1.0;
  }
  return cost;
}

// RMS distance of the lines to the point they pass closest to in the least-squares sense.
double common_point_rms(const std::vector<NormalLine>& lines,
                        const std::vector<std::uint32_t>& indices) {
  Eigen::Matrix3d lhs = Eigen::Matrix3d::Zero();
  Vec3d rhs = Vec3d::Zero();
  for (auto i : indices) {
    const Eigen::Matrix3d across =
        Eigen::Matrix3d::Identity() - lines[i].normal * lines[i].normal.transpose();
    lhs += across;
    rhs += across * lines[i].point;
  }
  const Vec3d centre = lhs.ldlt().solve(rhs);
  double sum_sq = 0.0;
  for (auto i : indices) {
    sum_sq += (lines[i].point - centre).cross(lines[i].normal).squaredNorm();
  }
  return std::sqrt(sum_sq / indices.size());
}

double angle_between_axes_deg(const Vec3d& a, const Vec3d& b) {
  return std::acos(std::min(1.0, std::abs(a.dot(b)))) / kDegToRad;
}

double point_to_line_distance(const Vec3d& p, const Line& l) {
  return (p - l.point).cross(l.direction).norm();
}

AxisEstimate not_found(AxisEstimate estimate, std::string reason) {
  estimate.found = false;
  estimate.reason = std::move(reason);
  return estimate;
}

}  // namespace

AxisEstimate estimate_axis(const Cloud& sherd, const Params& params) {
  AxisEstimate estimate;
  estimate.method = "normal-line-complex+ransac+lm";
  if (!sherd.has_normals()) {
    return not_found(estimate,
                     "no normals: the axis is estimated from surface normals; "
                     "compute normals before axis estimation");
  }
  for (std::size_t i = 0; i < sherd.size(); ++i) {
    if (!sherd.points[i].allFinite() || !sherd.normals[i].allFinite()) {
      throw InputError(fmt::format(
          "axis estimation: point {} of {} has a non-finite coordinate or normal; remove invalid "
          "points before processing",
          i, sherd.size()));
    }
  }
  constexpr std::size_t kMinLines = 50;
  if (sherd.size() < kMinLines) {
    return not_found(estimate, fmt::format("too few points: {} (at least {} with normals needed)",
                                           sherd.size(), kMinLines));
  }

  // Too small: over a few millimetres every smooth wall fits many axes.
  Vec3f lo = sherd.points[0], hi = sherd.points[0];
  for (const auto& p : sherd.points) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const double extent_mm = (hi - lo).norm();
  if (extent_mm < params.min_extent_mm) {
    return not_found(estimate, fmt::format("too small: {:.1f} mm across (at least {:.0f} mm "
                                           "needed for an axis)",
                                           extent_mm, params.min_extent_mm));
  }

  std::mt19937_64 rng(params.seed);
  const auto [chosen, centroid] = detail::subsample(sherd, params.max_lines, rng);
  // All points take part in the normal re-estimation, only the chosen ones become lines.
  std::vector<Vec3d> points(sherd.size()), input_normals(sherd.size());
  for (std::size_t i = 0; i < sherd.size(); ++i) {
    points[i] = sherd.points[i].cast<double>() - centroid;
    const Vec3d n = sherd.normals[i].cast<double>();
    // An unset (zero) normal carries no direction: it stays zero, agrees with no neighbour.
    input_normals[i] = n.norm() < 0.5 ? Vec3d::Zero() : Vec3d(n.normalized());
  }
  constexpr double kSpacingProbeMm = 2.0;  // spacings coarser than this leave the radius at its cap
  const double radius =
      params.normal_radius_mm > 0.0
          ? params.normal_radius_mm
          : std::clamp(params.normal_radius_spacings * median_spacing(points, rng, kSpacingProbeMm),
                       1.0, 5.0);
  const RadiusGrid grid(points, radius);
  const double min_cos = std::cos(params.normal_agreement_deg * kDegToRad);
  std::vector<NormalLine> lines;
  lines.reserve(chosen.size());
  double sum_sq_radius = 0.0;
  for (auto i : chosen) {
    if (input_normals[i].isZero()) continue;
    const auto n = pca_normal(points, input_normals, grid, i, radius, min_cos);
    if (!n) continue;
    lines.push_back({points[i], *n});
    sum_sq_radius += lines.back().point.squaredNorm();
  }
  if (lines.size() < kMinLines) {
    return not_found(estimate,
                     fmt::format("not a surface: only {} points have enough neighbours "
                                 "with agreeing normals within {:.1f} mm for a normal (at "
                                 "least {} needed)",
                                 lines.size(), radius, kMinLines));
  }
  const double scale = std::max(std::sqrt(sum_sq_radius / lines.size()), 1e-6);

  // Too flat: all normals (up to sign) along one direction.
  Eigen::Matrix3d normal_scatter = Eigen::Matrix3d::Zero();
  for (const auto& l : lines) normal_scatter += l.normal * l.normal.transpose();
  const double along_share =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(normal_scatter).eigenvalues()[2] /
      static_cast<double>(lines.size());
  const double spread_deg = std::asin(std::sqrt(std::max(0.0, 1.0 - along_share))) / kDegToRad;
  if (spread_deg < params.flat_normal_spread_deg) {
    return not_found(estimate, fmt::format("too flat: normals spread only {:.1f} deg around one "
                                           "direction (no surface of revolution)",
                                           spread_deg));
  }

  const double min_sin = std::sin(params.min_normal_axis_angle_deg * kDegToRad);
  const Tolerance tolerance{params.inlier_distance_mm,
                            std::tan(params.inlier_angle_deg * kDegToRad)};
  constexpr std::size_t kSampleSize = 6;  // 5 lines fix a linear complex; one more for noise
  std::uniform_int_distribution<std::uint32_t> pick(0,
                                                    static_cast<std::uint32_t>(lines.size() - 1));
  std::optional<Line> best;
  double best_cost = std::numeric_limits<double>::infinity();
  std::vector<std::uint32_t> sample(kSampleSize);
  for (int it = 0; it < params.ransac_iterations; ++it) {
    for (auto& s : sample) s = pick(rng);
    const auto hypothesis = fit_line_complex(lines, sample, scale);
    if (!hypothesis) continue;
    const double cost = msac_cost(lines, *hypothesis, tolerance, min_sin);
    if (cost < best_cost) {
      best_cost = cost;
      best = hypothesis;
    }
  }
  if (!best) return not_found(estimate, "not rotational: no line complex fits the normals");

  // Refit on the inliers, refine, and once more with the inliers of the refined axis.
  Scored scored = score(lines, *best, tolerance, min_sin);
  Line axis = *best;
  for (int round = 0; round < 2 && scored.inliers.size() >= kMinLines; ++round) {
    if (round == 0) {
      if (auto linear = fit_line_complex(lines, scored.inliers, scale)) axis = *linear;
    }
    axis = refine(lines, scored.inliers, axis, tolerance);
    scored = score(lines, axis, tolerance, min_sin);
  }
  // The share among the lines that can meet the axis at all: the floor of a plate or the flat
  // underside of a base (normals along the axis) says nothing for or against it.
  estimate.inlier_share = static_cast<double>(scored.inliers.size()) /
                          static_cast<double>(std::max<std::size_t>(scored.informative, 1));
  estimate.rms_mm = scored.rms;
  estimate.direction = axis.direction;
  // The axis point closest to the centroid: the centroid is the origin of the centred lines.
  estimate.point = centroid + axis.point - axis.point.dot(axis.direction) * axis.direction;
  if (estimate.inlier_share < params.min_inlier_share || scored.inliers.size() < kMinLines) {
    return not_found(estimate,
                     fmt::format("not rotational: only {:.0f}% of the normal lines meet "
                                 "one axis (at least {:.0f}% needed)",
                                 100.0 * estimate.inlier_share, 100.0 * params.min_inlier_share));
  }
  // Normals that all meet in one point (a sphere) fit every line through it. On clean data both
  // residuals are near zero and their ratio is noise, hence the absolute floor.
  const double sphere_rms = common_point_rms(lines, scored.inliers);
  if (sphere_rms < std::max(params.sphere_rms_ratio * scored.rms, params.inlier_distance_mm)) {
    return not_found(estimate, fmt::format("not rotational-unique: the normals meet in one point "
                                           "(RMS {:.2f} mm vs {:.2f} mm to the axis), sphere-like, "
                                           "every line through it fits",
                                           sphere_rms, scored.rms));
  }

  // Bootstrap over the inliers: spread of the refined axis under resampling.
  const Line final_axis{axis.point - axis.point.dot(axis.direction) * axis.direction,
                        axis.direction};
  std::uniform_int_distribution<std::size_t> pick_inlier(0, scored.inliers.size() - 1);
  std::vector<std::uint32_t> resample(scored.inliers.size());
  double angle_sq = 0.0, offset_sq = 0.0;
  for (int b = 0; b < params.bootstrap_resamples; ++b) {
    for (auto& r : resample) r = scored.inliers[pick_inlier(rng)];
    const Line replica = refine(lines, resample, final_axis, tolerance);
    angle_sq += std::pow(angle_between_axes_deg(replica.direction, final_axis.direction), 2);
    offset_sq += std::pow(point_to_line_distance(final_axis.point, replica), 2);
  }
  if (params.bootstrap_resamples > 0) {
    estimate.angle_sd_deg = std::sqrt(angle_sq / params.bootstrap_resamples);
    estimate.offset_sd_mm = std::sqrt(offset_sq / params.bootstrap_resamples);
  }
  if (estimate.angle_sd_deg > params.max_angle_sd_deg) {
    return not_found(estimate,
                     fmt::format("axis poorly constrained: direction varies by {:.1f} deg "
                                 "(sd) under resampling (at most {:.1f} accepted)",
                                 estimate.angle_sd_deg, params.max_angle_sd_deg));
  }
  estimate.found = true;
  return estimate;
}

namespace {
struct MethodName {
  Method method;
  const char* name;
};
constexpr MethodName kMethods[] = {{Method::NormalLines, "normal-lines"},
                                   {Method::ReferenceSemiAutomatic, "reference-semi"},
                                   {Method::ReferenceAutomatic, "reference-auto"},
                                   {Method::Refined, "refined"}};
}  // namespace

AxisEstimate estimate(const Cloud& sherd, Method method) {
  switch (method) {
    case Method::NormalLines:
      return estimate_axis(sherd);
    case Method::ReferenceSemiAutomatic:
      return estimate_axis_reference(sherd, {.variant = ReferenceVariant::SemiAutomatic});
    case Method::ReferenceAutomatic:
      return estimate_axis_reference(sherd, {.variant = ReferenceVariant::Automatic});
    case Method::Refined:
      return refine_axis(sherd, estimate_axis(sherd));
  }
  return {};
}

const char* to_string(Method method) {
  for (const auto& m : kMethods) {
    if (m.method == method) return m.name;
  }
  return "?";
}

std::optional<Method> method_from_string(const std::string& name) {
  for (const auto& m : kMethods) {
    if (name == m.name) return m.method;
  }
  return std::nullopt;
}

std::vector<Method> all_methods() {
  std::vector<Method> out;
  for (const auto& m : kMethods) out.push_back(m.method);
  return out;
}

std::string method_names() {
  std::string out;
  for (const auto& m : kMethods) out += (out.empty() ? "" : ", ") + std::string(m.name);
  return out;
}

}  // namespace sherd::axis
