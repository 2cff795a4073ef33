// estimate_axis against analytic surfaces of revolution with a known axis, placed at a tilted,
// offset pose, with scanner noise and fracture faces; and against objects that have no axis.
#include "processing/axis/axis.h"

#include "core/errors.h"
#include "tests/processing/axis_test_surfaces.h"

#include <gtest/gtest.h>

#include <limits>

namespace sherd {
namespace {

using testing::AxisTruth;
using testing::place;
using testing::Vec2;
using testing::WallOfRevolution;

void expect_axis_near(const axis::AxisEstimate& a, const AxisTruth& truth) {
  ASSERT_TRUE(a.found) << a.reason;
  EXPECT_LT(testing::axis_angle_deg(a.direction, truth.direction), 0.5);
  EXPECT_LT(testing::distance_point_to_line(a.point, truth.point, truth.direction), 0.5);
  EXPECT_NEAR(a.direction.norm(), 1.0, 1e-9);
}

TEST(AxisEstimate, CylinderWallSixtyDegreesWithFractureFaces) {
  WallOfRevolution w;
  w.outer = [](double s) { return Vec2(60.0, 50.0 * s); };
  w.phi_end_rad = M_PI / 3;
  Cloud cloud = testing::sample_wall(w);
  const AxisTruth truth = place(cloud, testing::arbitrary_pose());
  const auto a = axis::estimate_axis(cloud);
  expect_axis_near(a, truth);
  EXPECT_GT(a.inlier_share, 0.7);
  // Point closest to the centroid: the centroid's own foot on the true axis.
  Vec3d centroid = Vec3d::Zero();
  for (const auto& p : cloud.points) centroid += p.cast<double>();
  centroid /= cloud.size();
  const Vec3d foot = truth.point + (centroid - truth.point).dot(truth.direction) * truth.direction;
  EXPECT_LT((a.point - foot).norm(), 0.5);
  // The bootstrap spread is a small positive number for a well-constrained sherd.
  EXPECT_GT(a.angle_sd_deg, 0.0);
  EXPECT_LT(a.angle_sd_deg, 0.5);
  EXPECT_GT(a.offset_sd_mm, 0.0);
  EXPECT_LT(a.offset_sd_mm, 0.5);
}

TEST(AxisEstimate, ConeSectionNinetyDegrees) {
  WallOfRevolution w;
  const double half_angle = 25.0 * M_PI / 180.0;
  w.outer = [=](double s) { return Vec2(35.0 + 60.0 * s * std::sin(half_angle), 60.0 * s * std::cos(half_angle)); };
  w.phi_begin_rad = 0.4;
  w.phi_end_rad = 0.4 + M_PI / 2;
  w.thickness_mm = 5.0;
  Cloud cloud = testing::sample_wall(w);
  expect_axis_near(axis::estimate_axis(cloud), place(cloud, testing::arbitrary_pose(71.0)));
}

TEST(AxisEstimate, WideShallowWallWithScannerGradeNormals) {
  // A large plate-like wall (radius 100–130 mm, rising 25 mm) whose input normals are off by 5°
  // (scanner normals from a 0.5 mm grid at 0.05 mm depth noise): a normal line then misses the
  // axis by ~R·sin 5° ≈ 9 mm, so the axis must come from normals re-estimated on the points.
  WallOfRevolution w;
  w.outer = [](double s) { return Vec2(100.0 + 30.0 * s, 25.0 * s); };
  w.phi_end_rad = M_PI / 4;
  w.thickness_mm = 5.0;
  w.normal_noise_deg = 5.0;
  Cloud cloud = testing::sample_wall(w);
  const AxisTruth truth = place(cloud, testing::arbitrary_pose(23.0));
  const auto a = axis::estimate_axis(cloud);
  ASSERT_TRUE(a.found) << a.reason;
  EXPECT_LT(testing::axis_angle_deg(a.direction, truth.direction), 0.5);
  EXPECT_LT(testing::distance_point_to_line(a.point, truth.point, truth.direction), 1.0);
}

TEST(AxisEstimate, PlateFloorNormalsAlongTheAxisDoNotCountAgainstIt) {
  // A plate base sherd: a flat floor (r 15–60 mm, both skins facing along the axis) and a short
  // wall (r 60–80 mm). The floor's normal lines are parallel to the axis, neither for nor against
  // it; the wall alone fixes the axis.
  WallOfRevolution w;
  w.outer = [](double s) {
    const double l = s * 85.0;  // 45 mm of floor, then 40 mm of wall at 30° from horizontal
    return l <= 45.0 ? Vec2(15.0 + l, 0.0) : Vec2(60.0 + (l - 45.0) * std::cos(0.52), (l - 45.0) * std::sin(0.52));
  };
  w.phi_end_rad = M_PI / 3;
  w.thickness_mm = 5.0;
  w.break_amplitude_mm = 4.0;
  Cloud cloud = testing::sample_wall(w);
  expect_axis_near(axis::estimate_axis(cloud), place(cloud, testing::arbitrary_pose(-35.0)));
}

TEST(AxisEstimate, EllipsoidalBowlWithRandomOutliers) {
  // A bowl whose wall is half an oblate spheroid (not a sphere: its normals meet the axis at
  // different heights), from near the bottom to the rim at the equator.
  WallOfRevolution w;
  w.outer = [](double s) {
    const double t = -M_PI / 2 + 0.25 + s * (M_PI / 2 - 0.25);
    return Vec2(70.0 * std::cos(t), 50.0 * std::sin(t));
  };
  w.phi_end_rad = 2 * M_PI / 3;
  w.thickness_mm = 7.0;
  Cloud cloud = testing::sample_wall(w);
  // 10 % clutter: points and normals at random inside the sherd's box.
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  const std::size_t clutter = cloud.size() / 10;
  for (std::size_t i = 0; i < clutter; ++i) {
    cloud.points.emplace_back(70.0f * u(rng), 70.0f * u(rng), 50.0f * u(rng));
    cloud.normals.push_back(Vec3f(u(rng), u(rng), u(rng)).normalized());
  }
  expect_axis_near(axis::estimate_axis(cloud), place(cloud, testing::arbitrary_pose(-20.0)));
}

TEST(AxisEstimate, FlatDiscIsTooFlat) {
  // A flat stone: both faces of a 40 mm disc, 8 mm thick.
  Cloud cloud;
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.0f, 0.05f);
  for (float x = -40; x <= 40; x += 0.5f) {
    for (float y = -40; y <= 40; y += 0.5f) {
      if (x * x + y * y > 1600) continue;
      for (float face : {0.0f, 8.0f}) {
        cloud.points.emplace_back(x, y, face + noise(rng));
        cloud.normals.emplace_back(0.0f, 0.0f, face > 0 ? 1.0f : -1.0f);
      }
    }
  }
  cloud.transform(testing::arbitrary_pose());
  const auto a = axis::estimate_axis(cloud);
  EXPECT_FALSE(a.found);
  EXPECT_NE(a.reason.find("too flat"), std::string::npos) << a.reason;
}

TEST(AxisEstimate, SphereHasNoUniqueAxis) {
  // A ball seen from above and the sides (the part a scanner sees on a turntable): every line
  // through its centre is an equally good axis.
  Cloud cloud;
  std::mt19937 rng(2);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const Vec3d centre(10.0, 20.0, 30.0);
  for (int i = 0; i < 20000; ++i) {
    const Vec3d dir = Vec3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
    if (dir.z() < -0.3) continue;
    const Vec3d noisy_normal = (dir + 0.017 * Vec3d(gauss(rng), gauss(rng), gauss(rng))).normalized();
    cloud.points.push_back((centre + 40.0 * dir + 0.05 * Vec3d(gauss(rng), gauss(rng), gauss(rng))).cast<float>());
    cloud.normals.push_back(noisy_normal.cast<float>());
  }
  const auto a = axis::estimate_axis(cloud);
  EXPECT_FALSE(a.found);
  EXPECT_NE(a.reason.find("sphere"), std::string::npos) << a.reason;
}

TEST(AxisEstimate, RandomPointsAreNotRotational) {
  Cloud cloud;
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int i = 0; i < 5000; ++i) {
    cloud.points.emplace_back(50.0f * u(rng), 50.0f * u(rng), 50.0f * u(rng));
    cloud.normals.push_back(Vec3f(u(rng), u(rng), u(rng)).normalized());
  }
  // Scattered points (~6 mm apart, normals at random) form no surface to take normals from.
  const auto a = axis::estimate_axis(cloud);
  EXPECT_FALSE(a.found);
  EXPECT_NE(a.reason.find("not a surface"), std::string::npos) << a.reason;
}

TEST(AxisEstimate, TooFewPointsOrNoNormals) {
  Cloud few;
  for (int i = 0; i < 10; ++i) {
    few.points.emplace_back(float(i), 0.0f, 0.0f);
    few.normals.emplace_back(1.0f, 0.0f, 0.0f);
  }
  auto a = axis::estimate_axis(few);
  EXPECT_FALSE(a.found);
  EXPECT_NE(a.reason.find("too few"), std::string::npos) << a.reason;

  Cloud bare = few;
  bare.normals.clear();
  a = axis::estimate_axis(bare);
  EXPECT_FALSE(a.found);
  EXPECT_NE(a.reason.find("no normals"), std::string::npos) << a.reason;

  EXPECT_FALSE(axis::estimate_axis(Cloud{}).found);
}

TEST(AxisEstimate, NonFiniteInputIsRejected) {
  WallOfRevolution w;
  w.outer = [](double s) { return Vec2(60.0, 30.0 * s); };
  Cloud cloud = testing::sample_wall(w);
  cloud.points[17].y() = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(axis::estimate_axis(cloud), InputError);
}

}  // namespace
}  // namespace sherd
