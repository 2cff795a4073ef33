// A synthetic pottery world with ground truth: wheel-made vessels from profile families, broken
// into sherds with irregular fracture edges, placed at known poses in a holding frame or on the
// turntable plate. Deterministic from a seed. Millimetres, world = turntable frame (z up).
//
// Scenes: a plate (disk, radius 150 mm, top at z = 0) in the background colour, plus
//   Frame  — sherds standing on an edge in a low holding frame (8 mm plinths in the background
//            colour, each sherd sunk 5 mm into its own) on a ring of radius 95 mm, faces turned
//            radially, so that the turning plate shows both faces to a scanner from the side;
//   Plate  — sherds lying on the plate, outer face up or down, not touching;
//   Vessel — one complete vessel (bowl, plate, beaker or jar, ≤ 185 mm tall to stay in the
//            default scanner's view) standing near the plate centre;
//   Empty  — the plate and (when sherds > 0) the empty frame;
//   Calibration — the turntable calibration object (calibration::kCalibrationObject: a disc with
//            four spheres on posts) put down roughly centred, as an operator would; no truth
//            sherds (its truth is its description plus the placement in `calibration_placement`).
// A frame or plate tray of k sherds holds ⌈k/2⌉ rim sherds, max(1, k/4) base sherds from k = 3 on
// and body sherds in the rest, in an order shuffled by the seed (sizes: see break_sherd).
//
// truth.json (schema "sherdscan.truth/1"), the contract read by end-to-end tests and benchmarks:
//   schema, seed, scene ("frame"|"plate"|"vessel"|"empty"|"calibration"), background ("black"|"white"),
//   units: "mm", angles in degrees,
//   plate: {radius_mm, top_z_mm, colour: [r, g, b]}   (colour of plate and frame: the background)
//   sherds: [ one per sherd (or the vessel), in placement order:
//     id            "s01", …  (label k in SimulatedScanner::last_labels() is sherds[k-1])
//     family        bowl | plate | beaker | jar | amphora
//     complete      true for a whole vessel
//     has_rim, has_base   the piece keeps the rim (with its lip) / the base angle
//     axis: {point_mm, direction}   world frame; direction unit, from base towards rim; the point
//                   is the axis point nearest to centroid_mm (compare axes as lines, not points)
//     centroid_mm   mean of the piece's mesh vertices, world frame
//     bbox_mm       [[xmin, ymin, zmin], [xmax, ymax, zmax]], world frame
//     rim_diameter_mm   outer diameter at the top of the outer profile, where the outer wall
//                   meets the lip (2 × profile.outer's last r); null without rim
//     rim_percent   preserved rim arc of this jagged piece / 360 × 100; null without rim
//     wall_thickness_mm  the wall thickness (inner wall = outer wall offset by it)
//     arc_deg       angular extent of the piece about its axis (max θ − min θ of its vertices)
//     height_mm     preserved height along the axis (max z − min z in the sherd frame)
//     preserved_z_mm  [zmin, zmax] of the piece in the sherd frame (z = 0 at the vessel's base)
//     profile: {outer, inner}  the vessel's [[r, z], …] in the sherd frame, from the axis at the
//                   base (r = 0) to the rim; the rounded lip (≈ half an ellipse, height ≈ 0.35 ×
//                   wall thickness) joins their last points
//   ]
#pragma once

#include "core/types.h"
#include "simulators/vessel.h"

#include <nlohmann/json_fwd.hpp>

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace sherd::sim {

enum class SceneKind { Frame, Plate, Vessel, Empty, Calibration };
enum class Background { Black, White };

inline constexpr double kPlateRadiusMm = 150.0;
inline constexpr int kMaxSherds = 10;  // what a 300 mm plate holds without overlaps

const char* to_string(SceneKind kind);
const char* to_string(Background background);
// Parse "frame"|"plate"|"vessel"|"empty"|"calibration" and "black"|"white"; InputError otherwise.
SceneKind scene_kind_from_string(const std::string& name);
Background background_from_string(const std::string& name);
Rgb8 background_colour(Background background);

struct SceneSpec {
  std::uint64_t seed = 42;
  SceneKind kind = SceneKind::Frame;
  int sherds = 4;  // for Frame / Plate
  Background background = Background::Black;
};

// Ground truth of one sherd (or a complete vessel), as written to truth.json.
struct SherdTruth {
  std::string id;              // "s01", "s02", … in placement order
  std::string family;          // bowl | plate | beaker | jar | amphora
  Vec3d axis_point;            // on the axis, closest to the sherd's centroid, world frame
  Vec3d axis_direction;        // unit, world frame, from base towards rim
  bool has_rim = false;
  bool has_base = false;
  bool complete = false;       // a whole vessel
  std::optional<double> rim_diameter_mm;  // outer diameter at the rim (if the sherd has rim)
  std::optional<double> rim_percent;      // preserved rim arc / 360° × 100 (if it has rim)
  double wall_thickness_mm = 0.0;         // nominal wall thickness of the vessel body
  double arc_deg = 0.0;                   // angular extent of the sherd about its axis
  double height_mm = 0.0;                 // preserved height along the axis
  // Vessel profile in the sherd frame (r, z) in mm, z from the base (z = 0) to the rim.
  std::vector<std::array<double, 2>> outer_profile, inner_profile;
  Vec3d centroid = Vec3d::Zero();               // mean of the piece's vertices, world frame
  Box3 bbox;                                    // world frame
  std::array<double, 2> preserved_z_mm{0, 0};   // z range of the piece in the sherd frame
};

// A rigid body of the scene. Objects `on_plate` turn with the turntable; others (the table
// around it) stay. Colour per surface is in mesh.vertices.colours.
struct SceneObject {
  std::string name;      // "plate", "frame", "s01", …
  int label = 0;         // 0 = background, k ≥ 1 = truth[k-1]
  bool on_plate = true;
  Mesh mesh;             // world frame at turntable angle 0, outward normals
};

struct Scene {
  SceneSpec spec;
  std::vector<SceneObject> objects;
  std::vector<SherdTruth> truth;
  // Calibration scene: the object's pose on the plate (its frame: origin at the disc's centre on
  // the plate, z up) at turntable angle 0. Identity for the other scenes.
  Pose calibration_placement = Pose::Identity();
};

// Throws InputError for a sherd count outside 0…kMaxSherds.
Scene make_scene(const SceneSpec& spec);

// All objects merged into one mesh (world frame at turntable angle 0).
Mesh merged_mesh(const Scene& scene);

nlohmann::json truth_to_json(const Scene& scene);

// The kinds of sherd on a tray of `count`, in placement order: rim sherds in about half the
// places (at least one; two from three sherds on) because they are what gets measured most
// (diameter, EVE), a base from three sherds on (one in four beyond), body sherds in the rest —
// in an order shuffled by the seed.
std::vector<SherdKind> tray_kinds(int count, Rng& rng);

// A sherd of `kind` within max_extent_mm from a random vessel: families are drawn until one has
// room for that kind (a flat plate has no 25 mm of rim height, a short wall no body sherd).
struct BrokenVessel {
  VesselProfile profile;
  SherdPiece piece;
};
BrokenVessel break_random_vessel(SherdKind kind, double max_extent_mm, Rng& rng);

// Writes <dir>/scene.ply (all objects merged, colour + normals, binary) and <dir>/truth.json.
void write_scene(const Scene& scene, const std::filesystem::path& dir);

}  // namespace sherd::sim
