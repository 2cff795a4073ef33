// profile::analyse on sherds whose outer skin carries relief (wheel grooves): the skins must still
// be followed from end to end, whatever stray points the relief lets through the skin filter.
#include "processing/profile/profile.h"

#include "tests/processing/axis_test_surfaces.h"

#include <gtest/gtest.h>

namespace sherd {
namespace {

using testing::Vec2;

// A cylinder rim sherd (outer r = 60, inner r = 54, flat lip at z = 60) whose outer skin carries
// grooves 0.8 mm deep every 4 mm: the grooves' flanks face up and down by ~50°, so the lip's top
// finds "partners" across the wall in them and passes the skin filter as a stray inner-skin piece
// above the wall. The inner skin must still be the smooth r = 54 line over the whole height, and
// the wall 6 mm less or more the groove depth.
TEST(ProfileRelief, GroovedRimSherdKeepsBothSkinsWhole) {
  constexpr double kDepth = 0.8, kPitch = 4.0;
  testing::WallOfRevolution w;
  w.outer = [](double s) { return Vec2(60.0, 60.0 * s); };
  w.outer_relief_mm = [=](double z) { return kDepth * std::sin(2 * M_PI * z / kPitch); };
  w.phi_begin_rad = 0.3;
  w.phi_end_rad = 0.3 + M_PI / 2;
  w.thickness_mm = 6.0;
  Cloud cloud = testing::sample_wall(w);
  const Pose pose = testing::arbitrary_pose();
  cloud.transform(pose);
  axis::AxisEstimate axis;
  axis.found = true;
  axis.direction = pose.linear() * Vec3d::UnitZ();
  axis.point = pose.translation();

  const auto result = profile::analyse(cloud, axis);
  const auto& inner = result.profile.inner;
  const auto& outer = result.profile.outer;
  // 1 mm vertices over the ~50 mm the lower break leaves at the section (the break wanders 0-10
  // mm along the arc).
  ASSERT_GE(inner.size(), 40u);
  ASSERT_GE(outer.size(), 40u);
  EXPECT_GT(inner.back()[1] - inner.front()[1], 45.0);
  for (const auto& v : inner) EXPECT_NEAR(v[0], 54.0, 0.3) << "inner vertex at z " << v[1];
  // The outer skin between its two end vertices (where it meets the breaks, end vertices are
  // unsmoothed and may take a point of the break's face).
  for (std::size_t k = 1; k + 1 < outer.size(); ++k)
    EXPECT_NEAR(outer[k][0], 60.0, kDepth + 0.3) << "outer vertex at z " << outer[k][1];
  const auto& wall = result.measurements.wall_thickness_mm;
  EXPECT_NEAR(wall.mean, 6.0, 0.15);
  EXPECT_GT(wall.min, 6.0 - kDepth - 0.3);
  EXPECT_LT(wall.max, 6.0 + kDepth + 0.3);
  EXPECT_GT(wall.max - wall.min, kDepth);  // the grooves show in the wall along the profile
}

}  // namespace
}  // namespace sherd
