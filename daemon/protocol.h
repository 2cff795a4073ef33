// The control API between sherdctl and sherdd: one JSON object per line over a Unix domain
// socket. Requests: {"cmd": "scan" | "calibrate" | "status" | "jobs" | "show" | "follow", …}
// ("calibrate" with {"kind": "turntable"}; "scan" optionally with {"material": preset,
// "sherd_materials": {sherd_id: preset}}). Replies: one object {"ok": true, …} or {"ok": false,
// "error": "…"}; "scan", "calibrate" and "follow" then stream the job's events until
// {"event": "finished", …} (a calibration's carries {"calibration": {…}}, its figures).
#pragma once

#include <nlohmann/json.hpp>

#include <filesystem>
#include <optional>
#include <string>

namespace sherd::station {

// A connected stream socket carrying JSON lines. Owns the descriptor.
class JsonLineSocket {
 public:
  explicit JsonLineSocket(int fd) : fd_(fd) {}
  ~JsonLineSocket();
  JsonLineSocket(JsonLineSocket&& other) noexcept : fd_(other.fd_), buffer_(std::move(other.buffer_)) { other.fd_ = -1; }
  JsonLineSocket(const JsonLineSocket&) = delete;
  JsonLineSocket& operator=(const JsonLineSocket&) = delete;
  JsonLineSocket& operator=(JsonLineSocket&&) = delete;

  // False when the peer has gone.
  bool send(const nlohmann::json& message);
  // nullopt when the peer closed the connection. Throws InputError on a line that is not JSON.
  std::optional<nlohmann::json> receive();

 private:
  int fd_ = -1;
  std::string buffer_;
};

// Binds and listens on `path` with mode 0660 (owner and group only). A stale socket file left by
// a killed daemon is replaced; a live daemon on it is an error (InputError).
int listen_unix(const std::filesystem::path& path);

// Connects to sherdd. Throws InputError saying how to start it when nobody answers.
JsonLineSocket connect_unix(const std::filesystem::path& path);

}  // namespace sherd::station
