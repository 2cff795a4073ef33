#include "test_meshes.h"

#include <cmath>
#include <functional>
#include <numbers>

namespace sherd::render::test {
namespace {

using PointNormal = std::pair<Vec3f, Vec3f>;

// A (rows+1)×(cols+1) vertex grid over (s, t) ∈ [0,1]², triangulated.
void add_grid(Mesh& mesh, int rows, int cols,
              const std::function<PointNormal(double s, double t)>& point_normal) {
  const auto base = static_cast<std::uint32_t>(mesh.vertices.size());
  for (int i = 0; i <= rows; ++i)
    for (int j = 0; j <= cols; ++j) {
      const auto [p, n] =
          point_normal(static_cast<double>(j) / cols, static_cast<double>(i) / rows);
      mesh.vertices.points.push_back(p);
      mesh.vertices.normals.push_back(n);
    }
  const auto at = [&](int i, int j) {
    return base + static_cast<std::uint32_t>(i * (cols + 1) + j);
  };
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < cols; ++j) {
      mesh.triangles.push_back({at(i, j), at(i, j + 1), at(i + 1, j + 1)});
      mesh.triangles.push_back({at(i, j), at(i + 1, j + 1), at(i + 1, j)});
    }
}

}  // namespace

Mesh box(double size_x, double size_y, double size_z, const Vec3d& centre) {
  Mesh mesh;
  const Vec3d half(size_x / 2, size_y / 2, size_z / 2);
  for (int axis = 0; axis < 3; ++axis)
    for (double sign : {-1.0, 1.0}) {
      const int a = (axis + 1) % 3, b = (axis + 2) % 3;
      add_grid(mesh, 1, 1, [&](double s, double t) {
        Vec3d p = centre;
        p[axis] += sign * half[axis];
        p[a] += (2 * s - 1) * half[a];
        p[b] += (2 * t - 1) * half[b];
        Vec3d n = Vec3d::Zero();
        n[axis] = sign;
        return PointNormal{p.cast<float>(), n.cast<float>()};
      });
    }
  return mesh;
}

Mesh merged(Mesh a, const Mesh& b) {
  const auto offset = static_cast<std::uint32_t>(a.vertices.size());
  a.vertices.append(b.vertices);
  for (const Triangle& t : b.triangles)
    a.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  return a;
}

Mesh cylinder_wall(double outer_r, double inner_r, double height, double from_rad, double to_rad) {
  Mesh mesh;
  const int segments = 96, rows = 8;
  const auto radial = [&](double s) {
    const double phi = from_rad + s * (to_rad - from_rad);
    return Vec3d(std::cos(phi), std::sin(phi), 0.0);
  };
  for (const auto& [r, outward] : {std::pair{outer_r, 1.0}, std::pair{inner_r, -1.0}})
    add_grid(mesh, rows, segments, [&](double s, double t) {
      const Vec3d d = radial(s);
      return PointNormal{(r * d + Vec3d(0, 0, t * height)).cast<float>(),
                         (outward * d).cast<float>()};
    });
  for (const auto& [z, up] : {std::pair{height, 1.0}, std::pair{0.0, -1.0}})
    add_grid(mesh, 1, segments, [&](double s, double t) {
      const double r = inner_r + t * (outer_r - inner_r);
      return PointNormal{(r * radial(s) + Vec3d(0, 0, z)).cast<float>(), Vec3f(0, 0, up)};
    });
  return mesh;
}

Mesh relief_dome(double radius, int rings, int segments) {
  Mesh mesh;
  const double max_polar = std::numbers::pi / 3;
  // Radius modulated along the polar angle θ: r(θ) = R (1 + a sin(k θ)), six grooves.
  const double a = 0.03, k = 36.0;
  add_grid(mesh, rings, segments, [&](double s, double t) {
    const double theta = t * max_polar, phi = s * 2 * std::numbers::pi;
    const double r = radius * (1 + a * std::sin(k * theta));
    const double dr = radius * a * k * std::cos(k * theta);
    const Vec3d radial(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                       std::cos(theta));
    const Vec3d along(std::cos(theta) * std::cos(phi), std::cos(theta) * std::sin(phi),
                      -std::sin(theta));
    // The surface normal of a radius r(θ): r·radial − r'·along, normalised.
    const Vec3d n = (r * radial - dr * along).normalized();
    return PointNormal{(r * radial).cast<float>(), n.cast<float>()};
  });
  return mesh;
}

}  // namespace sherd::render::test
