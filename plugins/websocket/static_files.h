// static_files.h — the web app's files, served over plain HTTP on the websocket transport's
// port (docs/web.md).
//
// What: answers one plain HTTP request (not a WebSocket upgrade) with a file of the web
// root: GET and HEAD only (405 otherwise), "/" and ".../" mean index.html, the
// Content-Type from the extension, "Cache-Control: no-cache" (the browser asks again each
// time, and gets 304 while the file is unchanged), "Connection: close". The
// path is percent-decoded and refused (400) when malformed; a path with a ".." or "."
// segment, a backslash or a NUL, or one that leaves the root once symbolic links are
// resolved, is answered 404 as a missing file; so is anything but a regular file. Files
// larger than k_max_file_bytes are refused (403), targets longer than k_max_target_bytes
// too (414). Every error has a short text body.
//
// Validators: a file is answered with an `ETag` ("<size>-<mtime ns>", both hex) and a
// `Last-Modified`; a GET or HEAD whose `If-None-Match` names its ETag (or "*"), or, without
// If-None-Match, whose `If-Modified-Since` is not older than its mtime, gets 304 Not
// Modified with no body.
//
// Cache: the files' contents are kept in memory, keyed by their resolved path, up to
// the constructor's `cache_bytes` in all (least recently used out first; a larger file is read each
// time). A response shares the cached contents (never a copy per response: forty clients that do
// not read a 30 MB file hold it once); what a response holds of its own (its head, a file
// too large for the cache) counts against the transport's max_buffered_bytes while it is
// written (kit/held_bytes.h).
// Each request still looks at the file (stat): a file whose mtime or size changed is read
// again, so an edited file is served fresh; one that disappeared is 404.
//
// Life cycle: built by the transport from its options (`web_root`, `web`); only the cache
// changes after.
// Threads: answer() runs on the transport's I/O thread and does not touch the simulation;
// it reads a file there when it is not cached. The cache has its own mutex, so answer() may
// be called from any thread.
#ifndef SIMGATE_PLUGINS_WEBSOCKET_STATIC_FILES_H_
#define SIMGATE_PLUGINS_WEBSOCKET_STATIC_FILES_H_

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <list>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>

#include <boost/beast/http/message.hpp>
#include <boost/beast/http/string_body.hpp>

#include "simgate/core/config.h"
#include "simgate/kit/websocket_connection.h"

namespace simgate::websocket {

// The options `web` and `web_root` of the transport.
struct WebOptions {
  bool enabled = true;  // ("web") serve the web app on plain HTTP requests
  std::string root;     // ("web_root") its directory; default: default_web_root()

  // Reads and removes `web` and `web_root` from `options` (so that the JSON-RPC options
  // see the rest); ConfigError naming the key when one is malformed, or when an explicit
  // `web_root` is not a directory.
  static WebOptions take(json& options);
};

// Where the web app is when no `web_root` is given: the build tree's web directory when
// this plugin is the build tree's, else <prefix>/share/simgate/web found from where the
// plugin runs (so a moved prefix still finds its own), else the configured install prefix's.
std::string default_web_root();

// One HTTP response as written (kit/websocket_connection.h): its head (status line and
// headers, and the body of a short answer) and, for a file, the body, which the cache may
// share with other responses.
using kit::HttpResponse;

class StaticFiles {
 public:
  // `root` need not exist: every request is then answered 404 saying so.
  // `not_found_text`: the body of a 404 for "/" when there is no web app.
  // `cache_bytes`: the most bytes of file contents kept in memory (k_max_cache_bytes).
  StaticFiles(const std::string& root, std::string server_name, std::string not_found_text,
              std::size_t cache_bytes = k_max_cache_bytes);

  // The HTTP response to `request` (a file's body shared with the cache, not copied).
  HttpResponse answer(
      const boost::beast::http::request<boost::beast::http::string_body>& request) const;

  const std::filesystem::path& root() const { return root_; }

  // The largest file served.
  static constexpr std::size_t k_max_file_bytes = 32u << 20;
  // The longest request target accepted.
  static constexpr std::size_t k_max_target_bytes = 2048;
  // The most bytes of file contents kept in memory, by default.
  static constexpr std::size_t k_max_cache_bytes = 64u << 20;

  // The path under the root that `target` names ("/a/b.js?x" -> "a/b.js", "/" ->
  // "index.html"), or nullopt when it is malformed or names something outside it
  // (`bad_request` says which: true = malformed, 400; false = 404). Public for the tests.
  static std::optional<std::string> relative_path(std::string_view target, bool& bad_request);
  // "text/html; charset=utf-8" for "index.html", ... "application/octet-stream" if unknown.
  static std::string_view content_type(std::string_view file_name);
  // An HTTP date ("Sun, 06 Nov 1994 08:49:37 GMT", IMF-fixdate) of `seconds` since the
  // epoch, and back (nullopt unless `text` is an IMF-fixdate). Public for the tests.
  static std::string http_date(std::int64_t seconds);
  static std::optional<std::int64_t> parse_http_date(std::string_view text);

  // What the cache holds now (files, bytes), for the tests.
  std::size_t cached_files() const;
  std::size_t cached_bytes() const;

 private:
  // The head of a response whose body has `body_bytes` bytes.
  std::string head_of(unsigned status, std::string_view reason, std::string_view content_type,
                      std::size_t body_bytes, std::string_view extra_headers = {}) const;
  // A response whose (short) body goes in its head, unless `head` (a HEAD request).
  HttpResponse response(unsigned status, std::string_view reason, std::string_view content_type,
                        std::string_view body, bool head,
                        std::string_view extra_headers = {}) const;
  // A 304 with `validators` (the ETag and Last-Modified header lines) and no body.
  HttpResponse not_modified(std::string_view validators) const;

  // A file's contents as last read, and what says whether they are still current.
  struct Cached {
    std::filesystem::file_time_type mtime;    // the file's mtime when read
    std::uintmax_t size = 0;                  // its size when read (== body->size())
    std::shared_ptr<const std::string> body;  // its contents
    std::list<std::string>::iterator use;     // its place in lru_
  };
  // The contents of `file` (mtime and size as just seen), from the cache or read now
  // (`cached`: they are the cache's copy); nullptr when it cannot be read.
  std::shared_ptr<const std::string> contents(const std::filesystem::path& file,
                                              std::filesystem::file_time_type mtime,
                                              std::uintmax_t size, bool& cached) const;

  std::filesystem::path root_;      // the web root, canonical when it exists
  bool root_exists_ = false;        // it existed (as a directory) at construction
  std::string server_name_;         // the Server header
  std::string not_found_text_;      // the body of a 404 for "/" without a web app
  std::size_t cache_limit_;         // the most bytes cache_ holds
  mutable std::mutex cache_mutex_;  // guards the three members below
  mutable std::unordered_map<std::string, Cached> cache_;  // resolved path -> contents
  mutable std::list<std::string> lru_;   // the cached paths, most recently used first
  mutable std::size_t cache_bytes_ = 0;  // the sum of the cached sizes
};

}  // namespace simgate::websocket

#endif  // SIMGATE_PLUGINS_WEBSOCKET_STATIC_FILES_H_
