// Requests that run on the transport's I/O thread (RequestManager::run_or_submit: the
// simulation lock was free) and outcomes that the simulation thread produced: each
// connection gets its replies in the order the outcomes were produced, whichever thread
// produced them. Real sockets on 127.0.0.1 against the jsonrpc plugin; the test thread plays
// the simulation thread (there is no loop of its own).
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <condition_variable>
#include <mutex>
#include <thread>

#include <gtest/gtest.h>

#include "simgate/core/log.h"
#include "test_util.h"

namespace simgate::jsonrpc_test {
namespace {

// A log sink that holds the thread writing a message containing `trigger` until release()
// (bounded by k_timeout), so a test can stop the I/O thread at a known point of a read.
class LogGate {
 public:
  explicit LogGate(std::string trigger) : trigger_(std::move(trigger)) {
    previous_ = log::level();
    log::set_level(log::Level::debug);
    log::set_sink([this](log::Level, std::string_view message) {
      if (message.find(trigger_) == std::string_view::npos) return;
      std::unique_lock lock(mutex_);
      held_ = true;
      cv_.notify_all();
      cv_.wait_for(lock, k_timeout, [this] { return released_; });
    });
  }
  ~LogGate() {
    release();
    log::set_sink({});
    log::set_level(previous_);
  }
  // Waits until a thread is held; false on timeout.
  bool wait_held() {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, k_timeout, [this] { return held_; });
  }
  void release() {
    std::lock_guard lock(mutex_);
    released_ = true;
    cv_.notify_all();
  }

 private:
  std::string trigger_;         // the message part that holds the writer
  log::Level previous_;         // level to restore
  std::mutex mutex_;            // guards held_, released_
  std::condition_variable cv_;  // signals both
  bool held_ = false;           // a writer is held
  bool released_ = false;       // release() was called
};

TEST(JsonRpcInline, RequestsRunOnTheIoThreadWhenTheSimulationIsIdle) {
  // no simulation loop at all: the I/O thread runs every request itself
  auto state = std::make_shared<ServiceState>();
  auto rm = load_transport(TestHost::default_plugin_path(), json{{"port", 0}});
  register_test_services(*rm, state);
  rm->start();
  const auto endpoint = rm->endpoints().at(0);
  JsonRpcClient c("127.0.0.1",
                  static_cast<std::uint16_t>(std::stoi(endpoint.substr(endpoint.rfind(':') + 1))));
  EXPECT_EQ(c.request("robot.arm.add", json::array({1, 2}), k_timeout)["result"], 3.0);
  c.send_line(
      R"([{"jsonrpc":"2.0","method":"spec.subtract","params":[5,3],"id":1},{"jsonrpc":"2.0","method":"spec.sum","params":[1,2,3],"id":2}])");
  auto batch = next(c);
  ASSERT_TRUE(batch.is_array()) << batch.dump();
  EXPECT_EQ(batch[0]["result"], 2);
  EXPECT_EQ(batch[1]["result"], 6);
  rm->stop();
}

TEST(JsonRpcInline, ReplyRunInlineFollowsOutcomesTheSimulationThreadProducedBefore) {
  // max_in_flight 3: two held calls and one sync call fill it, so the notification that
  // follows in the same read is dropped with a debug log line, where LogGate holds the I/O
  // thread: after the sync call was read, before it is handed to the core
  auto state = std::make_shared<ServiceState>();
  auto rm =
      load_transport(TestHost::default_plugin_path(), json{{"port", 0}, {"max_in_flight", 3}});
  register_test_services(*rm, state);
  rm->start();
  const auto endpoint = rm->endpoints().at(0);
  JsonRpcClient c("127.0.0.1",
                  static_cast<std::uint16_t>(std::stoi(endpoint.substr(endpoint.rfind(':') + 1))));

  // two async calls (ids apart from the client's own), started (each request of a connection runs after the ones before)
  c.send_line(R"({"jsonrpc":"2.0","method":"robot.cam.hold","params":["k1"],"id":101})");
  c.send_line(R"({"jsonrpc":"2.0","method":"robot.arm.hold","params":["k2"],"id":102})");
  ASSERT_EQ(c.request("ctl.pending", json::array({"k2"}), k_timeout)["result"], true);

  {
    LogGate gate("dropped: overloaded");
    c.send_raw(
        "{\"jsonrpc\":\"2.0\",\"method\":\"robot.arm.add\",\"params\":[1,2],\"id\":103}\n"
        "{\"jsonrpc\":\"2.0\",\"method\":\"robot.arm.add\",\"params\":[1,2]}\n");
    ASSERT_TRUE(gate.wait_held()) << "the I/O thread never reached the overloaded notification";

    // meanwhile, on this ("simulation") thread: k2 finishes, its outcome is produced here
    {
      std::lock_guard lock(*rm->gate());
      ASSERT_TRUE(state->held.at("k2")(Status::success, json("k2 done")));
    }
    rm->process();
    gate.release();
  }

  // the I/O thread then runs call 103 itself: its reply comes after k2's
  auto first = next(c);
  auto second = next(c);
  EXPECT_EQ(first["id"], 102) << first.dump();
  EXPECT_EQ(first["result"], "k2 done");
  EXPECT_EQ(second["id"], 103) << second.dump();
  EXPECT_EQ(second["result"], 3.0);

  // k1 is still served normally
  EXPECT_EQ(c.request("ctl.release", json::array({"k1", "k1 done"}), k_timeout)["result"], true);
  EXPECT_EQ(c.wait_for(101, k_timeout)["result"], "k1 done");
  rm->stop();
}

// A client that sends `bytes`, reads one line (what the server answered at once), then
// vanishes: its socket closed with a reset (SO_LINGER 0), the way a killed process's goes.
std::string send_read_line_and_vanish(std::uint16_t port, const std::string& bytes) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(port);
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  std::string line;
  if (::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0 &&
      ::send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(bytes.size())) {
    timeval timeout{10, 0};
    ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
    char c;
    while (::recv(fd, &c, 1, 0) == 1 && c != '\n') line += c;
  }
  linger reset{1, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_LINGER, &reset, sizeof reset);
  ::close(fd);
  return line;
}

TEST(JsonRpcInline, RepliesInFlightToAClientThatVanishedGoNowhereNotToTheNextOne) {
  // replies remember their connection without owning it (kit::ConnectionRef): a client that
  // leaves with pipelined calls queued for the simulation thread, a batch among them, has
  // their outcomes dropped when they come back, and the next client (in its slot of the
  // server's table) gets none of them
  auto state = std::make_shared<ServiceState>();
  auto rm = load_transport(TestHost::default_plugin_path(),
                           json{{"port", 0}, {"on_disconnect", "let_run"}});
  register_test_services(*rm, state);
  rm->start();
  const auto endpoint = rm->endpoints().at(0);
  const auto port = static_cast<std::uint16_t>(std::stoi(endpoint.substr(endpoint.rfind(':') + 1)));
  std::unique_lock simulating(*rm->gate());  // this thread is the loop, stepping: calls queue
  std::string burst;
  for (int i = 1; i <= 64; ++i)
    burst += R"({"jsonrpc":"2.0","method":"ctl.mark","params":["v)" + std::to_string(i) +
             R"("],"id":)" + std::to_string(i) + "}\n";
  burst += R"([{"jsonrpc":"2.0","method":"ctl.mark","params":["b1"],"id":65},)"
           R"({"jsonrpc":"2.0","method":"robot.arm.add","params":[1,2],"id":66}])"
           "\n";
  // answered at once, after the calls before it in the same read went to the core
  burst += "not json\n";
  const std::string answered = send_read_line_and_vanish(port, burst);
  ASSERT_NE(answered.find("Parse error"), std::string::npos) << answered;
  const auto deadline = std::chrono::steady_clock::now() + k_timeout;
  while (rm->client_count() > 0 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(1ms);
  ASSERT_EQ(rm->client_count(), 0u) << "the server never saw the client leave";

  // the next client takes the freed slot; then the calls run and their outcomes come back
  JsonRpcClient next_client("127.0.0.1", port);
  while (rm->client_count() < 1 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(1ms);
  simulating.unlock();
  EXPECT_GE(rm->process(), 1u);
  EXPECT_EQ(next_client.request("ctl.marked", json::array({"v64"}), k_timeout)["result"], true);
  EXPECT_EQ(next_client.request("ctl.marked", json::array({"b1"}), k_timeout)["result"], true);
  // nothing of the vanished client's: the replies above were the only messages
  EXPECT_FALSE(next_client.receive(300ms).has_value());
  EXPECT_EQ(next_client.request("robot.arm.add", json::array({2, 2}), k_timeout)["result"], 4.0);
  EXPECT_FALSE(next_client.receive(100ms).has_value());
  rm->stop();
}

}  // namespace
}  // namespace simgate::jsonrpc_test
