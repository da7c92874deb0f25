// video_camera and depth_camera rendered for real (EGL, Mesa's llvmpipe), checked by their
// pixels: a red box in front of the camera is red in the middle of the image, the depth of
// a face at a known distance is that distance; capture n returns n images after enough
// steps; bad options are refused naming the option; without GL the services answer FAILED
// with the reason. The images are decoded from the PNG the services return
// (camera_png.h), so the encoder is checked on the way.
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <future>
#include <iostream>
#include <thread>

#include "camera_png.h"
#include "camera_scene.h"
#include "mjcf_fixture.h"
#include "simgate/core/log.h"
#include "simgate/core/streams.h"
#include "simgate/sim/cameras.h"
#include "simgate/sim/renderer.h"

namespace simgate::sim {
namespace {

using testing::decode_base64;
using testing::decode_png;
using testing::DecodedPng;
using ::testing::HasSubstr;

// A rig 0.5 m above a grey floor, looking along +x (MJCF camera "front", and site "eye"
// for a frame camera); a red box whose near face is at x = 1.7 m, centred on the axis.
const std::string k_camera_scene =
    simgate::testing::red_box_scene("camera-test", "0.01", "10", /*eye_site=*/true);
using simgate::testing::is_red;
using simgate::testing::k_red_box_face;
using simgate::testing::k_render_deadline;

class CameraTest : public testing::MjcfSim {
 protected:
  void SetUp() override {
    load_string(k_camera_scene);
    robot_ = &add_robot("rig", "rig");
  }

  // Steps (and serves) until `id` has its outcome, at most k_render_deadline of wall time.
  Outcome wait_for(RequestId id) { return step_until_outcome(id, k_render_deadline); }
  json image_of(const std::string& component) {
    Outcome o = wait_for(rm_->call(component, "get_image"));
    EXPECT_EQ(o.status, Status::success) << o.message;
    return o.value.value_or(json());
  }

  // Streams the camera "rig.camera" on the test transport.
  void stream_camera() {
    const ComponentEntry* entry = sim_->find("rig.camera");
    ASSERT_NE(entry, nullptr);
    sim_->streams().add(*entry->component, entry->type, {"test"});
  }
  Camera& camera() { return dynamic_cast<Camera&>(*sim_->find("rig.camera")->component); }
  // Steps (sleeping a little, so that the render thread keeps up) until `sub` has `n`
  // samples, or k_render_deadline; returns those it got.
  std::vector<SamplePtr> samples_of(StreamSubscription& sub, std::size_t n) {
    std::vector<SamplePtr> out;
    const auto deadline = std::chrono::steady_clock::now() + k_render_deadline;
    while (out.size() < n && std::chrono::steady_clock::now() < deadline) {
      sim_->process_requests();
      sim_->step();
      sub.take(out);
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    return out;
  }
  // Steps until every stream render asked for has come back (bounded).
  // Steps until the renders asked so far have come back and a few steps more ask for none:
  // the renderer idle after each of them (it was "no render counted for 100 ms", which a
  // render slower than that under ASan and a loaded machine broke). Bounded.
  void drain_renders() {
    auto renderer = Renderer::shared();
    for (int idle_steps = 0, i = 0; idle_steps < 5 && i < 4000; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
      sim_->step();
      idle_steps = renderer->idle() ? idle_steps + 1 : 0;
    }
  }

  Robot* robot_ = nullptr;
};

// The RGB pixel at (x, y) of a decoded 8-bit RGB image.
std::array<int, 3> rgb_at(const DecodedPng& png, int x, int y) {
  const std::size_t i = (static_cast<std::size_t>(y) * png.width + x) * 3;
  return {png.pixels[i], png.pixels[i + 1], png.pixels[i + 2]};
}
// The 16-bit sample at (x, y) of a decoded grayscale image.
int gray16_at(const DecodedPng& png, int x, int y) {
  const std::size_t i = (static_cast<std::size_t>(y) * png.width + x) * 2;
  return (png.pixels[i] << 8) | png.pixels[i + 1];
}

TEST_F(CameraTest, RedBoxInFrontIsRedInTheMiddle) {
  add_component(*robot_, "camera", "video_camera",
                {{"camera", "front"}, {"cam_width", 320}, {"cam_height", 240}});
  serve();
  const json record = image_of("rig.camera");
  ASSERT_TRUE(record.is_object()) << record.dump();
  EXPECT_EQ(record["width"], 320);
  EXPECT_EQ(record["height"], 240);
  EXPECT_EQ(record["format"], "png");
  const DecodedPng png = decode_png(decode_base64(record["image"].get<std::string>()));
  ASSERT_TRUE(png.error.empty()) << png.error;
  EXPECT_EQ(png.width, 320);
  EXPECT_EQ(png.height, 240);
  EXPECT_EQ(png.bit_depth, 8);
  EXPECT_EQ(png.colour_type, 2);
  EXPECT_TRUE(is_red(rgb_at(png, 160, 120)))
      << rgb_at(png, 160, 120)[0] << " " << rgb_at(png, 160, 120)[1];
  // the box spans atan(0.3 / 1.7) = 10° each side of the axis: the image's corners are not red
  EXPECT_FALSE(is_red(rgb_at(png, 5, 5)));
  EXPECT_FALSE(is_red(rgb_at(png, 314, 234)));
  // the floor fills the bottom rows: grey, not black (the image is not upside down)
  const auto floor = rgb_at(png, 160, 235);
  EXPECT_GT(floor[0], 20);
  EXPECT_NEAR(floor[0], floor[1], 10);
  // the sky (top rows) is not the floor
  EXPECT_FALSE(is_red(rgb_at(png, 160, 3)));
}

TEST_F(CameraTest, IntrinsicsFollowTheFieldOfView) {
  add_component(*robot_, "camera", "video_camera",
                {{"camera", "front"}, {"cam_width", 320}, {"cam_height", 240}});
  serve();
  const json props = value("rig.camera", "get_properties")["properties"];
  // MJCF fovy 60°: fy = 120 / tan(30°)
  const double f = 120 / std::tan(M_PI / 6);
  EXPECT_NEAR(props["focal_length"].get<double>(), f, 1e-9);
  EXPECT_EQ(props["principal_point"], json({160.0, 120.0}));
  EXPECT_NEAR(props["intrinsic_matrix"][0][0].get<double>(), f, 1e-9);
  // the optical frame at the rig, z along the world's +x
  EXPECT_NEAR(props["pose"]["position"][2].get<double>(), 0.5, 1e-9);
  const json q = props["pose"]["orientation"];
  const Eigen::Quaterniond rot(q[0], q[1], q[2], q[3]);
  EXPECT_TRUE((rot * Eigen::Vector3d::UnitZ()).isApprox(Eigen::Vector3d::UnitX(), 1e-9));
  EXPECT_TRUE((rot * Eigen::Vector3d::UnitY()).isApprox(-Eigen::Vector3d::UnitZ(), 1e-9));
}

TEST_F(CameraTest, FrameCameraOnASiteLooksAlongItsX) {
  add_component(*robot_, "eye", "video_camera",
                {{"site", "eye"}, {"cam_width", 64}, {"cam_height", 48}});
  serve();
  const json record = image_of("rig.eye");
  const DecodedPng png = decode_png(decode_base64(record["image"].get<std::string>()));
  ASSERT_TRUE(png.error.empty()) << png.error;
  EXPECT_TRUE(is_red(rgb_at(png, 32, 24)));
}

// issue #36, item 6: a camera with neither `camera` nor `site` sees from its body's origin,
// usually from inside the body: built, with a warning naming it and the body
TEST_F(CameraTest, ACameraWithNoSiteWarnsThatItLooksOutFromInsideItsBody) {
  std::vector<std::string> warnings;
  log::set_sink([&](log::Level level, std::string_view text) {
    if (level == log::Level::warning) warnings.emplace_back(text);
  });
  add_component(*robot_, "inside", "video_camera", {{"cam_width", 16}, {"cam_height", 16}}, "rig");
  add_component(*robot_, "eye", "video_camera",
                {{"site", "eye"}, {"cam_width", 16}, {"cam_height", 16}});
  log::set_sink({});
  ASSERT_EQ(warnings.size(), 1u) << ::testing::PrintToString(warnings);
  EXPECT_THAT(
      warnings[0],
      HasSubstr("camera 'rig.inside': no `site` and no `camera`: it looks out from the origin "
                "of body 'rig'"));
}

TEST_F(CameraTest, DepthOfTheBoxFaceIsItsDistance) {
  add_component(*robot_, "depth", "depth_camera",
                {{"site", "eye"},
                 {"cam_width", 160},
                 {"cam_height", 120},
                 {"cam_near", 0.05},
                 {"cam_far", 20}});
  serve();
  const json record = image_of("rig.depth");
  ASSERT_TRUE(record.is_object()) << record.dump();
  EXPECT_EQ(record["depth_unit"], "mm");
  const DecodedPng png = decode_png(decode_base64(record["image"].get<std::string>()));
  ASSERT_TRUE(png.error.empty()) << png.error;
  EXPECT_EQ(png.bit_depth, 16);
  EXPECT_EQ(png.colour_type, 0);
  EXPECT_NEAR(gray16_at(png, 80, 60), k_red_box_face * 1000, 5);
  // the nearest hit is the floor at the bottom row: 0.5 m below, 22.5° down (fovy 45°) at
  // the image's edge; within the bottom row's pixel (MuJoCo's multisampling resolves a
  // pixel's depth to one of its samples)
  const double edge = 0.5 / std::tan(22.5 * M_PI / 180);
  EXPECT_NEAR(record["min_depth"].get<double>(), edge + 0.008, 0.009);
  EXPECT_NEAR(gray16_at(png, 80, 119), record["min_depth"].get<double>() * 1000, 1);
  // the sky: nothing within cam_far reads 0
  EXPECT_EQ(gray16_at(png, 80, 0), 0);
}

TEST_F(CameraTest, CaptureCompletesWithNImagesAfterEnoughSteps) {
  add_component(*robot_, "camera", "video_camera",
                {{"camera", "front"}, {"cam_width", 32}, {"cam_height", 24}});
  serve();
  const RequestId id = rm_->call("rig.camera", "capture", {3});
  const Outcome o = wait_for(id);
  ASSERT_EQ(o.status, Status::success) << o.message;
  ASSERT_TRUE(o.value && o.value->is_array()) << o.value.value_or(json()).dump();
  ASSERT_EQ(o.value->size(), 3u);
  // one per 1/frequency (20 Hz by default) of simulated time
  const double t0 = (*o.value)[0]["timestamp"], t1 = (*o.value)[1]["timestamp"],
               t2 = (*o.value)[2]["timestamp"];
  EXPECT_NEAR(t1 - t0, 0.05, 0.011);
  EXPECT_NEAR(t2 - t1, 0.05, 0.011);
  for (const json& image : *o.value) {
    const DecodedPng png = decode_png(decode_base64(image["image"].get<std::string>()));
    EXPECT_TRUE(png.error.empty()) << png.error;
    EXPECT_EQ(png.width, 32);
  }
  // get_local_data: the last image
  EXPECT_EQ(wait_for(rm_->call("rig.camera", "get_local_data")).value.value_or(json())["timestamp"],
            (*o.value)[2]["timestamp"]);
}

TEST_F(CameraTest, SecondCapturePreemptsTheFirst) {
  add_component(*robot_, "camera", "video_camera",
                {{"camera", "front"}, {"cam_width", 16}, {"cam_height", 16}});
  serve();
  const RequestId first = rm_->call("rig.camera", "capture", {50});
  sim_->process_requests();
  const RequestId second = rm_->call("rig.camera", "capture", {1});
  const Outcome o = wait_for(second);
  EXPECT_EQ(o.status, Status::success) << o.message;
  EXPECT_EQ(o.value->size(), 1u);
  ASSERT_TRUE(rm_->outcome(first));
  EXPECT_EQ(rm_->outcome(first)->status, Status::preempted);
}

TEST_F(CameraTest, ACancelledCaptureEndsPreemptedAndTheNextOneWorks) {
  add_component(*robot_, "camera", "video_camera",
                {{"camera", "front"}, {"cam_width", 16}, {"cam_height", 16}});
  serve();
  const RequestId first = rm_->call("rig.camera", "capture", {50});
  sim_->process_requests();
  sim_->step();
  rm_->cancel(first);
  const Outcome cancelled = wait_for(first);
  EXPECT_EQ(cancelled.status, Status::preempted) << cancelled.message;
  const Outcome next = wait_for(rm_->call("rig.camera", "capture", {2}));
  ASSERT_EQ(next.status, Status::success) << next.message;
  EXPECT_EQ(next.value->size(), 2u);
}

TEST_F(CameraTest, GetLocalDataRendersTheFirstImage) {
  add_component(*robot_, "camera", "video_camera",
                {{"camera", "front"}, {"cam_width", 16}, {"cam_height", 16}});
  serve();
  const Outcome o = wait_for(rm_->call("rig.camera", "get_local_data"));
  ASSERT_EQ(o.status, Status::success) << o.message;
  const json record = o.value.value_or(json());
  ASSERT_TRUE(record.is_object()) << record.dump();
  EXPECT_EQ(record["width"], 16);
  EXPECT_TRUE(record["image"].is_string());
  EXPECT_EQ(record["intrinsic_matrix"].size(), 3u);
}

// The red middle pixel of an attachment (an "rgb8" image's raw pixels), with its shape checked.
void expect_red_attachment(const Outcome& o, std::size_t i, const json& record) {
  ASSERT_GT(o.attachments.size(), i);
  const StreamPayload& pixels = *o.attachments[i];
  EXPECT_EQ(pixels.content, "image");
  EXPECT_EQ(pixels.description["component"], "rig.camera");
  EXPECT_EQ(pixels.description["encoding"], "rgb8");
  EXPECT_EQ(pixels.description["width"], 64);
  EXPECT_EQ(pixels.description["height"], 48);
  EXPECT_EQ(pixels.description["step"], 64 * 3);
  EXPECT_EQ(pixels.description["timestamp"], record["timestamp"]);
  ASSERT_EQ(pixels.bytes.size(), 64u * 48 * 3);
  const std::size_t middle = (24 * 64 + 32) * 3;
  EXPECT_TRUE(is_red({pixels.bytes[middle], pixels.bytes[middle + 1], pixels.bytes[middle + 2]}));
  // the same image as the record's PNG
  const DecodedPng png = decode_png(decode_base64(record["image"].get<std::string>()));
  ASSERT_TRUE(png.error.empty()) << png.error;
  EXPECT_TRUE(
      std::equal(png.pixels.begin(), png.pixels.end(), pixels.bytes.begin(), pixels.bytes.end()));
}

TEST_F(CameraTest, RepliesCarryTheRawPixelsOfTheirImagesAsAttachments) {
  add_component(*robot_, "camera", "video_camera",
                {{"camera", "front"}, {"cam_width", 64}, {"cam_height", 48}});
  serve();
  // get_local_data's first image (rendered now), get_image's, and a capture's two
  const Outcome first = wait_for(rm_->call("rig.camera", "get_local_data"));
  ASSERT_EQ(first.status, Status::success) << first.message;
  ASSERT_EQ(first.attachments.size(), 1u);
  expect_red_attachment(first, 0, *first.value);
  const Outcome image = wait_for(rm_->call("rig.camera", "get_image"));
  ASSERT_EQ(image.status, Status::success) << image.message;
  ASSERT_EQ(image.attachments.size(), 1u);
  expect_red_attachment(image, 0, *image.value);
  const Outcome capture = wait_for(rm_->call("rig.camera", "capture", {2}));
  ASSERT_EQ(capture.status, Status::success) << capture.message;
  ASSERT_EQ(capture.attachments.size(), 2u);
  expect_red_attachment(capture, 0, (*capture.value)[0]);
  expect_red_attachment(capture, 1, (*capture.value)[1]);
  // get_local_data: the last image, its pixels with it
  const Outcome last = wait_for(rm_->call("rig.camera", "get_local_data"));
  ASSERT_EQ(last.attachments.size(), 1u);
  expect_red_attachment(last, 0, (*capture.value)[1]);
  // a service with no image attaches nothing
  EXPECT_TRUE(call("rig.camera", "get_properties").attachments.empty());
}

TEST_F(CameraTest, GetLocalDatasFirstImageRendersWhilePhysicsKeepsStepping) {
  add_component(*robot_, "camera", "video_camera",
                {{"camera", "front"}, {"cam_width", 16}, {"cam_height", 16}});
  serve();
  auto renderer = Renderer::shared();
  if (!renderer->unavailable().empty()) GTEST_SKIP() << renderer->unavailable();
  // the render thread held by a render of ours until the test lets it go
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  std::promise<void> holding;
  auto scene = std::make_unique<SceneCopy>(renderer->model_copy(sim_->m()));
  scene->update(sim_->m(), sim_->d(), camera().view(), sim_->state_time());
  renderer->render(std::move(scene), true, false, [&holding, released](RenderResult) {
    holding.set_value();
    released.wait();
  });
  holding.get_future().wait();
  // no image yet: the call does not wait for one under the lock (it used to, up to 30 s)
  const RequestId id = rm_->call("rig.camera", "get_local_data");
  sim_->process_requests();
  const bool answered_at_once = rm_->outcome(id).has_value();
  const double before = sim_->sim_time();
  run_for(0.1);
  const double after = sim_->sim_time();
  release.set_value();
  EXPECT_FALSE(answered_at_once);
  EXPECT_GT(after, before);  // physics stepped meanwhile
  // the image comes once the render thread is free
  const Outcome o = wait_for(id);
  ASSERT_EQ(o.status, Status::success) << o.message;
  EXPECT_EQ((*o.value)["width"], 16);
  EXPECT_EQ(o.attachments.size(), 1u);
}

TEST_F(CameraTest, CaptureRefusesABadCount) {
  add_component(*robot_, "camera", "video_camera", {{"camera", "front"}});
  serve();
  const Outcome o = call("rig.camera", "capture", {0});
  EXPECT_EQ(o.status, Status::failed);
  EXPECT_THAT(o.message, HasSubstr("n is the number of images"));
}

TEST_F(CameraTest, BadOptionsAreRefusedNamingTheOption) {
  EXPECT_THAT(config_error(*robot_, "video_camera", {{"cam_width", 0}, {"camera", "front"}}),
              HasSubstr("options.cam_width"));
  EXPECT_THAT(config_error(*robot_, "depth_camera", {{"cam_height", -3}, {"camera", "front"}}),
              HasSubstr("options.cam_height"));
  const std::string unknown = config_error(*robot_, "video_camera", {{"camera", "back"}});
  EXPECT_THAT(unknown, HasSubstr("options.camera"));
  EXPECT_THAT(unknown, HasSubstr("front"));  // the cameras the scene has
  EXPECT_THAT(config_error(*robot_, "video_camera", {{"cam_fovy", 180}, {"camera", "front"}}),
              HasSubstr("options.cam_fovy"));
  EXPECT_THAT(
      config_error(*robot_, "video_camera", {{"cam_near", 2}, {"cam_far", 1}, {"camera", "front"}}),
      HasSubstr("options.cam_far"));
  EXPECT_THAT(config_error(*robot_, "video_camera",
                           {{"cam_fovy", 40}, {"cam_focal", 25}, {"camera", "front"}}),
              HasSubstr("options.cam_focal"));
  EXPECT_THAT(config_error(*robot_, "video_camera", {{"site", "nowhere"}}), HasSubstr("site"));
  EXPECT_THAT(config_error(*robot_, "video_camera", {{"camera", "front"}, {"site", "eye"}}),
              HasSubstr("options.site"));
  // a misspelt option is not ignored
  EXPECT_THAT(config_error(*robot_, "video_camera", {{"camera", "front"}, {"cam_widht", 10}}),
              HasSubstr("cam_widht"));
}

TEST_F(CameraTest, WithoutGlTheServicesFailWithTheReason) {
  setenv("SIMGATE_RENDERER_UNAVAILABLE", "no GL in this test", 1);
  add_component(*robot_, "camera", "video_camera", {{"camera", "front"}});
  serve();
  const Outcome image = wait_for(rm_->call("rig.camera", "get_image"));
  const Outcome capture = call("rig.camera", "capture", {1});
  const Outcome data = wait_for(rm_->call("rig.camera", "get_local_data"));
  unsetenv("SIMGATE_RENDERER_UNAVAILABLE");
  for (const Outcome* o : {&image, &capture, &data}) {
    EXPECT_EQ(o->status, Status::failed);
    EXPECT_THAT(o->message, HasSubstr("rig.camera: cannot render"));
    EXPECT_THAT(o->message, HasSubstr("no GL in this test"));
  }
  // everything else runs
  EXPECT_TRUE(value("rig.camera", "get_properties")["properties"].contains("intrinsic_matrix"));
  const double before = sim_->sim_time();
  run_for(0.1);
  EXPECT_GT(sim_->sim_time(), before);
}

TEST_F(CameraTest, ASpawnedBodyIsSeenAndADeletedOneIsGone) {
  add_component(*robot_, "camera", "video_camera",
                {{"camera", "front"}, {"cam_width", 64}, {"cam_height", 48}});
  serve();
  auto centre = [&] {
    const DecodedPng png =
        decode_png(decode_base64(image_of("rig.camera")["image"].get<std::string>()));
    EXPECT_TRUE(png.error.empty()) << png.error;
    return png.error.empty() ? rgb_at(png, 32, 24) : std::array<int, 3>{};
  };
  ASSERT_TRUE(is_red(centre()));  // the context is made from the first model
  // a green box between the camera and the red one: the model is replaced
  const std::uint64_t generation = sim_->model_generation();
  const Outcome spawned =
      wait_for(rm_->call("simulation", "spawn_entity",
                         {"green",
                          R"(<body><geom type="box" size="0.1 0.1 0.1" rgba="0 1 0 1"/></body>)",
                          {1.0, 0.0, 0.5}}));
  ASSERT_EQ(spawned.status, Status::success) << spawned.message;
  ASSERT_GT(sim_->model_generation(), generation);
  const auto green = centre();
  EXPECT_TRUE(green[1] > 100 && green[1] > 3 * green[0])
      << green[0] << " " << green[1] << " " << green[2];
  // deleted: red again
  const Outcome deleted = wait_for(rm_->call("simulation", "delete_entity", {"green"}));
  ASSERT_EQ(deleted.status, Status::success) << deleted.message;
  EXPECT_TRUE(is_red(centre()));
}

// ---- the image stream ----

TEST_F(CameraTest, TheImageStreamGivesRawPixelsAndPngRecordsOfTheRedBoxAtItsFrequency) {
  add_component(*robot_, "camera", "video_camera",
                {{"camera", "front"}, {"cam_width", 64}, {"cam_height", 48}});
  serve();
  stream_camera();
  if (!Renderer::shared()->unavailable().empty()) GTEST_SKIP() << Renderer::shared()->unavailable();
  const auto info = sim_->streams().find("rig.camera", "test");
  ASSERT_TRUE(info);
  EXPECT_TRUE(info->pushed);
  EXPECT_EQ(info->kind, "image");
  EXPECT_EQ(info->frequency, 20);  // the camera's (its default), not the hub's default
  auto sub = sim_->streams().subscribe("rig.camera", "test", {16, "test", {}});
  const auto samples = samples_of(*sub, 4);
  ASSERT_EQ(samples.size(), 4u);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const StreamSample& s = *samples[i];
    EXPECT_EQ(s.seq(), i + 1);
    // raw pixels, described
    ASSERT_NE(s.payload(), nullptr);
    const StreamPayload& p = *s.payload();
    EXPECT_EQ(p.content, "image");
    EXPECT_EQ(p.description["encoding"], "rgb8");
    EXPECT_EQ(p.description["width"], 64);
    EXPECT_EQ(p.description["height"], 48);
    EXPECT_EQ(p.description["step"], 64 * 3);
    ASSERT_EQ(p.bytes.size(), 64u * 48 * 3);
    const std::size_t middle = (24 * 64 + 32) * 3;
    EXPECT_TRUE(is_red({p.bytes[middle], p.bytes[middle + 1], p.bytes[middle + 2]}));
    // the JSON record (get_local_data's): a PNG of the same pixels
    const json& record = s.data();
    EXPECT_EQ(record["timestamp"], s.time());
    EXPECT_EQ(record["encoding"], "rgb8");
    EXPECT_EQ(record["intrinsic_matrix"], p.description["intrinsic_matrix"]);
    const DecodedPng png = decode_png(decode_base64(record["image"].get<std::string>()));
    ASSERT_TRUE(png.error.empty()) << png.error;
    EXPECT_EQ(png.pixels, p.bytes);
    EXPECT_TRUE(is_red(rgb_at(png, 32, 24)));
  }
  // 20 Hz in simulated time: 0.05 s apart, unless the render thread fell behind (an image
  // skipped, counted): then a multiple of it
  for (std::size_t i = 1; i < samples.size(); ++i) {
    const double gap = samples[i]->time() - samples[i - 1]->time();
    const double periods = std::round(gap / 0.05);
    EXPECT_GE(periods, 1);
    EXPECT_NEAR(gap, periods * 0.05, 1e-9);
    if (camera().stream_skipped() == 0) {
      EXPECT_NEAR(gap, 0.05, 1e-9);
    }
  }
  std::cout << "[ info     ] stream images skipped (render thread behind): "
            << camera().stream_skipped() << "\n";
}

TEST_F(CameraTest, StreamImagesSkippedWhileTheRenderThreadIsBusyAreCountedInTheStatistics) {
  add_component(*robot_, "camera", "video_camera",
                {{"camera", "front"}, {"cam_width", 16}, {"cam_height", 16}});
  serve();
  stream_camera();
  auto renderer = Renderer::shared();
  if (!renderer->unavailable().empty()) GTEST_SKIP() << renderer->unavailable();
  // the render thread held by a render of ours until the test lets it go
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  std::promise<void> holding;
  CameraView view = camera().view();
  auto scene = std::make_unique<SceneCopy>(renderer->model_copy(sim_->m()));
  scene->update(sim_->m(), sim_->d(), view, sim_->state_time());
  renderer->render(std::move(scene), true, false, [&holding, released](RenderResult) {
    holding.set_value();
    released.wait();
  });
  holding.get_future().wait();
  // 20 Hz, 0.01 s steps: an image due every 5 steps; 2 are asked for, the next ones skipped
  auto sub = sim_->streams().subscribe("rig.camera", "test", {16, "test", {}});
  for (int i = 0; i < 40; ++i) sim_->step();
  const std::uint64_t skipped = camera().stream_skipped();
  const auto statistics = sim_->streams().statistics("test");
  release.set_value();
  ASSERT_EQ(statistics.size(), 1u);
  EXPECT_GE(skipped, 5u);  // 8 due, 2 rendering
  EXPECT_EQ(statistics[0].skipped, skipped);
  EXPECT_EQ(statistics[0].dropped, skipped);  // every subscriber lost them
  EXPECT_EQ(sim_->streams().total_dropped(), skipped);
  // simulation get_stream_statistics says so
  const json listed = value("simulation", "get_stream_statistics");
  ASSERT_TRUE(listed.is_array()) << listed.dump();
  ASSERT_EQ(listed.size(), 1u) << listed.dump();
  EXPECT_EQ(listed[0]["skipped"], skipped) << listed.dump();
  EXPECT_EQ(listed[0]["dropped"], skipped) << listed.dump();
  // the two held back come once the render thread is free again
  EXPECT_EQ(samples_of(*sub, 2).size(), 2u);
  sim_->streams().unsubscribe(sub);
}

TEST_F(CameraTest, TheDepthStreamGivesMetresAsFloatsAndTheMillimetrePngOnAsking) {
  add_component(*robot_, "depth", "depth_camera",
                {{"camera", "front"}, {"cam_width", 40}, {"cam_height", 30}});
  serve();
  const ComponentEntry* entry = sim_->find("rig.depth");
  sim_->streams().add(*entry->component, entry->type, {"test"});
  if (!Renderer::shared()->unavailable().empty()) GTEST_SKIP() << Renderer::shared()->unavailable();
  EXPECT_EQ(sim_->streams().find("rig.depth", "test")->kind, "depth_image");
  auto sub = sim_->streams().subscribe("rig.depth", "test", {16, "test", {}});
  const auto samples = samples_of(*sub, 1);
  ASSERT_EQ(samples.size(), 1u);
  const StreamPayload& p = *samples[0]->payload();
  EXPECT_EQ(p.description["encoding"], "32FC1");
  EXPECT_EQ(p.description["step"], 40 * 4);
  ASSERT_EQ(p.bytes.size(), 40u * 30 * 4);
  float middle = 0;
  std::memcpy(&middle, p.bytes.data() + (15 * 40 + 20) * 4, sizeof middle);
  EXPECT_NEAR(middle, k_red_box_face, 0.01);
  const json& record = samples[0]->data();
  EXPECT_EQ(record["encoding"], "mono16");
  const DecodedPng png = decode_png(decode_base64(record["image"].get<std::string>()));
  ASSERT_TRUE(png.error.empty()) << png.error;
  EXPECT_NEAR(gray16_at(png, 20, 15), k_red_box_face * 1000, 10);
}

TEST_F(CameraTest, WithoutASubscriberTheStreamRendersNothing) {
  add_component(*robot_, "camera", "video_camera",
                {{"camera", "front"}, {"cam_width", 32}, {"cam_height", 24}});
  serve();
  stream_camera();
  auto renderer = Renderer::shared();
  if (!renderer->unavailable().empty()) GTEST_SKIP() << renderer->unavailable();
  const std::uint64_t before = renderer->renders();
  run_for(0.5);  // 10 images' worth at 20 Hz
  EXPECT_EQ(renderer->renders(), before);
  // subscribed: it renders; unsubscribed: it stops (once those asked for came back)
  auto sub = sim_->streams().subscribe("rig.camera", "test", {16, "test", {}});
  ASSERT_EQ(samples_of(*sub, 2).size(), 2u);
  EXPECT_GE(renderer->renders(), before + 2);
  sim_->streams().unsubscribe(sub);
  drain_renders();
  const std::uint64_t after = renderer->renders();
  run_for(0.5);
  EXPECT_EQ(renderer->renders(), after);
  EXPECT_EQ(sim_->streams().statistics("test").at(0).subscribers, 0u);
}

TEST_F(CameraTest, WithoutGlTheStreamGivesNothingAndTheSimulationRuns) {
  setenv("SIMGATE_RENDERER_UNAVAILABLE", "no GL in this test", 1);
  add_component(*robot_, "camera", "video_camera", {{"camera", "front"}});
  serve();
  stream_camera();
  auto sub = sim_->streams().subscribe("rig.camera", "test", {16, "test", {}});
  const double before = sim_->sim_time();
  run_for(0.5);
  unsetenv("SIMGATE_RENDERER_UNAVAILABLE");
  EXPECT_GT(sim_->sim_time(), before + 0.4);
  std::vector<SamplePtr> samples;
  sub->take(samples);
  EXPECT_TRUE(samples.empty());
  EXPECT_FALSE(sub->closed());  // the subscription stays: a client sees no sample, no error
  EXPECT_EQ(sim_->streams().statistics("test").at(0).samples, 0u);
}

// A measurement printed for the docs, never asserted: 320x240 render + readPixels.
TEST_F(CameraTest, PrintsTheTimeOfA320x240Render) {
  auto renderer = Renderer::shared();
  if (!renderer->unavailable().empty()) GTEST_SKIP() << renderer->unavailable();
  auto model = renderer->model_copy(sim_->m());
  CameraView view;
  view.width = 320;
  view.height = 240;
  // what a camera does under the simulation lock: copy the scene
  {
    SceneCopy scene(model);
    constexpr int k_copies = 200;
    const auto start = std::chrono::steady_clock::now();
    for (int i = 0; i < k_copies; ++i) scene.update(sim_->m(), sim_->d(), view, 0);
    const double us =
        std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count();
    std::printf("[ measure  ] scene copy under the lock (%d geoms): %.1f us\n",
                scene.scene()->ngeom, us / k_copies);
  }
  constexpr int k_frames = 20;
  std::mutex mutex;
  std::condition_variable cv;
  int done = 0;
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < k_frames; ++i) {
    auto scene = std::make_unique<SceneCopy>(model);
    scene->update(sim_->m(), sim_->d(), view, 0);
    renderer->render(std::move(scene), true, false, [&](RenderResult r) {
      EXPECT_TRUE(r.error.empty()) << r.error;
      std::lock_guard lock(mutex);
      ++done;
      cv.notify_all();
    });
  }
  std::unique_lock lock(mutex);
  ASSERT_TRUE(cv.wait_for(lock, k_render_deadline, [&] { return done == k_frames; }));
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  std::printf(
      "[ measure  ] 320x240 render + readPixels (llvmpipe): %.2f ms per frame over %d frames\n",
      ms / k_frames, k_frames);
}

}  // namespace
}  // namespace simgate::sim
