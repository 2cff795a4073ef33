// A synthetic pottery world with ground truth: wheel-made vessels from profile families, broken
// into sherds with irregular fracture edges, placed at known poses in a holding frame or on the
// turntable plate. Deterministic from a seed. Millimetres, world = turntable frame (z up).
#pragma once

#include "core/types.h"

#include <nlohmann/json_fwd.hpp>

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace sherd::sim {

enum class SceneKind { Frame, Plate, Vessel, Empty };
enum class Background { Black, White };

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
};

Scene make_scene(const SceneSpec& spec);

nlohmann::json truth_to_json(const Scene& scene);

// Writes <dir>/scene.ply (all objects merged, colour + normals, binary) and <dir>/truth.json.
void write_scene(const Scene& scene, const std::filesystem::path& dir);

}  // namespace sherd::sim
