// Profile-consistency refinement of an axis. About the true axis every azimuth of a wheel-made
// sherd shows the same profile: its points, mapped to (radius, height), lie on one thin curve per
// skin. About a tilted or shifted axis the azimuths map to curves shifted against each other, and
// the points spread. The spread is measured, point by point, as the distance of the point from the
// line fitted (PCA) through its neighbours in the half-plane that come from other azimuths (a
// neighbour at the same azimuth agrees about any axis). The neighbourhoods are fixed within a round
// so that the cost is smooth in the 4 axis parameters; Levenberg-Marquardt (Eigen) minimises it
// with Cauchy weights (iteratively reweighted: lips and breaks that wander are outliers), and the
// next round re-finds neighbourhoods about the new axis, in a window scaled to the new spread.
#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <random>
#include <unordered_map>

#include "processing/axis/axis.h"
#include "processing/axis/fit_common.h"

namespace sherd::axis {
namespace {

constexpr double kDegToRad = M_PI / 180.0;
using Vec2 = Eigen::Vector2d;

using detail::Line;

// A point in the half-plane of an axis: (r, h), azimuth, and its normal's (radial, axial) part.
struct HalfPlanePoint {
  Vec2 rh;
  double phi;
  Vec2 normal;  // not normalised: its length is the share of the normal within the half-plane
};

void to_half_plane(const std::vector<Vec3d>& points, const std::vector<Vec3d>& normals,
                   const Line& axis, std::vector<HalfPlanePoint>& out) {
  const Vec3d x = detail::any_perpendicular(axis.direction), y = axis.direction.cross(x);
  out.resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3d d = points[i] - axis.point;
    const double px = d.dot(x), py = d.dot(y);
    const double r = std::hypot(px, py);
    const Vec3d radial = r > 1e-9 ? Vec3d((px * x + py * y) / r) : x;
    out[i] = {{r, d.dot(axis.direction)},
              std::atan2(py, px),
              {normals[i].dot(radial), normals[i].dot(axis.direction)}};
  }
}

// Distance of point i from the mean of its neighbours, along its own half-plane normal: the mean
// of neighbours within a short window along the profile lies on the profile curve.
double local_line_distance(const std::vector<HalfPlanePoint>& hp, std::uint32_t i,
                           const std::vector<std::uint32_t>& neighbours) {
  Vec2 mean = Vec2::Zero();
  for (auto j : neighbours) mean += hp[j].rh;
  mean /= static_cast<double>(neighbours.size());
  return hp[i].normal.normalized().dot(hp[i].rh - mean);
}

struct Problem {
  std::vector<Vec3d> points, normals;                  // centred on the sherd's centroid
  std::vector<std::uint32_t> used;                     // points with a neighbourhood this round
  std::vector<std::vector<std::uint32_t>> neighbours;  // per used point
  std::vector<double> sqrt_face_weight;                // per used point: skin 1, fracture less
  double cauchy_scale_mm = 1.0;
};

struct ConsistencyFunctor {
  using Scalar = double;
  using InputType = Eigen::VectorXd;
  using ValueType = Eigen::VectorXd;
  using JacobianType = Eigen::MatrixXd;
  enum { InputsAtCompileTime = Eigen::Dynamic, ValuesAtCompileTime = Eigen::Dynamic };

  const Problem* problem = nullptr;
  detail::LineAboutStart line;
  mutable std::vector<HalfPlanePoint> hp;

  int inputs() const { return 4; }
  int values() const { return static_cast<int>(problem->used.size()); }
  int operator()(const Eigen::VectorXd& x, Eigen::VectorXd& residuals) const {
    to_half_plane(problem->points, problem->normals, line.at(x), hp);
    for (std::size_t k = 0; k < problem->used.size(); ++k) {
      // Cauchy loss as a residual: its square is c² log(1 + (r/c)²), so that LM minimises the
      // robust cost itself and the weights follow the axis within the round.
      const double r = local_line_distance(hp, problem->used[k], problem->neighbours[k]);
      const double c = problem->cauchy_scale_mm;
      residuals[static_cast<Eigen::Index>(k)] =
          problem->sqrt_face_weight[k] *
          std::copysign(c * std::sqrt(std::log1p((r / c) * (r / c))), r);
    }
    return 0;
  }
};

// Neighbourhoods in the half-plane about the current axis. For each point whose normal lies mostly
// within the half-plane (a skin or a lip, not a side break): the points within `along_mm` of it
// along its profile tangent and `across_mm` across, whose half-plane normals agree (the same skin)
// and whose azimuth differs by at least `min_dphi` (another part of the sherd). The window is wide
// across (several times the spread) and the neighbours are an evenly strided subset, not the
// nearest: choosing the nearest across would choose those that agree with the current axis.
// With `same_azimuth`, the other way round: only neighbours from within min_dphi of the point
// (the local scatter of the surface, whatever the axis).
void find_neighbourhoods(Problem& problem, const std::vector<HalfPlanePoint>& hp, double along_mm,
                         double across_mm, double min_dphi, int max_neighbours,
                         bool same_azimuth = false) {
  // A uniform grid over the half-plane, one window size per round (hand-written for the same
  // reason as the normal-line method's grid).
  const double cell = std::max(along_mm, across_mm);
  auto key = [](std::int64_t cx, std::int64_t cy) { return (cx << 32) ^ (cy & 0xffffffff); };
  auto cell_of = [cell](double v) { return static_cast<std::int64_t>(std::floor(v / cell)); };
  std::unordered_map<std::int64_t, std::vector<std::uint32_t>> grid;
  for (std::uint32_t i = 0; i < hp.size(); ++i)
    grid[key(cell_of(hp[i].rh.x()), cell_of(hp[i].rh.y()))].push_back(i);
  problem.used.clear();
  problem.neighbours.clear();
  std::vector<std::uint32_t> found;
  for (std::uint32_t i = 0; i < hp.size(); ++i) {
    if (hp[i].normal.norm() < 0.7) continue;
    const Vec2 ni = hp[i].normal.normalized(), ti(-ni.y(), ni.x());
    found.clear();
    const auto cx = cell_of(hp[i].rh.x()), cy = cell_of(hp[i].rh.y());
    for (std::int64_t dx = -1; dx <= 1; ++dx)
      for (std::int64_t dy = -1; dy <= 1; ++dy) {
        const auto it = grid.find(key(cx + dx, cy + dy));
        if (it == grid.end()) continue;
        for (auto j : it->second) {
          const Vec2 d = hp[j].rh - hp[i].rh;
          if (std::abs(d.dot(ti)) > along_mm || std::abs(d.dot(ni)) > across_mm) continue;
          if (hp[j].normal.norm() < 0.7 || hp[j].normal.normalized().dot(ni) < 0.7) continue;
          const bool near = std::abs(std::remainder(hp[j].phi - hp[i].phi, 2 * M_PI)) < min_dphi;
          if (near != same_azimuth || j == i) continue;
          found.push_back(j);
        }
      }
    constexpr std::size_t kMinNeighbours = 5;
    if (found.size() < kMinNeighbours) continue;
    const std::size_t stride = (found.size() + max_neighbours - 1) / max_neighbours;
    std::vector<std::uint32_t> nb;
    for (std::size_t k = 0; k < found.size(); k += stride) nb.push_back(found[k]);
    problem.used.push_back(i);
    problem.neighbours.push_back(std::move(nb));
  }
}

// Whether each point is on a skin: it has a partner facing the other way straight through the wall
// (along its -normal, within max_wall_mm, off the line by at most `tolerance_mm`). A fracture face
// or a lip looks along the wall: its opposite face, if any, is the far end of the sherd.
std::vector<bool> skin_points(const std::vector<HalfPlanePoint>& hp, double max_wall_mm,
                              double tolerance_mm) {
  constexpr double kCell = 2.0, kStep = 1.0;
  auto key = [](std::int64_t cx, std::int64_t cy) { return (cx << 32) ^ (cy & 0xffffffff); };
  auto cell_of = [](double v) { return static_cast<std::int64_t>(std::floor(v / kCell)); };
  std::unordered_map<std::int64_t, std::vector<std::uint32_t>> grid;
  for (std::uint32_t i = 0; i < hp.size(); ++i)
    grid[key(cell_of(hp[i].rh.x()), cell_of(hp[i].rh.y()))].push_back(i);
  std::vector<bool> skin(hp.size(), false);
  for (std::uint32_t i = 0; i < hp.size(); ++i) {
    if (hp[i].normal.norm() < 0.7) continue;
    const Vec2 n = hp[i].normal.normalized();
    std::int64_t last = std::numeric_limits<std::int64_t>::min();
    for (double t = kStep; t <= max_wall_mm && !skin[i]; t += kStep) {
      const Vec2 q = hp[i].rh - t * n;
      const std::int64_t k = key(cell_of(q.x()), cell_of(q.y()));
      if (k == last) continue;
      last = k;
      const auto it = grid.find(k);
      if (it == grid.end()) continue;
      for (auto j : it->second) {
        const Vec2 d = hp[j].rh - hp[i].rh;
        if (hp[j].normal.dot(n) > -0.7 * hp[j].normal.norm() || -d.dot(n) < 0.3) continue;
        if (std::abs(d.x() * n.y() - d.y() * n.x()) <= tolerance_mm) {
          skin[i] = true;
          break;
        }
      }
    }
  }
  return skin;
}

double median_of(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// The two-sided 95 % quantile of Student's t with `dof` degrees of freedom (published table; the
// jackknife has at most a dozen).
double student_t_975(int dof) {
  static constexpr double kTable[] = {12.706, 4.303, 3.182, 2.776, 2.571, 2.447,
                                      2.365,  2.306, 2.262, 2.228, 2.201, 2.179};
  constexpr int kRows = sizeof(kTable) / sizeof(kTable[0]);
  return dof < 1 ? kTable[0] : dof <= kRows ? kTable[dof - 1] : 1.959964 + 2.4 / dof;
}

// The sherd's arc about an axis: the circular mean of the azimuths (they may wrap at ±pi) and the
// extent either side of it.
struct Arc {
  double middle = 0.0, lo = M_PI, hi = -M_PI;
  // Which of `sectors` equal parts of the arc the azimuth phi falls in.
  int sector(double phi, int sectors) const {
    const double a = std::remainder(phi - middle, 2 * M_PI);
    return std::clamp(static_cast<int>((a - lo) / (hi - lo + 1e-12) * sectors), 0, sectors - 1);
  }
};
Arc arc_of(const std::vector<HalfPlanePoint>& hp) {
  double sum_sin = 0.0, sum_cos = 0.0;
  for (const auto& p : hp) sum_sin += std::sin(p.phi), sum_cos += std::cos(p.phi);
  Arc arc;
  arc.middle = std::atan2(sum_sin, sum_cos);
  for (const auto& p : hp) {
    const double a = std::remainder(p.phi - arc.middle, 2 * M_PI);
    arc.lo = std::min(arc.lo, a);
    arc.hi = std::max(arc.hi, a);
  }
  return arc;
}

constexpr std::size_t kMinUsed = 100;  // residuals below which a round has nothing to fit

// One round's fixed part about the current axis (hp): neighbourhoods from at least 1/8 of the
// sherd's arc away, face weights (fracture faces and the lip count params.fracture_weight of a
// skin point) and the Cauchy scale from the residuals (MAD). Returns the robust sd of the
// residuals, or nullopt when fewer than kMinUsed points have a neighbourhood.
std::optional<double> prepare_round(Problem& problem, const std::vector<HalfPlanePoint>& hp,
                                    double across_mm, const RefineParams& params) {
  const Arc arc = arc_of(hp);
  find_neighbourhoods(problem, hp, params.along_mm, across_mm, (arc.hi - arc.lo) / 8.0,
                      params.max_neighbours);
  if (problem.used.size() < kMinUsed) return std::nullopt;
  const std::vector<bool> skin = skin_points(hp, params.max_wall_mm, std::max(0.5, across_mm / 2));
  problem.sqrt_face_weight.resize(problem.used.size());
  std::vector<double> absolute(problem.used.size());
  for (std::size_t k = 0; k < problem.used.size(); ++k) {
    problem.sqrt_face_weight[k] = skin[problem.used[k]] ? 1.0 : std::sqrt(params.fracture_weight);
    absolute[k] = std::abs(local_line_distance(hp, problem.used[k], problem.neighbours[k]));
  }
  const double sigma = 1.4826 * median_of(absolute);
  problem.cauchy_scale_mm = std::max(2.385 * sigma, 0.01);  // Cauchy's 95 % efficiency constant
  return sigma;
}

// Covariance of the 4 axis parameters about `axis` by a delete-a-group jackknife over azimuth
// sectors. Each replica repeats the last round — neighbourhoods, weights, fit — on the points
// outside one sector, so that the sector's points neither own a residual nor serve as anyone's
// neighbour. Residuals are not independent (neighbouring points share neighbours and the same
// local misfit of the profile, a break that pulls, a lip that wanders), so the Gauss-Newton
// covariance σ²(JᵀJ)⁻¹ is too small by an unknown factor; a group jackknife needs no model of that
// correlation, only groups longer than its reach (an eighth of the arc against a neighbourhood
// window of a few mm). Var = (g-1)/g Σ (x_i - x̄)(x_i - x̄)ᵀ over the g replicas (Efron & Stein).
// Zero when fewer than two replicas could be fitted.
Eigen::Matrix4d sector_jackknife(const Problem& full, const Line& axis, double across_mm,
                                 const RefineParams& params, int* replicas_fitted) {
  std::vector<HalfPlanePoint> hp;
  to_half_plane(full.points, full.normals, axis, hp);
  const Arc arc = arc_of(hp);
  const int sectors = params.jackknife_sectors, bands = params.jackknife_bands;
  // Height bands split at quantiles of the points' heights.
  std::vector<double> heights;
  for (const auto& p : hp) heights.push_back(p.rh.y());
  std::sort(heights.begin(), heights.end());
  auto band_of = [&](double h) {
    int b = 0;
    while (b + 1 < bands && h > heights[heights.size() * (b + 1) / bands]) ++b;
    return b;
  };
  std::vector<Eigen::VectorXd> replicas;
  for (int group = 0; group < sectors * bands; ++group) {
    Problem part;
    for (std::size_t i = 0; i < full.points.size(); ++i) {
      if (arc.sector(hp[i].phi, sectors) * bands + band_of(hp[i].rh.y()) == group) continue;
      part.points.push_back(full.points[i]);
      part.normals.push_back(full.normals[i]);
    }
    if (part.points.size() == full.points.size()) continue;  // an empty sector changes nothing
    std::vector<HalfPlanePoint> part_hp;
    to_half_plane(part.points, part.normals, axis, part_hp);
    if (!prepare_round(part, part_hp, across_mm, params)) continue;
    const ConsistencyFunctor functor{
        .problem = &part, .line = detail::LineAboutStart(axis), .hp = {}};
    // From the full fit's axis, a replica is a small step away.
    const Eigen::VectorXd x = detail::minimise_line(functor, 40);
    if (x.allFinite()) replicas.push_back(x);
  }
  *replicas_fitted = static_cast<int>(replicas.size());
  Eigen::Matrix4d covariance = Eigen::Matrix4d::Zero();
  if (replicas.size() < 2) return covariance;
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(4);
  for (const auto& x : replicas) mean += x;
  mean /= static_cast<double>(replicas.size());
  for (const auto& x : replicas) covariance += (x - mean) * (x - mean).transpose();
  const double g = static_cast<double>(replicas.size());
  return (g - 1.0) / g * covariance;
}

// How far the sherd is from a surface of revolution about `axis`, against how much its surface
// scatters locally: the robust sds (1.4826 × median absolute value) of the skin points' distances
// from the mean of their neighbours in the half-plane, from other azimuths (at least an eighth of
// the arc away) and from the same azimuths (within that). The windows are the first round's, wide
// enough to see a large spread whole. Fracture faces and the lip are left out.
struct Spread {
  double across_azimuths_mm = 0.0, within_azimuth_mm = 0.0;
};
Spread profile_spread(const Problem& problem, const Line& axis, const RefineParams& params) {
  std::vector<HalfPlanePoint> hp;
  to_half_plane(problem.points, problem.normals, axis, hp);
  const Arc arc = arc_of(hp);
  const std::vector<bool> skin =
      skin_points(hp, params.max_wall_mm, std::max(0.5, params.first_across_mm / 2));
  auto robust_sd = [&](bool same_azimuth) {
    Problem p;
    find_neighbourhoods(p, hp, params.along_mm, params.first_across_mm, (arc.hi - arc.lo) / 8.0,
                        params.max_neighbours, same_azimuth);
    std::vector<double> residuals;
    for (std::size_t k = 0; k < p.used.size(); ++k) {
      if (skin[p.used[k]])
        residuals.push_back(std::abs(local_line_distance(hp, p.used[k], p.neighbours[k])));
    }
    return 1.4826 * median_of(std::move(residuals));
  };
  return {robust_sd(false), robust_sd(true)};
}

// A wheel-made sherd about its axis shows one profile at every azimuth: its points scatter about
// the common profile as much as about their own azimuth's (the scanner's noise; spread / scatter
// ≈ 1 on the simulated sherds at 0.02–0.1 mm noise, at most 1.2 in bench_axis). A hand-made,
// irregular pot has no such axis: about the best one its azimuths disagree, by more than the noise.
// Records the figures; marks the estimate not found and returns false when the spread is more
// than max_spread_ratio times the scatter and more than max_excess_spread_mm beyond it
// (√(spread² − scatter²)).
// `verdict` opens the reason.
bool judge_wheel_made(AxisEstimate& estimate, const Spread& spread, const RefineParams& params,
                      const std::string& verdict = "not wheel-made") {
  estimate.profile_spread_mm = spread.across_azimuths_mm;
  estimate.local_scatter_mm = spread.within_azimuth_mm;
  const double excess =
      std::sqrt(std::max(0.0, spread.across_azimuths_mm * spread.across_azimuths_mm -
                                  spread.within_azimuth_mm * spread.within_azimuth_mm));
  if (spread.across_azimuths_mm <= params.max_spread_ratio * spread.within_azimuth_mm ||
      excess <= params.max_excess_spread_mm) {
    return true;
  }
  estimate.found = false;
  estimate.reason = fmt::format(
      "{}: the profile spreads {:.2f} mm around the fitted surface of revolution against {:.2f} "
      "mm of local scatter ({:.2f} mm beyond it; a wheel-made sherd spreads as much as it "
      "scatters); a hand-made or irregular piece has no axis to draw it about",
      verdict, spread.across_azimuths_mm, spread.within_azimuth_mm, excess);
  return false;
}

}  // namespace

AxisEstimate refine_axis(const Cloud& sherd, const AxisEstimate& start,
                         const RefineParams& params) {
  if (!start.found) return start;
  AxisEstimate estimate = start;
  estimate.method = start.method + "+profile-consistency";

  Problem problem;
  std::mt19937_64 rng(params.seed);
  const auto [chosen, centroid] = detail::subsample(sherd, params.max_points, rng);
  for (auto i : chosen) {
    problem.points.push_back(sherd.points[i].cast<double>() - centroid);
    problem.normals.push_back(sherd.normals[i].cast<double>().normalized());
  }
  const Vec3d start_direction = start.direction.normalized();
  Line axis{start.point - centroid, start_direction};
  axis.point -= axis.point.dot(axis.direction) * axis.direction;

  std::vector<HalfPlanePoint> hp;
  double sigma_mm = 0.0;
  double across_mm = params.first_across_mm;
  double round_across_mm = across_mm;  // the window of the last round
  // The last two rounds' steps (4 parameters each): how far the iteration still moves.
  Eigen::VectorXd last_step = Eigen::VectorXd::Zero(4), step_before = Eigen::VectorXd::Zero(4);
  for (int round = 0; round < params.max_rounds; ++round) {
    to_half_plane(problem.points, problem.normals, axis, hp);
    const auto sigma = prepare_round(problem, hp, across_mm, params);
    if (!sigma) {
      estimate.method = start.method;  // nothing to refine with: the start stands
      return estimate;
    }
    // The next round's window across the profile: wide against the spread about this round's axis.
    round_across_mm = across_mm;
    across_mm = std::max(params.min_across_mm, 6.0 * *sigma);

    const ConsistencyFunctor functor{
        .problem = &problem, .line = detail::LineAboutStart(axis), .hp = {}};
    const Eigen::VectorXd x = detail::minimise_line(functor, 100);
    if (!x.allFinite()) break;
    axis = functor.line.at(x);
    axis.point -= axis.point.dot(axis.direction) * axis.direction;
    step_before = last_step;
    last_step = x;
    Eigen::VectorXd fx(functor.values());
    functor(x, fx);
    sigma_mm = std::sqrt(fx.squaredNorm() / std::max(1, functor.values() - 4));
    const bool settled = x.head<2>().norm() < params.settled_tilt_rad &&
                         x.tail<2>().norm() < params.settled_shift_mm;
    if (round + 1 >= params.min_rounds && settled) break;
  }
  int replicas = 0;
  Eigen::Matrix4d covariance = sector_jackknife(problem, axis, round_across_mm, params, &replicas);
  // Where the rounds stop before the axis settles (each round's neighbourhoods, found about the
  // last axis, hold it back: the steps shrink geometrically, by a ratio q), the rest of the way is
  // an error the jackknife cannot see: the remaining steps sum to last · q / (1 - q). It is added
  // to the covariance as one more independent error (q from the last two steps, at most 0.9).
  if (step_before.norm() > 0.0) {
    const double q = std::min(0.9, last_step.norm() / step_before.norm());
    const Eigen::VectorXd rest = last_step * (q / (1.0 - q));
    covariance += rest * rest.transpose();
  }

  const double moved_deg =
      std::acos(std::min(1.0, std::abs(axis.direction.dot(start_direction)))) / kDegToRad;
  if (!(moved_deg <= params.max_move_deg) || !covariance.allFinite() || replicas < 2) {
    Line start_line{start.point - centroid, start_direction};
    estimate.method = start.method;
    estimate.reason = fmt::format(
        "profile-consistency refinement diverged ({:.1f} deg from the start); the start stands",
        moved_deg);
    // About the start, which stands: a large spread there may also be a start far off the axis.
    judge_wheel_made(estimate, profile_spread(problem, start_line, params), params,
                     fmt::format("not wheel-made, or no axis near the start (the "
                                 "profile-consistency refinement diverged by {:.1f} deg)",
                                 moved_deg));
    return estimate;
  }
  if (axis.direction.dot(start_direction) < 0.0) axis.direction = -axis.direction;
  estimate.direction = axis.direction;
  estimate.point = centroid + axis.point;
  estimate.rms_mm = sigma_mm;
  // Tilt parameters are tangents of the direction change: their sds are radians. The variance is
  // estimated from only replicas - 1 degrees of freedom, so that ±2 sd is the 95 % interval that
  // a known sd would give (Student's t against the normal quantile), the sd is scaled by t / z.
  const double t_over_z = student_t_975(replicas - 1) / 1.959964;
  estimate.angle_sd_deg = t_over_z * std::sqrt(covariance(0, 0) + covariance(1, 1)) / kDegToRad;
  estimate.offset_sd_mm = t_over_z * std::sqrt(covariance(2, 2) + covariance(3, 3));
  if (!judge_wheel_made(estimate, profile_spread(problem, axis, params), params)) return estimate;
  if (estimate.angle_sd_deg > params.max_angle_sd_deg) {
    estimate.found = false;
    estimate.reason = fmt::format(
        "axis poorly constrained: the profile-consistency axis varies by {:.1f} deg (sd) when "
        "parts "
        "of the sherd are left out (at most {:.1f} accepted)",
        estimate.angle_sd_deg, params.max_angle_sd_deg);
  }
  return estimate;
}

}  // namespace sherd::axis
