// Async completion out of order, cancel, preemption, disconnects, and the transport's
// limits (message size, nesting, in-flight calls, unsent replies, connections), all over
// real sockets on 127.0.0.1 against the jsonrpc plugin.
#include <atomic>
#include <set>
#include <thread>

#include <gtest/gtest.h>

#include "simgate/core/errors.h"
#include "test_util.h"

namespace simgate::jsonrpc_test {
namespace {

using JsonRpcAsync = JsonRpcFixture;

// Polls `method` on `c` until it returns `expected` (bounded in count and time).
bool eventually(JsonRpcClient& c, const std::string& method, const json& params,
                const json& expected) {
  const auto deadline = std::chrono::steady_clock::now() + k_timeout;
  for (int i = 0; i < 100000 && std::chrono::steady_clock::now() < deadline; ++i)
    if (c.request(method, params, k_timeout).value("result", json()) == expected) return true;
  return false;
}

TEST_F(JsonRpcAsync, RepliesComeOutOfOrderWhileTheConnectionKeepsServing) {
  auto hold = client_->send_request("robot.arm.hold", json::array({"k"}));
  // other calls on the same connection complete while the async one is pending
  for (int i = 0; i < 3; ++i) {
    auto r = client_->request("robot.arm.add", json::array({i, 1}), k_timeout);
    EXPECT_EQ(r["result"], i + 1.0);
  }
  auto release = client_->request("ctl.release", json::array({"k", {{"done", true}}}), k_timeout);
  EXPECT_EQ(release["result"], true);
  auto r = client_->wait_for(hold, k_timeout);
  EXPECT_EQ(r["result"], json({{"done", true}})) << r.dump();
}

TEST_F(JsonRpcAsync, SeveralAsyncCallsCompleteInReleaseOrder) {
  auto a = client_->send_request("robot.arm.hold", json::array({"a"}));
  auto b = client_->send_request("robot.cam.hold", json::array({"b"}));
  barrier(*client_);
  auto other = connect();
  EXPECT_EQ(other->request("ctl.release", json::array({"b", 2}), k_timeout)["result"], true);
  auto first = next(*client_);
  EXPECT_EQ(first["id"], b) << first.dump();
  EXPECT_EQ(first["result"], 2);
  EXPECT_EQ(other->request("ctl.release", json::array({"a", 1}), k_timeout)["result"], true);
  auto second = next(*client_);
  EXPECT_EQ(second["id"], a) << second.dump();
  EXPECT_EQ(second["result"], 1);
}

TEST_F(JsonRpcAsync, AsyncFailureCarriesTheServiceMessage) {
  auto hold = client_->send_request("robot.arm.hold", json::array({"f"}));
  barrier(*client_);
  client_->request("ctl.release_fail", json::array({"f", "target unreachable"}), k_timeout);
  auto r = client_->wait_for(hold, k_timeout);
  EXPECT_EQ(error_code(r), -32000) << r.dump();
  EXPECT_EQ(r["error"]["data"]["message"], "target unreachable");
}

TEST_F(JsonRpcAsync, CancelEndsThePendingCallAndAnswersTrue) {
  auto hold = client_->send_request("robot.arm.hold", json::array({"c"}));
  barrier(*client_);
  EXPECT_TRUE(client_->cancel(hold, k_timeout));
  auto r = client_->wait_for(hold, k_timeout);
  EXPECT_EQ(error_code(r), -32002) << r.dump();
  EXPECT_EQ(r["error"]["data"]["status"], "PREEMPTED");
  EXPECT_EQ(client_->request("ctl.pending", json::array({"c"}), k_timeout)["result"], false);
}

TEST_F(JsonRpcAsync, CancelAsNotificationAndLspAliasCancelSilently) {
  auto a = client_->send_request("robot.arm.hold", json::array({"n1"}));
  barrier(*client_);
  client_->send_notification("rpc.cancel", {{"id", a}});
  EXPECT_EQ(error_code(client_->wait_for(a, k_timeout)), -32002);
  auto b = client_->send_request("robot.cam.hold", json::array({"n2"}));
  barrier(*client_);
  client_->send_notification("$/cancelRequest", {{"id", b}});
  EXPECT_EQ(error_code(client_->wait_for(b, k_timeout)), -32002);
  // neither notification produced a response of its own
  EXPECT_FALSE(client_->receive(100ms).has_value());
}

TEST_F(JsonRpcAsync, CancelOfUnknownIdAnswersFalse) {
  EXPECT_FALSE(client_->cancel(12345, k_timeout));
  EXPECT_FALSE(client_->cancel("nope", k_timeout));
}

TEST_F(JsonRpcAsync, CancelIsScopedToTheConnection) {
  client_->send_line(R"({"jsonrpc":"2.0","method":"robot.arm.hold","params":["s"],"id":77})");
  barrier(*client_);
  auto other = connect();
  EXPECT_FALSE(other->cancel(77, k_timeout));
  EXPECT_EQ(other->request("ctl.pending", json::array({"s"}), k_timeout)["result"], true);
  other->request("ctl.release", json::array({"s", "mine"}), k_timeout);
  EXPECT_EQ(client_->wait_for(77, k_timeout)["result"], "mine");
}

TEST_F(JsonRpcAsync, InterruptibleServiceIsPreemptedByANewerCall) {
  auto first = client_->send_request("robot.arm.hold", json::array({"p1"}));
  barrier(*client_);
  auto second = client_->send_request("robot.arm.hold", json::array({"p2"}));
  auto r = client_->wait_for(first, k_timeout);
  EXPECT_EQ(error_code(r), -32001) << r.dump();
  client_->request("ctl.release", json::array({"p2", "second"}), k_timeout);
  EXPECT_EQ(client_->wait_for(second, k_timeout)["result"], "second");
}

TEST_F(JsonRpcAsync, NonInterruptibleServiceMakesTheNewCallBusy) {
  auto first = client_->send_request("robot.base.hold", json::array({"b1"}));
  barrier(*client_);
  auto r = client_->request("robot.base.hold", json::array({"b2"}), k_timeout);
  EXPECT_EQ(error_code(r), -32004) << r.dump();
  client_->request("ctl.release", json::array({"b1", "first"}), k_timeout);
  EXPECT_EQ(client_->wait_for(first, k_timeout)["result"], "first");
}

TEST_F(JsonRpcAsync, DuplicatePendingIdIsRefusedThenReusable) {
  client_->send_line(R"({"jsonrpc":"2.0","method":"robot.arm.hold","params":["d"],"id":"dup"})");
  auto r = round_trip(*client_,
                      R"({"jsonrpc":"2.0","method":"robot.arm.add","params":[1,2],"id":"dup"})");
  EXPECT_EQ(error_code(r), -32600) << r.dump();
  EXPECT_EQ(r["id"], "dup");
  client_->request("ctl.release", json::array({"d", 1}), k_timeout);
  EXPECT_EQ(client_->wait_for("dup", k_timeout)["result"], 1);
  r = round_trip(*client_,
                 R"({"jsonrpc":"2.0","method":"robot.arm.add","params":[1,2],"id":"dup"})");
  EXPECT_EQ(r["result"], 3.0) << r.dump();
}

TEST_F(JsonRpcAsync, BatchWithAsyncEntryAnswersWhenAllAreDone) {
  client_->send_line(one_line(R"([{"jsonrpc":"2.0","method":"robot.arm.add","params":[1,2],"id":1},
                         {"jsonrpc":"2.0","method":"robot.arm.hold","params":["bt"],"id":2}])"));
  auto other = connect();
  EXPECT_TRUE(eventually(*other, "ctl.pending", json::array({"bt"}), true));
  EXPECT_FALSE(client_->receive(50ms).has_value());
  other->request("ctl.release", json::array({"bt", "late"}), k_timeout);
  auto r = next(*client_);
  ASSERT_TRUE(r.is_array()) << r.dump();
  ASSERT_EQ(r.size(), 2u);
  EXPECT_EQ(r[0]["result"], 3.0);
  EXPECT_EQ(r[1]["result"], "late");
}

TEST_F(JsonRpcAsync, DisconnectCancelsPendingCalls) {
  auto hold = client_->send_request("robot.arm.hold", json::array({"gone"}));
  (void)hold;
  barrier(*client_);
  client_.reset();  // the client vanishes
  auto other = connect();
  EXPECT_TRUE(eventually(*other, "ctl.pending", json::array({"gone"}), false));
}

TEST_F(JsonRpcAsync, HalfCloseAfterNotificationStillRuns) {
  // what one-connection-per-call libraries do: write, then end the socket at once
  JsonRpcClient once("127.0.0.1", host_->port());
  once.send_notification("ctl.mark", json::array({"half"}));
  once.shutdown_write();
  EXPECT_TRUE(eventually(*client_, "ctl.marked", json::array({"half"}), true));
  EXPECT_TRUE(once.wait_closed(k_timeout));
}

TEST_F(JsonRpcAsync, HalfClosedClientStillGetsItsReply) {
  JsonRpcClient once("127.0.0.1", host_->port());
  once.send_line(R"({"jsonrpc":"2.0","method":"robot.arm.add","params":[20,22],"id":1})");
  once.shutdown_write();
  auto r = next(once);
  EXPECT_EQ(r["result"], 42.0);
  EXPECT_TRUE(once.wait_closed(k_timeout));
}

TEST_F(JsonRpcAsync, LastMessageWithoutNewlineBeforeEndIsAnswered) {
  JsonRpcClient once("127.0.0.1", host_->port());
  once.send_raw(R"({"jsonrpc":"2.0","method":"robot.arm.add","params":[1,1],"id":1})");
  once.shutdown_write();
  EXPECT_EQ(next(once)["result"], 2.0);
}

TEST_F(JsonRpcAsync, LargeBurstThenEndOfInputGetsEveryReply) {
  // a pipelining client's reads are read on while bytes wait and answered together; the
  // end of input may come in one of those reads: every call is still answered, in order
  JsonRpcClient once("127.0.0.1", host_->port());
  constexpr int k_calls = 2000;  // ~140 KB: many reads
  std::string burst;
  for (int i = 0; i < k_calls; ++i)
    burst += R"({"jsonrpc":"2.0","method":"robot.arm.add","params":[)" + std::to_string(i) +
             R"(,1],"id":)" + std::to_string(i) + "}\n";
  once.send_raw(burst);
  once.shutdown_write();
  for (int i = 0; i < k_calls; ++i) {
    json r = next(once);
    ASSERT_EQ(r["id"], i);
    ASSERT_EQ(r["result"], double(i + 1));
  }
  EXPECT_TRUE(once.wait_closed(k_timeout));
}

// ---- a lone client, read directly by the polling I/O thread (simgate/kit/idle_spin.h)

// Sync calls on `c` for `duration` (at most `max_calls`): long enough for the client to be
// alone (kit::ReadSplit::k_alone_after) and its socket read directly by the polling I/O thread.
// Returns how many were answered right; stops at the first wrong one.
int call_back_to_back(JsonRpcClient& c, std::chrono::milliseconds duration,
                      int max_calls = 50'000) {
  const auto end = std::chrono::steady_clock::now() + duration;
  int ok = 0;
  for (int i = 0; i < max_calls && std::chrono::steady_clock::now() < end; ++i, ++ok)
    if (c.request("robot.arm.add", json::array({i, 1}), k_timeout).value("result", json()) !=
        double(i + 1))
      break;
  return ok;
}

using JsonRpcLoneClient = JsonRpcFixture;

TEST_F(JsonRpcLoneClient, CallingBackToBackAndPausingIsAlwaysAnswered) {
  // after each pause, far longer than the polling window, the I/O thread has slept: it
  // must have handed the socket back to the event loop, or the next call goes unread
  for (int round = 0; round < 3; ++round) {
    EXPECT_GT(call_back_to_back(*client_, 20ms), 0);
    std::this_thread::sleep_for(5ms);
    EXPECT_EQ(client_->request("robot.arm.add", json::array({round, 1}), k_timeout)["result"],
              round + 1.0);
  }
  // end of input found by a direct read: the last call is answered, then the close
  EXPECT_GT(call_back_to_back(*client_, 20ms), 0);
  client_->send_raw(R"({"jsonrpc":"2.0","method":"robot.arm.add","params":[2,2],"id":"end"})");
  client_->shutdown_write();
  EXPECT_EQ(next(*client_)["result"], 4.0);
  EXPECT_TRUE(client_->wait_closed(k_timeout));
}

TEST_F(JsonRpcLoneClient, OthersAreServedWhileItIsReadDirectly) {
  std::atomic<bool> done{false};
  std::atomic<int> answered{0}, wrong{0};
  std::thread lone([&] {
    try {
      for (int round = 0; round < 1000 && !done.load(); ++round) {
        const int n = call_back_to_back(*client_, 5ms);
        answered += n;
        if (n == 0) ++wrong;
      }
    } catch (const std::exception&) {
      ++wrong;
    }
  });
  std::this_thread::sleep_for(20ms);  // the lone client's socket is read directly by now
  auto other = connect();
  auto hold = other->send_request("robot.arm.hold", json::array({"lone"}));
  EXPECT_EQ(other->request("robot.arm.add", json::array({3, 4}), k_timeout)["result"], 7.0);
  EXPECT_EQ(other->request("ctl.release", json::array({"lone", 5}), k_timeout)["result"], true);
  EXPECT_EQ(other->wait_for(hold, k_timeout)["result"], 5);
  auto late = connect();  // a new connection is accepted meanwhile
  EXPECT_EQ(late->request("robot.arm.add", json::array({1, 1}), k_timeout)["result"], 2.0);
  done = true;
  lone.join();
  EXPECT_GT(answered.load(), 0);
  EXPECT_EQ(wrong.load(), 0);
}

TEST_F(JsonRpcLoneClient, RepliesFromTheSimulationThreadReachItWhileItIsReadDirectly) {
  // the simulation lock is held: the call read directly is queued, run by the process()
  // thread, and its reply handed over to the polling I/O thread
  EXPECT_GT(call_back_to_back(*client_, 20ms), 0);
  json id;
  {
    std::lock_guard stepping(*host_->manager().gate());
    id = client_->send_request("robot.arm.add", json::array({1, 2}));
    std::this_thread::sleep_for(20ms);
  }
  EXPECT_EQ(client_->wait_for(id, k_timeout)["result"], 3.0);
  EXPECT_GT(call_back_to_back(*client_, 20ms), 0);
}

class JsonRpcAsyncLetRun : public JsonRpcFixture {
  json options() override { return {{"on_disconnect", "let_run"}}; }
};

TEST_F(JsonRpcAsyncLetRun, DisconnectLetsPendingCallsRun) {
  client_->send_request("robot.arm.hold", json::array({"stays"}));
  barrier(*client_);
  client_.reset();
  auto other = connect();
  // a few round trips after the disconnect: the call is still running
  for (int i = 0; i < 5; ++i)
    EXPECT_EQ(other->request("ctl.pending", json::array({"stays"}), k_timeout)["result"], true);
  EXPECT_EQ(other->request("ctl.release", json::array({"stays", 1}), k_timeout)["result"], true);
}

// ---- limits

class JsonRpcLimits : public JsonRpcFixture {
  json options() override {
    return {{"max_message_bytes", 1024},
            {"max_depth", 16},
            {"max_in_flight", 2},
            {"max_unsent_bytes", 65536},
            {"max_connections", 4}};
  }
};

TEST_F(JsonRpcLimits, OversizedMessageIsRefusedAndTheConnectionLivesOn) {
  const std::string big = R"({"jsonrpc":"2.0","method":"robot.arm.echo","params":[")" +
                          std::string(5000, 'a') + R"("],"id":1})";
  auto r = round_trip(*client_, big);
  EXPECT_EQ(error_code(r), -32600) << r.dump();
  EXPECT_TRUE(r["id"].is_null());
  // the same again, trickled in small writes
  for (std::size_t i = 0; i < big.size(); i += 700) client_->send_raw(big.substr(i, 700));
  client_->send_raw("\n");
  EXPECT_EQ(error_code(next(*client_)), -32600);
  EXPECT_EQ(client_->request("robot.arm.add", json::array({1, 2}), k_timeout)["result"], 3.0);
}

TEST_F(JsonRpcLimits, DeepNestingIsRefused) {
  std::string deep = R"({"jsonrpc":"2.0","method":"robot.arm.echo","params":[)" +
                     std::string(40, '[') + std::string(40, ']') + R"(],"id":1})";
  auto r = round_trip(*client_, deep);
  EXPECT_EQ(error_code(r), -32600) << r.dump();
  // brackets inside strings do not count
  auto ok = client_->request("robot.arm.echo", json::array({std::string(40, '[')}), k_timeout);
  EXPECT_EQ(ok["result"], std::string(40, '['));
}

TEST_F(JsonRpcLimits, ABatchLargerThanMaxInFlightIsRefusedWhole) {
  // issue #17: every entry counts, rpc.* and invalid ones included; entries with no id: one error
  auto r = round_trip(*client_, "[1,1,1]");
  ASSERT_TRUE(r.is_object()) << r.dump();
  EXPECT_EQ(error_code(r), -32006) << r.dump();
  EXPECT_EQ(r["error"]["data"]["batch_entries"], 3);
  // requests are each answered with their own id (their client knows which calls failed;
  // a null id would leave them pending), the notification not at all
  r = round_trip(
      *client_,
      R"([{"jsonrpc":"2.0","method":"rpc.discover","id":1},{"jsonrpc":"2.0","method":"rpc.discover","id":"b"},)"
      R"({"jsonrpc":"2.0","method":"rpc.discover"}])");
  ASSERT_TRUE(r.is_array()) << r.dump().substr(0, 300);
  ASSERT_EQ(r.size(), 2u) << r.dump();
  EXPECT_EQ(r[0]["id"], 1);
  EXPECT_EQ(r[1]["id"], "b");
  for (const json& e : r) {
    EXPECT_EQ(error_code(e), -32006) << e.dump();
    EXPECT_EQ(e["error"]["data"]["batch_entries"], 3);
  }
  // within the limit, a batch is served as before
  r = round_trip(*client_, "[1,1]");
  ASSERT_TRUE(r.is_array()) << r.dump();
  EXPECT_EQ(r.size(), 2u);
  EXPECT_EQ(client_->request("robot.arm.add", json::array({1, 2}), k_timeout)["result"], 3.0);
}

class JsonRpcBatchBytes : public JsonRpcFixture {
  json options() override { return {{"max_unsent_bytes", 4096}, {"max_in_flight", 64}}; }
};

TEST_F(JsonRpcBatchBytes, ABatchTooLargeToAnswerEntryByEntryIsOneError) {
  // past max_in_flight (64) and past the entries answered one by one (1024): one error
  std::string huge = "[";
  for (int i = 0; i < 1100; ++i)
    huge += std::string(i ? "," : "") + R"({"method":"x","id":)" + std::to_string(i) + "}";
  auto r = round_trip(*client_, huge + "]");
  ASSERT_TRUE(r.is_object()) << r.dump().substr(0, 200);
  EXPECT_EQ(error_code(r), -32006);
  EXPECT_TRUE(r["id"].is_null());
  EXPECT_EQ(r["error"]["data"]["batch_entries"], 1100);
}

TEST_F(JsonRpcBatchBytes, ABatchReplyStaysWithinMaxUnsentBytes) {
  // issue #17: a batch of rpc.discover built a 222 MB reply; now each entry past the budget
  // answers a short -32006 with its id
  std::string batch = "[";
  for (int i = 0; i < 40; ++i)
    batch += (i ? "," : "") + std::string(R"({"jsonrpc":"2.0","method":"rpc.discover","id":)") +
             std::to_string(i) + "}";
  batch += "]";
  client_->send_line(batch);
  const auto line = client_->read_line(k_timeout);
  ASSERT_TRUE(line);
  EXPECT_LT(line->size(), 4096u + 40 * 200) << line->size();
  const json r = json::parse(*line);
  ASSERT_TRUE(r.is_array());
  ASSERT_EQ(r.size(), 40u);
  for (int i = 0; i < 40; ++i) EXPECT_EQ(r[std::size_t(i)]["id"], i);
  EXPECT_EQ(error_code(r[39]), -32006) << r[39].dump();
  EXPECT_EQ(r[39]["error"]["data"]["max_unsent_bytes"], 4096);
  // the connection lives on
  EXPECT_EQ(client_->request("robot.arm.add", json::array({1, 2}), k_timeout)["result"], 3.0);
}

TEST_F(JsonRpcLimits, TooManyCallsInFlightAreOverloaded) {
  auto a = client_->send_request("robot.base.hold", json::array({"i1"}));
  auto b = client_->send_request("robot.cam.hold", json::array({"i2"}));
  auto r = client_->request("robot.arm.add", json::array({1, 2}), k_timeout);
  EXPECT_EQ(error_code(r), -32006) << r.dump();
  auto other = connect();  // the limit is per connection
  other->request("ctl.release", json::array({"i1", 1}), k_timeout);
  other->request("ctl.release", json::array({"i2", 2}), k_timeout);
  EXPECT_EQ(client_->wait_for(a, k_timeout)["result"], 1);
  EXPECT_EQ(client_->wait_for(b, k_timeout)["result"], 2);
  EXPECT_EQ(client_->request("robot.arm.add", json::array({1, 2}), k_timeout)["result"], 3.0);
}

class JsonRpcSlowReader : public JsonRpcFixture {
  json options() override { return {{"max_unsent_bytes", 65536}}; }
};

TEST_F(JsonRpcSlowReader, ClientThatNeverReadsIsDroppedOthersAreServed) {
  // requests for 64 x 256 KiB of replies in one write, far more than the kernel buffers of
  // a connection whose reader never reads; the client reads nothing
  JsonRpcClient hog("127.0.0.1", host_->port());
  std::string lines;
  for (int i = 0; i < 64; ++i)
    lines += R"({"jsonrpc":"2.0","method":"robot.arm.blob","params":[262144],"id":)" +
             std::to_string(i) + "}\n";
  hog.send_raw(lines);
  // meanwhile another client is served normally
  for (int i = 0; i < 5; ++i)
    EXPECT_EQ(client_->request("robot.arm.add", json::array({i, 1}), k_timeout)["result"], i + 1.0);
  // the hog's connection is closed by the server instead of buffering without bound
  EXPECT_TRUE(hog.wait_closed(k_timeout));
}

class JsonRpcTinyBacklog : public JsonRpcFixture {
  json options() override { return {{"max_unsent_bytes", 1024}}; }
};

TEST_F(JsonRpcTinyBacklog, NoMessageIsTakenFromAReadAfterItsFirstHalfClosedTheConnection) {
  // a lone client's large read is answered half-way (read_split.h); when those replies
  // exceed the limit the connection closes there, and the rest of the read must not run
  // for the client that is gone (a call there would escape on_disconnect's cancel)
  auto call = [](const std::string& method, const std::string& params, const std::string& id) {
    return R"({"jsonrpc":"2.0","method":")" + method + R"(","params":)" + params + R"(,"id":")" +
           id + "\"}\n";
  };
  // a first large read makes the connection the one sending (kit::ReadSplit notes it), then
  // it stays alone for longer than kit::ReadSplit::k_alone_after
  std::string warm;
  for (int i = 0; i < 10; ++i) warm += call("robot.arm.add", "[1,2]", "w" + std::to_string(i));
  ASSERT_GE(warm.size(), 512u);
  client_->send_raw(warm);
  for (int i = 0; i < 10; ++i) ASSERT_EQ(next(*client_)["result"], 3.0);
  std::this_thread::sleep_for(10ms);
  // first half: replies of 2 KB (the second finds the limit passed and closes); the second
  // half begins with a held call that must never start
  std::string first_half;
  for (int i = 0; i < 8; ++i)
    first_half += call("robot.arm.blob", "[2048]", "b" + std::to_string(i));
  const std::string hold = call("robot.arm.hold", R"(["after-close"])", "h");
  const std::string head = R"({"jsonrpc":"2.0","method":"robot.arm.echo","params":[")";
  const std::string tail = R"("],"id":"z"})"
                           "\n";
  const std::string padding =
      head + std::string(first_half.size() - hold.size() - head.size() - tail.size(), 'x') + tail;
  ASSERT_EQ(hold.size() + padding.size(), first_half.size());  // the half falls just before `hold`
  client_->send_raw(first_half + hold + padding);
  EXPECT_TRUE(client_->wait_closed(k_timeout));
  auto other = connect();
  EXPECT_EQ(other->request("ctl.pending", json::array({"after-close"}), k_timeout)["result"],
            false);
}

TEST_F(JsonRpcLimits, GarbageDoesNotDisturbOtherClients) {
  JsonRpcClient garbage("127.0.0.1", host_->port());
  std::string noise;
  for (int i = 0; i < 256; ++i)
    noise.push_back(static_cast<char>((i * 37 + 11) % 256 == '\n' ? 'x' : (i * 37 + 11) % 256));
  for (int i = 0; i < 20; ++i) {
    garbage.send_line(noise);
    EXPECT_EQ(client_->request("robot.arm.add", json::array({i, 1}), k_timeout)["result"], i + 1.0);
  }
  // each garbage line got its own error; the garbage connection still works
  for (int i = 0; i < 20; ++i) {
    int code = error_code(next(garbage));
    EXPECT_TRUE(code == -32700 || code == -32600) << code;
  }
  EXPECT_EQ(garbage.request("robot.arm.add", json::array({1, 1}), k_timeout)["result"], 2.0);
}

TEST_F(JsonRpcLimits, ConnectionsBeyondTheMaximumAreRefused) {
  std::vector<std::unique_ptr<JsonRpcClient>> clients;
  for (int i = 0; i < 3; ++i) {  // plus client_: 4 = max_connections
    clients.push_back(connect());
    barrier(*clients.back());
  }
  JsonRpcClient extra("127.0.0.1", host_->port());
  auto r = next(extra);
  EXPECT_EQ(error_code(r), -32006) << r.dump();
  EXPECT_TRUE(extra.wait_closed(k_timeout));
  // a slot frees up when a client leaves
  clients.pop_back();
  bool served = false;
  for (int attempt = 0; attempt < 200 && !served; ++attempt) {
    // until the server has seen the departure, it refuses and closes
    try {
      JsonRpcClient again("127.0.0.1", host_->port());
      auto m = again.request("robot.arm.add", json::array({1, 1}), k_timeout);
      served = m.contains("result");
    } catch (const client::ClientError&) {}
  }
  EXPECT_TRUE(served);
}

// ---- plugin options and life cycle

TEST(JsonRpcPlugin, EndpointReportsTheBoundPort) {
  TestHost host;
  EXPECT_NE(host.port(), 0);
  EXPECT_EQ(host.manager().endpoints().at(0), "tcp://127.0.0.1:" + std::to_string(host.port()));
}

TEST(JsonRpcPlugin, PortInUseIsAClearCreateError) {
  TestHost host;
  try {
    auto second = load_transport(TestHost::default_plugin_path(), {{"port", host.port()}});
    FAIL() << "a second server bound the same port";
  } catch (const std::exception& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(std::to_string(host.port())), std::string::npos) << what;
    EXPECT_NE(what.find("in use"), std::string::npos) << what;
  }
}

TEST(JsonRpcPlugin, BadOptionsAreRefusedWithTheirName) {
  const std::vector<std::pair<json, std::string>> cases = {
      {{{"port", 0}, {"prot", 1}}, "prot"},
      {{{"port", 0}, {"on_disconnect", "explode"}}, "on_disconnect"},
      {{{"port", 0}, {"host", "not an address"}}, "host"},
      {{{"port", 70000}}, "port"},
      {{{"port", 0}, {"max_in_flight", 0}}, "max_in_flight"}};
  for (const auto& [options, key] : cases) {
    try {
      load_transport(TestHost::default_plugin_path(), options);
      ADD_FAILURE() << "accepted " << options.dump();
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  }
}

TEST(JsonRpcPlugin, StopClosesConnectionsAndIsIdempotent) {
  TestHost host;
  JsonRpcClient c("127.0.0.1", host.port());
  c.send_request("robot.arm.hold", json::array({"x"}));
  EXPECT_EQ(c.request("robot.arm.add", json::array({1, 1}), k_timeout)["result"], 2.0);
  host.stop();
  host.stop();
  EXPECT_TRUE(c.wait_closed(k_timeout));
}

}  // namespace
}  // namespace simgate::jsonrpc_test
