// Analytic sherds for the axis and profile tests: points and outward normals sampled on a wall of
// revolution (outer skin, inner skin offset by an exact thickness, lip, irregular fracture faces),
// with scanner-like noise, then placed at an arbitrary pose. The truth (axis, radii, thickness)
// is known by construction, independently of the code under test.
#pragma once

#include "core/types.h"

#include <Eigen/Geometry>

#include <array>
#include <cmath>
#include <functional>
#include <random>
#include <vector>

namespace sherd::testing {

using Vec2 = Eigen::Vector2d;

struct WallOfRevolution {
  // Outer skin profile (r, z) in the sherd frame (axis = z through the origin), from base end
  // (s = 0) to rim end (s = 1).
  std::function<Vec2(double)> outer;
  double thickness_mm = 6.0;
  double phi_begin_rad = 0.0, phi_end_rad = M_PI / 3;
  bool flat_lip = true;              // rim end: flat lip face; otherwise an irregular break
  double break_amplitude_mm = 10.0;  // irregularity of the broken ends, in arc length
  bool side_faces = true;            // fracture faces at phi_begin / phi_end
  bool closed_base = false;          // base end closed at the axis (r(0) = 0): no break there
  double spacing_mm = 0.5;
  double noise_mm = 0.05;
  double normal_noise_deg = 1.0;
  unsigned seed = 1;
  // Relief cut into the outer skin only (grooves, ridges): a radial offset in mm as a function of
  // the height z, added to the outer skin; the inner skin stays the smooth offset of `outer`.
  std::function<double(double z)> outer_relief_mm;
};

// How far (in arc length along the profile) an irregular break lies inside the wall's end, at
// azimuth phi: a smooth, deterministic wiggle in [0, amplitude].
inline double break_offset_mm(double amplitude, double phi, double phase) {
  return amplitude * (0.5 + 0.3 * std::sin(5 * phi + phase) + 0.2 * std::sin(11 * phi));
}
constexpr double kLowBreakPhase = 1.0, kHighBreakPhase = 2.0;

// Outward normal in the (r, z) half-plane of the outer skin: right of the base→rim tangent.
inline Vec2 profile_normal(const std::function<Vec2(double)>& curve, double s) {
  constexpr double h = 1e-6;
  const Vec2 t = (curve(std::min(1.0, s + h)) - curve(std::max(0.0, s - h))).normalized();
  return {t.y(), -t.x()};
}

inline Cloud sample_wall(const WallOfRevolution& w) {
  std::mt19937 rng(w.seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  Cloud cloud;
  auto emit = [&](const Vec2& rz, const Vec2& n_rz, double phi, const Vec3d& extra_normal) {
    const Vec3d radial(std::cos(phi), std::sin(phi), 0.0);
    const Vec3d p = rz.x() * radial + Vec3d(0, 0, rz.y());
    Vec3d n =
        extra_normal.isZero() ? Vec3d(n_rz.x() * radial + Vec3d(0, 0, n_rz.y())) : extra_normal;
    const double sigma = w.normal_noise_deg * M_PI / 180.0;
    n = (n + sigma * Vec3d(gauss(rng), gauss(rng), gauss(rng))).normalized();
    const Vec3d noisy = p + w.noise_mm * Vec3d(gauss(rng), gauss(rng), gauss(rng));
    cloud.points.push_back(noisy.cast<float>());
    cloud.normals.push_back(n.cast<float>());
  };
  // Dense arc-length table of the outer profile.
  constexpr int kTable = 4000;
  std::vector<double> length(kTable + 1, 0.0);
  for (int k = 1; k <= kTable; ++k) {
    length[k] =
        length[k - 1] + (w.outer(double(k) / kTable) - w.outer(double(k - 1) / kTable)).norm();
  }
  auto s_at_length = [&](double l) {
    const auto it = std::lower_bound(length.begin(), length.end(), l);
    return double(std::min<long>(it - length.begin(), kTable)) / kTable;
  };
  const double total = length.back();
  auto low_end = [&](double phi) {
    return w.closed_base ? 0.0 : break_offset_mm(w.break_amplitude_mm, phi, kLowBreakPhase);
  };
  auto high_end = [&](double phi) {
    return w.flat_lip ? total : total - break_offset_mm(w.break_amplitude_mm, phi, kHighBreakPhase);
  };

  const auto relieved = [&](double s) {
    const Vec2 p = w.outer(s);
    return w.outer_relief_mm ? Vec2(p + Vec2(w.outer_relief_mm(p.y()), 0.0)) : p;
  };
  const Vec3d none = Vec3d::Zero();
  for (double l = 0.0; l <= total; l += w.spacing_mm) {
    const double s = s_at_length(l);
    const Vec2 out = w.outer(s);
    const Vec2 n = profile_normal(w.outer, s);
    const Vec2 in = out - w.thickness_mm * n;
    for (int skin = 0; skin < 2; ++skin) {
      const double r = skin == 0 ? out.x() : in.x();
      const double dphi = w.spacing_mm / std::max(r, w.spacing_mm);
      for (double phi = w.phi_begin_rad; phi <= w.phi_end_rad; phi += dphi) {
        if (l < low_end(phi) || l > high_end(phi)) continue;
        if (skin == 0)
          emit(relieved(s), profile_normal(relieved, s), phi, none);
        else
          emit(in, -n, phi, none);
      }
    }
  }
  // End faces across the wall: normal along the profile tangent, outwards from the wall.
  auto end_face = [&](double l, double phi, double sign) {
    const double s = s_at_length(l);
    const Vec2 out = w.outer(s), n = profile_normal(w.outer, s);
    const Vec2 tangent(-n.y(), n.x());
    for (double d = 0.0; d <= w.thickness_mm; d += w.spacing_mm)
      emit(out - d * n, sign * tangent, phi, none);
  };
  const double mid_r = w.outer(0.5).x();
  for (double phi = w.phi_begin_rad; phi <= w.phi_end_rad; phi += w.spacing_mm / mid_r) {
    if (!w.closed_base) end_face(low_end(phi), phi, -1.0);
    end_face(high_end(phi), phi, +1.0);
  }
  if (w.side_faces) {
    for (double phi : {w.phi_begin_rad, w.phi_end_rad}) {
      const double sign = phi == w.phi_begin_rad ? -1.0 : 1.0;
      const Vec3d tangential = sign * Vec3d(-std::sin(phi), std::cos(phi), 0.0);
      for (double l = std::max(low_end(phi), 0.0); l <= high_end(phi); l += w.spacing_mm) {
        const double s = s_at_length(l);
        const Vec2 out = w.outer(s), n = profile_normal(w.outer, s);
        for (double d = 0.0; d <= w.thickness_mm; d += w.spacing_mm) {
          emit(out - d * n, Vec2::Zero(), phi, tangential);
        }
      }
    }
  }
  return cloud;
}

// An arbitrary tilted, offset placement of the sherd frame in the world.
// A wheel-made conical wall (25° from the axis, 45 mm radius at its foot, 5 mm thick), 90° of
// arc broken at both ends, without a lip.
inline WallOfRevolution cone_wall() {
  WallOfRevolution w;
  const double half_angle = 25.0 * M_PI / 180.0;
  w.outer = [=](double s) {
    return Vec2(45.0 + 60.0 * s * std::sin(half_angle), 60.0 * s * std::cos(half_angle));
  };
  w.phi_begin_rad = 0.3;
  w.phi_end_rad = 0.3 + M_PI / 2;
  w.thickness_mm = 5.0;
  w.flat_lip = false;
  w.spacing_mm = 0.6;
  return w;
}

inline Pose arbitrary_pose(double tilt_deg = 37.0) {
  Pose pose = Pose::Identity();
  pose.linear() = (Eigen::AngleAxisd(0.7, Vec3d::UnitZ()) *
                   Eigen::AngleAxisd(tilt_deg * M_PI / 180.0, Vec3d(1, 2, 0).normalized()))
                      .toRotationMatrix();
  pose.translation() = Vec3d(120.0, -45.0, 33.0);
  return pose;
}

// Where the sherd frame's axis (z through the origin) lies once `cloud` is moved to `pose`.
struct AxisTruth {
  Vec3d point, direction;
};
inline AxisTruth place(Cloud& cloud, const Pose& pose) {
  cloud.transform(pose);
  return {pose.translation(), pose.linear() * Vec3d::UnitZ()};
}

inline double distance_point_to_line(const Vec3d& p, const Vec3d& line_point,
                                     const Vec3d& line_dir) {
  return (p - line_point).cross(line_dir.normalized()).norm();
}

inline double axis_angle_deg(const Vec3d& a, const Vec3d& b) {
  return std::acos(std::min(1.0, std::abs(a.normalized().dot(b.normalized())))) * 180.0 / M_PI;
}

}  // namespace sherd::testing
