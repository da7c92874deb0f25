// Integration tests of the DDS transport over real Cyclone DDS (loopback only): the plugin
// loaded with dlopen serves test services; DdsClient and a raw Cyclone client call them.
#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <memory>
#include <optional>
#include <string>
#include <set>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "cyclone_config.h"
#include "dds_support.h"
#include "dds_test_support.h"
#include "simgate/client/dds_client.h"
#include "simgate/core/log.h"

namespace simgate::dds::test {
namespace {

using client::ClientError;
using client::DdsClient;
using client::DdsClientOptions;

const char* const k_plugin = SIMGATE_TEST_PLUGIN_DIR "/libsimgate_transport_dds.so";

// A client speaking the wire types directly (no DdsClient), to control every field and
// the moment its reply reader appears.
class RawClient {
 public:
  explicit RawClient(const std::string& partition)
      : participant_(test_domain(), ("file://" + std::string(SIMGATE_LOOPBACK_DDS_XML)).c_str(), "raw client"),
        partition_(partition) {
    dds_entity_t pp = participant_.handle();
    QosPtr partition_qos(dds_create_qos());
    dds_qset_partition1(partition_qos.get(), partition.c_str());
    publisher_ = dds_create_publisher(pp, partition_qos.get(), nullptr);
    dds_entity_t topic = dds_create_topic(pp, &simgate_Request_desc, k_request_topic, nullptr, nullptr);
    QosPtr qos = make_qos(false, 0, DDS_SECS(1));
    writer_ = dds_create_writer(publisher_, topic, qos.get(), nullptr);
    dds_guid_t guid;
    dds_get_guid(writer_, &guid);
    id_ = to_client_id(guid);
  }

  bool wait_request_matched(std::chrono::milliseconds timeout = 10s) {
    return eventually([&] {
      dds_publication_matched_status_t st;
      dds_get_publication_matched_status(writer_, &st);
      return st.current_count > 0;
    }, timeout);
  }

  // announce: put "simgate.id=<our id>" in the reader's USER_DATA, as clients should;
  // max_samples: how many replies the reader holds (a reader that never takes stops
  // accepting, hence acknowledging, beyond that)
  void create_reply_reader(bool announce = true, int32_t max_samples = DDS_LENGTH_UNLIMITED) {
    dds_entity_t pp = participant_.handle();
    // in the client's own partition, "<partition>/<id>", where the server writes its replies
    QosPtr partition_qos(dds_create_qos());
    dds_qset_partition1(partition_qos.get(), (partition_ + "/" + to_hex(id_)).c_str());
    dds_entity_t subscriber = dds_create_subscriber(pp, partition_qos.get(), nullptr);
    dds_entity_t topic = dds_create_topic(pp, &simgate_Reply_desc, k_reply_topic, nullptr, nullptr);
    QosPtr qos = make_qos(false, 0, DDS_SECS(1));
    dds_qset_resource_limits(qos.get(), max_samples, DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED);
    std::string userdata = "simgate.id=" + to_hex(id_);
    if (announce) dds_qset_userdata(qos.get(), userdata.data(), userdata.size());
    reader_ = dds_create_reader(subscriber, topic, qos.get(), nullptr);
    ASSERT_GT(reader_, 0);
  }

  // as_client: write with another client's id (what a spoofer would do)
  void write(std::uint64_t seq, simgate_Op op, const char* component, const char* service, const char* params,
             std::uint64_t target = 0, const ClientId* as_client = nullptr) {
    simgate_Request rq{};
    std::memcpy(rq.id.client, (as_client ? *as_client : id_).data(), 16);
    rq.id.seq = seq;
    rq.op = op;
    rq.component = const_cast<char*>(component);
    rq.service = const_cast<char*>(service);
    rq.params = const_cast<char*>(params);
    rq.target = target;
    ASSERT_EQ(dds_write(writer_, &rq), DDS_RETCODE_OK);
  }

  struct Reply {
    std::uint64_t seq = 0;
    simgate_ReplyStatus status = simgate_ST_SUCCESS;
    simgate_Failure failure = simgate_FL_NONE;
    bool last = false;
    std::string result, message;
  };

  // The next reply for this client, or nullopt after `timeout`.
  std::optional<Reply> next(std::chrono::milliseconds timeout = 10s) {
    std::optional<Reply> out;
    eventually([&] {
      void* samples[1] = {nullptr};
      dds_sample_info_t info;
      while (dds_take(reader_, samples, &info, 1, 1) == 1) {
        const auto& r = *static_cast<const simgate_Reply*>(samples[0]);
        bool mine = info.valid_data && std::memcmp(r.client, id_.data(), 16) == 0;
        if (mine) out = Reply{r.seq, r.status, r.failure, r.last, r.result, r.message};
        dds_return_loan(reader_, samples, 1);
        if (mine) return true;
        samples[0] = nullptr;
      }
      return false;
    }, timeout);
    return out;
  }

  const ClientId& id() const { return id_; }

 private:
  Participant participant_;      // own participant
  std::string partition_;        // the server's
  dds_entity_t publisher_ = 0;   // in the partition
  dds_entity_t writer_ = 0;      // requests
  dds_entity_t reader_ = 0;      // replies (created on demand)
  ClientId id_{};                // our request writer's GUID
};

class DdsTransportTest : public ::testing::Test {
 protected:
  // A server with: calc.add(a, b), calc.echo(text), calc.fail(), calc.count(),
  // calc.whoami() -> `name`, robot.goto(x) async interruptible, arm.grasp() async
  // non-interruptible, tool.use() async without a local policy.
  std::shared_ptr<RequestManager> make_server(const std::string& partition, const std::string& name = "server",
                                              json extra = json::object()) {
    auto rm = load_transport(k_plugin, server_options(partition, extra));
    rm->register_service("calc", [](double a, double b) { return a + b; }, "add", {"a", "b"}).doc("a + b");
    rm->register_service("calc", [](std::string text) { return text; }, "echo", {"text"});
    rm->register_service("calc", []() -> int { throw ServiceError("calc.fail: it failed on purpose"); }, "fail");
    rm->register_service("calc", [this]() { return ++count_; }, "count");
    rm->register_service("calc", [name]() { return name; }, "whoami");
    rm->register_async_service("robot", [this](Completion c, double) { goto_.on_start(c); }, "goto", {"x"})
        .interruptible();
    rm->register_async_service("arm", [this](Completion c) { grasp_.on_start(c); }, "grasp").noninterruptible();
    rm->register_async_service("tool", [this](Completion c) { use_.on_start(c); }, "use");
    return rm;
  }

  std::unique_ptr<DdsClient> make_client(const std::string& partition) {
    auto c = std::make_unique<DdsClient>(DdsClientOptions::from_json(client_options(partition)));
    EXPECT_TRUE(c->wait_for_server(10s));
    return c;
  }

  std::atomic<int> count_{0};  // calc.count
  AsyncProbe goto_;            // robot.goto
  AsyncProbe grasp_;           // arm.grasp
  AsyncProbe use_;             // tool.use
};

TEST_F(DdsTransportTest, SyncCallReturnsItsResult) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  auto client = make_client(test_partition());
  Outcome out = client->call("calc", "add", {2, 3.5}, 10s);
  EXPECT_EQ(out.status, Status::success);
  ASSERT_TRUE(out.value);
  EXPECT_DOUBLE_EQ(out.value->get<double>(), 5.5);
  // named parameters too
  out = client->call("calc", "add", {{"a", 1}, {"b", 2}}, 10s);
  ASSERT_TRUE(out.value);
  EXPECT_DOUBLE_EQ(out.value->get<double>(), 3.0);
}

TEST_F(DdsTransportTest, ServiceErrorsFailWithTheirReasonAndServerKeepsServing) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  auto client = make_client(test_partition());

  Outcome unknown = client->call("calc", "nope", nullptr, 10s);
  EXPECT_EQ(unknown.status, Status::failed);
  EXPECT_EQ(unknown.failure, Failure::unknown_service);

  Outcome arity = client->call("calc", "add", {1}, 10s);
  EXPECT_EQ(arity.status, Status::failed);
  EXPECT_EQ(arity.failure, Failure::bad_arguments);
  EXPECT_NE(arity.message.find("wrong # of parameters"), std::string::npos) << arity.message;

  Outcome failed = client->call("calc", "fail", nullptr, 10s);
  EXPECT_EQ(failed.status, Status::failed);
  EXPECT_EQ(failed.failure, Failure::service_error);
  EXPECT_NE(failed.message.find("on purpose"), std::string::npos) << failed.message;

  EXPECT_EQ(client->call("calc", "add", {1, 1}, 10s).value, json(2.0));
}

TEST_F(DdsTransportTest, ParamsThatAreNotJsonFailWithBadArguments) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  RawClient raw(test_partition());
  raw.create_reply_reader();
  ASSERT_TRUE(raw.wait_request_matched());
  raw.write(1, simgate_OP_CALL, "calc", "add", "[1, 2");
  auto reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->seq, 1u);
  EXPECT_EQ(reply->status, simgate_ST_FAILED);
  EXPECT_EQ(reply->failure, simgate_FL_BAD_ARGUMENTS);
  EXPECT_NE(reply->message.find("calc.add"), std::string::npos) << reply->message;
  // a scalar is not a parameter list either
  raw.write(2, simgate_OP_CALL, "calc", "add", "42");
  reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->failure, simgate_FL_BAD_ARGUMENTS);
  // and the next good call works
  raw.write(3, simgate_OP_CALL, "calc", "add", "[1, 2]");
  reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->seq, 3u);
  EXPECT_EQ(reply->status, simgate_ST_SUCCESS);
  EXPECT_EQ(json::parse(reply->result), json(3.0));
}

TEST_F(DdsTransportTest, DuplicateSeqOfAPendingCallIsABadRequest) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  RawClient raw(test_partition());
  raw.create_reply_reader();
  ASSERT_TRUE(raw.wait_request_matched());
  // seq 2 is pending (async), so a second seq 2 is refused
  raw.write(2, simgate_OP_CALL, "robot", "goto", "[1]");
  auto reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->status, simgate_ST_ACCEPTED);
  ASSERT_TRUE(goto_.wait_started(1));
  raw.write(2, simgate_OP_CALL, "calc", "add", "[1, 2]");
  reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->seq, 2u);
  EXPECT_EQ(reply->failure, simgate_FL_BAD_REQUEST);
  EXPECT_NE(reply->message.find("duplicate"), std::string::npos) << reply->message;
  // issue #17, item 9: the refusal shares the running call's key (client, seq), so it must
  // not look final: it was ST_FAILED with last = true, which a client took for the end of
  // the running call
  EXPECT_EQ(reply->status, simgate_ST_REFUSED);
  EXPECT_FALSE(reply->last);
  goto_.completion()(Status::success, "arrived");
  reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->seq, 2u);
  EXPECT_EQ(reply->status, simgate_ST_SUCCESS);
  EXPECT_TRUE(reply->last);
}

TEST_F(DdsTransportTest, AsyncCallIsAcceptedThenCompleted) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  auto client = make_client(test_partition());
  auto id = client->start("robot", "goto", {4.0});
  EXPECT_TRUE(client->wait_accepted(id, 10s));
  ASSERT_TRUE(goto_.wait_started(1));
  goto_.completion()(Status::success, {{"x", 4.0}});
  Outcome out = client->wait(id, 10s);
  EXPECT_EQ(out.status, Status::success);
  EXPECT_EQ(out.value, (json{{"x", 4.0}}));
}

TEST_F(DdsTransportTest, CancelEndsTheCallerOwnAsyncCall) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  auto client = make_client(test_partition());
  auto id = client->start("robot", "goto", {1.0});
  ASSERT_TRUE(client->wait_accepted(id, 10s));
  ASSERT_TRUE(goto_.wait_started(1));
  EXPECT_TRUE(client->cancel(id, 10s));
  Outcome out = client->wait(id, 10s);
  EXPECT_EQ(out.status, Status::preempted);
  EXPECT_EQ(out.failure, Failure::cancelled);
  // nothing left to cancel, and ids of other clients are out of reach
  EXPECT_FALSE(client->cancel(id, 10s));
  auto other = make_client(test_partition());
  auto id2 = client->start("robot", "goto", {2.0});
  ASSERT_TRUE(client->wait_accepted(id2, 10s));
  EXPECT_FALSE(other->cancel(id2, 10s));
  EXPECT_TRUE(client->cancel(id2, 10s));
  EXPECT_EQ(client->wait(id2, 10s).failure, Failure::cancelled);
}

TEST_F(DdsTransportTest, SecondCallPreemptsInterruptibleService) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  auto first_client = make_client(test_partition());
  auto second_client = make_client(test_partition());
  auto first = first_client->start("robot", "goto", {1.0});
  ASSERT_TRUE(goto_.wait_started(1));
  auto second = second_client->start("robot", "goto", {2.0});
  Outcome preempted = first_client->wait(first, 10s);
  EXPECT_EQ(preempted.status, Status::preempted);
  EXPECT_EQ(preempted.failure, Failure::preempted);
  ASSERT_TRUE(goto_.wait_started(2));
  goto_.completion()(Status::success);
  EXPECT_EQ(second_client->wait(second, 10s).status, Status::success);
}

TEST_F(DdsTransportTest, NonInterruptibleServiceRefusesSecondCall) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  auto client = make_client(test_partition());
  auto first = client->start("arm", "grasp", nullptr);
  ASSERT_TRUE(grasp_.wait_started(1));
  Outcome refused = client->call("arm", "grasp", nullptr, 10s);
  EXPECT_EQ(refused.status, Status::failed);
  EXPECT_EQ(refused.failure, Failure::busy);
  grasp_.completion()(Status::success, true);
  EXPECT_EQ(client->wait(first, 10s).value, json(true));
}

TEST_F(DdsTransportTest, GlobalPolicyOptionDecidesForServicesWithoutLocalPolicy) {
  auto server = make_server(test_partition(), "server", {{"global_policy", "preempt"}});
  SimThread sim(server);
  auto client = make_client(test_partition());
  auto first = client->start("tool", "use", nullptr);
  ASSERT_TRUE(use_.wait_started(1));
  auto second = client->start("tool", "use", nullptr);
  EXPECT_EQ(client->wait(first, 10s).status, Status::preempted);
  ASSERT_TRUE(use_.wait_started(2));
  use_.completion()(Status::success);
  EXPECT_EQ(client->wait(second, 10s).status, Status::success);
}

TEST_F(DdsTransportTest, CatalogListsEveryServiceForLateJoiners) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  // the client joins after the catalog was published
  auto client = make_client(test_partition());
  json services = client->list_services(10s);
  ASSERT_TRUE(services.is_array());
  std::set<std::string> names;
  json add, go;
  for (const json& s : services) {
    names.insert(s.at("component").get<std::string>() + "." + s.at("name").get<std::string>());
    if (s["component"] == "calc" && s["name"] == "add") add = s;
    if (s["component"] == "robot" && s["name"] == "goto") go = s;
  }
  EXPECT_EQ(names, (std::set<std::string>{"calc.add", "calc.echo", "calc.fail", "calc.count", "calc.whoami",
                                          "robot.goto", "arm.grasp", "tool.use"}));
  ASSERT_TRUE(add.is_object());
  EXPECT_EQ(add["params"].size(), 2u);
  EXPECT_EQ(add["params"][0]["name"], "a");
  EXPECT_EQ(add["doc"], "a + b");
  EXPECT_EQ(go["async"], true);
  // listing again gives the same answer
  EXPECT_EQ(client->list_services(10s).size(), services.size());
}

TEST_F(DdsTransportTest, ListWithoutServerFailsClearly) {
  DdsClient client(DdsClientOptions::from_json(client_options(test_partition())));
  try {
    client.list_services(300ms);
    FAIL() << "list_services without a server returned";
  } catch (const ClientError& e) {
    EXPECT_NE(std::string(e.what()).find(test_partition()), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("catalog"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("network settings"), std::string::npos) << e.what();
  }
}

TEST_F(DdsTransportTest, CallWithoutServerFailsClearly) {
  DdsClient client(DdsClientOptions::from_json(client_options(test_partition())));
  try {
    client.call("calc", "add", {1, 2}, 300ms);
    FAIL() << "call without a server returned";
  } catch (const ClientError& e) {
    std::string what = e.what();
    EXPECT_NE(what.find("no simgate simulation in domain " + std::to_string(test_domain()) + ", partition '" +
                        test_partition() + "'"),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("request reader and reply writer"), std::string::npos) << what;
    EXPECT_NE(what.find("the settings of " + loopback_uri()), std::string::npos) << what;
  }
}

TEST_F(DdsTransportTest, CallTimeoutBoundsTheWaitForAServer) {
  // discovery_timeout (10 s by default) is for start(); call() waits its own timeout
  DdsClient client(DdsClientOptions::from_json(client_options(test_partition())));
  auto started = std::chrono::steady_clock::now();
  try {
    client.call("calc", "add", {1, 2}, 500ms);
    FAIL() << "call without a server returned";
  } catch (const ClientError& e) {
    EXPECT_NE(std::string(e.what()).find("within 500 ms"), std::string::npos) << e.what();
  }
  EXPECT_LT(std::chrono::steady_clock::now() - started, 5s);
}

// The discovery race: the request reaches the server before the server has matched the
// client's reply reader (here: before that reader even exists). The reply waits for it.
TEST_F(DdsTransportTest, ReplyWaitsForTheClientReaderToMatch) {
  std::mutex mutex;
  std::condition_variable cv;
  bool parked = false;
  log::set_level(log::Level::debug);
  log::set_sink([&](log::Level, std::string_view message) {
    if (message.find("parked until its reply reader matches") == std::string_view::npos) return;
    std::lock_guard lock(mutex);
    parked = true;
    cv.notify_all();
  });
  {
    auto server = make_server(test_partition());
    SimThread sim(server);
    RawClient raw(test_partition());
    ASSERT_TRUE(raw.wait_request_matched());
    raw.write(1, simgate_OP_CALL, "calc", "add", "[20, 22]");
    {
      std::unique_lock lock(mutex);
      ASSERT_TRUE(cv.wait_for(lock, 10s, [&] { return parked; }));
    }
    raw.create_reply_reader();
    auto reply = raw.next();
    ASSERT_TRUE(reply);
    EXPECT_EQ(reply->seq, 1u);
    EXPECT_EQ(reply->status, simgate_ST_SUCCESS);
    EXPECT_EQ(json::parse(reply->result), json(42.0));
  }
  log::set_sink({});
  log::set_level(log::Level::info);
}

// A reader without simgate.id USER_DATA is never recognised as matched: its replies are
// written anyway after park_timeout_ms.
TEST_F(DdsTransportTest, ParkedReplyIsWrittenAnywayAfterParkTimeout) {
  auto server = make_server(test_partition(), "server", {{"park_timeout_ms", 200}});
  SimThread sim(server);
  RawClient raw(test_partition());
  raw.create_reply_reader(false);
  ASSERT_TRUE(raw.wait_request_matched());
  raw.write(1, simgate_OP_CALL, "calc", "add", "[1, 1]");
  auto reply = raw.next(10s);
  ASSERT_TRUE(reply);
  EXPECT_EQ(json::parse(reply->result), json(2.0));
}

// A client id is its request writer's GUID: another writer cannot cancel (or otherwise act
// for) that client.
TEST_F(DdsTransportTest, AnotherWriterCannotCancelForAClient) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  RawClient owner(test_partition()), spoofer(test_partition());
  owner.create_reply_reader();
  spoofer.create_reply_reader();
  ASSERT_TRUE(owner.wait_request_matched());
  ASSERT_TRUE(spoofer.wait_request_matched());
  owner.write(1, simgate_OP_CALL, "robot", "goto", "[1]");
  auto reply = owner.next();
  ASSERT_TRUE(reply);
  ASSERT_EQ(reply->status, simgate_ST_ACCEPTED);
  ASSERT_TRUE(goto_.wait_started(1));
  // the spoofed cancel, then a call of the spoofer's own: once that is answered, the
  // cancel (same writer, earlier) has been handled
  spoofer.write(7, simgate_OP_CANCEL, "", "", "", 1, &owner.id());
  spoofer.write(1, simgate_OP_CALL, "calc", "add", "[1, 1]");
  reply = spoofer.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->seq, 7u);  // refused: not its id
  EXPECT_EQ(reply->failure, simgate_FL_BAD_REQUEST);
  reply = spoofer.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->seq, 1u);
  EXPECT_FALSE(goto_.completion().done());
  // the owner still can
  owner.write(2, simgate_OP_CANCEL, "", "", "", 1);
  std::set<std::uint64_t> seen;
  for (int i = 0; i < 2; ++i) {
    reply = owner.next();
    ASSERT_TRUE(reply);
    seen.insert(reply->seq);
    if (reply->seq == 1) {
      EXPECT_EQ(reply->failure, simgate_FL_CANCELLED);
    }
    if (reply->seq == 2) {
      EXPECT_EQ(reply->result, "true");
    }
  }
  EXPECT_EQ(seen, (std::set<std::uint64_t>{1, 2}));
}

TEST_F(DdsTransportTest, ClientThatDisappearsHasItsAsyncCallsCancelled) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  auto client = make_client(test_partition());
  auto id = client->start("robot", "goto", {3.0});
  ASSERT_TRUE(client->wait_accepted(id, 10s));
  ASSERT_TRUE(goto_.wait_started(1));
  Completion running = goto_.completion();
  EXPECT_FALSE(running.done());
  client.reset();  // leaves the domain with its call pending
  EXPECT_TRUE(eventually([&] { return running.done(); }));
  // everyone else is still served
  auto other = make_client(test_partition());
  EXPECT_EQ(other->call("calc", "add", {1, 2}, 10s).value, json(3.0));
}

TEST_F(DdsTransportTest, ServerShutdownAnswersPendingCalls) {
  auto server = make_server(test_partition());
  auto sim = std::make_unique<SimThread>(server);
  auto client = make_client(test_partition());
  auto id = client->start("robot", "goto", {3.0});
  ASSERT_TRUE(client->wait_accepted(id, 10s));
  sim.reset();
  server.reset();
  try {
    Outcome out = client->wait(id, 10s);
    EXPECT_EQ(out.status, Status::failed);
    EXPECT_EQ(out.failure, Failure::shutdown);
  } catch (const ClientError& e) {
    // the server left; the client said so instead of hanging
    EXPECT_NE(std::string(e.what()).find("went away"), std::string::npos) << e.what();
  }
}

TEST_F(DdsTransportTest, TwoSimulationsInTwoPartitionsOfOneDomainDoNotMix) {
  auto server_a = make_server(test_partition("a"), "a");
  auto server_b = make_server(test_partition("b"), "b");
  SimThread sim_a(server_a);
  SimThread sim_b(server_b);
  auto client_a = make_client(test_partition("a"));
  auto client_b = make_client(test_partition("b"));
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(client_a->call("calc", "whoami", nullptr, 10s).value, json("a"));
    EXPECT_EQ(client_b->call("calc", "whoami", nullptr, 10s).value, json("b"));
  }
  // each catalog lists its own server's services once
  EXPECT_EQ(client_a->list_services(10s).size(), 8u);
  EXPECT_EQ(client_b->list_services(10s).size(), 8u);
}

TEST_F(DdsTransportTest, ManyClientsCallConcurrently) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  constexpr int k_clients = 4, k_calls = 25;
  std::vector<std::unique_ptr<DdsClient>> clients;
  for (int c = 0; c < k_clients; ++c) clients.push_back(make_client(test_partition()));
  std::atomic<int> good{0};
  std::vector<std::thread> threads;
  for (int c = 0; c < k_clients; ++c)
    threads.emplace_back([&, c] {
      // pipelined: all calls out, then all answers
      std::vector<DdsClient::CallId> ids;
      for (int i = 0; i < k_calls; ++i) ids.push_back(clients[c]->start("calc", "add", {c, i}));
      for (int i = 0; i < k_calls; ++i) {
        Outcome out = clients[c]->wait(ids[i], 20s);
        if (out.value == json(double(c + i))) ++good;
      }
    });
  for (auto& t : threads) t.join();
  EXPECT_EQ(good, k_clients * k_calls);
}

TEST_F(DdsTransportTest, LargePayloadsTravelBothWays) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  auto client = make_client(test_partition());
  std::string big(256 * 1024, 'x');
  big[1000] = 'y';
  Outcome out = client->call("calc", "echo", {big}, 20s);
  ASSERT_TRUE(out.value);
  EXPECT_EQ(out.value->get<std::string>(), big);
}

TEST_F(DdsTransportTest, ParamsLargerThanMaxParamsAreRefused) {
  auto server = make_server(test_partition(), "server", {{"max_params", 100}});
  SimThread sim(server);
  auto client = make_client(test_partition());
  Outcome out = client->call("calc", "echo", {std::string(200, 'x')}, 10s);
  EXPECT_EQ(out.failure, Failure::bad_arguments);
  EXPECT_NE(out.message.find("max_params"), std::string::npos) << out.message;
}

// Issue #17: params nested 80 000 deep (160 KB, under max_params) once overflowed the stack
// while the error message described them. They are refused before parsing, naming the limit,
// and the server keeps serving.
TEST_F(DdsTransportTest, ParamsNestedDeeperThanMaxDepthAreRefusedAndServerKeepsServing) {
  auto server = make_server(test_partition());
  SimThread sim(server);
  RawClient raw(test_partition());
  raw.create_reply_reader();
  ASSERT_TRUE(raw.wait_request_matched());
  constexpr std::size_t k_deep = 80000;
  const std::string arrays = std::string(k_deep, '[') + std::string(k_deep, ']');
  std::string objects = "{\"text\":";
  for (std::size_t i = 1; i < k_deep; ++i) objects += "{\"a\":";
  objects += "1" + std::string(k_deep, '}');
  std::uint64_t seq = 0;
  for (const std::string& params : {arrays, objects}) {
    raw.write(++seq, simgate_OP_CALL, "calc", "echo", params.c_str());
    auto reply = raw.next();
    ASSERT_TRUE(reply);
    EXPECT_EQ(reply->seq, seq);
    EXPECT_EQ(reply->status, simgate_ST_FAILED);
    EXPECT_EQ(reply->failure, simgate_FL_BAD_ARGUMENTS);
    EXPECT_NE(reply->message.find("max_depth (128)"), std::string::npos) << reply->message.substr(0, 200);
    EXPECT_LT(reply->message.size(), 300u);
  }
  raw.write(++seq, simgate_OP_CALL, "calc", "add", "[1, 2]");
  auto reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->seq, seq);
  EXPECT_EQ(reply->status, simgate_ST_SUCCESS);
  EXPECT_EQ(json::parse(reply->result), json(3.0));
}

// max_depth counts the brackets of the params text: [[1]] is 2 deep. Within the limit a
// value reaches the service (here: a type error whose description stays short).
TEST_F(DdsTransportTest, MaxDepthOptionBoundsParamsNesting) {
  auto server = make_server(test_partition(), "server", {{"max_depth", 3}});
  SimThread sim(server);
  RawClient raw(test_partition());
  raw.create_reply_reader();
  ASSERT_TRUE(raw.wait_request_matched());
  raw.write(1, simgate_OP_CALL, "calc", "echo", "[[[\"[[[[\"]]]");  // brackets inside strings do not count
  auto reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->failure, simgate_FL_BAD_ARGUMENTS);
  EXPECT_EQ(reply->message.find("max_depth"), std::string::npos) << reply->message;
  raw.write(2, simgate_OP_CALL, "calc", "echo", "[[[[1]]]]");
  reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->failure, simgate_FL_BAD_ARGUMENTS);
  EXPECT_NE(reply->message.find("max_depth (3)"), std::string::npos) << reply->message;
  raw.write(3, simgate_OP_CALL, "calc", "echo", "[\"ok\"]");
  reply = raw.next();
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->status, simgate_ST_SUCCESS);
}

// ---- who runs a request and who writes its reply (run_or_submit) ----

// Records the threads a service ran on.
struct ThreadLog {
  std::mutex mutex;             // guards ids
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
  for (int i = 0; i < 3; ++i) EXPECT_EQ(client->call("calc", "add", {i, 1}, 10s).value, json(double(i + 1)));
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

// ---- issue #17: hardening ----

// Collects the log lines that contain `needle` while it lives (any thread).
class LogWatch {
 public:
  // level: the least level logged meanwhile (info again afterwards)
  explicit LogWatch(std::string needle, log::Level level = log::Level::info) : needle_(std::move(needle)) {
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
    std::size_t n = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xe ? 3 : (c >> 3) == 0x1e ? 4 : 0;
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
  EXPECT_NE(reply->message.find("component name is 1048576 bytes, more than 256"), std::string::npos)
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

// The inodes of this process's sockets.
std::set<std::string> socket_inodes() {
  std::set<std::string> out;
  for (const auto& entry : std::filesystem::directory_iterator("/proc/self/fd")) {
    std::error_code ec;
    std::string target = std::filesystem::read_symlink(entry.path(), ec).string();
    if (!ec && target.rfind("socket:[", 0) == 0) out.insert(target.substr(8, target.size() - 9));
  }
  return out;
}

// "address:port" of the sockets of /proc/net/<table> whose inode is in `inodes`.
std::vector<std::string> bound(const std::string& table, const std::set<std::string>& inodes) {
  std::vector<std::string> out;
  std::ifstream in("/proc/net/" + table);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    std::string slot, local, remote, state, queues, timer, retransmits, uid, timeout, inode;
    fields >> slot >> local >> remote >> state >> queues >> timer >> retransmits >> uid >> timeout >> inode;
    if (!inodes.count(inode)) continue;
    // IPv4 "0100007F:1F90": the address in host byte order (little-endian here), the port
    auto colon = local.find(':');
    std::string address = local.substr(0, colon);
    if (address.size() == 8) {
      unsigned long a = std::stoul(address, nullptr, 16);
      address = std::to_string(a & 0xff) + "." + std::to_string(a >> 8 & 0xff) + "." + std::to_string(a >> 16 & 0xff) +
                "." + std::to_string(a >> 24);
    }
    out.push_back(address + ":" + std::to_string(std::stoul(local.substr(colon + 1), nullptr, 16)));
  }
  return out;
}

// Item 9: Cyclone 0.10 binds its receive sockets to the wildcard address whatever interface it
// is given (ddsi_udp.c: unicast and multicast receive sockets bind INADDR_ANY; no setting
// changes it), so the loopback settings cannot keep them off other interfaces.
// docs/transports/dds.md says exactly what that exposes; this checks it is all there is: per
// participant, two UDP ports on 0.0.0.0 (discovery 7410 + 250 d + 2 i, data one above), one
// transmit socket on 127.0.0.1; no multicast port (7400 + 250 d), no TCP, no IPv6.
TEST(DdsExposure, LoopbackSettingsOpenTwoWildcardUdpPortsAndALoopbackOne) {
  const std::set<std::string> before = socket_inodes();
  auto rm = load_transport(k_plugin, server_options(test_partition()));
  std::set<std::string> ours;
  for (const std::string& inode : socket_inodes())
    if (!before.count(inode)) ours.insert(inode);
  std::vector<std::string> udp = bound("udp", ours);
  EXPECT_EQ(bound("tcp", ours), std::vector<std::string>{});
  EXPECT_EQ(bound("udp6", ours), std::vector<std::string>{});
  EXPECT_EQ(bound("tcp6", ours), std::vector<std::string>{});
  ASSERT_EQ(udp.size(), 3u) << ::testing::PrintToString(udp);
  std::vector<unsigned> wildcard;
  for (const std::string& socket : udp) {
    std::string address = socket.substr(0, socket.find(':'));
    unsigned port = static_cast<unsigned>(std::stoul(socket.substr(socket.find(':') + 1)));
    if (address == "0.0.0.0")
      wildcard.push_back(port);
    else
      EXPECT_EQ(address, "127.0.0.1") << socket;
  }
  ASSERT_EQ(wildcard.size(), 2u) << ::testing::PrintToString(udp);
  std::sort(wildcard.begin(), wildcard.end());
  const unsigned base = 7400 + 250 * test_domain();
  EXPECT_EQ((wildcard[0] - (base + 10)) % 2, 0u) << wildcard[0];  // discovery: 7410 + 250 d + 2 i
  EXPECT_LE(wildcard[0], base + 10 + 2 * 60);                       // i <= MaxAutoParticipantIndex
  EXPECT_EQ(wildcard[1], wildcard[0] + 1);                          // data
}

TEST(DdsTransportConfig, UnknownKeysAndBadValuesAreRejectedWithTheirName) {
  auto expect_error = [](json options, const std::string& needle) {
    try {
      load_transport(k_plugin, options);
      ADD_FAILURE() << "accepted " << options.dump();
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  std::string loopback = loopback_uri();
  expect_error({{"domain", test_domain()}, {"config", loopback}, {"bogus", 1}}, "bogus");
  expect_error({{"domain", 999}, {"config", loopback}}, "domain");
  expect_error({{"domain", test_domain()}, {"config", loopback}, {"partition", "sim*"}}, "partition");
  expect_error({{"domain", test_domain()}, {"config", loopback}, {"global_policy", "maybe"}}, "global_policy");
  expect_error({{"domain", test_domain()}, {"config", loopback}, {"max_depth", 1}}, "max_depth");
  expect_error({{"domain", test_domain()}, {"config", loopback}, {"max_depth", 10001}}, "max_depth");
  expect_error({{"domain", test_domain()}, {"config", "<CycloneDDS><Domain><General><NoSuchSetting/>"}}, "domain");
}

// ---- the Cyclone settings are checked before the transport starts (simgate check) ----

// The loopback settings, as XML text (config/dds/loopback.xml).
std::string loopback_xml() {
  std::ifstream in(SIMGATE_LOOPBACK_DDS_XML);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// Loopback settings with `extra` inside their <Domain> element.
std::string loopback_with(const std::string& extra) {
  std::string xml = loopback_xml();
  xml.insert(xml.find("</Domain>"), extra);
  return xml;
}

// What check_cyclone_config() says of `config` on this process's test domain ("" = nothing).
std::string settings_error(const std::string& config) {
  try {
    check_cyclone_config(test_domain(), config);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(DdsSettingsCheck, SettingsCycloneAcceptsPass) {
  EXPECT_EQ(settings_error(""), "");             // the compiled-in loopback settings
  EXPECT_EQ(settings_error(loopback_uri()), "");  // a file:// URI
  EXPECT_EQ(settings_error(SIMGATE_LOOPBACK_DDS_XML), "");  // a plain file name
  EXPECT_EQ(settings_error(loopback_xml()), "");  // XML text
  // two fragments; an element Cyclone closes at the end of the text itself
  EXPECT_EQ(settings_error(loopback_xml() + ",<CycloneDDS><Domain><Discovery><ParticipantIndex>auto"), "");
}

TEST(DdsSettingsCheck, SettingsCycloneRefusesAreAConfigErrorWithCyclonesReason) {
  const std::string expected = "config: expected Cyclone DDS settings (XML, file names or file:// URIs) that Cyclone "
                               "accepts for domain " + std::to_string(test_domain()) + ", found settings it refuses: ";
  // XML its parser cannot read
  EXPECT_THAT(settings_error("<CycloneDDS><Domain></General></Domain></CycloneDDS>"),
              ::testing::StartsWith(expected + "//CycloneDDS/Domain: parser error open/close tag mismatch (General)"));
  // an element that does not exist, in a later fragment too
  EXPECT_THAT(settings_error(loopback_with("<Bogus/>")),
              ::testing::StartsWith(expected + "//CycloneDDS/Domain: Bogus: unknown element"));
  EXPECT_THAT(settings_error(loopback_xml() + ",<CycloneDDS><Domain><Discovery><Bogus/>"),
              ::testing::HasSubstr("//CycloneDDS/Domain/Discovery: Bogus: unknown element"));
  // a misspelt one, with the name meant (Cyclone's setting names, from its installed header)
  EXPECT_THAT(settings_error(loopback_with("<Discovery><ParticipantIndx>auto</ParticipantIndx></Discovery>")),
              ::testing::HasSubstr("ParticipantIndx: unknown element (did you mean 'ParticipantIndex'?)"));
  // a value out of its set
  EXPECT_THAT(settings_error(loopback_with("<Discovery><ParticipantIndex>some</ParticipantIndex></Discovery>")),
              ::testing::HasSubstr("ParticipantIndex"));
  // a file that does not open
  EXPECT_EQ(settings_error("file:///nonexistent/cyclone.xml"),
            expected + "can't open configuration file file:///nonexistent/cyclone.xml");
  // an interface this machine does not have
  std::string absent = loopback_xml();
  absent.replace(absent.find("name=\"lo\""), 9, "name=\"nosuchif0\"");
  EXPECT_EQ(settings_error(absent), expected + "nosuchif0: does not match an available interface.");
}

TEST(DdsSettingsCheck, CheckingWritesNoTraceFile) {
  // Cyclone opens a trace file before its interface lookup: the check sends tracing to stderr
  // (and drops it) instead
  std::string trace = ::testing::TempDir() + "simgate-settings-check-" + std::to_string(getpid()) + ".log";
  std::remove(trace.c_str());
  std::string settings =
      loopback_with("<Tracing><Verbosity>finest</Verbosity><OutputFile>" + trace + "</OutputFile></Tracing>");
  EXPECT_EQ(settings_error(settings), "");
  EXPECT_FALSE(std::ifstream(trace).good()) << trace << " was written";
  EXPECT_THAT(settings_error(settings + ",<CycloneDDS><Domain><Bogus/>"), ::testing::HasSubstr("Bogus"));
  EXPECT_FALSE(std::ifstream(trace).good()) << trace << " was written";
}

TEST(DdsSettingsCheck, EnvMeansTheSettingsOfCycloneddsUri) {
  // ctest sets CYCLONEDDS_URI to the loopback file for every test
  const char* uri = std::getenv("CYCLONEDDS_URI");
  ASSERT_NE(uri, nullptr);
  EXPECT_STREQ(resolve_config("env"), uri);  // was nullptr, which dds_create_domain() reads as Cyclone's defaults
  EXPECT_EQ(settings_error("env"), "");
  std::string saved = uri;
  ::setenv("CYCLONEDDS_URI", "<CycloneDDS><Domain><Bogus/></Domain></CycloneDDS>", 1);
  EXPECT_THAT(settings_error("env"), ::testing::HasSubstr("Bogus: unknown element"));
  ::setenv("CYCLONEDDS_URI", saved.c_str(), 1);
}

TEST(DdsSettingsCheck, TheTransportStartsOnTheDomainItsSettingsWereCheckedOn) {
  // the check creates and deletes the domain: nothing of it is left to the transport
  auto plugin = load_transport_plugin(k_plugin, {});
  json options = server_options(test_partition());
  options["config"] = loopback_xml();
  EXPECT_NO_THROW(plugin->validate(options, "transports.dds.options"));
  auto rm = plugin->create(options, "transports.dds.options");
  ASSERT_NE(rm, nullptr);
  // once the process has the domain, its settings prevail: others are not checked (and
  // would not apply)
  EXPECT_EQ(settings_error(loopback_with("<Bogus/>")), "");
}

TEST(DdsSettingsCheck, ThePluginsValidateNamesTheOptionsPath) {
  auto plugin = load_transport_plugin(k_plugin, {});
  json options = {{"domain", test_domain()}, {"config", loopback_with("<Bogus/>")}};
  try {
    plugin->validate(options, "transports.dds.options");
    FAIL() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("transports.dds.options.config: expected Cyclone DDS settings"));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("Bogus: unknown element"));
  }
  options = {{"domain", 300}};
  EXPECT_THROW(plugin->validate(options, "transports.dds.options"), ConfigError);
}

TEST(DdsTransportConfig, EndpointsNameDomainAndPartition) {
  auto rm = load_transport(k_plugin, server_options(test_partition()));
  auto endpoints = rm->endpoints();
  ASSERT_EQ(endpoints.size(), 1u);
  EXPECT_EQ(endpoints[0], "dds:domain=" + std::to_string(test_domain()) + ";partition=" + test_partition());
}

}  // namespace
}  // namespace simgate::dds::test
