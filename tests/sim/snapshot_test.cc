// `simulation get_snapshot` (snapshot.h) rendered for real (EGL, Mesa's llvmpipe), checked
// by the pixels of the PNG it returns (camera_png.h): the free view is of the asked size and
// not one flat colour; an MJCF camera looking at a red box sees it red in the middle; bad
// parameters and unknown cameras are FAILED naming what is wrong; without GL it is FAILED
// with the renderer's reason; the service is listed with its parameters.
#include <chrono>
#include <cstdlib>
#include <set>
#include <thread>

#include "camera_png.h"
#include "camera_scene.h"
#include "mjcf_fixture.h"
#include "simgate/sim/snapshot.h"

namespace simgate::sim {
namespace {

using testing::decode_base64;
using testing::decode_png;
using testing::DecodedPng;
using ::testing::HasSubstr;

// A red box 1.7 m in front of MJCF camera "front", on a grey floor.
const std::string k_snapshot_scene =
    simgate::testing::red_box_scene("snapshot-test", "0.01", "3", /*eye_site=*/false);
using simgate::testing::is_red;
using simgate::testing::k_render_deadline;

class SnapshotTest : public testing::MjcfSim {
 protected:
  void SetUp() override {
    load_string(k_snapshot_scene);
    add_robot("rig", "rig");
    serve();
  }

  // Calls get_snapshot and serves (stepping) until it is answered, at most k_render_deadline.
  Outcome snapshot(json params) {
    return step_until_outcome(rm_->call("simulation", "get_snapshot", std::move(params)),
                              k_render_deadline);
  }
  DecodedPng png_of(const Outcome& o) {
    EXPECT_EQ(o.status, Status::success) << o.message;
    const json record = o.value.value_or(json::object());
    if (!record.contains("image")) {
      DecodedPng none;
      none.error = "no image in " + record.dump();
      return none;
    }
    return decode_png(decode_base64(record["image"].get<std::string>()));
  }
};

std::array<int, 3> rgb_at(const DecodedPng& png, int x, int y) {
  const std::size_t i = (static_cast<std::size_t>(y) * png.width + x) * 3;
  return {png.pixels[i], png.pixels[i + 1], png.pixels[i + 2]};
}

TEST_F(SnapshotTest, FreeViewHasTheAskedSizeAndShowsTheScene) {
  const auto started = std::chrono::steady_clock::now();
  const Outcome o = snapshot(json::object());
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - started).count();
  const DecodedPng png = png_of(o);
  ASSERT_TRUE(png.error.empty()) << png.error;
  EXPECT_EQ(png.width, 640);
  EXPECT_EQ(png.height, 480);
  EXPECT_EQ(png.colour_type, 2);
  const json& record = *o.value;
  EXPECT_EQ(record["width"], 640);
  EXPECT_EQ(record["height"], 480);
  EXPECT_EQ(record["format"], "png");
  EXPECT_EQ(record["encoding"], "rgb8");
  EXPECT_EQ(record["camera"], "free");
  EXPECT_TRUE(record.contains("timestamp"));
  EXPECT_TRUE(record["view"].contains("position"));
  // not one flat colour: the floor, the sky and the red box
  std::set<std::array<int, 3>> colours;
  bool red = false;
  for (int y = 0; y < png.height; y += 8)
    for (int x = 0; x < png.width; x += 8) {
      colours.insert(rgb_at(png, x, y));
      red = red || is_red(rgb_at(png, x, y));
    }
  EXPECT_GT(colours.size(), 10u);
  EXPECT_TRUE(red) << "the free view frames the whole scene: the red box is in it";
  std::printf(
      "[ measure ] get_snapshot 640x480 free view, first (renderer start included): %.1f ms, PNG "
      "%zu bytes\n",
      ms, decode_base64(record["image"].get<std::string>()).size());
  // a second one: the renderer is warm
  const auto again = std::chrono::steady_clock::now();
  const Outcome second = snapshot({{"width", 640}, {"height", 480}});
  std::printf(
      "[ measure ] get_snapshot 640x480 free view, warm: %.1f ms\n",
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - again).count());
  EXPECT_EQ(second.status, Status::success) << second.message;
}

TEST_F(SnapshotTest, SnapshotsWhoseRequestsEndedAreNotRenderedAndAtMostEightWait) {
  // issue #35 item 7: a client's batch of large snapshots kept the renderer (and every
  // camera) busy for minutes after it left; now a render whose request ended is skipped,
  // and a ninth snapshot under way is refused
  ASSERT_EQ(snapshot({{"width", 64}, {"height", 64}}).status,
            Status::success);  // the renderer is up
  const std::shared_ptr<Renderer> renderer = Renderer::shared();
  const std::uint64_t rendered = renderer->renders(), abandoned = renderer->abandoned();
  std::vector<RequestId> ids;
  for (std::size_t i = 0; i < Snapshotter::k_max_in_flight + 1; ++i)
    ids.push_back(rm_->call("simulation", "get_snapshot", {{"width", 2048}, {"height", 2048}}));
  sim_->process_requests();
  const auto refused = rm_->outcome(ids.back());
  ASSERT_TRUE(refused.has_value()) << "the ninth was queued too";
  EXPECT_EQ(refused->status, Status::failed);
  EXPECT_THAT(refused->message, HasSubstr("snapshots are being rendered already (the limit)"));
  ids.pop_back();
  // the client leaves: its calls are cancelled (the transports do so for a client gone)
  for (RequestId id : ids) rm_->cancel(id);
  sim_->process_requests();
  for (RequestId id : ids)
    EXPECT_EQ(rm_->outcome(id).value_or(Outcome{}).status, Status::preempted);
  // those left behind no longer count: another client's snapshot is taken at once
  const RequestId next = rm_->call("simulation", "get_snapshot", {{"width", 64}, {"height", 64}});
  sim_->process_requests();
  EXPECT_FALSE(rm_->outcome(next).has_value()) << rm_->outcome(next)->message;
  // the renderer goes through its queue: the first may be rendering already, the rest are skipped
  const auto deadline = std::chrono::steady_clock::now() + k_render_deadline;
  while (renderer->renders() + renderer->abandoned() < rendered + abandoned + ids.size() + 1 &&
         std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_GE(renderer->abandoned() - abandoned, ids.size() - 2);
  EXPECT_LE(renderer->renders() - rendered,
            3u);  // the one rendering when they left, the other client's
  EXPECT_EQ(step_until_outcome(next, k_render_deadline).status, Status::success);
}

TEST_F(SnapshotTest, NamedCameraSeesTheRedBoxAndSizeIsAsAsked) {
  const Outcome o = snapshot({{"camera", "front"}, {"width", 160}, {"height", 100}});
  const DecodedPng png = png_of(o);
  ASSERT_TRUE(png.error.empty()) << png.error;
  EXPECT_EQ(png.width, 160);
  EXPECT_EQ(png.height, 100);
  EXPECT_EQ((*o.value)["camera"], "front");
  EXPECT_TRUE(is_red(rgb_at(png, 80, 50)));
  EXPECT_FALSE(is_red(rgb_at(png, 2, 2)));
  // positional params work too (socket clients write them so)
  const Outcome positional = snapshot({"front", 32, 24});
  EXPECT_EQ(png_of(positional).width, 32);
}

TEST_F(SnapshotTest, BadParametersAreFailedNamingThem) {
  const Outcome unknown = snapshot({{"camera", "back"}});
  EXPECT_EQ(unknown.status, Status::failed);
  EXPECT_THAT(unknown.message, HasSubstr("camera 'back' is not an MJCF camera"));
  EXPECT_THAT(unknown.message, HasSubstr("front"));  // the scene's cameras are listed
  for (const json& params : {json{{"width", 0}}, json{{"width", 8193}}, json{{"height", -1}}}) {
    const Outcome o = snapshot(params);
    EXPECT_EQ(o.status, Status::failed) << params.dump();
    EXPECT_EQ(o.failure, Failure::bad_arguments) << params.dump();
    EXPECT_THAT(o.message, HasSubstr(params.begin().key())) << o.message;
    EXPECT_THAT(o.message, HasSubstr("from 1 to 8192")) << o.message;
  }
  const Outcome huge = snapshot({{"width", 8192}, {"height", 8192}});
  EXPECT_EQ(huge.failure, Failure::bad_arguments);
  EXPECT_THAT(huge.message, HasSubstr("8192 x 8192 is more than 16777216 pixels"));
  for (const json& params : {json{{"width", "wide"}}, json{{"width", 1.5}}, json{{"camera", 3}}}) {
    const Outcome o = snapshot(params);
    EXPECT_EQ(o.status, Status::failed) << params.dump();
    EXPECT_FALSE(o.message.empty());
  }
}

TEST_F(SnapshotTest, IsListedWithItsParameters) {
  const std::string services = value("simulation", "list_services").dump();
  EXPECT_THAT(services, HasSubstr("\"get_snapshot\""));
}

TEST(SnapshotFreeView, LooksAtTheSceneFromTheChosenAngleAndFramesIt) {
  const Model model = Model::load_string(k_snapshot_scene, "test.xml");
  const mjModel* m = model.model();
  const Framing f = frame_scene(m, model.data());
  // the floor plane and the invisible rig are left out: the box is the red cube's (at x = 2 m)
  EXPECT_NEAR((f.low[0] + f.high[0]) / 2, 2, 1e-9);
  EXPECT_NEAR((f.low[2] + f.high[2]) / 2, 0.5, 1e-9);
  EXPECT_NEAR(f.high[0] - f.low[0], 0.6, 1e-9);  // the box's own size: 0.6 m
  EXPECT_NEAR(f.high[2] - f.low[2], 0.6, 1e-9);
  const CameraView v = free_view(m, model.data(), 640, 480);
  double to_centre[3], d2 = 0;
  for (int i = 0; i < 3; ++i) {
    to_centre[i] = (f.low[i] + f.high[i]) / 2 - v.position[i];
    d2 += to_centre[i] * to_centre[i];
  }
  const double distance = std::sqrt(d2);
  // it looks at the centre from outside the box, downwards, upright
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(to_centre[i] / distance, v.forward[i], 1e-9);
  EXPECT_GT(distance, (f.high[0] - f.low[0]) / 2);
  EXPECT_LT(v.forward[2], 0);
  EXPECT_GT(v.up[2], 0);
  EXPECT_NEAR(v.forward[0] * v.up[0] + v.forward[1] * v.up[1] + v.forward[2] * v.up[2], 0, 1e-12);
  EXPECT_GT(v.near_clip, 0);
  EXPECT_LT(v.near_clip, distance / 2);
  EXPECT_GT(v.far_clip, 1.5 * distance);
}

// Without GL (its own fixture: the renderer is started per test, after setenv).
TEST_F(SnapshotTest, WithoutGlItFailsWithTheReason) {
  // the renderer of this test's simulation has not started yet: no snapshot was asked
  setenv("SIMGATE_RENDERER_UNAVAILABLE", "no GL in this test", 1);
  const Outcome o = snapshot(json::object());
  unsetenv("SIMGATE_RENDERER_UNAVAILABLE");
  EXPECT_EQ(o.status, Status::failed);
  EXPECT_THAT(o.message, HasSubstr("simulation get_snapshot: cannot render"));
  EXPECT_THAT(o.message, HasSubstr("no GL in this test"));
  // the simulation goes on
  const double before = sim_->sim_time();
  run_for(0.1);
  EXPECT_GT(sim_->sim_time(), before);
}

}  // namespace
}  // namespace simgate::sim
