// static_files.h — the web app's files, served over plain HTTP on the websocket transport's
// port (docs/web.md).
//
// What: answers one plain HTTP request (not a WebSocket upgrade) with a file of the web
// root: GET and HEAD only (405 otherwise), "/" and ".../" mean index.html, the
// Content-Type from the extension, "Cache-Control: no-cache", "Connection: close". The
// path is percent-decoded and refused (400) when malformed; a path with a ".." or "."
// segment, a backslash or a NUL, or one that leaves the root once symbolic links are
// resolved, is answered 404 as a missing file; so is anything but a regular file. Files
// larger than k_max_file_bytes are refused (403), targets longer than k_max_target_bytes
// too (414). Every error has a short text body.
//
// Life cycle: built by the transport from its options (`web_root`, `web`), immutable after.
// Threads: answer() runs on the transport's I/O thread; it reads the file there (a few
// small files, once per page load), holding no lock.
#ifndef SIMGATE_PLUGINS_WEBSOCKET_STATIC_FILES_H_
#define SIMGATE_PLUGINS_WEBSOCKET_STATIC_FILES_H_

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include <boost/beast/http/message.hpp>
#include <boost/beast/http/string_body.hpp>

#include "simgate/core/config.h"

namespace simgate::websocket {

// The options `web` and `web_root` of the transport.
struct WebOptions {
  bool enabled = true;    // ("web") serve the web app on plain HTTP requests
  std::string root;       // ("web_root") its directory; default: default_web_root()

  // Reads and removes `web` and `web_root` from `options` (so that the JSON-RPC options
  // see the rest); ConfigError naming the key when one is malformed, or when an explicit
  // `web_root` is not a directory.
  static WebOptions take(json& options);
};

// Where the web app is when no `web_root` is given: the build tree's web directory when
// this plugin is the build tree's, else <prefix>/share/simgate/web found from where the
// plugin runs (so a moved prefix still finds its own), else the configured install prefix's.
std::string default_web_root();

class StaticFiles {
 public:
  // `root` need not exist: every request is then answered 404 saying so.
  // `not_found_text`: the body of a 404 for "/" when there is no web app.
  StaticFiles(const std::string& root, std::string server_name, std::string not_found_text);

  // The whole HTTP response (status line, headers and body) to `request`.
  std::string answer(const boost::beast::http::request<boost::beast::http::string_body>& request) const;

  const std::filesystem::path& root() const { return root_; }

  // The largest file served.
  static constexpr std::size_t k_max_file_bytes = 32u << 20;
  // The longest request target accepted.
  static constexpr std::size_t k_max_target_bytes = 2048;

  // The path under the root that `target` names ("/a/b.js?x" -> "a/b.js", "/" ->
  // "index.html"), or nullopt when it is malformed or names something outside it
  // (`bad_request` says which: true = malformed, 400; false = 404). Public for the tests.
  static std::optional<std::string> relative_path(std::string_view target, bool& bad_request);
  // "text/html; charset=utf-8" for "index.html", ... "application/octet-stream" if unknown.
  static std::string_view content_type(std::string_view file_name);

 private:
  std::string response(unsigned status, std::string_view reason, std::string_view content_type, std::string_view body,
                       bool head, std::string_view extra_headers = {}) const;

  std::filesystem::path root_;          // the web root, canonical when it exists
  bool root_exists_ = false;            // it existed (as a directory) at construction
  std::string server_name_;             // the Server header
  std::string not_found_text_;          // the body of a 404 for "/" without a web app
};

}  // namespace simgate::websocket

#endif  // SIMGATE_PLUGINS_WEBSOCKET_STATIC_FILES_H_
