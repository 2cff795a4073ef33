// Benchmark: one scan of the default simulated station, from "press scan" to the last plate,
// in-process (the same JobRunner sherdd runs), repeated; prints one JSON object per line:
// each run's total and per-stage durations, then the medians and each stage's share.
//   bench_station_scan [--config config/station.toml] [--runs 3]
#include "bench/bench_stats.h"
#include "config/station_config.h"
#include "daemon/jobs.h"
#include "daemon/station.h"
#include "db/store.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <iostream>
#include <map>
#include <random>

namespace {

using sherd::bench::median;

// "axis:s01" and "axis:s02" are one stage for the share.
std::string stage_kind(const std::string& stage) { return stage.substr(0, stage.find(':')); }

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_station_scan: time from press-scan to the last plate on the simulated station"};
  std::string config_file = "config/station.toml";
  int runs = 3;
  app.add_option("--config", config_file)->capture_default_str();
  app.add_option("--runs", runs)->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(spdlog::level::warn);

  auto config = sherd::config::load_station_config(config_file);
  const auto data_dir = std::filesystem::temp_directory_path() /
                        ("sherdscan-bench-" + std::to_string(std::random_device{}()));
  sherd::config::set_data_dir(config, data_dir);
  std::filesystem::create_directories(data_dir);
  auto store = std::make_shared<sherd::db::Store>(config.paths.database);
  sherd::station::JobRunner runner(config, store, sherd::station::make_station(config));
  runner.start();

  std::vector<double> totals;
  std::map<std::string, std::vector<double>> per_stage;  // summed over sherds within a run
  for (int run = 0; run < runs; ++run) {
    const auto start = std::chrono::steady_clock::now();
    auto [scan_id, events] = runner.submit_scan();
    std::string state;
    int sherds = 0;
    while (auto e = events->next()) {
      if (e->value("event", "") == "finished") {
        state = e->value("state", "");
        sherds = static_cast<int>(e->value("sherds", nlohmann::json::array()).size());
      }
    }
    const double total_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    totals.push_back(total_ms);
    std::map<std::string, double> stages;
    for (const auto& s : store->stages(scan_id)) stages[stage_kind(s["stage"])] += s["duration_ms"].get<double>();
    for (const auto& [k, ms] : stages) per_stage[k].push_back(ms);
    std::cout << nlohmann::json{{"bench", "station_scan"}, {"run", run}, {"scan_id", scan_id}, {"state", state},
                                {"views", config.scan.views}, {"sherds", sherds}, {"dpi", config.render.dpi},
                                {"total_ms", total_ms}, {"stages_ms", stages}}.dump()
              << std::endl;
  }
  runner.stop();

  const double total = median(totals);
  nlohmann::json share, medians;
  for (const auto& [k, v] : per_stage) {
    medians[k] = median(v);
    if (k != "processing") share[k] = median(v) / total;  // "processing" contains the others
  }
  std::cout << nlohmann::json{{"bench", "station_scan"}, {"summary", true}, {"runs", runs},
                              {"median_total_ms", total}, {"median_stage_ms", medians},
                              {"share_of_total", share}}.dump()
            << std::endl;
  std::filesystem::remove_all(data_dir);
  return 0;
}
