// A hand-made, irregular pot has no axis: sherds of simulated vessels (simulators/vessel.h) whose
// walls are pushed out and in by ±4 mm lobes around the circumference get found = false with the
// reason "not wheel-made"; the same sherds without lobes, at the station's largest depth noise
// (0.1 mm), keep their axis.
#include <gtest/gtest.h>

#include "processing/axis/axis.h"
#include "simulators/vessel.h"
#include "tests/processing/axis_test_surfaces.h"

namespace sherd {
namespace {

constexpr double kNoiseMm = 0.1;

// A sherd of a jar (rim or body, as `seed` chooses), its mesh's radius changed by
// amplitude · sin(lobes·θ + phase + z / 40 mm) — lobes that also wander with height, as a coiled or
// pinched pot's do —, normals recomputed from the deformed mesh, scanner-like depth noise, placed
// at an arbitrary pose.
Cloud lobed_sherd(std::uint64_t seed, double lobes, double amplitude_mm) {
  sim::Rng rng(seed);
  const sim::VesselProfile vessel = sim::make_vessel_profile(sim::Family::Jar, rng);
  const sim::ClayColours colours = sim::random_clay(rng);
  const auto kind = seed % 2 ? sim::SherdKind::Rim : sim::SherdKind::Body;
  sim::SherdPiece piece = sim::break_sherd(vessel, colours, rng, 150.0, kind);
  const double phase = rng.uniform(0.0, 2.0 * M_PI);
  for (auto& p : piece.mesh.vertices.points) {
    const double theta = std::atan2(p.y(), p.x()), r = std::hypot(p.x(), p.y());
    const double dr = amplitude_mm * std::sin(lobes * theta + phase + p.z() / 40.0);
    p.x() *= static_cast<float>((r + dr) / r);
    p.y() *= static_cast<float>((r + dr) / r);
  }
  sim::compute_vertex_normals(piece.mesh);
  Cloud cloud = piece.mesh.vertices;
  for (std::size_t i = 0; i < cloud.size(); ++i)
    cloud.points[i] += static_cast<float>(kNoiseMm * rng.normal()) * cloud.normals[i];
  cloud.transform(testing::arbitrary_pose());
  return cloud;
}

TEST(AxisHandMade, LobedPotIsNotWheelMade) {
  for (const double lobes : {2.0, 3.0}) {
    for (std::uint64_t seed = 1; seed <= 4; ++seed) {
      const auto a = axis::estimate(lobed_sherd(seed, lobes, 4.0), axis::Method::Refined);
      EXPECT_FALSE(a.found) << lobes << " lobes, seed " << seed;
      EXPECT_NE(a.reason.find("not wheel-made"), std::string::npos)
          << lobes << " lobes, seed " << seed << ": " << a.reason;
    }
  }
}

TEST(AxisHandMade, WheelMadeSherdsAtTheLargestNoiseKeepTheirAxis) {
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    const auto a = axis::estimate(lobed_sherd(seed, 2.0, 0.0), axis::Method::Refined);
    EXPECT_TRUE(a.found) << "seed " << seed << ": " << a.reason;
    // Spread and scatter both measure the 0.1 mm depth noise.
    EXPECT_NEAR(a.profile_spread_mm, kNoiseMm, 0.03) << "seed " << seed;
    EXPECT_NEAR(a.local_scatter_mm, kNoiseMm, 0.03) << "seed " << seed;
  }
}

}  // namespace
}  // namespace sherd
