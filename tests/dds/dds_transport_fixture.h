// dds_transport_fixture.h — the DdsTransportTest fixture (a server with test services,
// DdsClients to call it) and RawClient (the wire types written and read directly), shared by
// the DDS transport's test files. Named, not anonymous: the DdsTransportTest suite spans
// several files, and GoogleTest requires one fixture type per suite.
#ifndef SIMGATE_TESTS_DDS_DDS_TRANSPORT_FIXTURE_H_
#define SIMGATE_TESTS_DDS_DDS_TRANSPORT_FIXTURE_H_

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "dds_support.h"
#include "dds_test_support.h"
#include "simgate/client/dds_client.h"
#include "simgate_streams.h"

namespace simgate::dds::test {

using client::ClientError;
using client::DdsClient;
using client::DdsClientOptions;

inline const char* const k_plugin = SIMGATE_TEST_PLUGIN_DIR "/libsimgate_transport_dds.so";

// A client speaking the wire types directly (no DdsClient), to control every field and
// the moment its reply reader appears.
class RawClient {
 public:
  explicit RawClient(const std::string& partition)
      : participant_(test_domain(), ("file://" + std::string(SIMGATE_LOOPBACK_DDS_XML)).c_str(),
                     "raw client"),
        partition_(partition) {
    dds_entity_t pp = participant_.handle();
    QosPtr partition_qos(dds_create_qos());
    dds_qset_partition1(partition_qos.get(), partition.c_str());
    publisher_ = dds_create_publisher(pp, partition_qos.get(), nullptr);
    dds_entity_t topic =
        dds_create_topic(pp, &simgate_Request_desc, k_request_topic, nullptr, nullptr);
    QosPtr qos = make_qos(false, 0, DDS_SECS(1));
    writer_ = dds_create_writer(publisher_, topic, qos.get(), nullptr);
    dds_guid_t guid;
    dds_get_guid(writer_, &guid);
    id_ = to_client_id(guid);
  }

  bool wait_request_matched(std::chrono::milliseconds timeout = 10s) {
    return eventually(
        [&] {
          dds_publication_matched_status_t st;
          dds_get_publication_matched_status(writer_, &st);
          return st.current_count > 0;
        },
        timeout);
  }

  // announce: put "simgate.id=<our id>" in the reader's USER_DATA, as clients should;
  // max_samples: how many replies the reader holds (a reader that never takes stops
  // accepting, hence acknowledging, beyond that)
  void create_reply_reader(bool announce = true, int32_t max_samples = DDS_LENGTH_UNLIMITED) {
    reader_ = own_partition_reader(&simgate_Reply_desc, k_reply_topic, announce, max_samples);
    ASSERT_GT(reader_, 0);
  }

  // A reader of its replies' images (simgate_ReplyImage, in its own partition), announcing
  // its id: the server then sends its replies' images raw. Create it before the reply reader
  // (as clients must); max_samples as create_reply_reader's. Never read by the tests.
  void create_image_reader(int32_t max_samples = DDS_LENGTH_UNLIMITED) {
    image_reader_ =
        own_partition_reader(&simgate_stream_Image_desc, k_reply_image_topic, true, max_samples);
    ASSERT_GT(image_reader_, 0);
  }

  // A reader of the client's progress reports (simgate_Progress, in its own partition):
  // best effort, as the server's writer; keeps the last `depth` reports.
  void create_progress_reader(int32_t depth = 64) {
    dds_entity_t pp = participant_.handle();
    QosPtr partition_qos(dds_create_qos());
    dds_qset_partition1(partition_qos.get(), (partition_ + "/" + to_hex(id_)).c_str());
    dds_entity_t subscriber = dds_create_subscriber(pp, partition_qos.get(), nullptr);
    dds_entity_t topic =
        dds_create_topic(pp, &simgate_Reply_desc, k_progress_topic, nullptr, nullptr);
    QosPtr qos = make_qos(false, depth, 0);
    dds_qset_reliability(qos.get(), DDS_RELIABILITY_BEST_EFFORT, 0);
    progress_reader_ = dds_create_reader(subscriber, topic, qos.get(), nullptr);
    ASSERT_GT(progress_reader_, 0);
  }

  // as_client: write with another client's id (what a spoofer would do); progress: the
  // call asks for progress reports; timeout_ms: the call's deadline (0: none)
  void write(std::uint64_t seq, simgate_Op op, const char* component, const char* service,
             const char* params, std::uint64_t target = 0, const ClientId* as_client = nullptr,
             bool progress = false, std::uint32_t timeout_ms = 0) {
    simgate_Request rq{};
    rq.progress = progress;
    std::memcpy(rq.id.client, (as_client ? *as_client : id_).data(), 16);
    rq.id.seq = seq;
    rq.op = op;
    rq.component = const_cast<char*>(component);
    rq.service = const_cast<char*>(service);
    rq.params = const_cast<char*>(params);
    rq.target = target;
    rq.timeout_ms = timeout_ms;
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
    eventually(
        [&] {
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
        },
        timeout);
    return out;
  }

  // The progress reports received so far (create_progress_reader), taken.
  std::vector<Reply> take_progress() {
    std::vector<Reply> out;
    void* samples[1] = {nullptr};
    dds_sample_info_t info;
    while (dds_take(progress_reader_, samples, &info, 1, 1) == 1) {
      const auto& r = *static_cast<const simgate_Reply*>(samples[0]);
      if (info.valid_data && std::memcmp(r.client, id_.data(), 16) == 0)
        out.push_back(Reply{r.seq, r.status, r.failure, r.last, r.result, r.message});
      dds_return_loan(progress_reader_, samples, 1);
      samples[0] = nullptr;
    }
    return out;
  }

  const ClientId& id() const { return id_; }

 private:
  // A reliable reader of `topic` in the client's own partition, "<partition>/<id>", where the
  // server writes to it alone; `announce`: "simgate.id=<our id>" in its USER_DATA, as clients
  // should; `max_samples` bounds what it holds.
  dds_entity_t own_partition_reader(const dds_topic_descriptor_t* type, const char* topic_name,
                                    bool announce, int32_t max_samples) {
    dds_entity_t pp = participant_.handle();
    QosPtr partition_qos(dds_create_qos());
    dds_qset_partition1(partition_qos.get(), (partition_ + "/" + to_hex(id_)).c_str());
    dds_entity_t subscriber = dds_create_subscriber(pp, partition_qos.get(), nullptr);
    dds_entity_t topic = dds_create_topic(pp, type, topic_name, nullptr, nullptr);
    QosPtr qos = make_qos(false, 0, DDS_SECS(1));
    dds_qset_resource_limits(qos.get(), max_samples, DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED);
    const std::string userdata = "simgate.id=" + to_hex(id_);
    if (announce) dds_qset_userdata(qos.get(), userdata.data(), userdata.size());
    return dds_create_reader(subscriber, topic, qos.get(), nullptr);
  }

  Participant participant_;           // own participant
  std::string partition_;             // the server's
  dds_entity_t publisher_ = 0;        // in the partition
  dds_entity_t writer_ = 0;           // requests
  dds_entity_t reader_ = 0;           // replies (created on demand)
  dds_entity_t progress_reader_ = 0;  // progress reports (created on demand)
  dds_entity_t image_reader_ = 0;     // its replies' images (created on demand)
  ClientId id_{};                     // our request writer's GUID
};

class DdsTransportTest : public ::testing::Test {
 protected:
  // A server with: calc.add(a, b), calc.echo(text), calc.fail(), calc.count(),
  // calc.whoami() -> `name`, robot.goto(x) async interruptible, arm.grasp() async
  // non-interruptible, tool.use() async without a local policy.
  std::shared_ptr<RequestManager> make_server(const std::string& partition,
                                              const std::string& name = "server",
                                              json extra = json::object()) {
    auto rm = load_transport(k_plugin, server_options(partition, extra));
    rm->register_service("calc", [](double a, double b) { return a + b; }, "add", {"a", "b"})
        .doc("a + b");
    rm->register_service("calc", [](std::string text) { return text; }, "echo", {"text"});
    rm->register_service(
        "calc", []() -> int { throw ServiceError("calc.fail: it failed on purpose"); }, "fail");
    rm->register_service("calc", [this]() { return ++count_; }, "count");
    rm->register_service("calc", [name]() { return name; }, "whoami");
    rm->register_async_service("robot", [this](Completion c, double) { goto_.on_start(c); }, "goto",
                               {"x"})
        .interruptible();
    rm->register_async_service(
          "arm", [this](Completion c) { grasp_.on_start(c); }, "grasp")
        .noninterruptible();
    rm->register_async_service("tool", [this](Completion c) { use_.on_start(c); }, "use");
    return rm;
  }

  std::unique_ptr<DdsClient> make_client(const std::string& partition) {
    auto c = std::make_unique<DdsClient>(DdsClientOptions::from_json(client_options(partition)));
    EXPECT_TRUE(c->wait_for_server(10s));
    return c;
  }

  // `raw`, its reply reader matched, with robot.goto pending under `seq` (ACCEPTED, started).
  void start_goto(RawClient& raw, std::uint64_t seq) {
    raw.create_reply_reader();
    ASSERT_TRUE(raw.wait_request_matched());
    raw.write(seq, simgate_OP_CALL, "robot", "goto", "[1]");
    auto accepted = raw.next();
    ASSERT_TRUE(accepted);
    EXPECT_EQ(accepted->status, simgate_ST_ACCEPTED);
    ASSERT_TRUE(goto_.wait_started(1));
  }

  std::atomic<int> count_{0};  // calc.count
  AsyncProbe goto_;            // robot.goto
  AsyncProbe grasp_;           // arm.grasp
  AsyncProbe use_;             // tool.use
};

}  // namespace simgate::dds::test

#endif  // SIMGATE_TESTS_DDS_DDS_TRANSPORT_FIXTURE_H_
