#include "simgate/mcp/protocol.h"

#include <algorithm>
#include <utility>

#include "simgate/jsonrpc/protocol.h"

namespace simgate::mcp {

bool is_served_version(std::string_view version) {
  return std::find(k_protocol_versions.begin(), k_protocol_versions.end(), version) !=
         k_protocol_versions.end();
}

std::string_view negotiate_version(std::string_view requested) {
  return is_served_version(requested) ? requested : k_protocol_versions.front();
}

namespace {

std::string with_dots_as(std::string_view qualified, char c) {
  std::string name(qualified);
  // the dots, and the slash of a world's prefix ("w3/rover.camera": docs/worlds.md)
  std::replace_if(name.begin(), name.end(), [](char x) { return x == '.' || x == '/'; }, c);
  return name;
}

}  // namespace

std::string tool_name(std::string_view qualified) { return with_dots_as(qualified, '_'); }

std::map<std::string, Tool> make_tools(const std::vector<ServiceDescriptor>& services,
                                       std::vector<std::string>& skipped) {
  std::vector<const ServiceDescriptor*> sorted;
  for (const ServiceDescriptor& d : services) sorted.push_back(&d);
  std::sort(sorted.begin(), sorted.end(),
            [](const auto* a, const auto* b) { return a->qualified_name() < b->qualified_name(); });
  std::map<std::string, Tool> tools;
  for (const ServiceDescriptor* d : sorted) {
    const std::string qualified = d->qualified_name();
    std::string name = tool_name(qualified);
    if (tools.count(name)) name = with_dots_as(qualified, '-');
    if (tools.count(name)) {
      skipped.push_back(qualified);
      continue;
    }
    tools.emplace(name, Tool{name, *d});
  }
  return tools;
}

namespace {

bool has_deadline_argument(const ServiceDescriptor& service) {
  if (!service.is_async) return false;
  return std::none_of(service.params.begin(), service.params.end(),
                      [](const ParamDescriptor& p) { return p.name == k_deadline_argument; });
}

}  // namespace

json tool_definition(const Tool& tool) {
  const ServiceDescriptor& s = tool.service;
  json schema = s.params_schema();
  schema.erase("description");  // the tool's description says it
  if (has_deadline_argument(s)) {
    schema["properties"][k_deadline_argument] = {
        {"type", "integer"},
        {"minimum", 1},
        {"maximum", jsonrpc::k_max_timeout_ms},
        {"description",
         "The longest this call may run, in milliseconds: it is cancelled after (none by "
         "default)."}};
  }
  std::string description = s.doc.empty() ? s.qualified_name() : s.doc;
  description += " (simgate service " + s.qualified_name() + "(" + s.signature() + ")";
  if (s.is_async) description += "; runs until done, reports progress, can be cancelled";
  description += ")";
  return {{"name", tool.name},
          {"title", s.qualified_name()},
          {"description", std::move(description)},
          {"inputSchema", std::move(schema)}};
}

std::chrono::milliseconds take_deadline(json& arguments, const Tool& tool, std::string& why) {
  why.clear();
  if (!has_deadline_argument(tool.service) || !arguments.is_object())
    return std::chrono::milliseconds{0};
  auto it = arguments.find(k_deadline_argument);
  if (it == arguments.end()) return std::chrono::milliseconds{0};
  const json value = std::move(*it);
  arguments.erase(it);
  if (!value.is_number_integer() || value.get<long long>() < 1 ||
      value.get<long long>() > jsonrpc::k_max_timeout_ms) {
    why = std::string(k_deadline_argument) + " must be an integer from 1 to " +
          std::to_string(jsonrpc::k_max_timeout_ms) + " (milliseconds), not " + value.dump();
    return std::chrono::milliseconds{0};
  }
  return std::chrono::milliseconds{value.get<long long>()};
}

namespace {

// Moves every PNG image record's image out of `value` (depth first, in order) into `images`,
// leaving {"image": "(image content N)"} in its place.
void take_images(json& value, json& images) {
  if (value.is_array()) {
    for (json& item : value) take_images(item, images);
    return;
  }
  if (!value.is_object()) return;
  auto image = value.find("image");
  auto format = value.find("format");
  if (image != value.end() && image->is_string() && format != value.end() && *format == "png") {
    images.push_back({{"type", "image"}, {"data", std::move(*image)}, {"mimeType", "image/png"}});
    *image = "(image content " + std::to_string(images.size()) + ")";
    return;
  }
  for (auto& [key, member] : value.items()) take_images(member, images);
}

}  // namespace

namespace {

// A failure, a preemption, a timeout as a tool execution error.
json error_result(const Outcome& outcome) {
  std::string text = outcome.message;
  if (text.empty() && outcome.value && outcome.value->is_string())
    text = outcome.value->get<std::string>();
  if (text.empty()) text = outcome.status == Status::preempted ? "preempted" : "failed";
  if (outcome.status == Status::preempted) text = "preempted: " + text;
  return {{"content", json::array({{{"type", "text"}, {"text", std::move(text)}}})},
          {"isError", true}};
}

// A success's result: `value` (its images taken out) as text and structured content, then
// the `images`.
json success_result(json value, json images) {
  json content = json::array({{{"type", "text"}, {"text", jsonrpc::dump(value)}}});
  for (json& image : images) content.push_back(std::move(image));
  json structured = value.is_object() ? std::move(value) : json{{"result", std::move(value)}};
  return {{"content", std::move(content)},
          {"structuredContent", std::move(structured)},
          {"isError", false}};
}

}  // namespace

json tool_result(Outcome&& outcome) {
  if (outcome.status != Status::success) return error_result(outcome);
  json value = outcome.value ? std::move(*outcome.value) : json(nullptr);
  json images = json::array();
  take_images(value, images);
  return success_result(std::move(value), std::move(images));
}

std::string tool_result_text(Outcome&& outcome) {
  if (outcome.status != Status::success) return jsonrpc::dump(error_result(outcome));
  json value = outcome.value ? std::move(*outcome.value) : json(nullptr);
  json images = json::array();
  take_images(value, images);
  if (!images.empty()) return jsonrpc::dump(success_result(std::move(value), std::move(images)));
  // the common case written straight: the value dumped once, as text and as itself
  const std::string text = jsonrpc::dump(value);
  std::string out = R"({"content":[{"type":"text","text":)";
  out += jsonrpc::dump(json(text));
  out += R"(}],"structuredContent":)";
  if (value.is_object()) {
    out += text;
  } else {
    out += R"({"result":)";
    out += text;
    out += '}';
  }
  out += R"(,"isError":false})";
  return out;
}

json progress_notification(const json& token, std::uint64_t count, const json& value) {
  json params = {{"progressToken", token}, {"message", jsonrpc::dump(value)}};
  const auto done = value.is_object() ? value.find("steps_done") : value.end();
  const auto requested = value.is_object() ? value.find("steps_requested") : value.end();
  if (done != value.end() && done->is_number() && requested != value.end() &&
      requested->is_number()) {
    params["progress"] = *done;
    params["total"] = *requested;
  } else {
    params["progress"] = count;
  }
  return {{"jsonrpc", "2.0"}, {"method", "notifications/progress"}, {"params", std::move(params)}};
}

json initialize_result(std::string_view version, std::string_view simgate_version) {
  return {{"protocolVersion", version},
          {"capabilities",
           {{"tools", {{"listChanged", true}}},
            {"resources", {{"subscribe", true}, {"listChanged", true}}}}},
          {"serverInfo",
           {{"name", "simgate"},
            {"title", "simgate robotics simulation"},
            {"version", simgate_version}}},
          {"instructions",
           "simgate runs a MuJoCo robotics simulation. Each tool is a service of a component: "
           "simulation_* tools control the world (list_robots, get_simulation_state, step, pause, "
           "play, reset, spawn_entity, get_snapshot for a picture), <robot>_<component>_* tools "
           "drive a robot's actuators and read its sensors. Long calls (a goto, a step of many "
           "steps) report progress and can be cancelled; deadline_ms bounds them. Resources: "
           "simgate://scene (the scene's objects) and simgate://streams/<component> (a sensor's "
           "latest sample; a camera's image), which can be subscribed to."}};
}

}  // namespace simgate::mcp
