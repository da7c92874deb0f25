// Progress reports over real Cyclone DDS (issue #20): an async call whose request asks
// (Request.progress) gets Reply{ST_RUNNING, last = false, result = the report} samples on
// simgate_Progress, in its client's partition, while it runs, then its final reply on
// simgate_Reply as before; a call that did not ask gets none; a client that never takes
// its reports still gets its final reply.
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "dds_transport_fixture.h"

namespace simgate::dds::test {
namespace {

// Reports {"step": i} on `call` until `client` has received `want` of them, bounded in count
// and time (best effort: the reports written before the client's progress reader matched
// the server's new progress writer are lost). Returns what was received.
std::vector<RawClient::Reply> report_until_received(RawClient& client, const Completion& call,
                                                    std::size_t want) {
  std::vector<RawClient::Reply> got;
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  for (int i = 0; i < 5000 && got.size() < want && std::chrono::steady_clock::now() < deadline;
       ++i) {
    EXPECT_TRUE(call.progress(json{{"step", i}}));
    std::this_thread::sleep_for(2ms);
    for (auto& r : client.take_progress()) got.push_back(std::move(r));
  }
  return got;
}

TEST_F(DdsTransportTest, AnAsyncCallThatAskedGetsProgressSamplesThenItsFinalReply) {
  auto server =
      make_server(test_partition(), "server", {{"progress_interval_ms", 0}});  // every report
  SimThread sim(server);
  RawClient raw(test_partition());
  raw.create_reply_reader();
  raw.create_progress_reader();
  ASSERT_TRUE(raw.wait_request_matched());
  raw.write(1, simgate_OP_CALL, "robot", "goto", "[1.0]", 0, nullptr, /*progress=*/true);
  auto accepted = raw.next();
  ASSERT_TRUE(accepted);
  EXPECT_EQ(accepted->status, simgate_ST_ACCEPTED);
  ASSERT_TRUE(goto_.wait_started(1));
  const Completion call = goto_.completion();

  std::vector<RawClient::Reply> got = report_until_received(raw, call, 3);
  ASSERT_GE(got.size(), 3u);
  int last_step = -1;
  for (const auto& r : got) {
    EXPECT_EQ(r.seq, 1u);
    EXPECT_EQ(r.status, simgate_ST_RUNNING);
    EXPECT_FALSE(r.last);
    json report = json::parse(r.result, nullptr, false);
    ASSERT_TRUE(report.is_object()) << r.result;
    const int step = report.value("step", -1);
    EXPECT_GT(step, last_step) << "reports in the order they were made";
    last_step = step;
  }

  // the final reply, on the reply topic as before
  ASSERT_TRUE(call(Status::success, "arrived"));
  auto final_reply = raw.next();
  ASSERT_TRUE(final_reply);
  EXPECT_EQ(final_reply->seq, 1u);
  EXPECT_EQ(final_reply->status, simgate_ST_SUCCESS);
  EXPECT_TRUE(final_reply->last);
  EXPECT_EQ(final_reply->result, "\"arrived\"");
  // no report after the end: the core passes none on once the call has finished
  EXPECT_FALSE(call.progress(json{{"step", "late"}}));
}

TEST_F(DdsTransportTest, ACallThatDidNotAskGetsNoProgressSamples) {
  auto server = make_server(test_partition(), "server", {{"progress_interval_ms", 0}});
  SimThread sim(server);
  RawClient raw(test_partition());
  raw.create_reply_reader();
  raw.create_progress_reader();
  ASSERT_TRUE(raw.wait_request_matched());
  raw.write(1, simgate_OP_CALL, "robot", "goto", "[1.0]");
  auto accepted = raw.next();
  ASSERT_TRUE(accepted);
  ASSERT_TRUE(goto_.wait_started(1));
  const Completion call = goto_.completion();
  EXPECT_FALSE(call.progress(json{{"step", 0}}));  // nobody asked: not passed on
  ASSERT_TRUE(call(Status::success, "arrived"));
  auto final_reply = raw.next();
  ASSERT_TRUE(final_reply);
  EXPECT_EQ(final_reply->status, simgate_ST_SUCCESS);
  EXPECT_TRUE(raw.take_progress().empty());
  // a sync call asking for progress is answered as usual (it has nothing to report)
  raw.write(2, simgate_OP_CALL, "calc", "add", "[1, 2]", 0, nullptr, /*progress=*/true);
  auto sum = raw.next();
  ASSERT_TRUE(sum);
  EXPECT_EQ(sum->seq, 2u);
  EXPECT_EQ(json::parse(sum->result), json(3.0));
}

TEST_F(DdsTransportTest, AClientThatNeverTakesItsProgressStillGetsItsFinalReply) {
  auto server = make_server(test_partition(), "server", {{"progress_interval_ms", 0}});
  SimThread sim(server);
  RawClient raw(test_partition());
  raw.create_reply_reader();
  raw.create_progress_reader(1);  // holds one report, never takes
  ASSERT_TRUE(raw.wait_request_matched());
  raw.write(1, simgate_OP_CALL, "robot", "goto", "[1.0]", 0, nullptr, /*progress=*/true);
  ASSERT_TRUE(raw.next());  // ST_ACCEPTED
  ASSERT_TRUE(goto_.wait_started(1));
  const Completion call = goto_.completion();
  constexpr int k_reports = 2000;
  for (int i = 0; i < k_reports; ++i) EXPECT_TRUE(call.progress(std::string(1024, 'p')));
  ASSERT_TRUE(call(Status::success, "arrived"));
  auto final_reply = raw.next();
  ASSERT_TRUE(final_reply);
  EXPECT_EQ(final_reply->status, simgate_ST_SUCCESS);
  EXPECT_TRUE(final_reply->last);
  // it kept the last report at most
  EXPECT_LE(raw.take_progress().size(), 1u);
}

}  // namespace
}  // namespace simgate::dds::test
