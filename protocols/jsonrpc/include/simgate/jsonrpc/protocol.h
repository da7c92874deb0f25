// simgate/jsonrpc/protocol.h — the JSON-RPC 2.0 wire vocabulary of the JSON-RPC transports.
//
// Pure functions, no I/O: error codes and the Outcome -> code mapping, building response
// lines, validating one request object (and its fast path, which reads the common shape of
// a request straight from the text), splitting "component.service" at the last dot, the
// nesting-depth pre-scan that protects the parser's callers, and the OpenRPC document that
// `rpc.discover` returns. Used by the I/O thread of JsonRpcRequestManager only.
//
// Terms: a *message* is one line of the stream: a request object or a batch (array). A
// *call* has an id and gets a response; a *notification* has none and gets nothing.
#ifndef SIMGATE_JSONRPC_PROTOCOL_H_
#define SIMGATE_JSONRPC_PROTOCOL_H_

#include <chrono>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "simgate/core/service.h"
#include "simgate/core/status.h"

namespace simgate::jsonrpc {

// Error codes: the spec's, then the server block (-32000..-32099) documented in
// docs/transports/jsonrpc.md. Keep in sync with clients/jsonrpc (JsonRpcClient).
namespace code {
inline constexpr int parse_error = -32700;       // the line is not JSON
inline constexpr int invalid_request = -32600;   // not a request object / too large / dup id
inline constexpr int method_not_found = -32601;  // unknown component, service or rpc.* method
inline constexpr int invalid_params = -32602;    // arity, types, names
inline constexpr int internal_error = -32603;    // the service threw something unexpected
inline constexpr int service_failed = -32000;    // ServiceError / completed(FAILED)
inline constexpr int preempted = -32001;         // interrupted by a newer call
inline constexpr int cancelled = -32002;         // rpc.cancel, or the client went away
inline constexpr int timeout = -32003;           // no reply within _meta.timeout_ms or max_wait_ms
inline constexpr int busy = -32004;              // a non-interruptible async call is running
inline constexpr int unauthorized = -32005;      // rpc.login first, or a wrong token
inline constexpr int overloaded = -32006;        // too many calls in flight on the connection
inline constexpr int shutting_down = -32007;     // the server stopped before the call ended
}  // namespace code

// The spec's short text for a code ("Method not found"), or a name for server codes.
std::string_view code_message(int error_code) noexcept;

// The JSON-RPC code for a failed or preempted Outcome.
int code_for(const Outcome& outcome) noexcept;

// Serialises without throwing: invalid UTF-8 in strings is replaced by U+FFFD.
std::string dump(const json& value);

// {"jsonrpc":"2.0","id":<id>,"error":{"code","message","data"?}} as a JSON value.
json error_response(const json& id, int error_code, std::string message, json data = nullptr);
// A success response: {"jsonrpc": "2.0", "id": id, "result": result}.
json result_response(const json& id, json result);
// The response (result or error) for a finished call.
json outcome_response(const json& id, const Outcome& outcome, const std::string& method);

// One request object, checked against the spec.
struct Request {
  json id;              // string, number or null (null also when absent)
  bool has_id = false;  // false: a notification
  std::string method;   // as sent
  json params;          // array, object or null (absent)
  std::string id_text;  // dump(id) when has_id; filled by parse_request_fast only ("" otherwise)
};

// Validates `message` as a request object; its params are moved into `out`. On error
// returns the -32600 response to send (id copied from the message when it is itself
// valid) and leaves `out` unspecified.
std::optional<json> parse_request(json& message, Request& out);

// The fast path for the common shape of a message: one request object whose members are
// "jsonrpc" ("2.0"), "method" (a string), and optionally "id" (an integer, a string or null)
// and "params" (an array or an object), each once, in any order. Reads `line` in one pass,
// without building a DOM for the envelope; flat params are converted directly, nested ones
// with json::parse of their own text. Returns true only for a valid request, with `out`
// exactly as json::parse + parse_request would fill it (plus id_text); returns false for
// anything else (a batch, an error, escapes or non-ASCII in the envelope, other members,
// deep nesting): the caller then takes the full path, which reports errors, and `out` is
// unspecified. `out` may hold an earlier request: its params array is reused. Never throws
// for bad input.
bool parse_request_fast(std::string_view line, std::size_t max_depth, Request& out);

// Appends {"jsonrpc":"2.0","id":<id_text>,"result":<result>} (no newline) to `out`;
// `id_text` is the id as dump() writes it.
void append_result_line(std::string& out, std::string_view id_text, const json& result);

// The text of a response (error_response, outcome_response or a result) whose id is
// written as `id_text`, exactly: {"jsonrpc":"2.0","id":<id_text>,"error"|"result":...}.
std::string response_with_id_text(const json& response, std::string_view id_text);

// The exact text of the number ids of `line` that json::parse reads as a double (an integer
// beyond 64 bits, a fraction, an exponent), which dump() would echo rounded: by request,
// index 0 for a lone request object, the entry's index in a batch. A client's id must come
// back as it sent it (two ids rounding alike would collide). Parses `line` again: call it
// only when the DOM holds such an id. Empty for text json::parse refuses.
std::vector<std::pair<std::size_t, std::string>> float_id_texts(std::string_view line);

// Splits "robot.arm.move" into {"robot.arm", "move"} at the last dot. False when there is
// no dot or either side is empty. The parts are views of `method`.
bool split_method(std::string_view method, std::string_view& component, std::string_view& service);

// The call options of "_meta" in named params: {"progress": true|false} (rpc.progress
// notifications for this call), {"timeout_ms": N} (the call's deadline: an integer from 1 to
// k_max_timeout_ms, or 0 for none). Returns them; `why` says what is wrong with `meta` when
// it is not an object of known options with valid values (empty otherwise).
struct CallOptions {
  bool progress = false;
  std::chrono::milliseconds timeout{0};  // zero: none of its own
};
inline constexpr long long k_max_timeout_ms = 2'147'483'647;  // about 24.8 days
CallOptions read_meta(const json& meta, std::string& why);

// The OpenRPC 1.2.6 document for `services` (rpc.discover's result).
json openrpc_document(const std::vector<ServiceDescriptor>& services, std::string_view version,
                      std::string_view global_policy);

}  // namespace simgate::jsonrpc

#endif  // SIMGATE_JSONRPC_PROTOCOL_H_
