// The tray simulator against what a tray must be: one point per plate cell (the plate's area over
// the cell area), every sherd visible under its own label, touching sherds with points of two
// labels side by side, the plate at z = 0 in its background colour, the same tray for a seed.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <set>

#include "core/errors.h"
#include "simulators/tray.h"

namespace sherd::sim {
namespace {

TEST(Tray, OnePointPerPlateCellAndEverySherdVisible) {
  TraySpec spec;
  spec.seed = 5;
  spec.sherds = 12;
  const Tray tray = make_tray(spec);
  ASSERT_EQ(tray.cloud.vertices.size(), tray.labels.size());
  ASSERT_TRUE(tray.cloud.vertices.has_colours());
  const double cells =
      std::numbers::pi * kPlateRadiusMm * kPlateRadiusMm / (spec.grid_mm * spec.grid_mm);
  const double grid_points = static_cast<double>(tray.cloud.vertices.size() - spec.stray_points);
  EXPECT_NEAR(grid_points / cells, 1.0, 0.01);
  const std::set<int> labels(tray.labels.begin(), tray.labels.end());
  EXPECT_EQ(labels.size(), 13u);  // background + 12 sherds
  EXPECT_EQ(*labels.rbegin(), 12);
  EXPECT_EQ(tray.touching + tray.leaning <= 11, true);
}

TEST(Tray, PlateIsFlatAndInTheBackgroundColour) {
  for (auto background : {Background::Black, Background::White}) {
    TraySpec spec;
    spec.seed = 9;
    spec.sherds = 6;
    spec.background = background;
    spec.dust_specks = 0;
    spec.stray_points = 0;
    const Tray tray = make_tray(spec);
    int clay = 0, coloured = 0;
    for (std::size_t i = 0; i < tray.labels.size(); ++i) {
      const Vec3f& p = tray.cloud.vertices.points[i];
      const Rgb8 c = tray.cloud.vertices.colours[i];
      const int hi = std::max({c.r, c.g, c.b}), lo = std::min({c.r, c.g, c.b});
      if (tray.labels[i] == 0) {
        ASSERT_LT(std::abs(p.z()), 0.3f) << i;  // 6 σ of the 0.05 mm noise
        ASSERT_LE(hi - lo, 16) << i;            // grey: tint noise only
        if (background == Background::Black) {
          ASSERT_LT(hi, 40) << i;
        } else {
          ASSERT_GT(lo, 160) << i;
        }
      } else {
        ASSERT_GT(p.z(), -0.3f) << i;  // nothing below the plate
        ++clay;
        coloured += hi - lo > hi / 4;
      }
    }
    // Clay is coloured (saturation > 0.25) even in shade, but for the darkest, greyest fracture
    // faces turned away from the light.
    EXPECT_GT(coloured, 0.99 * clay);
  }
}

// Touching sherds: two labels within one grid cell of each other somewhere on the tray.
TEST(Tray, TouchingSherdsHaveNeighbouringPointsOfTwoLabels) {
  TraySpec spec;
  spec.seed = 3;
  spec.sherds = 10;
  spec.touching_share = 1.0;
  spec.leaning_share = 0.0;
  const Tray tray = make_tray(spec);
  ASSERT_GT(tray.touching, 0);
  // Points on the grid in row-major order: compare each with its right-hand neighbour.
  const auto& pts = tray.cloud.vertices.points;
  int contacts = 0;
  for (std::size_t i = 0; i + 1 < tray.labels.size(); ++i) {
    if (tray.labels[i] == 0 || tray.labels[i + 1] == 0 || tray.labels[i] == tray.labels[i + 1])
      continue;
    if (std::abs(pts[i + 1].x() - pts[i].x() - spec.grid_mm) < 0.25f) ++contacts;
  }
  EXPECT_GT(contacts, 0);
}

TEST(Tray, SameSeedSameTray) {
  TraySpec spec;
  spec.seed = 11;
  spec.sherds = 4;
  const Tray a = make_tray(spec), b = make_tray(spec);
  ASSERT_EQ(a.labels, b.labels);
  EXPECT_TRUE(std::equal(a.cloud.vertices.points.begin(), a.cloud.vertices.points.end(),
                         b.cloud.vertices.points.begin()));
}

TEST(Tray, BadSpecIsRefused) {
  TraySpec spec;
  spec.sherds = 21;
  EXPECT_THROW(make_tray(spec), InputError);
  spec.sherds = 3;
  spec.grid_mm = 0.0;
  EXPECT_THROW(make_tray(spec), InputError);
}

}  // namespace
}  // namespace sherd::sim
