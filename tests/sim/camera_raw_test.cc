// The cameras' replies to a caller that takes its attachments raw (Call::raw_attachments: the
// DDS transport, for a client reading its replies' images): the records have no PNG and say
// "format": "raw", the pixels come as the attachments, and each attachment still makes the
// PNG record (to_json) for a transport that has to send it encoded after all. Callers that do
// not take them raw get what they always got, whatever the raw callers asked before. Rendered
// for real (EGL, Mesa's llvmpipe), on the red box scene.
#include <chrono>
#include <cstring>
#include <thread>

#include "camera_png.h"
#include "camera_scene.h"
#include "mjcf_fixture.h"
#include "simgate/core/streams.h"

namespace simgate::sim {
namespace {

using testing::decode_base64;
using testing::decode_png;
using testing::DecodedPng;

const std::string k_camera_raw_scene =
    simgate::testing::red_box_scene("camera-raw-test", "0.01", "10", /*eye_site=*/true);
using simgate::testing::is_red;
using simgate::testing::k_red_box_face;
using simgate::testing::k_render_deadline;

class CameraRawTest : public testing::MjcfSim {
 protected:
  void SetUp() override {
    load_string(k_camera_raw_scene);
    robot_ = &add_robot("rig", "rig");
  }

  // Steps (and serves) until `id` has its outcome, at most k_render_deadline of wall time.
  Outcome wait_for(RequestId id) { return step_until_outcome(id, k_render_deadline); }
  Outcome raw(const std::string& service, json params = json::array()) {
    return wait_for(rm_->call_raw("rig.camera", service, std::move(params)));
  }
  Outcome png(const std::string& service, json params = json::array()) {
    return wait_for(rm_->call("rig.camera", service, std::move(params)));
  }

  Robot* robot_ = nullptr;
};

// A 64x48 video record taken raw: no image, "format": "raw", the rest as the PNG record's;
// its attachment the red box's pixels, whose to_json makes the PNG record of those pixels.
void expect_raw_video(const json& record, const std::shared_ptr<const StreamPayload>& pixels) {
  ASSERT_TRUE(record.is_object()) << record.dump();
  EXPECT_FALSE(record.contains("image")) << record.dump();
  EXPECT_EQ(record["format"], "raw");
  EXPECT_EQ(record["encoding"], "rgb8");
  EXPECT_EQ(record["width"], 64);
  EXPECT_EQ(record["height"], 48);
  EXPECT_EQ(record["intrinsic_matrix"].size(), 3u);
  ASSERT_TRUE(pixels);
  EXPECT_EQ(pixels->content, "image");
  EXPECT_EQ(pixels->description["encoding"], "rgb8");
  EXPECT_EQ(pixels->description["timestamp"], record["timestamp"]);
  ASSERT_EQ(pixels->bytes.size(), 64u * 48 * 3);
  EXPECT_TRUE(is_red(&pixels->bytes[(24 * 64 + 32) * 3]));
  EXPECT_FALSE(is_red(&pixels->bytes[(2 * 64 + 2) * 3]));
  // the transport's fallback: the PNG record, made from the pixels on demand
  ASSERT_TRUE(pixels->to_json);
  json full = pixels->to_json(*pixels);
  EXPECT_EQ(full["format"], "png");
  const DecodedPng png = decode_png(decode_base64(full["image"].get<std::string>()));
  ASSERT_TRUE(png.error.empty()) << png.error;
  EXPECT_TRUE(
      std::equal(png.pixels.begin(), png.pixels.end(), pixels->bytes.begin(), pixels->bytes.end()));
  full.erase("image");
  full["format"] = "raw";
  EXPECT_EQ(full, record);
}

TEST_F(CameraRawTest, ACallerTakingAttachmentsRawGetsRecordsWithoutPngAndThePixelsBeside) {
  add_component(*robot_, "camera", "video_camera",
                {{"camera", "front"}, {"cam_width", 64}, {"cam_height", 48}});
  serve();
  // get_local_data's first image (rendered now), get_image's, a capture's two, the last one
  const Outcome first = raw("get_local_data");
  ASSERT_EQ(first.status, Status::success) << first.message;
  ASSERT_EQ(first.attachments.size(), 1u);
  expect_raw_video(*first.value, first.attachments[0]);
  const Outcome image = raw("get_image");
  ASSERT_EQ(image.status, Status::success) << image.message;
  ASSERT_EQ(image.attachments.size(), 1u);
  expect_raw_video(*image.value, image.attachments[0]);
  const Outcome capture = raw("capture", {2});
  ASSERT_EQ(capture.status, Status::success) << capture.message;
  ASSERT_TRUE(capture.value && capture.value->size() == 2u);
  ASSERT_EQ(capture.attachments.size(), 2u);
  expect_raw_video((*capture.value)[0], capture.attachments[0]);
  expect_raw_video((*capture.value)[1], capture.attachments[1]);
  const Outcome last = raw("get_local_data");
  ASSERT_EQ(last.attachments.size(), 1u);
  EXPECT_EQ(*last.value, (*capture.value)[1]);
  expect_raw_video(*last.value, last.attachments[0]);
}

TEST_F(CameraRawTest, CallersNotTakingThemRawStillGetPngsWhateverTheRawCallersGotBefore) {
  add_component(*robot_, "camera", "video_camera",
                {{"camera", "front"}, {"cam_width", 64}, {"cam_height", 48}});
  serve();
  const Outcome raw_image = raw("get_image");
  ASSERT_EQ(raw_image.status, Status::success) << raw_image.message;
  EXPECT_FALSE(raw_image.value->contains("image"));
  // the last image has no PNG: get_local_data renders one with it (off the lock, as its first)
  const Outcome local = png("get_local_data");
  ASSERT_EQ(local.status, Status::success) << local.message;
  ASSERT_TRUE(local.value->contains("image")) << local.value->dump();
  EXPECT_EQ((*local.value)["format"], "png");
  EXPECT_GE((*local.value)["timestamp"].get<double>(),
            (*raw_image.value)["timestamp"].get<double>());
  const DecodedPng decoded = decode_png(decode_base64((*local.value)["image"].get<std::string>()));
  ASSERT_TRUE(decoded.error.empty()) << decoded.error;
  EXPECT_TRUE(is_red(&decoded.pixels[(24 * 64 + 32) * 3]));
  // get_image and capture: PNGs, the pixels beside as always
  const Outcome image = png("get_image");
  ASSERT_EQ(image.status, Status::success) << image.message;
  EXPECT_EQ((*image.value)["format"], "png");
  EXPECT_TRUE((*image.value)["image"].is_string());
  EXPECT_EQ(image.attachments.size(), 1u);
  const Outcome capture = png("capture", {1});
  ASSERT_EQ(capture.status, Status::success) << capture.message;
  EXPECT_TRUE((*capture.value)[0]["image"].is_string());
  // and a raw caller's get_local_data after them: the same image, its PNG left out
  const Outcome last = raw("get_local_data");
  json expected = (*capture.value)[0];
  expected.erase("image");
  expected["format"] = "raw";
  EXPECT_EQ(*last.value, expected);
  ASSERT_EQ(last.attachments.size(), 1u);
  expect_raw_video(*last.value, last.attachments[0]);
}

TEST_F(CameraRawTest, ADepthRecordTakenRawKeepsItsDepthsAndItsPngComesOnDemand) {
  add_component(*robot_, "camera", "depth_camera",
                {{"site", "eye"},
                 {"cam_width", 160},
                 {"cam_height", 120},
                 {"cam_near", 0.05},
                 {"cam_far", 20}});
  serve();
  const Outcome o = raw("get_image");
  ASSERT_EQ(o.status, Status::success) << o.message;
  const json& record = *o.value;
  EXPECT_FALSE(record.contains("image")) << record.dump();
  EXPECT_EQ(record["format"], "raw");
  EXPECT_EQ(record["encoding"], "mono16");
  EXPECT_EQ(record["depth_unit"], "mm");
  EXPECT_TRUE(record["min_depth"].is_number());
  EXPECT_TRUE(record["max_depth"].is_number());
  ASSERT_EQ(o.attachments.size(), 1u);
  const StreamPayload& pixels = *o.attachments[0];
  EXPECT_EQ(pixels.description["encoding"], "32FC1");
  ASSERT_EQ(pixels.bytes.size(), 160u * 120 * sizeof(float));
  float middle;
  std::memcpy(&middle, &pixels.bytes[(60 * 160 + 80) * sizeof(float)], sizeof middle);
  EXPECT_NEAR(middle, k_red_box_face, 0.005);
  // the PNG record on demand: the same record with its 16-bit PNG
  json full = pixels.to_json(pixels);
  EXPECT_EQ(full["format"], "png");
  const DecodedPng png = decode_png(decode_base64(full["image"].get<std::string>()));
  ASSERT_TRUE(png.error.empty()) << png.error;
  EXPECT_EQ(png.bit_depth, 16);
  full.erase("image");
  full["format"] = "raw";
  EXPECT_EQ(full, record);
}

}  // namespace
}  // namespace simgate::sim
