// simgate/foxglove/protocol.h — Foxglove's WebSocket protocol, the wire without a socket: the
// messages a server sends (JSON text, and binary frames whose integers are little-endian),
// the client's messages read with a reason for each refusal, and the JSON Schemas simgate's
// channels and services are described with. The contract is foxglove/ws-protocol's
// docs/spec.md (subprotocol `foxglove.websocket.v1`; the Foxglove SDK's `foxglove.sdk.v1`
// speaks the same messages to a live server); the foxglove transport (plugins/foxglove) is
// built on it and tests/fuzz/foxglove_messages.cc fuzzes the readers. Wire examples:
// docs/transports/foxglove.md.
//
// Threads: pure functions, any thread.
#ifndef SIMGATE_FOXGLOVE_PROTOCOL_H_
#define SIMGATE_FOXGLOVE_PROTOCOL_H_

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include "simgate/core/service.h"

namespace simgate::foxglove {

// A message's JSON text: compact, invalid UTF-8 (in a name, a client's text) replaced rather
// than thrown.
std::string dump(const json& value);

// ---- the handshake

// The subprotocols a server speaks, in the order it prefers them.
inline constexpr std::string_view k_subprotocol = "foxglove.websocket.v1";
inline constexpr std::string_view k_sdk_subprotocol = "foxglove.sdk.v1";
// The subprotocol to answer an upgrade with, from its Sec-WebSocket-Protocol header (a
// comma-separated list): one of the two above, or "" when it offers neither.
std::string pick_subprotocol(std::string_view offered);

// ---- server messages

// Binary opcodes of the server's messages, and of the client's.
inline constexpr std::uint8_t k_message_data = 0x01;              // server: a sample
inline constexpr std::uint8_t k_time = 0x02;                      // server: the server's time
inline constexpr std::uint8_t k_service_call_response = 0x03;     // server: a service's answer
inline constexpr std::uint8_t k_playback_state = 0x05;            // server: playback's state
inline constexpr std::uint8_t k_client_message_data = 0x01;       // client: a published message
inline constexpr std::uint8_t k_service_call_request = 0x02;      // client: a service call
inline constexpr std::uint8_t k_playback_control_request = 0x03;  // client: the playback bar

// A status message's level.
enum class Level : int { info = 0, warning = 1, error = 2 };

// A channel the server advertises: one output stream.
struct Channel {
  std::uint32_t id = 0;
  std::string topic;              // "/robot/pose"
  std::string encoding = "json";  // of the messages
  std::string schema_name;        // "simgate.pose"
  std::string schema;             // the JSON Schema, as text
  std::string schema_encoding = "jsonschema";
  // What a client compares to reuse an id (the spec: same topic, encoding, schema).
  bool same_as(const Channel& o) const {
    return topic == o.topic && encoding == o.encoding && schema_name == o.schema_name &&
           schema == o.schema && schema_encoding == o.schema_encoding;
  }
};

// A service the server advertises: one simgate service, JSON in and out.
struct ServiceDef {
  std::uint32_t id = 0;
  std::string name;       // "/robot/motion/set_speed"
  std::string type;       // "simgate/robot.motion.set_speed"
  json request_schema;    // JSON Schema of the request (an object of the parameters)
  json response_schema;   // JSON Schema of the response (the service's result)
  std::string component;  // "robot.motion": what a call runs
  std::string service;    // "set_speed"
  bool same_as(const ServiceDef& o) const {
    return name == o.name && type == o.type && request_schema == o.request_schema &&
           response_schema == o.response_schema;
  }
};

// {"op": "serverInfo", ...}: the first message of every connection. `data_range` (ns), with
// the capability playbackControl: dataStartTime and dataEndTime ({sec, nsec}), the span the
// app's playback bar shows.
std::string server_info(std::string_view name, const std::vector<std::string>& capabilities,
                        const std::vector<std::string>& supported_encodings, const json& metadata,
                        std::string_view session_id,
                        std::optional<std::pair<std::uint64_t, std::uint64_t>> data_range = {});
// {"op": "advertise", "channels": [...]}
std::string advertise(const std::vector<Channel>& channels);
// {"op": "unadvertise", "channelIds": [...]}
std::string unadvertise(const std::vector<std::uint32_t>& channel_ids);
// {"op": "advertiseServices", "services": [...]} (both the `request`/`response` objects and
// the older `requestSchema`/`responseSchema` strings, for clients of either spec revision)
std::string advertise_services(const std::vector<ServiceDef>& services);
// {"op": "unadvertiseServices", "serviceIds": [...]}
std::string unadvertise_services(const std::vector<std::uint32_t>& service_ids);
// {"op": "parameterValues", "parameters": [{"name", "value"}...], "id"} (no id when "")
std::string parameter_values(const std::vector<std::pair<std::string, json>>& parameters,
                             std::string_view id);
// {"op": "status", "level": 0|1|2, "message": "..."}
std::string status(Level level, std::string_view message);
// {"op": "serviceCallFailure", "serviceId", "callId", "message"}
std::string service_call_failure(std::uint32_t service_id, std::uint32_t call_id,
                                 std::string_view message);

// A binary Message Data's first 13 bytes (opcode, subscription id, log time in ns); the
// message payload follows.
inline constexpr std::size_t k_message_data_head_bytes = 13;
void append_message_data_head(std::string& out, std::uint32_t subscription_id,
                              std::uint64_t time_ns);
// A binary Time message (9 bytes).
std::string time_message(std::uint64_t time_ns);
// A binary Service Call Response: its head (opcode, service id, call id, encoding), then
// `payload`.
void append_service_call_response(std::string& out, std::uint32_t service_id, std::uint32_t call_id,
                                  std::string_view encoding, std::string_view payload);
// A binary Playback State (capability playbackControl; the Foxglove SDK's layout): the
// status, the current time (ns), the speed, whether a seek made it, and the id of the
// request it answers ("": none, a change from elsewhere).
enum class PlaybackStatus : std::uint8_t { playing = 0, paused = 1, buffering = 2, ended = 3 };
std::string playback_state(PlaybackStatus status, std::uint64_t time_ns, float speed, bool did_seek,
                           std::string_view request_id);
// Simulated seconds as the protocol's nanoseconds (negative and NaN: 0; rounded).
std::uint64_t to_nanoseconds(double seconds);

// ---- client messages

// A client's text message, read: which op, and its fields. Ops simgate does not serve are
// read as `other` (the server answers them with a status naming the op).
struct Subscribe {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> subscriptions;  // (id, channelId)
};
struct Unsubscribe {
  std::vector<std::uint32_t> subscription_ids;
};
// A client's channel (capability clientPublish): what it will publish on `topic`.
struct ClientChannel {
  std::uint32_t id = 0;
  std::string topic;
  std::string encoding;
  std::string schema_name;
};
struct ClientAdvertise {
  std::vector<ClientChannel> channels;
};
struct ClientUnadvertise {
  std::vector<std::uint32_t> channel_ids;
};
// Parameters (capabilities parameters, parametersSubscribe): names are "/<component>/<name>"
// ("/robot/waypoint/max_angular_speed"); `id` is the request's, echoed in parameterValues
// (absent: "").
struct GetParameters {
  std::vector<std::string> names;  // empty: all
  std::string id;
};
struct SetParameters {
  std::vector<std::pair<std::string, json>> parameters;  // (name, value)
  std::string id;
};
struct SubscribeParameterUpdates {
  std::vector<std::string> names;  // empty: all
};
struct UnsubscribeParameterUpdates {
  std::vector<std::string> names;  // empty: all
};
struct OtherOp {
  std::string op;  // "getParameters", "fetchAsset", ...
};
struct Malformed {
  std::string reason;  // for the status message: what was wrong, and what was expected
};
using ClientText = std::variant<Subscribe, Unsubscribe, ClientAdvertise, ClientUnadvertise,
                                GetParameters, SetParameters, SubscribeParameterUpdates,
                                UnsubscribeParameterUpdates, OtherOp, Malformed>;
ClientText read_text(std::string_view message);

// A client's binary message, read.
struct ServiceCallRequest {
  std::uint32_t service_id = 0;
  std::uint32_t call_id = 0;
  std::string_view encoding;  // views into the message
  std::string_view payload;
};
struct ClientMessageData {
  std::uint32_t channel_id = 0;
  std::string_view payload;
};
// The app's playback bar (capability playbackControl): play or pause, at `speed` (a factor of
// real time), after seeking to `seek_ns` when it has one.
struct PlaybackControlRequest {
  bool play = true;
  float speed = 1;
  std::optional<std::uint64_t> seek_ns;
  std::string_view request_id;  // a view into the message
};
using ClientBinary =
    std::variant<ServiceCallRequest, ClientMessageData, PlaybackControlRequest, Malformed>;
ClientBinary read_binary(std::string_view message);

// ---- schemas

// The JSON Schema of a value of this shape (a stream's sample): numbers, integers, booleans,
// strings, arrays (of their first element's schema), objects (each key); {} for null.
json schema_of(const json& value);
// The topic of a component's stream ("robot.pose" -> "/robot/pose") and the name of one of
// its services ("robot.motion", "set_speed" -> "/robot/motion/set_speed"); the component a
// topic names ("/robot/motion" -> "robot.motion").
std::string topic_of(std::string_view component);
std::string component_of(std::string_view topic);
// A command published on a client channel, as the input stream with `fields` takes it: the
// object as it is, or a geometry_msgs/Twist ({"linear": {"x"}, "angular": {"z"}}, what
// Foxglove's Teleop panel publishes) as {"v": linear.x, "w": angular.z} for a velocity
// stream (fields v and w). Nullopt when `payload` is not a JSON object.
std::optional<json> read_command(std::string_view payload, const std::vector<std::string>& fields);
std::string service_name_of(std::string_view component, std::string_view service);

}  // namespace simgate::foxglove

#endif  // SIMGATE_FOXGLOVE_PROTOCOL_H_
