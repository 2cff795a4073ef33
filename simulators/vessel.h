// Wheel-made vessels and their sherds, in the vessel frame: z along the axis of rotation from the
// base (z = 0 at the lowest point) to the rim, origin on the axis. Used by pottery.cpp to build
// scenes; public so tests can check the geometry against the profile it came from.
#pragma once

#include "core/types.h"
#include "simulators/random.h"

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace sherd::sim {

using Point2 = Eigen::Vector2d;  // (r, z) in the vessel's half-plane, mm

enum class Family { Bowl, Plate, Beaker, Jar, Amphora };
const char* to_string(Family family);

// The section of a vessel. `outer[j]` and `inner[j]` lie across the wall from each other (the
// inner wall is the outer wall offset inwards by the thickness; the floor sits above the
// underside), which is what lets a sherd's fracture faces join the two skins. Both run from the
// axis (j = 0, r = 0) through the base to the rim. The lip joins outer.back() to inner.back().
struct VesselProfile {
  Family family = Family::Bowl;
  double wall_thickness_mm = 0.0;
  bool ring_foot = false;
  std::vector<Point2> outer, inner;
  std::vector<double> arc;      // arc length of `outer` up to sample j (mm); the sherd cut parameter
  std::size_t wall_start = 0;   // first sample of the side wall (samples before it are the base)
  std::vector<Point2> lip;      // rounded lip, outer.back() … inner.back(), both ends included

  double rim_radius() const { return outer.back().x(); }
  double total_arc() const { return arc.back(); }
};

// Size limits for a vessel that must fit somewhere (the whole vessel scaled down if needed).
struct VesselLimits {
  double max_diameter_mm = 1e9;
  double max_height_mm = 1e9;
};

Family random_family(Rng& rng);
VesselProfile make_vessel_profile(Family family, Rng& rng, const VesselLimits& limits = {});

// The whole vessel's section as one polyline from the axis under the base, along the outside,
// over the lip and down the inside back to the axis: the boundary of the solid's half-section.
std::vector<Point2> section_polyline(const VesselProfile& profile);

// Real fired clay is not one flat tone: firing clouds, slip, stains and temper grains vary it over
// millimetres to centimetres. A ClayTexture is that variation as a smooth brightness factor fixed
// in the vessel frame (a function of position, seeded per vessel, so a sherd and the vessel it came
// from agree); amplitude 0 is a flat tone. Every vertex also gets a small random mottle.
struct ClayTexture {
  std::uint64_t seed = 0;
  double amplitude = 0.0;  // relative brightness variation (±, roughly)
};

// The colour `base` at vessel-frame position p: texture times mottle (one factor for all
// channels, so the tone keeps its hue).
Rgb8 clay_colour(const Rgb8& base, const Vec3f& p, const ClayTexture& texture, Rng& rng);

// Surface colours of one vessel (clay tone per vessel; fracture faces show the fired core).
struct ClayColours {
  Rgb8 outer, inner, fracture;
  ClayTexture texture;
};
ClayColours random_clay(Rng& rng);

// The surface of revolution of a section polyline that starts and ends on the axis (closed),
// outward normals when the material lies left of the polyline's direction in the (r, z) plane;
// `colours[j]` colours ring j, varied by `texture`. Repeat a point to keep a sharp crease there.
Mesh revolve_section(const std::vector<Point2>& section, const std::vector<Rgb8>& colours,
                     Rng& rng, const ClayTexture& texture = {});

// The closed surface of revolution of the vessel's section, coloured per surface.
Mesh revolve_vessel(const VesselProfile& profile, const ClayColours& colours, Rng& rng);

// What part of the vessel a sherd keeps: the rim with its lip (maybe down to the base), the base
// angle (the join of base and wall, not the rim), or neither — a piece of the wall alone.
enum class SherdKind { Rim, Base, Body };
const char* to_string(SherdKind kind);

// Minimum sizes that make a sherd worth measuring. Rim: its preserved rim arc (what rim percent
// and EVE count) and its height along the axis (enough profile to orient it and read the
// diameter). Body: enough arc that the wall's curvature shows. Base: 5 % of the circumference.
inline constexpr double kMinRimPercent = 10.0;
inline constexpr double kMinRimHeightMm = 25.0;
inline constexpr double kMinBodyArcDeg = 20.0;

// The widest vessel (diameter, mm) from which a sherd of this kind keeps its minimum arc without
// going past max_extent_mm around the axis: a limit for make_vessel_profile.
double max_vessel_diameter(SherdKind kind, double max_extent_mm);

// Whether the profile has room for a sherd of this kind within max_extent_mm (a rim sherd
// kMinRimHeightMm tall — or as tall as max_extent_mm allows, where that is less —, a base sherd
// that stops short of the rim, a body sherd clear of both).
bool can_break(const VesselProfile& profile, SherdKind kind, double max_extent_mm);

// A piece of the vessel between irregular fracture edges, in the vessel frame, centred on the
// angle θ = 0, of the given kind and at least its minimum size. Its extents (along the profile and
// around the axis) stay below max_extent_mm, except where 30 mm around the axis is longer.
// InputError below 30 mm, ProcessingError where can_break is false.
struct SherdPiece {
  Mesh mesh;                    // closed: outer and inner skin, lip or fracture faces
  bool has_rim = false, has_base = false;
  double arc_rad = 0.0;         // max θ − min θ over the piece
  double rim_arc_rad = 0.0;     // preserved arc of the rim (0 without rim)
  double z_min = 0.0, z_max = 0.0;  // preserved height range along the axis
  Point2 centre_normal{1.0, 0.0};   // outer-surface normal (r, z) at the piece's centre, θ = 0
};
SherdPiece break_sherd(const VesselProfile& profile, const ClayColours& colours, Rng& rng,
                       double max_extent_mm, SherdKind kind);

// Area-weighted vertex normals from the triangles (vertices shared only within one surface, so
// creases between surfaces stay sharp).
void compute_vertex_normals(Mesh& mesh);

// Volume enclosed by a closed, outward-oriented triangle mesh (divergence theorem), mm³.
double enclosed_volume(const Mesh& mesh);

}  // namespace sherd::sim
