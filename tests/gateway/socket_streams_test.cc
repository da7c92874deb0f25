// MORSE's socket datastreams, end to end (plugins/socket/datastreams.h): a gateway running
// the demo deployment, whose robot.pose and robot.motion stream on the socket transport (on
// ephemeral ports here); clients find the ports through the `simulation` services, read
// JSON lines from the pose port and write commands to the motion port over real sockets.
#include <gtest/gtest.h>

#include <thread>
#include <sys/socket.h>

#include <chrono>

#include "in_process_gateway.h"

namespace simgate::gateway::testing {
namespace {

using namespace std::chrono_literals;

constexpr const char* k_publisher = "morse.middleware.socket_datastream.SocketPublisher";
constexpr const char* k_reader = "morse.middleware.socket_datastream.SocketReader";

// The demo with robot.pose and robot.motion streamed on the socket transport only (the demo
// itself carries robot.motion on its websocket too), pose at 50 Hz.
json streams_config(bool paused = false) {
  json c = demo_config();
  c["streams"]["robot.pose"] = {"socket"};
  c["streams"]["robot.motion"] = {"socket"};
  c["robots"][0]["components"][3]["frequency"] = 50;  // robot.pose
  c["scene"]["start_paused"] = paused;
  return c;
}

// The port `simulation get_stream_port` gives `component`.
int stream_port(LineClient& service, const std::string& component) {
  const std::string answer =
      service.request("p", "simulation get_stream_port [\"" + component + "\"]");
  EXPECT_EQ(answer.rfind("p SUCCESS ", 0), 0u) << answer;
  const json port = payload(answer);
  return port.is_number_integer() ? port.get<int>() : 0;
}

// The next sample of an output stream port, parsed; null on timeout or end of stream.
json next_sample(LineClient& reader) {
  auto line = reader.read_line();
  return line ? json::parse(*line, nullptr, false) : json();
}

// The statistics of `component`'s stream, once they show at least `want` of `key` (bounded
// polling: commands may be applied at the simulation's next turn).
json stream_stats(LineClient& service, const std::string& component, const char* key, int want) {
  json stream;
  for (int i = 0; i < 500; ++i) {
    stream = stream_of(
        payload(service.request("s" + std::to_string(i), "simulation get_stream_statistics")),
        component);
    if (stream.value(key, 0) >= want) break;
    std::this_thread::sleep_for(10ms);
  }
  return stream;
}

// A connection to 127.0.0.1:`port` that never reads, with a small receive buffer so that
// what it leaves unread piles up at the server soon.
class SilentClient {
 public:
  explicit SilentClient(int port) : fd_(connect_loopback(port, 4096)) {}
  ~SilentClient() { ::close(fd_); }
  SilentClient(const SilentClient&) = delete;
  SilentClient& operator=(const SilentClient&) = delete;

 private:
  int fd_ = -1;
};

// A listening socket on 127.0.0.1:`port`, held for the test (a port made busy on purpose).
class Listener {
 public:
  explicit Listener(int port) : fd_(::socket(AF_INET, SOCK_STREAM, 0)) {
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<std::uint16_t>(port));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::bind(fd_, reinterpret_cast<const sockaddr*>(&address), sizeof address) == 0)
      ::listen(fd_, 1);
  }
  ~Listener() { ::close(fd_); }
  Listener(const Listener&) = delete;
  Listener& operator=(const Listener&) = delete;

 private:
  int fd_ = -1;
};

TEST(SocketStreamsTest, TheSimulationServicesSayWhereEachStreamIs) {
  InProcessGateway g(streams_config());
  LineClient service(g.port());
  // the hub's order: the configuration's (motion comes before pose in the demo robot)
  EXPECT_EQ(payload(service.request("1", "simulation list_streams")),
            json({"robot.motion", "robot.pose"}));
  const int pose = stream_port(service, "robot.pose"),
            motion = stream_port(service, "robot.motion");
  EXPECT_GT(pose, 0);
  EXPECT_GT(motion, 0);
  EXPECT_NE(pose, motion);
  EXPECT_EQ(payload(service.request("2", "simulation get_all_stream_ports")),
            json({{"robot.pose", pose}, {"robot.motion", motion}}));
  // MORSE's words for a component without a stream here (pymorse logs them)
  EXPECT_EQ(service.request("3", "simulation get_stream_port [\"robot.waypoint\"]"),
            "3 FAILED \"Stream unavailable for component robot.waypoint\"");
  EXPECT_EQ(service.request("4", "simulation get_stream_port [\"nobody\"]"),
            "4 FAILED \"Stream unavailable for component nobody\"");
  // introspection lists them as services of this transport
  int found = 0;
  for (const auto& s : payload(service.request("5", "simulation list_services")))
    if (s["component"] == "simulation" &&
        (s["name"] == "list_streams" || s["name"] == "get_stream_port" ||
         s["name"] == "get_all_stream_ports")) {
      ++found;
      EXPECT_EQ(s["transports"], json({"socket"})) << s;
    }
  EXPECT_EQ(found, 3);
  // details names the streams by MORSE's datastream classes (what pymorse looks for)
  const json components =
      payload(service.request("6", "simulation details"))["robots"][0]["components"];
  EXPECT_EQ(components["robot.pose"]["stream_interfaces"],
            json::array({json::array({k_publisher, "OUT"})}))
      << components;
  EXPECT_EQ(components["robot.motion"]["stream_interfaces"],
            json::array({json::array({k_reader, "IN"})}))
      << components;
  EXPECT_FALSE(components["robot.waypoint"].contains("stream_interfaces")) << components;
}

// The `simulation` component's body_poses get a port of their own, after the robots'
// (whose ports do not move).
TEST(SocketStreamsTest, TheSimulationsBodyPosesHaveAPortAfterTheRobots) {
  json config = streams_config();
  config["streams"]["simulation"] = {"socket"};
  InProcessGateway g(config);
  LineClient service(g.port());
  EXPECT_EQ(payload(service.request("1", "simulation list_streams")),
            json({"robot.motion", "robot.pose", "simulation"}));
  const int poses = stream_port(service, "simulation");
  EXPECT_GT(poses, 0);
  EXPECT_NE(poses, stream_port(service, "robot.pose"));
  LineClient reader(poses);
  const json sample = next_sample(reader);
  ASSERT_TRUE(sample.is_object()) << sample;
  EXPECT_TRUE(sample.contains("timestamp") && sample.contains("generation")) << sample;
  ASSERT_TRUE(sample["poses"].is_array()) << sample;
  EXPECT_GT(sample["poses"].size(), 2u);
  EXPECT_EQ(sample["poses"][0].size(), 7u);
}

TEST(SocketStreamsTest, AnOutputPortSendsOneJsonSamplePerLineInOrder) {
  InProcessGateway g(streams_config());
  LineClient service(g.port());
  LineClient reader(stream_port(service, "robot.pose"));
  double last = -1;
  for (int i = 0; i < 5; ++i) {
    const json sample = next_sample(reader);
    ASSERT_TRUE(sample.is_object()) << sample;
    for (const char* key : {"x", "y", "z", "roll", "pitch", "yaw", "timestamp"})
      EXPECT_TRUE(sample.contains(key)) << sample;
    EXPECT_GT(sample["timestamp"].get<double>(), last);
    last = sample["timestamp"];
  }
  // what a reader sends is read and ignored: the samples go on
  reader.send("hello\n{\"x\": 1}\n");
  for (int i = 0; i < 3; ++i) {
    const json sample = next_sample(reader);
    ASSERT_TRUE(sample.is_object()) << sample;
    EXPECT_GT(sample["timestamp"].get<double>(), last);
    last = sample["timestamp"];
  }
  const json pose =
      stream_of(payload(service.request("1", "simulation get_stream_statistics")), "robot.pose");
  EXPECT_EQ(pose["subscribers"], 1) << pose;
}

TEST(SocketStreamsTest, APausedSimulationGivesANewReaderOneSample) {
  InProcessGateway g(streams_config(/*paused=*/true));
  LineClient service(g.port());
  LineClient reader(stream_port(service, "robot.pose"));
  const json sample = next_sample(reader);
  ASSERT_TRUE(sample.is_object()) << sample;
  EXPECT_EQ(sample["timestamp"], 0);
}

TEST(SocketStreamsTest, CommandLinesDriveTheRobotAndBadOnesAreCountedWithoutClosingAnything) {
  InProcessGateway g(streams_config());
  LineClient service(g.port());
  LineClient motion(stream_port(service, "robot.motion"));
  LineClient reader(stream_port(service, "robot.pose"));
  const double x0 = next_sample(reader)["x"];
  motion.send("{\"v\": 1, \"w\": 0}\n");
  double x = x0;
  for (int i = 0; i < 500 && x < x0 + 0.05; ++i) {
    const json sample = next_sample(reader);
    ASSERT_TRUE(sample.is_object()) << sample;
    x = sample["x"];
  }
  EXPECT_GT(x, x0 + 0.05);
  auto motion_stats = [&](const char* key, int want) {
    return stream_stats(service, "robot.motion", key, want);
  };
  EXPECT_EQ(motion_stats("commands", 1)["commands"], 1);
  // a line that is not JSON, then a command the component refuses: both counted, in that
  // order (one connection's lines are read in order); the connection stays, and the next
  // command is applied
  motion.send("faster please\n");
  motion.send("{\"v\": 1, \"speed\": 2}\n");
  const json refused = motion_stats("refused", 2);
  EXPECT_EQ(refused["refused"], 2) << refused;
  EXPECT_NE(refused.value("last_refusal", "").find("unknown key 'speed'"), std::string::npos)
      << refused;
  motion.send("{\"v\": 0, \"w\": 0}\n");
  EXPECT_EQ(motion_stats("commands", 2)["commands"], 2);
  // nothing is ever written back on an input stream: the next thing this connection sees is
  // its end, when the gateway stops
}

// MORSE's protocol writes nothing back on a stream port: a malformed line is a refused
// command in the statistics, its reason naming what was wrong.
TEST(SocketStreamsTest, MalformedCommandLinesAreCountedAsRefusedWithWhatWasWrong) {
  json c = streams_config();
  c["transports"]["socket"]["options"]["max_message_bytes"] = 256;
  InProcessGateway g(c);
  LineClient service(g.port());
  LineClient motion(stream_port(service, "robot.motion"));
  motion.send("hello\n");
  json stats = stream_stats(service, "robot.motion", "refused", 1);
  EXPECT_EQ(stats["refused"], 1) << stats;
  EXPECT_EQ(stats["last_refusal"], "not JSON: 'hello'") << stats;
  // each one is counted, though logged once per connection; a long one is quoted in part
  motion.send("[1, 0]\n");
  stats = stream_stats(service, "robot.motion", "refused", 2);
  EXPECT_EQ(stats["refused"], 2) << stats;
  EXPECT_EQ(stats["last_refusal"], "not a JSON object: '[1, 0]'") << stats;
  motion.send(std::string(100, 'x') + "\n");
  stats = stream_stats(service, "robot.motion", "refused", 3);
  EXPECT_EQ(stats["last_refusal"], "not JSON: '" + std::string(80, 'x') + "...'") << stats;
  motion.send(std::string(1000, 'x') + "\n");
  stats = stream_stats(service, "robot.motion", "refused", 4);
  EXPECT_EQ(stats["refused"], 4) << stats;
  EXPECT_EQ(stats["last_refusal"], "a line longer than 256 bytes (max_message_bytes)") << stats;
  // blank lines are nothing; the connection still takes commands
  motion.send("\n  \n{\"v\": 0, \"w\": 0}\n");
  stats = stream_stats(service, "robot.motion", "commands", 1);
  EXPECT_EQ(stats["commands"], 1) << stats;
  EXPECT_EQ(stats["refused"], 4) << stats;
}

// A web page posting to a command port (fetch with mode "no-cors", issue #35): the
// connection closes at its request line; neither the headers nor the body become commands.
TEST(SocketStreamsTest, ABrowsersPostToACommandPortIsClosedAndItsBodyNeverApplied) {
  InProcessGateway g(streams_config());
  LineClient service(g.port());
  const int port = stream_port(service, "robot.motion");
  LineClient page(port);
  page.send(
      "POST / HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: text/plain;charset=UTF-8\r\n"
      "Content-Length: 17\r\n\r\n{\"v\": 1, \"w\": 0}\n");
  EXPECT_FALSE(page.read_line(5s)) << "a stream port wrote to a client";
  // a command of another client afterwards is the only one counted
  LineClient motion(port);
  motion.send("{\"v\": 0, \"w\": 0}\n");
  const json stats = stream_stats(service, "robot.motion", "commands", 1);
  EXPECT_EQ(stats["commands"], 1) << stats;
  EXPECT_EQ(stats.value("refused", 0), 0) << "the headers were read as commands: " << stats;
}

// MORSE skips a port in use for the next one; past 65535 there is none: the last stream
// (robot.pose, after robot.motion on 65534) cannot have 65535 while this test holds it.
TEST(SocketStreamsTest, AStreamWhosePortCouldNotBeBoundSaysWhyAfterMorsesWords) {
  Listener held(65535);  // may fail if another program holds it: then it is in use all the same
  json c = streams_config();
  c["transports"]["socket"]["options"]["stream_port"] = 65534;
  InProcessGateway g(c);
  LineClient service(g.port());
  ASSERT_EQ(stream_port(service, "robot.motion"), 65534)
      << "port 65534 is in use by another program";
  const std::string answer = service.request("1", "simulation get_stream_port [\"robot.pose\"]");
  EXPECT_EQ(answer.rfind("1 FAILED \"Stream unavailable for component robot.pose: cannot listen on "
                         "127.0.0.1:65535: "
                         "bind failed: ",
                         0),
            0u)
      << answer;
  EXPECT_NE(answer.find("Address already in use"), std::string::npos) << answer;
  // the lists leave it out; a component without a stream keeps MORSE's words alone
  EXPECT_EQ(payload(service.request("2", "simulation list_streams")), json({"robot.motion"}));
  EXPECT_EQ(payload(service.request("3", "simulation get_all_stream_ports")),
            json({{"robot.motion", 65534}}));
  EXPECT_EQ(service.request("4", "simulation get_stream_port [\"robot.waypoint\"]"),
            "4 FAILED \"Stream unavailable for component robot.waypoint\"");
}

TEST(SocketStreamsTest, AReaderThatDoesNotReadHoldsUpNobodyAndItsLossesAreCounted) {
  json c = streams_config();
  c["scene"]["realtime_factor"] = 0;                   // as fast as possible: samples pile up fast
  c["robots"][0]["components"][3]["frequency"] = 500;  // one per step
  c["transports"]["socket"]["options"]["stream_queue"] = 4;
  InProcessGateway g(c);
  LineClient service(g.port());
  const int port = stream_port(service, "robot.pose");
  SilentClient silent(port);
  LineClient reader(port);
  // the reader gets every sample in order while the silent one falls behind, until the
  // silent one's losses show in the counters
  double last = -1;
  json pose;
  const auto give_up = std::chrono::steady_clock::now() + 120s;  // a bound, not a measurement
  for (int i = 0; i < 2'000'000 && std::chrono::steady_clock::now() < give_up; ++i) {
    const json sample = next_sample(reader);
    ASSERT_TRUE(sample.is_object()) << "sample " << i << ": " << sample;
    ASSERT_GT(sample["timestamp"].get<double>(), last);
    last = sample["timestamp"];
    if (i % 2000 != 0) continue;
    pose = stream_of(
        payload(service.request("s" + std::to_string(i), "simulation get_stream_statistics")),
        "robot.pose");
    if (pose["dropped"].get<int>() > 0) break;
  }
  EXPECT_GT(pose["dropped"].get<int>(), 0) << pose;
  EXPECT_EQ(pose["subscribers"], 2) << pose;
  // and the reader still gets samples
  for (int i = 0; i < 10; ++i) {
    const json sample = next_sample(reader);
    ASSERT_TRUE(sample.is_object()) << sample;
    EXPECT_GT(sample["timestamp"].get<double>(), last);
    last = sample["timestamp"];
  }
  EXPECT_GT(payload(service.request("t", "time statistics"))["stream_samples_dropped"].get<int>(),
            0);
}

TEST(SocketStreamsTest, ADeletedRobotClosesItsStreamPorts) {
  InProcessGateway g(streams_config());
  LineClient service(g.port());
  const int pose = stream_port(service, "robot.pose");
  LineClient reader(pose);
  ASSERT_TRUE(next_sample(reader).is_object());
  EXPECT_EQ(payload(service.request("1", "simulation delete_entity [\"robot\"]"))["name"], "robot");
  EXPECT_TRUE(reader.closed_by_server());
  EXPECT_EQ(service.request("2", "simulation get_stream_port [\"robot.pose\"]"),
            "2 FAILED \"Stream unavailable for component robot.pose\"");
  EXPECT_EQ(payload(service.request("3", "simulation list_streams")), json::array());
  EXPECT_EQ(payload(service.request("4", "simulation get_all_stream_ports")), json::object());
}

// A robot spawned at run time whose names the "streams" section maps gets stream ports at
// once, numbered after the others; deleted, they close; spawned again, it gets new ones. A
// transport that carried no stream registers the stream services with the first (issue #36).
TEST(SocketStreamsTest, ASpawnedRobotsStreamsGetPortsAtOnce) {
  for (const bool with_streams : {true, false}) {
    json config = streams_config();
    if (!with_streams) config.erase("streams");
    config["streams"]["forklift*"] = {"socket"};
    InProcessGateway g(config);
    LineClient service(g.port());
    const std::string spawn =
        "simulation spawn_entity " +
        json::array({"forklift",
                     "<body><freejoint/><geom type='box' size='.2 .1 .1' mass='2'/></body>",
                     {2.0, 2.0, 0.1},
                     {{"components", json::array({{{"name", "pose"}, {"type", "pose"}}})}}})
            .dump();
    for (int round = 0; round < 2; ++round) {
      const std::string r = std::to_string(round);
      ASSERT_EQ(payload(service.request("s" + r, spawn))["name"], "forklift") << with_streams;
      // the port opens on the transport's I/O thread, right after the spawn's answer
      int port = 0;
      for (int i = 0; i < 100 && port <= 0; ++i) {
        const std::string answer =
            service.request("p" + r, "simulation get_stream_port [\"forklift.pose\"]");
        if (answer.find("SUCCESS") != std::string::npos)
          port = payload(answer).get<int>();
        else
          std::this_thread::sleep_for(std::chrono::milliseconds(10));
      }
      ASSERT_GT(port, 0) << with_streams;
      LineClient reader(port);
      const json sample = next_sample(reader);
      ASSERT_TRUE(sample.is_object()) << sample;
      EXPECT_NEAR(sample["x"].get<double>(), 2.0, 0.05) << sample;
      EXPECT_EQ(payload(service.request("l" + r, "simulation list_streams")).back(),
                "forklift.pose");
      ASSERT_EQ(
          payload(service.request("d" + r, "simulation delete_entity [\"forklift\"]"))["name"],
          "forklift");
      EXPECT_TRUE(reader.closed_by_server());
      EXPECT_EQ(service.request("g" + r, "simulation get_stream_port [\"forklift.pose\"]"),
                "g" + r + " FAILED \"Stream unavailable for component forklift.pose\"");
    }
  }
}

TEST(SocketStreamsTest, WithoutStreamsTheStreamServicesDoNotExist) {
  json c = streams_config();
  c.erase("streams");
  InProcessGateway g(c);
  LineClient service(g.port());
  const std::string answer = service.request("1", "simulation get_stream_port [\"robot.pose\"]");
  EXPECT_NE(answer.find("1 FAILED \"The request get_stream_port has not been registered"),
            std::string::npos)
      << answer;
  for (const auto& s : payload(service.request("2", "simulation list_services")))
    EXPECT_EQ(s["name"].get<std::string>().find("stream_port"), std::string::npos) << s;
  const json components =
      payload(service.request("3", "simulation details"))["robots"][0]["components"];
  EXPECT_FALSE(components["robot.pose"].contains("stream_interfaces")) << components;
}

}  // namespace
}  // namespace simgate::gateway::testing
