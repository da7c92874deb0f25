// The transport kit's TCP pieces (kit/src/tcp_server.cc): the shared options, the listener
// (bind errors, refusal over the connection limit) and the I/O thread.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <future>
#include <stdexcept>
#include <thread>

#include <boost/asio/connect.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/read_until.hpp>
#include <boost/asio/streambuf.hpp>

#include "simgate/core/errors.h"
#include "simgate/kit/tcp_server.h"

namespace simgate::kit {
namespace {

namespace asio = boost::asio;
using asio::ip::tcp;
using ::testing::HasSubstr;

TcpOptions read_options(const json& options, std::span<const TcpOptions::Alias> aliases = {}) {
  ConfigObject config(options, "");
  TcpOptions defaults;
  defaults.port = 4000;
  TcpOptions o = TcpOptions::read(config, defaults, "test", aliases);
  o.finish(config);
  return o;
}

std::string config_error(const json& options, std::span<const TcpOptions::Alias> aliases = {}) {
  try {
    read_options(options, aliases);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "accepted";
}

TEST(TcpOptionsTest, DefaultsComeFromTheTransport) {
  const TcpOptions o = read_options(json::object());
  EXPECT_EQ(o.host, "127.0.0.1");
  EXPECT_EQ(o.port, 4000);
  EXPECT_TRUE(o.cancel_on_disconnect);
  EXPECT_EQ(o.global_policy, GlobalPolicy::reject);
}

TEST(TcpOptionsTest, EverySharedKeyIsRead) {
  const TcpOptions o = read_options({{"host", "::1"},
                                     {"port", 0},
                                     {"max_connections", 3},
                                     {"max_message_bytes", 100},
                                     {"max_unsent_bytes", 2048},
                                     {"max_in_flight", 5},
                                     {"io_spin_us", 0},
                                     {"on_disconnect", "let_run"},
                                     {"global_policy", "preempt"}});
  EXPECT_EQ(o.host, "::1");
  EXPECT_EQ(o.max_connections, 3u);
  EXPECT_EQ(o.max_message_bytes, 100u);
  EXPECT_EQ(o.max_unsent_bytes, 2048u);
  EXPECT_EQ(o.max_in_flight, 5u);
  EXPECT_EQ(o.io_spin.count(), 0);
  EXPECT_FALSE(o.cancel_on_disconnect);
  EXPECT_EQ(o.global_policy, GlobalPolicy::preempt);
}

TEST(TcpOptionsTest, BadValuesNameTheirKey) {
  EXPECT_THAT(config_error({{"port", 70000}}), HasSubstr("port"));
  EXPECT_THAT(config_error({{"max_in_flight", 0}}), HasSubstr("max_in_flight"));
  EXPECT_THAT(config_error({{"on_disconnect", "explode"}}), HasSubstr("on_disconnect"));
  EXPECT_THAT(config_error({{"host", "not an address"}}), HasSubstr("host"));
  EXPECT_THAT(config_error({{"prot", 1}}), HasSubstr("prot"));  // finish(): unknown keys
  // a resolver would read "" as some address of this machine (::1 here): refused
  EXPECT_THAT(config_error({{"host", ""}}), HasSubstr("host: expected an address or a name"));
  EXPECT_THAT(config_error({{"max_connections_per_peer", -1}}),
              HasSubstr("max_connections_per_peer"));
}

TEST(TcpOptionsTest, ThePerPeerLimitAndAuthAreShared) {
  const TcpOptions defaults = read_options(json::object());
  EXPECT_EQ(defaults.max_connections_per_peer, 64u);
  EXPECT_FALSE(defaults.auth.enabled);
  EXPECT_EQ(read_options({{"max_connections_per_peer", 0}}).max_connections_per_peer, 0u);
  EXPECT_THAT(config_error({{"auth", {{"token", "0123456789abcdef"}}}}),
              HasSubstr("auth.token: a token is never"));
}

constexpr TcpOptions::Alias k_aliases[] = {{"max_connections", "max_clients"}};

TEST(TcpOptionsTest, ADeprecatedNameWorksWithAWarningAndBothNamesAreRefused) {
  const TcpOptions o = read_options({{"max_clients", 7}}, k_aliases);
  EXPECT_EQ(o.max_connections, 7u);
  EXPECT_STREQ(o.connections_key, "max_clients");
  ASSERT_EQ(o.warnings.size(), 1u);
  EXPECT_THAT(o.warnings[0], HasSubstr("'max_clients' is deprecated, use 'max_connections'"));
  EXPECT_THAT(config_error({{"max_clients", 7}, {"max_connections", 8}}, k_aliases),
              HasSubstr("keep only"));
}

TEST(TcpListenerTest, APortInUseIsAClearErrorWithAHint) {
  asio::io_context io;
  TcpListener first(io, "Test service manager", "127.0.0.1", 0);
  try {
    TcpListener second(io, "Test service manager", "127.0.0.1", first.port());
    FAIL() << "bound a port in use";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("Test service manager: cannot listen on 127.0.0.1:" +
                                    std::to_string(first.port())));
    EXPECT_THAT(e.what(), HasSubstr("in use"));
    EXPECT_THAT(e.what(), HasSubstr("ss -ltnp"));
  }
  EXPECT_EQ(first.endpoint(), "tcp://127.0.0.1:" + std::to_string(first.port()));
}

// A server of at most one connection that echoes nothing: enough to see accept and refusal.
struct OneConnectionServer {
  asio::io_context io;
  TcpListener listener{io, "Test service manager", "127.0.0.1", 0};
  std::vector<tcp::socket> accepted;
  std::thread thread;

  OneConnectionServer() {
    listener.start({[this](tcp::socket s) { accepted.push_back(std::move(s)); },
                    [this](const tcp::endpoint&) {
                      return accepted.size() >= 1
                                 ? std::string("too many connections (max_connections 1)")
                                 : std::string();
                    },
                    [](const std::string& why) { return "refused: " + why + "\n"; }});
    thread = std::thread([this] { io.run(); });
  }
  ~OneConnectionServer() {
    asio::post(io, [this] {
      listener.close();
      accepted.clear();
    });
    thread.join();
  }
};

TEST(TcpListenerTest, AConnectionOverTheLimitIsToldWhyAndClosed) {
  OneConnectionServer server;
  asio::io_context io;
  tcp::socket first(io), second(io);
  first.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), server.listener.port()));
  second.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), server.listener.port()));
  // the second is refused (the first may still be on its way to accepted: then the first
  // is, and the second served; either way exactly one refusal line arrives, then EOF)
  asio::streambuf buffer;
  boost::system::error_code ec;
  asio::read_until(second, buffer, '\n', ec);
  std::string line(asio::buffers_begin(buffer.data()), asio::buffers_end(buffer.data()));
  if (line.empty()) {
    asio::read_until(first, buffer, '\n', ec);
    line.assign(asio::buffers_begin(buffer.data()), asio::buffers_end(buffer.data()));
  }
  EXPECT_EQ(line, "refused: too many connections (max_connections 1)\n");
}

TEST(IoThreadTest, RunsOnStartOnItsThreadKeepsServingWhenAHandlerThrowsAndStopsOnce) {
  asio::io_context io;
  IoThread thread(io, "Test service manager", std::chrono::microseconds(0));
  NoDirectReads direct;
  std::promise<std::thread::id> started;
  ASSERT_TRUE(thread.start([&] { started.set_value(std::this_thread::get_id()); }, direct));
  EXPECT_FALSE(thread.start([] {}, direct));  // once
  EXPECT_NE(started.get_future().get(), std::this_thread::get_id());

  asio::post(io, [] { throw std::runtime_error("a handler's bug"); });
  std::promise<void> served;
  asio::post(io, [&] { served.set_value(); });
  served.get_future().get();  // the loop went on

  std::atomic<int> closes{0};
  EXPECT_TRUE(thread.stop([&] { ++closes; }));
  EXPECT_FALSE(thread.stop([&] { ++closes; }));
  EXPECT_EQ(closes.load(), 1);
}

}  // namespace
}  // namespace simgate::kit
