// Test harness for the end-to-end tests: real processes (sherdd, sherdctl) started from the
// build tree, in a temporary station directory, talking over the real Unix socket.
#pragma once

#include "config/station_config.h"

#include <sys/types.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace sherd::testing {

struct ProcessResult {
  int exit_code = -1;
  std::string out, err;
};

std::filesystem::path binary(const std::string& name);  // build/daemon/sherdd, …

// Runs a program to completion (killing it after `timeout`), capturing stdout and stderr.
ProcessResult run(const std::vector<std::string>& argv,
                  std::chrono::seconds timeout = std::chrono::seconds(300));

// The shipped config/station.toml with some keys replaced: {"turntable.time_scale", "0.1"}.
// A key not present in the file is an error (the test would silently test something else).
std::string station_config_with(const std::map<std::string, std::string>& overrides);

// A fresh temporary directory, removed at destruction unless the test failed.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

// A station directory: the shipped config with `overrides`, materials.xml beside it (where the
// config finds it), and the parsed config pointing at its own data directory.
struct TestStation {
  TempDir dir;
  std::filesystem::path config_file, data;
  config::StationConfig config;

  explicit TestStation(const std::map<std::string, std::string>& overrides);
};

// sherdd running on a station directory.
class Daemon {
 public:
  Daemon(std::filesystem::path config, std::filesystem::path data_dir);
  ~Daemon();  // SIGTERM, then SIGKILL if it does not stop
  void start();                 // waits until the socket answers
  int terminate();              // SIGTERM; returns the exit code
  void kill9();                 // SIGKILL, no clean-up: a power cut
  bool running() const;
  std::filesystem::path socket() const { return data_dir_ / "sherdd.sock"; }
  std::string log() const;      // what sherdd wrote to stderr

 private:
  std::filesystem::path config_, data_dir_;
  pid_t pid_ = -1;
};

}  // namespace sherd::testing
