// The socket transport's connections over real TCP: clients that leave with requests
// running (on_disconnect), the limits of a connection and of the server, and option names
// shared with the JSON-RPC transport.
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <condition_variable>
#include <mutex>
#include <thread>

#include "socket_test_fixture.h"
#include "socket_test_support.h"

namespace simgate::socket::test {
namespace {

using ::testing::HasSubstr;
using ::testing::StartsWith;

// ---- clients that leave with requests running (on_disconnect)

// An async component that tells when it is interrupted (interrupt() runs under the
// simulation lock, on whichever thread holds it; the test thread waits for it).
class Rover : public Component {
 public:
  Rover() : Component("rover") {
    add_async_service("go", &Rover::go).interruptible();
    add_service("running", &Rover::running);
  }
  void go() {}
  bool running() const { return has_running_request(); }
  void interrupt() override {
    {
      std::lock_guard lock(mutex_);
      ++interrupts_;
    }
    interrupted_.notify_all();
    Component::interrupt();
  }
  // Waits (bounded) for the first interrupt().
  bool wait_interrupted(std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    return interrupted_.wait_for(lock, timeout, [&] { return interrupts_ > 0; });
  }
  int interrupts() {
    std::lock_guard lock(mutex_);
    return interrupts_;
  }

 private:
  std::mutex mutex_;                     // guards interrupts_
  std::condition_variable interrupted_;  // interrupt() ran
  int interrupts_ = 0;                   // interrupt() calls
};

class SocketDisconnect : public SocketFixture {
 protected:
  void register_more(RequestManager& rm) override { rm.register_component(rover_); }
  Rover rover_;  // outlives the manager (TearDown destroys it first)
};

TEST_F(SocketDisconnect, AClientThatLeavesHasItsAsyncRequestInterrupted) {
  start_server();
  auto gone = connect();
  gone->send_line("g rover go");
  EXPECT_EQ(roundtrip(*gone, "p test ping"), "p SUCCESS \"pong\"");  // g has started
  gone.reset();                                                      // closed with g running
  EXPECT_TRUE(rover_.wait_interrupted(10s));
  auto other = connect();
  EXPECT_EQ(roundtrip(*other, "r rover running"), "r SUCCESS false");
  EXPECT_EQ(rover_.interrupts(), 1);
}

TEST_F(SocketDisconnect, AClientThatEndsItsInputHasItsAsyncRequestCancelledAndIsTold) {
  start_server();
  auto c = connect();
  c->send_line("g rover go");
  EXPECT_EQ(roundtrip(*c, "p test ping"), "p SUCCESS \"pong\"");
  c->shutdown_send();
  EXPECT_EQ(next_line(*c), "g PREEMPTED");
  EXPECT_THROW(c->read_line(10s), client::ClientError);  // then the server closes
  EXPECT_EQ(rover_.interrupts(), 1);
}

TEST_F(SocketDisconnect, LetRunLeavesTheRequestsOfAClientThatLeftRunning) {
  start_server({{"on_disconnect", "let_run"}});
  auto gone = connect();
  gone->send_line("g rover go");
  EXPECT_EQ(roundtrip(*gone, "p test ping"), "p SUCCESS \"pong\"");
  gone.reset();
  auto other = connect();
  // a few round trips after the disconnect: the request is still running
  for (int i = 0; i < 5; ++i) EXPECT_EQ(roundtrip(*other, "r rover running"), "r SUCCESS true");
  EXPECT_EQ(rover_.interrupts(), 0);
}

TEST_F(SocketDisconnect, LetRunDropsTheResultOfAClientThatLeftWithoutDisturbingOthers) {
  start_server({{"on_disconnect", "let_run"}});
  {
    auto gone = connect();
    gone->send_line("v1 worker hold (1,)");
    EXPECT_EQ(roundtrip(*gone, "sync test ping"), "sync SUCCESS \"pong\"");
  }  // closed with v1 pending
  auto c = connect();
  EXPECT_EQ(roundtrip(*c, "r worker release (1,)"), "r SUCCESS true");
  EXPECT_EQ(roundtrip(*c, "p test ping"), "p SUCCESS \"pong\"");  // v1's result went nowhere
}

// Replies remember their connection without owning it: the pending requests by a raw
// pointer erased when the connection closes, an error reply deferred behind them by a
// kit::ConnectionRef. A client that vanishes with pipelined requests queued for the
// simulation thread gets nothing, and the next client (in its slot of the server's table)
// gets none of its replies.
class SocketVanishing : public SocketFixture {
 protected:
  void register_more(RequestManager& rm) override {
    rm.register_service("count", [this] { return ++hits_; }, "hit");
  }
  std::atomic<int> hits_{0};
};

// A client that sends bytes, then vanishes: its socket closed with a reset (SO_LINGER 0),
// the way a killed process's goes (what the server had not read yet is lost).
class VanishingClient {
 public:
  explicit VanishingClient(std::uint16_t port) : fd_(::socket(AF_INET, SOCK_STREAM, 0)) {
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(port);
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0)
      ADD_FAILURE() << "cannot connect";
  }
  ~VanishingClient() { vanish(); }
  void send(const std::string& bytes) {
    EXPECT_EQ(::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL),
              static_cast<ssize_t>(bytes.size()));
  }
  void vanish() {
    if (fd_ < 0) return;
    linger reset{1, 0};
    ::setsockopt(fd_, SOL_SOCKET, SO_LINGER, &reset, sizeof reset);
    ::close(fd_);
    fd_ = -1;
  }

 private:
  int fd_;
};

TEST_F(SocketVanishing, RepliesInFlightToAClientThatVanishedGoNowhereNotToTheNextOne) {
  start_server({{"max_message_bytes", 1024}});
  WarningLog warnings;
  std::unique_lock simulating(*manager_->gate());  // the loop is stepping: requests queue
  std::string burst;
  for (int i = 1; i <= 64; ++i) burst += std::to_string(i) + " count hit\n";
  // an error answered in order: deferred behind the 64 requests (answer_in_order)
  burst += "65 count\n";
  // logged once the lines before it went to the core: the client may vanish then
  burst += "66 count hit [" + std::string(2000, ' ') + "]\n";
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  VanishingClient gone(port_);
  gone.send(burst);
  while (warnings.count("request line longer than") == 0 &&
         std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(1ms);
  ASSERT_EQ(warnings.count("request line longer than"), 1u);
  gone.vanish();
  while (manager_->client_count() > 0 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(1ms);
  ASSERT_EQ(manager_->client_count(), 0u) << "the server never saw the client leave";

  // the next client takes the freed slot; then the requests run and their outcomes come back
  auto next = connect();
  while (manager_->client_count() < 1 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(1ms);
  simulating.unlock();
  while (hits_.load() < 64 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(1ms);
  EXPECT_EQ(hits_.load(), 64);
  EXPECT_EQ(roundtrip(*next, "p test ping"), "p SUCCESS \"pong\"");
  // nothing of the vanished client's: the reply above was the only line
  EXPECT_EQ(next->read_line(300ms), std::nullopt);
  EXPECT_EQ(roundtrip(*next, "1 test ping"), "1 SUCCESS \"pong\"");
  EXPECT_EQ(next->read_line(100ms), std::nullopt);
}

class SocketTransportLimits : public SocketFixture {};

TEST_F(SocketTransportLimits, OversizedLineGetsFailedAndConnectionKeepsWorking) {
  start_server({{"max_line_bytes", 1024}});
  auto c = connect();
  std::string huge = "big1 test echo ('" + std::string(5000, 'a') + "',)";
  EXPECT_EQ(roundtrip(*c, huge),
            "big1 FAILED \"Request too long: the line exceeds 1024 bytes (max_line_bytes); it was "
            "ignored\"");
  // a long line arriving in pieces, with its end much later
  c->send_raw("big2 test echo ('" + std::string(3000, 'b'));
  c->send_raw(std::string(3000, 'b') + "',)\nok1 test ping\n");
  EXPECT_EQ(next_line(*c),
            "big2 FAILED \"Request too long: the line exceeds 1024 bytes (max_line_bytes); it was "
            "ignored\"");
  EXPECT_EQ(next_line(*c), "ok1 SUCCESS \"pong\"");
  // exactly at the limit is fine
  std::string prefix = "ok2 test echo ('";
  std::string at_limit = prefix + std::string(1024 - prefix.size() - 3, 'c') + "',)";
  ASSERT_EQ(at_limit.size(), 1024u);
  EXPECT_THAT(roundtrip(*c, at_limit), StartsWith("ok2 SUCCESS \"ccc"));
}

TEST_F(SocketTransportLimits, ClientThatStopsReadingIsDisconnectedOthersAreServed) {
  start_server({{"max_unsent_bytes", 65536}});
  // a client with a tiny receive window that never reads its replies
  int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  ASSERT_GE(fd, 0);
  int small = 4096;
  ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port_);
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  constexpr int k_requests = 300;  // 300 x 64 KiB of replies: far beyond every buffer
  std::string flood;
  for (int i = 0; i < k_requests; ++i) flood += "h" + std::to_string(i) + " test big (65536,)\n";
  ASSERT_EQ(::send(fd, flood.data(), flood.size(), MSG_NOSIGNAL),
            static_cast<ssize_t>(flood.size()));

  // meanwhile a well-behaved client is answered
  auto good = connect();
  EXPECT_EQ(roundtrip(*good, "g1 test_component add (1,2)"), "g1 SUCCESS 3");

  // the flooder is cut off: it can read what the kernel buffered, then the end
  timeval tv{10, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  std::size_t received = 0;
  bool ended = false;
  char buffer[65536];
  for (int reads = 0; reads < 100000; ++reads) {
    ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
    if (n == 0 || (n < 0 && errno == ECONNRESET)) {
      ended = true;
      break;
    }
    if (n < 0) break;  // timeout: not disconnected
    received += static_cast<std::size_t>(n);
  }
  ::close(fd);
  EXPECT_TRUE(ended) << "the server kept a client that does not read";
  EXPECT_LT(received, std::size_t(k_requests) * 65536);
  EXPECT_EQ(roundtrip(*good, "g2 test ping"), "g2 SUCCESS \"pong\"");
}

TEST_F(SocketTransportLimits, NoLineIsTakenFromAReadAfterItsFirstHalfClosedTheConnection) {
  // a lone client's large read is answered half-way (read_split.h); when those replies
  // exceed the limit the connection closes there, and the rest of the read must not be
  // taken as requests of the closed connection (they would run, and their outcomes would
  // be delivered to the freed session: a use after free under the sanitizers)
  start_server({{"max_unsent_bytes", 1024}});
  auto c = connect();
  auto burst = [](const std::string& prefix, const std::string& request, int lines) {
    std::string out;
    for (int i = 0; i < lines; ++i) out += prefix + std::to_string(i) + " " + request + "\n";
    return out;
  };
  // a first large read makes the connection the one sending (kit::ReadSplit notes it), then
  // it stays alone for longer than kit::ReadSplit::k_alone_after
  c->send_raw(burst("p", "test ping", 40));
  for (int i = 0; i < 40; ++i)
    ASSERT_EQ(next_line(*c), "p" + std::to_string(i) + " SUCCESS \"pong\"");
  std::this_thread::sleep_for(10ms);
  // first half: replies of 2 KB (the first one is over the limit); the second half
  // begins with a held request that must never start
  const std::string first_half = burst("b", "test big (2048,)", 20);
  const std::string hold = "h worker hold (1,)\n";
  const std::string padding =
      "z test echo ('" + std::string(first_half.size() - hold.size() - 18, 'x') + "',)\n";
  ASSERT_EQ(hold.size() + padding.size(), first_half.size());  // the half falls just before `hold`
  c->send_raw(first_half + hold + padding);
  bool ended = false;  // the server closes the connection
  for (int i = 0; i < 100 && !ended; ++i) {
    try {
      if (!c->read_line(10s)) break;
    } catch (const client::ClientError&) {
      ended = true;
    }
  }
  EXPECT_TRUE(ended);
  auto other = connect();
  EXPECT_EQ(roundtrip(*other, "r worker release (5,)"), "r SUCCESS false");
}

TEST_F(SocketTransportLimits, SuccessWordOkForTheDocumentation) {
  start_server({{"success_word", "OK"}});
  auto c = connect();
  EXPECT_EQ(roundtrip(*c, "req1 test_component add (1,2)"), "req1 OK 3");
  EXPECT_EQ(roundtrip(*c, "req2 test nothing"), "req2 OK");
  EXPECT_EQ(roundtrip(*c, "req3 test fail ('no',)"), "req3 FAILED \"no\"");
}

TEST_F(SocketTransportLimits, GlobalPolicyPreemptAppliesToServicesWithoutLocalPolicy) {
  start_server({{"global_policy", "preempt"}});
  auto c = connect();
  c->send_line("c7 plain hold (20,)");
  c->send_line("c8 plain hold (2,)");
  EXPECT_EQ(next_line(*c), "c7 PREEMPTED");
  c->send_line("r plain release (1,)");
  EXPECT_EQ(next_lines(*c, 2), (std::multiset<std::string>{"r SUCCESS true", "c8 SUCCESS 1"}));
  // a local policy still wins
  c->send_line("s1 strict hold (1,)");
  EXPECT_THAT(roundtrip(*c, "s2 strict hold (1,)"), HasSubstr("non-interruptible"));
  c->send_line("r2 strict release (1,)");
  EXPECT_EQ(next_lines(*c, 2), (std::multiset<std::string>{"r2 SUCCESS true", "s1 SUCCESS 1"}));
}

TEST_F(SocketTransportLimits, MaxConnectionsTellsAnExtraConnectionWhyAndClosesIt) {
  start_server({{"max_connections", 1}});
  auto first = connect();
  EXPECT_EQ(roundtrip(*first, "a test ping"), "a SUCCESS \"pong\"");
  auto second = connect();  // accepted by the kernel, told why and closed by the server
  EXPECT_EQ(next_line(*second), "- FAILED \"too many connections (max_connections 1)\"");
  EXPECT_THROW(second->read_line(10s), client::ClientError);
  EXPECT_EQ(roundtrip(*first, "c test ping"), "c SUCCESS \"pong\"");
}

TEST_F(SocketTransportLimits, MaxMessageBytesLimitsALine) {
  start_server({{"max_message_bytes", 1024}});
  auto c = connect();
  EXPECT_EQ(roundtrip(*c, "big test echo ('" + std::string(2000, 'a') + "',)"),
            "big FAILED \"Request too long: the line exceeds 1024 bytes (max_message_bytes); it "
            "was ignored\"");
  std::string prefix = "ok test echo ('";
  EXPECT_THAT(roundtrip(*c, prefix + std::string(1024 - prefix.size() - 3, 'c') + "',)"),
              StartsWith("ok SUCCESS"));
}

TEST_F(SocketTransportLimits, EndpointIsLoopbackWithTheBoundPort) {
  start_server();
  EXPECT_NE(port_, 0);
  EXPECT_EQ(manager_->endpoints().at(0), "tcp://127.0.0.1:" + std::to_string(port_));
  EXPECT_EQ(manager_->name(), "Socket service manager");
}

TEST_F(SocketTransportLimits, PortInUseIsAClearStartupError) {
  start_server();
  auto plugin = load_transport_plugin(std::string(SIMGATE_TEST_PLUGIN_DIR) +
                                      "/libsimgate_transport_socket.so");
  try {
    plugin->create({{"port", port_}}, "transports.socket");
    FAIL() << "a second server started on a port in use";
  } catch (const std::exception& e) {
    EXPECT_THAT(e.what(), HasSubstr("cannot listen on 127.0.0.1:" + std::to_string(port_)));
    EXPECT_THAT(e.what(), HasSubstr("in use"));
  }
}

TEST_F(SocketTransportLimits, UnknownOrInvalidOptionsAreRefused) {
  auto plugin = load_transport_plugin(std::string(SIMGATE_TEST_PLUGIN_DIR) +
                                      "/libsimgate_transport_socket.so");
  EXPECT_THROW(plugin->create({{"port", 0}, {"prot", 1}}, "transports.socket"), std::exception);
  try {
    plugin->create({{"port", 0}, {"success_word", "YES"}}, "transports.socket");
    FAIL() << "success_word YES accepted";
  } catch (const std::exception& e) {
    EXPECT_THAT(e.what(), HasSubstr("success_word"));
  }
  EXPECT_THROW(plugin->create({{"port", 70000}}, "transports.socket"), std::exception);
  EXPECT_THROW(plugin->create({{"port", 0}, {"max_message_bytes", 1}}, "transports.socket"),
               std::exception);
  try {
    plugin->create({{"port", 0}, {"on_disconnect", "forget"}}, "transports.socket");
    FAIL() << "on_disconnect forget accepted";
  } catch (const std::exception& e) {
    EXPECT_THAT(e.what(), HasSubstr("on_disconnect"));
  }
}

// ---- option names shared with the JSON-RPC transport (the old names are deprecated aliases)

class SocketTransportOptions : public SocketFixture {};

TEST_F(SocketTransportOptions, TheJsonRpcTransportsNamesAreAcceptedWithoutWarning) {
  WarningLog warnings;
  start_server({{"max_connections", 8},
                {"max_message_bytes", 4096},
                {"max_unsent_bytes", 65536},
                {"max_in_flight", 4}});
  auto c = connect();
  EXPECT_EQ(roundtrip(*c, "a test ping"), "a SUCCESS \"pong\"");
  EXPECT_EQ(warnings.count("deprecated"), 0u) << ::testing::PrintToString(warnings.lines());
}

TEST_F(SocketTransportOptions, AnOldNameWorksAsBeforeAndWarnsOnceWithTheNewName) {
  WarningLog warnings;
  start_server({{"max_clients", 1}});
  EXPECT_EQ(
      warnings.count(
          "socket: option 'max_clients' is deprecated, use 'max_connections' (the old name goes in "
          "the next release)"),
      1u)
      << ::testing::PrintToString(warnings.lines());
  auto first = connect();
  EXPECT_EQ(roundtrip(*first, "a test ping"), "a SUCCESS \"pong\"");
  auto second = connect();  // the limit applies, named as the configuration spells it
  EXPECT_EQ(next_line(*second), "- FAILED \"too many connections (max_clients 1)\"");
}

TEST_F(SocketTransportOptions, AnOptionUnderItsOldAndNewNameIsAConfigError) {
  auto plugin = load_transport_plugin(std::string(SIMGATE_TEST_PLUGIN_DIR) +
                                      "/libsimgate_transport_socket.so");
  const std::vector<std::pair<std::string, std::string>> renamed = {
      {"max_clients", "max_connections"},
      {"max_line_bytes", "max_message_bytes"},
      {"max_pending_replies_bytes", "max_unsent_bytes"},
      {"max_pending_requests", "max_in_flight"}};
  for (const auto& [old_key, new_key] : renamed) {
    try {
      plugin->create({{"port", 0}, {old_key, 1024}, {new_key, 1024}}, "transports.socket");
      ADD_FAILURE() << old_key << " and " << new_key << " accepted together";
    } catch (const ConfigError& e) {
      EXPECT_THAT(e.what(), HasSubstr("transports.socket." + old_key +
                                      ": the deprecated name of '" + new_key + "'"));
      EXPECT_THAT(e.what(), HasSubstr("keep only '" + new_key + "'"));
    }
  }
}

}  // namespace
}  // namespace simgate::socket::test
