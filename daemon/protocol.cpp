#include "daemon/protocol.h"

#include "core/errors.h"

#include <fmt/format.h>

#include <cerrno>
#include <cstring>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

namespace sherd::station {
namespace {

sockaddr_un unix_address(const std::filesystem::path& path) {
  sockaddr_un address{};
  address.sun_family = AF_UNIX;
  const auto text = path.string();
  if (text.size() >= sizeof(address.sun_path)) {
    throw InputError(fmt::format("socket path {} is longer than {} characters: set a shorter station.socket",
                                 text, sizeof(address.sun_path) - 1));
  }
  std::memcpy(address.sun_path, text.c_str(), text.size() + 1);
  return address;
}

}  // namespace

JsonLineSocket::~JsonLineSocket() {
  if (fd_ >= 0) ::close(fd_);
}

bool JsonLineSocket::send(const nlohmann::json& message) {
  const std::string line = message.dump() + "\n";
  std::size_t sent = 0;
  while (sent < line.size()) {
    const ssize_t n = ::send(fd_, line.data() + sent, line.size() - sent, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    sent += static_cast<std::size_t>(n);
  }
  return true;
}

std::optional<nlohmann::json> JsonLineSocket::receive() {
  while (true) {
    const auto newline = buffer_.find('\n');
    if (newline != std::string::npos) {
      const std::string line = buffer_.substr(0, newline);
      buffer_.erase(0, newline + 1);
      try {
        return nlohmann::json::parse(line);
      } catch (const nlohmann::json::parse_error& e) {
        throw InputError(fmt::format("control socket: a message is not JSON ({}): send one JSON object per line",
                                     e.what()));
      }
    }
    char chunk[4096];
    const ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return std::nullopt;
    buffer_.append(chunk, static_cast<std::size_t>(n));
  }
}

int listen_unix(const std::filesystem::path& path) {
  const auto address = unix_address(path);
  std::filesystem::create_directories(path.parent_path());
  if (std::filesystem::exists(path)) {
    // A daemon still answering there must not be displaced; a dead one's file is removed.
    const int probe = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    const bool alive = ::connect(probe, reinterpret_cast<const sockaddr*>(&address), sizeof address) == 0;
    ::close(probe);
    if (alive) {
      throw InputError(fmt::format("another sherdd is already serving {}: stop it first (sherdctl status shows it)",
                                   path.string()));
    }
    std::filesystem::remove(path);
  }
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) throw InputError(fmt::format("cannot create a socket: {}", std::strerror(errno)));
  // Owner and group only, from the moment the file exists.
  const mode_t old_mask = ::umask(0117);
  const bool listening = ::bind(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address) == 0 &&
                         ::listen(fd, 16) == 0;
  const int error = errno;
  ::umask(old_mask);
  if (!listening) {
    ::close(fd);
    throw InputError(fmt::format("cannot listen on {}: {}: check the directory exists and is writable",
                                 path.string(), std::strerror(error)));
  }
  return fd;
}

JsonLineSocket connect_unix(const std::filesystem::path& path) {
  const auto address = unix_address(path);
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) throw InputError(fmt::format("cannot create a socket: {}", std::strerror(errno)));
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) {
    const int error = errno;
    ::close(fd);
    throw InputError(fmt::format("cannot reach sherdd at {}: {}: start it with `sherdd --config FILE`, "
                                 "or point sherdctl at its socket with --socket",
                                 path.string(), std::strerror(error)));
  }
  return JsonLineSocket(fd);
}

}  // namespace sherd::station
