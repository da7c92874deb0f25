// Requests that run on the transport's I/O thread (RequestManager::run_or_submit: the
// simulation lock was free) and outcomes that the simulation thread produced: each
// connection gets its replies in the order the outcomes were produced, whichever thread
// produced them. Real sockets on 127.0.0.1 against the jsonrpc plugin; the test thread plays
// the simulation thread (there is no loop of its own).
#include <condition_variable>
#include <mutex>

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

}  // namespace
}  // namespace simgate::jsonrpc_test
