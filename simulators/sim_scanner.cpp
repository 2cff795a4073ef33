#include "simulators/sim_scanner.h"

#include "core/errors.h"
#include "simulators/random.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>

namespace sherd::sim {
namespace {

// Why a hand-written z-buffer rasteriser: for a pinhole camera, the nearest surface along the ray
// of each pixel is exactly what a z-buffer of the scene's triangles keeps, so rasterising and then
// intersecting each pixel's ray with its winning triangle gives the same points as ray casting,
// without building an acceleration structure. The installed libraries offer no CPU ray caster
// (Embree is not among the station's dependencies, and VTK's pickers are far too slow per
// pixel), and the EGL renderer of render/ draws plates, it does not hand back per-pixel triangle
// ids and exact depths.

struct Pinhole {
  int width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
};

// Per pixel: the nearest triangle's depth and identity (object, triangle), −1 where none.
struct ZBuffer {
  std::vector<float> depth;
  std::vector<std::int32_t> object, triangle;
  explicit ZBuffer(const Pinhole& cam)
      : depth(static_cast<std::size_t>(cam.width) * cam.height,
              std::numeric_limits<float>::infinity()),
        object(depth.size(), -1),
        triangle(depth.size(), -1) {}
};

constexpr double kNearMm = 1.0;

void rasterise(const Pinhole& cam, const std::vector<std::vector<Vec3f>>& vertices,
               const Scene& scene, ZBuffer& zb) {
  for (std::size_t o = 0; o < scene.objects.size(); ++o) {
    const auto& v = vertices[o];
    const auto& tris = scene.objects[o].mesh.triangles;
    for (std::size_t t = 0; t < tris.size(); ++t) {
      const Vec3f &A = v[tris[t][0]], &B = v[tris[t][1]], &C = v[tris[t][2]];
      if (A.z() < kNearMm || B.z() < kNearMm || C.z() < kNearMm) continue;
      const double ax = cam.fx * A.x() / A.z() + cam.cx, ay = cam.fy * A.y() / A.z() + cam.cy;
      const double bx = cam.fx * B.x() / B.z() + cam.cx, by = cam.fy * B.y() / B.z() + cam.cy;
      const double cx = cam.fx * C.x() / C.z() + cam.cx, cy = cam.fy * C.y() / C.z() + cam.cy;
      const double area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
      if (std::abs(area) < 1e-12) continue;
      const int x0 = std::max(0, static_cast<int>(std::ceil(std::min({ax, bx, cx}))));
      const int x1 = std::min(cam.width - 1, static_cast<int>(std::floor(std::max({ax, bx, cx}))));
      const int y0 = std::max(0, static_cast<int>(std::ceil(std::min({ay, by, cy}))));
      const int y1 = std::min(cam.height - 1, static_cast<int>(std::floor(std::max({ay, by, cy}))));
      const double inv_area = 1.0 / area;
      for (int py = y0; py <= y1; ++py) {
        for (int px = x0; px <= x1; ++px) {
          // Barycentrics in the image (pixel centres at integer coordinates, OpenCV).
          const double l0 = ((bx - px) * (cy - py) - (by - py) * (cx - px)) * inv_area;
          const double l1 = ((cx - px) * (ay - py) - (cy - py) * (ax - px)) * inv_area;
          const double l2 = 1.0 - l0 - l1;
          constexpr double kEdge = -1e-9;
          if (l0 < kEdge || l1 < kEdge || l2 < kEdge) continue;
          // 1/z is linear in the image: perspective-correct depth.
          const double z = 1.0 / (l0 / A.z() + l1 / B.z() + l2 / C.z());
          const std::size_t i = static_cast<std::size_t>(py) * cam.width + px;
          if (z < zb.depth[i]) {
            zb.depth[i] = static_cast<float>(z);
            zb.object[i] = static_cast<std::int32_t>(o);
            zb.triangle[i] = static_cast<std::int32_t>(t);
          }
        }
      }
    }
  }
}

// Intersection of the ray origin + λ·dir with triangle ABC's plane: λ and the barycentrics
// (b1 for B, b2 for C) — Möller–Trumbore without the inside test.
struct RayHit {
  double lambda = 0, b1 = 0, b2 = 0;
  bool ok = false;
};
RayHit intersect_plane(const Vec3d& dir, const Vec3d& A, const Vec3d& B, const Vec3d& C) {
  const Vec3d e1 = B - A, e2 = C - A;
  const Vec3d p = dir.cross(e2);
  const double det = e1.dot(p);
  if (std::abs(det) < 1e-12) return {};
  const double inv = 1.0 / det;
  const Vec3d tvec = -A;  // ray origin at 0
  const Vec3d q = tvec.cross(e1);
  return {e2.dot(q) * inv, tvec.dot(p) * inv, dir.dot(q) * inv, true};
}

}  // namespace

Pose look_at_pose(const Vec3d& eye, const Vec3d& target) {
  Vec3d z = target - eye;
  if (!(z.norm() > 1e-9) || !z.allFinite()) {
    throw InputError("look_at_pose: the scanner's eye and target coincide or are not finite: "
                     "give a target in front of the scanner");
  }
  z.normalize();
  Vec3d x = z.cross(Vec3d::UnitZ());  // image right; image down is then z × x ≈ −world z
  if (x.norm() < 1e-6) {
    throw InputError("look_at_pose: the scanner looks straight up or down, so image up (+z) is "
                     "undefined: tilt the scanner or move its target");
  }
  x.normalize();
  Pose pose = Pose::Identity();
  pose.linear() << x, z.cross(x), z;
  pose.translation() = eye;
  return pose;
}

Pose mounted_pose(const Pose& nominal, const MountingError& error) {
  if (!(std::isfinite(error.tilt_deg) && std::isfinite(error.offset_mm))) {
    throw InputError("simulated scanner mounting error: tilt and offset must be finite numbers");
  }
  Rng rng(error.seed ^ 0x6D6F756E74ULL);  // its own stream: the scene's draws stay unchanged
  // Uniform directions on the unit sphere (normalised Gaussian triples).
  auto direction = [&rng] {
    const Vec3d v(rng.normal(), rng.normal(), rng.normal());
    return v.normalized();
  };
  const Vec3d tilt_axis = direction(), shift = direction();
  Pose pose = nominal;
  pose.linear() = Eigen::AngleAxisd(error.tilt_deg * std::numbers::pi / 180.0, tilt_axis) *
                  nominal.linear();
  pose.translation() += error.offset_mm * shift;
  return pose;
}

ScannerModel default_station_scanner() {
  ScannerModel model;
  model.scanner_to_world = look_at_pose({0.0, -420.0, 260.0}, {0.0, 0.0, 50.0});
  return model;
}

SimulatedScanner::SimulatedScanner(Scene scene, ScannerModel model,
                                   std::function<double()> plate_angle)
    : scene_(std::move(scene)), model_(model), plate_angle_(std::move(plate_angle)) {
  const auto& m = model_;
  if (m.width <= 0 || m.height <= 0 || m.width > 8192 || m.height > 8192) {
    throw InputError(fmt::format("simulated scanner: image size {}×{} out of range 1…8192",
                                 m.width, m.height));
  }
  if (!(m.fx > 0 && m.fy > 0 && std::isfinite(m.fx) && std::isfinite(m.fy) &&
        std::isfinite(m.cx) && std::isfinite(m.cy))) {
    throw InputError("simulated scanner: focal lengths must be positive and the intrinsics "
                     "finite: check fx, fy, cx, cy");
  }
  if (!(m.depth_noise_mm >= 0 && m.grazing_limit_deg > 0 && m.grazing_limit_deg <= 90 &&
        m.dropout_fraction >= 0 && m.dropout_fraction <= 1 && m.projector_offset_mm.allFinite() &&
        m.scanner_to_world.matrix().allFinite())) {
    throw InputError("simulated scanner: depth_noise_mm ≥ 0, grazing_limit_deg in (0, 90], "
                     "dropout_fraction in [0, 1] and a finite pose and projector offset expected");
  }
  if (!plate_angle_) {
    throw InputError("simulated scanner: no plate angle source: pass the turntable's "
                     "physical_angle()");
  }
}

std::string SimulatedScanner::describe() const {
  return fmt::format("simulated structured-light scanner {}x{} fx {:.0f} (noise {:.2f} mm)",
                     model_.width, model_.height, model_.fx, model_.depth_noise_mm);
}

OrganisedView SimulatedScanner::capture() {
  const double angle = plate_angle_();
  const auto& m = model_;
  const Pinhole camera{m.width, m.height, m.fx, m.fy, m.cx, m.cy};
  // The projector looks the same way as the camera from its offset; a wider field so that it
  // lights everything the camera sees at the working distance.
  const Pinhole projector{1024, 768, 0.8 * m.fx, 0.8 * m.fy, 511.5, 383.5};
  const Vec3f offset = m.projector_offset_mm.cast<float>();

  // Scene into the scanner frame: objects on the plate turn with it first.
  const Pose world_to_scanner = m.scanner_to_world.inverse();
  const Pose turned = world_to_scanner * Eigen::AngleAxisd(angle, Vec3d::UnitZ());
  std::vector<std::vector<Vec3f>> in_camera(scene_.objects.size()),
      in_projector(scene_.objects.size()), normals(scene_.objects.size());
  for (std::size_t o = 0; o < scene_.objects.size(); ++o) {
    const auto& object = scene_.objects[o];
    const Pose& pose = object.on_plate ? turned : world_to_scanner;
    const Eigen::Matrix3f R = pose.linear().cast<float>();
    const Vec3f t = pose.translation().cast<float>();
    for (const auto& p : object.mesh.vertices.points) {
      in_camera[o].push_back(R * p + t);
      in_projector[o].push_back(in_camera[o].back() - offset);
    }
    for (const auto& n : object.mesh.vertices.normals) normals[o].push_back(R * n);
  }
  ZBuffer seen(camera), lit(projector);
  rasterise(camera, in_camera, scene_, seen);
  rasterise(projector, in_projector, scene_, lit);

  Rng rng(m.seed + 0x9E3779B97F4A7C15ULL * (++captures_));
  const double cos_grazing = std::cos(m.grazing_limit_deg * std::numbers::pi / 180.0);
  constexpr double kShadowBiasMm = 0.5;
  constexpr double kAmbient = 0.3;  // share of light not from the projector: black stays dark

  OrganisedView view;
  view.width = m.width;
  view.height = m.height;
  const std::size_t cells = view.cells();
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  view.points.assign(cells, Vec3f::Constant(kNaN));
  view.normals.assign(cells, Vec3f::Constant(kNaN));
  view.colours.assign(cells, Rgb8{});
  view.valid.assign(cells, 0);
  std::vector<int> label(cells, 0);

  for (int py = 0; py < m.height; ++py) {
    for (int px = 0; px < m.width; ++px) {
      const std::size_t i = static_cast<std::size_t>(py) * m.width + px;
      const int o = seen.object[i];
      if (o < 0) continue;
      const auto& object = scene_.objects[o];
      const auto& tri = object.mesh.triangles[seen.triangle[i]];
      const Vec3d A = in_camera[o][tri[0]].cast<double>(), B = in_camera[o][tri[1]].cast<double>(),
                  C = in_camera[o][tri[2]].cast<double>();
      const Vec3d ray((px - m.cx) / m.fx, (py - m.cy) / m.fy, 1.0);
      const RayHit hit = intersect_plane(ray, A, B, C);
      if (!hit.ok || hit.lambda <= 0) continue;
      const Vec3d P = hit.lambda * ray;
      // Attributes from the (clamped) barycentrics.
      const double b1 = std::clamp(hit.b1, 0.0, 1.0), b2 = std::clamp(hit.b2, 0.0, 1.0 - b1);
      const double b0 = 1.0 - b1 - b2;
      const Vec3d n = (b0 * normals[o][tri[0]].cast<double>() +
                       b1 * normals[o][tri[1]].cast<double>() +
                       b2 * normals[o][tri[2]].cast<double>()).normalized();
      const Vec3d to_camera = -P.normalized();
      const Vec3d to_projector = (offset.cast<double>() - P).normalized();
      const double cos_camera = n.dot(to_camera), cos_projector = n.dot(to_projector);
      if (cos_camera < cos_grazing || cos_projector < cos_grazing) continue;  // grazing

      // Projector shadow: the surface the projector's ray towards P meets first.
      const Vec3d Q = P - offset.cast<double>();
      const double qu = projector.fx * Q.x() / Q.z() + projector.cx;
      const double qv = projector.fy * Q.y() / Q.z() + projector.cy;
      const long ju = std::lround(qu), jv = std::lround(qv);
      if (Q.z() <= kNearMm || ju < 0 || jv < 0 || ju >= projector.width ||
          jv >= projector.height) {
        continue;  // outside the projected pattern
      }
      const std::size_t j = static_cast<std::size_t>(jv) * projector.width + ju;
      const int lo = lit.object[j];
      if (lo < 0) continue;
      if (lo != o || lit.triangle[j] != seen.triangle[i]) {
        const auto& ltri = scene_.objects[lo].mesh.triangles[lit.triangle[j]];
        const RayHit blocker = intersect_plane(Q, in_projector[lo][ltri[0]].cast<double>(),
                                               in_projector[lo][ltri[1]].cast<double>(),
                                               in_projector[lo][ltri[2]].cast<double>());
        if (blocker.ok && blocker.lambda > 0 && blocker.lambda < 1.0 - kShadowBiasMm / Q.norm()) {
          continue;  // shadowed
        }
      }
      if (rng.chance(m.dropout_fraction)) continue;

      const Vec3d measured = P + m.depth_noise_mm * rng.normal() * ray.normalized();
      const auto& colours = object.mesh.vertices.colours;
      const double shade = kAmbient + (1.0 - kAmbient) * cos_projector;
      auto channel = [&](auto member) {
        const double c = b0 * (colours[tri[0]].*member) + b1 * (colours[tri[1]].*member) +
                         b2 * (colours[tri[2]].*member);
        return static_cast<std::uint8_t>(std::clamp(std::round(c * shade), 0.0, 255.0));
      };
      view.points[i] = measured.cast<float>();
      view.colours[i] = {channel(&Rgb8::r), channel(&Rgb8::g), channel(&Rgb8::b)};
      view.valid[i] = 1;
      label[i] = object.label;
    }
  }

  // Normals from the measured grid, as a real scanner computes them: the cross product of the
  // horizontal and vertical neighbour differences. A neighbour across a depth jump belongs to
  // another surface; a cell with no usable neighbour pair is dropped (an isolated point).
  constexpr float kMaxJumpMm = 5.0f;
  auto neighbour_difference = [&](int px, int py, int dx, int dy, Vec3f& out) {
    const auto usable = [&](int x, int y) {
      if (x < 0 || y < 0 || x >= m.width || y >= m.height) return false;
      const std::size_t k = static_cast<std::size_t>(y) * m.width + x;
      const std::size_t c = static_cast<std::size_t>(py) * m.width + px;
      return view.valid[k] && std::abs(view.points[k].z() - view.points[c].z()) < kMaxJumpMm;
    };
    const bool fwd = usable(px + dx, py + dy), back = usable(px - dx, py - dy);
    if (!fwd && !back) return false;
    const auto at = [&](int x, int y) { return view.points[static_cast<std::size_t>(y) * m.width + x]; };
    out = (fwd ? at(px + dx, py + dy) : at(px, py)) - (back ? at(px - dx, py - dy) : at(px, py));
    return true;
  };
  std::vector<std::uint8_t> keep(cells, 0);
  for (int py = 0; py < m.height; ++py) {
    for (int px = 0; px < m.width; ++px) {
      const std::size_t i = static_cast<std::size_t>(py) * m.width + px;
      if (!view.valid[i]) continue;
      Vec3f dx, dy;
      if (!neighbour_difference(px, py, 1, 0, dx) || !neighbour_difference(px, py, 0, 1, dy)) {
        continue;
      }
      Vec3f n = dx.cross(dy);
      if (!(n.norm() > 0)) continue;
      n.normalize();
      if (n.dot(view.points[i]) > 0) n = -n;  // towards the scanner
      view.normals[i] = n;
      keep[i] = 1;
    }
  }
  for (std::size_t i = 0; i < cells; ++i) {
    if (view.valid[i] && !keep[i]) {
      view.valid[i] = 0;
      view.points[i] = Vec3f::Constant(kNaN);
      view.colours[i] = {};
      label[i] = 0;
    }
  }
  view.timestamp_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                          std::chrono::system_clock::now().time_since_epoch())
                          .count();
  last_labels_ = std::move(label);
  return view;
}

}  // namespace sherd::sim
