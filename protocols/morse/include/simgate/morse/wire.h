// simgate/morse/wire.h — the socket transport's line grammar and reply formatting (MORSE's text
// protocol).
//
// Requests, one per line (LF or CRLF; blanks between tokens are any run of spaces/tabs):
//
//   <id> <component> <service> [<params>]      a call (params: see params_parser.h)
//   <id> cancel                                cancels this connection's pending <id>
//   <id> simgate progress [<on>]               a call the transport answers itself: opts the
//                                              connection in to progress lines (on: true,
//                                              the default) or out (false)
//
// Replies, one per line, LF-terminated, single spaces:
//
//   <id> <STATUS>                              service returned nothing / PREEMPTED
//   <id> <STATUS> <json>                       result (SUCCESS) or message (FAILED)
//   <id> PROGRESS <json>                       a report of the running request <id>, only
//                                              to a connection that opted in; never final
//
// JSON is written the way MORSE's Python `json.dumps` writes it (separators ", " and
// ": ", non-ASCII escaped as \uXXXX, NaN/Infinity bare), so clients that compare bytes
// with MORSE see the same text. Invalid UTF-8 inside strings is replaced by U+FFFD, so
// formatting never fails.
//
// Threads: pure functions, callable from any thread.
#ifndef SIMGATE_MORSE_WIRE_H_
#define SIMGATE_MORSE_WIRE_H_

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "simgate/core/status.h"

namespace simgate::socket {

// One request line, split into tokens (views into the line).
struct RequestLine {
  enum class Kind {
    blank,      // nothing but blanks: ignored
    call,       // <id> <component> <service> [params]
    cancel,     // <id> cancel
    malformed,  // an id and something unusable; `error` says what (reply FAILED)
  };
  Kind kind = Kind::blank;
  std::string_view id;            // the client's request id, echoed verbatim
  std::string_view component;     // call only
  std::string_view service;       // call only
  std::string_view params;        // call only: the rest of the line, trimmed (may be empty)
  std::size_t params_column = 0;  // 1-based column of params[0] in the line
  std::string error;              // malformed only
};

// The status word of a progress line, never a final reply's.
inline constexpr std::string_view k_progress_status = "PROGRESS";

// Splits one line (without its '\n'; a trailing '\r' and surrounding blanks are ignored).
// An id with a control character is malformed, answered under the id "-": ids are echoed
// verbatim, and a terminal (telnet) would act on an escape sequence.
RequestLine parse_request_line(std::string_view line);

// Whether `id` can be echoed: no control character (below 0x20, or 0x7f).
bool echoable_id(std::string_view id);

// The token of an authentication line, `auth <token>` (blanks around the token ignored;
// empty if there is none), or nullopt when the line is something else. The first line of
// a client that must authenticate (kit/auth.h), on the service port and the stream ports.
std::optional<std::string_view> parse_auth_line(std::string_view line);

// Decodes one UTF-8 sequence at s[i]: its length (0 if invalid: truncated, overlong,
// surrogate, past U+10FFFF) and, through `cp`, the code point.
std::size_t decode_utf8(std::string_view s, std::size_t i, std::uint32_t& cp);

// True if `s` is valid UTF-8; otherwise `bad_offset` is the first invalid byte.
bool valid_utf8(std::string_view s, std::size_t& bad_offset);

// Appends `value` as Python's json.dumps would write it.
void append_json(std::string& out, const json& value);

// Appends "<id> <status>[ <json>]\n".
void append_reply(std::string& out, std::string_view id, std::string_view status,
                  const json* value);

}  // namespace simgate::socket

#endif  // SIMGATE_MORSE_WIRE_H_
