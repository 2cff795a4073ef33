// Headless orthographic rendering of a mesh with the Lafortune BRDF (GLSL ES 3 on the shared EGL
// context): directional lights, the key light casting shadows (shadow map) so relief reads.
#pragma once

#include "core/types.h"
#include "render/materials.h"

#include <cstdint>
#include <limits>
#include <vector>

namespace sherd::render {

struct DirectionalLight {
  Vec3d towards_light = Vec3d::UnitZ();  // view frame, need not be unit
  double intensity = 1.0;                // irradiance on a surface facing the light
  bool casts_shadow = false;             // at most one light casts shadows
};

struct Lighting {
  std::vector<DirectionalLight> lights;  // at most 4
  double ambient = 0.0;                  // adds ambient × diffuse reflectance
  double exposure = 1.0;                 // radiance scale before display encoding
  bool srgb_encode = true;               // false: linear output (for measuring radiance)
};

// Drawing convention: key light from the upper left (casting shadows), a weaker fill from the
// right, a little ambient.
Lighting drawing_lighting();

// Orthographic camera. The view frame has x to the right, y up and z towards the viewer; pixel
// (column i, row j counted from the bottom) covers view x in [left_mm + i·pixel_mm, left_mm +
// (i+1)·pixel_mm), likewise y from bottom_mm: the scale is exact by construction.
struct OrthoCamera {
  Pose world_to_view = Pose::Identity();
  double left_mm = 0.0, bottom_mm = 0.0;
  double pixel_mm = 25.4 / 600.0;
  int width_px = 0, height_px = 0;
  // Fragments with view x outside [keep_x_min_mm, keep_x_max_mm] are discarded (half views).
  double keep_x_min_mm = -std::numeric_limits<double>::infinity();
  double keep_x_max_mm = std::numeric_limits<double>::infinity();
};

// 8-bit RGBA, straight (not premultiplied) alpha, rows from the top; alpha 0 where empty.
struct RgbaImage {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgba;
  const std::uint8_t* pixel(int column, int row_from_top) const {
    return rgba.data() + (static_cast<std::size_t>(row_from_top) * width + column) * 4;
  }
};

// Renders `mesh` (world frame). Vertex normals are used where present, else computed from the
// triangles; surfaces seen from behind are shaded on their visible side. A mesh without triangles
// is drawn as round points about one sample spacing wide. Throws sherd::InputError for an empty
// mesh or non-finite vertices, sherd::ProcessingError for an image larger than the GL allows or
// a GL failure.
RgbaImage render_mesh(const Mesh& mesh, const LafortuneMaterial& material,
                      const OrthoCamera& camera, const Lighting& lighting);

}  // namespace sherd::render
