// The DDS transport's side of the images in replies (docs/transports/dds.md, "Images in
// replies"), with a fake camera whose service, like the real one, leaves the PNG out of its
// record when its caller takes the pixels raw (CallContext::takes_raw_attachments) and
// attaches the pixels with a to_json that makes the PNG record: a client with an image reader
// is called raw and gets no PNG; one without is not and gets it; an image that cannot go raw
// after all (its image writer full past park_timeout_ms) gets its PNG made from its pixels by
// the transport. The real camera over DDS: DdsStreamsTest in dds_process_test.cc.
#include <atomic>
#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "dds_transport_fixture.h"
#include "simgate/core/call_context.h"
#include "simgate/core/streams.h"

namespace simgate::dds::test {
namespace {

// "cam.shot(size)": an image of `size` bytes (rgb8, one row), the record raw or with its
// "PNG" as its caller takes it; counts the callers taken raw and the PNGs made on demand.
struct FakeCamera {
  std::atomic<int> raw_calls{0};  // calls whose caller took the attachments raw
  std::atomic<int> pngs_made{0};  // to_json calls (the transport's fallback)
  double clock = 0;               // the last image's timestamp (the service's thread only)

  // The record with its PNG ("PNG-<width>": the test's stand-in for the base64 PNG).
  static json png_record(int width, double timestamp) {
    return {{"encoding", "rgb8"},     {"format", "png"},
            {"width", width},         {"height", 1},
            {"timestamp", timestamp}, {"image", "PNG-" + std::to_string(width)}};
  }

  json shot(int size) {
    const double timestamp = clock += 0.5;
    const int width = size / 3;
    auto payload = std::make_shared<StreamPayload>();
    payload->content = "image";
    payload->description = {{"component", "cam"},
                            {"width", width},
                            {"height", 1},
                            {"encoding", "rgb8"},
                            {"step", width * 3},
                            {"is_bigendian", false},
                            {"intrinsic_matrix", {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}},
                            {"timestamp", timestamp}};
    payload->bytes.assign(static_cast<std::size_t>(width) * 3, 7);
    payload->to_json = [this](const StreamPayload& p) {
      ++pngs_made;
      return png_record(p.description["width"], p.description["timestamp"]);
    };
    CallContext::attach(payload);
    json record = png_record(width, timestamp);
    if (caller_takes_raw_attachments()) {
      ++raw_calls;
      record.erase("image");
      record["format"] = "raw";
    }
    return record;
  }
};

class DdsReplyImagesTest : public DdsTransportTest {
 protected:
  std::shared_ptr<RequestManager> make_camera_server(json extra = json::object()) {
    auto server = make_server(test_partition(), "server", std::move(extra));
    server->register_service("cam", [this](int size) { return camera_.shot(size); }, "shot",
                             {"size"});
    return server;
  }
  std::unique_ptr<DdsClient> make_camera_client(bool raw_images) {
    json options = client_options(test_partition());
    options["raw_images"] = raw_images;
    auto c = std::make_unique<DdsClient>(DdsClientOptions::from_json(options));
    EXPECT_TRUE(c->wait_for_server(10s));
    return c;
  }

  FakeCamera camera_;
};

TEST_F(DdsReplyImagesTest, AClientReadingItsImagesRawIsCalledRawAndGetsNoPng) {
  auto server = make_camera_server();
  SimThread sim(server);
  auto c = make_camera_client(true);
  for (int i = 0; i < 3; ++i) {
    const Outcome o = c->call("cam", "shot", {30}, 10s);
    ASSERT_EQ(o.status, Status::success) << o.message;
    EXPECT_EQ((*o.value)["format"], "raw") << o.value->dump();
    EXPECT_FALSE(o.value->contains("image")) << o.value->dump();
    ASSERT_EQ(o.attachments.size(), 1u);
    ASSERT_TRUE(o.attachments[0]);
    EXPECT_EQ(o.attachments[0]->bytes, std::vector<std::uint8_t>(30, 7));
  }
  EXPECT_EQ(camera_.raw_calls, 3);
  EXPECT_EQ(camera_.pngs_made, 0);  // no PNG anywhere
}

TEST_F(DdsReplyImagesTest, AClientWithoutAnImageReaderIsNotCalledRawAndGetsThePng) {
  auto server = make_camera_server();
  SimThread sim(server);
  auto c = make_camera_client(false);
  const Outcome o = c->call("cam", "shot", {30}, 10s);
  ASSERT_EQ(o.status, Status::success) << o.message;
  EXPECT_EQ(*o.value, FakeCamera::png_record(10, (*o.value)["timestamp"]));
  EXPECT_TRUE(o.attachments.empty());
  EXPECT_EQ(camera_.raw_calls, 0);
  EXPECT_EQ(camera_.pngs_made, 0);  // the service's own PNG
  // calc.add and the rest are called as before
  EXPECT_EQ(c->call("calc", "add", {1, 2}, 10s).value, json(3.0));
}

// The client's image reader holds one image and never takes it: past its first images (600 kB
// each, beyond Cyclone's WhcHigh), the image writer stays full, and after park_timeout_ms the
// reply goes with its PNG, which the service, having called it raw, did not make.
TEST_F(DdsReplyImagesTest, AnImageThatCannotGoRawAfterAllGetsItsPngMadeFromItsPixels) {
  auto server = make_camera_server({{"park_timeout_ms", 300}});
  SimThread sim(server);
  RawClient client(test_partition());
  client.create_image_reader(1);
  client.create_reply_reader();
  ASSERT_TRUE(client.wait_request_matched());
  constexpr int k_size = 600000;
  std::vector<json> results;
  for (std::uint64_t seq = 1; seq <= 3; ++seq) {
    client.write(seq, simgate_OP_CALL, "cam", "shot", "[600000]");
    auto reply = client.next(30s);
    ASSERT_TRUE(reply) << "reply " << seq;
    ASSERT_EQ(reply->seq, seq);
    ASSERT_EQ(reply->status, simgate_ST_SUCCESS) << reply->message;
    results.push_back(json::parse(reply->result));
  }
  // every call was made raw (the image reader is matched), the first image went raw
  EXPECT_EQ(camera_.raw_calls, 3);
  EXPECT_EQ(results[0]["format"], "raw") << results[0].dump();
  EXPECT_FALSE(results[0].contains("image"));
  // the last could not: its record is the full one, made from its pixels
  const json& last = results[2];
  EXPECT_EQ(last, FakeCamera::png_record(k_size / 3, last["timestamp"])) << last.dump();
  EXPECT_GE(camera_.pngs_made, 1);
  int pngs = 0;
  for (const json& result : results) pngs += result["format"] == "png";
  EXPECT_EQ(camera_.pngs_made, pngs);
}

}  // namespace
}  // namespace simgate::dds::test
