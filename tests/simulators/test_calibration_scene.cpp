// The calibration scene and the scanner's mounting error against analytic geometry: the spheres
// are where (and as large as) the published object description says, every view of the default
// station sees at least three of them, and a mounting error is a rigid motion of exactly the
// configured size.
#include "processing/calibration/turntable_calibration.h"
#include "simulators/pottery.h"
#include "simulators/sim_scanner.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace sherd::sim {
namespace {

constexpr double kPi = std::numbers::pi;
const auto& kObject = calibration::kCalibrationObject;

// Sphere k's centre in the world at turntable angle 0, from the description and the placement.
Vec3d sphere_centre(const Scene& scene, std::size_t k) {
  const auto& s = kObject.spheres[k];
  const double a = s.azimuth_deg * kPi / 180.0;
  return scene.calibration_placement *
         Vec3d(s.distance_mm * std::cos(a), s.distance_mm * std::sin(a), kObject.disc_thickness_mm + s.height_mm);
}

TEST(CalibrationScene, SpheresAreWhereTheDescriptionSays) {
  const Scene scene = make_scene({.seed = 5, .kind = SceneKind::Calibration});
  EXPECT_EQ(std::string(to_string(scene.spec.kind)), "calibration");
  EXPECT_EQ(scene_kind_from_string("calibration"), SceneKind::Calibration);
  EXPECT_TRUE(scene.truth.empty());
  ASSERT_EQ(scene.objects.size(), 2u);  // the plate and the object, both turning with the plate
  const auto& object = scene.objects[1];
  EXPECT_TRUE(object.on_plate);
  // Put down roughly centred, not exactly.
  const Vec3d offset = scene.calibration_placement.translation();
  EXPECT_GT(offset.norm(), 0.0);
  EXPECT_LE(offset.norm(), 8.0 * std::sqrt(2.0));
  EXPECT_DOUBLE_EQ(offset.z(), 0.0);
  for (std::size_t k = 0; k < kObject.spheres.size(); ++k) {
    const Vec3d centre = sphere_centre(scene, k);
    const double r = kObject.spheres[k].radius_mm;
    int on_sphere = 0;
    for (const auto& p : object.mesh.vertices.points) {
      const double d = (p.cast<double>() - centre).norm();
      // The post joins the sphere from below: vertices near the centre are on the sphere.
      if (d < r + 1.0 && p.z() > centre.z() - 0.9 * r) {
        EXPECT_NEAR(d, r, 1e-3) << "sphere " << k;
        ++on_sphere;
      }
    }
    EXPECT_GT(on_sphere, 1000) << "sphere " << k;
  }
  // Every sphere differs in radius from every other by more than twice the recognition tolerance.
  for (std::size_t a = 0; a < kObject.spheres.size(); ++a) {
    for (std::size_t b = a + 1; b < kObject.spheres.size(); ++b) {
      EXPECT_GT(std::abs(kObject.spheres[a].radius_mm - kObject.spheres[b].radius_mm),
                2 * calibration::EstimatorParams{}.sphere_tolerance_mm);
    }
  }
}

TEST(CalibrationScene, EveryViewOfTheDefaultStationSeesAtLeastThreeSpheres) {
  const Scene scene = make_scene({.seed = 11, .kind = SceneKind::Calibration});
  double angle = 0.0;
  ScannerModel model = default_station_scanner();
  SimulatedScanner scanner(scene, model, [&angle] { return angle; });
  for (int view = 0; view < 12; ++view) {
    angle = 2 * kPi * view / 12;
    const OrganisedView captured = scanner.capture();
    const Pose world_to_scanner = model.scanner_to_world.inverse();
    int seen = 0;
    for (std::size_t k = 0; k < kObject.spheres.size(); ++k) {
      const Vec3d centre = world_to_scanner * (Eigen::AngleAxisd(angle, Vec3d::UnitZ()) * sphere_centre(scene, k));
      const double r = kObject.spheres[k].radius_mm;
      int on_sphere = 0;
      for (std::size_t i = 0; i < captured.points.size(); ++i) {
        if (captured.valid[i] && std::abs((captured.points[i].cast<double>() - centre).norm() - r) < 0.3) ++on_sphere;
      }
      // A well-seen cap: a third of the sphere's silhouette area in pixels, at least.
      const double pixels = kPi * std::pow(model.fx * r / centre.norm(), 2);
      if (on_sphere > pixels / 3) ++seen;
    }
    EXPECT_GE(seen, 3) << "view " << view;
  }
}

TEST(MountingError, IsARigidMotionOfTheConfiguredSize) {
  const Pose nominal = default_station_scanner().scanner_to_world;
  EXPECT_TRUE(mounted_pose(nominal, {}).isApprox(nominal, 1e-15));
  const Pose mounted = mounted_pose(nominal, {.tilt_deg = 1.5, .offset_mm = 4.0, .seed = 3});
  const Eigen::AngleAxisd tilt(mounted.linear() * nominal.linear().transpose());
  EXPECT_NEAR(tilt.angle() * 180.0 / kPi, 1.5, 1e-9);
  EXPECT_NEAR((mounted.translation() - nominal.translation()).norm(), 4.0, 1e-9);
  EXPECT_NEAR(mounted.linear().determinant(), 1.0, 1e-12);
  // The seed draws the directions: the same seed the same pose, another seed another one.
  EXPECT_TRUE(mounted_pose(nominal, {.tilt_deg = 1.5, .offset_mm = 4.0, .seed = 3}).isApprox(mounted, 1e-15));
  const Pose other = mounted_pose(nominal, {.tilt_deg = 1.5, .offset_mm = 4.0, .seed = 4});
  EXPECT_GT((other.translation() - mounted.translation()).norm(), 0.1);
}

}  // namespace
}  // namespace sherd::sim
