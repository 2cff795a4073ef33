#include "harness.h"

#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <random>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <thread>

extern char** environ;

namespace sherd::testing {
namespace {

std::string slurp(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

pid_t spawn(const std::vector<std::string>& argv, const std::filesystem::path& out,
            const std::filesystem::path& err) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 1, out.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
  posix_spawn_file_actions_addopen(&actions, 2, err.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) throw std::runtime_error("cannot start " + argv[0]);
  return pid;
}

int wait_exit(pid_t pid, std::chrono::seconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  int status = 0;
  while (waitpid(pid, &status, WNOHANG) == 0) {
    if (std::chrono::steady_clock::now() > deadline) {
      ::kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      return -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

}  // namespace

std::filesystem::path binary(const std::string& name) {
  for (const char* dir : {"daemon", "simulators"}) {
    const auto path = std::filesystem::path(SHERD_BINARY_DIR) / dir / name;
    if (std::filesystem::exists(path)) return path;
  }
  throw std::runtime_error("no binary " + name + " in " SHERD_BINARY_DIR);
}

ProcessResult run(const std::vector<std::string>& argv, std::chrono::seconds timeout) {
  TempDir capture;
  const auto out = capture.path() / "out", err = capture.path() / "err";
  const pid_t pid = spawn(argv, out, err);
  ProcessResult result;
  result.exit_code = wait_exit(pid, timeout);
  result.out = slurp(out);
  result.err = slurp(err);
  return result;
}

TestStation::TestStation(const std::map<std::string, std::string>& overrides) {
  config_file = dir.path() / "station.toml";
  data = dir.path() / "data";
  std::ofstream(config_file) << station_config_with(overrides);
  std::filesystem::copy_file(std::filesystem::path(SHERD_SOURCE_DIR) / "config" / "materials.xml",
                             dir.path() / "materials.xml");
  config = config::load_station_config(config_file);
  config::set_data_dir(config, data);
}

std::string station_config_with(const std::map<std::string, std::string>& overrides) {
  std::istringstream in(slurp(std::filesystem::path(SHERD_SOURCE_DIR) / "config" / "station.toml"));
  std::map<std::string, bool> used;
  std::string table, line, result;
  const std::regex header(R"(^\s*\[([A-Za-z0-9_.]+)\]\s*(#.*)?$)");
  const std::regex assignment(R"(^\s*([A-Za-z0-9_]+)\s*=.*$)");
  std::smatch m;
  while (std::getline(in, line)) {
    if (std::regex_match(line, m, header)) {
      table = m[1];
    } else if (std::regex_match(line, m, assignment)) {
      const auto key = table + "." + m[1].str();
      if (auto it = overrides.find(key); it != overrides.end()) {
        line = m[1].str() + " = " + it->second;
        used[key] = true;
      }
    }
    result += line + "\n";
  }
  for (const auto& [key, value] : overrides) {
    if (!used[key]) throw std::runtime_error("config/station.toml has no key " + key);
  }
  return result;
}

TempDir::TempDir() {
  std::random_device rd;
  path_ = std::filesystem::temp_directory_path() / ("sherdscan-test-" + std::to_string(rd()));
  std::filesystem::create_directories(path_);
}

TempDir::~TempDir() {
  const auto* test = ::testing::UnitTest::GetInstance()->current_test_info();
  const bool failed = test && test->result() && test->result()->Failed();
  std::error_code ignored;
  if (!failed) std::filesystem::remove_all(path_, ignored);
}

Daemon::Daemon(std::filesystem::path config, std::filesystem::path data_dir)
    : config_(std::move(config)), data_dir_(std::move(data_dir)) {}

Daemon::~Daemon() {
  if (running()) terminate();
}

void Daemon::start() {
  std::filesystem::create_directories(data_dir_);
  pid_ = spawn({binary("sherdd").string(), "--config", config_.string(), "--data-dir", data_dir_.string()},
               data_dir_ / "sherdd.stdout", data_dir_ / "sherdd.stderr");
  for (int i = 0; i < 600; ++i) {
    if (std::filesystem::exists(socket())) {
      const auto status = run({binary("sherdctl").string(), "--socket", socket().string(), "status"},
                              std::chrono::seconds(10));
      if (status.exit_code == 0) return;
    }
    int st = 0;
    if (waitpid(pid_, &st, WNOHANG) == pid_) {
      pid_ = -1;
      throw std::runtime_error("sherdd exited at start: " + log());
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  throw std::runtime_error("sherdd did not answer within 30 s: " + log());
}

int Daemon::terminate() {
  if (pid_ < 0) return -1;
  ::kill(pid_, SIGTERM);
  const int code = wait_exit(pid_, std::chrono::seconds(120));
  pid_ = -1;
  return code;
}

void Daemon::kill9() {
  if (pid_ < 0) return;
  ::kill(pid_, SIGKILL);
  int status = 0;
  waitpid(pid_, &status, 0);
  pid_ = -1;
}

bool Daemon::running() const { return pid_ > 0 && ::kill(pid_, 0) == 0; }

std::string Daemon::log() const { return slurp(data_dir_ / "sherdd.stderr"); }

}  // namespace sherd::testing
