// The web app's files on the websocket transport's port (plugins/websocket/static_files.h):
// plain HTTP requests from a raw socket against libsimgate_transport_websocket.so serving a
// web root the test writes (index.html, a vendor script, a secret beside the root, a
// symbolic link out of it), the refusals (traversal, methods, long targets), the options,
// and the build tree's own web app as the default web_root (each of its ES modules as in the
// source tree); the in-memory cache (an edited file served fresh, a cached answer identical)
// and the validators (ETag, Last-Modified, 304); StaticFiles itself, compiled in: what its
// cache holds within its bound.
#include <gtest/gtest.h>

#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/read.hpp>
#include <boost/asio/write.hpp>

#include "simgate/core/plugin_loader.h"
#include "static_files.h"
#include "test_services.h"
#include "ws_test_client.h"

namespace simgate::websocket_test {
namespace {

namespace fs = std::filesystem;
using jsonrpc_test::TestHost;

// One HTTP exchange: `request` written whole, the answer read until the server closes.
std::string http_exchange(std::uint16_t port, const std::string& request) {
  boost::asio::io_context io;
  boost::asio::ip::tcp::socket socket(io);
  socket.connect({boost::asio::ip::make_address("127.0.0.1"), port});
  boost::asio::write(socket, boost::asio::buffer(request));
  std::string response;
  boost::system::error_code ec;
  char buffer[65536];
  for (int reads = 0; reads < 100000 && !ec;
       ++reads) {  // bounded; the server closes after its answer
    const std::size_t n = socket.read_some(boost::asio::buffer(buffer), ec);
    response.append(buffer, n);
  }
  return response;
}

std::string get(std::uint16_t port, const std::string& target, const std::string& method = "GET") {
  return http_exchange(port, method + " " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
}

int status_of(const std::string& response) {
  if (!response.starts_with("HTTP/1.1 ") || response.size() < 12) return 0;
  return std::atoi(response.substr(9, 3).c_str());
}

std::string header(const std::string& response, const std::string& name) {
  const std::string key = "\r\n" + name + ": ";
  const auto at = response.find(key);
  if (at == std::string::npos) return {};
  const auto start = at + key.size();
  return response.substr(start, response.find("\r\n", start) - start);
}

std::string body_of(const std::string& response) {
  const auto at = response.find("\r\n\r\n");
  return at == std::string::npos ? std::string() : response.substr(at + 4);
}

// A web root under a temporary directory, with a secret beside it.
class WebRoot {
 public:
  WebRoot() {
    std::string pattern = (fs::temp_directory_path() / "simgate-web-test-XXXXXX").string();
    if (!::mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed");
    dir_ = pattern;
    fs::create_directories(root() / "vendor");
    write(root() / "index.html", index_html);
    write(root() / "vendor" / "three.module.js", script);
    write(root() / "style.css", "body { margin: 0; }\n");
    write(dir_ / "secret.txt", secret);
    fs::create_symlink(dir_ / "secret.txt", root() / "escape.txt");
  }
  ~WebRoot() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  fs::path root() const { return dir_ / "web"; }
  fs::path dir() const { return dir_; }
  // Replaces `file`'s contents and moves its mtime `seconds` on (a file edited later).
  static void rewrite(const fs::path& file, const std::string& text, int seconds = 2) {
    const auto before = fs::last_write_time(file);
    write(file, text);
    fs::last_write_time(file, before + std::chrono::seconds(seconds));
  }

  static constexpr const char* index_html = "<!doctype html><title>simgate</title>\n";
  static constexpr const char* script = "export const REVISION = 'test';\n";
  static constexpr const char* secret = "the secret beside the web root\n";

  static void write(const fs::path& file, const std::string& text) { std::ofstream(file) << text; }
  fs::path dir_;
};

class WebSocketWebTest : public ::testing::Test {
 protected:
  void SetUp() override {
    host_ = std::make_unique<TestHost>(json{{"web_root", web_.root().string()}}, plugin_path());
  }
  std::uint16_t port() const { return host_->port(); }
  WebRoot web_;
  std::unique_ptr<TestHost> host_;
};

TEST_F(WebSocketWebTest, GetSlashServesIndexHtml) {
  const std::string r = get(port(), "/");
  EXPECT_EQ(status_of(r), 200) << r;
  EXPECT_EQ(header(r, "Content-Type"), "text/html; charset=utf-8") << r;
  EXPECT_EQ(header(r, "Cache-Control"), "no-cache") << r;
  EXPECT_EQ(header(r, "Content-Length"), std::to_string(std::string(WebRoot::index_html).size()))
      << r;
  EXPECT_EQ(body_of(r), WebRoot::index_html);
}

TEST_F(WebSocketWebTest, GetServesAScriptAsJavaScriptAndIgnoresTheQuery) {
  const std::string r = get(port(), "/vendor/three.module.js?v=1");
  EXPECT_EQ(status_of(r), 200) << r;
  EXPECT_EQ(header(r, "Content-Type"), "text/javascript; charset=utf-8") << r;
  EXPECT_EQ(body_of(r), WebRoot::script);
  EXPECT_EQ(header(get(port(), "/style.css"), "Content-Type"), "text/css; charset=utf-8");
}

TEST_F(WebSocketWebTest, HeadAnswersTheHeadersWithoutTheBody) {
  const std::string r = get(port(), "/index.html", "HEAD");
  EXPECT_EQ(status_of(r), 200) << r;
  EXPECT_EQ(header(r, "Content-Length"), std::to_string(std::string(WebRoot::index_html).size()))
      << r;
  EXPECT_EQ(body_of(r), "");
}

TEST_F(WebSocketWebTest, TraversalOutOfTheRootIsRefused) {
  for (const char* target :
       {"/../secret.txt", "/%2e%2e/secret.txt", "/%2E%2E%2Fsecret.txt", "/vendor/../../secret.txt",
        "/vendor/..%2f..%2fsecret.txt", "/..%5csecret.txt", "/.%2e/secret.txt", "//etc/passwd",
        "/index.html%00.png", "/./index.html", "/../etc/passwd"}) {
    const std::string r = get(port(), target);
    EXPECT_EQ(status_of(r), 404) << target << ": " << r;
    EXPECT_EQ(r.find("secret beside"), std::string::npos) << target << ": " << r;
  }
  // malformed escapes and a target that is no path
  for (const char* target : {"/%zz", "/%2", "*"})
    EXPECT_EQ(status_of(get(port(), target)), 400) << target;
}

TEST_F(WebSocketWebTest, ASymbolicLinkOutOfTheRootIsNotFollowed) {
  const std::string r = get(port(), "/escape.txt");
  EXPECT_EQ(status_of(r), 404) << r;
  EXPECT_EQ(r.find("secret beside"), std::string::npos) << r;
}

TEST_F(WebSocketWebTest, OnlyRegularFilesAreServed) {
  EXPECT_EQ(status_of(get(port(), "/no-such-file.js")), 404);
  EXPECT_EQ(status_of(get(port(), "/vendor")), 404);   // a directory
  EXPECT_EQ(status_of(get(port(), "/vendor/")), 404);  // a directory without index.html
}

TEST_F(WebSocketWebTest, MethodsOtherThanGetAndHeadAreNotAllowed) {
  const std::string r = http_exchange(
      port(), "POST /index.html HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 2\r\n\r\n{}");
  EXPECT_EQ(status_of(r), 405) << r;
  EXPECT_EQ(header(r, "Allow"), "GET, HEAD") << r;
  EXPECT_EQ(status_of(get(port(), "/", "DELETE")), 405);
}

TEST_F(WebSocketWebTest, ATooLongTargetIsRefused) {
  const std::string r = get(port(), "/" + std::string(3000, 'a'));
  EXPECT_EQ(status_of(r), 414) << r.substr(0, 200);
}

TEST_F(WebSocketWebTest, TheWebSocketUpgradeStillWorksBesideTheFiles) {
  WsClient client(port());
  const json r = client.call(
      json{{"jsonrpc", "2.0"}, {"id", 1}, {"method", "spec.subtract"}, {"params", {42, 23}}});
  EXPECT_EQ(r["result"], 19) << r.dump();
}

// ---- the cache and the validators (static_files.h: Validators, Cache)

std::string get_with(std::uint16_t port, const std::string& target, const std::string& headers) {
  return http_exchange(port,
                       "GET " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\n" + headers + "\r\n");
}

TEST_F(WebSocketWebTest, ACachedAnswerIsTheFirstOneByteForByte) {
  const std::string first = get(port(), "/vendor/three.module.js");
  ASSERT_EQ(status_of(first), 200) << first;
  for (int i = 0; i < 3; ++i) EXPECT_EQ(get(port(), "/vendor/three.module.js"), first);
  EXPECT_EQ(body_of(first), WebRoot::script);
  EXPECT_FALSE(header(first, "ETag").empty()) << first;
  EXPECT_FALSE(header(first, "Last-Modified").empty()) << first;
}

TEST_F(WebSocketWebTest, AChangedFileIsServedFresh) {
  const fs::path file = web_.root() / "vendor" / "three.module.js";
  const std::string first = get(port(), "/vendor/three.module.js");
  ASSERT_EQ(body_of(first), WebRoot::script);
  // same size, later mtime
  std::string same_size(WebRoot::script);
  same_size[same_size.size() - 3] = 'X';
  WebRoot::rewrite(file, same_size);
  const std::string second = get(port(), "/vendor/three.module.js");
  EXPECT_EQ(body_of(second), same_size);
  EXPECT_NE(header(second, "ETag"), header(first, "ETag"));
  // another size, the same mtime as before the edit
  WebRoot::rewrite(file, "export const REVISION = 'longer than before';\n", -2);
  EXPECT_EQ(body_of(get(port(), "/vendor/three.module.js")),
            "export const REVISION = 'longer than before';\n");
  // gone
  fs::remove(file);
  EXPECT_EQ(status_of(get(port(), "/vendor/three.module.js")), 404);
}

TEST_F(WebSocketWebTest, IfNoneMatchWithTheETagGets304WithoutABody) {
  const std::string first = get(port(), "/index.html");
  const std::string etag = header(first, "ETag");
  ASSERT_FALSE(etag.empty()) << first;
  const std::string r = get_with(port(), "/index.html", "If-None-Match: " + etag + "\r\n");
  EXPECT_EQ(status_of(r), 304) << r;
  EXPECT_EQ(body_of(r), "") << r;
  EXPECT_EQ(header(r, "ETag"), etag) << r;
  EXPECT_EQ(header(r, "Content-Length"), "") << r;
  EXPECT_EQ(
      status_of(get_with(port(), "/index.html", "If-None-Match: \"other\", W/" + etag + "\r\n")),
      304);
  EXPECT_EQ(status_of(get_with(port(), "/index.html", "If-None-Match: *\r\n")), 304);
  EXPECT_EQ(status_of(http_exchange(
                port(), "HEAD /index.html HTTP/1.1\r\nHost: 127.0.0.1\r\nIf-None-Match: " + etag +
                            "\r\n\r\n")),
            304);
  // another ETag, or the file changed since: the whole file
  EXPECT_EQ(status_of(get_with(port(), "/index.html", "If-None-Match: \"other\"\r\n")), 200);
  WebRoot::rewrite(web_.root() / "index.html", "<!doctype html><title>edited</title>\n");
  const std::string edited = get_with(port(), "/index.html", "If-None-Match: " + etag + "\r\n");
  EXPECT_EQ(status_of(edited), 200) << edited;
  EXPECT_EQ(body_of(edited), "<!doctype html><title>edited</title>\n");
}

TEST_F(WebSocketWebTest, IfModifiedSinceTheLastModificationGets304) {
  const std::string first = get(port(), "/style.css");
  const std::string last_modified = header(first, "Last-Modified");
  ASSERT_FALSE(last_modified.empty()) << first;
  const std::string r =
      get_with(port(), "/style.css", "If-Modified-Since: " + last_modified + "\r\n");
  EXPECT_EQ(status_of(r), 304) << r;
  EXPECT_EQ(body_of(r), "");
  // older, malformed, or overridden by a non-matching If-None-Match: the whole file
  EXPECT_EQ(status_of(get_with(port(), "/style.css",
                               "If-Modified-Since: Thu, 01 Jan 1970 00:00:00 GMT\r\n")),
            200);
  EXPECT_EQ(status_of(get_with(port(), "/style.css", "If-Modified-Since: yesterday\r\n")), 200);
  EXPECT_EQ(status_of(get_with(
                port(), "/style.css",
                "If-None-Match: \"other\"\r\nIf-Modified-Since: " + last_modified + "\r\n")),
            200);
  WebRoot::rewrite(web_.root() / "style.css", "body { margin: 1px; }\n");
  EXPECT_EQ(
      status_of(get_with(port(), "/style.css", "If-Modified-Since: " + last_modified + "\r\n")),
      200);
}

// StaticFiles alone (compiled into this test): what its cache holds
boost::beast::http::request<boost::beast::http::string_body> request_for(
    const std::string& target) {
  return {boost::beast::http::verb::get, target, 11};
}

TEST(StaticFilesCache, HoldsTheFilesServedWithinItsBoundLeastRecentlyUsedOut) {
  WebRoot web;
  const std::string big(600, 'b');
  WebRoot::write(web.root() / "a.txt", big);
  WebRoot::write(web.root() / "b.txt", big);
  WebRoot::write(web.root() / "huge.txt", std::string(1500, 'h'));
  websocket::StaticFiles files(web.root().string(), "test", "", 1000);
  EXPECT_EQ(files.cached_files(), 0u);
  EXPECT_EQ(body_of(files.answer(request_for("/a.txt")).text()), big);
  EXPECT_EQ(files.cached_files(), 1u);
  EXPECT_EQ(files.cached_bytes(), 600u);
  // b pushes a out (1200 > 1000)
  EXPECT_EQ(body_of(files.answer(request_for("/b.txt")).text()), big);
  EXPECT_EQ(files.cached_files(), 1u);
  EXPECT_EQ(files.cached_bytes(), 600u);
  // larger than the bound: served, never cached
  EXPECT_EQ(body_of(files.answer(request_for("/huge.txt")).text()), std::string(1500, 'h'));
  EXPECT_EQ(files.cached_bytes(), 600u);
  // a changed file replaces its old contents
  WebRoot::rewrite(web.root() / "b.txt", "short");
  EXPECT_EQ(body_of(files.answer(request_for("/b.txt")).text()), "short");
  EXPECT_EQ(files.cached_files(), 1u);
  EXPECT_EQ(files.cached_bytes(), 5u);
  EXPECT_EQ(body_of(files.answer(request_for("/index.html")).text()), WebRoot::index_html);
  EXPECT_EQ(files.cached_files(), 2u);
  // refusals and 304s cache nothing
  EXPECT_EQ(status_of(files.answer(request_for("/../secret.txt")).text()), 404);
  EXPECT_EQ(files.cached_files(), 2u);
}

// issue #35, item 6: every response carried its own copy of the file (40 clients that do not
// read a 30 MB file: 1.25 GB); a cached file is now shared, and only what a response owns
// counts against max_buffered_bytes
TEST(StaticFilesCache, ResponsesShareTheCachedContentsInsteadOfCopyingThem) {
  WebRoot web;
  WebRoot::write(web.root() / "big.bin", std::string(600, 'b'));
  WebRoot::write(web.root() / "huge.bin", std::string(1500, 'h'));
  websocket::StaticFiles files(web.root().string(), "test", "", 1000);
  const auto first = files.answer(request_for("/big.bin"));
  const auto second = files.answer(request_for("/big.bin"));
  ASSERT_TRUE(first.body && second.body);
  EXPECT_EQ(first.body.get(), second.body.get()) << "each response copied the file";
  EXPECT_TRUE(second.body_cached);
  EXPECT_EQ(second.own_bytes(), second.head.size());
  // a file larger than the cache is this response's own, and counted as such
  const auto huge = files.answer(request_for("/huge.bin"));
  ASSERT_TRUE(huge.body);
  EXPECT_FALSE(huge.body_cached);
  EXPECT_EQ(huge.own_bytes(), huge.head.size() + 1500);
}

TEST(StaticFilesCache, HttpDatesRoundTrip) {
  EXPECT_EQ(websocket::StaticFiles::http_date(784111777), "Sun, 06 Nov 1994 08:49:37 GMT");
  EXPECT_EQ(websocket::StaticFiles::parse_http_date("Sun, 06 Nov 1994 08:49:37 GMT"), 784111777);
  EXPECT_EQ(websocket::StaticFiles::parse_http_date("Sunday, 06-Nov-94 08:49:37 GMT"),
            std::nullopt);
  EXPECT_EQ(websocket::StaticFiles::parse_http_date("Sun, 06 Nov 1994 08:49:37 UTC"), std::nullopt);
  EXPECT_EQ(websocket::StaticFiles::parse_http_date("Sun, 06 Foo 1994 08:49:37 GMT"), std::nullopt);
}

TEST(WebSocketWebOptions, WebFalseAnswersEveryPlainRequestNotFound) {
  WebRoot web;
  TestHost host(json{{"web", false}, {"web_root", web.root().string()}}, plugin_path());
  const std::string r = get(host.port(), "/");
  EXPECT_EQ(status_of(r), 404) << r;
  EXPECT_NE(r.find("JSON-RPC 2.0 over WebSocket"), std::string::npos) << r;
}

TEST(WebSocketWebOptions, BadOptionsAreRefusedNamingTheKey) {
  try {
    load_transport(plugin_path(), json{{"port", 0}, {"web_root", "/no/such/simgate/web"}});
    FAIL() << "a web_root that is no directory was accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("web_root"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("/no/such/simgate/web"), std::string::npos) << e.what();
  }
  try {
    load_transport(plugin_path(), json{{"port", 0}, {"web", "yes"}});
    FAIL() << "web: \"yes\" was accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("web"), std::string::npos) << e.what();
  }
}

TEST(WebSocketWebOptions, TheDefaultWebRootIsTheBuildTreesWebApp) {
  if (!fs::exists(SIMGATE_BINARY_DIR "/web/index.html"))
    GTEST_SKIP() << "the web app is not built (" SIMGATE_BINARY_DIR
                    "/web, -DSIMGATE_WITH_WEB=OFF?)";
  TestHost host(json::object(), plugin_path());
  const std::string page = get(host.port(), "/");
  EXPECT_EQ(status_of(page), 200) << page.substr(0, 300);
  EXPECT_NE(page.find("<title>simgate</title>"), std::string::npos) << page.substr(0, 300);
  const std::string three = get(host.port(), "/vendor/three.module.js", "HEAD");
  EXPECT_EQ(status_of(three), 200) << three;
  EXPECT_EQ(header(three, "Content-Type"), "text/javascript; charset=utf-8") << three;
  // every ES module of the page's source (app.js and those it imports), served as it is there
  // (a module missing from web/CMakeLists.txt's app_files would fail the page's imports)
  int modules = 0;
  for (const auto& entry : fs::directory_iterator(SIMGATE_SOURCE_DIR "/web")) {
    if (entry.path().extension() != ".js") continue;
    ++modules;
    const std::string name = entry.path().filename().string();
    std::ifstream in(entry.path(), std::ios::binary);
    const std::string source{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    const std::string answer = get(host.port(), "/" + name);
    EXPECT_EQ(status_of(answer), 200) << name << ": " << answer.substr(0, 300);
    EXPECT_EQ(header(answer, "Content-Type"), "text/javascript; charset=utf-8") << name;
    EXPECT_EQ(body_of(answer), source) << name << " differs from the source tree's";
  }
  EXPECT_GE(modules, 2) << "app.js and the modules it imports, in " SIMGATE_SOURCE_DIR "/web";
}

}  // namespace
}  // namespace simgate::websocket_test
