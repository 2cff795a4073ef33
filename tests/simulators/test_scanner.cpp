// The simulated scanner against analytic scenes: a plane, a sphere, a post casting a projector
// shadow — depths, normals, shadows and dropouts compared with what geometry says.
#include "core/errors.h"
#include "simulators/pottery.h"
#include "simulators/sim_scanner.h"
#include "simulators/vessel.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <optional>

namespace sherd::sim {
namespace {

constexpr double kPi = std::numbers::pi;

ScannerModel station_model() {
  ScannerModel m = default_station_scanner();
  m.dropout_fraction = 0.0;
  return m;
}

SceneObject object(std::string name, int label, Mesh mesh) {
  SceneObject o;
  o.name = std::move(name);
  o.label = label;
  o.mesh = std::move(mesh);
  return o;
}

// A UV sphere as a surface of revolution of a half circle (bottom pole to top pole).
Mesh sphere(const Vec3d& centre, double radius, Rgb8 colour) {
  std::vector<Point2> half;
  for (int k = 0; k <= 180; ++k) {
    const double a = -kPi / 2 + kPi * k / 180;
    half.emplace_back(k == 0 || k == 180 ? 0.0 : radius * std::cos(a), radius * std::sin(a));
  }
  Rng rng(1);
  Mesh m = revolve_section(half, std::vector<Rgb8>(half.size(), colour), rng);
  Pose at = Pose::Identity();
  at.translate(centre);
  m.vertices.transform(at);
  m.vertices.colours.assign(m.vertices.size(), colour);
  return m;
}

// An axis-aligned box from `lo` to `hi`, 8 shared vertices.
Mesh box(const Vec3d& lo, const Vec3d& hi) {
  Mesh m;
  for (int i = 0; i < 8; ++i) {
    m.vertices.points.emplace_back(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(),
                                   i & 4 ? hi.z() : lo.z());
  }
  m.triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                 {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  m.vertices.colours.assign(8, Rgb8{200, 200, 200});
  compute_vertex_normals(m);
  return m;
}

Scene plate_only(Background bg = Background::Black) {
  return make_scene({.seed = 1, .kind = SceneKind::Empty, .sherds = 0, .background = bg});
}

// Parameter λ where the ray o + λ·d crosses the plane z = 0 (world).
std::optional<double> hit_plate(const Vec3d& o, const Vec3d& d) {
  if (std::abs(d.z()) < 1e-12) return std::nullopt;
  const double l = -o.z() / d.z();
  const Vec3d x = o + l * d;
  if (l <= 0 || std::hypot(x.x(), x.y()) > kPlateRadiusMm) return std::nullopt;
  return l;
}

// Whether the segment a→b passes through the axis-aligned box (slab test).
bool segment_hits_box(const Vec3d& a, const Vec3d& b, const Vec3d& lo, const Vec3d& hi) {
  double t0 = 0.0, t1 = 1.0;
  const Vec3d d = b - a;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(d[k]) < 1e-12) {
      if (a[k] < lo[k] || a[k] > hi[k]) return false;
      continue;
    }
    double u = (lo[k] - a[k]) / d[k], v = (hi[k] - a[k]) / d[k];
    if (u > v) std::swap(u, v);
    t0 = std::max(t0, u);
    t1 = std::min(t1, v);
    if (t0 > t1) return false;
  }
  return true;
}

TEST(Scanner, LookAtPutsTheTargetAtTheImageCentreWithZUp) {
  const Pose pose = look_at_pose({0, -420, 260}, {0, 0, 50});
  const Vec3d target = pose.inverse() * Vec3d(0, 0, 50);
  EXPECT_NEAR(target.x(), 0.0, 1e-9);
  EXPECT_NEAR(target.y(), 0.0, 1e-9);
  EXPECT_NEAR(target.z(), std::hypot(420.0, 210.0), 1e-9);
  const Vec3d above = pose.inverse() * Vec3d(0, 0, 100);
  EXPECT_LT(above.y(), 0.0);  // image y points down, so world up is image up
  const Vec3d right = pose.inverse() * Vec3d(50, 0, 50);
  EXPECT_GT(right.x(), 0.0);
  EXPECT_THROW(look_at_pose({0, 0, 100}, {0, 0, 0}), InputError);
}

TEST(Scanner, PlaneDepthErrorFollowsTheNoiseModel) {
  ScannerModel m = station_model();
  m.depth_noise_mm = 0.3;
  SimulatedScanner scanner(plate_only(), m, [] { return 0.0; });
  const OrganisedView view = scanner.capture();
  ASSERT_EQ(view.width, 640);
  ASSERT_EQ(view.height, 480);
  const Pose& to_world = m.scanner_to_world;
  double sum = 0, sum2 = 0;
  int n = 0;
  for (std::size_t i = 0; i < view.cells(); ++i) {
    if (!view.valid[i]) continue;
    const Vec3d p = view.points[i].cast<double>();
    // Distance along the ray to the analytic plate top, z = 0 in the world.
    const Vec3d dir_world = to_world.linear() * p.normalized();
    const auto l = hit_plate(to_world.translation(), dir_world);
    if (!l) continue;  // the plate's rim
    const double err = p.norm() - *l;
    sum += err;
    sum2 += err * err;
    ++n;
  }
  ASSERT_GT(n, 50000);
  const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
  EXPECT_NEAR(mean, 0.0, 0.01);
  EXPECT_NEAR(sd, 0.3, 0.015);
}

TEST(Scanner, SphereSurfaceNormalsAndGrazingLimit) {
  ScannerModel m = station_model();
  m.depth_noise_mm = 0.0;
  m.grazing_limit_deg = 60.0;
  const Vec3d centre(0, 0, 60);
  const double radius = 40.0;
  Scene scene = plate_only();
  scene.objects.push_back(object("ball", 1, sphere(centre, radius, {230, 230, 230})));
  SimulatedScanner scanner(scene, m, [] { return 0.0; });
  const OrganisedView view = scanner.capture();
  const Pose& to_world = m.scanner_to_world;
  const Vec3d camera = to_world.translation();
  const Vec3d projector = to_world * m.projector_offset_mm;
  int n = 0;
  double worst_radius_err = 0, normal_err_sum = 0, max_incidence = 0;
  for (std::size_t i = 0; i < view.cells(); ++i) {
    if (!view.valid[i] || scanner.last_labels()[i] != 1) continue;
    const Vec3d p = to_world * view.points[i].cast<double>();
    const Vec3d n_true = (p - centre).normalized();
    worst_radius_err = std::max(worst_radius_err, std::abs((p - centre).norm() - radius));
    const Vec3d n_est = to_world.linear() * view.normals[i].cast<double>();
    normal_err_sum += std::acos(std::clamp(n_est.dot(n_true), -1.0, 1.0));
    for (const Vec3d& eye : {camera, projector}) {
      max_incidence = std::max(max_incidence, std::acos(n_true.dot((eye - p).normalized())));
    }
    ++n;
  }
  ASSERT_GT(n, 3000);
  EXPECT_LT(worst_radius_err, 0.05);              // faceting of a 1° UV sphere: < 0.01 mm
  EXPECT_LT(normal_err_sum / n * 180 / kPi, 2.0);  // grid-estimated normals
  EXPECT_LT(max_incidence * 180 / kPi, 61.0);      // nothing beyond the grazing limit …
  EXPECT_GT(max_incidence * 180 / kPi, 55.0);      // … but the surface up to it
}

TEST(Scanner, PostCastsTheProjectorShadowGeometrySays) {
  ScannerModel m = station_model();
  m.depth_noise_mm = 0.0;
  m.grazing_limit_deg = 89.0;
  const Vec3d lo(-15, -15, 0), hi(15, 15, 120);
  Scene scene = plate_only();
  scene.objects.push_back(object("post", 1, box(lo, hi)));
  SimulatedScanner scanner(scene, m, [] { return 0.0; });
  const OrganisedView view = scanner.capture();
  const Pose& to_world = m.scanner_to_world;
  const Vec3d camera = to_world.translation();
  const Vec3d projector = to_world * m.projector_offset_mm;
  int agree = 0, total = 0, shadowed = 0;
  for (int v = 0; v < view.height; ++v) {
    for (int u = 0; u < view.width; ++u) {
      const Vec3d ray = to_world.linear() * Vec3d((u - m.cx) / m.fx, (v - m.cy) / m.fy, 1.0);
      const auto l = hit_plate(camera, ray);
      if (!l) continue;
      const Vec3d x = camera + *l * ray;
      if (segment_hits_box(camera, x, lo, hi)) continue;  // the camera sees the post here
      const bool lit = !segment_hits_box(projector, x, lo, hi);
      shadowed += !lit;
      const std::size_t i = static_cast<std::size_t>(v) * view.width + u;
      agree += (view.valid[i] != 0) == lit;
      ++total;
    }
  }
  ASSERT_GT(shadowed, 2000);  // the projector (to the right) throws a real shadow
  EXPECT_GT(static_cast<double>(agree) / total, 0.995);
}

TEST(Scanner, RandomDropoutsAtTheConfiguredRate) {
  ScannerModel m = station_model();
  const auto valid_with = [&](double fraction) {
    m.dropout_fraction = fraction;
    SimulatedScanner scanner(plate_only(), m, [] { return 0.0; });
    return static_cast<double>(scanner.capture().valid_count());
  };
  const double ratio = valid_with(0.05) / valid_with(0.0);
  // 5 % dropped, plus cells left without a horizontal or vertical neighbour pair (≈ 2 × 0.05²).
  EXPECT_NEAR(ratio, 0.95 * (1 - 2 * 0.05 * 0.05), 0.01);
}

TEST(Scanner, ObjectsOnThePlateTurnWithIt) {
  ScannerModel m = station_model();
  m.depth_noise_mm = 0.0;
  const Vec3d centre(70, 0, 25);
  const double radius = 25.0;
  Scene scene = plate_only();
  scene.objects.push_back(object("ball", 1, sphere(centre, radius, {180, 120, 80})));
  double angle = 0.0;
  SimulatedScanner scanner(scene, m, [&angle] { return angle; });
  for (double a : {0.0, kPi / 2, 3.0}) {
    angle = a;
    const OrganisedView view = scanner.capture();
    // Each point minus radius × its estimated normal lands on the ball's centre.
    Vec3d sum = Vec3d::Zero();
    int n = 0;
    for (std::size_t i = 0; i < view.cells(); ++i) {
      if (!view.valid[i] || scanner.last_labels()[i] != 1) continue;
      sum += m.scanner_to_world * (view.points[i].cast<double>() -
                                   radius * view.normals[i].cast<double>());
      ++n;
    }
    ASSERT_GT(n, 500);
    const Vec3d expected = Eigen::AngleAxisd(a, Vec3d::UnitZ()) * centre;
    EXPECT_LT((sum / n - expected).norm(), 1.0) << "angle " << a;
  }
}

TEST(Scanner, BackgroundColourSurvivesShading) {
  for (Background bg : {Background::Black, Background::White}) {
    SimulatedScanner scanner(plate_only(bg), station_model(), [] { return 0.0; });
    const OrganisedView view = scanner.capture();
    double sum = 0;
    for (std::size_t i = 0; i < view.cells(); ++i) {
      if (view.valid[i]) sum += (view.colours[i].r + view.colours[i].g + view.colours[i].b) / 3.0;
    }
    const double mean = sum / view.valid_count();
    if (bg == Background::Black) {
      EXPECT_LT(mean, 30.0);
    } else {
      EXPECT_GT(mean, 150.0);
    }
  }
}

TEST(Scanner, LabelsPointAtTheTruthSherds) {
  const Scene scene = make_scene({.seed = 4, .kind = SceneKind::Frame, .sherds = 4});
  const ScannerModel m = station_model();
  SimulatedScanner scanner(scene, m, [] { return 0.0; });
  const OrganisedView view = scanner.capture();
  std::vector<int> per_label(5, 0);
  for (std::size_t i = 0; i < view.cells(); ++i) {
    const int label = scanner.last_labels()[i];
    if (label == 0) continue;
    ASSERT_TRUE(view.valid[i]);
    const Box3& b = scene.truth[label - 1].bbox;
    const Vec3d p = m.scanner_to_world * view.points[i].cast<double>();
    EXPECT_TRUE((p.array() >= b.min.array() - 0.5).all() && (p.array() <= b.max.array() + 0.5).all());
    ++per_label[label];
  }
  int seen = 0;
  for (int k = 1; k <= 4; ++k) seen += per_label[k] > 500;
  EXPECT_GE(seen, 3);  // at most one hidden behind another from this side
}

TEST(Scanner, RejectsBadModels) {
  ScannerModel m = station_model();
  m.fx = 0;
  EXPECT_THROW(SimulatedScanner(plate_only(), m, [] { return 0.0; }), InputError);
  m = station_model();
  m.dropout_fraction = 1.5;
  EXPECT_THROW(SimulatedScanner(plate_only(), m, [] { return 0.0; }), InputError);
  EXPECT_THROW(SimulatedScanner(plate_only(), station_model(), nullptr), InputError);
}

}  // namespace
}  // namespace sherd::sim
