#include "render/mesh_view.h"

#include "core/errors.h"
#include "render/egl_context.h"

#include <GLES3/gl3.h>
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <string>

namespace sherd::render {
namespace {

constexpr int kShadowMapSize = 2048;

constexpr const char* kVertexShader = R"(#version 300 es
// Shadow pass: world → clip. Main pass: world → (pixel column, pixel row counted from the
// bottom of the whole image, clip z, 1); the tile's origin is subtracted exactly (whole pixels)
// and the viewport (−V/2, −V/2, V, V) with V a power of two maps x·2/V back to x exactly, so
// every tile rasterises at the same sample positions as one pass would.
uniform mat4 u_world_to_clip;
uniform bool u_tiled;
uniform vec2 u_tile_origin_px;
uniform float u_px_to_ndc;
uniform mat4 u_world_to_view;
uniform mat4 u_world_to_shadow_clip;
uniform float u_point_size;
in vec3 a_position;
in vec3 a_normal;
out vec3 v_view_position;
out vec3 v_view_normal;
out vec4 v_shadow_clip;
void main() {
  vec4 p = vec4(a_position, 1.0);
  v_view_position = (u_world_to_view * p).xyz;
  v_view_normal = mat3(u_world_to_view) * a_normal;
  v_shadow_clip = u_world_to_shadow_clip * p;
  gl_Position = u_world_to_clip * p;
  if (u_tiled) gl_Position.xy = (gl_Position.xy - u_tile_origin_px) * u_px_to_ndc;
  gl_PointSize = u_point_size;
}
)";

// pbrt's Lafortune evaluation (see config/materials.xml). The local frame has z = n; pbrt takes
// x from dp/du, but every preset is isotropic (Cx = Cy), and then
//   Cxy (wo.x wi.x + wo.y wi.y) = Cxy (wo·wi − wo.z wi.z)
// holds in any tangent frame, so no tangent is needed.
// Without `discard` in the shader (ROUND_POINTS undefined) llvmpipe can test depth before
// shading, which matters for a vessel's hidden inner wall: the half-view cut is a scissor.
constexpr const char* kFragmentShaderBody = R"(
precision highp float;
precision highp sampler2DShadow;
const int MAX_LOBES = 4;
const float PI = 3.14159265358979;
uniform vec3 u_diffuse;
uniform int u_lobe_count;
uniform vec3 u_cxy[MAX_LOBES];
uniform vec3 u_cz[MAX_LOBES];
uniform vec3 u_exponent[MAX_LOBES];
// Light i is texel (i, 0): unit direction towards the light (view frame), irradiance. A texture
// rather than a uniform array so that the number of lights has no small fixed bound.
uniform highp sampler2D u_lights;
uniform int u_light_count;
uniform int u_shadow_light;
uniform sampler2DShadow u_shadow_map;
uniform float u_ambient;
uniform float u_exposure;
uniform bool u_srgb_encode;
in vec3 v_view_position;
in vec3 v_view_normal;
in vec4 v_shadow_clip;
out vec4 o_colour;

float clamped_pow(float base, float exponent) {
  return base > 0.0 ? pow(base, exponent) : 0.0;  // pbrt: negative lobe bases contribute 0
}

vec3 lafortune(vec3 n, vec3 wo, vec3 wi) {
  float cos_o = dot(n, wo);
  float cos_i = dot(n, wi);
  float tangential = dot(wo, wi) - cos_o * cos_i;
  vec3 f = u_diffuse / PI;
  for (int i = 0; i < u_lobe_count; ++i) {
    vec3 base = u_cxy[i] * tangential + u_cz[i] * (cos_o * cos_i);
    f += vec3(clamped_pow(base.r, u_exponent[i].r), clamped_pow(base.g, u_exponent[i].g),
              clamped_pow(base.b, u_exponent[i].b));
  }
  return f;
}

float key_light_visibility() {
  // One comparison tap: with linear filtering on a depth texture it is a bilinear 2×2
  // percentage-closer filter, enough for soft-edged shadows at one texel.
  vec3 p = v_shadow_clip.xyz / v_shadow_clip.w * 0.5 + 0.5;
  return texture(u_shadow_map, p);
}

void main() {
#ifdef ROUND_POINTS
  if (length(gl_PointCoord - 0.5) > 0.5) discard;
#endif
  vec3 wo = vec3(0.0, 0.0, 1.0);  // orthographic: the viewer is along +z everywhere
  vec3 n = normalize(v_view_normal);
  if (dot(n, wo) < 0.0) n = -n;   // a surface seen from behind is shaded on its visible side
  vec3 radiance = u_ambient * u_diffuse;
  for (int i = 0; i < u_light_count; ++i) {
    vec4 light = texelFetch(u_lights, ivec2(i, 0), 0);
    vec3 wi = light.xyz;
    float cos_i = dot(n, wi);
    if (cos_i <= 0.0) continue;   // wo and wi on opposite sides: no reflection
    float visibility = i == u_shadow_light ? key_light_visibility() : 1.0;
    radiance += lafortune(n, wo, wi) * (cos_i * light.w * visibility);
  }
  vec3 colour = clamp(radiance * u_exposure, 0.0, 1.0);
  if (u_srgb_encode) colour = pow(colour, vec3(1.0 / 2.2));
  o_colour = vec4(colour, 1.0);
}
)";

constexpr const char* kShadowFragmentShader = R"(#version 300 es
precision mediump float;
void main() {}
)";

void check_gl(const char* what) {
  if (GLenum error = glGetError(); error != GL_NO_ERROR)
    throw ProcessingError(fmt::format("render: OpenGL error 0x{:x} during {}", error, what));
}

// RAII names for GL objects, so that an exception mid-render leaks nothing in the shared context.
template <void (*Delete)(GLsizei, const GLuint*)>
struct GlNames {
  GLuint id = 0;
  ~GlNames() {
    if (id) Delete(1, &id);
  }
};
void delete_buffers(GLsizei n, const GLuint* ids) { glDeleteBuffers(n, ids); }
void delete_textures(GLsizei n, const GLuint* ids) { glDeleteTextures(n, ids); }
void delete_framebuffers(GLsizei n, const GLuint* ids) { glDeleteFramebuffers(n, ids); }
void delete_renderbuffers(GLsizei n, const GLuint* ids) { glDeleteRenderbuffers(n, ids); }
void delete_vertex_arrays(GLsizei n, const GLuint* ids) { glDeleteVertexArrays(n, ids); }
using Buffer = GlNames<delete_buffers>;
using Texture = GlNames<delete_textures>;
using Framebuffer = GlNames<delete_framebuffers>;
using Renderbuffer = GlNames<delete_renderbuffers>;
using VertexArray = GlNames<delete_vertex_arrays>;

struct Program {
  GLuint id = 0;
  ~Program() {
    if (id) glDeleteProgram(id);
  }
  GLint uniform(const char* name) const { return glGetUniformLocation(id, name); }
};

GLuint compile(GLenum type, const char* source) {
  GLuint shader = glCreateShader(type);
  glShaderSource(shader, 1, &source, nullptr);
  glCompileShader(shader);
  GLint ok = 0;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    std::array<char, 4096> log{};
    glGetShaderInfoLog(shader, log.size(), nullptr, log.data());
    glDeleteShader(shader);
    throw ProcessingError(fmt::format("render: shader compilation failed: {}", log.data()));
  }
  return shader;
}

void link(Program& program, const char* vertex_source, const char* fragment_source) {
  GLuint vertex = compile(GL_VERTEX_SHADER, vertex_source);
  GLuint fragment = 0;
  try {
    fragment = compile(GL_FRAGMENT_SHADER, fragment_source);
  } catch (...) {
    glDeleteShader(vertex);
    throw;
  }
  program.id = glCreateProgram();
  glAttachShader(program.id, vertex);
  glAttachShader(program.id, fragment);
  glBindAttribLocation(program.id, 0, "a_position");
  glBindAttribLocation(program.id, 1, "a_normal");
  glLinkProgram(program.id);
  glDeleteShader(vertex);
  glDeleteShader(fragment);
  GLint ok = 0;
  glGetProgramiv(program.id, GL_LINK_STATUS, &ok);
  if (!ok) {
    std::array<char, 4096> log{};
    glGetProgramInfoLog(program.id, log.size(), nullptr, log.data());
    throw ProcessingError(fmt::format("render: shader link failed: {}", log.data()));
  }
}

// Maps the box [x0,x1]×[y0,y1]×[z0,z1] of a frame (z towards the viewer) onto clip space, the
// nearest z to depth −1.
Eigen::Matrix4f orthographic(double x0, double x1, double y0, double y1, double z0, double z1) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m(0, 0) = 2.0 / (x1 - x0);
  m(0, 3) = -(x1 + x0) / (x1 - x0);
  m(1, 1) = 2.0 / (y1 - y0);
  m(1, 3) = -(y1 + y0) / (y1 - y0);
  m(2, 2) = -2.0 / (z1 - z0);
  m(2, 3) = (z1 + z0) / (z1 - z0);
  return m.cast<float>();
}

std::vector<Vec3f> vertex_normals(const Mesh& mesh) {
  if (mesh.vertices.has_normals()) return mesh.vertices.normals;
  std::vector<Vec3f> normals(mesh.vertices.size(), Vec3f::Zero());
  for (const Triangle& t : mesh.triangles) {
    const Vec3f& a = mesh.vertices.points[t[0]];
    // Unnormalised cross product: larger triangles weigh more.
    const Vec3f n = (mesh.vertices.points[t[1]] - a).cross(mesh.vertices.points[t[2]] - a);
    for (std::uint32_t v : t) normals[v] += n;
  }
  for (Vec3f& n : normals) n = n.squaredNorm() > 0.f ? n.normalized() : Vec3f::UnitZ();
  return normals;
}

void validate_mesh(const Mesh& mesh, const Lighting& lighting) {
  if (mesh.empty()) throw InputError("render: the mesh to render has no vertices");
  for (const Vec3f& p : mesh.vertices.points)
    if (!p.allFinite())
      throw InputError(
          "render: the mesh has a non-finite vertex (NaN/inf); remove invalid "
          "points before rendering");
  const auto n = static_cast<std::uint32_t>(mesh.vertices.size());
  for (const Triangle& t : mesh.triangles)
    if (t[0] >= n || t[1] >= n || t[2] >= n)
      throw InputError(fmt::format("render: a triangle refers to vertex {} of a {}-vertex mesh",
                                   std::max({t[0], t[1], t[2]}), n));
  if (std::count_if(lighting.lights.begin(), lighting.lights.end(),
                    [](const DirectionalLight& l) { return l.casts_shadow; }) > 1)
    throw InputError("render: at most one light may cast shadows");
  for (const DirectionalLight& light : lighting.lights)
    if (!light.towards_light.allFinite() || light.towards_light.squaredNorm() == 0.0 ||
        !std::isfinite(light.intensity))
      throw InputError("render: a light has no direction or a non-finite intensity");
}

void validate_camera(const OrthoCamera& camera) {
  if (camera.width_px <= 0 || camera.height_px <= 0 || !(camera.pixel_mm > 0.0))
    throw InputError(fmt::format("render: bad image size {}×{} px at {} mm/px", camera.width_px,
                                 camera.height_px, camera.pixel_mm));
}

// Compiled once per process: the context lives as long as the process, and compiling costs
// more than a small render on llvmpipe. Only called with the context current (lock held).
// Never destroyed: at exit no context is current to delete them in.
const Program& shading_program(bool round_points) {
  static Program& for_triangles = *new Program;
  static Program& for_points = *new Program;
  Program& program = round_points ? for_points : for_triangles;
  if (!program.id) {
    const std::string source = std::string("#version 300 es\n") +
                               (round_points ? "#define ROUND_POINTS\n" : "") + kFragmentShaderBody;
    link(program, kVertexShader, source.c_str());
  }
  return program;
}

const Program& shadow_program() {
  static Program& program = *new Program;
  if (!program.id) link(program, kVertexShader, kShadowFragmentShader);
  return program;
}

struct MeshBuffers {
  VertexArray vao;
  Buffer positions, normals, indices;
  GLsizei vertex_count = 0;
};

// A triangle mesh's triangles ordered for one view, nearest first, with their extents in the
// view (mm). Nearest first lets llvmpipe's early depth test skip shading what lies behind (a
// vessel's far wall and inside): each visible pixel is shaded about once rather than once per
// layer drawn before the nearest one (−25 % CPU on bench_render's plate). The extents let a band
// or tile draw only the triangles that can reach it; a culled triangle has no fragment there,
// so the pixels are the same as drawing them all.
struct ViewTriangles {
  std::vector<Triangle> triangles;
  std::vector<Eigen::AlignedBox2f> extents;
};

ViewTriangles nearest_first(const Mesh& mesh, const Pose& world_to_view) {
  std::vector<Vec3f> view(mesh.vertices.size());
  const Eigen::Affine3f to_view = world_to_view.cast<float>();
  for (std::size_t i = 0; i < view.size(); ++i) view[i] = to_view * mesh.vertices.points[i];
  // Sort key: view z of the centroid (z points towards the viewer), largest first.
  std::vector<std::pair<float, std::uint32_t>> order(mesh.triangles.size());
  for (std::size_t i = 0; i < order.size(); ++i) {
    const Triangle& t = mesh.triangles[i];
    order[i] = {-(view[t[0]].z() + view[t[1]].z() + view[t[2]].z()), static_cast<std::uint32_t>(i)};
  }
  std::sort(order.begin(), order.end());
  ViewTriangles sorted;
  sorted.triangles.reserve(order.size());
  sorted.extents.reserve(order.size());
  for (const auto& [key, i] : order) {
    const Triangle& t = mesh.triangles[i];
    sorted.triangles.push_back(t);
    Eigen::AlignedBox2f extent(view[t[0]].head<2>());
    extent.extend(view[t[1]].head<2>());
    extent.extend(view[t[2]].head<2>());
    sorted.extents.push_back(extent);
  }
  return sorted;
}

void upload(const Mesh& mesh, MeshBuffers& buffers) {
  const std::vector<Vec3f> normals = vertex_normals(mesh);
  glGenVertexArrays(1, &buffers.vao.id);
  glBindVertexArray(buffers.vao.id);
  glGenBuffers(1, &buffers.positions.id);
  glBindBuffer(GL_ARRAY_BUFFER, buffers.positions.id);
  glBufferData(GL_ARRAY_BUFFER, mesh.vertices.points.size() * sizeof(Vec3f),
               mesh.vertices.points.data(), GL_STATIC_DRAW);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, sizeof(Vec3f), nullptr);
  glEnableVertexAttribArray(0);
  glGenBuffers(1, &buffers.normals.id);
  glBindBuffer(GL_ARRAY_BUFFER, buffers.normals.id);
  glBufferData(GL_ARRAY_BUFFER, normals.size() * sizeof(Vec3f), normals.data(), GL_STATIC_DRAW);
  glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, sizeof(Vec3f), nullptr);
  glEnableVertexAttribArray(1);
  buffers.vertex_count = static_cast<GLsizei>(mesh.vertices.size());
  if (!mesh.triangles.empty()) glGenBuffers(1, &buffers.indices.id);  // filled per draw
  check_gl("vertex upload");
}

// Draws `triangles`, or the points when the mesh has no triangles.
void draw(const MeshBuffers& buffers, const std::vector<Triangle>& triangles) {
  glBindVertexArray(buffers.vao.id);
  if (!buffers.indices.id) {
    glDrawArrays(GL_POINTS, 0, buffers.vertex_count);
    return;
  }
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, buffers.indices.id);
  glBufferData(GL_ELEMENT_ARRAY_BUFFER, triangles.size() * sizeof(Triangle), triangles.data(),
               GL_STREAM_DRAW);
  glDrawElements(GL_TRIANGLES, static_cast<GLsizei>(triangles.size() * 3), GL_UNSIGNED_INT,
                 nullptr);
}

// Sample spacing of a point set, for the point size: its points spread over roughly the two
// largest extents of its bounding box. A coarse estimate, good enough to close the gaps.
double point_spacing_mm(const Cloud& cloud) {
  Vec3d e = Box3::of(cloud).extent();
  std::sort(e.data(), e.data() + 3);
  return std::sqrt(std::max(e[2] * e[1], 1e-6) / static_cast<double>(cloud.size()));
}

// Points are drawn about 1.5 sample spacings wide (clamped to what GL ES guarantees).
float point_size_px(double spacing_mm, double pixel_mm) {
  return static_cast<float>(std::clamp(1.5 * spacing_mm / pixel_mm, 1.0, 64.0));
}

// The key light's shadow map: depth of the mesh seen along the light, orthographic over the
// mesh's bounding sphere. Returns world → shadow clip.
Eigen::Matrix4f render_shadow_map(const Mesh& mesh, const MeshBuffers& buffers,
                                  const std::vector<Triangle>& triangles, const Pose& world_to_view,
                                  const Vec3d& towards_light_view, double point_spacing,
                                  Texture& depth) {
  const Box3 box = Box3::of(mesh.vertices);
  const Vec3d centre = 0.5 * (box.min + box.max);
  const double radius = std::max(0.5 * box.extent().norm(), 1e-3);
  // Light frame: z towards the light, any x ⟂ z.
  const Vec3d z = (world_to_view.linear().transpose() * towards_light_view).normalized();
  const Vec3d x = z.unitOrthogonal();
  Eigen::Matrix4d world_to_light = Eigen::Matrix4d::Identity();
  world_to_light.block<1, 3>(0, 0) = x.transpose();
  world_to_light.block<1, 3>(1, 0) = z.cross(x).transpose();
  world_to_light.block<1, 3>(2, 0) = z.transpose();
  world_to_light.block<3, 1>(0, 3) = -world_to_light.block<3, 3>(0, 0) * centre;
  const Eigen::Matrix4f world_to_shadow_clip =
      orthographic(-radius, radius, -radius, radius, -radius, radius) *
      world_to_light.cast<float>();

  glGenTextures(1, &depth.id);
  glBindTexture(GL_TEXTURE_2D, depth.id);
  glTexStorage2D(GL_TEXTURE_2D, 1, GL_DEPTH_COMPONENT32F, kShadowMapSize, kShadowMapSize);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_MODE, GL_COMPARE_REF_TO_TEXTURE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_FUNC, GL_LEQUAL);
  Framebuffer fbo;
  glGenFramebuffers(1, &fbo.id);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo.id);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, depth.id, 0);
  const GLenum none = GL_NONE;
  glDrawBuffers(1, &none);
  if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    throw ProcessingError("render: the shadow-map framebuffer is incomplete");

  const Program& program = shadow_program();
  glUseProgram(program.id);
  glUniformMatrix4fv(program.uniform("u_world_to_clip"), 1, GL_FALSE, world_to_shadow_clip.data());
  glUniform1f(program.uniform("u_point_size"),
              point_size_px(point_spacing, 2.0 * radius / kShadowMapSize));
  glUniform1i(program.uniform("u_tiled"), 0);
  glViewport(0, 0, kShadowMapSize, kShadowMapSize);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glClear(GL_DEPTH_BUFFER_BIT);
  // Slope-scaled offset pushes the stored depth behind the surface: no self-shadowing acne.
  glEnable(GL_POLYGON_OFFSET_FILL);
  glPolygonOffset(2.0f, 4.0f);
  draw(buffers, triangles);
  glDisable(GL_POLYGON_OFFSET_FILL);
  check_gl("shadow pass");
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  return world_to_shadow_clip;
}

// The lights as one RGBA32F texel each (see u_lights in the fragment shader).
void upload_lights(const Lighting& lighting, Texture& texture) {
  GLint max_texture = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_texture);
  if (lighting.lights.size() > static_cast<std::size_t>(max_texture))
    throw InputError(fmt::format("render: {} lights; this GL takes at most {}",
                                 lighting.lights.size(), max_texture));
  std::vector<GLfloat> texels(4 * std::max<std::size_t>(lighting.lights.size(), 1), 0.f);
  for (std::size_t i = 0; i < lighting.lights.size(); ++i) {
    const Vec3d d = lighting.lights[i].towards_light.normalized();
    texels[4 * i] = static_cast<GLfloat>(d.x());
    texels[4 * i + 1] = static_cast<GLfloat>(d.y());
    texels[4 * i + 2] = static_cast<GLfloat>(d.z());
    texels[4 * i + 3] = static_cast<GLfloat>(lighting.lights[i].intensity);
  }
  glGenTextures(1, &texture.id);
  glBindTexture(GL_TEXTURE_2D, texture.id);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, static_cast<GLsizei>(texels.size() / 4), 1, 0, GL_RGBA,
               GL_FLOAT, texels.data());
  // Float textures are not filterable in ES 3: nearest, read with texelFetch anyway.
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  check_gl("light upload");
}

void set_material_uniforms(const Program& program, const LafortuneMaterial& material) {
  auto rgb = [](const RgbCoefficients& c) {
    return std::array<GLfloat, 3>{static_cast<GLfloat>(c[0]), static_cast<GLfloat>(c[1]),
                                  static_cast<GLfloat>(c[2])};
  };
  std::array<std::array<GLfloat, 3>, kMaxLafortuneLobes> cxy{}, cz{}, exponent{};
  for (std::size_t i = 0; i < material.lobes.size(); ++i) {
    cxy[i] = rgb(material.lobes[i].cxy);
    cz[i] = rgb(material.lobes[i].cz);
    exponent[i] = rgb(material.lobes[i].exponent);
  }
  glUniform3fv(program.uniform("u_diffuse"), 1, rgb(material.diffuse).data());
  glUniform1i(program.uniform("u_lobe_count"), static_cast<GLint>(material.lobes.size()));
  glUniform3fv(program.uniform("u_cxy"), kMaxLafortuneLobes, cxy[0].data());
  glUniform3fv(program.uniform("u_cz"), kMaxLafortuneLobes, cz[0].data());
  glUniform3fv(program.uniform("u_exponent"), kMaxLafortuneLobes, exponent[0].data());
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

Lighting drawing_lighting() {
  Lighting lighting;
  lighting.lights = {{Vec3d(-1.0, 1.0, 1.2), 2.4, true}, {Vec3d(1.0, 0.2, 0.8), 0.8, false}};
  lighting.ambient = 0.35;
  lighting.exposure = 1.0;
  return lighting;
}

struct MeshRenderer::Gl {
  MeshBuffers buffers;
  ViewTriangles triangles;        // empty for a point set
  std::vector<Triangle> in_tile;  // the triangles drawn into the current tile
  Texture shadow_map, lights;
  Eigen::Matrix4f world_to_shadow_clip = Eigen::Matrix4f::Identity();
  int shadow_light = -1;
  Pose world_to_view = Pose::Identity();
  double z_min = 0.0, z_max = 0.0;  // depth range of the mesh in the view, padded
  double point_spacing = 0.0;       // 0 for triangle meshes
  int max_tile = 0;                 // the GL's renderbuffer and viewport limit
  Lighting lighting;
  LafortuneMaterial material;
};

MeshRenderer::MeshRenderer(const Mesh& mesh, const LafortuneMaterial& material,
                           const Pose& world_to_view, const Lighting& lighting)
    : gl_(std::make_unique<Gl>()) {
  validate_mesh(mesh, lighting);
  if (material.lobes.size() > kMaxLafortuneLobes)
    throw InputError(fmt::format("render: material '{}' has more than {} lobes", material.name,
                                 kMaxLafortuneLobes));
  Gl& gl = *gl_;
  gl.world_to_view = world_to_view;
  gl.lighting = lighting;
  gl.material = material;
  GLint max_size = 0, max_viewport[2] = {0, 0};
  glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_size);
  glGetIntegerv(GL_MAX_VIEWPORT_DIMS, max_viewport);
  // Tiles are drawn through a viewport twice their size (see u_tiled) and sized in powers of two.
  const int limit = std::min({max_size, max_viewport[0] / 2, max_viewport[1] / 2});
  gl.max_tile = 1;
  while (gl.max_tile * 2 <= limit) gl.max_tile *= 2;

  upload(mesh, gl.buffers);
  gl.triangles = nearest_first(mesh, world_to_view);
  upload_lights(lighting, gl.lights);
  if (mesh.triangles.empty()) gl.point_spacing = point_spacing_mm(mesh.vertices);
  gl.z_min = std::numeric_limits<double>::infinity();
  gl.z_max = -gl.z_min;
  for (const Vec3f& p : mesh.vertices.points) {
    const double z = (world_to_view * p.cast<double>()).z();
    gl.z_min = std::min(gl.z_min, z);
    gl.z_max = std::max(gl.z_max, z);
  }
  // Padded so that nothing is clipped by the near/far planes.
  const double pad = 1.0 + 0.01 * (gl.z_max - gl.z_min);
  gl.z_min -= pad;
  gl.z_max += pad;

  for (std::size_t i = 0; i < lighting.lights.size(); ++i)
    if (lighting.lights[i].casts_shadow) {
      gl.shadow_light = static_cast<int>(i);
      gl.world_to_shadow_clip =
          render_shadow_map(mesh, gl.buffers, gl.triangles.triangles, world_to_view,
                            lighting.lights[i].towards_light, gl.point_spacing, gl.shadow_map);
    }
  if (gl.shadow_light < 0) {
    // The sampler must still be complete: a 1×1 map at depth 1 lights everything.
    glGenTextures(1, &gl.shadow_map.id);
    glBindTexture(GL_TEXTURE_2D, gl.shadow_map.id);
    const float far = 1.0f;
    glTexImage2D(GL_TEXTURE_2D, 0, GL_DEPTH_COMPONENT32F, 1, 1, 0, GL_DEPTH_COMPONENT, GL_FLOAT,
                 &far);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_MODE, GL_COMPARE_REF_TO_TEXTURE);
  }
  check_gl("renderer set-up");
}

MeshRenderer::~MeshRenderer() = default;

namespace {

bool has_gl_extension(const char* name) {
  GLint count = 0;
  glGetIntegerv(GL_NUM_EXTENSIONS, &count);
  for (GLint i = 0; i < count; ++i)
    if (std::strcmp(reinterpret_cast<const char*>(glGetStringi(GL_EXTENSIONS, i)), name) == 0)
      return true;
  return false;
}

}  // namespace

RgbaImage MeshRenderer::render(const OrthoCamera& camera, int max_tile_px, bool sixteen_bit) {
  validate_camera(camera);
  Gl& gl = *gl_;
  if (!camera.world_to_view.isApprox(gl.world_to_view, 1e-12))
    throw ProcessingError("render: a camera with another view direction than the renderer's");
  const int tile = max_tile_px > 0 ? std::min(max_tile_px, gl.max_tile) : gl.max_tile;
  const int tile_w = std::min(tile, camera.width_px), tile_h = std::min(tile, camera.height_px);
  stats_ = {};

  Renderbuffer colour, depth;
  Framebuffer fbo;
  glGenRenderbuffers(1, &colour.id);
  glBindRenderbuffer(GL_RENDERBUFFER, colour.id);
  if (sixteen_bit && !has_gl_extension("GL_EXT_color_buffer_float"))
    throw ProcessingError(
        "render: 16-bit output needs GL_EXT_color_buffer_float, which this GL lacks; write 8-bit");
  glRenderbufferStorage(GL_RENDERBUFFER, sixteen_bit ? GL_RGBA16F : GL_RGBA8, tile_w, tile_h);
  glGenRenderbuffers(1, &depth.id);
  glBindRenderbuffer(GL_RENDERBUFFER, depth.id);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, tile_w, tile_h);
  glGenFramebuffers(1, &fbo.id);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo.id);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, colour.id);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth.id);
  if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    throw ProcessingError(
        fmt::format("render: a {}×{} px framebuffer is incomplete (out of memory?); lower the dpi",
                    tile_w, tile_h));

  const Program& program = shading_program(gl.point_spacing > 0);
  glUseProgram(program.id);
  const Eigen::Matrix4f world_to_view = gl.world_to_view.matrix().cast<float>();
  glUniformMatrix4fv(program.uniform("u_world_to_view"), 1, GL_FALSE, world_to_view.data());
  glUniformMatrix4fv(program.uniform("u_world_to_shadow_clip"), 1, GL_FALSE,
                     gl.world_to_shadow_clip.data());
  glUniform1f(program.uniform("u_point_size"),
              gl.point_spacing > 0 ? point_size_px(gl.point_spacing, camera.pixel_mm) : 1.0f);
  set_material_uniforms(program, gl.material);
  glUniform1i(program.uniform("u_light_count"), static_cast<GLint>(gl.lighting.lights.size()));
  glUniform1i(program.uniform("u_shadow_light"), gl.shadow_light);
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, gl.shadow_map.id);
  glUniform1i(program.uniform("u_shadow_map"), 0);
  glActiveTexture(GL_TEXTURE1);
  glBindTexture(GL_TEXTURE_2D, gl.lights.id);
  glUniform1i(program.uniform("u_lights"), 1);
  glActiveTexture(GL_TEXTURE0);
  glUniform1f(program.uniform("u_ambient"), static_cast<GLfloat>(gl.lighting.ambient));
  glUniform1f(program.uniform("u_exposure"), static_cast<GLfloat>(gl.lighting.exposure));
  glUniform1i(program.uniform("u_srgb_encode"), gl.lighting.srgb_encode);
  // Columns whose pixel centres lie within [keep_x_min_mm, keep_x_max_mm].
  const auto column_of = [&](double x_mm) {
    return std::clamp((x_mm - camera.left_mm) / camera.pixel_mm - 0.5, -1.0,
                      static_cast<double>(camera.width_px));
  };
  const int keep_from = static_cast<int>(std::ceil(column_of(camera.keep_x_min_mm)));
  const int keep_to = static_cast<int>(std::floor(column_of(camera.keep_x_max_mm))) + 1;
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDisable(GL_CULL_FACE);  // sherds are open shells: both sides of a triangle can be seen
  glClearColor(0.f, 0.f, 0.f, 0.f);
  glClearDepthf(1.f);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);

  RgbaImage image;
  image.width = camera.width_px;
  image.height = camera.height_px;
  const std::size_t samples = static_cast<std::size_t>(image.width) * image.height * 4;
  (sixteen_bit ? image.rgba16.resize(samples) : image.rgba.resize(samples));
  std::vector<std::uint8_t> tile_pixels(static_cast<std::size_t>(tile_w) * tile_h * 4);
  std::vector<float> tile_floats(sixteen_bit ? tile_pixels.size() : 0);
  // Whole image: view mm → pixels (x right, y up from the bottom edge), clip z.
  const double p = camera.pixel_mm;
  Eigen::Matrix4d view_to_pixel = Eigen::Matrix4d::Identity();
  view_to_pixel(0, 0) = view_to_pixel(1, 1) = 1.0 / p;
  view_to_pixel(0, 3) = -camera.left_mm / p;
  view_to_pixel(1, 3) = -camera.bottom_mm / p;
  view_to_pixel.row(2) = orthographic(0, 1, 0, 1, gl.z_min, gl.z_max).cast<double>().row(2);
  const Eigen::Matrix4f world_to_pixel = (view_to_pixel * gl.world_to_view.matrix()).cast<float>();
  glUniformMatrix4fv(program.uniform("u_world_to_clip"), 1, GL_FALSE, world_to_pixel.data());
  glUniform1i(program.uniform("u_tiled"), 1);
  int viewport = 1;
  while (viewport < 2 * std::max(tile_w, tile_h)) viewport *= 2;
  glUniform1f(program.uniform("u_px_to_ndc"), 2.0f / static_cast<float>(viewport));
  glViewport(-viewport / 2, -viewport / 2, viewport, viewport);
  // Tile (x0, y0) covers image columns [x0, x0 + w) and GL rows [y0, y0 + h) (counted from the
  // bottom).
  for (int y0 = 0; y0 < image.height; y0 += tile_h)
    for (int x0 = 0; x0 < image.width; x0 += tile_w) {
      const int w = std::min(tile_w, image.width - x0), h = std::min(tile_h, image.height - y0);
      const auto start = std::chrono::steady_clock::now();
      glUniform2f(program.uniform("u_tile_origin_px"), static_cast<GLfloat>(x0),
                  static_cast<GLfloat>(y0));
      glDisable(GL_SCISSOR_TEST);  // clear the whole tile
      glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
      const int scissor_from = std::clamp(keep_from - x0, 0, w);
      const int scissor_to = std::clamp(keep_to - x0, 0, w);
      glEnable(GL_SCISSOR_TEST);
      glScissor(scissor_from, 0, std::max(0, scissor_to - scissor_from), h);
      // The kept part of the tile in view mm, one pixel wider all round against rounding.
      const Eigen::AlignedBox2f kept(Eigen::Vector2f(camera.left_mm + (x0 + scissor_from - 1) * p,
                                                     camera.bottom_mm + (y0 - 1) * p),
                                     Eigen::Vector2f(camera.left_mm + (x0 + scissor_to + 1) * p,
                                                     camera.bottom_mm + (y0 + h + 1) * p));
      gl.in_tile.clear();
      for (std::size_t t = 0; t < gl.triangles.triangles.size(); ++t)
        if (gl.triangles.extents[t].intersects(kept))
          gl.in_tile.push_back(gl.triangles.triangles[t]);
      draw(gl.buffers, gl.in_tile);
      glDisable(GL_SCISSOR_TEST);
      glFinish();
      check_gl("main pass");
      const auto drawn = std::chrono::steady_clock::now();
      stats_.draw_s += seconds_since(start);
      if (sixteen_bit)
        glReadPixels(0, 0, w, h, GL_RGBA, GL_FLOAT, tile_floats.data());
      else
        glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, tile_pixels.data());
      check_gl("read-back");
      // GL rows run bottom-up; images here run top-down.
      for (int r = 0; r < h; ++r) {
        const std::size_t to =
            (static_cast<std::size_t>(image.height - 1 - (y0 + r)) * image.width + x0) * 4;
        const std::size_t from = static_cast<std::size_t>(r) * w * 4;
        if (sixteen_bit)
          std::transform(
              tile_floats.begin() + from, tile_floats.begin() + from + w * 4,
              image.rgba16.begin() + to, [](float v) {
                return static_cast<std::uint16_t>(std::lround(std::clamp(v, 0.f, 1.f) * 65535.f));
              });
        else
          std::memcpy(image.rgba.data() + to, tile_pixels.data() + from,
                      static_cast<std::size_t>(w) * 4);
      }
      stats_.readback_s += seconds_since(drawn);
      ++stats_.tiles;
    }
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  return image;
}

RgbaImage render_mesh(const Mesh& mesh, const LafortuneMaterial& material,
                      const OrthoCamera& camera, const Lighting& lighting) {
  validate_camera(camera);
  return MeshRenderer(mesh, material, camera.world_to_view, lighting).render(camera);
}

}  // namespace sherd::render
