// Fuzz target jsonrpc_message: what a JSON-RPC client's bytes go through (plugins/jsonrpc/
// protocol.h, core's json_nests_deeper_than). The input is a connection's stream, split
// at '\n' (NDJSON); each message takes the transport's steps: blank lines skipped, the fast
// path (parse_request_fast, into the Request the previous message used), else the depth
// pre-scan, json::parse, the batch reader and parse_request per entry; split_method; the
// call run on a ServiceHost; the response written (append_result_line, outcome_response,
// error_response, dump).
//
// Properties: the fast path, whenever it accepts, reads exactly what json::parse +
// parse_request read (types included, id_text == dump(id)), at the transport's max_depth
// and at a small one; the pre-scan never sees less than the depth of what json::parse
// builds; split_method
// splits at the last dot; every response is JSON carrying the request's id.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_support.h"
#include "simgate/jsonrpc/protocol.h"

namespace simgate::fuzz {
namespace {

constexpr std::size_t k_max_depth = 128;  // the transport's default max_depth

// What the full path reads from one line: nothing (an error answered), one request, or a
// batch of entries (each a request or an error).
struct FullPath {
  bool answered_error = false;  // parse error, too deep, empty batch, not a request
  bool batch = false;
  std::vector<std::optional<jsonrpc::Request>> requests;  // nullopt: answered invalid
  std::vector<json> errors;                               // the error responses written
};

FullPath full_path(std::string_view line, std::size_t max_depth) {
  FullPath out;
  if (json_nests_deeper_than(line, max_depth)) {
    out.answered_error = true;
    out.errors.push_back(
        jsonrpc::error_response(nullptr, jsonrpc::code::invalid_request, "too deep"));
    return out;
  }
  // the manager refuses a NUL byte before parsing (nlohmann would end the text there)
  if (line.find('\0') != std::string_view::npos) {
    out.answered_error = true;
    out.errors.push_back(
        jsonrpc::error_response(nullptr, jsonrpc::code::parse_error, "Parse error"));
    return out;
  }
  json message;
  try {
    message = json::parse(line.begin(), line.end());
  } catch (const json::exception& e) {
    out.answered_error = true;
    out.errors.push_back(jsonrpc::error_response(nullptr, jsonrpc::code::parse_error, "Parse error",
                                                 json{{"reason", e.what()}}));
    return out;
  }
  // the pre-scan never sees less than the value's depth (it may see more: a duplicate
  // key's first value is dropped by the parser)
  const std::size_t depth = depth_of(message);
  FUZZ_CHECK(depth <= max_depth, "the pre-scan keeps deeper messages out");
  FUZZ_CHECK(depth == 0 || json_nests_deeper_than(line, depth - 1),
             "the pre-scan sees the value's depth");

  auto one = [&](json& entry) {
    jsonrpc::Request request;
    if (auto error = jsonrpc::parse_request(entry, request)) {
      FUZZ_CHECK(error->is_object() && error->contains("error") && error->contains("id"),
                 "an error response");
      out.errors.push_back(std::move(*error));
      out.requests.emplace_back();
    } else {
      out.requests.emplace_back(std::move(request));
    }
  };
  if (message.is_array()) {
    out.batch = true;
    if (message.empty()) {
      out.answered_error = true;
      out.errors.push_back(
          jsonrpc::error_response(nullptr, jsonrpc::code::invalid_request, "empty batch"));
      return out;
    }
    for (auto& entry : message) one(entry);
  } else {
    one(message);
  }
  return out;
}

// The fast path agrees with the full path.
void check_fast(std::string_view line, std::size_t max_depth, jsonrpc::Request& reused) {
  jsonrpc::Request fresh;
  const bool fast = jsonrpc::parse_request_fast(line, max_depth, fresh);
  const bool fast_reused = jsonrpc::parse_request_fast(line, max_depth, reused);
  FUZZ_CHECK(fast == fast_reused, "the fast path does not depend on the Request it refills");
  if (!fast) return;
  FullPath full = full_path(line, max_depth);
  FUZZ_CHECK(!full.answered_error && !full.batch && full.requests.size() == 1 && full.requests[0],
             "a message the fast path accepts is one valid request for the full path");
  const jsonrpc::Request& r = *full.requests[0];
  for (const jsonrpc::Request* f : {&fresh, &reused}) {
    FUZZ_CHECK(f->has_id == r.has_id, "fast path: has_id");
    FUZZ_CHECK(identical(f->id, r.id), "fast path: id " + dump(f->id) + " vs " + dump(r.id));
    FUZZ_CHECK(f->method == r.method, "fast path: method");
    FUZZ_CHECK(identical(f->params, r.params),
               "fast path: params " + dump(f->params) + " vs " + dump(r.params));
    if (f->has_id) FUZZ_CHECK(f->id_text == jsonrpc::dump(f->id), "fast path: id_text is dump(id)");
  }
}

// A response is JSON with the request's id (a client must be able to match it).
void check_response(const std::string& text, const json& id) {
  const json parsed = json::parse(text, nullptr, false);
  FUZZ_CHECK(!parsed.is_discarded() && parsed.is_object(), "a response is a JSON object: " + text);
  FUZZ_CHECK(parsed.value("jsonrpc", "") == "2.0", "a response says jsonrpc 2.0");
  FUZZ_CHECK(parsed.contains("id") &&
                 (identical(parsed["id"], id) || (id.is_number() && parsed["id"] == id)),
             "a response carries the request's id: " + text);
  FUZZ_CHECK(parsed.contains("result") != parsed.contains("error"), "a result or an error");
}

// Runs one request as the transport's dispatch() does; the response text, if any.
void dispatch(jsonrpc::Request& request, ServiceHost& host, const json& discover) {
  const std::string& method = request.method;
  if (method == "rpc.discover") {
    if (request.has_id)
      check_response(dump(json{{"jsonrpc", "2.0"}, {"id", request.id}, {"result", discover}}),
                     request.id);
    return;
  }
  std::string_view component, service;
  const bool split = jsonrpc::split_method(method, component, service);
  if (split) {
    FUZZ_CHECK(!component.empty() && !service.empty() && service.find('.') == std::string::npos &&
                   std::string(component) + "." + std::string(service) == method,
               "split_method splits at the last dot");
  } else {
    FUZZ_CHECK(
        method.find('.') == std::string::npos || method.front() == '.' || method.back() == '.',
        "split_method refuses only methods without a usable dot");
  }
  if (method.rfind("rpc.", 0) == 0 || !split) {
    const json error =
        jsonrpc::error_response(request.id, jsonrpc::code::method_not_found,
                                "Method not found: " + method, json{{"method", method}});
    if (request.has_id) check_response(jsonrpc::dump(error), request.id);
    return;
  }
  const std::optional<Outcome> outcome =
      host.call(std::string(component), std::string(service), request.params);
  if (!outcome || !request.has_id) return;  // async: ends later; a notification: no response
  if (outcome->status == Status::success) {
    const json result = outcome->value ? *outcome->value : json(nullptr);
    std::string line;
    jsonrpc::append_result_line(line, jsonrpc::dump(request.id), result);
    FUZZ_CHECK(line == R"({"jsonrpc":"2.0","id":)" + jsonrpc::dump(request.id) + R"(,"result":)" +
                           jsonrpc::dump(result) + "}",
               "append_result_line writes what dump() writes");
    check_response(line, request.id);
  } else {
    check_response(jsonrpc::dump(jsonrpc::outcome_response(request.id, *outcome, method)),
                   request.id);
  }
}

void one_message(std::string_view line, jsonrpc::Request& reused, ServiceHost& host,
                 const json& discover) {
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  if (line.find_first_not_of(" \t\r") == std::string_view::npos) return;  // keep-alive

  check_fast(line, k_max_depth, reused);
  check_fast(line, 3, reused);  // the depth limit's edges, on small inputs

  // as the transport: the fast path, else the full path (errors answered)
  if (jsonrpc::parse_request_fast(line, k_max_depth, reused)) {
    dispatch(reused, host, discover);
    return;
  }
  FullPath full = full_path(line, k_max_depth);
  for (const json& error : full.errors) check_response(jsonrpc::dump(error), error["id"]);
  for (auto& request : full.requests)
    if (request) dispatch(*request, host, discover);
}

}  // namespace
}  // namespace simgate::fuzz

namespace {
simgate::json discover_document;  // rpc.discover's result for the ServiceHost's services
}

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  simgate::fuzz::quiet_logs();
  discover_document = simgate::jsonrpc::openrpc_document(
      simgate::fuzz::ServiceHost::instance().descriptors(), "0.1.0", "reject");
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace simgate;
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  fuzz::ServiceHost& host = fuzz::ServiceHost::instance();
  jsonrpc::Request reused;  // the transport refills one Request message after message
  std::size_t begin = 0;
  while (begin <= input.size()) {
    std::size_t end = input.find('\n', begin);
    if (end == std::string_view::npos) end = input.size();
    fuzz::one_message(input.substr(begin, end - begin), reused, host, discover_document);
    host.tick();
    begin = end + 1;
  }
  host.end_input();
  return 0;
}
