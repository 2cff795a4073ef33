// Pieces without a usable axis, through the station's method (refined): each gets found = false
// and a reason of its own, so that the plate says why no profile is drawn (a hand-made, irregular
// pot: axis_hand_made_test.cpp).
#include <gtest/gtest.h>

#include "processing/axis/axis.h"
#include "tests/processing/axis_test_surfaces.h"

namespace sherd {
namespace {

using testing::Vec2;
using testing::WallOfRevolution;
using testing::cone_wall;

// A flat tile: both faces of a 60 × 40 mm slab, 10 mm thick, and its four edges.
TEST(AxisNotFound, FlatTileIsTooFlat) {
  Cloud cloud;
  std::mt19937 rng(5);
  std::normal_distribution<float> noise(0.0f, 0.05f);
  for (float x = -30; x <= 30; x += 0.5f) {
    for (float y = -20; y <= 20; y += 0.5f) {
      for (float face : {0.0f, 10.0f}) {
        cloud.points.emplace_back(x, y, face + noise(rng));
        cloud.normals.emplace_back(0.0f, 0.0f, face > 0 ? 1.0f : -1.0f);
      }
    }
  }
  cloud.transform(testing::arbitrary_pose());
  const auto a = axis::estimate(cloud, axis::Method::Refined);
  EXPECT_FALSE(a.found);
  EXPECT_NE(a.reason.find("too flat"), std::string::npos) << a.reason;
}

// A tiny fragment of a wheel-made wall: 12 mm along the profile, 4° (about 4 mm) around.
TEST(AxisNotFound, TinyFragmentIsTooSmall) {
  WallOfRevolution w = cone_wall();
  const double half_angle = 25.0 * M_PI / 180.0;
  w.outer = [=](double s) {
    return Vec2(45.0 + 12.0 * s * std::sin(half_angle), 12.0 * s * std::cos(half_angle));
  };
  w.phi_end_rad = w.phi_begin_rad + 4.0 * M_PI / 180.0;
  w.break_amplitude_mm = 1.0;
  w.spacing_mm = 0.3;
  Cloud cloud = testing::sample_wall(w);
  cloud.transform(testing::arbitrary_pose());
  const auto a = axis::estimate(cloud, axis::Method::Refined);
  EXPECT_FALSE(a.found);
  EXPECT_NE(a.reason.find("too small"), std::string::npos) << a.reason;
}

}  // namespace
}  // namespace sherd
