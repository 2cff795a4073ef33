// Plain value types shared by every part of sherdscan. Millimetres everywhere; no PCL here
// (PCL headers are slow to compile and stay inside processing/*.cpp).
#pragma once

#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace sherd {

using Vec3f = Eigen::Vector3f;
using Vec3d = Eigen::Vector3d;
using Pose = Eigen::Isometry3d;  // maps points of one frame into another (e.g. scanner → world)

struct Rgb8 {
  std::uint8_t r = 0, g = 0, b = 0;
  friend bool operator==(const Rgb8&, const Rgb8&) = default;
};

// An unorganised point set. `normals` and `colours` are either empty or the size of `points`.
// Normals, where present, are unit vectors pointing out of the material (towards where the
// surface was seen from).
struct Cloud {
  std::vector<Vec3f> points;
  std::vector<Vec3f> normals;
  std::vector<Rgb8> colours;

  std::size_t size() const { return points.size(); }
  bool empty() const { return points.empty(); }
  bool has_normals() const { return !normals.empty() && normals.size() == points.size(); }
  bool has_colours() const { return !colours.empty() && colours.size() == points.size(); }
  // Appends `other` (attributes kept only where both have them).
  void append(const Cloud& other);
  // The subset at `indices`, attributes included.
  Cloud subset(const std::vector<std::uint32_t>& indices) const;
  // Applies a rigid transform to points and normals.
  void transform(const Pose& pose);
};

using Triangle = std::array<std::uint32_t, 3>;

// A triangle mesh; `triangles` may be empty (then it is just a cloud).
struct Mesh {
  Cloud vertices;
  std::vector<Triangle> triangles;

  bool empty() const { return vertices.empty(); }
  // The sub-mesh on the given vertices: triangles with all three corners kept are kept.
  Mesh subset(const std::vector<std::uint32_t>& vertex_indices) const;
};

// Axis-aligned box in millimetres.
struct Box3 {
  Vec3d min = Vec3d::Constant(0.0), max = Vec3d::Constant(0.0);
  static Box3 of(const Cloud& cloud);
  Vec3d extent() const { return max - min; }
};

// One capture of the scanner: an organised grid (row-major, width × height) of points in the
// scanner frame, millimetres. Cells with valid[i] == 0 carry no measurement (their point is NaN).
struct OrganisedView {
  int width = 0, height = 0;
  std::vector<Vec3f> points;
  std::vector<Vec3f> normals;
  std::vector<Rgb8> colours;
  std::vector<std::uint8_t> valid;
  std::int64_t timestamp_ns = 0;  // capture time, UNIX epoch

  std::size_t cells() const { return static_cast<std::size_t>(width) * height; }
  std::size_t valid_count() const;
  // The valid cells as a cloud (same frame), and the organised-grid triangulation of neighbouring
  // valid cells whose depths do not jump by more than `max_edge_mm` (a depth discontinuity is an
  // occlusion boundary, not surface).
  Mesh to_mesh(float max_edge_mm) const;
  // Throws InputError, naming `part` and the view's `index`, when the arrays do not match
  // width × height or a valid cell is not finite.
  void check(std::string_view part, std::size_t index) const;
};

}  // namespace sherd
