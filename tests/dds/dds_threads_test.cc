// The DDS transport over real Cyclone DDS: who runs a request and who writes its reply
// (run_or_submit: the DDS thread when the simulation lock is free, else the simulation
// thread's next process()), and DdsClient callers sharing one client.
#include <atomic>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "dds_transport_fixture.h"

namespace simgate::dds::test {
namespace {

// ---- who runs a request and who writes its reply (run_or_submit) ----

// Records the threads a service ran on.
struct ThreadLog {
  std::mutex mutex;               // guards ids
  std::set<std::thread::id> ids;  // where the service ran

  int record() {
    std::lock_guard lock(mutex);
    ids.insert(std::this_thread::get_id());
    return 1;
  }
  std::set<std::thread::id> get() {
    std::lock_guard lock(mutex);
    return ids;
  }
};

// With no simulation thread at all, the simulation lock is always free: the DDS thread runs
// the call itself and writes its reply (nobody else calls process()).
TEST_F(DdsTransportTest, SyncCallIsAnsweredFromTheDdsThreadWhenTheLockIsFree) {
  ThreadLog where;
  auto server = make_server(test_partition());
  server->register_service("probe", [&where] { return where.record(); }, "where");
  server->start();
  auto client = make_client(test_partition());
  for (int i = 0; i < 3; ++i)
    EXPECT_EQ(client->call("calc", "add", {i, 1}, 10s).value, json(double(i + 1)));
  EXPECT_EQ(client->call("probe", "where", nullptr, 10s).value, json(1));
  EXPECT_EQ(client->call("probe", "where", nullptr, 10s).value, json(1));
  auto ids = where.get();
  ASSERT_EQ(ids.size(), 1u);  // always the same thread: the DDS thread
  EXPECT_NE(*ids.begin(), std::this_thread::get_id());
  server->stop();
}

// While the simulation lock is held (the loop is stepping), a call waits for the holder's
// next process(); its reply then goes back through the DDS thread (the guard condition).
TEST_F(DdsTransportTest, CallQueuedWhileTheLockIsBusyIsAnsweredAfterTheNextProcess) {
  ThreadLog where;
  auto server = make_server(test_partition());
  server->register_service("probe", [&where] { return where.record(); }, "where");
  server->start();
  auto client = make_client(test_partition());
  std::shared_ptr<SimulationGate> gate = server->gate();
  gate->lock();
  gate->consume();
  auto id = client->start("probe", "where", nullptr);
  // the DDS thread finds the lock busy: it queues the call and signals the gate
  bool queued = gate->wait_for(10s);
  gate->unlock();
  ASSERT_TRUE(queued);
  // this thread plays the simulation thread
  EXPECT_GE(server->process(), 1u);
  EXPECT_EQ(client->wait(id, 10s).value, json(1));
  EXPECT_EQ(where.get(), std::set<std::thread::id>{std::this_thread::get_id()});
  server->stop();
}

// An async call run on the DDS thread is still acknowledged before its result, also when
// it completes at once (inside the same run) and when it completes later on another thread.
TEST_F(DdsTransportTest, AsyncCallRunOnTheDdsThreadIsAcceptedThenFinished) {
  auto server = make_server(test_partition());
  server->register_async_service("quick", [](Completion c) { c(Status::success, 7); }, "now");
  server->start();  // no simulation thread: the DDS thread runs every call
  RawClient raw(test_partition());
  raw.create_reply_reader();
  ASSERT_TRUE(raw.wait_request_matched());

  // completes inside its start
  raw.write(1, simgate_OP_CALL, "quick", "now", "");
  auto reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->seq, 1u);
  EXPECT_EQ(reply->status, simgate_ST_ACCEPTED);
  EXPECT_FALSE(reply->last);
  reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->seq, 1u);
  EXPECT_EQ(reply->status, simgate_ST_SUCCESS);
  EXPECT_TRUE(reply->last);
  EXPECT_EQ(json::parse(reply->result), json(7));

  // completes later, from this thread; this thread's process() delivers it
  raw.write(2, simgate_OP_CALL, "robot", "goto", "[5]");
  reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->seq, 2u);
  EXPECT_EQ(reply->status, simgate_ST_ACCEPTED);
  ASSERT_TRUE(goto_.wait_started(1));
  goto_.completion()(Status::success, "arrived");
  EXPECT_GE(server->process(), 1u);
  reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->seq, 2u);
  EXPECT_EQ(reply->status, simgate_ST_SUCCESS);
  EXPECT_TRUE(reply->last);
  server->stop();
}

// Several threads share one client: whichever caller reads the replies, each gets its own.
// One caller waits meanwhile for an async call that finishes last.
TEST_F(DdsTransportTest, ConcurrentCallersOnOneClientEachGetTheirOwnReply) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  auto client = make_client(test_partition());
  auto slow = client->start("robot", "goto", {9.0});
  ASSERT_TRUE(client->wait_accepted(slow, 10s));
  ASSERT_TRUE(goto_.wait_started(1));
  std::optional<Outcome> slow_outcome;
  std::thread slow_waiter([&] { slow_outcome = client->wait(slow, 30s); });

  constexpr int k_threads = 4, k_calls = 50;
  std::atomic<int> good{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < k_threads; ++t)
    threads.emplace_back([&, t] {
      for (int i = 0; i < k_calls; ++i) {
        std::string text = "caller " + std::to_string(t) + " call " + std::to_string(i);
        Outcome out = client->call("calc", "echo", {text}, 20s);
        if (out.value == json(text)) ++good;
      }
    });
  for (auto& t : threads) t.join();
  EXPECT_EQ(good, k_threads * k_calls);

  goto_.completion()(Status::success, "arrived");
  slow_waiter.join();
  ASSERT_TRUE(slow_outcome);
  EXPECT_EQ(slow_outcome->value, json("arrived"));
}

// A caller whose reply does not come times out on its own deadline, even while another
// caller is the one reading; the other caller still gets its reply.
TEST_F(DdsTransportTest, WaitTimesOutOnItsOwnDeadlineWhileAnotherCallerReads) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  auto client = make_client(test_partition());
  auto first = client->start("robot", "goto", {1.0});
  ASSERT_TRUE(goto_.wait_started(1));
  std::optional<Outcome> first_outcome;
  std::thread reader([&] { first_outcome = client->wait(first, 30s); });
  auto second = client->start("arm", "grasp", nullptr);
  ASSERT_TRUE(client->wait_accepted(second, 10s));
  EXPECT_THROW(client->wait(second, 100ms), ClientError);
  goto_.completion()(Status::success, 1);
  reader.join();
  ASSERT_TRUE(first_outcome);
  EXPECT_EQ(first_outcome->value, json(1));
  grasp_.completion()(Status::success);
}

}  // namespace
}  // namespace simgate::dds::test
