#include "static_files.h"

#include <dlfcn.h>

#include <array>
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
      throw ConfigError("web_root: expected a directory (the web app's files), found '" + o.root + "': " +
                        (fs::exists(o.root, ec) ? "not a directory" : "no such directory"));
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

StaticFiles::StaticFiles(const std::string& root, std::string server_name, std::string not_found_text)
    : root_(root), server_name_(std::move(server_name)), not_found_text_(std::move(not_found_text)) {}

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

std::string StaticFiles::response(unsigned status, std::string_view reason, std::string_view type,
                                  std::string_view body, bool head, std::string_view extra_headers) const {
  std::string out;
  out.reserve(256 + (head ? 0 : body.size()));
  out += "HTTP/1.1 " + std::to_string(status) + " ";
  out += reason;
  out += "\r\nServer: " + server_name_;
  out += "\r\nContent-Type: ";
  out += type;
  out += "\r\nContent-Length: " + std::to_string(body.size());
  out += "\r\nCache-Control: no-cache\r\nX-Content-Type-Options: nosniff\r\nConnection: close\r\n";
  out += extra_headers;
  out += "\r\n";
  if (!head) out += body;
  return out;
}

std::string StaticFiles::answer(const http::request<http::string_body>& request) const {
  constexpr std::string_view text = "text/plain; charset=utf-8";
  const bool head = request.method() == http::verb::head;
  if (request.method() != http::verb::get && !head)
    return response(405, "Method Not Allowed", text, "405 method not allowed: GET or HEAD only\n", false,
                    "Allow: GET, HEAD\r\n");
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
                    not_found_text_ + "the web app is not here: no directory " + root_.string() + " (web_root)\n",
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
                    "403 file larger than the web server's limit (" + std::to_string(k_max_file_bytes) + " bytes)\n",
                    head);

  // read whole (the files are small); a file that cannot be read is missing
  std::string body;
  std::ifstream in(file, std::ios::binary);
  if (!in) return not_found();
  body.resize(size);
  if (size > 0 && !in.read(body.data(), static_cast<std::streamsize>(size))) return not_found();
  return response(200, "OK", content_type(file.filename().string()), body, head);
}

}  // namespace simgate::websocket
