// Deadlines over real Cyclone DDS (issue #20): Request.timeout_ms bounds a call's wait for its
// final reply; past it the reply is ST_FAILED, FL_TIMEOUT, and the async service was
// interrupted, so the component takes the next call instead of refusing it busy. A timeout
// beyond 2147483647 ms is refused (FL_BAD_ARGUMENTS). No timed assertions.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "dds_transport_fixture.h"

namespace simgate::dds::test {
namespace {

using ::testing::HasSubstr;

TEST_F(DdsTransportTest, ACallPastItsTimeoutEndsFailedWithTimeoutAndItsServiceIsInterrupted) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  RawClient raw(test_partition());
  raw.create_reply_reader();
  ASSERT_TRUE(raw.wait_request_matched());
  // arm.grasp is non-interruptible: a second grasp is refused busy while one runs
  raw.write(1, simgate_OP_CALL, "arm", "grasp", "", 0, nullptr, /*progress=*/false, 50);
  auto reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->status, simgate_ST_ACCEPTED);
  reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->seq, 1u);
  EXPECT_EQ(reply->status, simgate_ST_FAILED);
  EXPECT_EQ(reply->failure, simgate_FL_TIMEOUT);
  EXPECT_TRUE(reply->last);
  EXPECT_EQ(reply->message, "arm.grasp: no reply within 50 ms (deadline); interrupted");
  EXPECT_TRUE(grasp_.completion().done());
  // the component is free: the next grasp (no deadline) is accepted and runs
  raw.write(2, simgate_OP_CALL, "arm", "grasp", "");
  reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->seq, 2u);
  EXPECT_EQ(reply->status, simgate_ST_ACCEPTED);
  ASSERT_TRUE(grasp_.wait_started(2));
  grasp_.completion()(Status::success, "held");
  reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->seq, 2u);
  EXPECT_EQ(reply->status, simgate_ST_SUCCESS);
  EXPECT_EQ(json::parse(reply->result), "held");
}

TEST_F(DdsTransportTest, SyncCallsWithATimeoutRunAndATimeoutTooLargeIsRefused) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  RawClient raw(test_partition());
  raw.create_reply_reader();
  ASSERT_TRUE(raw.wait_request_matched());
  raw.write(1, simgate_OP_CALL, "calc", "add", "[1, 2]", 0, nullptr, /*progress=*/false, 1000);
  auto reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->status, simgate_ST_SUCCESS);
  EXPECT_EQ(json::parse(reply->result), json(3.0));
  for (std::uint32_t bad : {2'147'483'648u, 4'294'967'295u}) {
    raw.write(2, simgate_OP_CALL, "arm", "grasp", "", 0, nullptr, /*progress=*/false, bad);
    reply = raw.next();
    ASSERT_TRUE(reply);
    EXPECT_EQ(reply->status, simgate_ST_FAILED);
    EXPECT_EQ(reply->failure, simgate_FL_BAD_ARGUMENTS);
    EXPECT_TRUE(reply->last);
    EXPECT_THAT(reply->message,
                HasSubstr("timeout_ms " + std::to_string(bad) + " is more than 2147483647"));
  }
  EXPECT_FALSE(grasp_.wait_started(1, 0ms));  // nothing ran
}

}  // namespace
}  // namespace simgate::dds::test
