// simgate/kit/tcp_server.h — what every TCP transport of simgate does the same way: the
// options it shares with the others, its listening socket, its I/O thread.
//
//   TcpOptions  the knobs every TCP transport has, under one name each (host, port,
//               max_connections, max_message_bytes, max_unsent_bytes, max_in_flight,
//               io_spin_us, on_disconnect, global_policy, idle_timeout_s, idle_evict_s,
//               line_timeout_s, max_buffered_bytes, max_connections_per_peer, auth,
//               progress_interval_ms);
//               renamed keys stay accepted for a release with a warning.
//   TcpListener binds at construction (a port in use fails there, with a hint naming the
//               tool that finds who holds it); accepts on the I/O thread, backs off 100 ms
//               after accept() fails (out of file descriptors) instead of spinning, and tells
//               a connection it refuses (over max_connections or max_connections_per_peer)
//               why in one line of the transport's protocol before closing it (logged once
//               until a connection is accepted again).
//   IoThread    the transport's one I/O thread: names itself to the core as the thread
//               outcomes are delivered on (RequestManager::deliver_on_this_thread), runs the
//               io_context with the idle-spin rule (idle_spin.h), keeps serving when a handler
//               throws, and stops idempotently.
//
// A transport built on the kit supplies its protocol (parse a line into calls, format an
// outcome) and its sessions; docs/writing-a-transport.md shows one in full.
#ifndef SIMGATE_KIT_TCP_SERVER_H_
#define SIMGATE_KIT_TCP_SERVER_H_

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <thread>
#include <utility>  // before Asio: Boost 1.74 needs std::exchange in C++20 mode
#include <vector>

#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>

#include "simgate/core/config.h"
#include "simgate/core/request_manager.h"
#include "simgate/kit/auth.h"

namespace simgate::kit {

// The options every TCP transport shares, parsed. Each transport gives its defaults and reads
// its own keys besides (TcpOptions::read leaves `config` open for them).
struct TcpOptions {
  std::string host = "127.0.0.1";                     // ("host") address or name to listen on
  std::uint16_t port = 0;                             // ("port") 0: any free port
  std::size_t max_connections = 1024;                 // ("max_connections") more are refused
  std::size_t max_message_bytes = 1 << 20;            // ("max_message_bytes") one request line
  std::size_t max_unsent_bytes = 8 << 20;             // ("max_unsent_bytes") per connection
  std::size_t max_in_flight = 1024;                   // ("max_in_flight") per connection
  std::chrono::microseconds io_spin{50};              // ("io_spin_us") idle_spin.h
  bool cancel_on_disconnect = true;                   // ("on_disconnect": "cancel" | "let_run")
  GlobalPolicy global_policy = GlobalPolicy::reject;  // ("global_policy": "reject" | "preempt")
  // Connections that hold resources without using them (connection.h, ConnectionServer):
  // ("idle_timeout_s") close a connection idle this long; 0: never
  std::chrono::milliseconds idle_timeout{0};
  // ("idle_evict_s") at max_connections, the connection idle longest makes room if idle
  // this long; 0: never
  std::chrono::milliseconds idle_evict{60000};
  // ("line_timeout_s") a line begun must end within this; 0: never
  std::chrono::milliseconds line_timeout{60000};
  // ("max_buffered_bytes") unfinished lines and unsent replies of all connections together
  std::size_t max_buffered_bytes = std::size_t{256} << 20;
  // ("max_connections_per_peer") open connections from one non-loopback address; 0: no
  // limit. Loopback peers are the machine's own programs (all one address): not counted.
  std::size_t max_connections_per_peer = 64;
  TokenAuth auth;  // ("auth") off unless given (auth.h)
  // ("progress_interval_ms") the shortest time between two progress reports of one call
  // (RequestManager::set_progress_interval), for the transports that carry them
  std::chrono::milliseconds progress_interval{50};

  // Each knob's key as the options spell it (a deprecated alias when that was used): for
  // messages that name the option to change.
  const char* connections_key = "max_connections";
  const char* message_bytes_key = "max_message_bytes";
  const char* unsent_bytes_key = "max_unsent_bytes";
  const char* in_flight_key = "max_in_flight";
  // One warning per deprecated key used, or token file others may read; the transport logs
  // them when it is created (not when its options are only validated).
  std::vector<std::string> warnings;

  // A knob renamed: `old_key` is still accepted, with a warning, for one release.
  struct Alias {
    const char* key;      // the name to use
    const char* old_key;  // the deprecated name
  };

  // Reads the shared keys of `config` over `defaults`; `transport` names the transport in
  // warnings. Throws ConfigError (a key set under both its names is one). The caller reads
  // its own keys, then calls finish().
  static TcpOptions read(ConfigObject& config, const TcpOptions& defaults,
                         std::string_view transport, std::span<const Alias> aliases = {});
  // config.finish() (unknown keys), then: the host must be an address or a name that
  // resolves. Throws ConfigError.
  void finish(const ConfigObject& config) const;
};

// The address to listen on for `host` ("localhost" is 127.0.0.1): a literal, or the first
// address the name resolves to. Throws ConfigError naming "host".
boost::asio::ip::tcp::endpoint listen_endpoint(const std::string& host, std::uint16_t port);

// "127.0.0.1:4000" or "[::1]:4000".
std::string to_string(const boost::asio::ip::tcp::endpoint& endpoint);

// A listening socket and its accept loop (the I/O thread only, after construction).
class TcpListener {
 public:
  // Binds host:port now. `who` starts every message ("Socket service manager"). Throws
  // std::runtime_error when it cannot listen: "<who>: cannot listen on 127.0.0.1:4000:
  // bind failed: Address already in use (another program listens there: ...)".
  TcpListener(boost::asio::io_context& io, std::string who, const std::string& host,
              std::uint16_t port);

  std::uint16_t port() const { return port_; }
  // "tcp://127.0.0.1:4000", with the bound port
  const std::string& endpoint() const { return endpoint_; }

  // What the listener does with connections (called on the I/O thread).
  struct Handlers {
    // A new connection (TCP_NODELAY set) to serve.
    std::function<void(boost::asio::ip::tcp::socket)> accepted;
    // Why a connection from `peer` is refused ("" to accept it), for the log and the client:
    // "too many connections (max_connections 1024)" (ConnectionServer::refusal_reason).
    std::function<std::string(const boost::asio::ip::tcp::endpoint& peer)> refuse;
    // The one line (with its '\n') a refused connection is sent before it is closed.
    std::function<std::string(const std::string& why)> refusal;
  };
  // Accepts until close(). Post it to the I/O thread, or call it before that thread runs.
  void start(Handlers handlers);
  // Stops accepting (the I/O thread, or once it has ended). Idempotent.
  void close();

 private:
  void accept_next();
  void refuse(boost::asio::ip::tcp::socket socket, const boost::asio::ip::tcp::endpoint& peer,
              const std::string& why);

  std::string who_;                          // the transport, for messages
  boost::asio::ip::tcp::acceptor acceptor_;  // bound in the constructor
  boost::asio::steady_timer retry_;          // the back-off after accept() fails
  std::uint16_t port_ = 0;                   // the bound port
  std::string endpoint_;                     // "tcp://127.0.0.1:4000"
  Handlers handlers_;                        // from start()
  bool refusing_ = false;                    // refused one since the last accepted (I/O thread)
};

// A transport's I/O thread: runs `io` with the idle-spin rule until stop().
class IoThread {
 public:
  // `who` names the transport in logs; `spin`: idle_spin.h (0: sleep in epoll at once).
  IoThread(boost::asio::io_context& io, std::string who, std::chrono::microseconds spin);
  ~IoThread();
  IoThread(const IoThread&) = delete;
  IoThread& operator=(const IoThread&) = delete;

  // Starts the thread: it first runs `on_start` (the transport names it the delivery thread
  // there: deliver_on_this_thread), then the loop, calling `direct` as run_with_idle_spin's
  // direct-read argument (NoDirectReads when the transport reads nothing itself). Once;
  // false when it had already started or stopped.
  template <class Direct>
  bool start(std::function<void()> on_start, Direct& direct) {
    return launch(std::move(on_start), [this, &direct] { run_loop(direct); });
  }
  // Runs `close` on the I/O thread (to close the sessions), lets the loop end, joins, and
  // stops the io_context (handlers posted later are dropped). Without a thread, runs
  // `close` here. Idempotent: false when it had already stopped.
  bool stop(const std::function<void()>& close);

 private:
  bool launch(std::function<void()> on_start, std::function<void()> loop);
  template <class Direct>
  void run_loop(Direct& direct);
  void log_handler_error(const char* what) const;

  boost::asio::io_context& io_;  // the transport's
  boost::asio::executor_work_guard<boost::asio::io_context::executor_type>
      work_;         // keeps run() going
  std::string who_;  // for logs
  std::chrono::microseconds spin_;
  std::thread thread_;
  std::mutex life_mutex_;  // serialises start() and stop()
  bool started_ = false;
  bool stopped_ = false;
};

}  // namespace simgate::kit

#include "simgate/kit/idle_spin.h"

namespace simgate::kit {

template <class Direct>
void IoThread::run_loop(Direct& direct) {
  for (;;) {
    try {
      run_with_idle_spin(io_, spin_, direct);
      return;
    } catch (const std::exception& e) {
      // handlers catch their own errors; this last line of defence keeps the server up
      log_handler_error(e.what());
    }
  }
}

}  // namespace simgate::kit

#endif  // SIMGATE_KIT_TCP_SERVER_H_
