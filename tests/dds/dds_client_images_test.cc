// DdsClient with raw_images against a fake server written with the wire types: what the
// client waits for when a reply's images are not there yet (the two topics are not ordered
// at the reader), and that the wait stays bounded when they never come. The real camera
// over DDS: DdsStreamsTest in dds_process_test.cc.
#include <chrono>
#include <cstring>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "dds_transport_fixture.h"
#include "simgate/core/streams.h"
#include "simgate_streams.h"

namespace simgate::dds::test {
namespace {

// A server of one client, by hand: a request reader in the partition, a reply writer and an
// image writer in the client's reply partition.
class FakeImageServer {
 public:
  FakeImageServer(const std::string& partition, const std::string& client_hex)
      : participant_(test_domain(), loopback_uri().c_str(), "fake server") {
    dds_entity_t pp = participant_.handle();
    QosPtr partition_qos(dds_create_qos());
    dds_qset_partition1(partition_qos.get(), partition.c_str());
    QosPtr reply_partition_qos(dds_create_qos());
    dds_qset_partition1(reply_partition_qos.get(), (partition + "/" + client_hex).c_str());
    QosPtr qos = make_qos(false, 0, DDS_SECS(1));
    dds_entity_t subscriber = dds_create_subscriber(pp, partition_qos.get(), nullptr);
    requests_ = dds_create_reader(
        subscriber, dds_create_topic(pp, &simgate_Request_desc, k_request_topic, nullptr, nullptr),
        qos.get(), nullptr);
    dds_entity_t publisher = dds_create_publisher(pp, reply_partition_qos.get(), nullptr);
    replies_ = dds_create_writer(
        publisher, dds_create_topic(pp, &simgate_Reply_desc, k_reply_topic, nullptr, nullptr),
        qos.get(), nullptr);
    images_ = dds_create_writer(
        publisher,
        dds_create_topic(pp, &simgate_stream_Image_desc, k_reply_image_topic, nullptr, nullptr),
        qos.get(), nullptr);
  }
  bool ok() const { return requests_ > 0 && replies_ > 0 && images_ > 0; }

  // The seq of the next request (0 if none within 10 s).
  std::uint64_t take_request() {
    std::uint64_t seq = 0;
    eventually([&] {
      void* samples[1] = {nullptr};
      dds_sample_info_t info;
      if (dds_take(requests_, samples, &info, 1, 1) != 1) return false;
      if (info.valid_data)
        std::memcpy(client_.data(), static_cast<simgate_Request*>(samples[0])->id.client, 16);
      if (info.valid_data) seq = static_cast<simgate_Request*>(samples[0])->id.seq;
      dds_return_loan(requests_, samples, 1);
      return seq != 0;
    });
    return seq;
  }

  void reply(std::uint64_t seq, const json& result) {
    const std::string text = result.dump();
    simgate_Reply reply{};
    std::memcpy(reply.client, client_.data(), client_.size());
    reply.seq = seq;
    reply.status = simgate_ST_SUCCESS;
    reply.failure = simgate_FL_NONE;
    reply.last = true;
    reply.result = const_cast<char*>(text.c_str());
    reply.message = const_cast<char*>("");
    reply.data = const_cast<char*>("");
    ASSERT_GE(dds_write(replies_, &reply), 0);
  }

  // A 2 x 2 rgb8 image of one colour.
  void image(std::uint64_t seq, double time, std::uint8_t r, std::uint8_t g, std::uint8_t b) {
    std::vector<std::uint8_t> pixels;
    for (int i = 0; i < 4; ++i) pixels.insert(pixels.end(), {r, g, b});
    simgate_stream_Image image{};
    image.component = const_cast<char*>("rig.camera");
    image.seq = seq;
    image.time = time;
    image.height = 2;
    image.width = 2;
    image.encoding = const_cast<char*>("rgb8");
    image.step = 6;
    const double k[9] = {2, 0, 1, 0, 2, 1, 0, 0, 1};
    std::memcpy(image.K, k, sizeof k);
    image.data = {static_cast<uint32_t>(pixels.size()), static_cast<uint32_t>(pixels.size()),
                  pixels.data(), false};
    ASSERT_GE(dds_write(images_, &image), 0);
  }

 private:
  Participant participant_;    // its own participant (as a remote server's)
  dds_entity_t requests_ = 0;  // simgate_Request
  dds_entity_t replies_ = 0;   // simgate_Reply, in "<partition>/<client>"
  dds_entity_t images_ = 0;    // simgate_ReplyImage, same partition
  ClientId client_{};          // the last request's client
};

DdsClientOptions raw_options(const std::string& partition) {
  json options = client_options(partition);
  options["raw_images"] = true;
  return DdsClientOptions::from_json(options);
}

json record(double time) {
  return {
      {"encoding", "rgb8"}, {"format", "raw"}, {"width", 2}, {"height", 2}, {"timestamp", time}};
}

TEST(DdsClientImagesTest, AReplyThatArrivesBeforeItsImagesIsReturnedWithThemOnceTheyCome) {
  const std::string partition = test_partition();
  DdsClient client(raw_options(partition));
  FakeImageServer server(partition, client.id());
  ASSERT_TRUE(server.ok());
  ASSERT_TRUE(client.wait_for_server(10s));
  const DdsClient::CallId id = client.start("rig.camera", "capture", {2});
  const std::uint64_t seq = server.take_request();
  ASSERT_EQ(seq, id);
  // the reply first (a real server writes the images first; the reader may see either first)
  server.reply(seq, json::array({record(1.0), record(2.0)}));
  ASSERT_TRUE(client.wait_accepted(id, 10s));  // the final reply is in the client
  server.image(seq, 1.0, 255, 0, 0);
  server.image(seq, 2.0, 0, 0, 255);
  const Outcome outcome = client.wait(id, 10s);
  ASSERT_EQ(outcome.status, Status::success);
  ASSERT_TRUE(outcome.value && outcome.value->is_array())
      << (outcome.value ? outcome.value->dump() : "");
  EXPECT_EQ((*outcome.value)[0]["format"], "raw");
  ASSERT_EQ(outcome.attachments.size(), 2u);
  ASSERT_TRUE(outcome.attachments[0] && outcome.attachments[1]);
  // in record order, matched by seq: red, then blue
  EXPECT_EQ(outcome.attachments[0]->content, "image");
  EXPECT_EQ(outcome.attachments[0]->bytes,
            std::vector<std::uint8_t>({255, 0, 0, 255, 0, 0, 255, 0, 0, 255, 0, 0}));
  EXPECT_EQ(outcome.attachments[0]->description["timestamp"], 1.0);
  EXPECT_EQ(outcome.attachments[0]->description["component"], "rig.camera");
  EXPECT_EQ(outcome.attachments[0]->description["intrinsic_matrix"],
            json::parse("[[2,0,1],[0,2,1],[0,0,1]]"));
  EXPECT_EQ(outcome.attachments[1]->bytes[2], 255);
  EXPECT_EQ(outcome.attachments[1]->description["timestamp"], 2.0);
}

TEST(DdsClientImagesTest, ARecordThatKeptItsPngHasANullAttachment) {
  const std::string partition = test_partition();
  DdsClient client(raw_options(partition));
  FakeImageServer server(partition, client.id());
  ASSERT_TRUE(server.ok());
  ASSERT_TRUE(client.wait_for_server(10s));
  const DdsClient::CallId id = client.start("rig.camera", "capture", {2});
  const std::uint64_t seq = server.take_request();
  ASSERT_EQ(seq, id);
  // the server could send the first image only: the second record keeps its PNG
  server.image(seq, 1.0, 255, 0, 0);
  server.reply(
      seq, json::array(
               {record(1.0), {{"format", "png"}, {"image", "iVBORw0KGgo="}, {"timestamp", 2.0}}}));
  const Outcome outcome = client.wait(id, 10s);
  ASSERT_EQ(outcome.attachments.size(), 2u);
  ASSERT_TRUE(outcome.attachments[0]);
  EXPECT_EQ(outcome.attachments[0]->description["timestamp"], 1.0);
  EXPECT_FALSE(outcome.attachments[1]);
}

TEST(DdsClientImagesTest, AReplyWhoseImagesNeverComeEndsAtTheTimeoutSayingHowManyCame) {
  const std::string partition = test_partition();
  DdsClient client(raw_options(partition));
  FakeImageServer server(partition, client.id());
  ASSERT_TRUE(server.ok());
  ASSERT_TRUE(client.wait_for_server(10s));
  const DdsClient::CallId id = client.start("rig.camera", "capture", {2});
  const std::uint64_t seq = server.take_request();
  ASSERT_EQ(seq, id);
  server.image(seq, 1.0, 255, 0, 0);
  server.reply(seq, json::array({record(1.0), record(2.0)}));
  ASSERT_TRUE(client.wait_accepted(id, 10s));
  try {
    client.wait(id, 300ms);
    FAIL() << "wait() returned without the second image";
  } catch (const ClientError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("call " + std::to_string(id) + " replied"), std::string::npos) << what;
    EXPECT_NE(what.find("of the 2 raw images"), std::string::npos) << what;
    EXPECT_NE(what.find("within 300 ms"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace simgate::dds::test
