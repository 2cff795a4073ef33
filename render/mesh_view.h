// Headless orthographic rendering of a mesh with the Lafortune BRDF (GLSL ES 3 on the shared EGL
// context): directional lights, the key light casting shadows (shadow map) so relief reads.
// Images larger than the GL's renderbuffer/viewport limits are drawn in tiles.
#pragma once

#include "core/types.h"
#include "render/egl_context.h"
#include "render/materials.h"

#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

namespace sherd::render {

struct DirectionalLight {
  Vec3d towards_light = Vec3d::UnitZ();  // view frame, need not be unit
  double intensity = 1.0;                // irradiance on a surface facing the light
  bool casts_shadow = false;             // at most one light casts shadows
};

struct Lighting {
  std::vector<DirectionalLight> lights;  // any number (up to the GL's texture width)
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
  // Pixels whose centres lie outside view x ∈ [keep_x_min_mm, keep_x_max_mm] stay empty (half
  // views; a scissor, exact to the pixel).
  double keep_x_min_mm = -std::numeric_limits<double>::infinity();
  double keep_x_max_mm = std::numeric_limits<double>::infinity();
};

// 8-bit RGBA, straight (not premultiplied) alpha, rows from the top; alpha 0 where empty.
// A 16-bit render fills rgba16 (0…65535) instead of rgba.
struct RgbaImage {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgba;
  std::vector<std::uint16_t> rgba16;
  const std::uint8_t* pixel(int column, int row_from_top) const {
    return rgba.data() + (static_cast<std::size_t>(row_from_top) * width + column) * 4;
  }
};

// Time spent in the last MeshRenderer::render (for bench/render).
struct RenderStats {
  double draw_s = 0.0;      // GL drawing, finished (glFinish)
  double readback_s = 0.0;  // glReadPixels and row order
  int tiles = 0;
};

// A mesh uploaded once (with its key light's shadow map) and drawn into any number of images
// that share the view direction: the bands of a large plate, or the tiles of one image. Holds
// the shared GL context for its lifetime; keep it short-lived. Throws like render_mesh.
class MeshRenderer {
 public:
  MeshRenderer(const Mesh& mesh, const LafortuneMaterial& material, const Pose& world_to_view,
               const Lighting& lighting);
  ~MeshRenderer();
  MeshRenderer(const MeshRenderer&) = delete;
  MeshRenderer& operator=(const MeshRenderer&) = delete;

  // The image `camera` frames (its world_to_view must be the renderer's). Drawn in tiles of at
  // most `max_tile_px` per side (0: the GL's renderbuffer/viewport limit); the result does not
  // depend on the tiling. `sixteen_bit`: drawn in half floats (EXT_color_buffer_float) and read
  // back into rgba16.
  RgbaImage render(const OrthoCamera& camera, int max_tile_px = 0, bool sixteen_bit = false);
  const RenderStats& last_stats() const { return stats_; }

 private:
  struct Gl;
  GlContextLock context_;
  std::unique_ptr<Gl> gl_;
  RenderStats stats_;
};

// Renders `mesh` (world frame). Vertex normals are used where present, else computed from the
// triangles; surfaces seen from behind are shaded on their visible side. A mesh without triangles
// is drawn as round points about one sample spacing wide. Throws sherd::InputError for an empty
// mesh or non-finite vertices, sherd::ProcessingError for a GL failure (e.g. out of memory).
RgbaImage render_mesh(const Mesh& mesh, const LafortuneMaterial& material,
                      const OrthoCamera& camera, const Lighting& lighting);

}  // namespace sherd::render
