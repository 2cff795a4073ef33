// sherdd's control server: accepts sherdctl connections on the Unix socket and answers them from
// the job runner and the store (see protocol.h for the messages).
#pragma once

#include "daemon/jobs.h"
#include "db/store.h"

#include <atomic>
#include <filesystem>
#include <list>
#include <memory>
#include <mutex>
#include <set>
#include <thread>

namespace sherd::station {

// Why a calibration of `kind` cannot be run (every kind but "turntable"): one line for the operator.
std::string calibration_refusal(const std::string& kind);

class Server {
 public:
  Server(const std::filesystem::path& socket_path, JobRunner& runner, db::Store& store);
  ~Server();
  void start();
  // Stops accepting, ends every connection, removes the socket file. Idempotent.
  void stop();

  // Answers one request that is not a stream (status, jobs, show); exposed for tests.
  nlohmann::json answer(const nlohmann::json& request);

 private:
  void accept_loop();
  void serve(int fd);
  void stream(class JsonLineSocket& socket, const std::shared_ptr<Subscription>& subscription);

  std::filesystem::path socket_path_;
  JobRunner& runner_;
  db::Store& store_;
  int listen_fd_ = -1;
  int wake_pipe_[2] = {-1, -1};
  std::thread accept_thread_;
  std::mutex mutex_;
  std::set<int> open_fds_;
  struct Connection {
    std::thread thread;
    std::shared_ptr<std::atomic<bool>> done;
  };
  std::list<Connection> connections_;  // finished ones are joined at the next accept
  bool stopped_ = false;
};

}  // namespace sherd::station
