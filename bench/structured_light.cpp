// Structured-light benchmark on the real procam-graycode-calib captures (../shared/data):
//   {"bench":"structured_light","case":"decode_real",...}        decoded share on the board, per
//   pose
//   {"bench":"structured_light","case":"calibration",...}        ours beside calibration_result.xml
//   {"bench":"structured_light","case":"board_geometry",...}     triangulated board vs 75 mm
//   squares
//   {"bench":"structured_light","case":"speed",...}              decode + stripe edges +
//        triangulate, 1280×1024×42
//   {"bench":"structured_light","case":"aravis_acquisition",...} frames/s at 1280×1024 through
//        Aravis's simulated GigE camera (127.0.0.1) filming the simulated projector, beside the
//        same camera with Aravis's own fill (baseline)
//   {"bench":"structured_light","case":"simulated_scene",...} a vessel on a table through Aravis's
//        simulated GigE camera, the Aravis driver, the decoder and the triangulation: share of the
//        camera pixels seeing a lit surface that are decoded, distance of the points to the true
//        surface; Gray code alone and Gray code + phase shift
// Usage: bench_structured_light [SHARED_DATA_DIR] (default ../shared/data beside the repository;
// --help lists it).
#include <nlohmann/json.hpp>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iostream>

#include <arv.h>

#include <CLI/CLI.hpp>

#include "bench/bench_stats.h"
#include "drivers/aravis_camera.h"
#include "drivers/projector.h"
#include "processing/structured_light/calibration.h"
#include "processing/structured_light/gray_code.h"
#include "processing/structured_light/scanner.h"
#include "processing/structured_light/triangulation.h"
#include "simulators/structured_light_world.h"

namespace sl = sherd::structured_light;
using nlohmann::json;

namespace {

json intrinsics_json(const sl::Intrinsics& in) {
  return {{"fx", in.matrix(0, 0)},
          {"fy", in.matrix(1, 1)},
          {"cx", in.matrix(0, 2)},
          {"cy", in.matrix(1, 2)},
          {"dist", in.distortion}};
}

json calibration_json(const sl::ProCamCalibration& c) {
  const Eigen::AngleAxisd r(c.rotation);
  return {{"camera", intrinsics_json(c.camera)},
          {"projector", intrinsics_json(c.projector)},
          {"rotation_deg", r.angle() * 180 / M_PI},
          {"translation_mm", {c.translation_mm.x(), c.translation_mm.y(), c.translation_mm.z()}},
          {"stereo_rms_px", c.stereo_rms_px}};
}

// The fake camera films the simulated projector (camera pixel (u, v) sees projector pixel
// (u·0.8, v·0.75): 1280×1024 over 1024×768).
void film_projector(ArvBuffer* buffer, void* data, guint32, guint32, ArvPixelFormat) {
  const auto* projector = static_cast<const sherd::drivers::SimulatedProjector*>(data);
  auto* pixels =
      static_cast<std::uint8_t*>(const_cast<void*>(arv_buffer_get_data(buffer, nullptr)));
  const int width = arv_buffer_get_image_width(buffer),
            height = arv_buffer_get_image_height(buffer);
  for (int v = 0; v < height; ++v)
    for (int u = 0; u < width; ++u)
      pixels[std::size_t(v) * width + u] = projector->lit(u * 4 / 5, v * 3 / 4);
}

// Frames/s of `frames` triggered captures at 1280×1024; `projector` null = Aravis's own fill.
json acquisition(sherd::drivers::SimulatedProjector* projector,
                 const sl::GrayCodePatterns& patterns) {
  ArvGvFakeCamera* fake = arv_gv_fake_camera_new("127.0.0.1", "SHERDBENCH");
  if (!arv_gv_fake_camera_is_running(fake)) {
    g_object_unref(fake);
    return {{"error", "cannot bind 127.0.0.1:3956"}};
  }
  if (projector)
    arv_fake_camera_set_fill_pattern(arv_gv_fake_camera_get_fake_camera(fake), film_projector,
                                     projector);
  json out;
  {
    sherd::drivers::AravisCameraSettings settings;
    settings.id = "127.0.0.1";
    settings.width = 1280;
    settings.height = 1024;
    sherd::drivers::AravisCamera camera(settings);
    std::vector<sl::GreyImage> shown;
    for (int f = 0; f < patterns.frame_count(); ++f) shown.push_back(patterns.frame(f));
    const auto t0 = std::chrono::steady_clock::now();
    for (int f = 0; f < patterns.frame_count(); ++f) {
      if (projector) projector->show(shown[f].pixels);
      camera.capture();
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    out = {{"frames", patterns.frame_count()},
           {"seconds", seconds},
           {"frames_per_s", patterns.frame_count() / seconds},
           {"incomplete_frames", camera.incomplete_frames()}};
  }
  g_object_unref(fake);
  return out;
}

// One capture of the simulated vessel scene through the real transport, scored against the
// world's truth. The distance of a point to the true surface is taken along the true normal at the
// pixel's true point (the surface is smooth at a pixel's scale). "interior" leaves out the pixels
// within 2 px of a depth jump or a shadow edge of the truth, where a camera pixel mixes two
// surfaces: those are reported as the share of points off the surface by more than 1 mm.
json simulated_scene(int width, int height, std::uint64_t seed, sl::PatternSet patterns) {
  const sherd::sim::VesselOnTable scene = sherd::sim::vessel_on_table(width, height, seed);
  const sherd::sim::StructuredLightOptics optics;
  auto world = std::make_shared<const sherd::sim::StructuredLightWorld>(
      scene.calibration, scene.table, scene.objects, optics);
  sherd::drivers::SimulatedProjector projector(1024, 768);
  sherd::sim::SimulatedGigECamera fake(world, projector);
  sherd::drivers::AravisCameraSettings settings;
  settings.id = "127.0.0.1";
  settings.width = width;
  settings.height = height;
  sherd::drivers::AravisCamera camera(settings);
  sl::ScannerOptions options;
  options.patterns = patterns;
  // The reference's 40 suits its real captures; here it would drop the dim, steep flanks of the
  // vessel, which the simulated sensor's noise lets decode.
  options.thresholds.black = optics.shadow_threshold();
  sl::StructuredLightScanner scanner(camera, projector, scene.calibration, options);
  const auto t0 = std::chrono::steady_clock::now();
  const sherd::OrganisedView view = scanner.capture();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  const sherd::sim::WorldTruth& truth = world->truth();
  auto at = [&](int x, int y) { return std::size_t(y) * width + x; };
  // A pixel is interior when its 5×5 neighbourhood is lit and free of depth jumps (> 2 mm between
  // neighbours' true depths).
  auto interior = [&](int x, int y) {
    if (x < 2 || y < 2 || x >= width - 2 || y >= height - 2) return false;
    for (int dy = -2; dy <= 2; ++dy)
      for (int dx = -2; dx <= 2; ++dx) {
        const std::size_t j = at(x + dx, y + dy);
        if (!truth.lit[j]) return false;
        if (dx < 2 && std::abs(truth.points[j].z() - truth.points[at(x + dx + 1, y + dy)].z()) > 2)
          return false;
        if (dy < 2 && std::abs(truth.points[j].z() - truth.points[at(x + dx, y + dy + 1)].z()) > 2)
          return false;
      }
    return true;
  };
  std::size_t lit = 0, decoded = 0, lit_interior = 0, decoded_interior = 0, off_1mm = 0,
              spurious = 0, points = 0;
  std::vector<double> distances_all, distances_interior;
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const std::size_t i = at(x, y);
      const bool inner = truth.lit[i] && interior(x, y);
      lit += truth.lit[i];
      lit_interior += inner;
      if (!view.valid[i]) continue;
      ++points;
      if (!truth.lit[i]) {
        ++spurious;
        continue;
      }
      ++decoded;
      const double d = std::abs(
          (view.points[i] - truth.points[i]).cast<double>().dot(truth.normals[i].cast<double>()));
      distances_all.push_back(d);
      off_1mm += d > 1.0;
      if (inner) {
        ++decoded_interior;
        distances_interior.push_back(d);
      }
    }
  auto rms = [](const std::vector<double>& d) {
    double sum = 0;
    for (double v : d) sum += v * v;
    return d.empty() ? 0.0 : std::sqrt(sum / double(d.size()));
  };
  return {
      {"bench", "structured_light"},
      {"case", "simulated_scene"},
      {"patterns", patterns == sl::PatternSet::kPhase ? "gray+phase" : "gray"},
      {"seed", seed},
      {"camera", {width, height}},
      {"projector", {1024, 768}},
      {"frames", scanner.frame_count()},
      {"lit_pixels", lit},
      {"decoded_share_of_lit", double(decoded) / double(lit)},
      {"decoded_share_of_lit_interior", double(decoded_interior) / double(lit_interior)},
      {"rms_mm_interior", rms(distances_interior)},
      {"median_mm_interior", sherd::bench::median(distances_interior)},
      {"rms_mm_all", rms(distances_all)},
      {"share_off_surface_over_1mm", double(off_1mm) / double(std::max<std::size_t>(1, decoded))},
      {"points_where_truth_unlit", spurious},
      {"points", points},
      {"capture_s", seconds},
      {"note", "capture_s: shared 2-core machine under other builds"}};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "bench_structured_light: simulated scenes through Aravis's fake GigE camera (Gray code and "
      "Gray + phase, seeds 1-3), then calibration, decoding, board geometry and speed on the real "
      "procam-graycode-calib captures, and Aravis acquisition throughput"};
  std::filesystem::path shared = std::filesystem::path(SHERD_SOURCE_DIR) / "../shared/data";
  app.add_option("shared_data_dir", shared, "the shared data directory (holds procam-graycode-calib)")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  const auto sample = shared / "procam-graycode-calib/sample_data";
  for (std::uint64_t seed : {1, 2, 3})
    for (sl::PatternSet set : {sl::PatternSet::kGray, sl::PatternSet::kPhase})
      std::cout << simulated_scene(1280, 1024, seed, set).dump() << "\n" << std::flush;

  const sl::GrayCodePatterns patterns{1024, 768};
  const sl::Chessboard board;
  std::vector<std::filesystem::path> dirs;
  for (int i = 0; i < 5; ++i) dirs.push_back(sample / ("capture_" + std::to_string(i)));

  // Calibration beside the reference.
  const sl::CalibrationReport report = sl::calibrate(dirs, {});
  sl::ProCamCalibration reference = sl::read_calibration(sample / "calibration_result.xml");
  reference.projector.width = patterns.projector_width;  // not stored in the reference file
  reference.projector.height = patterns.projector_height;
  std::cout << json{{"bench", "structured_light"},
                    {"case", "calibration"},
                    {"poses", report.poses_used},
                    {"projector_corners", report.projector_corners},
                    {"corners_skipped", report.corners_skipped},
                    {"ours", calibration_json(report.calibration)},
                    {"ours_camera_rms_px", report.calibration.camera_rms_px},
                    {"ours_projector_rms_px", report.calibration.projector_rms_px},
                    {"reference", calibration_json(reference)},
                    {"rms_ratio_ours_over_reference",
                     report.calibration.stereo_rms_px / reference.stereo_rms_px}}
                   .dump()
            << "\n";

  const sl::Triangulator ours(report.calibration), theirs(reference);
  for (std::size_t pose = 0; pose < dirs.size(); ++pose) {
    const auto frames = sl::read_sequence(dirs[pose], "graycode_", patterns.frame_count());
    const sl::DecodedMap map = sl::decode(patterns, frames, {40, 5});
    const auto corners = sl::find_board_corners(frames[patterns.white_frame()], board);
    if (corners.empty()) continue;
    auto measured = [&](const sl::Triangulator& t) {
      const sl::BoardMeasurement b =
          sl::measure_board(t, t.triangulate(map, nullptr, 2), corners, board);
      return json{{"long_span_mm", b.long_span_mm},
                  {"short_span_mm", b.short_span_mm},
                  {"distance_mm", b.distance_mm},
                  {"plane_rms_mm", b.plane_rms_mm},
                  {"board_pixels", b.pixels},
                  {"triangulated_share_on_board", double(b.points) / double(b.pixels)}};
    };
    // Spans from the dense points (plane fit), not from the calibration's own corner fit.
    std::cout << json{{"bench", "structured_light"},
                      {"case", "real_board"},
                      {"pose", static_cast<int>(pose)},
                      {"decoded_share_frame", double(map.decoded_count()) / map.state.size()},
                      {"truth_long_span_mm", (board.inner_columns - 1) * board.square_mm},
                      {"truth_short_span_mm", (board.inner_rows - 1) * board.square_mm},
                      {"ours", measured(ours)},
                      {"reference_calibration", measured(theirs)}}
                     .dump()
              << "\n";
  }

  // Speed: decode + stripe edges + triangulate the 1280×1024, 42-frame sequence (frames already in
  // memory; the scanner's Gray-code path), two threads; median of 7. Baseline in the same run: one
  // thread.
  const auto frames = sl::read_sequence(dirs[0], "graycode_", patterns.frame_count());
  for (int threads : {1, 2}) {
    std::vector<double> decode_s, edges_s, total_s;
    for (int rep = 0; rep < 7; ++rep) {
      const auto t0 = std::chrono::steady_clock::now();
      sl::DecodedMap map = sl::decode(patterns, frames, {40, 5}, threads);
      const auto t1 = std::chrono::steady_clock::now();
      sl::refine_columns_at_edges(patterns, frames, map);
      const auto t2 = std::chrono::steady_clock::now();
      const sl::TriangulatedView tv =
          ours.triangulate(map, &frames[patterns.white_frame()], threads);
      const auto t3 = std::chrono::steady_clock::now();
      decode_s.push_back(std::chrono::duration<double>(t1 - t0).count());
      edges_s.push_back(std::chrono::duration<double>(t2 - t1).count());
      total_s.push_back(std::chrono::duration<double>(t3 - t0).count());
    }
    std::cout << json{{"bench", "structured_light"},
                      {"case", "speed"},
                      {"frames", patterns.frame_count()},
                      {"width", frames[0].width},
                      {"height", frames[0].height},
                      {"threads", threads},
                      {"decode_s_median", sherd::bench::median(decode_s)},
                      {"stripe_edges_s_median", sherd::bench::median(edges_s)},
                      {"decode_triangulate_s_median", sherd::bench::median(total_s)},
                      {"note", "shared 2-core machine under other builds"}}
                     .dump()
              << "\n";
  }

  sherd::drivers::SimulatedProjector projector(patterns.projector_width, patterns.projector_height);
  std::cout << json{{"bench", "structured_light"},
                    {"case", "aravis_acquisition"},
                    {"width", 1280},
                    {"height", 1024},
                    {"filming_projector", acquisition(&projector, patterns)},
                    {"baseline_aravis_fill", acquisition(nullptr, patterns)},
                    {"note", "loopback; shared 2-core machine under other builds"}}
                   .dump()
            << "\n";
  arv_shutdown();
}
