#include "static_files.h"

#include <dlfcn.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <system_error>
#include <utility>

#include "simgate/core/errors.h"

namespace simgate::websocket {

namespace fs = std::filesystem;
namespace http = boost::beast::http;

// ---- options

WebOptions WebOptions::take(json& options) {
  WebOptions o;
  if (!options.is_object()) return o;  // the JSON-RPC options say what is wrong with it
  json mine = json::object();
  for (const char* key : {"web", "web_root"}) {
    if (auto it = options.find(key); it != options.end()) {
      mine[key] = *it;
      options.erase(it);
    }
  }
  ConfigObject config(mine, "");
  o.enabled = config.get_bool("web", true);
  const bool explicit_root = config.has("web_root");
  o.root = explicit_root ? config.get_string("web_root", "") : default_web_root();
  if (explicit_root) {
    std::error_code ec;
    if (o.root.empty()) config.fail("web_root", "a directory (the web app's files)");
    if (o.enabled && !fs::is_directory(o.root, ec))
      throw ConfigError("web_root: expected a directory (the web app's files), found '" + o.root +
                        "': " + (fs::exists(o.root, ec) ? "not a directory" : "no such directory"));
  }
  config.finish();
  return o;
}

std::string default_web_root() {
  // the plugin finds itself (dladdr), as libsimgate_core finds the plugins
  static const char anchor = 0;
  Dl_info info{};
  std::error_code ec;
  if (::dladdr(&anchor, &info) && info.dli_fname) {
    const fs::path self = fs::canonical(info.dli_fname, ec);
    if (!ec) {
      const fs::path dir = self.parent_path();
      const fs::path build_plugins = fs::canonical(SIMGATE_WEB_BUILD_PLUGIN_DIR, ec);
      if (!ec && dir == build_plugins) return SIMGATE_WEB_BUILD_DIR;
      return (dir / SIMGATE_WEB_DIR_FROM_PLUGIN_DIR).lexically_normal().string();
    }
  }
  return SIMGATE_WEB_INSTALL_DIR;
}

// ---- requests

StaticFiles::StaticFiles(const std::string& root, std::string server_name,
                         std::string not_found_text, std::size_t cache_bytes)
    : root_(root),
      server_name_(std::move(server_name)),
      not_found_text_(std::move(not_found_text)),
      cache_limit_(cache_bytes) {}

namespace {

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

}  // namespace

std::optional<std::string> StaticFiles::relative_path(std::string_view target, bool& bad_request) {
  bad_request = false;
  // the path alone: no query, no fragment; origin-form only ("/...")
  target = target.substr(0, target.find_first_of("?#"));
  if (!target.starts_with('/')) {
    bad_request = true;
    return std::nullopt;
  }
  // percent-decoded; a malformed escape is a bad request
  std::string path;
  path.reserve(target.size());
  for (std::size_t i = 0; i < target.size(); ++i) {
    if (target[i] != '%') {
      path += target[i];
      continue;
    }
    const int hi = i + 2 < target.size() ? hex_digit(target[i + 1]) : -1;
    const int lo = i + 2 < target.size() ? hex_digit(target[i + 2]) : -1;
    if (hi < 0 || lo < 0) {
      bad_request = true;
      return std::nullopt;
    }
    path += static_cast<char>(hi * 16 + lo);
    i += 2;
  }
  // no NUL, no backslash, no "." or ".." segment, no "//" (an absolute path once the
  // leading slash is gone): such a path names nothing here
  if (path.find('\0') != std::string::npos || path.find('\\') != std::string::npos ||
      path.find("//") != std::string::npos)
    return std::nullopt;
  std::string relative = path.substr(1);
  for (std::size_t start = 0; start <= relative.size();) {
    const std::size_t end = std::min(relative.find('/', start), relative.size());
    const std::string_view segment(relative.data() + start, end - start);
    if (segment == "." || segment == "..") return std::nullopt;
    start = end + 1;
  }
  // a directory means its index.html
  if (relative.empty() || relative.ends_with('/')) relative += "index.html";
  return relative;
}

std::string_view StaticFiles::content_type(std::string_view file_name) {
  static constexpr std::array<std::pair<std::string_view, std::string_view>, 14> types{{
      {".html", "text/html; charset=utf-8"},
      {".htm", "text/html; charset=utf-8"},
      {".js", "text/javascript; charset=utf-8"},
      {".mjs", "text/javascript; charset=utf-8"},
      {".css", "text/css; charset=utf-8"},
      {".json", "application/json"},
      {".map", "application/json"},
      {".png", "image/png"},
      {".jpg", "image/jpeg"},
      {".svg", "image/svg+xml"},
      {".ico", "image/x-icon"},
      {".txt", "text/plain; charset=utf-8"},
      {".wasm", "application/wasm"},
      {".webmanifest", "application/manifest+json"},
  }};
  for (const auto& [extension, type] : types)
    if (file_name.ends_with(extension)) return type;
  return "application/octet-stream";
}

namespace {

constexpr std::array<const char*, 7> k_days{"Sun", "Mon", "Tue", "Wed", "Thu", "Fri", "Sat"};
constexpr std::array<const char*, 12> k_months{"Jan", "Feb", "Mar", "Apr", "May", "Jun",
                                               "Jul", "Aug", "Sep", "Oct", "Nov", "Dec"};

// A file time as nanoseconds and as whole seconds since the Unix epoch.
std::int64_t epoch_ns(fs::file_time_type t) {
  using namespace std::chrono;
  return duration_cast<nanoseconds>(file_clock::to_sys(t).time_since_epoch()).count();
}
std::int64_t epoch_s(fs::file_time_type t) {
  using namespace std::chrono;
  return floor<seconds>(file_clock::to_sys(t)).time_since_epoch().count();
}

std::string etag_of(std::uintmax_t size, fs::file_time_type mtime) {
  char text[64];
  std::snprintf(text, sizeof text, "\"%jx-%llx\"", size,
                static_cast<unsigned long long>(epoch_ns(mtime)));
  return text;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

// If-None-Match names `etag` (weak comparison, as RFC 9110 wants for it) or is "*".
bool none_match_names(std::string_view header, std::string_view etag) {
  for (std::size_t start = 0; start <= header.size();) {
    const std::size_t end = std::min(header.find(',', start), header.size());
    std::string_view tag = trim(header.substr(start, end - start));
    if (tag == "*") return true;
    if (tag.starts_with("W/")) tag.remove_prefix(2);
    if (tag == etag) return true;
    start = end + 1;
  }
  return false;
}

}  // namespace

std::string StaticFiles::http_date(std::int64_t seconds) {
  const std::time_t t = static_cast<std::time_t>(seconds);
  std::tm tm{};
  ::gmtime_r(&t, &tm);
  char text[40];
  std::snprintf(text, sizeof text, "%s, %02d %s %04d %02d:%02d:%02d GMT", k_days[tm.tm_wday % 7],
                tm.tm_mday, k_months[tm.tm_mon % 12], tm.tm_year + 1900, tm.tm_hour, tm.tm_min,
                tm.tm_sec);
  return text;
}

std::optional<std::int64_t> StaticFiles::parse_http_date(std::string_view text) {
  // "Sun, 06 Nov 1994 08:49:37 GMT": 29 characters, fixed places
  if (text.size() != 29 || text.substr(3, 2) != ", " || text.substr(25) != " GMT")
    return std::nullopt;
  const auto number = [&](std::size_t at, std::size_t digits) -> int {
    int n = 0;
    for (std::size_t i = at; i < at + digits; ++i) {
      if (text[i] < '0' || text[i] > '9') return -1;
      n = n * 10 + (text[i] - '0');
    }
    return n;
  };
  std::tm tm{};
  tm.tm_mday = number(5, 2);
  tm.tm_mon = -1;
  for (int i = 0; i < 12; ++i)
    if (text.substr(8, 3) == k_months[i]) tm.tm_mon = i;
  tm.tm_year = number(12, 4) - 1900;
  tm.tm_hour = number(17, 2);
  tm.tm_min = number(20, 2);
  tm.tm_sec = number(23, 2);
  if (tm.tm_mday < 1 || tm.tm_mday > 31 || tm.tm_mon < 0 || tm.tm_year < 70 - 1900 ||
      tm.tm_hour < 0 || tm.tm_hour > 23 || tm.tm_min < 0 || tm.tm_min > 59 || tm.tm_sec < 0 ||
      tm.tm_sec > 60 || text[7] != ' ' || text[11] != ' ' || text[16] != ' ' || text[19] != ':' ||
      text[22] != ':')
    return std::nullopt;
  return static_cast<std::int64_t>(::timegm(&tm));
}

std::size_t StaticFiles::cached_files() const {
  std::lock_guard lock(cache_mutex_);
  return cache_.size();
}

std::size_t StaticFiles::cached_bytes() const {
  std::lock_guard lock(cache_mutex_);
  return cache_bytes_;
}

std::shared_ptr<const std::string> StaticFiles::contents(const fs::path& file,
                                                         fs::file_time_type mtime,
                                                         std::uintmax_t size, bool& cached) const {
  const std::string key = file.string();
  {
    std::lock_guard lock(cache_mutex_);
    if (auto it = cache_.find(key); it != cache_.end()) {
      if (it->second.mtime == mtime && it->second.size == size) {
        lru_.splice(lru_.begin(), lru_, it->second.use);
        cached = true;
        return it->second.body;
      }
      // changed since it was read: drop it, read it again below
      cache_bytes_ -= it->second.size;
      lru_.erase(it->second.use);
      cache_.erase(it);
    }
  }
  // read whole, outside the cache's lock
  std::ifstream in(file, std::ios::binary);
  if (!in) return nullptr;
  auto body = std::make_shared<std::string>(size, '\0');
  if (size > 0 && !in.read(body->data(), static_cast<std::streamsize>(size))) return nullptr;
  // a file that grew while it was read is read again on the next request (its size differs)
  if (in.peek() != std::char_traits<char>::eof()) return body;
  if (size > cache_limit_) return body;
  std::lock_guard lock(cache_mutex_);
  if (cache_.contains(key)) return body;  // another thread read it meanwhile
  while (!lru_.empty() && cache_bytes_ + size > cache_limit_) {
    const auto victim = cache_.find(lru_.back());
    cache_bytes_ -= victim->second.size;
    cache_.erase(victim);
    lru_.pop_back();
  }
  lru_.push_front(key);
  cache_.emplace(key, Cached{mtime, size, body, lru_.begin()});
  cache_bytes_ += size;
  cached = true;
  return body;
}

std::string StaticFiles::head_of(unsigned status, std::string_view reason, std::string_view type,
                                 std::size_t body_bytes, std::string_view extra_headers) const {
  std::string out;
  out.reserve(256);
  out += "HTTP/1.1 " + std::to_string(status) + " ";
  out += reason;
  out += "\r\nServer: " + server_name_;
  out += "\r\nContent-Type: ";
  out += type;
  out += "\r\nContent-Length: " + std::to_string(body_bytes);
  out += "\r\nCache-Control: no-cache\r\nX-Content-Type-Options: nosniff\r\nConnection: close\r\n";
  out += extra_headers;
  out += "\r\n";
  return out;
}

HttpResponse StaticFiles::response(unsigned status, std::string_view reason, std::string_view type,
                                   std::string_view body, bool head,
                                   std::string_view extra_headers) const {
  HttpResponse out{head_of(status, reason, type, body.size(), extra_headers)};
  if (!head) out.head += body;
  return out;
}

HttpResponse StaticFiles::answer(const http::request<http::string_body>& request) const {
  constexpr std::string_view text = "text/plain; charset=utf-8";
  const bool head = request.method() == http::verb::head;
  if (request.method() != http::verb::get && !head)
    return response(405, "Method Not Allowed", text, "405 method not allowed: GET or HEAD only\n",
                    false, "Allow: GET, HEAD\r\n");
  const std::string_view target(request.target().data(), request.target().size());
  if (target.size() > k_max_target_bytes)
    return response(414, "URI Too Long", text, "414 request target too long\n", head);
  bool bad_request = false;
  const std::optional<std::string> relative = relative_path(target, bad_request);
  if (bad_request) return response(400, "Bad Request", text, "400 bad request target\n", head);
  const auto not_found = [&] { return response(404, "Not Found", text, "404 not found\n", head); };
  if (!relative) return not_found();

  // the file, once symbolic links are resolved, must still be under the root
  std::error_code ec;
  const fs::path root = fs::canonical(root_, ec);
  if (ec || !fs::is_directory(root, ec)) {
    // no web app (not built, not installed, or turned off): say what the port is
    return response(404, "Not Found", text,
                    not_found_text_ + "the web app is not here: no directory " + root_.string() +
                        " (web_root)\n",
                    head);
  }
  const fs::path file = fs::weakly_canonical(root / *relative, ec);
  if (ec) return not_found();
  const fs::path inside = file.lexically_relative(root);
  if (inside.empty() || *inside.begin() == ".." || inside.is_absolute()) return not_found();
  if (!fs::is_regular_file(file, ec)) return not_found();
  const auto size = fs::file_size(file, ec);
  if (ec) return not_found();
  if (size > k_max_file_bytes)
    return response(403, "Forbidden", text,
                    "403 file larger than the web server's limit (" +
                        std::to_string(k_max_file_bytes) + " bytes)\n",
                    head);

  const auto mtime = fs::last_write_time(file, ec);
  if (ec) return not_found();

  // validators: 304 when the client has this version
  const std::string etag = etag_of(size, mtime);
  const std::string last_modified = http_date(epoch_s(mtime));
  const std::string validators = "ETag: " + etag + "\r\nLast-Modified: " + last_modified + "\r\n";
  if (const auto inm = request.find(http::field::if_none_match); inm != request.end()) {
    if (none_match_names(std::string_view(inm->value().data(), inm->value().size()), etag))
      return not_modified(validators);
  } else if (const auto ims = request.find(http::field::if_modified_since); ims != request.end()) {
    const auto since = parse_http_date(std::string_view(ims->value().data(), ims->value().size()));
    if (since && epoch_s(mtime) <= *since) return not_modified(validators);
  }

  // the contents, from memory when unchanged since they were read; unreadable = missing
  bool cached = false;
  std::shared_ptr<const std::string> body = contents(file, mtime, size, cached);
  if (!body) return not_found();
  HttpResponse out{
      head_of(200, "OK", content_type(file.filename().string()), body->size(), validators)};
  if (!head) {
    out.body = std::move(body);
    out.body_cached = cached;
  }
  return out;
}

HttpResponse StaticFiles::not_modified(std::string_view validators) const {
  std::string out = "HTTP/1.1 304 Not Modified\r\nServer: " + server_name_;
  out += "\r\nCache-Control: no-cache\r\nConnection: close\r\n";
  out += validators;
  out += "\r\n";
  return HttpResponse{std::move(out)};
}

}  // namespace simgate::websocket
