// The pottery world against geometry computed independently: Pappus volumes of the revolved
// section, angles measured on the mesh about the truth axis, closedness by translation
// invariance of the divergence volume.
#include "core/errors.h"
#include "simulators/pottery.h"
#include "simulators/vessel.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace sherd::sim {
namespace {

constexpr double kPi = std::numbers::pi;

// Exact volume of the solid swept by a closed (r, z) polygon about the z axis: each edge sweeps
// a frustum, V = π/3 Σ (r_i² + r_i r_j + r_j²)(z_i − z_j) (Pappus, per edge).
double revolved_volume(const std::vector<Point2>& poly) {
  double v = 0.0;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Point2& a = poly[i];
    const Point2& b = poly[(i + 1) % poly.size()];
    v += (a.x() * a.x() + a.x() * b.x() + b.x() * b.x()) * (a.y() - b.y());
  }
  return std::abs(v) * kPi / 3.0;
}

// Cylindrical coordinates of a world point about a truth axis: (radius, angle, height).
struct AxisFrame {
  Vec3d point, dir, e1, e2;
  AxisFrame(const SherdTruth& t) : point(t.axis_point), dir(t.axis_direction.normalized()) {
    e1 = (t.centroid - point - (t.centroid - point).dot(dir) * dir).normalized();
    e2 = dir.cross(e1);
  }
  double height(const Vec3f& p) const { return (p.cast<double>() - point).dot(dir); }
  double radius(const Vec3f& p) const {
    const Vec3d q = p.cast<double>() - point;
    return (q - q.dot(dir) * dir).norm();
  }
  double angle(const Vec3f& p) const {
    const Vec3d q = p.cast<double>() - point;
    return std::atan2(q.dot(e2), q.dot(e1));
  }
};

const SceneObject& object_of(const Scene& scene, const SherdTruth& truth) {
  for (const auto& o : scene.objects)
    if (o.name == truth.id) return o;
  throw std::runtime_error("no object for " + truth.id);
}

// A sherd measured on its mesh about its truth axis: angular extent, height along the axis and,
// for a rim sherd, the preserved rim arc (the lip's vertices, at the top).
struct MeshMeasure {
  double arc_deg = 0.0, height_mm = 0.0, rim_percent = 0.0;
};

MeshMeasure measure_on_mesh(const Scene& scene, const SherdTruth& truth) {
  const AxisFrame axis(truth);
  const auto& points = object_of(scene, truth).mesh.vertices.points;
  double a0 = 1e9, a1 = -1e9, h0 = 1e9, h1 = -1e9;
  for (const auto& p : points) {
    a0 = std::min(a0, axis.angle(p));
    a1 = std::max(a1, axis.angle(p));
    h0 = std::min(h0, axis.height(p));
    h1 = std::max(h1, axis.height(p));
  }
  double r0 = 1e9, r1 = -1e9;
  for (const auto& p : points) {
    if (axis.height(p) > h1 - 0.3) {
      r0 = std::min(r0, axis.angle(p));
      r1 = std::max(r1, axis.angle(p));
    }
  }
  return {(a1 - a0) * 180.0 / kPi, h1 - h0, (r1 - r0) / (2 * kPi) * 100.0};
}

TEST(Vessel, MeshVolumeEqualsRevolvedSectionForEveryFamily) {
  for (int f = 0; f < 5; ++f) {
    for (std::uint64_t seed : {1u, 2u, 3u}) {
      Rng rng(seed * 17 + f);
      const auto profile = make_vessel_profile(static_cast<Family>(f), rng);
      const Mesh mesh = revolve_vessel(profile, random_clay(rng), rng);
      const double expected = revolved_volume(section_polyline(profile));
      const double volume = enclosed_volume(mesh);
      // Positive: normals point outwards. The polygon inscribed in the circle (≥ 180 segments)
      // loses < 0.03 % of the volume.
      EXPECT_NEAR(volume / expected, 1.0, 0.002) << to_string(static_cast<Family>(f));
    }
  }
}

TEST(Vessel, ProfilesArePlausible) {
  for (int f = 0; f < 5; ++f) {
    for (std::uint64_t seed = 0; seed < 20; ++seed) {
      Rng rng(seed * 31 + f);
      const auto p = make_vessel_profile(static_cast<Family>(f), rng);
      const double d = 2 * p.rim_radius();
      EXPECT_GE(d, 75.0);
      EXPECT_LE(d, 325.0);
      EXPECT_GE(p.wall_thickness_mm, 3.0);
      EXPECT_LE(p.wall_thickness_mm, 10.0);
      // Inner wall at the wall thickness from the outer one (the offset construction).
      for (std::size_t j = p.wall_start + 5; j + 5 < p.outer.size(); j += 7) {
        double nearest = 1e9;
        for (const auto& q : p.inner) nearest = std::min(nearest, (q - p.outer[j]).norm());
        if (p.inner[j].y() > p.inner[p.wall_start].y() + 1.0) {
          EXPECT_NEAR(nearest, p.wall_thickness_mm, 0.05 * p.wall_thickness_mm);
        }
      }
    }
  }
}

// The clay texture belongs to the surface, not to the draw: the same vessel-frame point gets the
// same texture factor whatever the random stream (only the ±5 % per-vertex mottle differs, so two
// draws differ by a factor within 0.95/1.05 … 1.05/0.95), and over the surface it varies beyond
// that mottle; a flat tone (amplitude 0) stays within the mottle.
TEST(Clay, TextureIsFixedOnTheSurfaceAndVariesAcrossIt) {
  const Rgb8 base{200, 140, 100};
  const ClayTexture texture{.seed = 42, .amplitude = 0.12};
  Rng points(1), first(2), second(3);
  double widest = 0.0;
  for (int i = 0; i < 500; ++i) {
    const Vec3f p(static_cast<float>(points.uniform(-100, 100)),
                  static_cast<float>(points.uniform(-100, 100)),
                  static_cast<float>(points.uniform(0, 200)));
    const double a = clay_colour(base, p, texture, first).r;
    const double b = clay_colour(base, p, texture, second).r;
    EXPECT_NEAR(a / b, 1.0, 0.11) << "at point " << i;
    widest = std::max(widest, std::abs(a / base.r - 1.0));
    const double flat = clay_colour(base, p, ClayTexture{}, first).r;
    EXPECT_NEAR(flat / base.r, 1.0, 0.051);
  }
  EXPECT_GT(widest, 0.08);  // beyond the mottle's 5 %
}

TEST(Vessel, RimDiameterMatchesTheMesh) {
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    const Scene scene = make_scene({.seed = seed, .kind = SceneKind::Vessel});
    ASSERT_EQ(scene.truth.size(), 1u);
    const SherdTruth& truth = scene.truth[0];
    ASSERT_TRUE(truth.rim_diameter_mm);
    const AxisFrame axis(truth);
    const auto& points = object_of(scene, truth).mesh.vertices.points;
    double top = -1e9;
    for (const auto& p : points) top = std::max(top, axis.height(p));
    // The outer edge of the rim: the widest vertex within one wall thickness of the top.
    double rim_r = 0.0;
    for (const auto& p : points) {
      if (axis.height(p) > top - truth.wall_thickness_mm) rim_r = std::max(rim_r, axis.radius(p));
    }
    EXPECT_NEAR(2 * rim_r, *truth.rim_diameter_mm, 0.35 * truth.wall_thickness_mm)
        << truth.family << " seed " << seed;
    double bottom = 1e9, lowest_z = 1e9;
    for (const auto& p : points) {
      bottom = std::min(bottom, axis.height(p));
      lowest_z = std::min(lowest_z, static_cast<double>(p.z()));
    }
    EXPECT_NEAR(truth.height_mm, top - bottom, 1e-3);
    EXPECT_NEAR(lowest_z, 0.0, 1e-3);  // standing on the plate (z = 0)
    EXPECT_NEAR(truth.axis_direction.z(), 1.0, 1e-9);  // standing upright
  }
}

// Frame and plate scenes over many seeds: sherds within their specified sizes and arcs, truth
// angles equal to those measured on the mesh about the truth axis.
class SherdScenes : public ::testing::TestWithParam<SceneKind> {};

TEST_P(SherdScenes, ArcRimPercentAndHeightMatchTheMesh) {
  int rims = 0, bases = 0, total = 0;
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    const Scene scene = make_scene({.seed = seed, .kind = GetParam(), .sherds = 4});
    ASSERT_EQ(scene.truth.size(), 4u);
    for (const auto& truth : scene.truth) {
      ++total;
      rims += truth.has_rim;
      bases += truth.has_base;
      const MeshMeasure measured = measure_on_mesh(scene, truth);
      EXPECT_NEAR(measured.arc_deg, truth.arc_deg, 0.2) << truth.id << " seed " << seed;
      EXPECT_GE(measured.arc_deg, 0.05 * 360.0);
      EXPECT_LE(measured.arc_deg, 0.50 * 360.0);
      EXPECT_NEAR(measured.height_mm, truth.height_mm, 0.01);
      // Sherd sized for the 300 mm plate.
      const Vec3d extent = truth.bbox.extent();
      EXPECT_LE(extent.maxCoeff(), 125.0);
      EXPECT_GE(extent.maxCoeff(), 25.0);
      if (truth.has_rim) {
        ASSERT_TRUE(truth.rim_percent && truth.rim_diameter_mm);
        EXPECT_NEAR(*truth.rim_percent, measured.rim_percent, 0.3) << truth.id;
        EXPECT_LE(*truth.rim_percent, truth.arc_deg / 3.6 + 1e-9);
      } else {
        EXPECT_FALSE(truth.rim_percent || truth.rim_diameter_mm);
      }
    }
  }
  // The mix holds rim, base and body sherds.
  EXPECT_GT(rims, total / 5);
  EXPECT_GT(bases, 0);
  EXPECT_LT(rims, total);
}

TEST_P(SherdScenes, SherdsAreClosedOutwardAndApart) {
  const Scene scene = make_scene({.seed = 11, .kind = GetParam(), .sherds = 6});
  std::vector<const SceneObject*> sherds;
  for (const auto& o : scene.objects)
    if (o.label > 0) sherds.push_back(&o);
  ASSERT_EQ(sherds.size(), 6u);
  for (const auto* o : sherds) {
    // A closed surface encloses the same volume wherever the origin is; an open one does not.
    const double volume = enclosed_volume(o->mesh);
    Mesh moved = o->mesh;
    Pose shift = Pose::Identity();
    shift.translate(Vec3d(300.0, -200.0, 150.0));
    moved.vertices.transform(shift);
    EXPECT_GT(volume, 0.0) << o->name;
    EXPECT_NEAR(enclosed_volume(moved) / volume, 1.0, 1e-3) << o->name;
    for (const auto& p : o->mesh.vertices.points) {
      ASSERT_LE(std::hypot(p.x(), p.y()), kPlateRadiusMm) << o->name;
      ASSERT_GE(p.z(), -1e-3) << o->name;  // on or above the plate
    }
  }
  for (std::size_t a = 0; a < sherds.size(); ++a) {
    for (std::size_t b = a + 1; b < sherds.size(); ++b) {
      double nearest = 1e9;
      const auto& pa = sherds[a]->mesh.vertices.points;
      const auto& pb = sherds[b]->mesh.vertices.points;
      for (std::size_t i = 0; i < pa.size(); i += 7)
        for (std::size_t j = 0; j < pb.size(); j += 7) {
          nearest = std::min(nearest, static_cast<double>((pa[i] - pb[j]).norm()));
        }
      EXPECT_GT(nearest, 3.0) << sherds[a]->name << " touches " << sherds[b]->name;
    }
  }
}

// The tray's composition over many seeds and sizes: rim sherds in about half the places (at least
// one; two from three sherds on), a base sherd from three on, body sherds in the rest, the kinds'
// order varying with the seed; rim sherds big enough to measure (≥ 10 % of the rim, ≥ 25 mm
// tall, measured on the mesh) wherever the slot has room, amphora body sherds curved (≥ 20°).
TEST_P(SherdScenes, TrayIsMostlyRimSherdsWithBasesAndBodies) {
  constexpr int kSeeds = 12;
  for (int k = 1; k <= kMaxSherds; ++k) {
    std::vector<int> rim_at(static_cast<std::size_t>(k), 0);  // seeds with a rim in place i
    for (std::uint64_t seed = 1; seed <= kSeeds; ++seed) {
      const Scene scene = make_scene({.seed = seed * 1000 + k, .kind = GetParam(), .sherds = k});
      ASSERT_EQ(static_cast<int>(scene.truth.size()), k);
      int rims = 0, bases = 0, bodies = 0;
      for (std::size_t i = 0; i < scene.truth.size(); ++i) {
        const SherdTruth& truth = scene.truth[i];
        const MeshMeasure measured = measure_on_mesh(scene, truth);
        const auto& outer = truth.outer_profile;
        const auto& inner = truth.inner_profile;
        const std::string where = fmt::format("{} k={} seed={}", truth.id, k, seed);
        if (truth.has_rim) {
          ++rims;
          ++rim_at[i];
          // The rim is really there: the piece reaches the top of the outer wall.
          EXPECT_GE(truth.preserved_z_mm[1], outer.back()[1]) << where;
          EXPECT_GE(measured.rim_percent, kMinRimPercent) << where;
          // A frame of 10 sherds leaves 30 mm a slot: 25 mm plus the fracture's wander do not fit.
          const bool roomy = GetParam() == SceneKind::Plate || k < 10;
          EXPECT_GE(measured.height_mm, roomy ? kMinRimHeightMm : 24.0) << where;
        } else {
          // Without the lip the piece stays below the rim's top on both skins.
          EXPECT_LT(truth.preserved_z_mm[1], std::max(outer.back()[1], inner.back()[1])) << where;
          truth.has_base ? ++bases : ++bodies;
        }
        if (!truth.has_rim && !truth.has_base) {
          // A body sherd keeps neither the base angle nor the base: it starts above the floor.
          EXPECT_GT(truth.preserved_z_mm[0], 0.0) << where;
          if (truth.family == "amphora") {
            EXPECT_GE(measured.arc_deg, kMinBodyArcDeg) << where;
          }
        }
      }
      EXPECT_GE(rims, 1) << "k=" << k << " seed " << seed;
      EXPECT_NEAR(rims, 0.5 * k, 0.5) << "k=" << k << " seed " << seed;
      if (k >= 3) {
        EXPECT_GE(rims, 2) << "k=" << k << " seed " << seed;
        EXPECT_GE(bases, 1) << "k=" << k << " seed " << seed;
      }
      if (k >= 4) {
        EXPECT_GE(bodies, 1) << "k=" << k << " seed " << seed;
      }
    }
    // The order is shuffled: from two sherds on, no place is always or never a rim.
    if (k >= 2) {
      for (int i = 0; i < k; ++i) {
        EXPECT_GT(rim_at[i], 0) << "k=" << k << " place " << i;
        EXPECT_LT(rim_at[i], kSeeds) << "k=" << k << " place " << i;
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(FrameAndPlate, SherdScenes,
                         ::testing::Values(SceneKind::Frame, SceneKind::Plate),
                         [](const auto& info) { return std::string(to_string(info.param)); });

TEST(Scene, DeterministicFromSeed) {
  const SceneSpec spec{.seed = 5, .kind = SceneKind::Frame, .sherds = 3};
  const Scene a = make_scene(spec), b = make_scene(spec);
  const Scene c = make_scene({.seed = 6, .kind = SceneKind::Frame, .sherds = 3});
  const Mesh ma = merged_mesh(a), mb = merged_mesh(b), mc = merged_mesh(c);
  ASSERT_EQ(ma.vertices.size(), mb.vertices.size());
  EXPECT_TRUE(ma.vertices.points == mb.vertices.points);
  EXPECT_TRUE(ma.vertices.colours == mb.vertices.colours);
  EXPECT_EQ(truth_to_json(a), truth_to_json(b));
  EXPECT_NE(truth_to_json(a), truth_to_json(c));
}

TEST(Scene, EmptyHasOnlyBackground) {
  const Scene scene = make_scene({.seed = 3, .kind = SceneKind::Empty, .sherds = 4,
                                  .background = Background::White});
  EXPECT_TRUE(scene.truth.empty());
  ASSERT_EQ(scene.objects.size(), 2u);  // plate + frame
  for (const auto& o : scene.objects) {
    EXPECT_EQ(o.label, 0);
    for (const auto& c : o.mesh.vertices.colours) ASSERT_GE(c.r, 215);  // white, give or take the mottling
  }
}

TEST(Scene, TruthJsonCarriesTheDocumentedFields) {
  const Scene scene = make_scene({.seed = 2, .kind = SceneKind::Frame, .sherds = 5});
  const auto j = truth_to_json(scene);
  EXPECT_EQ(j["schema"], "sherdscan.truth/1");
  EXPECT_EQ(j["scene"], "frame");
  EXPECT_EQ(j["plate"]["radius_mm"], 150.0);
  ASSERT_EQ(j["sherds"].size(), 5u);
  for (const auto& s : j["sherds"]) {
    for (const char* key : {"id", "family", "complete", "has_rim", "has_base", "axis",
                            "centroid_mm", "bbox_mm", "rim_diameter_mm", "rim_percent",
                            "wall_thickness_mm", "arc_deg", "height_mm", "preserved_z_mm",
                            "profile"}) {
      EXPECT_TRUE(s.contains(key)) << key;
    }
    const auto& d = s["axis"]["direction"];
    EXPECT_NEAR(std::hypot(d[0].get<double>(), d[1].get<double>(), d[2].get<double>()), 1.0,
                1e-9);
    EXPECT_EQ(s["rim_diameter_mm"].is_null(), !s["has_rim"].get<bool>());
    EXPECT_EQ(s["profile"]["outer"][0][0], 0.0);  // from the axis at the base
  }
}

TEST(Scene, RejectsImpossibleRequests) {
  EXPECT_THROW(make_scene({.kind = SceneKind::Frame, .sherds = 11}), InputError);
  EXPECT_THROW(make_scene({.kind = SceneKind::Plate, .sherds = -1}), InputError);
  EXPECT_THROW(scene_kind_from_string("tray"), InputError);
  EXPECT_THROW(background_from_string("grey"), InputError);
}

}  // namespace
}  // namespace sherd::sim
