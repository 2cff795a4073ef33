// The reference method (what the station's design descends from): circle templates in parallel
// plane sections. A plane perpendicular to the axis cuts a surface of revolution in circles about
// the axis, so with the right plane normal the circle centres of all sections lie on one line along
// that normal; with a tilted plane set the sections are ellipses whose fitted circles drift across
// the planes. The spread of the centres, projected into the planes, measures that drift.
#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

#include "processing/axis/axis.h"

namespace sherd::axis {
namespace {

constexpr double kDegToRad = M_PI / 180.0;
constexpr double kNoFit = std::numeric_limits<double>::infinity();

using Vec2 = Eigen::Vector2d;

Vec3d perpendicular_to(const Vec3d& v) {
  const Vec3d helper = std::abs(v.x()) < 0.9 ? Vec3d::UnitX() : Vec3d::UnitY();
  return v.cross(helper).normalized();
}

struct Circle {
  Vec2 centre;
  double radius = 0.0;
};

// Algebraic (Kåsa) circle fit, then Gauss-Newton on the geometric distances. Hand-written: a
// 3-parameter least squares that Eigen solves directly; no Debian library fits circles to 2D points
// without pulling in PCL's sample-consensus machinery for a model it would not refine.
std::optional<Circle> fit_circle(const std::vector<Vec2>& pts) {
  if (pts.size() < 5) return std::nullopt;
  Vec2 mean = Vec2::Zero();
  for (const auto& p : pts) mean += p;
  mean /= static_cast<double>(pts.size());
  Eigen::MatrixXd a(pts.size(), 3);
  Eigen::VectorXd b(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Vec2 q = pts[i] - mean;
    a.row(i) << q.x(), q.y(), 1.0;
    b[i] = -q.squaredNorm();
  }
  const Eigen::Vector3d abc = a.colPivHouseholderQr().solve(b);
  Circle c{mean + Vec2(-abc[0] / 2, -abc[1] / 2), 0.0};
  const double r2 = abc.head<2>().squaredNorm() / 4 - abc[2];
  if (!(r2 > 0.0)) return std::nullopt;
  c.radius = std::sqrt(r2);
  for (int it = 0; it < 10; ++it) {
    Eigen::Matrix3d jtj = Eigen::Matrix3d::Zero();
    Eigen::Vector3d jtr = Eigen::Vector3d::Zero();
    for (const auto& p : pts) {
      const Vec2 d = p - c.centre;
      const double dist = d.norm();
      if (dist < 1e-9) continue;
      const Eigen::Vector3d j(-d.x() / dist, -d.y() / dist, -1.0);
      jtj += j * j.transpose();
      jtr += j * (dist - c.radius);
    }
    const Eigen::Vector3d step = jtj.ldlt().solve(-jtr);
    if (!step.allFinite()) return std::nullopt;
    c.centre += step.head<2>();
    c.radius += step[2];
    if (step.norm() < 1e-6) break;
  }
  if (!c.centre.allFinite() || !(c.radius > 0.0)) return std::nullopt;
  return c;
}

// The sections of the sherd with planes perpendicular to `normal`, a circle fitted into each.
struct Sections {
  std::vector<Vec3d> centres;  // 3D, centred frame
  double spread_mm = kNoFit;   // RMS of the centres about their mean, within the planes
  double mean_radius_mm = 0.0;
};

Sections fit_sections(const std::vector<Vec3d>& points, const std::vector<Vec3d>& normals,
                      const Vec3d& normal, const ReferenceParams& params) {
  const Vec3d u = perpendicular_to(normal), v = normal.cross(u);
  double lo = kNoFit, hi = -kNoFit;
  for (const auto& p : points) {
    lo = std::min(lo, p.dot(normal));
    hi = std::max(hi, p.dot(normal));
  }
  Sections s;
  const int n = params.sections;
  // Planes inset from both ends: the end sections hold only the rounded lip or a ragged break.
  std::vector<std::vector<Vec2>> slab(n);
  for (std::size_t i = 0; i < points.size(); ++i) {
    // A skin crosses the plane where its normal lies in the plane; a face parallel to it does not.
    if (std::abs(normals[i].dot(normal)) > 0.8) continue;
    const double t = (points[i].dot(normal) - lo) / std::max(hi - lo, 1e-9) * (n + 1) - 1.0;
    const int k = static_cast<int>(std::lround(t));
    if (k < 0 || k >= n) continue;
    if (std::abs(t - k) * (hi - lo) / (n + 1) > params.slab_half_width_mm) continue;
    slab[k].push_back({points[i].dot(u), points[i].dot(v)});
  }
  std::vector<Vec2> centres2;
  double radius_sum = 0.0;
  for (int k = 0; k < n; ++k) {
    if (static_cast<int>(slab[k].size()) < params.min_section_points) continue;
    const auto circle = fit_circle(slab[k]);
    if (!circle) continue;
    const double h = lo + (hi - lo) * (k + 1) / (n + 1);
    centres2.push_back(circle->centre);
    s.centres.push_back(h * normal + circle->centre.x() * u + circle->centre.y() * v);
    radius_sum += circle->radius;
  }
  if (centres2.size() < 3) return s;
  Vec2 mean = Vec2::Zero();
  for (const auto& c : centres2) mean += c;
  mean /= static_cast<double>(centres2.size());
  double sum_sq = 0.0;
  for (const auto& c : centres2) sum_sq += (c - mean).squaredNorm();
  s.spread_mm = std::sqrt(sum_sq / centres2.size());
  s.mean_radius_mm = radius_sum / centres2.size();
  return s;
}

// The plane normal whose sections' centres align best, searched by shrinking steps of tilt about
// `start` (a pattern search: the spread is not smooth in the normal, sections gain and lose
// points).
Vec3d align_centres(const std::vector<Vec3d>& points, const std::vector<Vec3d>& normals, Vec3d best,
                    const ReferenceParams& params, double step_deg) {
  double best_spread = fit_sections(points, normals, best, params).spread_mm;
  for (; step_deg > 0.02; step_deg /= 2) {
    bool moved = true;
    while (moved) {
      moved = false;
      const Vec3d e1 = perpendicular_to(best), e2 = best.cross(e1);
      for (const Vec3d& e : {e1, Vec3d(-e1), e2, Vec3d(-e2)}) {
        const Vec3d candidate = (best + std::tan(step_deg * kDegToRad) * e).normalized();
        const double spread = fit_sections(points, normals, candidate, params).spread_mm;
        if (spread < best_spread) {
          best_spread = spread;
          best = candidate;
          moved = true;
          break;
        }
      }
    }
  }
  return best;
}

// Best plane normal among directions cos(a)·x + sin(a)·y, a in [from, to] by `step` (degrees).
Vec3d best_in_fan(const std::vector<Vec3d>& points, const std::vector<Vec3d>& normals,
                  const Vec3d& x, const Vec3d& y, double from, double to, double step,
                  const ReferenceParams& params) {
  Vec3d best = x;
  double best_spread = kNoFit;
  for (double a = from; a <= to; a += step) {
    const Vec3d d = std::cos(a * kDegToRad) * x + std::sin(a * kDegToRad) * y;
    const double spread = fit_sections(points, normals, d, params).spread_mm;
    if (spread < best_spread) best_spread = spread, best = d;
  }
  return best;
}

// The balancing plane: the best-fit plane of the sherd's inner (concave) side. Returns its
// in-plane axes and normal (eigenvectors of the inner side's covariance, largest first).
Eigen::Matrix3d balancing_plane(const std::vector<Vec3d>& points,
                                const std::vector<Vec3d>& normals) {
  auto covariance_of = [&](auto&& keep) {
    Vec3d mean = Vec3d::Zero();
    int n = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (keep(i)) mean += points[i], ++n;
    }
    mean /= std::max(n, 1);
    Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (keep(i)) c += (points[i] - mean) * (points[i] - mean).transpose();
    }
    return c;
  };
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> all(
      covariance_of([](std::size_t) { return true; }));
  Vec3d thin = all.eigenvectors().col(0);
  // Turn the thin direction towards the concave side: the sherd's far parts bend that way.
  double bend = 0.0;
  for (const auto& p : points) bend += p.dot(thin) * (p.squaredNorm() - std::pow(p.dot(thin), 2));
  if (bend < 0.0) thin = -thin;
  // The inner skin faces the concave side.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> inner(
      covariance_of([&](std::size_t i) { return normals[i].dot(thin) > 0.5; }));
  Eigen::Matrix3d axes;
  axes.col(0) = inner.eigenvectors().col(2);
  axes.col(1) = inner.eigenvectors().col(1);
  axes.col(2) = inner.eigenvectors().col(0);
  if (!axes.allFinite()) {
    axes.col(0) = all.eigenvectors().col(2);
    axes.col(1) = all.eigenvectors().col(1);
    axes.col(2) = thin;
  }
  return axes;
}

}  // namespace

AxisEstimate estimate_axis_reference(const Cloud& sherd, const ReferenceParams& params) {
  AxisEstimate estimate;
  estimate.method = params.variant == ReferenceVariant::Automatic
                        ? "reference-circle-templates-automatic"
                        : "reference-circle-templates-semi-automatic";
  if (!sherd.has_normals() || sherd.size() < 50) {
    estimate.reason = "too few points with normals for plane sections";
    return estimate;
  }
  Vec3d centroid = Vec3d::Zero();
  for (const auto& p : sherd.points) centroid += p.cast<double>();
  centroid /= static_cast<double>(sherd.size());
  std::vector<Vec3d> points(sherd.size()), normals(sherd.size());
  for (std::size_t i = 0; i < sherd.size(); ++i) {
    points[i] = sherd.points[i].cast<double>() - centroid;
    normals[i] = sherd.normals[i].cast<double>().normalized();
  }

  Vec3d normal = Vec3d::UnitZ();
  if (params.variant == ReferenceVariant::Automatic) {
    const Eigen::Matrix3d plane = balancing_plane(points, normals);
    // Stage 1: plane normals within the balancing plane; the best lies in the plane of symmetry.
    const Vec3d in_symmetry =
        best_in_fan(points, normals, plane.col(0), plane.col(1), 0.0, 179.0, 5.0, params);
    // Stage 2: turn the plane set about the normal of the plane of symmetry.
    normal = best_in_fan(points, normals, in_symmetry, plane.col(2), -85.0, 85.0, 2.5, params);
  }
  // Finish: align the centres by small tilts of the plane set.
  normal = align_centres(points, normals, normal, params,
                         params.variant == ReferenceVariant::Automatic ? 2.0 : 8.0);
  const Sections sections = fit_sections(points, normals, normal, params);
  if (!std::isfinite(sections.spread_mm)) {
    estimate.reason = "no three plane sections hold a circle";
    return estimate;
  }
  Vec3d mean = Vec3d::Zero();
  for (const auto& c : sections.centres) mean += c;
  mean /= static_cast<double>(sections.centres.size());
  estimate.direction = normal;
  // The axis point nearest the centroid (the origin of the centred frame).
  estimate.point = centroid + mean - mean.dot(normal) * normal;
  estimate.rms_mm = sections.spread_mm;
  estimate.found = true;
  return estimate;
}

}  // namespace sherd::axis
