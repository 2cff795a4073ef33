#include "simulators/vessel.h"

#include "core/errors.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <numbers>
#include <optional>
#include <utility>

namespace sherd::sim {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kSampleSpacingMm = 1.5;  // profile and sherd grid spacing: ~2–3 camera pixels

double clampd(double x, double lo, double hi) { return std::min(std::max(x, lo), hi); }

// Centripetal Catmull–Rom through the control points (no cusps or self-intersections, unlike the
// uniform variant), sampled densely.
std::vector<Point2> catmull_rom(const std::vector<Point2>& c) {
  std::vector<Point2> p;
  p.push_back(2.0 * c[0] - c[1]);
  p.insert(p.end(), c.begin(), c.end());
  p.push_back(2.0 * c[c.size() - 1] - c[c.size() - 2]);
  std::vector<Point2> out;
  constexpr int kPerSegment = 40;
  for (std::size_t i = 1; i + 2 < p.size(); ++i) {
    const Point2 &P0 = p[i - 1], &P1 = p[i], &P2 = p[i + 1], &P3 = p[i + 2];
    const double t0 = 0.0;
    const double t1 = t0 + std::sqrt(std::max((P1 - P0).norm(), 1e-9));
    const double t2 = t1 + std::sqrt(std::max((P2 - P1).norm(), 1e-9));
    const double t3 = t2 + std::sqrt(std::max((P3 - P2).norm(), 1e-9));
    for (int k = 0; k < kPerSegment; ++k) {
      const double t = t1 + (t2 - t1) * k / kPerSegment;
      const Point2 A1 = (t1 - t) / (t1 - t0) * P0 + (t - t0) / (t1 - t0) * P1;
      const Point2 A2 = (t2 - t) / (t2 - t1) * P1 + (t - t1) / (t2 - t1) * P2;
      const Point2 A3 = (t3 - t) / (t3 - t2) * P2 + (t - t2) / (t3 - t2) * P3;
      const Point2 B1 = (t2 - t) / (t2 - t0) * A1 + (t - t0) / (t2 - t0) * A2;
      const Point2 B2 = (t3 - t) / (t3 - t1) * A2 + (t - t1) / (t3 - t1) * A3;
      out.push_back((t2 - t) / (t2 - t1) * B1 + (t - t1) / (t2 - t1) * B2);
    }
  }
  out.push_back(c.back());
  return out;
}

std::vector<double> cumulative_length(const std::vector<Point2>& pts) {
  std::vector<double> arc(pts.size(), 0.0);
  for (std::size_t i = 1; i < pts.size(); ++i) arc[i] = arc[i - 1] + (pts[i] - pts[i - 1]).norm();
  return arc;
}

// The point at arc length `s` along a polyline with cumulative lengths `arc`.
Point2 at_arc(const std::vector<Point2>& pts, const std::vector<double>& arc, double s) {
  s = clampd(s, arc.front(), arc.back());
  auto it = std::upper_bound(arc.begin(), arc.end(), s);
  std::size_t i = it == arc.end() ? arc.size() - 1 : static_cast<std::size_t>(it - arc.begin());
  if (i == 0) return pts.front();
  const double len = arc[i] - arc[i - 1];
  const double f = len > 0.0 ? (s - arc[i - 1]) / len : 0.0;
  return pts[i - 1] + f * (pts[i] - pts[i - 1]);
}

// Evenly spaced samples along a polyline, keeping its corners (the foot's edges stay sharp).
std::vector<Point2> resample_keep_corners(const std::vector<Point2>& poly, double spacing) {
  std::vector<Point2> out{poly.front()};
  for (std::size_t i = 1; i < poly.size(); ++i) {
    const double len = (poly[i] - poly[i - 1]).norm();
    const int n = std::max(1, static_cast<int>(std::ceil(len / spacing)));
    for (int k = 1; k <= n; ++k) out.push_back(poly[i - 1] + (poly[i] - poly[i - 1]) * k / n);
  }
  return out;
}

std::vector<Point2> resample_even(const std::vector<Point2>& dense, double spacing) {
  const auto arc = cumulative_length(dense);
  const int n = std::max(2, static_cast<int>(std::ceil(arc.back() / spacing)));
  std::vector<Point2> out;
  for (int k = 0; k <= n; ++k) out.push_back(at_arc(dense, arc, arc.back() * k / n));
  return out;
}

// Unit tangent of a polyline at sample i (central difference inside, one-sided at the ends).
Point2 tangent_at(const std::vector<Point2>& pts, std::size_t i) {
  const std::size_t a = i == 0 ? 0 : i - 1;
  const std::size_t b = std::min(i + 1, pts.size() - 1);
  return (pts[b] - pts[a]).normalized();
}

// Control points (r, z) of the outer wall from the base edge (rb, 0) to the rim (R, H), per
// family, with the family's plausible proportions and a little per-vessel irregularity.
std::vector<Point2> wall_controls(Family family, Rng& rng) {
  auto jitter = [&rng](double x) { return x * rng.uniform(0.97, 1.03); };
  std::vector<Point2> c;
  switch (family) {
    case Family::Bowl: {
      const double R = rng.uniform(120.0, 300.0) / 2.0;
      const double H = 2.0 * R * rng.uniform(0.28, 0.45);
      const double rb = R * rng.uniform(0.30, 0.45);
      // A quarter-ellipse: horizontal at the base, vertical at the rim.
      for (int k = 0; k <= 6; ++k) {
        const double a = k * kPi / 12.0;
        const double r = rb + (R - rb) * std::sin(a);
        const double z = H * (1.0 - std::cos(a));
        c.emplace_back(k == 0 || k == 6 ? r : jitter(r), z);
      }
      break;
    }
    case Family::Plate: {
      const double R = rng.uniform(180.0, 320.0) / 2.0;
      const double H = rng.uniform(18.0, 40.0);
      const double rb = R * rng.uniform(0.45, 0.65);
      c = {{rb, 0.0},
           {rb + 0.15 * (R - rb), 0.04 * H},
           {rb + 0.5 * (R - rb), jitter(0.3 * H)},
           {rb + 0.85 * (R - rb), jitter(0.7 * H)},
           {R, H}};
      break;
    }
    case Family::Beaker: {
      const double R = rng.uniform(80.0, 120.0) / 2.0;
      const double H = 2.0 * R * rng.uniform(1.0, 1.5);
      const double rb = R * rng.uniform(0.6, 0.8);
      const double waist = rng.uniform(0.9, 1.0);
      c = {{rb, 0.0},
           {rb * 1.02, 0.08 * H},
           {(rb + 0.3 * (R - rb)) * waist, 0.35 * H},
           {jitter(0.97 * R), 0.72 * H},
           {R, H}};
      break;
    }
    case Family::Jar: {
      const double R = rng.uniform(90.0, 180.0) / 2.0;
      const double belly = R * rng.uniform(1.25, 1.55);
      const double H = 2.0 * belly * rng.uniform(0.9, 1.2);
      const double rb = belly * rng.uniform(0.45, 0.6);
      c = {{rb, 0.0},
           {jitter(0.85 * belly), 0.2 * H},
           {belly, 0.45 * H},
           {jitter(0.85 * belly), 0.7 * H},
           {0.92 * R, 0.88 * H},
           {R, H}};
      break;
    }
    case Family::Amphora: {
      const double R = rng.uniform(85.0, 120.0) / 2.0;
      const double belly = R * rng.uniform(1.9, 2.4);
      const double H = 2.0 * R * rng.uniform(2.4, 3.0);
      const double rb = R * rng.uniform(0.35, 0.5);
      c = {{rb, 0.0},
           {0.55 * belly, 0.08 * H},
           {jitter(0.95 * belly), 0.3 * H},
           {belly, 0.42 * H},
           {jitter(0.7 * belly), 0.66 * H},
           {0.95 * R, 0.82 * H},
           {0.93 * R, 0.92 * H},
           {R, H}};
      break;
    }
  }
  return c;
}

// Smooth value noise in [-1, 1]: random values on an integer lattice, hashed from the cell and
// the seed, blended with a smoothstep. Written here because it is a dozen lines and a noise
// library (libnoise) would be a dependency for the simulator alone.
double lattice_value(std::int64_t x, std::int64_t y, std::int64_t z, std::uint64_t seed) {
  std::uint64_t h = seed ^ (static_cast<std::uint64_t>(x) * 0x9E3779B97F4A7C15ULL) ^
                    (static_cast<std::uint64_t>(y) * 0xC2B2AE3D27D4EB4FULL) ^
                    (static_cast<std::uint64_t>(z) * 0x165667B19E3779F9ULL);
  h ^= h >> 33;  // splitmix64's finaliser
  h *= 0xFF51AFD7ED558CCDULL;
  h ^= h >> 33;
  h *= 0xC4CEB9FE1A85EC53ULL;
  h ^= h >> 33;
  return static_cast<double>(h >> 11) * 0x1.0p-52 - 1.0;
}

double value_noise(const Vec3d& p, std::uint64_t seed) {
  const Vec3d cell = p.array().floor();
  const Vec3d f = p - cell;
  const Vec3d w = f.array().square() * (3.0 - 2.0 * f.array());  // smoothstep
  const auto x = static_cast<std::int64_t>(cell.x()), y = static_cast<std::int64_t>(cell.y()),
             z = static_cast<std::int64_t>(cell.z());
  double sum = 0.0;
  for (int corner = 0; corner < 8; ++corner) {
    const int dx = corner & 1, dy = (corner >> 1) & 1, dz = (corner >> 2) & 1;
    sum += (dx ? w.x() : 1 - w.x()) * (dy ? w.y() : 1 - w.y()) * (dz ? w.z() : 1 - w.z()) *
           lattice_value(x + dx, y + dy, z + dz, seed);
  }
  return sum;
}

// ±12 %: plain to see in a photo, far from a black or white background.
constexpr double kClayTextureAmplitude = 0.12;
// Wavelengths of the clay texture's octaves (mm) and their shares of its amplitude: grains and
// spots of a few millimetres up to firing clouds of a few centimetres.
constexpr std::array<std::pair<double, double>, 3> kTextureOctaves{
    {{4.0, 0.5}, {9.0, 0.3}, {25.0, 0.2}}};

double texture_factor(const Vec3f& p, const ClayTexture& texture) {
  if (texture.amplitude == 0.0) return 1.0;
  double noise = 0.0;
  std::uint64_t seed = texture.seed;
  for (const auto& [wavelength, share] : kTextureOctaves) {
    noise += share * value_noise(p.cast<double>() / wavelength, seed++);
  }
  return 1.0 + texture.amplitude * noise;
}

Vec3f revolve(const Point2& p, double theta) {
  return Vec3f(static_cast<float>(p.x() * std::cos(theta)),
               static_cast<float>(p.x() * std::sin(theta)), static_cast<float>(p.y()));
}

// Emits the triangles of a grid of vertex indices index(a, b), a < nA, b < nB. Each triangle's
// normal is e_b × e_a (e_a, e_b the grid directions): callers pick which parameter is `a` so
// that this points out of the material.
template <typename Index>
void emit_grid(Mesh& mesh, int nA, int nB, Index index) {
  for (int a = 0; a + 1 < nA; ++a) {
    for (int b = 0; b + 1 < nB; ++b) {
      const std::uint32_t p = index(a, b), q = index(a, b + 1), r = index(a + 1, b),
                          s = index(a + 1, b + 1);
      if (p != q && p != r && q != r) mesh.triangles.push_back({p, q, r});
      if (q != s && q != r && s != r) mesh.triangles.push_back({q, s, r});
    }
  }
}

std::uint32_t add_vertex(Mesh& mesh, const Vec3f& p, const Rgb8& colour) {
  mesh.vertices.points.push_back(p);
  mesh.vertices.colours.push_back(colour);
  return static_cast<std::uint32_t>(mesh.vertices.points.size() - 1);
}

// A vertex of clay of colour `base`, textured where it lies.
std::uint32_t add_clay_vertex(Mesh& mesh, const Vec3f& p, const Rgb8& base,
                              const ClayTexture& texture, Rng& rng) {
  return add_vertex(mesh, p, clay_colour(base, p, texture, rng));
}

// A smooth random wobble (a few sines) of the given peak amplitude: the shape of a fracture
// edge along its length `x` (mm).
class Wobble {
 public:
  Wobble(Rng& rng, double amplitude) {
    double total = 0.0;
    for (auto& w : waves_) {
      w = {rng.uniform(0.3, 1.0), 2.0 * kPi / rng.uniform(8.0, 45.0), rng.uniform(0.0, 2 * kPi)};
      total += w[0];
    }
    for (auto& w : waves_) w[0] *= amplitude / total;
  }
  double operator()(double x) const {
    double y = 0.0;
    for (const auto& w : waves_) y += w[0] * std::sin(w[1] * x + w[2]);
    return y;
  }

 private:
  std::array<std::array<double, 3>, 4> waves_{};  // amplitude, angular frequency, phase
};

// Sherd breaking. Fracture edges wander by at most kMaxCutWobbleMm across the profile and by
// kSideWander of the nominal arc on each side.
constexpr double kMinSherdMm = 30.0;        // smallest extent along the profile and around
constexpr double kMaxCutWobbleMm = 5.0;
constexpr double kCutClearanceMm = kMaxCutWobbleMm + 1.0;  // a wandering cut still misses it
constexpr double kSideWander = 0.12;
constexpr double kExtentMarginMm = 6.0;     // along-profile extent below max_extent (wander)
constexpr double kArcMarginMm = 8.0;        // arc length below max_extent (wander, thickness)
constexpr double kBaseCutFraction = 0.35;   // base cuts stay this far out from the axis (× s_wall)

// The smallest nominal arc fraction that keeps the kind's minimum after the side edges wander in.
double min_nominal_fraction(SherdKind kind) {
  double fraction = 0.05;
  if (kind == SherdKind::Rim) fraction = kMinRimPercent / 100.0;
  if (kind == SherdKind::Body) fraction = std::max(fraction, kMinBodyArcDeg / 360.0);
  return fraction / (1.0 - 2 * kSideWander);
}

// The range [min, max] of the sherd's length along the profile (mm) for which a sherd of `kind`
// fits this profile within max_extent_mm; nullopt where none does.
std::optional<std::pair<double, double>> along_profile_extent(const VesselProfile& profile,
                                                              SherdKind kind,
                                                              double max_extent_mm) {
  const double S = profile.total_arc();
  const double s_wall = profile.arc[profile.wall_start];
  // Never below kMinSherdMm, even where the slot is smaller (as documented for break_sherd).
  double lo = kMinSherdMm, hi = std::max(kMinSherdMm, max_extent_mm - kExtentMarginMm);
  switch (kind) {
    case SherdKind::Rim: {
      // The bottom cut must lie, wander included, where the outer wall is at least the target
      // height below the rim: below the first point where the wall rises above that level.
      // In a slot too small for that height, as tall as the slot allows.
      const double height = std::min(kMinRimHeightMm, hi - kMaxCutWobbleMm - 0.5);
      const double z_low_enough = profile.outer.back().y() - height;
      const auto& outer = profile.outer;
      std::size_t last = 0;
      while (last + 1 < outer.size() && outer[last + 1].y() <= z_low_enough) ++last;
      double s_rise = profile.arc[last];
      if (last + 1 < outer.size()) {  // where the wall crosses the level, between two samples
        s_rise += (z_low_enough - outer[last].y()) / (outer[last + 1].y() - outer[last].y()) *
                  (profile.arc[last + 1] - profile.arc[last]);
      }
      const double sa_max = s_rise - kMaxCutWobbleMm;
      if (sa_max < kBaseCutFraction * s_wall) return std::nullopt;  // too low a vessel
      lo = std::max(lo, S - sa_max);
      break;
    }
    case SherdKind::Base:
      // Up past the base angle, short of the rim.
      if (S - s_wall < 15.0 + kCutClearanceMm) return std::nullopt;
      break;
    case SherdKind::Body:
      hi = std::min(hi, S - s_wall - 2 * kCutClearanceMm);
      break;
  }
  if (lo > hi) return std::nullopt;
  return std::pair{lo, hi};
}

}  // namespace

const char* to_string(Family family) {
  switch (family) {
    case Family::Bowl: return "bowl";
    case Family::Plate: return "plate";
    case Family::Beaker: return "beaker";
    case Family::Jar: return "jar";
    case Family::Amphora: return "amphora";
  }
  return "unknown";
}

Family random_family(Rng& rng) { return static_cast<Family>(rng.integer(0, 4)); }

VesselProfile make_vessel_profile(Family family, Rng& rng, const VesselLimits& limits) {
  VesselProfile v;
  v.family = family;
  auto controls = wall_controls(family, rng);

  // Scale the whole shape down (never up) to the limits.
  double max_r = 0.0, height = controls.back().y();
  for (const auto& c : controls) max_r = std::max(max_r, c.x());
  const double scale =
      std::min({1.0, limits.max_diameter_mm / (2.0 * max_r), limits.max_height_mm / height});
  for (auto& c : controls) c *= scale;

  const double R = controls.back().x();
  const double t = rng.uniform(3.0, std::min(10.0, 3.0 + 0.035 * 2.0 * R));
  v.wall_thickness_mm = t;
  const double rb = controls.front().x();
  const double foot_width = t * rng.uniform(1.3, 1.8);
  v.ring_foot = (family == Family::Amphora || rng.chance(0.5)) && rb - foot_width > 8.0;
  const double foot_height = v.ring_foot ? rng.uniform(3.0, 7.0) : 0.0;
  // The ring foot lifts the body: the foot's outer face is the wall's first stretch.
  for (std::size_t i = 1; i < controls.size(); ++i) controls[i].y() += foot_height;

  const auto wall = resample_even(catmull_rom(controls), kSampleSpacingMm);
  std::vector<Point2> underside =
      v.ring_foot ? std::vector<Point2>{{0.0, foot_height},
                                        {rb - foot_width, foot_height},
                                        {rb - foot_width, 0.0},
                                        {rb, 0.0}}
                  : std::vector<Point2>{{0.0, 0.0}, {rb, 0.0}};
  underside = resample_keep_corners(underside, 2.0);

  // Inner wall: the outer wall offset into the material by t, clamped onto the floor where it
  // would dip below it (near the base the offset runs under the floor).
  const double floor_z = foot_height + t * rng.uniform(1.0, 1.4);
  std::vector<Point2> inner_wall;
  for (std::size_t i = 0; i < wall.size(); ++i) {
    const Point2 d = tangent_at(wall, i);
    Point2 q = wall[i] + t * Point2(-d.y(), d.x());
    q.y() = std::max(q.y(), floor_z);
    inner_wall.push_back(q);
  }
  // Floor samples correspond to underside samples by arc-length fraction.
  const auto under_arc = cumulative_length(underside);
  std::vector<Point2> floor;
  for (std::size_t i = 0; i + 1 < underside.size(); ++i) {
    const double f = under_arc[i] / under_arc.back();
    floor.push_back(Point2(0.0, floor_z) + f * (inner_wall.front() - Point2(0.0, floor_z)));
  }

  v.outer.assign(underside.begin(), underside.end() - 1);
  v.wall_start = v.outer.size();
  v.outer.insert(v.outer.end(), wall.begin(), wall.end());
  v.inner = floor;
  v.inner.insert(v.inner.end(), inner_wall.begin(), inner_wall.end());
  v.arc = cumulative_length(v.outer);

  // Rounded lip: a half-ellipse from the outer to the inner rim edge, bulging along the wall.
  const Point2 P = v.outer.back(), Q = v.inner.back();
  const Point2 d = tangent_at(v.outer, v.outer.size() - 1);
  const double bulge = 0.35 * t;
  constexpr int kLipSamples = 9;
  for (int k = 0; k < kLipSamples; ++k) {
    const double phi = kPi * k / (kLipSamples - 1);
    v.lip.push_back(P + 0.5 * (1.0 - std::cos(phi)) * (Q - P) + bulge * std::sin(phi) * d);
  }
  v.lip.back() = Q;
  return v;
}

std::vector<Point2> section_polyline(const VesselProfile& p) {
  std::vector<Point2> poly(p.outer.begin(), p.outer.end());
  poly.insert(poly.end(), p.lip.begin() + 1, p.lip.end() - 1);
  poly.insert(poly.end(), p.inner.rbegin(), p.inner.rend());
  return poly;
}

ClayColours random_clay(Rng& rng) {
  const double r = rng.uniform(140.0, 205.0);
  const double g = r * rng.uniform(0.55, 0.78);
  const double b = g * rng.uniform(0.55, 0.8);
  auto rgb = [](double x, double y, double z) {
    return Rgb8{static_cast<std::uint8_t>(clampd(x, 0, 255)),
                static_cast<std::uint8_t>(clampd(y, 0, 255)),
                static_cast<std::uint8_t>(clampd(z, 0, 255))};
  };
  const double inner = rng.uniform(0.85, 0.97);
  // The fired core is greyer and darker than the surfaces.
  const double grey = 100.0;
  // The texture is seeded from the tone's own draws (distinct per vessel), not from a further
  // draw: that would shift the random stream of every later part of every scene.
  const ClayTexture texture{.seed = std::bit_cast<std::uint64_t>(r) ^
                                    std::rotl(std::bit_cast<std::uint64_t>(g), 21) ^
                                    std::rotl(std::bit_cast<std::uint64_t>(b), 42),
                            .amplitude = kClayTextureAmplitude};
  return {rgb(r, g, b), rgb(r * inner, g * inner, b * inner),
          rgb(0.85 * (0.6 * r + 0.4 * grey), 0.85 * (0.6 * g + 0.4 * grey),
              0.85 * (0.6 * b + 0.4 * grey)),
          texture};
}

Rgb8 clay_colour(const Rgb8& base, const Vec3f& p, const ClayTexture& texture, Rng& rng) {
  const double k = texture_factor(p, texture) * rng.uniform(0.95, 1.05);
  auto ch = [k](std::uint8_t v) {
    return static_cast<std::uint8_t>(clampd(std::round(v * k), 0.0, 255.0));
  };
  return {ch(base.r), ch(base.g), ch(base.b)};
}

Mesh revolve_section(const std::vector<Point2>& poly, const std::vector<Rgb8>& colours,
                     Rng& rng, const ClayTexture& texture) {
  double max_r = 0.0;
  for (const auto& p : poly) max_r = std::max(max_r, p.x());
  const int n_theta =
      std::clamp(static_cast<int>(std::ceil(2 * kPi * max_r / kSampleSpacingMm)), 180, 720);

  Mesh mesh;
  std::vector<std::uint32_t> ring_start(poly.size());
  for (std::size_t j = 0; j < poly.size(); ++j) {
    ring_start[j] = static_cast<std::uint32_t>(mesh.vertices.points.size());
    const int n = poly[j].x() < 1e-9 ? 1 : n_theta;  // one vertex on the axis
    for (int k = 0; k < n; ++k) {
      add_clay_vertex(mesh, revolve(poly[j], 2 * kPi * k / n_theta), colours[j], texture, rng);
    }
  }
  // Ring j along the profile is `a`, angle is `b`: the normal e_θ × e_profile points to the
  // right of the profile's direction, away from the material.
  emit_grid(mesh, static_cast<int>(poly.size()), n_theta + 1, [&](int j, int k) {
    return poly[j].x() < 1e-9 ? ring_start[j] : ring_start[j] + k % n_theta;
  });
  compute_vertex_normals(mesh);
  return mesh;
}

Mesh revolve_vessel(const VesselProfile& profile, const ClayColours& colours, Rng& rng) {
  const auto poly = section_polyline(profile);
  std::vector<Rgb8> ring_colours(poly.size(), colours.outer);
  std::fill(ring_colours.end() - static_cast<std::ptrdiff_t>(profile.inner.size()),
            ring_colours.end(), colours.inner);
  return revolve_section(poly, ring_colours, rng, colours.texture);
}

const char* to_string(SherdKind kind) {
  switch (kind) {
    case SherdKind::Rim: return "rim";
    case SherdKind::Base: return "base";
    case SherdKind::Body: return "body";
  }
  return "unknown";
}

double max_vessel_diameter(SherdKind kind, double max_extent_mm) {
  // break_sherd's upper arc bound (max_extent − kArcMarginMm) / (2π r) stays above the kind's
  // lower one for every radius r of a vessel this narrow.
  return (max_extent_mm - kArcMarginMm) / (kPi * min_nominal_fraction(kind));
}

bool can_break(const VesselProfile& profile, SherdKind kind, double max_extent_mm) {
  return max_extent_mm >= kMinSherdMm && along_profile_extent(profile, kind, max_extent_mm);
}

SherdPiece break_sherd(const VesselProfile& profile, const ClayColours& colours, Rng& rng,
                       double max_extent_mm, SherdKind kind) {
  if (!(max_extent_mm >= kMinSherdMm)) {
    throw InputError(fmt::format(
        "sherd simulator: no room for a sherd ({:.0f} mm < {:.0f} mm): use fewer sherds per scene",
        max_extent_mm, kMinSherdMm));
  }
  const auto extent_range = along_profile_extent(profile, kind, max_extent_mm);
  if (!extent_range) {
    throw ProcessingError(fmt::format(
        "sherd simulator: a {} cannot give a {} sherd within {:.0f} mm: check can_break first",
        to_string(profile.family), to_string(kind), max_extent_mm));
  }
  const double S = profile.total_arc();
  const double s_wall = profile.arc[profile.wall_start];
  const double s_min = kBaseCutFraction * s_wall;
  const double extent = rng.uniform(extent_range->first, extent_range->second);

  // Where along the profile the piece lies (along_profile_extent made room for each case).
  double sa = 0.0, sb = 0.0;
  switch (kind) {
    case SherdKind::Rim:
      sb = S;
      sa = std::max(s_min, S - extent);
      break;
    case SherdKind::Base:
      // A base sherd keeps the base angle (the join of base and wall), as a real one must to be
      // recognised as such; a fragment of flat floor alone tells nothing about the vessel.
      sa = s_wall * rng.uniform(kBaseCutFraction, 0.7);
      sb = std::min(S - kCutClearanceMm, std::max(sa + extent, s_wall + 15.0));
      sa = std::max(sa, sb - extent);
      break;
    case SherdKind::Body:
      sa = rng.uniform(s_wall + kCutClearanceMm, S - kCutClearanceMm - extent);
      sb = sa + extent;
      break;
  }
  const bool has_rim = kind == SherdKind::Rim;

  auto outer_at = [&](double s) { return at_arc(profile.outer, profile.arc, s); };
  auto inner_at = [&](double s) { return at_arc(profile.inner, profile.arc, s); };

  // Angular range: from the kind's minimum (at least 5 %) to 50 % of the circumference including
  // the edges' wander, at least 30 mm around, and at most the extent limit where the widest part
  // of the piece allows.
  double r_ref = 1.0;
  for (double s = sa; s <= sb; s += 1.0) r_ref = std::max(r_ref, outer_at(s).x());
  const double f_lo = std::max(min_nominal_fraction(kind), kMinSherdMm / (2 * kPi * r_ref));
  const double f_hi = std::min(0.5 / (1.0 + 2 * kSideWander),
                               (max_extent_mm - kArcMarginMm) / (2 * kPi * r_ref));
  const double fraction = f_hi > f_lo ? rng.uniform(f_lo, f_hi) : f_lo;
  const double delta = 2 * kPi * fraction;

  // Fracture edges: the cuts across the profile wander along s with angle; the side breaks
  // wander in angle with height. Amplitudes of a few mm.
  auto amplitude = [&rng] { return rng.uniform(2.0, kMaxCutWobbleMm); };
  const Wobble bottom_cut(rng, amplitude()), top_cut(rng, amplitude());
  const Wobble left_cut(rng, amplitude()), right_cut(rng, amplitude());
  const double arc_len = delta * r_ref;
  auto s_of = [&](double u, double v) {
    const double lo = std::max(s_min * 0.85, sa + bottom_cut(v * arc_len));
    const double hi = has_rim ? S : std::min(S - 1.0, sb + top_cut(v * arc_len));
    return lo + u * (hi - lo);
  };
  auto theta_of = [&](double s, double v) {
    const double r = std::max(outer_at(s).x(), 10.0);
    const double cap = kSideWander * delta;
    const double left = -delta / 2 + clampd(left_cut(s) / r, -cap, cap);
    const double right = delta / 2 + clampd(right_cut(s) / r, -cap, cap);
    return left + v * (right - left);
  };

  const int nu = std::clamp(static_cast<int>(std::ceil((sb - sa) / kSampleSpacingMm)), 8, 200) + 1;
  const int nv = std::clamp(static_cast<int>(std::ceil(arc_len / kSampleSpacingMm)), 8, 300) + 1;
  std::vector<double> S_uv(static_cast<std::size_t>(nu) * nv), T_uv(S_uv.size());
  for (int i = 0; i < nu; ++i) {
    for (int j = 0; j < nv; ++j) {
      const double v = static_cast<double>(j) / (nv - 1);
      const double s = s_of(static_cast<double>(i) / (nu - 1), v);
      S_uv[i * nv + j] = s;
      T_uv[i * nv + j] = theta_of(s, v);
    }
  }
  // The material point at grid (i, j) and across-wall position w (0 outer, 1 inner).
  auto point = [&](int i, int j, int w) {
    const double s = S_uv[i * nv + j];
    return revolve(w == 0 ? outer_at(s) : inner_at(s), T_uv[i * nv + j]);
  };

  SherdPiece piece;
  Mesh& mesh = piece.mesh;
  // Each surface gets its own vertices (own colour; normals do not blend across the crease).
  // Grid roles (see emit_grid): (u, v, w) is a positively oriented parametrisation, so the
  // outward normal of each face is the cross product written next to it.
  auto skin = [&](int w, const Rgb8& colour) {
    const auto base = static_cast<std::uint32_t>(mesh.vertices.points.size());
    for (int i = 0; i < nu; ++i)
      for (int j = 0; j < nv; ++j)
        add_clay_vertex(mesh, point(i, j, w), colour, colours.texture, rng);
    auto idx = [&](int i, int j) { return base + static_cast<std::uint32_t>(i * nv + j); };
    if (w == 0) {
      emit_grid(mesh, nu, nv, [&](int u, int v) { return idx(u, v); });  // e_v × e_u
    } else {
      emit_grid(mesh, nv, nu, [&](int v, int u) { return idx(u, v); });  // e_u × e_v
    }
  };
  skin(0, colours.outer);
  skin(1, colours.inner);

  // Fracture face along a grid edge: a strip joining outer and inner straight across the wall.
  auto side = [&](int count, auto cell, bool along_first) {
    const auto base = static_cast<std::uint32_t>(mesh.vertices.points.size());
    for (int k = 0; k < count; ++k) {
      for (int w = 0; w < 2; ++w) {
        const auto [i, j] = cell(k);
        add_clay_vertex(mesh, point(i, j, w), colours.fracture, colours.texture, rng);
      }
    }
    auto idx = [&](int k, int w) { return base + static_cast<std::uint32_t>(2 * k + w); };
    if (along_first) {
      emit_grid(mesh, count, 2, idx);  // e_w × e_k
    } else {
      emit_grid(mesh, 2, count, [&](int w, int k) { return idx(k, w); });  // e_k × e_w
    }
  };
  using Cell = std::pair<int, int>;
  side(nu, [](int k) { return Cell{k, 0}; }, false);                 // v = 0: e_u × e_w
  side(nu, [&](int k) { return Cell{k, nv - 1}; }, true);            // v = 1: e_w × e_u
  side(nv, [](int k) { return Cell{0, k}; }, true);                  // u = 0: e_w × e_v
  if (!has_rim) side(nv, [&](int k) { return Cell{nu - 1, k}; }, false);  // u = 1: e_v × e_w
  if (has_rim) {
    // The lip replaces the top fracture: the lip section revolved over the rim's angles.
    const auto base = static_cast<std::uint32_t>(mesh.vertices.points.size());
    const int nl = static_cast<int>(profile.lip.size());
    for (int k = 0; k < nl; ++k) {
      for (int j = 0; j < nv; ++j) {
        add_clay_vertex(mesh, revolve(profile.lip[k], T_uv[(nu - 1) * nv + j]), colours.outer,
                        colours.texture, rng);
      }
    }
    emit_grid(mesh, nl, nv, [&](int k, int j) {  // e_v × e_w
      return base + static_cast<std::uint32_t>(k * nv + j);
    });
    // The broken ends of the lip: its half-ellipse section, closed by the side fracture's top
    // edge (the chord from outer to inner rim), fanned from the outer rim edge.
    for (int j : {0, nv - 1}) {
      const double theta = T_uv[(nu - 1) * nv + j];
      const Vec3f outward = (j == 0 ? -1.0f : 1.0f) *
                            Vec3f(static_cast<float>(-std::sin(theta)),
                                  static_cast<float>(std::cos(theta)), 0.0f);
      const auto first = static_cast<std::uint32_t>(mesh.vertices.points.size());
      for (int k = 0; k < nl; ++k) {
        add_clay_vertex(mesh, revolve(profile.lip[k], theta), colours.fracture, colours.texture,
                        rng);
      }
      for (int k = 1; k + 1 < nl; ++k) {
        Triangle t{first, first + k, first + k + 1};
        const auto& P = mesh.vertices.points;
        if ((P[t[1]] - P[t[0]]).cross(P[t[2]] - P[t[0]]).dot(outward) < 0) std::swap(t[1], t[2]);
        mesh.triangles.push_back(t);
      }
    }
  }
  compute_vertex_normals(mesh);

  piece.has_rim = has_rim;
  piece.has_base = sa < s_wall;
  const auto [t_min, t_max] = std::minmax_element(T_uv.begin(), T_uv.end());
  piece.arc_rad = *t_max - *t_min;
  piece.rim_arc_rad = has_rim ? T_uv[(nu - 1) * nv + nv - 1] - T_uv[(nu - 1) * nv] : 0.0;
  piece.z_min = 1e9;
  piece.z_max = -1e9;
  for (const auto& p : mesh.vertices.points) {
    piece.z_min = std::min(piece.z_min, static_cast<double>(p.z()));
    piece.z_max = std::max(piece.z_max, static_cast<double>(p.z()));
  }
  const double s_mid = 0.5 * (sa + sb);
  const Point2 d = (outer_at(s_mid + 0.5) - outer_at(s_mid - 0.5)).normalized();
  piece.centre_normal = Point2(d.y(), -d.x());
  return piece;
}

void compute_vertex_normals(Mesh& mesh) {
  auto& cloud = mesh.vertices;
  std::vector<Vec3d> acc(cloud.points.size(), Vec3d::Zero());
  for (const auto& t : mesh.triangles) {
    const Vec3d a = cloud.points[t[0]].cast<double>(), b = cloud.points[t[1]].cast<double>(),
                c = cloud.points[t[2]].cast<double>();
    const Vec3d n = (b - a).cross(c - a);  // length = twice the area: area weighting
    for (auto i : t) acc[i] += n;
  }
  cloud.normals.resize(cloud.points.size());
  for (std::size_t i = 0; i < acc.size(); ++i) {
    const double len = acc[i].norm();
    cloud.normals[i] = len > 0.0 ? Vec3f((acc[i] / len).cast<float>()) : Vec3f::UnitZ();
  }
}

double enclosed_volume(const Mesh& mesh) {
  double six_v = 0.0;
  for (const auto& t : mesh.triangles) {
    const Vec3d a = mesh.vertices.points[t[0]].cast<double>();
    const Vec3d b = mesh.vertices.points[t[1]].cast<double>();
    const Vec3d c = mesh.vertices.points[t[2]].cast<double>();
    six_v += a.dot(b.cross(c));
  }
  return six_v / 6.0;
}

}  // namespace sherd::sim
