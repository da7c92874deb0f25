#include "simgate/foxglove/protocol.h"

#include <cmath>
#include <cstring>
#include <limits>

#include "simgate/core/text.h"

namespace simgate::foxglove {

std::string dump(const json& value) {
  return value.dump(-1, ' ', false, json::error_handler_t::replace);
}

namespace {

void put_u32(std::string& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>(v >> (8 * i)));
}

void put_u64(std::string& out, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<char>(v >> (8 * i)));
}

std::uint32_t get_u32(std::string_view bytes, std::size_t at) {
  std::uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(bytes[at + i]);
  return v;
}

std::uint64_t get_u64(std::string_view bytes, std::size_t at) {
  return static_cast<std::uint64_t>(get_u32(bytes, at)) |
         static_cast<std::uint64_t>(get_u32(bytes, at + 4)) << 32;
}

// Whether `v` is an integer an unsigned 32-bit id holds (the protocol's ids).
bool is_u32(const json& v) {
  return v.is_number_integer() && v.get<std::int64_t>() >= 0 &&
         v.get<std::uint64_t>() <= std::numeric_limits<std::uint32_t>::max();
}

// The unsigned 32-bit integer `value[key]`, or why not.
std::optional<std::uint32_t> u32_field(const json& object, const char* key, std::string& why,
                                       std::string_view where) {
  const auto it = object.find(key);
  if (it == object.end()) {
    why = std::string(where) + " has no \"" + key + "\"";
    return std::nullopt;
  }
  if (!is_u32(*it)) {
    why = std::string(where) + "'s \"" + key +
          "\" is not an unsigned 32-bit integer: " + quoted_prefix(dump(*it), 40);
    return std::nullopt;
  }
  return it->get<std::uint32_t>();
}

ClientText read_subscribe(const json& message) {
  const auto list = message.find("subscriptions");
  if (list == message.end() || !list->is_array())
    return Malformed{
        "subscribe takes \"subscriptions\": [{\"id\": <number>, \"channelId\": "
        "<an advertised channel>}]"};
  Subscribe s;
  std::string why;
  for (const json& entry : *list) {
    if (!entry.is_object())
      return Malformed{"subscribe: each subscription is an object {id, channelId}"};
    const auto id = u32_field(entry, "id", why, "a subscription");
    const auto channel = id ? u32_field(entry, "channelId", why, "a subscription") : std::nullopt;
    if (!channel) return Malformed{"subscribe: " + why};
    s.subscriptions.emplace_back(*id, *channel);
  }
  return s;
}

// An array of unsigned 32-bit ids at `key`, or why not.
std::optional<std::vector<std::uint32_t>> id_list(const json& message, const char* key,
                                                  std::string_view op, std::string& why) {
  const auto list = message.find(key);
  if (list == message.end() || !list->is_array()) {
    why = std::string(op) + " takes \"" + key + "\": [<ids>]";
    return std::nullopt;
  }
  std::vector<std::uint32_t> ids;
  for (const json& id : *list) {
    if (!is_u32(id)) {
      why = std::string(op) +
            ": an id is not an unsigned 32-bit integer: " + quoted_prefix(dump(id), 40);
      return std::nullopt;
    }
    ids.push_back(id.get<std::uint32_t>());
  }
  return ids;
}

ClientText read_client_advertise(const json& message) {
  const auto list = message.find("channels");
  if (list == message.end() || !list->is_array())
    return Malformed{
        "advertise takes \"channels\": [{\"id\", \"topic\", \"encoding\", "
        "\"schemaName\"}]"};
  ClientAdvertise a;
  std::string why;
  for (const json& entry : *list) {
    if (!entry.is_object()) return Malformed{"advertise: each channel is an object"};
    const auto id = u32_field(entry, "id", why, "a client channel");
    if (!id) return Malformed{"advertise: " + why};
    ClientChannel c;
    c.id = *id;
    for (auto [key, field] : {std::pair{"topic", &c.topic}, std::pair{"encoding", &c.encoding},
                              std::pair{"schemaName", &c.schema_name}}) {
      const auto it = entry.find(key);
      if (it == entry.end() || !it->is_string())
        return Malformed{std::string("advertise: a client channel's \"") + key +
                         "\" is missing or not a string"};
      *field = it->get<std::string>();
    }
    a.channels.push_back(std::move(c));
  }
  return a;
}

// The strings at `key` (absent: none), or why not.
std::optional<std::vector<std::string>> name_list(const json& message, const char* key,
                                                  std::string_view op, std::string& why) {
  std::vector<std::string> names;
  const auto list = message.find(key);
  if (list == message.end()) return names;
  if (!list->is_array()) {
    why = std::string(op) + " takes \"" + key + "\": [<parameter names>]";
    return std::nullopt;
  }
  for (const json& n : *list) {
    if (!n.is_string()) {
      why = std::string(op) + ": a parameter name is not a string: " + quoted_prefix(dump(n), 40);
      return std::nullopt;
    }
    names.push_back(n.get<std::string>());
  }
  return names;
}

// The request's "id" (a string, optional), or why not.
std::optional<std::string> request_id(const json& message, std::string_view op, std::string& why) {
  const auto id = message.find("id");
  if (id == message.end() || id->is_null()) return std::string();
  if (!id->is_string()) {
    why = std::string(op) + ": \"id\" is a string";
    return std::nullopt;
  }
  return id->get<std::string>();
}

ClientText read_parameters_op(const json& message, const std::string& op) {
  std::string why;
  if (op == "setParameters") {
    const auto list = message.find("parameters");
    if (list == message.end() || !list->is_array())
      return Malformed{"setParameters takes \"parameters\": [{\"name\", \"value\"}]"};
    SetParameters s;
    for (const json& p : *list) {
      if (!p.is_object() || !p.contains("name") || !p["name"].is_string())
        return Malformed{"setParameters: each parameter is {\"name\": <string>, \"value\"}"};
      s.parameters.emplace_back(p["name"].get<std::string>(), p.value("value", json()));
    }
    auto id = request_id(message, op, why);
    if (!id) return Malformed{why};
    s.id = std::move(*id);
    return s;
  }
  auto names = name_list(message, "parameterNames", op, why);
  if (!names) return Malformed{why};
  if (op == "getParameters") {
    auto id = request_id(message, op, why);
    if (!id) return Malformed{why};
    return GetParameters{std::move(*names), std::move(*id)};
  }
  if (op == "subscribeParameterUpdates") return SubscribeParameterUpdates{std::move(*names)};
  return UnsubscribeParameterUpdates{std::move(*names)};
}

json channel_json(const Channel& c) {
  return json{{"id", c.id},
              {"topic", c.topic},
              {"encoding", c.encoding},
              {"schemaName", c.schema_name},
              {"schema", c.schema},
              {"schemaEncoding", c.schema_encoding}};
}

}  // namespace

std::string pick_subprotocol(std::string_view offered) {
  bool sdk = false;
  while (!offered.empty()) {
    const std::size_t comma = offered.find(',');
    std::string_view item = offered.substr(0, comma);
    offered = comma == std::string_view::npos ? std::string_view() : offered.substr(comma + 1);
    while (!item.empty() && (item.front() == ' ' || item.front() == '\t')) item.remove_prefix(1);
    while (!item.empty() && (item.back() == ' ' || item.back() == '\t')) item.remove_suffix(1);
    if (item == k_subprotocol) return std::string(k_subprotocol);
    if (item == k_sdk_subprotocol) sdk = true;
  }
  return sdk ? std::string(k_sdk_subprotocol) : std::string();
}

// ---- server messages

std::string server_info(std::string_view name, const std::vector<std::string>& capabilities,
                        const std::vector<std::string>& supported_encodings, const json& metadata,
                        std::string_view session_id,
                        std::optional<std::pair<std::uint64_t, std::uint64_t>> data_range) {
  json m{{"op", "serverInfo"},
         {"name", name},
         {"capabilities", capabilities},
         {"metadata", metadata.is_object() ? metadata : json::object()},
         {"sessionId", session_id}};
  if (!supported_encodings.empty()) m["supportedEncodings"] = supported_encodings;
  if (data_range) {
    const auto time = [](std::uint64_t ns) {
      return json{{"sec", ns / 1'000'000'000}, {"nsec", ns % 1'000'000'000}};
    };
    m["dataStartTime"] = time(data_range->first);
    m["dataEndTime"] = time(data_range->second);
  }
  return dump(m);
}

std::string advertise(const std::vector<Channel>& channels) {
  json list = json::array();
  for (const Channel& c : channels) list.push_back(channel_json(c));
  return dump(json{{"op", "advertise"}, {"channels", std::move(list)}});
}

std::string unadvertise(const std::vector<std::uint32_t>& channel_ids) {
  return dump(json{{"op", "unadvertise"}, {"channelIds", channel_ids}});
}

std::string advertise_services(const std::vector<ServiceDef>& services) {
  json list = json::array();
  for (const ServiceDef& s : services) {
    const std::string request = dump(s.request_schema), response = dump(s.response_schema);
    list.push_back(json{{"id", s.id},
                        {"name", s.name},
                        {"type", s.type},
                        {"request",
                         {{"encoding", "json"},
                          {"schemaName", s.type + "_Request"},
                          {"schemaEncoding", "jsonschema"},
                          {"schema", request}}},
                        {"response",
                         {{"encoding", "json"},
                          {"schemaName", s.type + "_Response"},
                          {"schemaEncoding", "jsonschema"},
                          {"schema", response}}},
                        {"requestSchema", request},
                        {"responseSchema", response}});
  }
  return dump(json{{"op", "advertiseServices"}, {"services", std::move(list)}});
}

std::string unadvertise_services(const std::vector<std::uint32_t>& service_ids) {
  return dump(json{{"op", "unadvertiseServices"}, {"serviceIds", service_ids}});
}

std::string parameter_values(const std::vector<std::pair<std::string, json>>& parameters,
                             std::string_view id) {
  json list = json::array();
  for (const auto& [name, value] : parameters)
    list.push_back(json{{"name", name}, {"value", value}});
  json m{{"op", "parameterValues"}, {"parameters", std::move(list)}};
  if (!id.empty()) m["id"] = id;
  return dump(m);
}

std::string status(Level level, std::string_view message) {
  return dump(json{{"op", "status"}, {"level", static_cast<int>(level)}, {"message", message}});
}

std::string service_call_failure(std::uint32_t service_id, std::uint32_t call_id,
                                 std::string_view message) {
  return dump(json{{"op", "serviceCallFailure"},
                   {"serviceId", service_id},
                   {"callId", call_id},
                   {"message", message}});
}

void append_message_data_head(std::string& out, std::uint32_t subscription_id,
                              std::uint64_t time_ns) {
  out.push_back(static_cast<char>(k_message_data));
  put_u32(out, subscription_id);
  put_u64(out, time_ns);
}

std::string time_message(std::uint64_t time_ns) {
  std::string out;
  out.push_back(static_cast<char>(k_time));
  put_u64(out, time_ns);
  return out;
}

std::string playback_state(PlaybackStatus status, std::uint64_t time_ns, float speed, bool did_seek,
                           std::string_view request_id) {
  std::string out;
  out.push_back(static_cast<char>(k_playback_state));
  out.push_back(static_cast<char>(status));
  put_u64(out, time_ns);
  std::uint32_t bits;
  static_assert(sizeof bits == sizeof speed);
  std::memcpy(&bits, &speed, sizeof bits);
  put_u32(out, bits);
  out.push_back(did_seek ? 1 : 0);
  put_u32(out, static_cast<std::uint32_t>(request_id.size()));
  out += request_id;
  return out;
}

void append_service_call_response(std::string& out, std::uint32_t service_id, std::uint32_t call_id,
                                  std::string_view encoding, std::string_view payload) {
  out.push_back(static_cast<char>(k_service_call_response));
  put_u32(out, service_id);
  put_u32(out, call_id);
  put_u32(out, static_cast<std::uint32_t>(encoding.size()));
  out.append(encoding);
  out.append(payload);
}

std::uint64_t to_nanoseconds(double seconds) {
  if (!(seconds > 0)) return 0;
  const double ns = std::round(seconds * 1e9);
  if (ns >= 18446744073709549568.0) return std::numeric_limits<std::uint64_t>::max();
  return static_cast<std::uint64_t>(ns);
}

// ---- client messages

ClientText read_text(std::string_view text) {
  // nlohmann's parser would stop at a NUL byte and take what comes before it for the message
  if (text.find('\0') != std::string_view::npos)
    return Malformed{"a text message is not JSON: it holds a NUL byte at " +
                     std::to_string(text.find('\0'))};
  const json message = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (message.is_discarded())
    return Malformed{"a text message is not JSON: " + quoted_prefix(text, 60)};
  if (!message.is_object())
    return Malformed{"a text message is a JSON object with an \"op\", not " +
                     quoted_prefix(text, 60)};
  const auto op = message.find("op");
  if (op == message.end() || !op->is_string())
    return Malformed{"a text message names its operation in \"op\" (a string): " +
                     quoted_prefix(text, 60)};
  const std::string& name = op->get_ref<const std::string&>();
  if (name == "subscribe") return read_subscribe(message);
  std::string why;
  if (name == "unsubscribe") {
    auto ids = id_list(message, "subscriptionIds", "unsubscribe", why);
    if (!ids) return Malformed{why};
    return Unsubscribe{std::move(*ids)};
  }
  if (name == "advertise") return read_client_advertise(message);
  if (name == "getParameters" || name == "setParameters" || name == "subscribeParameterUpdates" ||
      name == "unsubscribeParameterUpdates")
    return read_parameters_op(message, name);
  if (name == "unadvertise") {
    auto ids = id_list(message, "channelIds", "unadvertise", why);
    if (!ids) return Malformed{why};
    return ClientUnadvertise{std::move(*ids)};
  }
  return OtherOp{name};
}

ClientBinary read_binary(std::string_view message) {
  if (message.empty()) return Malformed{"an empty binary message (the first byte is the opcode)"};
  const auto opcode = static_cast<std::uint8_t>(message[0]);
  if (opcode == k_service_call_request) {
    if (message.size() < 13)
      return Malformed{"a service call request of " + std::to_string(message.size()) +
                       " bytes (its head alone is 13: opcode, service id, call id, encoding "
                       "length)"};
    ServiceCallRequest r;
    r.service_id = get_u32(message, 1);
    r.call_id = get_u32(message, 5);
    const std::uint32_t length = get_u32(message, 9);
    if (length > message.size() - 13)
      return Malformed{"a service call request whose encoding (" + std::to_string(length) +
                       " bytes) runs past its end"};
    r.encoding = message.substr(13, length);
    r.payload = message.substr(13 + length);
    return r;
  }
  if (opcode == k_client_message_data) {
    if (message.size() < 5)
      return Malformed{"a client message of " + std::to_string(message.size()) +
                       " bytes (its head alone is 5: opcode, channel id)"};
    return ClientMessageData{get_u32(message, 1), message.substr(5)};
  }
  if (opcode == k_playback_control_request) {
    // opcode, command, speed (f32), had seek, seek time (u64), request id length, request id
    constexpr std::size_t k_head = 1 + 1 + 4 + 1 + 8 + 4;
    if (message.size() < k_head)
      return Malformed{"a playback control request of " + std::to_string(message.size()) +
                       " bytes (its head alone is 19: opcode, command, speed, had seek, seek "
                       "time, request id length)"};
    const auto command = static_cast<std::uint8_t>(message[1]);
    if (command > 1)
      return Malformed{"a playback control request with command " + std::to_string(command) +
                       " (0: play, 1: pause)"};
    PlaybackControlRequest r;
    r.play = command == 0;
    const std::uint32_t bits = get_u32(message, 2);
    std::memcpy(&r.speed, &bits, sizeof bits);
    if (message[6] != 0) r.seek_ns = get_u64(message, 7);
    const std::uint32_t length = get_u32(message, 15);
    if (length > message.size() - k_head)
      return Malformed{"a playback control request whose request id (" + std::to_string(length) +
                       " bytes) runs past its end"};
    r.request_id = message.substr(k_head, length);
    return r;
  }
  return Malformed{"unknown binary opcode " + std::to_string(opcode) +
                   " (a client sends 1, message data, 2, a service call request, or 3, a playback "
                   "control request)"};
}

// ---- schemas

json schema_of(const json& value) {
  switch (value.type()) {
    case json::value_t::boolean: return json{{"type", "boolean"}};
    case json::value_t::number_integer:
    case json::value_t::number_unsigned: return json{{"type", "integer"}};
    case json::value_t::number_float: return json{{"type", "number"}};
    case json::value_t::string: return json{{"type", "string"}};
    case json::value_t::array: {
      json schema{{"type", "array"}};
      if (!value.empty()) schema["items"] = schema_of(value.front());
      return schema;
    }
    case json::value_t::object: {
      json properties = json::object();
      for (const auto& [key, member] : value.items()) properties[key] = schema_of(member);
      return json{{"type", "object"}, {"properties", std::move(properties)}};
    }
    default: return json::object();
  }
}

std::string topic_of(std::string_view component) {
  std::string out = "/";
  for (char c : component) out += c == '.' ? '/' : c;
  return out;
}

std::string component_of(std::string_view topic) {
  if (topic.starts_with('/')) topic.remove_prefix(1);
  std::string out;
  for (char c : topic) out += c == '/' ? '.' : c;
  return out;
}

std::optional<json> read_command(std::string_view payload, const std::vector<std::string>& fields) {
  json command = json::parse(payload, nullptr, /*allow_exceptions=*/false);
  if (!command.is_object()) return std::nullopt;
  const bool velocity =
      fields.size() == 2 && fields[0] == "v" && fields[1] == "w";  // motion_vw's order
  const auto linear = command.find("linear");
  const auto angular = command.find("angular");
  if (velocity && linear != command.end() && angular != command.end() && linear->is_object() &&
      angular->is_object())
    return json{{"v", linear->value("x", 0.0)}, {"w", angular->value("z", 0.0)}};
  return command;
}

std::string service_name_of(std::string_view component, std::string_view service) {
  return topic_of(component) + "/" + std::string(service);
}

}  // namespace simgate::foxglove
