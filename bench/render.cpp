// Benchmark: the plate renderer on a procedural 300 mm vessel of 1 million triangles, at 300
// (baseline), 600 and 1200 dpi. Each case in a child process of its own (so that its peak memory
// is its own): "view", the stages of one full-vessel side view in one image (context, upload
// incl. shadow map, draw, read-back, PNG encode); "plate", the whole plate composed in bands.
// One JSON object per line.
//   bench_render [--dpi 300 --dpi 600 --dpi 1200] [--case view --case plate]
#include "processing/profile/profile.h"
#include "render/egl_context.h"
#include "render/materials.h"
#include "render/mesh_view.h"
#include "render/plate.h"
#include "render/png_writer.h"

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <numbers>

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

constexpr double kHeightMm = 300.0, kWallMm = 6.0;
constexpr int kRings = 250, kSegments = 1000;  // 2 walls × 2 × 250 × 1000 = 1 M triangles

// Outer radius at height z: a bellied jar with 0.4 mm deep grooves every 12 mm.
double outer_radius(double z) {
  return 90.0 + 45.0 * std::sin(std::numbers::pi * z / kHeightMm) +
         0.4 * std::sin(2 * std::numbers::pi * z / 12.0);
}

sherd::Mesh vessel() {
  sherd::Mesh mesh;
  for (const double inset : {0.0, kWallMm})
    for (int i = 0; i <= kRings; ++i) {
      const double z = kHeightMm * i / kRings, r = outer_radius(z) - inset;
      for (int j = 0; j < kSegments; ++j) {
        const double phi = 2 * std::numbers::pi * j / kSegments;
        mesh.vertices.points.emplace_back(r * std::cos(phi), r * std::sin(phi), z);
      }
    }
  const auto at = [](int wall, int i, int j) {
    return static_cast<std::uint32_t>((wall * (kRings + 1) + i) * kSegments + j % kSegments);
  };
  for (int wall = 0; wall < 2; ++wall)
    for (int i = 0; i < kRings; ++i)
      for (int j = 0; j < kSegments; ++j) {
        mesh.triangles.push_back({at(wall, i, j), at(wall, i, j + 1), at(wall, i + 1, j + 1)});
        mesh.triangles.push_back({at(wall, i, j), at(wall, i + 1, j + 1), at(wall, i + 1, j)});
      }
  for (int j = 0; j < kSegments; ++j) {  // the rim joins the walls at the top
    mesh.triangles.push_back({at(0, kRings, j), at(1, kRings, j), at(1, kRings, j + 1)});
    mesh.triangles.push_back({at(0, kRings, j), at(1, kRings, j + 1), at(0, kRings, j + 1)});
  }
  return mesh;
}

// What a perfect profile step would report for the vessel (axis = world z).
sherd::profile::Analysis analysis() {
  sherd::profile::Analysis a;
  a.axis.found = true;
  a.axis.point = sherd::Vec3d::Zero();
  a.axis.direction = sherd::Vec3d::UnitZ();
  a.sherd_to_world = sherd::Pose::Identity();
  a.has_rim = true;
  a.arc_deg = 360.0;
  for (int i = 0; i <= kRings; ++i) {
    const double z = kHeightMm * i / kRings;
    a.profile.outer.push_back({outer_radius(z), z});
    a.profile.inner.push_back({outer_radius(z) - kWallMm, z});
  }
  a.measurements.rim_diameter_mm = 2 * outer_radius(kHeightMm);
  a.measurements.rim_percent = 100.0;
  a.measurements.max_diameter_mm = 2 * outer_radius(kHeightMm / 2);
  a.measurements.height_mm = kHeightMm;
  a.measurements.wall_thickness_mm = {kWallMm, kWallMm, kWallMm};
  return a;
}

// CPU seconds of this process, llvmpipe's threads included: steadier than wall time on a
// shared machine.
double cpu_s() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_utime.tv_sec + usage.ru_stime.tv_sec +
         1e-6 * (usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

double peak_rss_mb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;  // kilobytes on Linux
}

// One dpi, run in a child process: the stages of the full side view, or the whole plate.
void run_case(int dpi, bool plate, const std::filesystem::path& out_dir) {
  using namespace sherd;
  const auto mesh_start = Clock::now();
  const Mesh mesh = vessel();
  const double mesh_s = seconds_since(mesh_start);
  const render::LafortuneMaterial clay = render::find_material(
      std::filesystem::path(SHERD_SOURCE_DIR) / "config/materials.xml", "clay");

  auto start = Clock::now();
  const std::string context = render::GlContextLock::description();
  const double context_s = seconds_since(start);

  if (plate) {  // the whole plate, composed in bands
    const profile::Analysis a = analysis();
    render::PlateSettings settings;
    settings.dpi = dpi;
    settings.materials_file = std::filesystem::path(SHERD_SOURCE_DIR) / "config/materials.xml";
    start = Clock::now();
    const render::PlateFiles files =
        render::render_plate({"bench", "vessel", &mesh, &a}, settings, out_dir / "plate");
    std::cout << nlohmann::json{{"bench", "render"},
                                {"case", "plate"},
                                {"dpi", dpi},
                                {"triangles", mesh.triangles.size()},
                                {"plate_px", {files.width_px, files.height_px}},
                                {"context_s", context_s},
                                {"plate_s", seconds_since(start)},
                                {"process_cpu_s", cpu_s()},
                                {"peak_rss_mb", peak_rss_mb()}}
                     .dump()
              << std::endl;
    return;
  }

  // The whole vessel from the side (view: x right, y = height, z towards the viewer).
  render::OrthoCamera camera;
  camera.world_to_view.linear() << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  camera.pixel_mm = 25.4 / dpi;
  camera.left_mm = -140.0;
  camera.bottom_mm = -5.0;
  camera.width_px = static_cast<int>(std::ceil(280.0 / camera.pixel_mm));
  camera.height_px = static_cast<int>(std::ceil((kHeightMm + 10.0) / camera.pixel_mm));
  start = Clock::now();
  render::RgbaImage image;
  double upload_s = 0.0;
  int tiles = 0;
  double draw_s = 0.0, readback_s = 0.0;
  {
    render::MeshRenderer renderer(mesh, clay, camera.world_to_view, render::drawing_lighting());
    upload_s = seconds_since(start);
    image = renderer.render(camera);
    draw_s = renderer.last_stats().draw_s;
    readback_s = renderer.last_stats().readback_s;
    tiles = renderer.last_stats().tiles;
  }
  start = Clock::now();
  {
    render::PngStream png(out_dir / "view.png", image.width, image.height, dpi,
                          render::PngFormat::kRgb8);
    std::vector<std::uint8_t> row(static_cast<std::size_t>(image.width) * 3);
    for (int j = 0; j < image.height; ++j) {
      for (int i = 0; i < image.width; ++i) {
        const std::uint8_t* p = image.pixel(i, j);
        for (int c = 0; c < 3; ++c)
          row[i * 3 + c] = static_cast<std::uint8_t>((p[c] * p[3] + 255 * (255 - p[3])) / 255);
      }
      png.write_row(row.data());
    }
    png.finish();
  }
  const double encode_s = seconds_since(start);
  std::cout << nlohmann::json{{"bench", "render"},
                              {"case", "view"},
                              {"dpi", dpi},
                              {"triangles", mesh.triangles.size()},
                              {"context", context},
                              {"mesh_build_s", mesh_s},
                              {"view_px", {camera.width_px, camera.height_px}},
                              {"tiles", tiles},
                              {"context_s", context_s},
                              {"upload_s", upload_s},
                              {"render_s", draw_s},
                              {"readback_s", readback_s},
                              {"encode_s", encode_s},
                              {"view_total_s",
                               context_s + upload_s + draw_s + readback_s + encode_s},
                              {"process_cpu_s", cpu_s()},
                              {"peak_rss_mb", peak_rss_mb()}}
                   .dump()
            << std::endl;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_render: plate rendering of a 1 M triangle vessel, per stage and dpi"};
  std::vector<int> dpis{300, 600, 1200};
  app.add_option("--dpi", dpis, "resolutions (the first is the baseline)")->capture_default_str();
  std::vector<std::string> cases{"view", "plate"};
  app.add_option("--case", cases, "view: one full side view by stages; plate: the whole plate")
      ->check(CLI::IsMember({"view", "plate"}))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  const auto out_dir = std::filesystem::temp_directory_path() / "sherd_bench_render";
  std::filesystem::create_directories(out_dir);
  for (int dpi : dpis)
    for (const std::string& name : cases) {
      const bool plate = name == "plate";
      // A child per case: its peak RSS is its own, and the parent never holds a GL context.
      const pid_t child = fork();
      if (child == 0) {
        try {
          run_case(dpi, plate, out_dir);
        } catch (const std::exception& e) {
          std::cout << nlohmann::json{{"bench", "render"}, {"dpi", dpi}, {"error", e.what()}}.dump()
                    << std::endl;
          _exit(1);
        }
        _exit(0);
      }
      int status = 0;
      waitpid(child, &status, 0);
    }
  std::filesystem::remove_all(out_dir);
  return 0;
}
