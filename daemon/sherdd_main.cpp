// sherdd — the station daemon. Loads the configuration, opens the database, starts the drivers,
// resumes unfinished scans and serves the control API until SIGTERM/SIGINT.
#include "config/station_config.h"
#include "core/errors.h"
#include "daemon/jobs.h"
#include "daemon/server.h"
#include "daemon/station.h"
#include "db/event_sink.h"
#include "db/store.h"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <spdlog/sinks/basic_file_sink.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <csignal>
#include <cstdio>
#include <iostream>

namespace {

void set_up_logging(const sherd::config::StationConfig& config, std::shared_ptr<sherd::db::Store> store) {
  std::filesystem::create_directories(config.paths.log_file.parent_path());
  std::vector<spdlog::sink_ptr> sinks{
      std::make_shared<spdlog::sinks::stderr_color_sink_mt>(),
      std::make_shared<spdlog::sinks::basic_file_sink_mt>(config.paths.log_file.string()),
      sherd::db::make_event_sink(std::move(store))};
  auto logger = std::make_shared<spdlog::logger>("sherdd", sinks.begin(), sinks.end());
  logger->set_pattern("%Y-%m-%dT%H:%M:%S.%e %^%l%$ %v");
  logger->flush_on(spdlog::level::info);
  spdlog::set_default_logger(logger);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"sherdd — the sherdscan station daemon: drives the scanner and turntable, processes scans\n"
               "and serves sherdctl on a Unix domain socket. Stops cleanly on SIGTERM or SIGINT."};
  std::string config_file = "config/station.toml";
  std::string data_dir;
  app.add_option("-c,--config", config_file, "station configuration (TOML)")->capture_default_str();
  app.add_option("--data-dir", data_dir, "override station.data_dir (database, raw views, outputs, socket, log)");
  app.set_version_flag("--version", "sherdd 0.1.0");
  CLI11_PARSE(app, argc, argv);

  // Signals are taken by sigwait below; every thread started from here on inherits the mask.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  std::signal(SIGPIPE, SIG_IGN);

  sherd::config::StationConfig config;
  std::shared_ptr<sherd::db::Store> store;
  try {
    config = sherd::config::load_station_config(config_file);
    if (!data_dir.empty()) sherd::config::set_data_dir(config, data_dir);
    std::filesystem::create_directories(config.paths.data_dir);
    store = std::make_shared<sherd::db::Store>(config.paths.database);
  } catch (const std::exception& e) {
    std::cerr << "sherdd: " << e.what() << '\n';
    return 2;
  }
  set_up_logging(config, store);

  try {
    auto station = sherd::station::make_station(config);
    spdlog::info("sherdd starting: {} (scanner: {}; turntable: {}); data in {}", config.name,
                 station.scanner->describe(), station.turntable->describe(), config.paths.data_dir.string());
    sherd::station::JobRunner runner(config, store, std::move(station));
    sherd::station::Server server(config.paths.socket, runner, *store);
    server.start();
    runner.start();

    int signal_number = 0;
    sigwait(&signals, &signal_number);
    spdlog::info("{} received: finishing cleanly", signal_number == SIGTERM ? "SIGTERM" : "SIGINT");
    runner.stop();  // ends every event stream, so the connections can close
    server.stop();
    spdlog::info("sherdd stopped");
    return 0;
  } catch (const std::exception& e) {
    spdlog::critical("{}", e.what());
    return 3;
  }
}
