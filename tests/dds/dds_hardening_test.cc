// The DDS transport over real Cyclone DDS, hardened against hostile or broken clients
// (issue #17): clients that never take their replies (or take them again), that leave (and,
// under on_disconnect "let_run", whose calls run on), that claim an id not theirs; names over
// 256 bytes; quoted params cut at a character boundary.
#include <algorithm>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "dds_transport_fixture.h"
#include "simgate/core/component.h"
#include "simgate/core/streams.h"
#include "simgate/core/log.h"

namespace simgate::dds::test {
namespace {

// ---- issue #17: hardening ----

// Collects the log lines that contain `needle` while it lives (any thread).
class LogWatch {
 public:
  // level: the least level logged meanwhile (info again afterwards)
  explicit LogWatch(std::string needle, log::Level level = log::Level::info)
      : needle_(std::move(needle)) {
    log::set_level(level);
    log::set_sink([this](log::Level, std::string_view message) {
      if (message.find(needle_) == std::string_view::npos) return;
      std::lock_guard lock(mutex_);
      lines_.emplace_back(message);
    });
  }
  ~LogWatch() {
    log::set_sink({});
    log::set_level(log::Level::info);
  }
  std::vector<std::string> lines() {
    std::lock_guard lock(mutex_);
    return lines_;
  }

 private:
  const std::string needle_;        // what a line must contain
  std::mutex mutex_;                // guards lines_
  std::vector<std::string> lines_;  // the lines seen
};

bool valid_utf8(const std::string& text) {
  for (std::size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    std::size_t n = c < 0x80           ? 1
                    : (c >> 5) == 0x6  ? 2
                    : (c >> 4) == 0xe  ? 3
                    : (c >> 3) == 0x1e ? 4
                                       : 0;
    if (n == 0 || i + n > text.size()) return false;
    for (std::size_t k = 1; k < n; ++k)
      if ((static_cast<unsigned char>(text[i + k]) & 0xc0) != 0x80) return false;
    i += n;
  }
  return true;
}

// Item 3: a client whose reply reader never takes (and so, once full, never acknowledges)
// made every reply write block 200 ms, for everyone, and other readers lost replies. Now it
// loses only its own replies, said in a few log lines, while the others are served.
TEST_F(DdsTransportTest, AClientThatNeverTakesItsRepliesLosesOnlyItsOwn) {
  LogWatch watch("does not take its replies");
  auto server = make_server(test_partition(), "server", {{"park_timeout_ms", 300}});
  SimThread sim(server);
  RawClient stuck(test_partition());
  stuck.create_reply_reader(true, 1);  // holds one reply, never takes
  ASSERT_TRUE(stuck.wait_request_matched());
  auto good = make_client(test_partition());
  constexpr int k_stuck_calls = 40, k_calls = 20;
  for (int i = 1; i <= k_stuck_calls; ++i) stuck.write(i, simgate_OP_CALL, "calc", "add", "[1, 1]");
  // the good client's calls all complete (they took 8 s and more before, or were lost)
  int answered = 0;
  const auto started = std::chrono::steady_clock::now();
  for (int i = 0; i < k_calls; ++i) {
    try {
      if (good->call("calc", "add", {i, 1}, 5s).value == json(double(i + 1))) ++answered;
    } catch (const ClientError& e) {
      ADD_FAILURE() << "call " << i << ": " << e.what();
    }
  }
  EXPECT_EQ(answered, k_calls);
  EXPECT_LT(std::chrono::steady_clock::now() - started, 10s);
  // the stuck client's losses are logged, in a few lines rather than one per reply
  EXPECT_TRUE(eventually([&] { return !watch.lines().empty(); }));
  EXPECT_LE(watch.lines().size(), 3u);
  if (!watch.lines().empty()) {
    EXPECT_THAT(watch.lines().front(), ::testing::HasSubstr(to_hex(stuck.id())));
  }
  // and it is still served once it reads again: not part of this test (its reader is full)
}

// Item 3: the replies that waited for room in a client's reply writer (its reader was full
// for a while) reach it, in order, once it takes again within park_timeout_ms.
TEST_F(DdsTransportTest, AClientThatTakesAgainGetsTheRepliesThatWaited) {
  auto server = make_server(test_partition());  // park_timeout_ms: 10 s
  SimThread sim(server);
  RawClient slow(test_partition());
  LogWatch watch(to_hex(slow.id()), log::Level::debug);
  slow.create_reply_reader(true, 2);  // holds two replies until it takes
  ASSERT_TRUE(slow.wait_request_matched());
  constexpr int k_calls = 6;
  for (int i = 1; i <= k_calls; ++i) {
    const std::string params = "[" + std::to_string(i) + ", 0]";
    slow.write(i, simgate_OP_CALL, "calc", "add", params.c_str());
  }
  auto logged = [&](const std::string& what) {
    for (const std::string& line : watch.lines())
      if (line.find(what) != std::string::npos) return true;
    return false;
  };
  // the third reply found the writer full
  ASSERT_TRUE(eventually([&] { return logged("is full"); }));
  // now it takes: every reply, in order
  for (int i = 1; i <= k_calls; ++i) {
    auto reply = slow.next();
    ASSERT_TRUE(reply) << "reply " << i;
    EXPECT_EQ(reply->seq, static_cast<std::uint64_t>(i));
    EXPECT_EQ(json::parse(reply->result), json(double(i)));
  }
  EXPECT_TRUE(logged("takes its replies again"));
  EXPECT_FALSE(logged("dropped"));
}

// Item 9: what the server keeps of a client lives from the match of its request writer until
// that writer left and its calls are over, so clients that come and go leave nothing behind.
// (What Cyclone 0.10 itself keeps per endpoint it saw is another matter: docs/transports/dds.md.)
TEST_F(DdsTransportTest, ClientsThatLeftAreForgotten) {
  LogWatch watch(" known)", log::Level::debug);
  {
    auto server = make_server(test_partition());
    SimThread sim(server);
    constexpr int k_sessions = 40;
    for (int i = 0; i < k_sessions; ++i) {
      RawClient raw(test_partition());
      raw.create_reply_reader();
      ASSERT_TRUE(raw.wait_request_matched());
      raw.write(1, simgate_OP_CALL, "calc", "add", "[1, 2]");
      auto reply = raw.next();
      ASSERT_TRUE(reply);
      EXPECT_EQ(reply->status, simgate_ST_SUCCESS);
    }
    // the last one is forgotten too
    EXPECT_TRUE(eventually([&] {
      auto lines = watch.lines();
      return !lines.empty() && lines.back().find("forgotten (0 known)") != std::string::npos;
    })) << (watch.lines().empty() ? "" : watch.lines().back());
    std::size_t appeared = 0, most = 0;
    for (const std::string& line : watch.lines()) {
      appeared += line.find("appeared") != std::string::npos;
      auto open = line.rfind('(');
      most = std::max<std::size_t>(most, std::stoul(line.substr(open + 1)));
    }
    EXPECT_EQ(appeared, static_cast<std::size_t>(k_sessions));
    EXPECT_LE(most, 2u);  // one client at a time (and the one leaving)
  }
}

// Item 5: an id was bound to whichever writer used it first, so a spoofer that wrote first
// took a client's id over. The id must be the GUID of the request writer that sends it.
TEST_F(DdsTransportTest, AClientIdIsTheGuidOfItsRequestWriter) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  RawClient owner(test_partition()), spoofer(test_partition());
  owner.create_reply_reader();
  spoofer.create_reply_reader();
  ASSERT_TRUE(owner.wait_request_matched());
  ASSERT_TRUE(spoofer.wait_request_matched());
  // the spoofer uses the owner's id before the owner did: refused, and told so (keyed with
  // the spoofer's own GUID, the only id its writer may use)
  spoofer.write(1, simgate_OP_CALL, "calc", "add", "[1, 1]", 0, &owner.id());
  auto refused = spoofer.next();
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->seq, 1u);
  EXPECT_EQ(refused->status, simgate_ST_FAILED);
  EXPECT_EQ(refused->failure, simgate_FL_BAD_REQUEST);
  EXPECT_TRUE(refused->last);
  EXPECT_THAT(refused->message, ::testing::HasSubstr(to_hex(spoofer.id())));
  // the owner is served under its id
  owner.write(1, simgate_OP_CALL, "calc", "add", "[2, 2]");
  auto reply = owner.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->seq, 1u);
  EXPECT_EQ(reply->status, simgate_ST_SUCCESS);
  EXPECT_EQ(json::parse(reply->result), json(4.0));
}

TEST_F(DdsTransportTest, AZeroClientIdIsRefused) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  RawClient raw(test_partition());
  raw.create_reply_reader();
  ASSERT_TRUE(raw.wait_request_matched());
  const ClientId zero{};
  raw.write(1, simgate_OP_CALL, "calc", "add", "[1, 1]", 0, &zero);
  auto reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->status, simgate_ST_FAILED);
  EXPECT_EQ(reply->failure, simgate_FL_BAD_REQUEST);
  EXPECT_THAT(reply->message, ::testing::HasSubstr("zero"));
  EXPECT_THAT(reply->message, ::testing::HasSubstr(to_hex(raw.id())));
}

// Item 9: component and service names had no bound (10 MB each were looked up, remembered
// and echoed in the error). Beyond 256 bytes they are refused before any lookup.
TEST_F(DdsTransportTest, NamesLongerThan256BytesAreRefused) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  RawClient raw(test_partition());
  raw.create_reply_reader();
  ASSERT_TRUE(raw.wait_request_matched());
  const std::string huge(1 << 20, 'c'), long_service(257, 's'), at_limit(256, 'c');
  raw.write(1, simgate_OP_CALL, huge.c_str(), "add", "[1, 1]");
  auto reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->failure, simgate_FL_BAD_REQUEST);
  EXPECT_NE(reply->message.find("component name is 1048576 bytes, more than 256"),
            std::string::npos)
      << reply->message.substr(0, 200);
  EXPECT_LT(reply->message.size(), 300u);
  raw.write(2, simgate_OP_CALL, "calc", long_service.c_str(), "[]");
  reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->failure, simgate_FL_BAD_REQUEST);
  EXPECT_THAT(reply->message, ::testing::HasSubstr("service name is 257 bytes, more than 256"));
  EXPECT_LT(reply->message.size(), 300u);
  // at the limit a name is looked up as usual
  raw.write(3, simgate_OP_CALL, at_limit.c_str(), "add", "[]");
  reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->failure, simgate_FL_UNKNOWN_SERVICE);
  raw.write(4, simgate_OP_CALL, "calc", "add", "[1, 2]");
  reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->status, simgate_ST_SUCCESS);
}

// Item 9: the quoted params of a FL_BAD_ARGUMENTS message were cut at byte 60, in the middle
// of a character; the message is UTF-8 again.
TEST_F(DdsTransportTest, QuotedParamsAreCutAtACharacterBoundary) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  RawClient raw(test_partition());
  raw.create_reply_reader();
  ASSERT_TRUE(raw.wait_request_matched());
  std::string params = "a";
  for (int i = 0; i < 40; ++i) params += "\xc3\xa9";  // e acute: byte 60 is inside the 30th
  raw.write(1, simgate_OP_CALL, "calc", "echo", params.c_str());
  auto reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->failure, simgate_FL_BAD_ARGUMENTS);
  EXPECT_TRUE(valid_utf8(reply->message)) << reply->message;
  EXPECT_THAT(reply->message, ::testing::HasSubstr("'a\xc3\xa9\xc3\xa9"));
}

// on_disconnect "let_run": the async calls of a client that leaves run on (MORSE's way);
// their replies go nowhere. (The default, "cancel": ClientThatDisappearsHasItsAsyncCallsCancelled.)
TEST_F(DdsTransportTest, UnderLetRunTheCallsOfAClientThatLeftRunOn) {
  LogWatch watch("disappeared");
  auto server = make_server(test_partition(), "server", {{"on_disconnect", "let_run"}});
  SimThread sim(server);
  auto client = make_client(test_partition());
  auto id = client->start("robot", "goto", {3.0});
  ASSERT_TRUE(client->wait_accepted(id, 10s));
  ASSERT_TRUE(goto_.wait_started(1));
  Completion running = goto_.completion();
  client.reset();  // leaves the domain with its call pending
  ASSERT_TRUE(eventually([&] { return !watch.lines().empty(); }));
  EXPECT_THAT(watch.lines().front(),
              ::testing::HasSubstr("0 async call(s) cancelled (on_disconnect: let_run)"));
  EXPECT_FALSE(running.done());
  EXPECT_TRUE(running(Status::success, "arrived"));  // it ends when it ends; nobody to tell
  auto other = make_client(test_partition());
  EXPECT_EQ(other->call("calc", "add", {1, 2}, 10s).value, json(3.0));
}

// ---- issue #35, item 10 ----

// The replies of `raw` for `seq` up to the final reply of `until` (a later call: a client's
// replies leave in the order they were produced, so everything for `seq` came before it).
std::vector<RawClient::Reply> replies_for(RawClient& raw, std::uint64_t seq, std::uint64_t until) {
  std::vector<RawClient::Reply> out;
  while (auto reply = raw.next()) {
    if (reply->seq == seq) out.push_back(*reply);
    if (reply->seq == until && reply->last) break;
  }
  return out;
}

int final_count(const std::vector<RawClient::Reply>& replies) {
  return static_cast<int>(
      std::count_if(replies.begin(), replies.end(), [](const auto& r) { return r.last; }));
}

// Item 10: a cancel under its target's own seq (OP_CANCEL {id.seq 5, target 5}) was answered
// under that id (SUCCESS, last) beside the call's own end (PREEMPTED, last): two final replies
// for one id. It cancels the call, whose PREEMPTED reply is the id's one final reply.
TEST_F(DdsTransportTest, ACancelUnderItsCallsOwnSeqEndsTheCallWithOneFinalReply) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  RawClient raw(test_partition());
  ASSERT_NO_FATAL_FAILURE(start_goto(raw, 5));
  raw.write(5, simgate_OP_CANCEL, "", "", "", 5);
  raw.write(6, simgate_OP_CALL, "calc", "add", "[1, 2]");
  const auto replies = replies_for(raw, 5, 6);
  ASSERT_EQ(final_count(replies), 1);
  for (const auto& reply : replies) {
    if (!reply.last) continue;
    EXPECT_EQ(reply.status, simgate_ST_PREEMPTED);
    EXPECT_EQ(reply.failure, simgate_FL_CANCELLED);
  }
  EXPECT_TRUE(goto_.completion().done());
}

// Item 10: any other request under a pending seq (a cancel of another call, a call) is
// refused without being acted on, ST_REFUSED and not final; the pending call goes on and
// ends with its own final reply, the id's only one.
TEST_F(DdsTransportTest, ACancelUnderAnotherPendingSeqIsRefusedNotFinal) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  RawClient raw(test_partition());
  ASSERT_NO_FATAL_FAILURE(start_goto(raw, 5));
  raw.write(7, simgate_OP_CALL, "arm", "grasp", "");  // another pending call, the cancel's target
  ASSERT_TRUE(grasp_.wait_started(1));
  raw.write(5, simgate_OP_CANCEL, "", "", "", 7);
  raw.write(6, simgate_OP_CALL, "calc", "add", "[1, 2]");
  auto replies = replies_for(raw, 5, 6);
  EXPECT_EQ(final_count(replies), 0);
  ASSERT_EQ(replies.size(), 1u);
  EXPECT_EQ(replies[0].status, simgate_ST_REFUSED);
  EXPECT_EQ(replies[0].failure, simgate_FL_BAD_REQUEST);
  EXPECT_THAT(replies[0].message, ::testing::HasSubstr("call 5 is still pending"));
  // neither call was touched; each ends with its own one final reply
  EXPECT_FALSE(grasp_.completion().done());
  EXPECT_TRUE(goto_.completion()(Status::success, "arrived"));
  EXPECT_TRUE(grasp_.completion()(Status::success, "grasped"));
  replies = replies_for(raw, 5, 5);
  ASSERT_EQ(final_count(replies), 1);
  EXPECT_EQ(replies.back().status, simgate_ST_SUCCESS);
}

// An actuator with an input stream, as motion_vw's: keeps the commands it was given.
class Motion : public Component {
 public:
  Motion() : Component("robot.motion") {
    declare_input_stream("velocity", {"v", "w"}, [this](const json& command) {
      std::lock_guard lock(mutex);
      applied.push_back(command);
    });
  }
  std::vector<json> given() {
    std::lock_guard lock(mutex);
    return applied;
  }
  std::mutex mutex;  // guards applied (applied under the simulation lock; read by the test)
  std::vector<json> applied;  // every command applied
};

// A writer of an input stream's JsonCommand topic ("simgate/<component>/json"), matched.
class CommandWriter {
 public:
  CommandWriter(const std::string& partition, const std::string& topic_name)
      : participant_(test_domain(), loopback_uri().c_str(), "command writer") {
    dds_entity_t pp = participant_.handle();
    QosPtr partition_qos(dds_create_qos());
    dds_qset_partition1(partition_qos.get(), partition.c_str());
    dds_entity_t publisher = dds_create_publisher(pp, partition_qos.get(), nullptr);
    dds_entity_t topic = dds_create_topic(pp, &simgate_stream_JsonCommand_desc, topic_name.c_str(),
                                          nullptr, nullptr);
    QosPtr qos = make_qos(false, 0, DDS_SECS(5));
    writer_ = dds_create_writer(publisher, topic, qos.get(), nullptr);
  }
  bool wait_matched() {
    return eventually([&] {
      dds_publication_matched_status_t st{};
      dds_get_publication_matched_status(writer_, &st);
      return st.current_count > 0;
    });
  }
  dds_return_t write(const std::string& text) {
    simgate_stream_JsonCommand command{};
    command.json = const_cast<char*>(text.c_str());
    return dds_write(writer_, &command);
  }

 private:
  Participant participant_;  // own participant
  dds_entity_t writer_ = 0;  // JsonCommand
};

// Item 10: a command on a DDS input stream had no bound: a 20 MB one was parsed on the DDS
// thread (the server's peak resident size 510 MB, its next reply 1.3 s late) and handed to
// the component. A JsonCommand's text is bounded as a request's params are, by max_params
// and max_depth, before it is parsed: refused unread, counted as a refused command of the
// stream, logged once; the next command is applied.
TEST_F(DdsTransportTest, AStreamCommandBeyondMaxParamsOrMaxDepthIsRefusedUnread) {
  LogWatch watch("refused unread");
  auto server = make_server(test_partition(), "server", {{"max_params", 4096}, {"max_depth", 8}});
  auto hub = std::make_shared<StreamHub>(server->gate());
  Motion motion;
  hub->add(motion, "motion_vw", {"dds"});
  server->set_streams(hub, "dds");
  SimThread sim(server);
  CommandWriter commands(test_partition(), "simgate/robot/motion/json");
  ASSERT_TRUE(commands.wait_matched());
  auto refused = [&] { return hub->statistics("dds").at(0).refused; };
  // a command of 10 kB, then one nested 9 deep: refused, neither reaches the component
  std::string big = "{\"v\": [1";
  while (big.size() < 10000) big += ",1";
  big += "], \"w\": 0}";
  ASSERT_EQ(commands.write(big), DDS_RETCODE_OK);
  ASSERT_TRUE(eventually([&] { return refused() == 1; })) << refused();
  EXPECT_THAT(hub->statistics("dds").at(0).last_refusal,
              ::testing::HasSubstr("a command of 10010 bytes, more than max_params (4096)"));
  ASSERT_EQ(commands.write("{\"v\": [[[[[[[[1]]]]]]]], \"w\": 0}"), DDS_RETCODE_OK);
  ASSERT_TRUE(eventually([&] { return refused() == 2; })) << refused();
  EXPECT_THAT(hub->statistics("dds").at(0).last_refusal,
              ::testing::HasSubstr("deeper than max_depth (8)"));
  // at the limits, a command is applied (the lock taken for the hub's turn, as the loop does)
  ASSERT_EQ(commands.write("{\"v\": 0.5, \"w\": [[[[[[[0]]]]]]]}"), DDS_RETCODE_OK);
  ASSERT_TRUE(eventually([&] {
    std::lock_guard lock(*server->gate());
    hub->apply_commands();
    return !motion.given().empty();
  }));
  EXPECT_EQ(motion.given().size(), 1u);
  EXPECT_EQ(motion.given().front()["v"], 0.5);
  EXPECT_EQ(refused(), 2u);
  EXPECT_EQ(watch.lines().size(), 1u);  // once per reader
  // and the server still serves
  auto client = make_client(test_partition());
  EXPECT_EQ(client->call("calc", "add", {1, 2}, 10s).value, json(3.0));
  hub->remove("robot.motion");
}

}  // namespace
}  // namespace simgate::dds::test
