// Benchmark: fusion of one simulated station scan (default scanner, 8 views at 45° steps, true
// poses), per scene kind and seed; prints one JSON object per scan, then the median time.
//   bench_fusion [--seeds 3]
#include "bench/bench_stats.h"
#include "processing/fusion/fusion.h"
#include "simulators/pottery.h"
#include "simulators/sim_scanner.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <iostream>
#include <numbers>

int main(int argc, char** argv) {
  CLI::App app{"bench_fusion: time and size of fusing a simulated 8-view scan"};
  int seeds = 3;
  app.add_option("--seeds", seeds)->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  constexpr int kViews = 8;
  std::vector<double> times_ms;
  for (const auto kind : {sherd::sim::SceneKind::Vessel, sherd::sim::SceneKind::Frame}) {
    for (int seed = 1; seed <= seeds; ++seed) {
      sherd::sim::SceneSpec spec;
      spec.seed = static_cast<std::uint64_t>(seed);
      spec.kind = kind;
      double angle = 0.0;
      sherd::sim::ScannerModel model = sherd::sim::default_station_scanner();
      model.seed = spec.seed;
      sherd::sim::SimulatedScanner scanner(sherd::sim::make_scene(spec), model,
                                           [&] { return angle; });
      std::vector<sherd::OrganisedView> views;
      std::vector<sherd::fusion::PosedView> posed;
      views.reserve(kViews);
      for (int v = 0; v < kViews; ++v) {
        angle = 2.0 * std::numbers::pi * v / kViews;
        views.push_back(scanner.capture());
        // The plate turned by `angle`: its frame sees the scanner turned back by it.
        const sherd::Pose pose =
            Eigen::AngleAxisd(-angle, Eigen::Vector3d::UnitZ()) * model.scanner_to_world;
        posed.push_back({&views.back(), pose});
      }
      const auto start = std::chrono::steady_clock::now();
      const auto fused = sherd::fusion::fuse_views(posed, {});
      const double ms = std::chrono::duration<double, std::milli>(
                            std::chrono::steady_clock::now() - start).count();
      times_ms.push_back(ms);
      std::cout << nlohmann::json{{"bench", "fusion"}, {"scene", sherd::sim::to_string(kind)},
                                  {"seed", seed}, {"views", kViews},
                                  {"input_points", fused.input_points},
                                  {"mesh_vertices", fused.mesh.vertices.size()},
                                  {"mesh_triangles", fused.mesh.triangles.size()},
                                  {"cloud_points", fused.cloud.size()},
                                  {"outliers_removed", fused.outliers_removed},
                                  {"overlap_points_dropped", fused.overlap_points_dropped},
                                  {"time_ms", ms}}.dump()
                << std::endl;
    }
  }
  std::cout << nlohmann::json{{"bench", "fusion"}, {"summary", true},
                              {"median_time_ms", sherd::bench::number_or_null(sherd::bench::median(times_ms))}}
                   .dump()
            << std::endl;
}
