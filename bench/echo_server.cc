// echo_server.cc — the physical limit: a Boost.Asio line-echo server.
//
// Every byte a client sends comes back unchanged, one complete line at a time: each read
// takes what the socket holds, and every complete line in it is written back in a single
// write (an echo server "that writes all ready replies at once"). An incomplete trailing
// line waits for the next read. One I/O thread, like the socket and JSON-RPC transports,
// so the comparison isolates what simgate adds: parsing, the hand-off to the thread that
// calls process(), the service and the reply formatting.
//
// Waiting: with --spin-us 0 (the default) the I/O thread sleeps in epoll_wait between
// requests, as a plain Asio server does. With --spin-us N it runs the io_context with
// simgate's idle-spin rule (kit::run_with_idle_spin, simgate/kit/idle_spin.h: poll for N µs
// after each event before sleeping, while events come close together), the rule simgate's
// TCP transports run with (io_spin_us, default 50): the harness takes this polling echo as
// the limit, and the sleeping one as the "plain Asio server" peer. It does not read sockets
// directly (kit::DirectReads): that is the transports' own optimisation, not the waiting rule.
//
// Usage: simgate_bench_echo [--host 127.0.0.1] [--port 0] [--spin-us 0] [--max-seconds 600]
// Prints {"port": N} on stdout once listening; exits on SIGTERM/SIGINT or after
// --max-seconds (a bounded run).
#include <chrono>
#include <csignal>
#include <cstdint>
#include <iostream>
#include <memory>
#include <string>
#include <utility>  // before Asio: Boost 1.74 awaitable.hpp needs std::exchange

#include <boost/asio.hpp>

#include "bench_util.h"
#include "simgate/kit/idle_spin.h"

namespace asio = boost::asio;
using asio::ip::tcp;

namespace {

// One client connection: read, write back the complete lines, read again.
class EchoSession : public std::enable_shared_from_this<EchoSession> {
 public:
  explicit EchoSession(tcp::socket socket) : socket_(std::move(socket)) {}

  void start() { read(); }

 private:
  void read() {
    // room for what the kernel holds, after the incomplete line kept from last time
    if (buffer_.size() - kept_ < 4096) buffer_.resize(buffer_.size() * 2);
    socket_.async_read_some(
        asio::buffer(buffer_.data() + kept_, buffer_.size() - kept_),
        [self = shared_from_this()](boost::system::error_code ec, std::size_t n) {
          if (!ec) self->on_read(n);
        });
  }

  void on_read(std::size_t n) {
    // echo every complete line at once; keep the incomplete tail for the next read
    std::size_t filled = kept_ + n;
    std::size_t end = filled;
    while (end > 0 && buffer_[end - 1] != '\n') --end;
    if (end == 0) {
      kept_ = filled;
      read();
      return;
    }
    out_.assign(buffer_.data(), end);
    kept_ = filled - end;
    std::copy(buffer_.begin() + static_cast<std::ptrdiff_t>(end),
              buffer_.begin() + static_cast<std::ptrdiff_t>(filled), buffer_.begin());
    asio::async_write(socket_, asio::buffer(out_),
                      [self = shared_from_this()](boost::system::error_code ec, std::size_t) {
                        if (!ec) self->read();
                      });
  }

  tcp::socket socket_;                             // the client
  std::string buffer_ = std::string(65536, '\0');  // bytes read; [0, kept_) is an incomplete line
  std::size_t kept_ = 0;  // length of the incomplete line at the front of buffer_
  std::string out_;       // the lines being written back
};

// Accepts clients until the io_context stops.
void accept_next(tcp::acceptor& acceptor) {
  acceptor.async_accept([&acceptor](boost::system::error_code ec, tcp::socket socket) {
    if (ec) return;  // the acceptor was closed
    boost::system::error_code ignored;
    socket.set_option(tcp::no_delay(true), ignored);
    std::make_shared<EchoSession>(std::move(socket))->start();
    accept_next(acceptor);
  });
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "A Boost.Asio line-echo server: the limit (--spin-us 50) or a plain Asio server (--spin-us "
      "0); "
      "prints {\"port\": N} once listening.",
      "simgate_bench_echo"};
  std::string host = "127.0.0.1";
  std::uint16_t port = 0;
  double max_seconds = 600;
  int spin_us = 0;
  app.add_option("--host", host, "address to listen on")->capture_default_str();
  app.add_option("--port", port, "port to listen on (0 = any free port)")->capture_default_str();
  app.add_option("--spin-us", spin_us,
                 "poll this many µs after each event before sleeping (simgate's idle-spin rule, "
                 "as the transports' io_spin_us); 0 = sleep in epoll_wait (a plain Asio server)")
      ->capture_default_str()
      ->check(CLI::Range(0, 10000));
  app.add_option("--max-seconds", max_seconds, "exit after this long (a bounded run)")
      ->capture_default_str();
  if (auto code = simgate::bench::parse_command_line(app, argc, argv)) return *code;
  try {
    asio::io_context io;
    tcp::acceptor acceptor(io, tcp::endpoint(asio::ip::make_address(host), port));
    accept_next(acceptor);

    // stop on a signal or when the bounded run is over
    asio::signal_set signals(io, SIGINT, SIGTERM);
    signals.async_wait([&io](boost::system::error_code, int) { io.stop(); });
    asio::steady_timer limit(io, std::chrono::duration_cast<std::chrono::nanoseconds>(
                                     std::chrono::duration<double>(max_seconds)));
    limit.async_wait([&io](boost::system::error_code ec) {
      if (!ec) io.stop();
    });

    std::cout << simgate::bench::json{{"port", acceptor.local_endpoint().port()}}.dump()
              << std::endl;
    // returns when stopped (signal, --max-seconds), as io.run() does
    simgate::kit::run_with_idle_spin(io, std::chrono::microseconds(spin_us));
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "simgate_bench_echo: " << e.what() << "\n";
    return 1;
  }
}
