// CallContext (core/src/call_context.cc): while the core runs a service for a request, the
// service knows the manager (transport) it came through and what that manager serves; outside
// a request it knows nothing and is trusted (issue #17, item 6).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <stdexcept>

#include "simgate/core/call_context.h"
#include "simgate/core/component.h"
#include "simgate/core/streams.h"
#include "test_manager.h"

namespace simgate {
namespace {

using testing::TestManager;

// What a service saw of its caller.
struct Seen {
  const RequestManager* manager = nullptr;  // CallContext::current()->manager(), or null
  RequestId request = 0;                    // its request id
  bool serves_private = false;              // caller_serves("private")
  bool raw = false;                         // caller_takes_raw_attachments()
};

Seen look() {
  Seen seen;
  if (const CallContext* context = CallContext::current()) {
    seen.manager = &context->manager();
    seen.request = context->request();
  }
  seen.serves_private = caller_serves("private");
  seen.raw = caller_takes_raw_attachments();
  return seen;
}

// Served by two managers; records what each of its services saw.
class Shared : public Component {
 public:
  Shared() : Component("shared") {
    add_service("look", [this] { seen = look(); });
    add_async_service("start", [this] { seen = look(); });
    // a result with its bytes raw beside it (a camera's get_local_data)
    add_service("attached", [] {
      auto payload = std::make_shared<StreamPayload>();
      payload->content = "image";
      payload->bytes = {1, 2, 3};
      CallContext::attach(payload);
      return json{{"image", "AQID"}};
    });
    add_service("fail", [this] {
      seen = look();
      throw std::runtime_error("boom");
    });
  }
  void default_action() override { in_default_action = look(); }

  Seen seen;               // in the last service
  Seen in_default_action;  // in the last default_action()
};

class CallContextTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // `a` serves "private" too, `b` only "shared"
    a_.register_component(shared_);
    a_.register_service("private", [] { return 1; }, "one");
    b_.register_component(shared_);
  }

  Shared shared_;
  TestManager a_, b_;
};

TEST_F(CallContextTest, SyncServiceSeesTheManagerAndRequestItWasCalledThrough) {
  RequestId id = a_.call("shared", "look");
  a_.process();
  EXPECT_EQ(shared_.seen.manager, &a_);
  EXPECT_EQ(shared_.seen.request, id);
  id = b_.call("shared", "look");
  b_.process();
  EXPECT_EQ(shared_.seen.manager, &b_);
  EXPECT_EQ(shared_.seen.request, id);
}

TEST_F(CallContextTest, CallerServesWhatTheCallingManagerServes) {
  a_.run("shared", "look");
  EXPECT_TRUE(shared_.seen.serves_private);
  b_.run("shared", "look");
  EXPECT_FALSE(shared_.seen.serves_private);
}

TEST_F(CallContextTest, AsyncStartMethodSeesItsCaller) {
  RequestId id = b_.call("shared", "start");
  b_.process();
  EXPECT_EQ(shared_.seen.manager, &b_);
  EXPECT_EQ(shared_.seen.request, id);
  EXPECT_FALSE(shared_.seen.serves_private);
}

TEST_F(CallContextTest, OutsideARequestThereIsNoneAndTheHostSeesEverything) {
  EXPECT_EQ(CallContext::current(), nullptr);
  EXPECT_TRUE(caller_serves("private"));
  EXPECT_TRUE(caller_serves("anything at all"));
  // after a request, on the same thread, the component's own step has no caller
  a_.run("shared", "look");
  shared_.default_action();
  EXPECT_EQ(shared_.in_default_action.manager, nullptr);
  EXPECT_TRUE(shared_.in_default_action.serves_private);
}

TEST_F(CallContextTest, ContextEndsWhenTheServiceThrows) {
  std::optional<Outcome> o = b_.run("shared", "fail");
  ASSERT_TRUE(o);
  EXPECT_EQ(o->status, Status::failed);
  EXPECT_EQ(shared_.seen.manager, &b_);
  EXPECT_EQ(CallContext::current(), nullptr);
}

TEST_F(CallContextTest, NestedContextsRestoreTheOuterOne) {
  const CallContext outer(a_, 7);
  {
    const CallContext inner(b_, 8);
    EXPECT_EQ(CallContext::current(), &inner);
    EXPECT_FALSE(caller_serves("private"));
  }
  EXPECT_EQ(CallContext::current(), &outer);
  EXPECT_TRUE(caller_serves("private"));
  EXPECT_FALSE(caller_serves("nobody serves this"));
}

}  // namespace
}  // namespace simgate

namespace simgate {
namespace {

TEST_F(CallContextTest, ASyncServiceAttachesBytesToItsOutcomeAndOnlyToIt) {
  std::optional<Outcome> o = a_.run("shared", "attached");
  ASSERT_TRUE(o);
  ASSERT_EQ(o->status, Status::success);
  EXPECT_EQ(o->value, (json{{"image", "AQID"}}));
  ASSERT_EQ(o->attachments.size(), 1u);
  EXPECT_EQ(o->attachments[0]->content, "image");
  EXPECT_EQ(o->attachments[0]->bytes, (std::vector<std::uint8_t>{1, 2, 3}));
  // the next call's outcome has none (the manager reuses its outcome)
  o = a_.run("shared", "look");
  ASSERT_TRUE(o);
  EXPECT_TRUE(o->attachments.empty());
  // outside a request an attachment goes nowhere
  CallContext::attach(std::make_shared<StreamPayload>());
  EXPECT_EQ(CallContext::current(), nullptr);
}

}  // namespace
}  // namespace simgate

namespace simgate {
namespace {

// Call::raw_attachments reaches the service as CallContext::takes_raw_attachments(), for that
// call only: a camera leaves the PNG out of its records for a DDS client that reads them raw.
TEST_F(CallContextTest, TheServiceKnowsWhetherItsCallerTakesAttachmentsRaw) {
  auto run_with = [this](const char* service, bool raw) {
    RequestId id = a_.new_request_id();
    Call call{"shared", service, nullptr};
    call.raw_attachments = raw;
    a_.submit(id, std::move(call));
    a_.process();
  };
  run_with("look", true);
  EXPECT_TRUE(shared_.seen.raw);
  run_with("look", false);
  EXPECT_FALSE(shared_.seen.raw);
  // an async service's start method too
  run_with("start", true);
  EXPECT_TRUE(shared_.seen.raw);
  // by default, and outside a request, no
  a_.run("shared", "look");
  EXPECT_FALSE(shared_.seen.raw);
  EXPECT_FALSE(caller_takes_raw_attachments());
  const CallContext host(a_, 9, true);
  EXPECT_TRUE(caller_takes_raw_attachments());
}

}  // namespace
}  // namespace simgate
