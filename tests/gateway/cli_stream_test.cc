// GatewayCliStream: `simgate watch` and `simgate publish` — the executable against a gateway
// running in the test's process on loopback ephemeral ports, robot.pose and robot.motion
// streamed through socket, jsonrpc and websocket: watch prints N parseable pose samples
// through each, ends at --duration, Ctrl-C and a closed stdout with exit 0; publish moves the
// robot; the errors (no such stream, a stream of the wrong direction, JSON that is no
// object, a refused command, dds, no server) have their message and exit code.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <sstream>

#include "in_process_gateway.h"
#include "simgate/client/client.h"
#include "test_support.h"

namespace simgate::gateway {
namespace {

using ::testing::HasSubstr;
using namespace testing;

CliRun simgate(std::vector<std::string> args, const TempDir& dir) {
  return run_cli(std::move(args), dir, 60s);
}

// The demo with a jsonrpc transport too, every transport serving everything and carrying
// the pose and motion streams.
json demo_streaming_everywhere() {
  json c = demo_config();
  c["transports"]["jsonrpc"] = {{"plugin", "jsonrpc"},
                                {"options", {{"host", "127.0.0.1"}, {"port", 0}}}};
  const json all = json::array({"socket", "jsonrpc", "websocket"});
  c["services"] = {{"default", all}};
  c["streams"] = {{"robot.pose", all}, {"robot.motion", all}};
  return c;
}

const std::vector<std::string> k_transports = {"socket", "jsonrpc", "websocket"};

// `watch`/`publish` ARGS through `transport` to `gateway`.
std::vector<std::string> through(const InProcessGateway& gateway, const std::string& transport,
                                 std::vector<std::string> rest) {
  std::vector<std::string> args = {rest.front(), "--transport", transport, "--port",
                                   std::to_string(gateway.port(transport))};
  args.insert(args.end(), rest.begin() + 1, rest.end());
  return args;
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// Every line a pose sample.
void expect_pose_samples(const std::string& out, std::size_t count, const std::string& transport) {
  const auto lines = lines_of(out);
  ASSERT_EQ(lines.size(), count) << transport << ": " << out;
  for (const auto& line : lines) {
    const json sample = json::parse(line, nullptr, false);
    ASSERT_TRUE(sample.is_object()) << transport << ": " << line;
    for (const char* field : {"x", "y", "z", "roll", "pitch", "yaw", "timestamp"})
      EXPECT_TRUE(sample.contains(field) && sample[field].is_number())
          << transport << ": " << field << " in " << line;
  }
}

// robot.pose get_local_data through the socket transport.
json pose_of(const InProcessGateway& gateway) {
  auto client =
      client::make_client("socket", {{"host", "127.0.0.1"}, {"port", gateway.port("socket")}});
  Outcome pose = client->call("robot.pose", "get_local_data", json::array(), 10s);
  return pose.status == Status::success && pose.value ? *pose.value : json();
}

// Waits (bounded) for the robot to be `distance` metres away from `from`; true if it got there.
bool moves_away(const InProcessGateway& gateway, const json& from, double distance,
                std::chrono::milliseconds timeout = 30s) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    const json pose = pose_of(gateway);
    if (pose.is_object() &&
        std::hypot(pose["x"].get<double>() - from["x"].get<double>(),
                   pose["y"].get<double>() - from["y"].get<double>()) > distance)
      return true;
    std::this_thread::sleep_for(50ms);  // the simulation steps meanwhile; bounded by the deadline
  }
  return false;
}

TEST(GatewayCliStream, WatchPrintsParseablePoseSamplesThroughEveryTransport) {
  const TempDir dir;
  InProcessGateway gateway(demo_streaming_everywhere());
  for (const auto& transport : k_transports) {
    const CliRun run =
        simgate(through(gateway, transport, {"watch", "robot.pose", "--count", "3"}), dir);
    EXPECT_EQ(run.code, 0) << transport << ": " << run.err;
    EXPECT_EQ(run.err, "") << transport;
    expect_pose_samples(run.out, 3, transport);
  }
}

TEST(GatewayCliStream, WatchEndsAfterItsDuration) {
  const TempDir dir;
  InProcessGateway gateway(demo_streaming_everywhere());
  for (const auto& transport : k_transports) {
    const CliRun run =
        simgate(through(gateway, transport, {"watch", "robot.pose", "--duration", "0.3"}), dir);
    EXPECT_EQ(run.code, 0) << transport << ": " << run.err;
    // how many samples fit in 0.3 s depends on the host: only that each is one
    for (const auto& line : lines_of(run.out))
      EXPECT_TRUE(json::parse(line, nullptr, false).is_object()) << line;
  }
}

TEST(GatewayCliStream, WatchStopsCleanlyAtCtrlC) {
  const TempDir dir;
  InProcessGateway gateway(demo_streaming_everywhere());
  // socket and jsonrpc wait in slices; a WebSocket read is interrupted by shutting it down
  for (const auto& transport : k_transports) {
    std::vector<std::string> args = through(gateway, transport, {"watch", "robot.pose"});
    args.insert(args.begin(), simgate_binary());
    Process watch(args, dir.file(""));
    const auto deadline = std::chrono::steady_clock::now() + 30s;
    while (watch.out().empty() && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(10ms);  // polling the output file; bounded
    ASSERT_FALSE(watch.out().empty()) << transport << ": " << watch.err();
    watch.signal(SIGINT);
    EXPECT_EQ(watch.wait(30s), 0) << transport << ": " << watch.err();
    EXPECT_EQ(watch.err(), "") << transport;
  }
}

TEST(GatewayCliStream, WatchEndsWhenStdoutCloses) {
  const TempDir dir;
  InProcessGateway gateway(demo_streaming_everywhere());
  // `| head -2`: watch learns at its next line that nobody reads; pipefail gives its code
  for (const auto& transport : k_transports) {
    std::string command = "set -o pipefail; '" + simgate_binary() + "'";
    for (const auto& a : through(gateway, transport, {"watch", "robot.pose"})) command += " " + a;
    const CliRun run = [&] {
      Process p({"/bin/bash", "-c", command + " | head -2"}, dir.file(""));
      const auto code = p.wait(60s);
      return CliRun{code.value_or(-1), p.out(), p.err()};
    }();
    EXPECT_EQ(run.code, 0) << transport << ": " << run.err;
    expect_pose_samples(run.out, 2, transport);
  }
}

TEST(GatewayCliStream, PublishMovesTheRobotThroughEveryTransport) {
  const TempDir dir;
  for (const auto& transport : k_transports) {
    InProcessGateway gateway(demo_streaming_everywhere());
    const json start = pose_of(gateway);
    ASSERT_TRUE(start.is_object()) << transport;
    const CliRun run = simgate(
        through(gateway, transport, {"publish", "robot.motion", R"({"v": 1, "w": 0})"}), dir);
    EXPECT_EQ(run.code, 0) << transport << ": " << run.err;
    EXPECT_THAT(run.out, HasSubstr("robot.motion: 1 command")) << transport;
    EXPECT_TRUE(moves_away(gateway, start, 0.05)) << transport << ": the robot did not move";
  }
}

TEST(GatewayCliStream, PublishSendsCountCommandsAtARate) {
  const TempDir dir;
  InProcessGateway gateway(demo_streaming_everywhere());
  const CliRun rpc = simgate(through(gateway, "jsonrpc",
                                     {"publish", "robot.motion", R"({"v": 0.2, "w": 0.1})",
                                      "--count", "3", "--rate", "50"}),
                             dir);
  EXPECT_EQ(rpc.code, 0) << rpc.err;
  EXPECT_THAT(rpc.out, HasSubstr("robot.motion: 3 commands published"));
  const CliRun socket = simgate(
      through(gateway, "socket",
              {"publish", "robot.motion", R"({"v": 0, "w": 0})", "--count", "2", "--rate", "50"}),
      dir);
  EXPECT_EQ(socket.code, 0) << socket.err;
  EXPECT_THAT(socket.out, HasSubstr("robot.motion: 2 commands written to stream port"));
  // the server counted all five (socket commands are applied on the server's thread)
  auto client =
      client::make_client("socket", {{"host", "127.0.0.1"}, {"port", gateway.port("socket")}});
  const auto deadline = std::chrono::steady_clock::now() + 30s;
  json motion;
  while (std::chrono::steady_clock::now() < deadline) {
    Outcome stats = client->call("simulation", "get_stream_statistics", json::array(), 10s);
    motion = stats.value ? stream_of(*stats.value, "robot.motion") : json();
    if (motion.is_object() && motion.value("commands", 0) >= 5) break;
    std::this_thread::sleep_for(20ms);  // the stream port's reader runs meanwhile; bounded
  }
  EXPECT_EQ(motion.value("commands", 0), 5) << motion.dump();
}

TEST(GatewayCliStream, AComponentWithoutAStreamIsAnErrorNamingTheStreams) {
  const TempDir dir;
  InProcessGateway gateway(demo_streaming_everywhere());
  for (const auto& transport : k_transports) {
    const CliRun run =
        simgate(through(gateway, transport, {"watch", "robot.psoe", "--count", "1"}), dir);
    EXPECT_EQ(run.code, 1) << transport;
    EXPECT_THAT(run.err,
                HasSubstr("watch: robot.psoe has no stream on the " + transport + " transport"))
        << transport;
    EXPECT_THAT(run.err, HasSubstr("did you mean 'robot.pose'?")) << transport;
    EXPECT_THAT(run.err, HasSubstr("robot.pose (OUT pose)")) << transport;
    EXPECT_EQ(run.out, "") << transport;
  }
}

TEST(GatewayCliStream, AStreamOfTheWrongDirectionIsAnError) {
  const TempDir dir;
  InProcessGateway gateway(demo_streaming_everywhere());
  for (const auto& transport : {"socket", "jsonrpc"}) {
    const CliRun watch =
        simgate(through(gateway, transport, {"watch", "robot.motion", "--count", "1"}), dir);
    EXPECT_EQ(watch.code, 1) << transport;
    EXPECT_THAT(watch.err, HasSubstr("watch: robot.motion is an input stream (IN velocity)"))
        << transport;
    EXPECT_THAT(watch.err, HasSubstr("simgate publish robot.motion")) << transport;
    const CliRun publish =
        simgate(through(gateway, transport, {"publish", "robot.pose", R"({"x": 1})"}), dir);
    EXPECT_EQ(publish.code, 1) << transport;
    EXPECT_THAT(publish.err, HasSubstr("publish: robot.pose is an output stream (OUT pose)"))
        << transport;
  }
}

TEST(GatewayCliStream, ACommandThatIsNoJsonObjectIsAUsageError) {
  const TempDir dir;
  // checked before anything connects: no gateway needed
  for (const std::string bad : {"[0.5, 0]", "v=0.5", "{\"v\": 0.5", "0.5"}) {
    const CliRun run = simgate({"publish", "--port", "1", "robot.motion", bad}, dir);
    EXPECT_EQ(run.code, 2) << bad;
    EXPECT_THAT(run.err, HasSubstr("publish: JSON_OBJECT: expected one JSON object")) << bad;
    EXPECT_THAT(run.err, HasSubstr("'" + bad + "'")) << bad;
  }
}

TEST(GatewayCliStream, ARefusedCommandIsAFailedPublishOverJsonRpcAndWebSocket) {
  const TempDir dir;
  InProcessGateway gateway(demo_streaming_everywhere());
  for (const auto& transport : {"jsonrpc", "websocket"}) {
    const CliRun run = simgate(
        through(gateway, transport, {"publish", "robot.motion", R"({"v": 0.5, "speed": 1})"}), dir);
    EXPECT_EQ(run.code, 1) << transport;
    EXPECT_THAT(run.err, HasSubstr("rpc.publish refused")) << transport;
    EXPECT_THAT(run.err, HasSubstr("unknown key 'speed'")) << transport;
  }
  // the socket transport answers nothing on a stream port: sent is success
  const CliRun socket = simgate(
      through(gateway, "socket", {"publish", "robot.motion", R"({"v": 0.5, "speed": 1})"}), dir);
  EXPECT_EQ(socket.code, 0) << socket.err;
}

TEST(GatewayCliStream, DdsAndAnUnreachableServerAreClearErrors) {
  const TempDir dir;
  const CliRun dds = simgate({"watch", "--transport", "dds", "robot.pose"}, dir);
  EXPECT_EQ(dds.code, 2);
  EXPECT_THAT(dds.err, HasSubstr("DDS carries streams as typed topics"));
  EXPECT_THAT(dds.err, HasSubstr("docs/transports/dds.md"));
  // port 1 on loopback: nothing listens (and no root process binds it in a test)
  const CliRun refused = simgate({"watch", "--port", "1", "--timeout", "5", "robot.pose"}, dir);
  EXPECT_EQ(refused.code, 1);
  EXPECT_THAT(refused.err, HasSubstr("cannot connect to 127.0.0.1:1"));
  const CliRun bad_count = simgate({"watch", "--port", "1", "robot.pose", "--count", "0"}, dir);
  EXPECT_EQ(bad_count.code, 2);
  EXPECT_THAT(bad_count.err, HasSubstr("--count"));
}

// ---- a gateway whose transports require a token (the "auth" option, issue #35 item 11)

constexpr const char* k_token = "cli-stream-token-0123456789abcdef";
constexpr const char* k_token_env = "SIMGATE_TEST_CLI_STREAM_TOKEN";  // where the gateway reads it

// The demo streaming everywhere, its three transports requiring k_token of every client.
json demo_requiring_a_token() {
  json c = demo_streaming_everywhere();
  require_token(c, k_token_env);
  return c;
}

// robot.motion's commands counted by the server (the socket transport answers none on its
// stream port: counting them is how to know they got through), through a client that logs in.
int motion_commands(const InProcessGateway& gateway) {
  auto client = client::make_client(
      "socket", {{"host", "127.0.0.1"}, {"port", gateway.port("socket")}, {"token", k_token}});
  Outcome stats = client->call("simulation", "get_stream_statistics", json::array(), 10s);
  const json motion = stats.value ? stream_of(*stats.value, "robot.motion") : json();
  return motion.is_object() ? motion.value("commands", 0) : -1;
}

// Waits (bounded) for the server to have counted `count` commands of robot.motion.
bool counted(const InProcessGateway& gateway, int count) {
  const auto deadline = std::chrono::steady_clock::now() + 30s;
  while (std::chrono::steady_clock::now() < deadline) {
    if (motion_commands(gateway) >= count) return true;
    std::this_thread::sleep_for(20ms);  // the stream port's reader runs meanwhile; bounded
  }
  return false;
}

TEST(GatewayCliStream, WatchAndPublishPresentTheTokenOfTokenOrSimgateToken) {
  const TempDir dir;
  const ScopedEnv source(k_token_env, k_token);
  const ScopedEnv unset("SIMGATE_TOKEN", std::nullopt);
  InProcessGateway gateway(demo_requiring_a_token());
  int published = 0;  // commands sent so far
  for (const auto& transport : k_transports) {
    const CliRun watch = simgate(
        through(gateway, transport, {"watch", "--token", k_token, "robot.pose", "--count", "2"}),
        dir);
    EXPECT_EQ(watch.code, 0) << transport << ": " << watch.err;
    expect_pose_samples(watch.out, 2, transport);
    const CliRun publish =
        simgate(through(gateway, transport,
                        {"publish", "--token", k_token, "robot.motion", R"({"v": 0, "w": 0})"}),
                dir);
    EXPECT_EQ(publish.code, 0) << transport << ": " << publish.err;
    EXPECT_TRUE(counted(gateway, ++published)) << transport << ": the command did not get through";
    {
      const ScopedEnv token("SIMGATE_TOKEN", k_token);
      const CliRun env_watch =
          simgate(through(gateway, transport, {"watch", "robot.pose", "--count", "1"}), dir);
      EXPECT_EQ(env_watch.code, 0) << transport << ": " << env_watch.err;
      expect_pose_samples(env_watch.out, 1, transport);
      const CliRun env_publish = simgate(
          through(gateway, transport, {"publish", "robot.motion", R"({"v": 0, "w": 0})"}), dir);
      EXPECT_EQ(env_publish.code, 0) << transport << ": " << env_publish.err;
      EXPECT_TRUE(counted(gateway, ++published))
          << transport << ": the command did not get through";
    }
    // the option wins over the variable
    const ScopedEnv wrong("SIMGATE_TOKEN", "a-wrong-token-0123456789");
    const CliRun both = simgate(
        through(gateway, transport, {"watch", "--token", k_token, "robot.pose", "--count", "1"}),
        dir);
    EXPECT_EQ(both.code, 0) << transport << ": " << both.err;
  }
}

TEST(GatewayCliStream, WatchAndPublishWithoutTheTokenOrWithAWrongOneFailClearly) {
  const TempDir dir;
  const ScopedEnv source(k_token_env, k_token);
  const ScopedEnv unset("SIMGATE_TOKEN", std::nullopt);
  InProcessGateway gateway(demo_requiring_a_token());
  for (const auto& transport : k_transports) {
    for (const std::string command : {"watch", "publish"}) {
      std::vector<std::string> rest = {command, "robot.motion", R"({"v": 0, "w": 0})"};
      if (command == "watch") rest = {command, "robot.pose", "--count", "1"};
      const CliRun none = simgate(through(gateway, transport, rest), dir);
      EXPECT_EQ(none.code, 1) << transport << " " << command << ": " << none.err;
      EXPECT_THAT(none.err, HasSubstr("--token TOKEN or the SIMGATE_TOKEN environment variable"))
          << transport << " " << command;
      EXPECT_EQ(none.out, "") << transport << " " << command;
      rest.insert(rest.begin() + 1, {"--token", "a-wrong-token-0123456789"});
      const CliRun wrong = simgate(through(gateway, transport, rest), dir);
      EXPECT_EQ(wrong.code, 1) << transport << " " << command << ": " << wrong.err;
      EXPECT_THAT(wrong.err, HasSubstr("wrong token")) << transport << " " << command;
      EXPECT_EQ(wrong.out, "") << transport << " " << command;
    }
  }
  EXPECT_EQ(motion_commands(gateway), 0);  // none got through
}

TEST(GatewayCliStream, HelpDescribesWatchAndPublish) {
  const TempDir dir;
  const CliRun top = simgate({"--help"}, dir);
  EXPECT_THAT(top.out, HasSubstr("simgate watch [CLIENT OPTIONS] COMPONENT"));
  EXPECT_THAT(top.out, HasSubstr("simgate publish [CLIENT OPTIONS] COMPONENT JSON_OBJECT"));
  const CliRun watch = simgate({"help", "watch"}, dir);
  EXPECT_EQ(watch.code, 0);
  EXPECT_THAT(watch.out, HasSubstr("--duration"));
  EXPECT_THAT(watch.out, HasSubstr("--count"));
  EXPECT_THAT(watch.out, HasSubstr("--transport"));
  const CliRun publish = simgate({"publish", "--help"}, dir);
  EXPECT_EQ(publish.code, 0);
  EXPECT_THAT(publish.out, HasSubstr("--rate"));
  EXPECT_THAT(publish.out, HasSubstr("only counted by the server"));
}

}  // namespace
}  // namespace simgate::gateway
