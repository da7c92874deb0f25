// What both TCP transports (socket and JSON-RPC, through the kit) do with their
// connections: one over max_connections, and resources held without use (issue #17).
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <functional>
#include <stdexcept>

#include "socket_test_fixture.h"
#include "socket_test_support.h"

namespace simgate::socket::test {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

// ---- what both TCP transports do with a connection over max_connections

// Reads until the peer closes (or `timeout` passes): what was received, and whether it ended.
std::pair<std::string, bool> read_to_end(int fd, std::chrono::seconds timeout) {
  timeval tv{static_cast<time_t>(timeout.count()), 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  std::string received;
  char buffer[4096];
  for (;;) {
    ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
    if (n == 0 || (n < 0 && errno == ECONNRESET)) return {received, true};
    if (n < 0) return {received, false};  // timeout
    received.append(buffer, std::size_t(n));
  }
}

// `receive_buffer` (bytes, 0: the system's), set before connecting: the window it offers.
int connect_raw(std::uint16_t port, int receive_buffer = 0) {
  int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd >= 0 && receive_buffer > 0)
    ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &receive_buffer, sizeof receive_buffer);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (fd < 0 || ::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0)
    throw std::runtime_error(std::string("connect: ") + std::strerror(errno));
  return fd;
}

// The transport (plugin name) under test, with a `test ping` service, and `test hold`
// (async: ends on `test release`).
class TcpTransportFixture : public ::testing::TestWithParam<std::string> {
 protected:
  void start(json options) {
    plugin_ = load_transport_plugin(std::string(SIMGATE_TEST_PLUGIN_DIR) +
                                    "/libsimgate_transport_" + GetParam() + ".so");
    options["port"] = 0;
    manager_ = plugin_->create(options, "transports." + GetParam());
    manager_->register_service("test", [] { return std::string("pong"); }, "ping");
    manager_->register_async_service(
        "test",
        [this](Completion done) {
          held_ = done;
          return true;
        },
        "hold");
    manager_->register_service(
        "test",
        [this] {
          const bool done = held_(Status::success, json("released"));
          held_ = Completion();
          return done;
        },
        "release");
    manager_->register_service("test", [this] { return ++touched_; }, "touch");
    manager_->register_service("test", [] { return std::string(k_big_reply_bytes, 'x'); }, "big");
    manager_->start();
    const std::string endpoint = manager_->endpoints().at(0);
    port_ = static_cast<std::uint16_t>(std::stoi(endpoint.substr(endpoint.rfind(':') + 1)));
    loop_ = std::thread([this] {
      while (!stop_.load()) manager_->process(50ms);
    });
  }
  void TearDown() override {
    if (!manager_) return;
    stop_ = true;
    manager_->gate()->signal();
    loop_.join();
    manager_->stop();
  }
  // `service` of `test` in the transport's protocol, with its newline.
  std::string request(const std::string& service) const {
    return GetParam() == "socket"
               ? "p test " + service + "\n"
               : "{\"jsonrpc\":\"2.0\",\"method\":\"test." + service + "\",\"id\":1}\n";
  }
  // One call in the transport's protocol on `fd`, and the first line of its answer.
  std::string ping(int fd, const std::string& service = "ping") {
    const std::string request = this->request(service);
    if (::send(fd, request.data(), request.size(), MSG_NOSIGNAL) !=
        static_cast<ssize_t>(request.size()))
      throw std::runtime_error("send failed");
    timeval tv{10, 0};
    ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    std::string line;
    char ch = 0;
    while (::recv(fd, &ch, 1, 0) == 1 && ch != '\n') line += ch;
    return line;
  }
  // Keeps `busy` calling, running `meanwhile` before each call, until a newcomer is let in
  // (30 attempts, 100 ms apart); the newcomer's answer ("" when it never was).
  std::string newcomer_answer_once_room_is_made(int busy,
                                                const std::function<void()>& meanwhile = {}) {
    std::string answer;
    for (int i = 0; i < 30 && answer.find("pong") == std::string::npos; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      if (meanwhile) meanwhile();
      EXPECT_THAT(ping(busy), ::testing::HasSubstr("pong"));
      int newcomer = connect_raw(port_);
      answer = ping(newcomer);
      ::close(newcomer);
    }
    return answer;
  }

  std::shared_ptr<TransportPlugin> plugin_;  // keeps the library loaded
  std::shared_ptr<RequestManager> manager_;  // the transport under test
  std::uint16_t port_ = 0;                   // its ephemeral port
  std::thread loop_;                         // runs process()
  std::atomic<bool> stop_{false};            // ends loop_
  Completion held_;                          // test hold's call (the process() thread)
  std::atomic<int> touched_{0};              // test touch's calls
  static constexpr std::size_t k_big_reply_bytes = 6000000;  // test big's reply
};

class TcpTransportOverTheLimit : public TcpTransportFixture {
 protected:
  void SetUp() override { start({{"max_connections", 1}, {"idle_evict_s", 0}}); }
};

TEST_P(TcpTransportOverTheLimit, IsToldWhyInOneLineThenClosedAndLoggedOnce) {
  WarningLog warnings;
  int first = connect_raw(port_);
  EXPECT_THAT(ping(first), HasSubstr("pong"));  // accepted: the one connection allowed
  for (int i = 0; i < 2; ++i) {
    int extra = connect_raw(port_);
    auto [received, ended] = read_to_end(extra, 10s);
    ::close(extra);
    EXPECT_TRUE(ended) << "connection " << i << " over the limit was kept";
    EXPECT_EQ(std::count(received.begin(), received.end(), '\n'), 1) << received;
    EXPECT_THAT(received, HasSubstr("too many connections (max_connections 1)"));
  }
  // one warning for the two refusals, naming the option
  EXPECT_EQ(warnings.count("refused a connection"), 1u)
      << ::testing::PrintToString(warnings.lines());
  EXPECT_EQ(warnings.count("(max_connections 1)"), 1u);
  EXPECT_THAT(ping(first), HasSubstr("pong"));  // the connection within the limit is served on
  ::close(first);
}

INSTANTIATE_TEST_SUITE_P(SocketAndJsonRpc, TcpTransportOverTheLimit,
                         ::testing::Values("socket", "jsonrpc"));

// ---- resources held without use (issue #17, item 7): both TCP transports, through the kit

using TcpTransportResources = TcpTransportFixture;

TEST_P(TcpTransportResources, ALineNotFinishedInTimeClosesItsConnection) {
  start({{"line_timeout_s", 0.5}});
  int slow = connect_raw(port_);
  int good = connect_raw(port_);
  const std::string begun = request("ping").substr(0, 8);  // no newline: a line begun
  ASSERT_EQ(::send(slow, begun.data(), begun.size(), MSG_NOSIGNAL),
            static_cast<ssize_t>(begun.size()));
  auto [received, ended] = read_to_end(slow, 10s);
  ::close(slow);
  EXPECT_TRUE(ended) << "a connection sat on an unfinished line past line_timeout_s";
  EXPECT_THAT(ping(good), HasSubstr("pong"));  // a connection sending whole lines is served on
  ::close(good);
}

TEST_P(TcpTransportResources, AnIdleConnectionIsClosedButNotOneWaitingForAnAnswer) {
  start({{"idle_timeout_s", 0.5}});
  int idle = connect_raw(port_);
  EXPECT_THAT(ping(idle), HasSubstr("pong"));
  int waiting = connect_raw(port_);
  const std::string hold = request("hold");
  ASSERT_EQ(::send(waiting, hold.data(), hold.size(), MSG_NOSIGNAL),
            static_cast<ssize_t>(hold.size()));
  auto [received, ended] = read_to_end(idle, 10s);
  ::close(idle);
  EXPECT_TRUE(ended) << "an idle connection was kept past idle_timeout_s";
  // the one owed an answer is not idle: it gets it (a second connection releases the call)
  int other = connect_raw(port_);
  EXPECT_THAT(ping(other, "release"), Not(HasSubstr("rror")));
  auto [answer, closed] = read_to_end(waiting, 2s);
  EXPECT_THAT(answer, HasSubstr("released"));
  ::close(waiting);
  ::close(other);
}

TEST_P(TcpTransportResources, AtTheLimitTheConnectionIdleLongestMakesRoom) {
  WarningLog warnings;
  start({{"max_connections", 2}, {"idle_evict_s", 0.5}});
  int oldest = connect_raw(port_);
  EXPECT_THAT(ping(oldest), HasSubstr("pong"));
  int busy = connect_raw(port_);
  EXPECT_THAT(ping(busy), HasSubstr("pong"));
  // `busy` keeps sending, `oldest` does not: after idle_evict_s a newcomer takes its place
  for (int i = 0; i < 20 && warnings.count("to make room") == 0; ++i) {
    std::this_thread::sleep_for(100ms);
    EXPECT_THAT(ping(busy), HasSubstr("pong"));
    int newcomer = connect_raw(port_);
    const std::string answer = ping(newcomer);
    ::close(newcomer);
    if (answer.find("pong") != std::string::npos) break;
  }
  EXPECT_EQ(warnings.count("to make room"), 1u) << ::testing::PrintToString(warnings.lines());
  auto [received, ended] = read_to_end(oldest, 10s);
  EXPECT_TRUE(ended) << "the idle connection was kept";
  EXPECT_THAT(ping(busy), HasSubstr("pong"));  // the busy one was never chosen
  ::close(oldest);
  ::close(busy);
}

// issue #35 item 9: a connection that sends only blank lines is idle (before, each blank
// line kept its place, and 1 024 of them locked newcomers out for good)
TEST_P(TcpTransportResources, AtTheLimitAConnectionSendingOnlyBlankLinesIsIdleAndMakesRoom) {
  WarningLog warnings;
  start({{"max_connections", 2}, {"idle_evict_s", 0.5}});
  int blank = connect_raw(port_);
  EXPECT_THAT(ping(blank), HasSubstr("pong"));
  int busy = connect_raw(port_);
  EXPECT_THAT(ping(busy), HasSubstr("pong"));
  // (the send fails once it is closed: the newcomer is in then)
  const std::string answer =
      newcomer_answer_once_room_is_made(busy, [&] { ::send(blank, "\n", 1, MSG_NOSIGNAL); });
  EXPECT_THAT(answer, HasSubstr("pong")) << "the newcomer was never let in";
  EXPECT_EQ(warnings.count("to make room"), 1u) << ::testing::PrintToString(warnings.lines());
  auto [received, ended] = read_to_end(blank, 10s);
  EXPECT_TRUE(ended) << "the connection sending blank lines was kept";
  EXPECT_THAT(ping(busy), HasSubstr("pong"));
  ::close(blank);
  ::close(busy);
}

// issue #17 (bench/attacks 7a'): a client whose every connection waits for a call that never
// ends (`time sleep [1e9]`) owes nothing idle; at the limit the one silent longest makes room
TEST_P(TcpTransportResources, AtTheLimitAConnectionSilentWhileItWaitsMakesRoomToo) {
  WarningLog warnings;
  start({{"max_connections", 2}, {"idle_evict_s", 0.5}});
  int waiting = connect_raw(port_);
  const std::string hold = request("hold");
  ASSERT_EQ(::send(waiting, hold.data(), hold.size(), MSG_NOSIGNAL),
            static_cast<ssize_t>(hold.size()));
  int busy = connect_raw(port_);
  EXPECT_THAT(ping(busy), HasSubstr("pong"));
  const std::string answer = newcomer_answer_once_room_is_made(busy);
  EXPECT_THAT(answer, HasSubstr("pong")) << "the newcomer was never let in";
  EXPECT_EQ(warnings.count("replies owed"), 1u) << ::testing::PrintToString(warnings.lines());
  auto [received, ended] = read_to_end(waiting, 10s);
  EXPECT_TRUE(ended) << "the silent connection was kept";
  EXPECT_THAT(ping(busy), HasSubstr("pong"));  // the busy one was never chosen
  ::close(waiting);
  ::close(busy);
}

TEST_P(TcpTransportResources, UnfinishedLinesOfAllConnectionsStayUnderMaxBufferedBytes) {
  WarningLog warnings;
  start({{"max_buffered_bytes", 65536}});
  // three clients each begin a 30 000-byte line (under max_message_bytes): the third would
  // take the transport past 64 KiB held and is closed; the first two finish and are served
  std::vector<int> fds;
  const std::string begun =
      GetParam() == "socket" ? "p test ping [\"" : "{\"jsonrpc\":\"2.0\",\"id\":1,\"x\":\"";
  for (int i = 0; i < 3; ++i) {
    fds.push_back(connect_raw(port_));
    const std::string part = begun + std::string(30000, 'x');
    ASSERT_EQ(::send(fds.back(), part.data(), part.size(), MSG_NOSIGNAL),
              static_cast<ssize_t>(part.size()));
    std::this_thread::sleep_for(100ms);  // read in this order
  }
  auto [received, ended] = read_to_end(fds[2], 10s);
  EXPECT_TRUE(ended) << "the connection past max_buffered_bytes was kept";
  EXPECT_EQ(warnings.count("max_buffered_bytes"), 1u) << ::testing::PrintToString(warnings.lines());
  for (int i = 0; i < 2; ++i) {
    const std::string end = GetParam() == "socket" ? "\"]\n" : "\",\"method\":\"test.ping\"}\n";
    ASSERT_EQ(::send(fds[i], end.data(), end.size(), MSG_NOSIGNAL),
              static_cast<ssize_t>(end.size()));
    timeval tv{10, 0};
    ::setsockopt(fds[i], SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    std::string line;
    char ch = 0;
    while (::recv(fds[i], &ch, 1, 0) == 1 && ch != '\n') line += ch;
    EXPECT_FALSE(line.empty()) << "connection " << i << " within the budget got no answer";
  }
  for (int fd : fds) ::close(fd);
}

// issue #35, item 6: a reply that finds nothing unsent on its connection was queued whatever
// the transport held, so clients that each asked one large reply and read nothing held
// memory past max_buffered_bytes without bound (one reply each)
TEST_P(TcpTransportResources, FirstRepliesOfClientsThatDoNotReadStayUnderMaxBufferedBytes) {
  WarningLog warnings;
  start({{"max_buffered_bytes", 1 << 20}, {"max_message_bytes", 2 << 20}});
  // a client's unfinished line holds 700 kB of the 1 MiB; then four clients offering a small
  // window each ask a 6 MB reply (more than the kernel takes at once) and read nothing
  int occupier = connect_raw(port_);
  const std::string begun =
      GetParam() == "socket" ? "p test ping [\"" : "{\"jsonrpc\":\"2.0\",\"id\":1,\"x\":\"";
  const std::string part = begun + std::string(700000, 'x');
  ASSERT_EQ(::send(occupier, part.data(), part.size(), MSG_NOSIGNAL),
            static_cast<ssize_t>(part.size()));
  std::this_thread::sleep_for(100ms);
  std::vector<int> fds;
  const std::string big = request("big");
  for (int i = 0; i < 4; ++i) {
    fds.push_back(connect_raw(port_, 4096));
    ASSERT_EQ(::send(fds.back(), big.data(), big.size(), MSG_NOSIGNAL),
              static_cast<ssize_t>(big.size()));
  }
  int reader = connect_raw(port_);
  EXPECT_THAT(ping(reader), HasSubstr("pong")) << "a client that reads is served";
  // each reply took the transport past its budget and was not taken at once: closed
  int closed = 0;
  for (int fd : fds) {
    auto [received, ended] = read_to_end(fd, 2s);
    if (ended && received.size() < k_big_reply_bytes) ++closed;
  }
  EXPECT_EQ(closed, 4) << "unread first replies held past max_buffered_bytes";
  EXPECT_GE(warnings.count("max_buffered_bytes"), 4u) << ::testing::PrintToString(warnings.lines());
  // the client within the budget finishes its line and is answered
  const std::string end = GetParam() == "socket" ? "\"]\n" : "\",\"method\":\"test.ping\"}\n";
  ASSERT_EQ(::send(occupier, end.data(), end.size(), MSG_NOSIGNAL),
            static_cast<ssize_t>(end.size()));
  auto [answer, ended] = read_to_end(occupier, 2s);
  EXPECT_FALSE(ended);
  EXPECT_NE(answer.find('\n'), std::string::npos) << "the client within the budget got no answer";
  EXPECT_THAT(ping(reader), HasSubstr("pong"));
  for (int fd : fds) ::close(fd);
  ::close(occupier);
  ::close(reader);
}

INSTANTIATE_TEST_SUITE_P(SocketAndJsonRpc, TcpTransportResources,
                         ::testing::Values("socket", "jsonrpc"));

// ---- cross-site requests (issue #35, item 4): both TCP transports, through the kit

using TcpTransportCrossSite = TcpTransportFixture;

// What a browser sends for fetch("http://127.0.0.1:<port>/", {mode: "no-cors", method: "POST",
// body}) from any web page: the request line, the headers, then the body.
std::string browser_post(std::uint16_t port, const std::string& body) {
  return "POST / HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(port) +
         "\r\nConnection: keep-alive\r\nContent-Length: " + std::to_string(body.size()) +
         "\r\nContent-Type: text/plain;charset=UTF-8\r\nOrigin: http://attacker.example\r\nAccept: "
         "*/*\r\n\r\n" +
         body;
}

TEST_P(TcpTransportCrossSite, ABrowsersPostIsClosedAtItsRequestLineAndItsBodyNeverRuns) {
  start({});
  WarningLog warnings;
  int page = connect_raw(port_);
  const std::string post = browser_post(port_, request("touch") + request("touch"));
  ASSERT_EQ(::send(page, post.data(), post.size(), MSG_NOSIGNAL),
            static_cast<ssize_t>(post.size()));
  auto [received, ended] = read_to_end(page, 10s);
  ::close(page);
  EXPECT_TRUE(ended) << "the connection of an HTTP request was kept";
  EXPECT_EQ(received, "") << "the headers or the body were answered";
  // the transport serves on; the body never ran
  int good = connect_raw(port_);
  EXPECT_THAT(ping(good), HasSubstr("pong"));
  ::close(good);
  EXPECT_EQ(touched_.load(), 0);
  EXPECT_EQ(warnings.count("closed on an HTTP request line ('POST / HTTP/1.1"), 1u)
      << ::testing::PrintToString(warnings.lines());
}

TEST_P(TcpTransportCrossSite, TheBodyInALaterSegmentNeverRunsEither) {
  start({});
  int page = connect_raw(port_);
  const std::string head = "GET /x HTTP/1.0\r\n";
  ASSERT_EQ(::send(page, head.data(), head.size(), MSG_NOSIGNAL),
            static_cast<ssize_t>(head.size()));
  auto [received, ended] = read_to_end(page, 10s);
  EXPECT_TRUE(ended);
  EXPECT_EQ(received, "");
  const std::string body = request("touch");
  ::send(page, body.data(), body.size(),
         MSG_NOSIGNAL);  // to a closed connection: fails or is dropped
  ::close(page);
  int good = connect_raw(port_);
  EXPECT_THAT(ping(good), HasSubstr("pong"));
  ::close(good);
  EXPECT_EQ(touched_.load(), 0);
}

INSTANTIATE_TEST_SUITE_P(SocketAndJsonRpc, TcpTransportCrossSite,
                         ::testing::Values("socket", "jsonrpc"));

}  // namespace
}  // namespace simgate::socket::test
