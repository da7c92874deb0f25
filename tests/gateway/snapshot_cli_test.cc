// GatewaySnapshot: `simgate snapshot` (issue #22) — the executable writes a valid PNG of the
// asked size from a gateway running in the test's process (socket, JSON-RPC, DDS), and offline
// from a config or a model; its errors (bad --size, unknown camera, unwritable path, no
// gateway, no GL, client options with --config) are clear, with their exit codes.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <cstdlib>
#include <filesystem>
#include <utility>

#include "../sim/camera_png.h"
#include "in_process_gateway.h"
#include "test_support.h"

namespace simgate::gateway {
namespace {

using ::testing::HasSubstr;
using namespace testing;
using sim::testing::decode_png;
using sim::testing::DecodedPng;

CliRun simgate(std::vector<std::string> args, const TempDir& dir) {
  return run_cli(std::move(args), dir, 120s);
}

DecodedPng png_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                        std::istreambuf_iterator<char>());
  return decode_png(bytes);
}

// Not one flat colour: the scene is in the picture.
bool has_a_picture(const DecodedPng& png) {
  if (png.pixels.empty()) return false;
  std::size_t differing = 0;
  for (std::size_t i = 3; i < png.pixels.size(); i += 3 * 97)
    if (png.pixels[i] != png.pixels[0] || png.pixels[i + 1] != png.pixels[1]) ++differing;
  return differing > 10;
}

// The demo on ephemeral socket and JSON-RPC ports, `simulation` served by both.
json demo_on_two_transports() {
  json c = demo_config(0.0);
  c["transports"]["jsonrpc"] = {{"plugin", "jsonrpc"},
                                {"options", {{"host", "127.0.0.1"}, {"port", 0}}}};
  c["services"]["simulation"] = json::array({"socket", "jsonrpc"});
  return c;
}

TEST(GatewaySnapshot, WritesThePngOfARunningGatewayThroughSocketAndJsonRpc) {
  const TempDir dir;
  InProcessGateway gateway(demo_on_two_transports());
  const CliRun socket = simgate(
      {"snapshot", "--port", std::to_string(gateway.port("socket")), dir.file("socket.png")}, dir);
  ASSERT_EQ(socket.code, 0) << socket.err;
  EXPECT_THAT(socket.out, HasSubstr("socket.png: 640x480 PNG"));
  EXPECT_THAT(socket.out, HasSubstr("camera free"));
  const DecodedPng a = png_file(dir.file("socket.png"));
  ASSERT_TRUE(a.error.empty()) << a.error;
  EXPECT_EQ(a.width, 640);
  EXPECT_EQ(a.height, 480);
  EXPECT_TRUE(has_a_picture(a));

  const CliRun rpc =
      simgate({"snapshot", "--transport", "jsonrpc", "--port",
               std::to_string(gateway.port("jsonrpc")), "--size", "200x150", dir.file("rpc.png")},
              dir);
  ASSERT_EQ(rpc.code, 0) << rpc.err;
  const DecodedPng b = png_file(dir.file("rpc.png"));
  ASSERT_TRUE(b.error.empty()) << b.error;
  EXPECT_EQ(b.width, 200);
  EXPECT_EQ(b.height, 150);
  EXPECT_TRUE(has_a_picture(b));
}

// (`simgate list --transport jsonrpc` reads rpc.discover)
TEST(GatewaySnapshot, ListedThroughSocketAndJsonRpc) {
  const TempDir dir;
  InProcessGateway gateway(demo_on_two_transports());
  const CliRun list = simgate({"list", "--port", std::to_string(gateway.port("socket"))}, dir);
  ASSERT_EQ(list.code, 0) << list.err;
  EXPECT_THAT(list.out,
              HasSubstr("simulation get_snapshot(camera=\"\", width=640, height=480) async"));
  const CliRun list_rpc = simgate(
      {"list", "--transport", "jsonrpc", "--port", std::to_string(gateway.port("jsonrpc"))}, dir);
  ASSERT_EQ(list_rpc.code, 0) << list_rpc.err;
  EXPECT_THAT(list_rpc.out, HasSubstr("simulation get_snapshot("));
}

#ifdef SIMGATE_TEST_WITH_DDS
TEST(GatewaySnapshot, WritesThePngThroughDds) {
  ::setenv("ASAN_OPTIONS", "detect_leaks=0:abort_on_error=1", 1);  // as cli_test's DDS clients
  const TempDir dir;
  json c = demo_config(0.0);
  const std::string partition = "snapshot-" + std::to_string(::getpid());
  c["transports"]["dds"] = {{"plugin", "dds"},
                            {"options", {{"domain", 0}, {"partition", partition}}}};
  c["services"]["simulation"] = json::array({"socket", "dds"});
  InProcessGateway gateway(c);
  const CliRun r = simgate({"snapshot", "--transport", "dds", "--partition", partition, "--timeout",
                            "60", "--size", "320x240", dir.file("dds.png")},
                           dir);
  ASSERT_EQ(r.code, 0) << r.err;
  const DecodedPng png = png_file(dir.file("dds.png"));
  ASSERT_TRUE(png.error.empty()) << png.error;
  EXPECT_EQ(png.width, 320);
  EXPECT_EQ(png.height, 240);
  EXPECT_TRUE(has_a_picture(png));
}
#endif

TEST(GatewaySnapshot, UnknownCameraOfARunningGatewayIsFailedListingTheCameras) {
  const TempDir dir;
  InProcessGateway gateway(demo_on_two_transports());
  const CliRun r = simgate({"snapshot", "--port", std::to_string(gateway.port("socket")),
                            "--camera", "nope", dir.file("x.png")},
                           dir);
  EXPECT_EQ(r.code, 1);
  EXPECT_THAT(r.err, HasSubstr("FAILED"));
  EXPECT_THAT(r.err, HasSubstr("camera 'nope' is not an MJCF camera of the scene"));
  EXPECT_FALSE(std::filesystem::exists(dir.file("x.png")));
}

TEST(GatewaySnapshot, OfflineFromAConfigAndFromAModel) {
  const TempDir dir;
  const std::string config = dir.write("demo.json", demo_config().dump());
  const CliRun r =
      simgate({"snapshot", "--config", config, "--size", "320x240", dir.file("offline.png")}, dir);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("offline.png: 320x240 PNG"));
  const DecodedPng png = png_file(dir.file("offline.png"));
  ASSERT_TRUE(png.error.empty()) << png.error;
  EXPECT_EQ(png.width, 320);
  EXPECT_EQ(png.height, 240);
  EXPECT_TRUE(has_a_picture(png));

  const CliRun model = simgate({"snapshot", "--model", source_path("config/scenes/arm_table.xml"),
                                "--size", "64x48", dir.file("arm.png")},
                               dir);
  ASSERT_EQ(model.code, 0) << model.err;
  EXPECT_EQ(png_file(dir.file("arm.png")).width, 64);
}

// The RGB pixel at (x, y) of a decoded 8-bit RGB image.
std::array<int, 3> rgb_at(const DecodedPng& png, int x, int y) {
  const std::size_t i = (static_cast<std::size_t>(y) * png.width + x) * 3;
  return {png.pixels[i], png.pixels[i + 1], png.pixels[i + 2]};
}
// The crates (rgba 0.6 0.4 0.1), lit: orange-brown, not the floor's grey-green.
bool is_orange(const std::array<int, 3>& p) {
  return p[0] > 120 && p[0] > p[1] + 30 && p[1] > p[2] + 50;
}
// Not the floor (whose blue is about its red): the rover's orange chassis (0.8 0.35 0.1),
// however washed out by the lamp right above it.
bool is_chassis(const std::array<int, 3>& p) { return p[0] > 120 && p[2] + 40 < p[0]; }

TEST(GatewaySnapshot, TheRoverScenesOverheadCameraSeesTheRoverInTheMiddleOfTheRoom) {
  const TempDir dir;
  // the shipped config as it is: its scene next to it, its MJCF camera "overhead"
  const CliRun r = simgate({"snapshot", "--config", source_path("config/rover.json"), "--camera",
                            "overhead", "--size", "320x240", dir.file("overhead.png")},
                           dir);
  ASSERT_EQ(r.code, 0) << r.err;
  const DecodedPng png = png_file(dir.file("overhead.png"));
  ASSERT_TRUE(png.error.empty()) << png.error;
  ASSERT_EQ(png.width, 320);
  ASSERT_EQ(png.height, 240);
  // straight down on the room's centre, east to the right, north up (f = 120 / tan 25° =
  // 257 px): the rover's chassis in the middle of the image
  const auto middle = rgb_at(png, 160, 120);
  EXPECT_TRUE(is_chassis(middle)) << middle[0] << " " << middle[1] << " " << middle[2];
  // the crates' tops (0.4 m high, 5.6 m below): crate_2 at (-1.6, 1.4) up left, crate_1 at
  // (1.5, -1.3) down right
  for (const auto& [x, y] : {std::pair{86, 56}, std::pair{229, 180}}) {
    const auto crate = rgb_at(png, x, y);
    EXPECT_TRUE(is_orange(crate)) << x << "," << y << ": " << crate[0] << " " << crate[1] << " "
                                  << crate[2];
  }
  // the floor between them and the rover (at (-0.9, 0.7))
  const auto floor = rgb_at(png, 120, 90);
  EXPECT_FALSE(is_orange(floor)) << floor[0] << " " << floor[1] << " " << floor[2];
  EXPECT_FALSE(is_chassis(floor)) << floor[0] << " " << floor[1] << " " << floor[2];
}

TEST(GatewaySnapshot, ErrorsAreClear) {
  const TempDir dir;
  const std::string config = dir.write("demo.json", demo_config().dump());
  for (const std::string size : {"640", "0x480", "640x9000", "axb", "640x480x3", "-5x5"}) {
    const CliRun r =
        simgate({"snapshot", "--config", config, "--size", size, dir.file("s.png")}, dir);
    EXPECT_EQ(r.code, 2) << size;
    EXPECT_THAT(r.err, HasSubstr("--size: expected WIDTHxHEIGHT")) << size;
  }
  const CliRun camera =
      simgate({"snapshot", "--config", config, "--camera", "nope", dir.file("c.png")}, dir);
  EXPECT_EQ(camera.code, 1);
  EXPECT_THAT(camera.err, HasSubstr("camera 'nope' is not an MJCF camera of the scene"));
  EXPECT_FALSE(std::filesystem::exists(dir.file("c.png")));

  const CliRun nodir =
      simgate({"snapshot", "--config", config, dir.file("missing/dir/x.png")}, dir);
  EXPECT_EQ(nodir.code, 1);
  EXPECT_THAT(nodir.err, HasSubstr("cannot write"));

  const CliRun isdir = simgate({"snapshot", "--config", config, dir.file("")}, dir);
  EXPECT_EQ(isdir.code, 2);
  EXPECT_THAT(isdir.err, HasSubstr("is a directory"));

  const CliRun both =
      simgate({"snapshot", "--config", config, "--port", "4000", dir.file("b.png")}, dir);
  EXPECT_EQ(both.code, 2);
  EXPECT_THAT(both.err, HasSubstr("not both"));

  const CliRun no_out = simgate({"snapshot", "--config", config}, dir);
  EXPECT_EQ(no_out.code, 2);
  EXPECT_THAT(no_out.err, HasSubstr("OUT"));

  // no gateway on that port (a port just freed: nothing listens)
  int free_port = 0;
  {
    InProcessGateway gateway(demo_config(0.0));
    free_port = gateway.port("socket");
  }
  const CliRun none = simgate(
      {"snapshot", "--port", std::to_string(free_port), "--timeout", "5", dir.file("n.png")}, dir);
  EXPECT_EQ(none.code, 1);
  EXPECT_FALSE(none.err.empty());
  EXPECT_FALSE(std::filesystem::exists(dir.file("n.png")));
}

TEST(GatewaySnapshot, PresentsTheTokenOfTokenOrSimgateTokenAndFailsClearlyWithoutIt) {
  // the "auth" option (issue #35, item 11): both transports require the token of every client
  const TempDir dir;
  const std::string token = "snapshot-token-0123456789abcdef";
  const ScopedEnv source("SIMGATE_TEST_SNAPSHOT_TOKEN", token);
  const ScopedEnv unset("SIMGATE_TOKEN", std::nullopt);
  json c = demo_on_two_transports();
  require_token(c, "SIMGATE_TEST_SNAPSHOT_TOKEN");
  InProcessGateway gateway(c);
  for (const std::string transport : {"socket", "jsonrpc"}) {
    auto args = [&](const std::string& out, std::vector<std::string> more) {
      std::vector<std::string> a = {
          "snapshot", "--transport", transport, "--port", std::to_string(gateway.port(transport)),
          "--size",   "64x48"};
      a.insert(a.end(), more.begin(), more.end());
      a.push_back(dir.file(out));
      return a;
    };
    const CliRun with_option = simgate(args(transport + "-option.png", {"--token", token}), dir);
    ASSERT_EQ(with_option.code, 0) << transport << ": " << with_option.err;
    EXPECT_EQ(png_file(dir.file(transport + "-option.png")).width, 64) << transport;
    {
      const ScopedEnv env("SIMGATE_TOKEN", token);
      const CliRun with_env = simgate(args(transport + "-env.png", {}), dir);
      ASSERT_EQ(with_env.code, 0) << transport << ": " << with_env.err;
      EXPECT_EQ(png_file(dir.file(transport + "-env.png")).width, 64) << transport;
    }
    const CliRun none = simgate(args(transport + "-none.png", {}), dir);
    EXPECT_EQ(none.code, 1) << transport;
    EXPECT_THAT(none.err, HasSubstr("--token TOKEN or the SIMGATE_TOKEN environment variable"))
        << transport;
    EXPECT_FALSE(std::filesystem::exists(dir.file(transport + "-none.png"))) << transport;
    const CliRun wrong =
        simgate(args(transport + "-wrong.png", {"--token", "a-wrong-token-0123456789"}), dir);
    EXPECT_EQ(wrong.code, 1) << transport;
    EXPECT_THAT(wrong.err, HasSubstr("wrong token")) << transport;
    EXPECT_FALSE(std::filesystem::exists(dir.file(transport + "-wrong.png"))) << transport;
  }
}

TEST(GatewaySnapshot, WithoutGlTheReasonIsGiven) {
  const TempDir dir;
  const std::string config = dir.write("demo.json", demo_config().dump());
  setenv("SIMGATE_RENDERER_UNAVAILABLE", "rendering switched off for this test", 1);
  const CliRun r = simgate({"snapshot", "--config", config, dir.file("g.png")}, dir);
  unsetenv("SIMGATE_RENDERER_UNAVAILABLE");
  EXPECT_EQ(r.code, 1);
  EXPECT_THAT(r.err, HasSubstr("simulation get_snapshot: cannot render"));
  EXPECT_THAT(r.err, HasSubstr("rendering switched off for this test"));
  EXPECT_FALSE(std::filesystem::exists(dir.file("g.png")));
}

}  // namespace
}  // namespace simgate::gateway
