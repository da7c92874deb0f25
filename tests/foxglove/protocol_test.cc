// Foxglove's WebSocket protocol without a socket (simgate/foxglove/protocol.h): the bytes of
// the server's binary messages as the spec lays them out, the client's messages read with a
// reason for each refusal, the handshake's subprotocol, and the schemas.
#include "simgate/foxglove/protocol.h"

#include <gtest/gtest.h>

namespace simgate::foxglove {
namespace {

std::string bytes(std::initializer_list<int> values) {
  std::string out;
  for (int v : values) out.push_back(static_cast<char>(v));
  return out;
}

TEST(FoxgloveProtocol, TheSubprotocolIsPickedFromTheOfferedList) {
  EXPECT_EQ(pick_subprotocol("foxglove.websocket.v1"), "foxglove.websocket.v1");
  EXPECT_EQ(pick_subprotocol("foxglove.sdk.v1"), "foxglove.sdk.v1");
  EXPECT_EQ(pick_subprotocol("chat, foxglove.sdk.v1 ,foxglove.websocket.v1"),
            "foxglove.websocket.v1");
  EXPECT_EQ(pick_subprotocol(" foxglove.sdk.v1"), "foxglove.sdk.v1");
  EXPECT_EQ(pick_subprotocol("foxglove.websocket.v2, chat"), "");
  EXPECT_EQ(pick_subprotocol(""), "");
}

TEST(FoxgloveProtocol, BinaryMessagesAreLaidOutAsTheSpecSays) {
  std::string out;
  append_message_data_head(out, 0x01020304, 0x1122334455667788ull);
  EXPECT_EQ(out,
            bytes({0x01, 0x04, 0x03, 0x02, 0x01, 0x88, 0x77, 0x66, 0x55, 0x44, 0x33, 0x22, 0x11}));
  EXPECT_EQ(out.size(), k_message_data_head_bytes);
  EXPECT_EQ(time_message(1'500'000'000), bytes({0x02, 0x00, 0x2f, 0x68, 0x59, 0, 0, 0, 0}));
  out.clear();
  append_service_call_response(out, 7, 9, "json", "[1]");
  EXPECT_EQ(out, bytes({0x03, 7, 0, 0, 0, 9, 0, 0, 0, 4, 0, 0, 0}) + "json[1]");
}

TEST(FoxgloveProtocol, SimulatedSecondsBecomeNanoseconds) {
  EXPECT_EQ(to_nanoseconds(1.5), 1'500'000'000u);

  EXPECT_EQ(to_nanoseconds(0), 0u);
  EXPECT_EQ(to_nanoseconds(-3), 0u);
  EXPECT_EQ(to_nanoseconds(std::nan("")), 0u);
  EXPECT_EQ(to_nanoseconds(1e30), ~std::uint64_t{0});
}

TEST(FoxgloveProtocol, TextMessagesAreReadOrRefusedWithTheReason) {
  auto s = read_text(R"({"op": "subscribe", "subscriptions": [{"id": 0, "channelId": 3},
                                                              {"id": 1, "channelId": 5}]})");
  ASSERT_TRUE(std::holds_alternative<Subscribe>(s));
  EXPECT_EQ(std::get<Subscribe>(s).subscriptions,
            (std::vector<std::pair<std::uint32_t, std::uint32_t>>{{0, 3}, {1, 5}}));
  auto u = read_text(R"({"op": "unsubscribe", "subscriptionIds": [0, 1]})");
  ASSERT_TRUE(std::holds_alternative<Unsubscribe>(u));
  EXPECT_EQ(std::get<Unsubscribe>(u).subscription_ids, (std::vector<std::uint32_t>{0, 1}));
  auto other = read_text(R"({"op": "fetchAsset", "uri": "package://a", "requestId": 1})");
  ASSERT_TRUE(std::holds_alternative<OtherOp>(other));
  EXPECT_EQ(std::get<OtherOp>(other).op, "fetchAsset");
  auto advertised = read_text(
      R"({"op": "advertise", "channels": [{"id": 2, "topic": "/robot/motion", "encoding": "json",
                                            "schemaName": "geometry_msgs/Twist"}]})");
  ASSERT_TRUE(std::holds_alternative<ClientAdvertise>(advertised));
  EXPECT_EQ(std::get<ClientAdvertise>(advertised).channels[0].topic, "/robot/motion");
  auto get = read_text(R"({"op": "getParameters", "parameterNames": ["/a/b"], "id": "r1"})");
  ASSERT_TRUE(std::holds_alternative<GetParameters>(get));
  EXPECT_EQ(std::get<GetParameters>(get).names, std::vector<std::string>{"/a/b"});
  EXPECT_EQ(std::get<GetParameters>(get).id, "r1");
  auto set = read_text(R"({"op": "setParameters", "parameters": [{"name": "/a/b", "value": 2}]})");
  ASSERT_TRUE(std::holds_alternative<SetParameters>(set));
  EXPECT_EQ(std::get<SetParameters>(set).parameters[0].second, 2);
  EXPECT_EQ(std::get<SetParameters>(set).id, "");
  EXPECT_TRUE(std::holds_alternative<SubscribeParameterUpdates>(
      read_text(R"({"op": "subscribeParameterUpdates", "parameterNames": []})")));

  const auto reason = [](std::string_view text) {
    auto r = read_text(text);
    return std::holds_alternative<Malformed>(r) ? std::get<Malformed>(r).reason : "(read)";
  };
  EXPECT_NE(reason("{\"op\": ").find("not JSON"), std::string::npos);
  EXPECT_NE(reason("[1]").find("JSON object"), std::string::npos);
  EXPECT_NE(reason(std::string(R"({"op": "unsubscribe", "subscriptionIds": []})") + '\0' + "x")
                .find("NUL byte"),
            std::string::npos);
  EXPECT_NE(reason("{\"subscriptions\": []}").find("\"op\""), std::string::npos);
  EXPECT_NE(reason(R"({"op": "subscribe"})").find("subscriptions"), std::string::npos);
  EXPECT_NE(reason(R"({"op": "subscribe", "subscriptions": [{"id": 1}]})").find("channelId"),
            std::string::npos);
  EXPECT_NE(reason(R"({"op": "subscribe", "subscriptions": [{"id": -1, "channelId": 1}]})")
                .find("unsigned 32-bit"),
            std::string::npos);
  EXPECT_NE(reason(R"({"op": "subscribe", "subscriptions": [{"id": 4294967296, "channelId": 1}]})")
                .find("unsigned 32-bit"),
            std::string::npos);
  EXPECT_NE(reason(R"({"op": "unsubscribe", "subscriptionIds": ["a"]})").find("unsigned 32-bit"),
            std::string::npos);
  EXPECT_NE(reason(R"({"op": "getParameters", "parameterNames": [1]})").find("not a string"),
            std::string::npos);
  EXPECT_NE(reason(R"({"op": "setParameters", "parameters": [{"value": 1}]})").find("name"),
            std::string::npos);
  EXPECT_NE(reason(R"({"op": "getParameters", "id": 7})").find("\"id\" is a string"),
            std::string::npos);
  EXPECT_NE(reason(R"({"op": "advertise", "channels": [{"id": 1, "topic": 5}]})").find("topic"),
            std::string::npos);
  // control characters of a client's text are not echoed into the status as they are
  EXPECT_EQ(reason("\x1b[2J").find('\x1b'), std::string::npos);
}

TEST(FoxgloveProtocol, BinaryMessagesAreReadOrRefusedWithTheReason) {
  const std::string call = bytes({0x02, 7, 0, 0, 0, 9, 0, 0, 0, 4, 0, 0, 0}) + "json{\"a\":1}";
  auto r = read_binary(call);
  ASSERT_TRUE(std::holds_alternative<ServiceCallRequest>(r));
  const auto& request = std::get<ServiceCallRequest>(r);
  EXPECT_EQ(request.service_id, 7u);
  EXPECT_EQ(request.call_id, 9u);
  EXPECT_EQ(request.encoding, "json");
  EXPECT_EQ(request.payload, "{\"a\":1}");
  // (what is read are views into the message: it outlives them)
  const std::string published = bytes({0x01, 3, 0, 0, 0}) + "xyz";
  auto data = read_binary(published);
  ASSERT_TRUE(std::holds_alternative<ClientMessageData>(data));
  EXPECT_EQ(std::get<ClientMessageData>(data).channel_id, 3u);
  EXPECT_EQ(std::get<ClientMessageData>(data).payload, "xyz");

  const auto reason = [](const std::string& message) {
    auto m = read_binary(message);
    return std::holds_alternative<Malformed>(m) ? std::get<Malformed>(m).reason : "(read)";
  };
  EXPECT_NE(reason("").find("empty"), std::string::npos);
  EXPECT_NE(reason(bytes({0x02, 1, 0})).find("3 bytes"), std::string::npos);
  EXPECT_NE(reason(bytes({0x02, 1, 0, 0, 0, 1, 0, 0, 0, 0xff, 0xff, 0xff, 0xff})).find("runs past"),
            std::string::npos);
  EXPECT_NE(reason(bytes({0x01, 1})).find("2 bytes"), std::string::npos);
  EXPECT_NE(reason(bytes({0x09})).find("opcode 9"), std::string::npos);
}

TEST(FoxgloveProtocol, PlaybackMessagesAreLaidOutAsTheSdkLaysThemOut) {
  // a request: pause (1), speed 2.0f (0x40000000), a seek to 1.5 s, request id "r1"
  const std::string request =
      bytes({0x03, 1, 0, 0, 0, 0x40, 1, 0x00, 0x2f, 0x68, 0x59, 0, 0, 0, 0, 2, 0, 0, 0}) + "r1";
  auto r = read_binary(request);
  ASSERT_TRUE(std::holds_alternative<PlaybackControlRequest>(r));
  const auto& playback = std::get<PlaybackControlRequest>(r);
  EXPECT_FALSE(playback.play);
  EXPECT_EQ(playback.speed, 2.0f);
  ASSERT_TRUE(playback.seek_ns.has_value());
  EXPECT_EQ(*playback.seek_ns, 1'500'000'000u);
  EXPECT_EQ(playback.request_id, "r1");
  // no seek: the seek time's bytes are there, and ignored
  std::string no_seek = request;
  no_seek[6] = 0;
  EXPECT_FALSE(std::get<PlaybackControlRequest>(read_binary(no_seek)).seek_ns.has_value());
  const auto reason = [](const std::string& message) {
    auto m = read_binary(message);
    return std::holds_alternative<Malformed>(m) ? std::get<Malformed>(m).reason : "(read)";
  };
  EXPECT_NE(reason(request.substr(0, 10)).find("10 bytes"), std::string::npos);
  std::string bad_command = request;
  bad_command[1] = 7;
  EXPECT_NE(reason(bad_command).find("command 7"), std::string::npos);
  EXPECT_NE(reason(request.substr(0, 20)).find("runs past"), std::string::npos);
  // the state: paused, at 1.5 s, speed 1.0f, after a seek, answering "r1"
  EXPECT_EQ(
      playback_state(PlaybackStatus::paused, 1'500'000'000, 1.0f, true, "r1"),
      bytes({0x05, 1, 0x00, 0x2f, 0x68, 0x59, 0, 0, 0, 0, 0, 0, 0x80, 0x3f, 1, 2, 0, 0, 0}) + "r1");
  // serverInfo carries the range the playback bar shows
  const json info =
      json::parse(server_info("s", {"playbackControl"}, {}, json::object(), "1",
                              std::pair{std::uint64_t{5}, std::uint64_t{3'000'000'009}}));
  EXPECT_EQ(info["dataStartTime"], (json{{"sec", 0}, {"nsec", 5}}));
  EXPECT_EQ(info["dataEndTime"], (json{{"sec", 3}, {"nsec", 9}}));
  EXPECT_FALSE(
      json::parse(server_info("s", {}, {}, json::object(), "1")).contains("dataStartTime"));
}

TEST(FoxgloveProtocol, ServerTextMessagesCarryTheSpecsFields) {
  const json info =
      json::parse(server_info("simgate", {"services", "time"}, {"json"}, json{{"k", "v"}}, "123"));
  EXPECT_EQ(info["op"], "serverInfo");
  EXPECT_EQ(info["capabilities"], (json{"services", "time"}));
  EXPECT_EQ(info["supportedEncodings"], json{"json"});
  EXPECT_EQ(info["sessionId"], "123");
  Channel c;
  c.id = 4;
  c.topic = "/robot/pose";
  c.schema_name = "simgate.pose";
  c.schema = "{}";
  const json ad = json::parse(advertise({c}));
  EXPECT_EQ(ad["channels"][0], (json{{"id", 4},
                                     {"topic", "/robot/pose"},
                                     {"encoding", "json"},
                                     {"schemaName", "simgate.pose"},
                                     {"schema", "{}"},
                                     {"schemaEncoding", "jsonschema"}}));
  EXPECT_EQ(json::parse(unadvertise({4}))["channelIds"], json{4});
  ServiceDef s;
  s.id = 2;
  s.name = "/time/set_time_scale";
  s.type = "simgate/time.set_time_scale";
  s.request_schema = json{{"type", "object"}};
  s.response_schema = json::object();
  const json services = json::parse(advertise_services({s}));
  EXPECT_EQ(services["services"][0]["request"]["encoding"], "json");
  EXPECT_EQ(services["services"][0]["request"]["schemaEncoding"], "jsonschema");
  EXPECT_EQ(json::parse(services["services"][0]["request"]["schema"].get<std::string>()),
            s.request_schema);
  EXPECT_EQ(services["services"][0]["requestSchema"], services["services"][0]["request"]["schema"]);
  EXPECT_EQ(json::parse(parameter_values({{"/a/b", 2}}, "r1")),
            (json{{"op", "parameterValues"},
                  {"parameters", {{{"name", "/a/b"}, {"value", 2}}}},
                  {"id", "r1"}}));
  EXPECT_FALSE(json::parse(parameter_values({}, "")).contains("id"));
  EXPECT_EQ(json::parse(status(Level::warning, "careful")),
            (json{{"op", "status"}, {"level", 1}, {"message", "careful"}}));
  EXPECT_EQ(json::parse(service_call_failure(2, 5, "FAILED: no")),
            (json{{"op", "serviceCallFailure"},
                  {"serviceId", 2},
                  {"callId", 5},
                  {"message", "FAILED: no"}}));
}

TEST(FoxgloveProtocol, SchemasDescribeSamplesAndServiceParameters) {
  EXPECT_EQ(schema_of(json{{"x", 1.5},
                           {"n", 2},
                           {"ok", true},
                           {"name", "a"},
                           {"list", {1.0, 2.0}},
                           {"none", nullptr}}),
            (json{{"type", "object"},
                  {"properties",
                   {{"x", {{"type", "number"}}},
                    {"n", {{"type", "integer"}}},
                    {"ok", {{"type", "boolean"}}},
                    {"name", {{"type", "string"}}},
                    {"list", {{"type", "array"}, {"items", {{"type", "number"}}}}},
                    {"none", json::object()}}}}));
  ServiceDescriptor d;
  d.component = "robot.waypoint";
  d.name = "goto";
  d.doc = "Go there";
  d.params = {{"x", json{{"type", "number"}}, "number", std::nullopt},
              {"tolerance", json{{"type", "number"}}, "number", json(0.5)}};
  EXPECT_EQ(
      d.params_schema(),
      (json{{"type", "object"},
            {"properties",
             {{"x", {{"type", "number"}}}, {"tolerance", {{"type", "number"}, {"default", 0.5}}}}},
            {"required", {"x"}},
            {"description", "Go there"}}));
  EXPECT_EQ(topic_of("robot.pose"), "/robot/pose");
  EXPECT_EQ(component_of("/robot/motion"), "robot.motion");
  // a command: the object; a Twist for a velocity stream
  EXPECT_EQ(read_command(R"({"v": 1, "w": 0})", {"v", "w"}), (json{{"v", 1}, {"w", 0}}));
  EXPECT_EQ(read_command(R"({"linear": {"x": 0.5}, "angular": {"z": -0.2}})", {"v", "w"}),
            (json{{"v", 0.5}, {"w", -0.2}}));
  EXPECT_EQ(read_command(R"({"linear": {"x": 0.5}, "angular": {"z": 1}})", {"x", "y"}),
            (json{{"linear", {{"x", 0.5}}}, {"angular", {{"z", 1}}}}));
  EXPECT_FALSE(read_command("[1]", {"v", "w"}).has_value());
  EXPECT_EQ(service_name_of("robot.motion", "set_speed"), "/robot/motion/set_speed");
}

}  // namespace
}  // namespace simgate::foxglove
