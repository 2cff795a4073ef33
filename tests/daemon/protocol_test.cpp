// The control socket: JSON lines over a real Unix domain socket.
#include "core/errors.h"
#include "daemon/protocol.h"

#include <gtest/gtest.h>

#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <random>
#include <thread>

namespace sherd::station {
namespace {

std::filesystem::path temp_socket() {
  std::random_device rd;
  return std::filesystem::temp_directory_path() / ("sherd-proto-" + std::to_string(rd())) / "s.sock";
}

TEST(Protocol, MessagesSplitAcrossWritesAndSeveralPerWriteArriveWhole) {
  int fds[2];
  ASSERT_EQ(::socketpair(AF_UNIX, SOCK_STREAM, 0, fds), 0);
  JsonLineSocket reader(fds[0]);
  // Two messages in one write, the second split over two writes.
  const std::string a = R"({"cmd":"status"})" "\n" R"({"cmd":"sh)", b = R"(ow","scan_id":"x"})" "\n";
  ASSERT_EQ(::write(fds[1], a.data(), a.size()), static_cast<ssize_t>(a.size()));
  ASSERT_EQ(::write(fds[1], b.data(), b.size()), static_cast<ssize_t>(b.size()));
  ::close(fds[1]);
  EXPECT_EQ((*reader.receive())["cmd"], "status");
  const auto second = reader.receive();
  EXPECT_EQ((*second)["cmd"], "show");
  EXPECT_EQ((*second)["scan_id"], "x");
  EXPECT_FALSE(reader.receive().has_value());  // peer closed
}

TEST(Protocol, ALineThatIsNotJsonIsAnInputError) {
  int fds[2];
  ASSERT_EQ(::socketpair(AF_UNIX, SOCK_STREAM, 0, fds), 0);
  JsonLineSocket reader(fds[0]);
  const std::string garbage = "scan please\n";
  ASSERT_EQ(::write(fds[1], garbage.data(), garbage.size()), static_cast<ssize_t>(garbage.size()));
  EXPECT_THROW(reader.receive(), InputError);
  ::close(fds[1]);
}

TEST(Protocol, ListenerIsOwnerAndGroupOnlyAndRefusesToDisplaceALiveDaemon) {
  const auto path = temp_socket();
  const int fd = listen_unix(path);
  struct stat st {};
  ASSERT_EQ(::stat(path.c_str(), &st), 0);
  EXPECT_TRUE(S_ISSOCK(st.st_mode));
  EXPECT_EQ(st.st_mode & 0777, 0660u);
  EXPECT_THROW(listen_unix(path), InputError);

  std::thread server([fd] {
    // The first connection is listen_unix's liveness probe above, which closes without a word.
    while (true) {
      JsonLineSocket connection(::accept(fd, nullptr, nullptr));
      if (auto request = connection.receive()) {
        connection.send({{"echo", (*request)["cmd"]}});
        return;
      }
    }
  });
  auto client = connect_unix(path);
  client.send({{"cmd", "ping"}});
  EXPECT_EQ((*client.receive())["echo"], "ping");
  server.join();
  ::close(fd);

  // The listener is gone: its file is stale and a new daemon may take the path.
  const int again = listen_unix(path);
  EXPECT_GE(again, 0);
  ::close(again);
  std::filesystem::remove_all(path.parent_path());
}

TEST(Protocol, ConnectingToNoDaemonSaysHowToStartIt) {
  try {
    connect_unix(temp_socket());
    FAIL() << "connected to nothing";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("sherdd --config"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace sherd::station
