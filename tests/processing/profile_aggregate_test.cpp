// The aggregate profile (the skins' mean curves over every azimuth) against the true profile of
// the simulated vessel each sherd was broken from (simulators/vessel.h).
#include "processing/profile/profile.h"

#include "simulators/vessel.h"
#include "tests/processing/axis_test_surfaces.h"

#include <gtest/gtest.h>

namespace sherd {
namespace {

using sim::Point2;

double distance_to(const std::vector<Point2>& line, const Point2& p) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k + 1 < line.size(); ++k) {
    const Point2 ab = line[k + 1] - line[k];
    const double t =
        std::clamp((p - line[k]).dot(ab) / std::max(ab.squaredNorm(), 1e-12), 0.0, 1.0);
    best = std::min(best, (line[k] + t * ab - p).norm());
  }
  return best;
}

// Rim sherds of six simulated vessels, their mesh vertices moved along the normal by 0.05 mm
// depth noise and placed at an arbitrary pose, analysed about the true axis: both aggregate curves
// lie on the vessel's true skins (interior vertices; the two end vertices meet the breaks and the
// lip) and run over the sherd's whole preserved height, and their spread is the noise's.
TEST(ProfileAggregate, FollowsTheVesselsTrueProfile) {
  constexpr double kNoiseMm = 0.05;
  int tested = 0;
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    sim::Rng rng(seed);
    const sim::Family family = sim::random_family(rng);
    const sim::VesselProfile vessel = sim::make_vessel_profile(family, rng);
    const sim::ClayColours colours = sim::random_clay(rng);
    if (!sim::can_break(vessel, sim::SherdKind::Rim, 120.0)) continue;
    const sim::SherdPiece piece =
        sim::break_sherd(vessel, colours, rng, 120.0, sim::SherdKind::Rim);
    Cloud cloud = piece.mesh.vertices;
    for (std::size_t i = 0; i < cloud.size(); ++i)
      cloud.points[i] += static_cast<float>(kNoiseMm * rng.normal()) * cloud.normals[i];
    const Pose pose = testing::arbitrary_pose();
    cloud.transform(pose);
    axis::AxisEstimate axis;
    axis.found = true;
    axis.point = pose.translation();
    axis.direction = pose.linear() * Vec3d::UnitZ();

    const auto a = profile::analyse(cloud, axis);
    SCOPED_TRACE(::testing::Message() << "seed " << seed << ", " << sim::to_string(family));
    ++tested;
    for (const auto& [curve, truth] : {std::pair{&a.profile.aggregate_outer, &vessel.outer},
                                       std::pair{&a.profile.aggregate_inner, &vessel.inner}}) {
      ASSERT_GE(curve->size(), 10u);
      for (std::size_t k = 1; k + 1 < curve->size(); ++k) {
        const Point2 v((*curve)[k][0], (*curve)[k][1]);
        EXPECT_LT(distance_to(*truth, v), 0.1) << "vertex (" << v.x() << ", " << v.y() << ")";
      }
      // The skin's true height range within the piece, less the lip's rounding or a break's edge.
      double lo = std::numeric_limits<double>::infinity(), hi = -lo;
      for (const Point2& p : *truth) lo = std::min(lo, p.y()), hi = std::max(hi, p.y());
      const double span = std::min(hi, piece.z_max) - std::max(lo, piece.z_min);
      EXPECT_GT(curve->back()[1] - curve->front()[1], span - 3.0);
    }
    EXPECT_NEAR(a.profile.aggregate_spread_mm, kNoiseMm, 0.03);
  }
  EXPECT_GE(tested, 4);
}

}  // namespace
}  // namespace sherd
