// JSON-RPC data streams, end to end: a gateway with the demo robot whose pose and motion
// stream on the jsonrpc transport; clients list, subscribe, read rpc.sample notifications,
// unsubscribe and publish commands over a real socket.
#include <gtest/gtest.h>

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "../sim/camera_png.h"
#include "../sim/camera_scene.h"
#include "in_process_gateway.h"
#include "simgate/sim/renderer.h"

namespace simgate::gateway::testing {
namespace {

using namespace std::chrono_literals;

json streams_config(bool paused = false) {
  json c = demo_config();
  c["transports"]["jsonrpc"] = {{"plugin", "jsonrpc"}, {"options", {{"port", 0}}}};
  c["services"]["simulation"] = {"socket", "jsonrpc"};
  c["streams"] = {{"robot.pose", {"jsonrpc"}}, {"robot.motion", {"jsonrpc"}}};
  c["robots"][0]["components"][3]["frequency"] = 50;  // robot.pose
  c["scene"]["start_paused"] = paused;
  return c;
}

// A JSON-RPC client that keeps the notifications it reads while it waits for a response.
class StreamClient {
 public:
  explicit StreamClient(int port) : line_(port) {}
  // Sends one call; returns its response (null on timeout), keeping notifications.
  json call(int id, const std::string& method, json params = nullptr) {
    json request{{"jsonrpc", "2.0"}, {"id", id}, {"method", method}};
    if (!params.is_null()) request["params"] = std::move(params);
    line_.send(request.dump() + "\n");
    for (int lines = 0; lines < 10000; ++lines) {
      auto line = line_.read_line();
      if (!line) return nullptr;
      json message = json::parse(*line);
      if (message.contains("id") && message["id"] == id) return message;
      notifications.push_back(std::move(message));
    }
    return nullptr;
  }
  // The next rpc.sample (from those kept, then from the socket); null on timeout.
  json next_sample(std::chrono::milliseconds timeout = 20s) {
    for (int lines = 0; lines < 10000; ++lines) {
      json message;
      if (!notifications.empty()) {
        message = std::move(notifications.front());
        notifications.erase(notifications.begin());
      } else {
        auto line = line_.read_line(timeout);
        if (!line) return nullptr;
        message = json::parse(*line);
      }
      if (message.value("method", "") == "rpc.sample") return message["params"];
    }
    return nullptr;
  }
  LineClient& line() { return line_; }
  std::vector<json> notifications;

 private:
  LineClient line_;
};

TEST(JsonRpcStreamsTest, ListsItsStreamsInRpcStreamsAndDiscover) {
  InProcessGateway g(streams_config());
  StreamClient c(g.port("jsonrpc"));
  json streams = c.call(1, "rpc.streams")["result"];
  ASSERT_EQ(streams.size(), 2u) << streams.dump();
  EXPECT_EQ(streams[0]["component"], "robot.motion");
  EXPECT_EQ(streams[0]["direction"], "IN");
  EXPECT_EQ(streams[0]["fields"], json({"v", "w"}));
  EXPECT_EQ(streams[1]["component"], "robot.pose");
  EXPECT_EQ(streams[1]["direction"], "OUT");
  EXPECT_EQ(streams[1]["kind"], "pose");
  EXPECT_EQ(streams[1]["frequency"], 50);
  json discover = c.call(2, "rpc.discover")["result"];
  EXPECT_EQ(discover["x-simgate-streams"], streams);
}

TEST(JsonRpcStreamsTest, AStreamIsNotCarriedWhereTheListsRefuseItsComponentsServices) {
  // before, a transport denying robot.teleport.* still teleported the robot through the
  // teleport's input stream, and showed robot.pose's samples with get_local_data denied
  // (issue #35, item 8: a denied service is denied on every path to it)
  json config = streams_config();
  config["transports"]["jsonrpc"]["deny"] = {"robot.teleport.*", "robot.pose.get_local_data"};
  config["streams"]["robot.teleport"] = {"socket", "jsonrpc"};
  InProcessGateway g(config);
  StreamClient c(g.port("jsonrpc"));
  json streams = c.call(1, "rpc.streams")["result"];
  ASSERT_EQ(streams.size(), 1u) << streams.dump();
  EXPECT_EQ(streams[0]["component"], "robot.motion");
  json teleported =
      c.call(2, "rpc.publish", {{"component", "robot.teleport"}, {"data", {{"x", 5.0}}}});
  EXPECT_EQ(teleported["error"]["code"], -32602) << teleported.dump();
  EXPECT_EQ(c.call(3, "rpc.subscribe", {{"component", "robot.pose"}})["error"]["code"], -32602);
  const auto& warnings = g.gateway().warnings();
  auto warned = [&](const std::string& text) {
    return std::any_of(warnings.begin(), warnings.end(),
                       [&](const std::string& w) { return w.find(text) != std::string::npos; });
  };
  EXPECT_TRUE(
      warned("transport 'jsonrpc' does not carry the input stream of 'robot.teleport': its "
             "allow/deny lists "
             "refuse robot.teleport."));
  EXPECT_TRUE(warned(
      "transport 'jsonrpc' does not carry the output stream of 'robot.pose': its allow/deny lists "
      "refuse robot.pose.get_local_data"));
  // the socket transport, whose lists refuse nothing, still carries the teleport's
  bool on_socket = false;
  for (const auto& info : g.gateway().simulation().streams().streams("socket"))
    on_socket |= info.component == "robot.teleport";
  EXPECT_TRUE(on_socket);
}

TEST(JsonRpcStreamsTest, SamplesComeAsNotificationsUntilUnsubscribed) {
  InProcessGateway g(streams_config());
  StreamClient c(g.port("jsonrpc"));
  json subscribed = c.call(1, "rpc.subscribe", {{"component", "robot.pose"}});
  ASSERT_TRUE(subscribed.contains("result")) << subscribed.dump();
  const json id = subscribed["result"]["subscription"];
  EXPECT_EQ(subscribed["result"]["stream"]["frequency"], 50);
  // the same stream again on this connection is the same subscription
  EXPECT_EQ(c.call(2, "rpc.subscribe", json::array({"robot.pose"}))["result"]["subscription"], id);
  double last_time = -1;
  std::uint64_t last_seq = 0;
  for (int i = 0; i < 5; ++i) {
    json sample = c.next_sample();
    ASSERT_FALSE(sample.is_null());
    EXPECT_EQ(sample["subscription"], id);
    EXPECT_EQ(sample["component"], "robot.pose");
    EXPECT_GT(sample["time"].get<double>(), last_time);
    EXPECT_GT(sample["seq"].get<std::uint64_t>(), last_seq);
    EXPECT_TRUE(sample["data"].contains("x") && sample["data"].contains("yaw")) << sample.dump();
    EXPECT_EQ(sample["data"]["timestamp"], sample["time"]);
    last_time = sample["time"];
    last_seq = sample["seq"];
  }
  // 50 Hz in simulated time: 0.02 s apart once they flow
  json a = c.next_sample(), b = c.next_sample();
  EXPECT_NEAR(b["time"].get<double>() - a["time"].get<double>(), 0.02, 0.0021);
  EXPECT_EQ(c.call(3, "rpc.unsubscribe", {{"subscription", id}})["result"], true);
  EXPECT_EQ(c.call(4, "rpc.unsubscribe", json::array({id}))["result"], false);
  // nothing after the answer (what came before it was sent before it)
  c.notifications.clear();
  EXPECT_TRUE(c.next_sample(300ms).is_null());
}

TEST(JsonRpcStreamsTest, APausedSimulationGivesANewSubscriberOneSample) {
  InProcessGateway g(streams_config(/*paused=*/true));
  StreamClient c(g.port("jsonrpc"));
  ASSERT_TRUE(c.call(1, "rpc.subscribe", {{"component", "robot.pose"}}).contains("result"));
  json sample = c.next_sample();
  ASSERT_FALSE(sample.is_null());
  EXPECT_EQ(sample["time"], 0);
  EXPECT_TRUE(c.next_sample(300ms).is_null());  // time stands still: no more
}

TEST(JsonRpcStreamsTest, PublishedCommandsDriveTheRobot) {
  InProcessGateway g(streams_config());
  StreamClient c(g.port("jsonrpc"));
  json published =
      c.call(1, "rpc.publish", {{"component", "robot.motion"}, {"data", {{"v", 1.0}, {"w", 0.0}}}});
  ASSERT_TRUE(published.contains("result")) << published.dump();
  EXPECT_TRUE(published["result"].contains("applied"));
  ASSERT_TRUE(c.call(2, "rpc.subscribe", {{"component", "robot.pose"}}).contains("result"));
  const double x0 = c.next_sample()["data"]["x"];
  double x = x0;
  for (int i = 0; i < 200 && x < x0 + 0.05; ++i) x = c.next_sample()["data"]["x"];
  EXPECT_GT(x, x0 + 0.05);
  // a command the component refuses, and one of a stream that is not there. The component
  // says at once when the simulation lock is free; when it is not the command waits for the
  // simulation's turn and is refused then (counted). Paused, the simulation holds the lock
  // only for its turns (a loaded host's stepping loop may hold it nearly always), and the
  // command is published until one is refused at once.
  ASSERT_TRUE(c.call(7, "simulation.pause").contains("result"));
  json refused;
  int attempts = 0;
  do {
    refused = c.call(100 + attempts, "rpc.publish",
                     json::array({"robot.motion", {{"v", 1.0}, {"speed", 2}}}));
    ++attempts;
  } while (!refused.contains("error") && attempts < 50);
  ASSERT_EQ(refused["error"]["code"], -32602) << refused.dump();
  EXPECT_NE(refused["error"]["message"].get<std::string>().find("unknown key 'speed'"),
            std::string::npos)
      << refused.dump();
  json missing = c.call(4, "rpc.publish", {{"component", "robot.pose"}, {"data", {{"x", 1}}}});
  EXPECT_EQ(missing["error"]["code"], -32602);
  EXPECT_EQ(c.call(5, "rpc.publish", {{"component", "robot.motion"}})["error"]["code"], -32602);
  // the counters say what happened
  json stats;
  for (int i = 0; i < 200; ++i) {  // the commands that waited are refused at the next turn
    stats = c.call(6, "simulation.get_stream_statistics")["result"];
    const json m = stream_of(stats, "robot.motion");
    if (m.is_object() && m.value("refused", 0) + m.value("replaced", 0) == attempts) break;
    std::this_thread::sleep_for(10ms);
  }
  ASSERT_EQ(stats.size(), 2u) << stats.dump();
  json pose = stream_of(stats, "robot.pose"), motion = stream_of(stats, "robot.motion");
  EXPECT_GT(pose["samples"].get<int>(), 0);
  EXPECT_EQ(pose["subscribers"], 1);
  EXPECT_EQ(motion["commands"], 1);
  EXPECT_EQ(motion["refused"].get<int>() + motion["replaced"].get<int>(), attempts) << stats.dump();
  EXPECT_NE(motion["last_refusal"].get<std::string>().find("unknown key 'speed'"),
            std::string::npos);
}

// Data that is no object never reaches the component, but is a refused command of the stream
// all the same (a client whose commands all go nowhere shows in the statistics).
TEST(JsonRpcStreamsTest, PublishedDataThatIsNoObjectIsRefusedAndCounted) {
  InProcessGateway g(streams_config());
  StreamClient c(g.port("jsonrpc"));
  json r = c.call(1, "rpc.publish", {{"component", "robot.motion"}, {"data", json::array({1, 0})}});
  EXPECT_EQ(r["error"]["code"], -32602) << r.dump();
  EXPECT_EQ(r["error"]["message"],
            "Invalid params: a command of robot.motion is a JSON object, found array")
      << r.dump();
  r = c.call(2, "rpc.publish", json::array({"robot.motion", "faster"}));
  EXPECT_EQ(r["error"]["code"], -32602) << r.dump();
  // counted at once (nothing waits for the simulation's turn), for the stream's transport only
  const json motion =
      stream_of(c.call(3, "simulation.get_stream_statistics")["result"], "robot.motion");
  EXPECT_EQ(motion["refused"], 2) << motion.dump();
  EXPECT_EQ(motion["commands"], 0) << motion.dump();
  EXPECT_EQ(motion["last_refusal"], "a command of robot.motion is a JSON object, found string")
      << motion.dump();
}

TEST(JsonRpcStreamsTest, SubscribingToWhatIsNotThereSaysWhatIs) {
  InProcessGateway g(streams_config());
  StreamClient c(g.port("jsonrpc"));
  json r = c.call(1, "rpc.subscribe", {{"component", "robot.motion"}});  // an input stream
  EXPECT_EQ(r["error"]["code"], -32602);
  EXPECT_EQ(r["error"]["data"]["streams"], json({"robot.pose"}));
  EXPECT_EQ(c.call(2, "rpc.subscribe", json::object())["error"]["code"], -32602);
  EXPECT_EQ(c.call(3, "rpc.unsubscribe", {{"subscription", "x"}})["error"]["code"], -32602);
  // another transport's clients see none of it
  LineClient socket(g.port("socket"));
  EXPECT_EQ(payload(socket.request("1", "simulation get_stream_statistics")), json::array());
}

TEST(JsonRpcStreamsTest, AClientThatLeavesEndsItsSubscriptions) {
  InProcessGateway g(streams_config());
  {
    StreamClient c(g.port("jsonrpc"));
    ASSERT_TRUE(c.call(1, "rpc.subscribe", {{"component", "robot.pose"}}).contains("result"));
    ASSERT_FALSE(c.next_sample().is_null());
  }
  StreamClient other(g.port("jsonrpc"));
  json stats;
  for (int i = 0; i < 200; ++i) {
    stats = other.call(i, "simulation.get_stream_statistics")["result"];
    if (stream_of(stats, "robot.pose")["subscribers"] == 0) break;
    std::this_thread::sleep_for(10ms);
  }
  EXPECT_EQ(stream_of(stats, "robot.pose")["subscribers"], 0) << stats.dump();
}

// The `simulation` component's body_poses (issue #23): what a browser needs to move the
// bodies it drew from simulation.get_scene_geometry, at 30 Hz of simulated time by default.
TEST(JsonRpcStreamsTest, TheSimulationsBodyPosesMatchItsSceneGeometry) {
  json config = streams_config();
  config["streams"]["simulation"] = {"jsonrpc"};
  InProcessGateway g(config);
  StreamClient c(g.port("jsonrpc"));
  const json streams = c.call(1, "rpc.streams")["result"];
  json listed;
  for (const auto& s : streams)
    if (s["component"] == "simulation") listed = s;
  ASSERT_TRUE(listed.is_object()) << "simulation not in rpc.streams: " << streams.dump();
  EXPECT_EQ(listed["kind"], "body_poses");
  EXPECT_EQ(listed["direction"], "OUT");
  EXPECT_EQ(listed["frequency"], 30);

  const json geometry = c.call(2, "simulation.get_scene_geometry", {{"include_meshes", false}});
  ASSERT_TRUE(geometry.contains("result")) << geometry.dump();
  const json& scene = geometry["result"];
  EXPECT_EQ(scene["meshes"], json::array());
  const std::size_t bodies = scene["bodies"].size();
  ASSERT_GT(bodies, 2u);  // the world, the robot and its wheels, the human...
  EXPECT_EQ(scene["bodies"][0]["name"], "world");
  EXPECT_FALSE(scene["geoms"].empty());

  json subscribed = c.call(3, "rpc.subscribe", {{"component", "simulation"}});
  ASSERT_TRUE(subscribed.contains("result")) << subscribed.dump();
  EXPECT_EQ(subscribed["result"]["stream"]["kind"], "body_poses");
  const json id = subscribed["result"]["subscription"];
  json previous;
  for (int i = 0; i < 4; ++i) {
    json sample = c.next_sample();
    ASSERT_FALSE(sample.is_null());
    EXPECT_EQ(sample["subscription"], id);
    EXPECT_EQ(sample["component"], "simulation");
    const json& data = sample["data"];
    EXPECT_EQ(data["timestamp"], sample["time"]);
    EXPECT_EQ(data["generation"], scene["generation"]);
    ASSERT_EQ(data["poses"].size(), bodies) << data.dump();
    for (const auto& pose : data["poses"]) ASSERT_EQ(pose.size(), 7u) << pose.dump();
    // the world stays at the origin, unrotated: [x, y, z, qw, qx, qy, qz]
    EXPECT_EQ(data["poses"][0], json({0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0}));
    // 30 per simulated second once they flow (on 2 ms steps)
    if (i >= 2) {
      EXPECT_NEAR(sample["time"].get<double>() - previous["time"].get<double>(), 1.0 / 30, 0.0021);
    }
    previous = sample;
  }
  EXPECT_EQ(c.call(4, "rpc.unsubscribe", {{"subscription", id}})["result"], true);
  const json stats = c.call(5, "simulation.get_stream_statistics")["result"];
  const json simulation = stream_of(stats, "simulation");
  ASSERT_TRUE(simulation.is_object()) << stats.dump();
  EXPECT_EQ(simulation["kind"], "body_poses");
  EXPECT_GT(simulation["samples"].get<int>(), 0);
}

TEST(JsonRpcStreamsTest, AStreamsRuleSetsTheSimulationsFrequency) {
  json config = streams_config();
  config["streams"]["simulation"] = {{"transports", {"jsonrpc"}}, {"frequency", 10}};
  InProcessGateway g(config);
  StreamClient c(g.port("jsonrpc"));
  json subscribed = c.call(1, "rpc.subscribe", json::array({"simulation"}));
  ASSERT_TRUE(subscribed.contains("result")) << subscribed.dump();
  EXPECT_EQ(subscribed["result"]["stream"]["frequency"], 10);
  c.next_sample();  // the first, at once
  json a = c.next_sample(), b = c.next_sample();
  ASSERT_FALSE(a.is_null());
  ASSERT_FALSE(b.is_null());
  EXPECT_NEAR(b["time"].get<double>() - a["time"].get<double>(), 0.1, 0.0021);
}

// A camera's image stream (issue #22): a video_camera looking at a red box streams at its
// frequency, in simulated time, each sample the record get_local_data returns (PNG, base64).
class CameraScene {
 public:
  CameraScene() {
    path_ = std::filesystem::temp_directory_path() /
            ("simgate-camera-stream-" + std::to_string(getpid()) + ".xml");
    std::ofstream(path_) << simgate::testing::red_box_scene("camera-stream", "0.005", "10",
                                                            /*eye_site=*/false);
  }
  ~CameraScene() { std::filesystem::remove(path_); }
  json config() const {
    json c = demo_config();
    c["scene"] = {{"mjcf", path_.string()}, {"timestep", 0.005}, {"realtime_factor", 1.0}};
    c["transports"]["jsonrpc"] = {{"plugin", "jsonrpc"}, {"options", {{"port", 0}}}};
    c["services"] = {{"default", {"socket", "jsonrpc"}}};
    c["robots"] = json::array(
        {{{"name", "rig"},
          {"type", "robot"},
          {"body", "rig"},
          {"components",
           json::array(
               {{{"name", "camera"},
                 {"type", "video_camera"},
                 {"frequency", 10},
                 {"options", {{"camera", "front"}, {"cam_width", 64}, {"cam_height", 48}}}}})}}});
    c["streams"] = {{"rig.camera", {"jsonrpc"}}};
    return c;
  }

 private:
  std::filesystem::path path_;
};

TEST(JsonRpcStreamsTest, ACamerasStreamGivesPngRecordsOfWhatItSeesAtItsFrequency) {
  auto renderer = sim::Renderer::shared();
  if (!renderer->unavailable().empty()) GTEST_SKIP() << "no GL: " << renderer->unavailable();
  CameraScene scene;
  InProcessGateway g(scene.config());
  StreamClient c(g.port("jsonrpc"));
  json subscribed = c.call(1, "rpc.subscribe", {{"component", "rig.camera"}});
  ASSERT_TRUE(subscribed.contains("result")) << subscribed.dump();
  EXPECT_EQ(subscribed["result"]["stream"]["kind"], "image");
  EXPECT_EQ(subscribed["result"]["stream"]["frequency"], 10);
  std::vector<json> samples;
  for (int i = 0; i < 3; ++i) {
    json sample = c.next_sample(60s);
    ASSERT_FALSE(sample.is_null());
    samples.push_back(std::move(sample));
  }
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const json& data = samples[i]["data"];
    EXPECT_EQ(samples[i]["component"], "rig.camera");
    EXPECT_EQ(data["timestamp"], samples[i]["time"]);
    EXPECT_EQ(data["width"], 64);
    EXPECT_EQ(data["format"], "png");
    const auto png =
        sim::testing::decode_png(sim::testing::decode_base64(data["image"].get<std::string>()));
    ASSERT_TRUE(png.error.empty()) << png.error;
    const std::size_t middle = (24 * 64 + 32) * 3;
    const int r = png.pixels[middle], green = png.pixels[middle + 1], b = png.pixels[middle + 2];
    EXPECT_TRUE(r > 100 && r > 3 * green && r > 3 * b) << r << " " << green << " " << b;
    if (i == 0) continue;
    // 10 Hz in simulated time: 0.1 s apart (a multiple, if the render thread fell behind)
    const double gap = samples[i]["time"].get<double>() - samples[i - 1]["time"].get<double>();
    EXPECT_GE(std::round(gap / 0.1), 1);
    EXPECT_NEAR(gap, std::round(gap / 0.1) * 0.1, 1e-6);
  }
}

}  // namespace
}  // namespace simgate::gateway::testing
