#include "daemon/server.h"

#include "core/errors.h"
#include "daemon/protocol.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

namespace sherd::station {
namespace {

nlohmann::json scan_summary(const db::ScanRecord& scan, db::Store& store) {
  return {{"scan_id", scan.id},
          {"state", db::to_string(scan.state)},
          {"reason", scan.reason},
          {"source", scan.source},
          {"created_at", scan.created_at},
          {"updated_at", scan.updated_at},
          {"planned_views", scan.planned_views},
          {"views", store.views(scan.id).size()},
          {"sherds", store.sherds(scan.id).size()},
          {"output_dir", (std::filesystem::path(scan.output_dir) / scan.id).string()}};
}

bool finished(db::ScanState state) { return state == db::ScanState::Done || state == db::ScanState::Failed; }

}  // namespace

std::string calibration_refusal(const std::string& kind) {
  if (kind == "scanner") {
    return "scanner calibration through sherdd is not available yet (it needs the structured-light "
           "scanner driver): calibrate from captures with `sherdctl calibrate scanner --captures "
           "DIR…`";
  }
  return fmt::format("unknown calibration \"{}\": use `sherdctl calibrate turntable`", kind);
}

namespace {

}  // namespace

Server::Server(const std::filesystem::path& socket_path, JobRunner& runner, db::Store& store)
    : socket_path_(socket_path), runner_(runner), store_(store) {}

Server::~Server() { stop(); }

void Server::start() {
  listen_fd_ = listen_unix(socket_path_);
  if (::pipe2(wake_pipe_, O_CLOEXEC) != 0) throw InputError("cannot create the server's wake-up pipe");
  accept_thread_ = std::thread([this] { accept_loop(); });
  spdlog::info("listening on {}", socket_path_.string());
}

void Server::stop() {
  {
    std::lock_guard lock(mutex_);
    if (stopped_ || listen_fd_ < 0) return;
    stopped_ = true;
    for (int fd : open_fds_) ::shutdown(fd, SHUT_RDWR);  // wakes connections blocked in recv
  }
  const char byte = 0;
  [[maybe_unused]] auto n = ::write(wake_pipe_[1], &byte, 1);
  if (accept_thread_.joinable()) accept_thread_.join();
  for (auto& c : connections_) c.thread.join();
  ::close(listen_fd_);
  ::close(wake_pipe_[0]);
  ::close(wake_pipe_[1]);
  std::error_code ignored;
  std::filesystem::remove(socket_path_, ignored);
}

void Server::accept_loop() {
  while (true) {
    pollfd fds[2] = {{listen_fd_, POLLIN, 0}, {wake_pipe_[0], POLLIN, 0}};
    if (::poll(fds, 2, -1) < 0) continue;  // EINTR
    if (fds[1].revents) return;
    if (!(fds[0].revents & POLLIN)) continue;
    const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC);
    if (fd < 0) continue;
    std::lock_guard lock(mutex_);
    if (stopped_) {
      ::close(fd);
      return;
    }
    for (auto it = connections_.begin(); it != connections_.end();) {
      if (*it->done) {
        it->thread.join();
        it = connections_.erase(it);
      } else {
        ++it;
      }
    }
    open_fds_.insert(fd);
    auto done = std::make_shared<std::atomic<bool>>(false);
    connections_.push_back({std::thread([this, fd, done] {
                              serve(fd);
                              *done = true;
                            }),
                            done});
  }
}

void Server::stream(JsonLineSocket& socket, const std::shared_ptr<Subscription>& subscription) {
  while (auto event = subscription->next()) {
    if (!socket.send(*event)) return;  // the client went away; the scan goes on without it
  }
}

void Server::serve(int fd) {
  {
    JsonLineSocket socket(fd);
    try {
      while (auto request = socket.receive()) {
        const std::string cmd = request->value("cmd", "");
        if (cmd == "scan") {
          auto [scan_id, subscription] = runner_.submit_scan(MaterialChoice::from_json(*request));
          socket.send({{"ok", true}, {"scan_id", scan_id}});
          stream(socket, subscription);
          break;
        }
        if (cmd == "calibrate") {
          const std::string kind = request->value("kind", "");
          if (kind != "turntable") {
            socket.send({{"ok", false}, {"error", calibration_refusal(kind)}});
            break;
          }
          auto [job_id, subscription] = runner_.submit_turntable_calibration();
          socket.send({{"ok", true}, {"scan_id", job_id}});
          stream(socket, subscription);
          break;
        }
        if (cmd == "follow") {
          const std::string scan_id = request->value("scan_id", "");
          auto subscription = runner_.subscribe(scan_id);  // before the check: no event slips by
          const auto scan = store_.scan(scan_id);
          if (!scan) {
            socket.send({{"ok", false}, {"error", fmt::format("no scan {}: see `sherdctl jobs`", scan_id)}});
            break;
          }
          socket.send({{"ok", true}, {"scan_id", scan_id}});
          if (finished(scan->state)) {
            socket.send({{"event", "finished"}, {"scan_id", scan_id}, {"state", db::to_string(scan->state)},
                         {"reason", scan->reason}});
          } else {
            stream(socket, subscription);
          }
          break;
        }
        socket.send(answer(*request));
      }
    } catch (const std::exception& e) {
      socket.send({{"ok", false}, {"error", e.what()}});
    }
  }  // the socket closes here, before the descriptor number can be reused
  std::lock_guard lock(mutex_);
  open_fds_.erase(fd);
}

nlohmann::json Server::answer(const nlohmann::json& request) {
  const std::string cmd = request.value("cmd", "");
  if (cmd == "status") return {{"ok", true}, {"status", runner_.status()}};
  if (cmd == "jobs") {
    auto jobs = nlohmann::json::array();
    for (const auto& scan : store_.scans(request.value("limit", 20))) jobs.push_back(scan_summary(scan, store_));
    return {{"ok", true}, {"jobs", jobs}};
  }
  if (cmd == "show") {
    const std::string scan_id = request.value("scan_id", "");
    const auto scan = store_.scan(scan_id);
    if (!scan) return {{"ok", false}, {"error", fmt::format("no scan {}: see `sherdctl jobs` for the ids", scan_id)}};
    auto views = nlohmann::json::array();
    for (const auto& v : store_.views(scan_id)) {
      views.push_back({{"index", v.index}, {"raw", v.raw_path}, {"commanded_angle_deg", v.commanded_angle_deg},
                       {"measured_angle_deg", v.measured_angle_deg}, {"points", v.valid_points},
                       {"registration", v.registration}});
    }
    auto sherds = nlohmann::json::array();
    for (const auto& s : store_.sherds(scan_id)) sherds.push_back(s.summary);
    auto artifacts = nlohmann::json::array();
    for (const auto& [kind, path] : store_.artifacts(scan_id)) artifacts.push_back({{"kind", kind}, {"path", path}});
    return {{"ok", true},          {"scan", scan_summary(*scan, store_)}, {"views", views},
            {"sherds", sherds},    {"stages", store_.stages(scan_id)},    {"artifacts", artifacts}};
  }
  return {{"ok", false},
          {"error", fmt::format("unknown command \"{}\": use scan, calibrate, follow, status, jobs or show", cmd)}};
}

}  // namespace sherd::station
