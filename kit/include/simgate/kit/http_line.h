// simgate/kit/http_line.h — whether a line a line transport read is an HTTP request line:
// what a browser sends first when a web page posts to the port ("POST / HTTP/1.1"). No line
// of a line protocol looks like one, so a line connection that sees one closes before the
// headers and the body that follow could be taken as requests (line_connection.h; issue
// #35, item 4). Header-only and free of Asio: the fuzz target line_decoders checks it.
#ifndef SIMGATE_KIT_HTTP_LINE_H_
#define SIMGATE_KIT_HTTP_LINE_H_

#include <cstddef>
#include <string_view>

namespace simgate::kit {

namespace http_line_detail {

// is_http_request_line past its first byte (a capital letter): out of line, so that the
// check every line of a line protocol gets is one compare inlined into its caller.
[[gnu::noinline]] inline bool rest_is_request_line(std::string_view line) {
  if (line.back() == '\r') line.remove_suffix(1);
  std::size_t method = 0;
  while (method < line.size() && line[method] >= 'A' && line[method] <= 'Z') ++method;
  if (method == 0 || method > 16 || method >= line.size() || line[method] != ' ') return false;
  const std::size_t version = line.rfind(' ');
  if (version <= method + 1) return false;  // no request target between the two spaces
  const std::string_view v = line.substr(version + 1);
  return v.size() == 8 && v.substr(0, 5) == "HTTP/" && v[5] >= '0' && v[5] <= '9' && v[6] == '.' &&
         v[7] >= '0' && v[7] <= '9' &&
         line.substr(method + 1, version - method - 1).find(' ') == std::string_view::npos;
}

}  // namespace http_line_detail

// True when `line` is a method token of 1 to 16 capital letters, one space, a request target
// without spaces, one space, "HTTP/<digit>.<digit>", maybe a '\r'.
inline bool is_http_request_line(std::string_view line) {
  // what nearly every line fails at: a method begins with a capital letter ('{', digits,
  // lower-case names do not)
  if (line.empty() || static_cast<unsigned char>(line.front() - 'A') > 'Z' - 'A') return false;
  return http_line_detail::rest_is_request_line(line);
}

}  // namespace simgate::kit

#endif  // SIMGATE_KIT_HTTP_LINE_H_
