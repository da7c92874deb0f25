// Fuzz target socket_line: what a socket client's bytes go through (simgate/morse/wire.h,
// params_parser.h). The input is a connection's stream: split at '\n' like the session
// does, each line tokenised by parse_request_line, a call's parameters parsed by
// parse_params_into into the value the previous call used (the transport refills it) and
// compared with a fresh parse_params, the call run on a ServiceHost under the simulation
// lock, and its reply written by append_reply.
//
// Properties: tokens are views into the line without blanks; the parameters start at
// params_column; refilled and fresh parses agree exactly (value or error, column, example);
// every reply is one line.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "fuzz_support.h"
#include "simgate/morse/params_parser.h"
#include "simgate/morse/wire.h"

namespace simgate::fuzz {
namespace {

bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

bool has_blank(std::string_view s) {
  for (char c : s)
    if (is_blank(c)) return true;
  return false;
}

// `part` lies inside `line`
bool inside(std::string_view part, std::string_view line) {
  return part.data() >= line.data() && part.data() + part.size() <= line.data() + line.size();
}

// Appends one reply and checks it is a single line.
void reply(std::string& out, std::string_view id, std::string_view status, const json* value) {
  const std::size_t before = out.size();
  socket::append_reply(out, id, status, value);
  const std::string_view line = std::string_view(out).substr(before);
  FUZZ_CHECK(!line.empty() && line.back() == '\n', "a reply ends with a newline");
  FUZZ_CHECK(line.find('\n') == line.size() - 1, "a reply is one line");
  FUZZ_CHECK(line.substr(0, id.size()) == id, "a reply starts with the request's id");
}

void one_line(std::string_view line, json& reused, socket::ParamsParse& error, ServiceHost& host,
              std::string& out) {
  const socket::RequestLine r = socket::parse_request_line(line);
  switch (r.kind) {
    case socket::RequestLine::Kind::blank:
      for (char c : line) FUZZ_CHECK(is_blank(c), "a blank line holds blanks only");
      return;
    case socket::RequestLine::Kind::malformed: {
      // its own id, or "-" for one that cannot be echoed (a control character in it)
      FUZZ_CHECK(r.id == "-" || (!r.id.empty() && !has_blank(r.id) && inside(r.id, line)),
                 "a malformed line has an id");
      FUZZ_CHECK(socket::echoable_id(r.id), "an id echoed holds no control character");
      FUZZ_CHECK(!r.error.empty(), "a malformed line says why");
      const json message = r.error;
      reply(out, r.id, "FAILED", &message);
      return;
    }
    case socket::RequestLine::Kind::cancel:
      FUZZ_CHECK(!r.id.empty() && !has_blank(r.id) && inside(r.id, line), "a cancel has an id");
      FUZZ_CHECK(socket::echoable_id(r.id), "an id echoed holds no control character");
      host.cancel_started(r.id.size());
      return;
    case socket::RequestLine::Kind::call: break;
  }
  FUZZ_CHECK(!r.id.empty() && !has_blank(r.id) && inside(r.id, line), "a call has an id");
  FUZZ_CHECK(socket::echoable_id(r.id), "an id echoed holds no control character");
  FUZZ_CHECK(!r.component.empty() && !has_blank(r.component) && inside(r.component, line),
             "a call has a component");
  FUZZ_CHECK(!r.service.empty() && !has_blank(r.service) && inside(r.service, line),
             "a call has a service");
  FUZZ_CHECK(inside(r.params, line), "the parameters are part of the line");
  FUZZ_CHECK(r.params_column >= 1 && r.params_column - 1 <= line.size(),
             "params_column is in the line");
  FUZZ_CHECK(r.params.empty() || r.params.data() == line.data() + (r.params_column - 1),
             "params_column is where the parameters start");
  FUZZ_CHECK(r.params.empty() || (!is_blank(r.params.front()) && !is_blank(r.params.back())),
             "the parameters are trimmed");

  // the transport's parse (into last call's value) against a fresh one
  const bool ok = socket::parse_params_into(r.params, r.params_column, reused, error);
  const socket::ParamsParse fresh = socket::parse_params(r.params, r.params_column);
  FUZZ_CHECK(ok == fresh.ok, "parse_params_into and parse_params agree on success");
  if (!ok) {
    FUZZ_CHECK(error.error == fresh.error && error.column == fresh.column &&
                   error.example == fresh.example,
               "parse_params_into and parse_params report the same error");
    FUZZ_CHECK(!error.error.empty(), "a syntax error says what");
    FUZZ_CHECK(error.column >= r.params_column && error.column <= r.params_column + r.params.size(),
               "the error's column points into the parameters");
    const json message = "Invalid request syntax: error while parsing the parameters at column " +
                         std::to_string(error.column) + ": " + error.error;
    reply(out, r.id, "FAILED", &message);
    return;
  }
  FUZZ_CHECK(identical(reused, fresh.value),
             "a refilled value is the fresh one: " + dump(reused) + " vs " + dump(fresh.value));

  const std::optional<Outcome> outcome =
      host.call(std::string(r.component), std::string(r.service), reused);
  if (!outcome) return;  // async: ends in a later tick
  if (outcome->status == Status::success) {
    reply(out, r.id, "SUCCESS", outcome->value ? &*outcome->value : nullptr);
  } else {
    const json message = outcome->message;
    reply(out, r.id, to_string(outcome->status), &message);
  }
}

}  // namespace
}  // namespace simgate::fuzz

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  simgate::fuzz::quiet_logs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace simgate;
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  fuzz::ServiceHost& host = fuzz::ServiceHost::instance();
  json reused;  // the call object a connection refills, line after line
  socket::ParamsParse error;
  std::string out;
  std::size_t begin = 0;
  while (begin <= input.size()) {
    std::size_t end = input.find('\n', begin);
    if (end == std::string_view::npos) end = input.size();
    fuzz::one_line(input.substr(begin, end - begin), reused, error, host, out);
    begin = end + 1;
    if (!out.empty() && out.size() > (1u << 16)) out.clear();
    host.tick();  // async calls end between reads
  }
  host.end_input();
  return 0;
}
