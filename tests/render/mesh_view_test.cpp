// The renderer on a real EGL context: exact orthographic scale, the shader's Lafortune BRDF against
// pbrt's formula evaluated here in an explicit local frame, and the key light's shadow where
// analytic geometry puts it.
#include "render/mesh_view.h"

#include "core/errors.h"
#include "render/materials.h"
#include "test_meshes.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <numbers>

namespace sherd::render {
namespace {

const std::filesystem::path kMaterials =
    std::filesystem::path(SHERD_SOURCE_DIR) / "config/materials.xml";

struct Coverage {
  int count = 0, first = -1, last = -1;
};

Coverage row_coverage(const RgbaImage& image, int row) {
  Coverage c;
  for (int i = 0; i < image.width; ++i)
    if (image.pixel(i, row)[3] > 127) {
      if (c.first < 0) c.first = i;
      c.last = i;
      ++c.count;
    }
  return c;
}

Coverage column_coverage(const RgbaImage& image, int column) {
  Coverage c;
  for (int j = 0; j < image.height; ++j)
    if (image.pixel(column, j)[3] > 127) {
      if (c.first < 0) c.first = j;
      c.last = j;
      ++c.count;
    }
  return c;
}

// A 100.000 mm long, 8 mm wide face seen square-on, lying along x and then along y: 100 mm /
// (25.4 mm / dpi) pixels long both ways (square pixels), placed where the camera says.
void expect_exact_scale(int dpi, int expected_px) {
  const LafortuneMaterial clay = find_material(kMaterials, "clay");
  Lighting lighting = drawing_lighting();
  for (DirectionalLight& light : lighting.lights) light.casts_shadow = false;  // not needed here
  for (const bool along_x : {true, false}) {
    const Mesh slab = along_x ? test::box(100.0, 8.0, 5.0) : test::box(8.0, 100.0, 5.0);
    OrthoCamera camera;
    camera.pixel_mm = 25.4 / dpi;
    camera.left_mm = along_x ? -53.0 : -6.0;  // 3 mm left of the face along x, else 2 mm
    camera.bottom_mm = along_x ? -6.0 : -53.0;
    camera.width_px = static_cast<int>(std::ceil((along_x ? 106.0 : 12.0) / camera.pixel_mm));
    camera.height_px = static_cast<int>(std::ceil((along_x ? 12.0 : 106.0) / camera.pixel_mm));
    const RgbaImage image = render_mesh(slab, clay, camera, lighting);
    ASSERT_EQ(image.width, camera.width_px);
    ASSERT_EQ(image.height, camera.height_px);
    const Coverage c =
        along_x ? row_coverage(image, image.height / 2) : column_coverage(image, image.width / 2);
    EXPECT_NEAR(c.count, expected_px, 1) << dpi << " dpi, along " << (along_x ? "x" : "y");
    EXPECT_EQ(c.last - c.first + 1, c.count) << "holes in the face";
    // The face starts 3 mm from the image's left edge, and 3 mm below its top edge.
    EXPECT_NEAR(c.first, 3.0 / camera.pixel_mm, 1.0);
  }
}

TEST(MeshView, HundredMillimetresAt600DpiAre2362Pixels) { expect_exact_scale(600, 2362); }

TEST(MeshView, HundredMillimetresAt1200DpiAre4724Pixels) { expect_exact_scale(1200, 4724); }

// pbrt's Lafortune BRDF, one channel, wo/wi given in the local shading frame (z = normal).
double pbrt_lafortune(const LafortuneMaterial& m, int channel, const Vec3d& wo, const Vec3d& wi) {
  double f = m.diffuse[channel] / std::numbers::pi;
  for (const LafortuneLobe& lobe : m.lobes) {
    const double base = lobe.cxy[channel] * wo.x() * wi.x() + lobe.cxy[channel] * wo.y() * wi.y() +
                        lobe.cz[channel] * wo.z() * wi.z();
    f += base > 0 ? std::pow(base, lobe.exponent[channel]) : 0.0;
  }
  return f;
}

// A flat square tilted `tilt_deg` about y, seen along −z; one light at `towards_light` (view
// frame); the centre pixel read back in linear radiance.
void expect_shader_matches_pbrt(const std::string& material_name, double tilt_deg,
                                const Vec3d& towards_light) {
  const LafortuneMaterial material = find_material(kMaterials, material_name);
  const Eigen::Matrix3d tilt =
      Eigen::AngleAxisd(tilt_deg * std::numbers::pi / 180.0, Vec3d::UnitY()).toRotationMatrix();
  Mesh quad = test::box(20.0, 20.0, 0.0);  // the z = 0 faces of a flat box: two squares
  quad.vertices.transform(Pose(tilt));
  // Local frame as pbrt builds it: x = dp/du (the square's first edge), y = n × x, z = n.
  const Vec3d x = tilt.col(0), n = tilt.col(2), y = n.cross(x);
  const Vec3d wo_view = Vec3d::UnitZ(), wi_view = towards_light.normalized();
  const Vec3d wo(wo_view.dot(x), wo_view.dot(y), wo_view.dot(n));
  const Vec3d wi(wi_view.dot(x), wi_view.dot(y), wi_view.dot(n));
  ASSERT_GT(wi.z(), 0.0);

  Vec3d expected;
  for (int c = 0; c < 3; ++c) expected[c] = pbrt_lafortune(material, c, wo, wi) * wi.z();
  // Scale the light so the brightest channel lands at 0.8: 8-bit read-back, well inside range.
  const double intensity = 0.8 / expected.maxCoeff();
  expected *= intensity;

  Lighting lighting;
  lighting.lights = {{towards_light, intensity, false}};
  lighting.ambient = 0.0;
  lighting.srgb_encode = false;
  OrthoCamera camera;
  camera.pixel_mm = 0.5;
  camera.left_mm = camera.bottom_mm = -16.0;
  camera.width_px = camera.height_px = 64;
  const RgbaImage image = render_mesh(quad, material, camera, lighting);
  const std::uint8_t* centre = image.pixel(32, 32);
  ASSERT_EQ(centre[3], 255);
  for (int c = 0; c < 3; ++c)
    EXPECT_NEAR(centre[c] / 255.0, expected[c], 1.5 / 255.0)
        << material_name << " channel " << c << ", f·cos·E = " << expected[c];
}

TEST(MeshView, ClayAtTheMirrorDirectionMatchesPbrt) {
  // Tilted 25°: the mirror of wo = +z about the normal is 50° from +z.
  const double a = 50.0 * std::numbers::pi / 180.0;
  expect_shader_matches_pbrt("clay", 25.0, Vec3d(std::sin(a), 0.0, std::cos(a)));
}

TEST(MeshView, BrushedMetalLobesMatchPbrt) {
  // Diffuse 0: the whole value comes from the lobes (lobe 0 and 2 ≈ 1.6 and 2.1 here).
  const double a = 50.0 * std::numbers::pi / 180.0;
  expect_shader_matches_pbrt("brushedmetal", 25.0, Vec3d(std::sin(a), 0.0, std::cos(a)));
}

TEST(MeshView, BluePaintOffMirrorMatchesPbrt) {
  expect_shader_matches_pbrt("bluepaint", 10.0, Vec3d(-0.3, 0.5, 1.0));
}

// The centre pixel, in [0, 1] and not sRGB-encoded, of a 20 mm tile facing the viewer: where the
// hand-computed shading values below are checked.
std::array<double, 3> tile_centre(const LafortuneMaterial& material, Lighting lighting) {
  lighting.srgb_encode = false;
  OrthoCamera camera;
  camera.pixel_mm = 0.5;
  camera.left_mm = camera.bottom_mm = -8.0;
  camera.width_px = camera.height_px = 32;
  const RgbaImage image = render_mesh(test::box(20.0, 20.0, 1.0), material, camera, lighting);
  const std::uint8_t* rgb = image.pixel(16, 16);
  return {rgb[0] / 255.0, rgb[1] / 255.0, rgb[2] / 255.0};
}

TEST(MeshView, HeadOnDiffuseIsAlbedoOverPiTimesCosine) {
  // Hand value: a Lambertian (no lobes) 0.6 albedo lit at 60° by E = 2: 0.6/π · cos 60° · 2.
  LafortuneMaterial lambert{"lambert", {0.6, 0.6, 0.6}, {}};
  Lighting lighting;
  lighting.lights = {
      {Vec3d(std::sin(std::numbers::pi / 3), 0, std::cos(std::numbers::pi / 3)), 2.0, false}};
  EXPECT_NEAR(tile_centre(lambert, lighting)[0], 0.190986, 1.0 / 255.0);
}

TEST(MeshView, KeyLightShadowFallsWhereGeometryPutsIt) {
  // A 10 mm cube standing on a 60 mm plate that faces the viewer. The key light's direction
  // (−1, 1, 1.2) throws the cube top's shadow 10/1.2 = 8.33 mm right and down: (8, −8) on the
  // plate is in shadow, (−8, 8) behind the light's side is lit.
  Mesh scene = test::box(60.0, 60.0, 2.0);
  scene.vertices.transform(Pose(Eigen::Translation3d(0, 0, -1.0)));  // plate top at z = 0
  Mesh cube = test::box(10.0, 10.0, 10.0);
  cube.vertices.transform(Pose(Eigen::Translation3d(0, 0, 5.0)));
  const auto offset = static_cast<std::uint32_t>(scene.vertices.size());
  scene.vertices.append(cube.vertices);
  for (Triangle t : cube.triangles)
    scene.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});

  const LafortuneMaterial grey{"grey", {0.5, 0.5, 0.5}, {}};
  const Vec3d key(-1.0, 1.0, 1.2), fill(1.0, 0.0, 1.0);
  Lighting lighting;
  lighting.lights = {{key, 1.5, true}, {fill, 0.5, false}};
  lighting.ambient = 0.2;
  lighting.srgb_encode = false;
  OrthoCamera camera;
  camera.pixel_mm = 0.25;
  camera.left_mm = camera.bottom_mm = -32.0;
  camera.width_px = camera.height_px = 256;
  const RgbaImage image = render_mesh(scene, grey, camera, lighting);
  const auto value_at = [&](double x, double y) {
    return image.pixel(static_cast<int>((x + 32.0) / 0.25),
                       static_cast<int>((32.0 - y) / 0.25))[0] /
           255.0;
  };
  const double key_term = 0.5 / std::numbers::pi * 1.5 * key.normalized().z();
  const double fill_term = 0.5 / std::numbers::pi * 0.5 * fill.normalized().z();
  const double ambient_term = 0.2 * 0.5;
  EXPECT_NEAR(value_at(-8.0, 8.0), key_term + fill_term + ambient_term, 1.5 / 255.0);
  EXPECT_NEAR(value_at(8.0, -8.0), fill_term + ambient_term, 1.5 / 255.0);
  // The cube's own top, nearest the light, is lit.
  EXPECT_NEAR(value_at(0.0, 0.0), key_term + fill_term + ambient_term, 1.5 / 255.0);
}

TEST(MeshView, PointCloudIsDrawnWithoutHoles) {
  // A 100 × 8 mm grid of points 0.5 mm apart, no triangles: the points must close the gaps
  // (pixels are 0.1 mm) and the extent stay 100 mm plus about one point radius each side.
  Mesh cloud;
  for (int i = 0; i <= 200; ++i)
    for (int j = 0; j <= 16; ++j) {
      cloud.vertices.points.emplace_back(-50.0f + 0.5f * i, -4.0f + 0.5f * j, 0.0f);
      cloud.vertices.normals.emplace_back(0.0f, 0.0f, 1.0f);
    }
  OrthoCamera camera;
  camera.pixel_mm = 0.1;
  camera.left_mm = -53.0;
  camera.bottom_mm = -6.0;
  camera.width_px = 1060;
  camera.height_px = 120;
  const RgbaImage image =
      render_mesh(cloud, {"grey", {0.5, 0.5, 0.5}, {}}, camera, drawing_lighting());
  const Coverage c = row_coverage(image, 60);
  EXPECT_EQ(c.last - c.first + 1, c.count) << "holes between the points";
  EXPECT_NEAR(c.count * camera.pixel_mm, 100.0, 1.0);
}

TEST(MeshView, NegativeLobeBaseIsClampedToZero) {
  // Hand value. One lobe with Cxy = Cz = −1 seen and lit head-on: base = −1·(wo·wi) < 0, which
  // pbrt clamps to 0 (with exponent 2 an unclamped power would give +1). Only the diffuse term
  // 0.4/π remains: under E = 1.5 along the normal, 0.4/π · 1.5 = 0.190986.
  const LafortuneMaterial material{
      "clamped", {0.4, 0.4, 0.4}, {{{-1.0, -1.0, -1.0}, {-1.0, -1.0, -1.0}, {2.0, 2.0, 2.0}}}};
  Lighting lighting;
  lighting.lights = {{Vec3d::UnitZ(), 1.5, false}};
  for (const double value : tile_centre(material, lighting))
    EXPECT_NEAR(value, 0.190986, 1.0 / 255.0);
}

TEST(MeshView, AnyNumberOfLightsAddUp) {
  // Hand value. Nine lights (more than any fixed small array), each 0.2 irradiance from 40° off
  // the normal at azimuths 40° apart, on a Lambertian 0.5 albedo:
  // 9 · 0.5/π · cos 40° · 0.2 = 0.219453. Two more lights from behind add nothing.
  const LafortuneMaterial lambert{"lambert", {0.5, 0.5, 0.5}, {}};
  const double polar = 40.0 * std::numbers::pi / 180.0;
  Lighting lighting;
  for (int i = 0; i < 9; ++i) {
    const double azimuth = i * 40.0 * std::numbers::pi / 180.0;
    lighting.lights.push_back({Vec3d(std::sin(polar) * std::cos(azimuth),
                                     std::sin(polar) * std::sin(azimuth), std::cos(polar)),
                               0.2, false});
  }
  lighting.lights.push_back({Vec3d(0.3, 0.0, -1.0), 5.0, false});
  lighting.lights.push_back({Vec3d(0.0, -0.2, -1.0), 5.0, false});
  EXPECT_NEAR(tile_centre(lambert, lighting)[0], 0.219453, 1.0 / 255.0);
}

TEST(MeshView, TiledRenderEqualsSinglePass) {
  // A relief dome with shadows, 331 × 297 px (odd sizes: partial tiles at the right and top),
  // drawn in one pass and in 64 px tiles.
  const Mesh dome = test::relief_dome(30.0, 120, 240);
  const LafortuneMaterial clay = find_material(kMaterials, "clay");
  OrthoCamera camera;
  camera.pixel_mm = 0.2;
  camera.left_mm = -33.1;
  camera.bottom_mm = -29.7;
  camera.width_px = 331;
  camera.height_px = 297;
  MeshRenderer renderer(dome, clay, camera.world_to_view, drawing_lighting());
  const RgbaImage single = renderer.render(camera);
  ASSERT_EQ(renderer.last_stats().tiles, 1);
  const RgbaImage tiled = renderer.render(camera, 64);
  ASSERT_EQ(renderer.last_stats().tiles, 6 * 5);
  ASSERT_EQ(tiled.rgba.size(), single.rgba.size());
  // Coverage must be identical (same sample positions); the shading may differ by one 8-bit
  // level in a few pixels, where llvmpipe's varying interpolation rounds differently for another
  // tile origin.
  int covered = 0, coverage_differs = 0, colour_differs = 0, largest_difference = 0;
  for (std::size_t i = 0; i < single.rgba.size(); i += 4) {
    covered += single.rgba[i + 3] > 0;
    coverage_differs += single.rgba[i + 3] != tiled.rgba[i + 3];
    int difference = 0;
    for (int c = 0; c < 3; ++c)
      difference = std::max(difference, std::abs(single.rgba[i + c] - tiled.rgba[i + c]));
    colour_differs += difference > 0;
    largest_difference = std::max(largest_difference, difference);
  }
  EXPECT_GT(covered, 20000) << "the dome is in the picture";
  EXPECT_EQ(coverage_differs, 0);
  EXPECT_LE(largest_difference, 1);
  EXPECT_LE(colour_differs, covered / 1000) << "pixels whose colour differs by one level";
}

TEST(MeshView, RejectsNonFiniteVertices) {
  Mesh mesh = test::box(1, 1, 1);
  mesh.vertices.points[3].x() = std::nanf("");
  OrthoCamera camera;
  camera.width_px = camera.height_px = 8;
  EXPECT_THROW(render_mesh(mesh, {"grey", {0.5, 0.5, 0.5}, {}}, camera, drawing_lighting()),
               InputError);
}

}  // namespace
}  // namespace sherd::render
