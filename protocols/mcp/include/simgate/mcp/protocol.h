// simgate/mcp/protocol.h — the Model Context Protocol's vocabulary as the mcp transport speaks
// it: the revisions served, the tools generated from the services, a finished call as a tool's
// result (its images as image content), progress notifications, the initialize result.
//
// Pure functions, no I/O (the transport, plugins/mcp, holds the HTTP and the sessions). MCP's
// messages are JSON-RPC 2.0 (one message per POST, no batches since 2025-06-18): the envelope
// is simgate/jsonrpc/protocol.h's. The contract is the published specification (revision
// 2025-11-25, https://modelcontextprotocol.io/specification/2025-11-25); docs/transports/mcp.md
// says what simgate does of it.
#ifndef SIMGATE_MCP_PROTOCOL_H_
#define SIMGATE_MCP_PROTOCOL_H_

#include <array>
#include <chrono>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "simgate/core/service.h"
#include "simgate/core/status.h"
#include "simgate/core/text.h"

namespace simgate::mcp {

// The revisions served, newest first.
inline constexpr std::array<std::string_view, 3> k_protocol_versions = {"2025-11-25", "2025-06-18",
                                                                        "2025-03-26"};
bool is_served_version(std::string_view version);
// The revision an initialize asking for `requested` gets: it when served, else the newest.
std::string_view negotiate_version(std::string_view requested);

// The argument every tool of an async service takes besides the service's own: the longest
// the call may run, in milliseconds (it is cancelled after), as Call::timeout.
inline constexpr const char* k_deadline_argument = "deadline_ms";

// One tool: a service under its MCP name.
struct Tool {
  std::string name;           // "rover_camera_get_image"
  ServiceDescriptor service;  // what it calls
};

// The tool name of the service `qualified` ("rover.camera.get_image"): its dots as '_'
// ("rover_camera_get_image"), the characters every model API takes in a function's name;
// a world's prefix too ("w3/rover.camera.get_image": "w3_rover_camera_get_image").
std::string tool_name(std::string_view qualified);
// The tools of `services` (RequestManager::descriptors(): what the transport's lists let
// through), by name. Two services whose names differ only by a '.' against a '_' would get one
// name: the second is named with '-' for its dots ("rover-camera-get_image"), and one still
// taken is left out, `skipped` saying which.
std::map<std::string, Tool> make_tools(const std::vector<ServiceDescriptor>& services,
                                       std::vector<std::string>& skipped);

// tools/list's entry for `tool`: name, title (the service's qualified name), description (its
// doc, its signature and whether it runs long), inputSchema (ServiceDescriptor::params_schema,
// with deadline_ms for an async service, one that has no parameter of that name) and
// annotations.
json tool_definition(const Tool& tool);

// Takes the deadline argument out of a tools/call's `arguments` (an object) when the tool has
// one: the call's timeout (zero: none). `why` says what is wrong with its value ("" when fine).
std::chrono::milliseconds take_deadline(json& arguments, const Tool& tool, std::string& why);

// A finished call as a CallToolResult: a success's value as text content and as
// structuredContent (an object; another value as {"result": value}), each image record in it
// (a camera's, a snapshot's: "format": "png" with the base64 "image") as image content
// (image/png) and, in the structured copy and the text, without its "image" field; a failure,
// a preemption, a timeout as isError with the reason as text (the spec's tool execution
// errors, which a model reads and may correct). The outcome's value is moved from.
json tool_result(Outcome&& outcome);
// The same as JSON text, written without building the result's DOM when it has no image (a
// tool call's answer, the transport's hot path).
std::string tool_result_text(Outcome&& outcome);

// A notifications/progress message for the call that asked with `token`: its `count`-th
// report `value`. The progress is the steps done (of the steps requested: the total) when the
// report says them, else the count; the message is the report's JSON.
json progress_notification(const json& token, std::uint64_t count, const json& value);

// initialize's result: the revision agreed, the server's capabilities (tools), its name and
// version, and instructions for the model.
json initialize_result(std::string_view version, std::string_view simgate_version);

}  // namespace simgate::mcp

#endif  // SIMGATE_MCP_PROTOCOL_H_
