// profile::analyse against analytic walls of revolution: orientation, section profile and the
// measurements, compared with the values fixed by construction.
#include "processing/profile/profile.h"

#include "core/errors.h"
#include "tests/processing/axis_test_surfaces.h"

#include <gtest/gtest.h>

namespace sherd {
namespace {

using testing::Vec2;
using testing::WallOfRevolution;

// The true axis, with the direction deliberately pointing from rim to base (or as given).
axis::AxisEstimate true_axis(const Pose& pose, double sign, double shift_along_mm = 13.0) {
  axis::AxisEstimate a;
  a.found = true;
  a.direction = sign * (pose.linear() * Vec3d::UnitZ());
  a.point = pose * Vec3d(0, 0, shift_along_mm);
  a.method = "ground truth";
  return a;
}

TEST(ProfileAnalyse, CylinderRimSherdNinetyDegrees) {
  WallOfRevolution w;
  w.outer = [](double s) { return Vec2(60.0, 50.0 * s); };
  w.phi_begin_rad = 0.3;
  w.phi_end_rad = 0.3 + M_PI / 2;
  w.thickness_mm = 6.0;
  Cloud cloud = testing::sample_wall(w);
  const Pose pose = testing::arbitrary_pose();
  cloud.transform(pose);
  const Vec3d up = pose.linear() * Vec3d::UnitZ();

  // Given pointing at the base: the lip must turn it round.
  const auto result = profile::analyse(cloud, true_axis(pose, -1.0));
  EXPECT_GT(result.axis.direction.dot(up), 0.9999);
  EXPECT_TRUE(result.rim_up_certain);
  EXPECT_TRUE(result.has_rim);
  EXPECT_FALSE(result.has_base);
  EXPECT_NEAR(result.arc_deg, 90.0, 1.0);

  const auto& m = result.measurements;
  ASSERT_TRUE(m.rim_diameter_mm.has_value());
  EXPECT_NEAR(*m.rim_diameter_mm, 120.0, 0.3);
  ASSERT_TRUE(m.rim_percent.has_value());
  EXPECT_NEAR(*m.rim_percent, 25.0, 0.5);
  ASSERT_TRUE(m.rim_inclination_deg.has_value());
  EXPECT_NEAR(*m.rim_inclination_deg, 0.0, 1.0);
  EXPECT_NEAR(m.max_diameter_mm, 120.0, 0.3);
  EXPECT_NEAR(m.wall_thickness_mm.mean, 6.0, 0.15);
  EXPECT_GT(m.wall_thickness_mm.min, 5.7);
  EXPECT_LT(m.wall_thickness_mm.max, 6.3);
  EXPECT_FALSE(m.base_diameter_mm.has_value());
  EXPECT_FALSE(m.volume_ml.has_value());
  // Height: from the lowest point of the irregular lower break to the flat lip at z = 50.
  double deepest_break = w.break_amplitude_mm;
  for (double phi = w.phi_begin_rad; phi <= w.phi_end_rad; phi += 1e-4) {
    deepest_break = std::min(deepest_break, testing::break_offset_mm(w.break_amplitude_mm, phi,
                                                                     testing::kLowBreakPhase));
  }
  EXPECT_NEAR(m.height_mm, 50.0 - deepest_break, 0.6);

  // The skins: outer on r = 60, inner on r = 54, ordered from base to rim.
  const auto& outer = result.profile.outer;
  const auto& inner = result.profile.inner;
  ASSERT_GE(outer.size(), 20u);
  ASSERT_GE(inner.size(), 20u);
  for (const auto& v : outer) EXPECT_NEAR(v[0], 60.0, 0.15);
  for (const auto& v : inner) EXPECT_NEAR(v[0], 54.0, 0.15);
  EXPECT_LT(outer.front()[1], outer.back()[1] - 30.0);
  EXPECT_LT(inner.front()[1], inner.back()[1] - 30.0);

  // Sherd frame: z up the axis, origin on the axis, x towards the section half-plane.
  const Eigen::Matrix3d rot = result.sherd_to_world.linear();
  EXPECT_GT(rot.col(2).dot(up), 0.9999);
  EXPECT_NEAR((rot.transpose() * rot - Eigen::Matrix3d::Identity()).norm(), 0.0, 1e-9);
  EXPECT_LT(
      testing::distance_point_to_line(result.sherd_to_world.translation(), pose.translation(), up),
      1e-6);
  // The rim vertex, mapped back to the world, lies on the true outer rim circle.
  const Vec3d rim_world = result.sherd_to_world * Vec3d(outer.back()[0], 0.0, outer.back()[1]);
  const Vec3d rim_local = pose.inverse() * rim_world;
  EXPECT_NEAR(std::hypot(rim_local.x(), rim_local.y()), 60.0, 0.2);
  EXPECT_NEAR(rim_local.z(), 50.0, 0.6);
  const double rim_azimuth = std::atan2(rim_local.y(), rim_local.x());
  EXPECT_GT(rim_azimuth, w.phi_begin_rad);
  EXPECT_LT(rim_azimuth, w.phi_end_rad);
}

// The closed section (outer up, inner back down) and the measurement sds propagated from the
// axis sds. Shifting the axis of a cylinder by s towards the section moves the measured rim radius
// by s (away from it: by s cos α); two perpendicular shifts of offset_sd/√2 each give a diameter
// sd of 2·offset_sd/√2 = √2·offset_sd whatever α; a shift leaves the height and the wall as they
// are.
TEST(ProfileAnalyse, ClosedSectionAndSdsPropagatedFromTheAxis) {
  WallOfRevolution w;
  w.outer = [](double s) { return Vec2(60.0, 50.0 * s); };
  w.phi_begin_rad = 0.3;
  w.phi_end_rad = 0.3 + M_PI / 2;
  w.thickness_mm = 6.0;
  w.noise_mm = 0.01;
  Cloud cloud = testing::sample_wall(w);
  const Pose pose = testing::arbitrary_pose();
  cloud.transform(pose);
  axis::AxisEstimate axis = true_axis(pose, 1.0);
  axis.offset_sd_mm = 0.5;
  const auto result = profile::analyse(cloud, axis);

  const auto& p = result.profile;
  ASSERT_EQ(p.section.size(), p.outer.size() + p.inner.size());
  EXPECT_EQ(p.section.front(), p.outer.front());
  EXPECT_EQ(p.section[p.outer.size()], p.inner.back());
  EXPECT_EQ(p.section.back(), p.inner.front());
  // Shoelace area of the section: the wall (6 mm) times its preserved height along the outer skin.
  double twice_area = 0.0;
  for (std::size_t k = 0; k < p.section.size(); ++k) {
    const auto& a = p.section[k];
    const auto& b = p.section[(k + 1) % p.section.size()];
    twice_area += a[0] * b[1] - b[0] * a[1];
  }
  const double outer_height = p.outer.back()[1] - p.outer.front()[1];
  EXPECT_NEAR(std::abs(twice_area) / 2.0, 6.0 * outer_height, 0.05 * 6.0 * outer_height);

  const auto& sd = result.measurement_sds;
  ASSERT_TRUE(sd.rim_diameter_mm.has_value());
  EXPECT_NEAR(*sd.rim_diameter_mm, std::sqrt(2.0) * 0.5, 0.1);
  EXPECT_LT(sd.height_mm, 0.05);
  EXPECT_LT(sd.wall_thickness_mean_mm, 0.05);
  EXPECT_FALSE(sd.base_diameter_mm.has_value());
  // Without axis sds nothing is propagated.
  const auto exact = profile::analyse(cloud, true_axis(pose, 1.0));
  EXPECT_FALSE(exact.measurement_sds.rim_diameter_mm.has_value());
}

TEST(ProfileAnalyse, ConeRimSherdAfterAxisEstimation) {
  WallOfRevolution w;
  const double half_angle = 25.0 * M_PI / 180.0;
  w.outer = [=](double s) {
    return Vec2(35.0 + 60.0 * s * std::sin(half_angle), 60.0 * s * std::cos(half_angle));
  };
  w.phi_end_rad = M_PI / 2;
  w.thickness_mm = 5.0;
  Cloud cloud = testing::sample_wall(w);
  const Pose pose = testing::arbitrary_pose(71.0);
  cloud.transform(pose);

  const auto estimate = axis::estimate_axis(cloud);
  ASSERT_TRUE(estimate.found) << estimate.reason;
  const auto result = profile::analyse(cloud, estimate);
  EXPECT_GT(result.axis.direction.dot(pose.linear() * Vec3d::UnitZ()), 0.999);
  EXPECT_TRUE(result.has_rim);
  const double rim_radius = 35.0 + 60.0 * std::sin(half_angle);
  ASSERT_TRUE(result.measurements.rim_diameter_mm.has_value());
  EXPECT_NEAR(*result.measurements.rim_diameter_mm, 2.0 * rim_radius, 0.01 * 2.0 * rim_radius);
  ASSERT_TRUE(result.measurements.rim_percent.has_value());
  EXPECT_NEAR(*result.measurements.rim_percent, 25.0, 0.7);
  ASSERT_TRUE(result.measurements.rim_inclination_deg.has_value());
  EXPECT_NEAR(*result.measurements.rim_inclination_deg, 25.0, 1.0);
  EXPECT_NEAR(result.measurements.wall_thickness_mm.mean, 5.0, 0.2);
}

TEST(ProfileAnalyse, BaseSherdWithFlatUndersideIsUprightWithoutRim) {
  // A base sherd broken off short of the axis: a flat underside from r = 25 mm to r = 45 mm
  // (z = 0), then a wall rising at 60° to an irregular break. The underside is level all round
  // and wider than the wall: a base, at the bottom; the top is a break, so no rim is claimed.
  WallOfRevolution w;
  w.outer = [](double s) {
    const double l = s * 60.0;
    return l <= 20.0 ? Vec2(25.0 + l, 0.0)
                     : Vec2(45.0 + (l - 20.0) * 0.5, (l - 20.0) * std::sqrt(0.75));
  };
  w.flat_lip = false;
  w.break_amplitude_mm = 6.0;
  w.phi_end_rad = M_PI / 2;
  w.thickness_mm = 6.0;
  Cloud cloud = testing::sample_wall(w);
  const Pose pose = testing::arbitrary_pose(-28.0);
  cloud.transform(pose);
  const Vec3d up = pose.linear() * Vec3d::UnitZ();
  for (double sign : {1.0, -1.0}) {  // whichever way the axis comes in
    const auto result = profile::analyse(cloud, true_axis(pose, sign));
    EXPECT_GT(result.axis.direction.dot(up), 0.9999) << sign;
    EXPECT_TRUE(result.rim_up_certain) << sign;
    EXPECT_TRUE(result.has_base) << sign;
    EXPECT_FALSE(result.has_rim) << sign;
    EXPECT_FALSE(result.measurements.rim_diameter_mm.has_value()) << sign;
    EXPECT_FALSE(result.measurements.rim_percent.has_value()) << sign;
  }
}

TEST(ProfileAnalyse, BodySherdBrokenAtBothEndsIsNotSureWhichWayUp) {
  // A cylinder wall broken at both ends: nothing tells up from down, no rim and no base.
  WallOfRevolution w;
  w.outer = [](double s) { return Vec2(70.0, 50.0 * s); };
  w.flat_lip = false;
  w.phi_end_rad = M_PI / 3;
  Cloud cloud = testing::sample_wall(w);
  const Pose pose = testing::arbitrary_pose();
  cloud.transform(pose);
  const auto result = profile::analyse(cloud, true_axis(pose, 1.0));
  EXPECT_FALSE(result.rim_up_certain);
  EXPECT_FALSE(result.has_rim);
  EXPECT_FALSE(result.has_base);
  EXPECT_FALSE(result.measurements.rim_diameter_mm.has_value());
  EXPECT_NEAR(result.measurements.wall_thickness_mm.mean, 6.0, 0.15);
}

// Both ends cut level and square across the wall (a collar, a pot stand, or a sherd whose lower
// end broke cleanly along a join): two ends of one kind, so the rule cannot tell up from down and
// says so; it takes the wider end as the top (most vessels widen from the base up), whichever way
// the axis came in and whichever end is the wider.
TEST(ProfileAnalyse, TwoLevelEndsAreNotSureWhichWayUpAndPutTheWiderEndOnTop) {
  const double half_angle = 20.0 * M_PI / 180.0;
  for (const double widening : {1.0, -1.0}) {  // +1: wider at the sherd frame's top (s = 1)
    WallOfRevolution w;
    w.outer = [=](double s) {
      const double t = widening > 0 ? s : 1.0 - s;
      return Vec2(50.0 + 40.0 * t * std::sin(half_angle), 40.0 * s * std::cos(half_angle));
    };
    w.break_amplitude_mm = 0.0;  // the lower end level, like the flat lip at the top
    w.phi_end_rad = M_PI / 2;
    w.thickness_mm = 6.0;
    Cloud cloud = testing::sample_wall(w);
    const Pose pose = testing::arbitrary_pose();
    cloud.transform(pose);
    const Vec3d wider_end = widening * (pose.linear() * Vec3d::UnitZ());
    for (const double sign : {1.0, -1.0}) {
      SCOPED_TRACE(::testing::Message() << "widening " << widening << ", axis sign " << sign);
      const auto result = profile::analyse(cloud, true_axis(pose, sign));
      EXPECT_FALSE(result.rim_up_certain) << widening << " " << sign;
      EXPECT_GT(result.axis.direction.dot(wider_end), 0.9999) << widening << " " << sign;
    }
  }
}

TEST(ProfileAnalyse, CompleteCupCapacity) {
  // A cup: flat base (outer underside r ≤ 32 at z = 0), a rounded foot (radius 8), a straight
  // wall at r = 40 up to a flat lip at z = 70; 6 mm thick. Outer profile by arc length.
  constexpr double kFlat = 32.0, kRound = 8.0, kWall = 62.0;
  const double corner = M_PI / 2 * kRound, total = kFlat + corner + kWall;
  WallOfRevolution w;
  w.outer = [=](double s) {
    const double l = s * total;
    if (l <= kFlat) return Vec2(l, 0.0);
    if (l <= kFlat + corner) {
      const double t = (l - kFlat) / kRound;
      return Vec2(kFlat + kRound * std::sin(t), kRound - kRound * std::cos(t));
    }
    return Vec2(kFlat + kRound, kRound + (l - kFlat - corner));
  };
  w.thickness_mm = 6.0;
  w.phi_begin_rad = 0.0;
  w.phi_end_rad = 2 * M_PI - 1e-3;
  w.closed_base = true;
  w.side_faces = false;
  w.spacing_mm = 0.7;
  Cloud cloud = testing::sample_wall(w);
  const Pose pose = testing::arbitrary_pose(15.0);
  cloud.transform(pose);

  const auto result = profile::analyse(cloud, true_axis(pose, -1.0, 40.0));
  EXPECT_GT(result.axis.direction.dot(pose.linear() * Vec3d::UnitZ()), 0.9999);
  EXPECT_TRUE(result.rim_up_certain);
  EXPECT_TRUE(result.has_rim);
  EXPECT_TRUE(result.has_base);
  EXPECT_NEAR(result.arc_deg, 360.0, 0.5);
  const auto& m = result.measurements;
  ASSERT_TRUE(m.rim_diameter_mm.has_value());
  EXPECT_NEAR(*m.rim_diameter_mm, 80.0, 0.3);
  ASSERT_TRUE(m.rim_percent.has_value());
  EXPECT_NEAR(*m.rim_percent, 100.0, 0.5);
  EXPECT_NEAR(m.height_mm, 70.0, 0.5);  // extremes of 0.05 mm noise: up to ~4 sd at each end
  ASSERT_TRUE(m.base_diameter_mm.has_value());
  EXPECT_GT(*m.base_diameter_mm, 2.0 * kFlat - 1.0);  // at least the flat resting disc
  EXPECT_LT(*m.base_diameter_mm, 80.0);
  // Capacity: inner floor at z = 6, inner foot radius 2 (centre r = 32, z = 8), inner wall r = 34
  // up to z = 70; integrated numerically from that analytic shape.
  double capacity_mm3 = M_PI * 34.0 * 34.0 * (70.0 - 8.0);
  constexpr int kSteps = 20000;
  for (int k = 0; k < kSteps; ++k) {
    const double z = 6.0 + 2.0 * (k + 0.5) / kSteps;
    const double r = 32.0 + std::sqrt(4.0 - (8.0 - z) * (8.0 - z));
    capacity_mm3 += M_PI * r * r * 2.0 / kSteps;
  }
  ASSERT_TRUE(m.volume_ml.has_value());
  EXPECT_NEAR(*m.volume_ml, capacity_mm3 / 1000.0, 0.015 * capacity_mm3 / 1000.0);
}

TEST(ProfileAnalyse, RejectsMissingAxisAndBadInput) {
  WallOfRevolution w;
  w.outer = [](double s) { return Vec2(60.0, 30.0 * s); };
  Cloud cloud = testing::sample_wall(w);
  axis::AxisEstimate none;
  none.found = false;
  none.reason = "too flat";
  EXPECT_THROW(profile::analyse(cloud, none), InputError);

  const auto axis = true_axis(Pose::Identity(), 1.0);
  Cloud bare = cloud;
  bare.normals.clear();
  EXPECT_THROW(profile::analyse(bare, axis), InputError);
  cloud.normals[5].x() = std::nanf("");
  EXPECT_THROW(profile::analyse(cloud, axis), InputError);
}

}  // namespace
}  // namespace sherd
