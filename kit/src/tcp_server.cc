#include "simgate/kit/tcp_server.h"

#include <boost/asio/post.hpp>

#include "simgate/core/errors.h"
#include "simgate/core/log.h"

namespace simgate::kit {

namespace asio = boost::asio;
using asio::ip::tcp;
using boost::system::error_code;

namespace {

// How long accepting pauses after accept() failed (out of file descriptors, say).
constexpr std::chrono::milliseconds k_accept_retry{100};

// The key `config` spells a knob with: the old one only if the new one is absent (noted in
// `warnings`). Both at once is a ConfigError.
const char* spelling(const ConfigObject& config, const char* key,
                     std::span<const TcpOptions::Alias> aliases, std::string_view transport,
                     std::vector<std::string>& warnings) {
  for (const auto& alias : aliases) {
    if (std::string_view(alias.key) != key || !config.has(alias.old_key)) continue;
    if (config.has(alias.key))
      throw ConfigError(std::string(alias.old_key) + ": the deprecated name of '" + alias.key +
                        "', which is set too; keep only '" + alias.key + "'");
    warnings.push_back(std::string(transport) + ": option '" + alias.old_key +
                       "' is deprecated, use '" + alias.key +
                       "' (the old name goes in the next release)");
    return alias.old_key;
  }
  return key;
}

std::size_t get_size(ConfigObject& config, const char* key, std::size_t fallback, long long min,
                     long long max) {
  return static_cast<std::size_t>(config.get_int(key, static_cast<long long>(fallback), min, max));
}

}  // namespace

// ---- options

TcpOptions TcpOptions::read(ConfigObject& config, const TcpOptions& defaults,
                            std::string_view transport, std::span<const Alias> aliases) {
  TcpOptions o = defaults;
  o.warnings.clear();
  auto key = [&](const char* name) {
    return spelling(config, name, aliases, transport, o.warnings);
  };
  o.host = config.get_string("host", o.host);
  // a resolver reads "" as "this machine" and picks an address of its choosing
  if (o.host.empty())
    config.fail("host",
                "an address or a name (\"127.0.0.1\": this machine only, \"0.0.0.0\": every "
                "interface), not \"\"");
  o.port = static_cast<std::uint16_t>(config.get_int("port", o.port, 0, 65535));
  o.connections_key = key("max_connections");
  o.max_connections = get_size(config, o.connections_key, o.max_connections, 1, 1 << 20);
  o.message_bytes_key = key("max_message_bytes");
  o.max_message_bytes = get_size(config, o.message_bytes_key, o.max_message_bytes, 64, 1LL << 30);
  o.unsent_bytes_key = key("max_unsent_bytes");
  o.max_unsent_bytes = get_size(config, o.unsent_bytes_key, o.max_unsent_bytes, 1024, 1LL << 34);
  o.in_flight_key = key("max_in_flight");
  o.max_in_flight = get_size(config, o.in_flight_key, o.max_in_flight, 1, 1 << 20);
  o.io_spin = std::chrono::microseconds(config.get_int("io_spin_us", o.io_spin.count(), 0, 10000));
  o.cancel_on_disconnect =
      config.get_choice("on_disconnect", o.cancel_on_disconnect ? "cancel" : "let_run",
                        {"cancel", "let_run"}) == "cancel";
  o.global_policy =
      config.get_choice("global_policy",
                        o.global_policy == GlobalPolicy::preempt ? "preempt" : "reject",
                        {"reject", "preempt"}) == "preempt"
          ? GlobalPolicy::preempt
          : GlobalPolicy::reject;
  auto seconds = [&](const char* name, std::chrono::milliseconds fallback) {
    const double s =
        config.get_number(name, static_cast<double>(fallback.count()) / 1000.0, 0.0, 86400.0 * 7);
    return std::chrono::milliseconds(static_cast<std::int64_t>(s * 1000.0 + 0.5));
  };
  o.idle_timeout = seconds("idle_timeout_s", o.idle_timeout);
  o.idle_evict = seconds("idle_evict_s", o.idle_evict);
  o.line_timeout = seconds("line_timeout_s", o.line_timeout);
  o.max_buffered_bytes =
      get_size(config, "max_buffered_bytes", o.max_buffered_bytes, 1 << 16, 1LL << 40);
  o.max_connections_per_peer =
      get_size(config, "max_connections_per_peer", o.max_connections_per_peer, 0, 1 << 20);
  o.auth = TokenAuth::read(config, o.warnings);
  o.progress_interval = std::chrono::milliseconds(
      config.get_int("progress_interval_ms", o.progress_interval.count(), 0, 3600 * 1000));
  return o;
}

void TcpOptions::finish(const ConfigObject& config) const {
  config.finish();
  (void)listen_endpoint(host, port);  // a host that does not resolve is a config error
}

tcp::endpoint listen_endpoint(const std::string& host, std::uint16_t port) {
  error_code ec;
  auto address = asio::ip::make_address(host == "localhost" ? "127.0.0.1" : host, ec);
  if (!ec) return tcp::endpoint(address, port);
  asio::io_context io;
  tcp::resolver resolver(io);
  auto results = resolver.resolve(host, std::to_string(port), ec);
  if (ec || results.empty())
    throw ConfigError("host: cannot resolve '" + host +
                      "' (an IP address such as \"127.0.0.1\" or \"::1\", or a name): " +
                      (ec ? ec.message() : std::string("no address")));
  return results.begin()->endpoint();
}

std::string to_string(const tcp::endpoint& endpoint) {
  const auto address = endpoint.address().to_string();
  return (endpoint.address().is_v6() ? "[" + address + "]" : address) + ":" +
         std::to_string(endpoint.port());
}

// ---- the listening socket

TcpListener::TcpListener(asio::io_context& io, std::string who, const std::string& host,
                         std::uint16_t port)
    : who_(std::move(who)), acceptor_(io), retry_(io) {
  const tcp::endpoint endpoint = listen_endpoint(host, port);
  auto fail = [&](const char* step, const error_code& ec) {
    std::string hint;
    if (ec == asio::error::address_in_use)
      hint = " (another program listens there: `ss -ltnp 'sport = :" + std::to_string(port) +
             "'` names it; stop it, or choose another 'port', 0 for any free one)";
    else if (ec == asio::error::access_denied)
      hint = " (ports below 1024 need privileges)";
    throw std::runtime_error(who_ + ": cannot listen on " + host + ":" + std::to_string(port) +
                             ": " + step + " failed: " + ec.message() + hint);
  };
  error_code ec;
  acceptor_.open(endpoint.protocol(), ec);
  if (ec) fail("open", ec);
  acceptor_.set_option(tcp::acceptor::reuse_address(true),
                       ec);  // TIME_WAIT only, not a live listener
  acceptor_.bind(endpoint, ec);
  if (ec) fail("bind", ec);
  acceptor_.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) fail("listen", ec);
  const auto bound = acceptor_.local_endpoint(ec);
  if (ec) fail("getsockname", ec);
  port_ = bound.port();
  endpoint_ = "tcp://" + to_string(bound);
}

void TcpListener::start(Handlers handlers) {
  handlers_ = std::move(handlers);
  accept_next();
}

void TcpListener::close() {
  error_code ignored;
  acceptor_.close(ignored);
  retry_.cancel();
}

void TcpListener::accept_next() {
  acceptor_.async_accept([this](const error_code& ec, tcp::socket socket) {
    if (ec == asio::error::operation_aborted || !acceptor_.is_open()) return;
    if (ec) {
      // e.g. out of file descriptors: back off instead of spinning
      log::warning(who_, ": accept failed: ", ec.message(), "; accepting again in ",
                   k_accept_retry.count(), " ms");
      retry_.expires_after(k_accept_retry);
      retry_.async_wait([this](const error_code& e) {
        if (!e && acceptor_.is_open()) accept_next();
      });
      return;
    }
    try {
      error_code peer_error;
      const tcp::endpoint peer = socket.remote_endpoint(peer_error);
      std::string why = peer_error ? std::string() : handlers_.refuse(peer);
      if (peer_error) {
        // gone before it was accepted: nothing to serve
        log::debug(who_, ": a connection left before it was accepted: ", peer_error.message());
      } else if (!why.empty()) {
        refuse(std::move(socket), peer, why);
      } else {
        refusing_ = false;
        error_code ignored;
        socket.set_option(tcp::no_delay(true), ignored);  // replies are small: no Nagle delay
        handlers_.accepted(std::move(socket));
      }
    } catch (const std::exception& e) {
      log::error(who_, ": accepting a connection: ", e.what());
    }
    accept_next();
  });
}

void TcpListener::refuse(tcp::socket socket, const tcp::endpoint& peer, const std::string& why) {
  // one warning until a connection is accepted again; the client is told why in its
  // protocol (one line, best effort, never blocking)
  error_code ignored;
  if (!refusing_)
    log::warning(who_, ": refused a connection from ", to_string(peer), ": ", why,
                 "; further refusals are logged at debug level until one is accepted");
  else
    log::debug(who_, ": refused a connection from ", to_string(peer), ": ", why);
  refusing_ = true;
  socket.non_blocking(true, ignored);
  const std::string line = handlers_.refusal(why);
  socket.write_some(asio::buffer(line), ignored);
  socket.close(ignored);
}

// ---- the I/O thread

IoThread::IoThread(asio::io_context& io, std::string who, std::chrono::microseconds spin)
    : io_(io), work_(asio::make_work_guard(io)), who_(std::move(who)), spin_(spin) {}

IoThread::~IoThread() {
  stop([] {});
}

bool IoThread::launch(std::function<void()> on_start, std::function<void()> loop) {
  std::lock_guard lock(life_mutex_);
  if (started_ || stopped_) return false;
  started_ = true;
  thread_ = std::thread([on_start = std::move(on_start), loop = std::move(loop)] {
    on_start();
    loop();
  });
  return true;
}

bool IoThread::stop(const std::function<void()>& close) {
  std::lock_guard lock(life_mutex_);
  if (stopped_) return false;
  stopped_ = true;
  if (thread_.joinable()) {
    // close everything on the I/O thread, then let run() return
    asio::post(io_, close);
    work_.reset();
    thread_.join();
  } else {
    close();
  }
  // handlers that never ran (outcomes posted after the close) are dropped here
  io_.stop();
  return true;
}

void IoThread::log_handler_error(const char* what) const {
  log::error(who_, ": I/O handler threw: ", what);
}

}  // namespace simgate::kit
