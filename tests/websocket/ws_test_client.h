// tests/websocket/ws_test_client.h — a small blocking WebSocket client (Boost.Beast, client
// side) for the websocket transport's tests: connect and upgrade, send text or binary
// messages, receive the next message within a deadline (SO_RCVTIMEO: a reply that never
// comes fails the test instead of hanging it); the plugin's path and the frame opcodes the
// tests that write frames by hand use.
#ifndef SIMGATE_TESTS_WEBSOCKET_WS_TEST_CLIENT_H_
#define SIMGATE_TESTS_WEBSOCKET_WS_TEST_CLIENT_H_

#include <sys/socket.h>
#include <sys/time.h>

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>  // before Asio: Boost 1.74 needs std::exchange in C++20 mode

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/buffers_to_string.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/websocket.hpp>

#include "simgate/core/status.h"

namespace simgate::websocket_test {

// The websocket transport plugin of this build.
inline std::string plugin_path() {
  return std::string(SIMGATE_TEST_PLUGIN_DIR) + "/libsimgate_transport_websocket.so";
}

// RFC 6455 opcodes, for the tests that write frames by hand
constexpr std::uint8_t k_text = 0x1, k_binary = 0x2, k_close = 0x8, k_ping = 0x9, k_pong = 0xA;

class WsClient {
 public:
  // Connects to 127.0.0.1:`port` and upgrades; throws boost::system::system_error.
  // `receive_buffer` (bytes, 0: the system's) is set before connecting: the window it offers.
  // `origin` (non-empty): the Origin header a browser would send with the upgrade; `target`:
  // the request's ("/?token=...").
  explicit WsClient(std::uint16_t port,
                    std::chrono::milliseconds timeout = std::chrono::milliseconds(10000),
                    int receive_buffer = 0, const std::string& origin = "",
                    const std::string& target = "/")
      : ws_(io_) {
    boost::asio::ip::tcp::endpoint endpoint(boost::asio::ip::make_address("127.0.0.1"), port);
    if (receive_buffer > 0) {
      ws_.next_layer().open(boost::asio::ip::tcp::v4());
      ws_.next_layer().set_option(boost::asio::socket_base::receive_buffer_size(receive_buffer));
    }
    ws_.next_layer().connect(endpoint);
    ws_.next_layer().set_option(boost::asio::ip::tcp::no_delay(true));
    timeval tv{};
    tv.tv_sec = static_cast<time_t>(timeout.count() / 1000);
    tv.tv_usec = static_cast<suseconds_t>((timeout.count() % 1000) * 1000);
    ::setsockopt(ws_.next_layer().native_handle(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    ws_.read_message_max(0);
    if (!origin.empty())
      ws_.set_option(boost::beast::websocket::stream_base::decorator(
          [origin](boost::beast::websocket::request_type& request) {
            request.set("Origin", origin);
          }));
    ws_.handshake("127.0.0.1:" + std::to_string(port), target);
  }

  // One text message.
  void send(const std::string& text) {
    ws_.text(true);
    ws_.write(boost::asio::buffer(text));
  }
  void send(const json& message) { send(message.dump()); }
  // One binary message.
  void send_binary(const std::string& bytes) {
    ws_.binary(true);
    ws_.write(boost::asio::buffer(bytes));
  }
  // The next message as text; nullopt on timeout, close or error (`error` says which).
  std::optional<std::string> receive_text() {
    boost::beast::flat_buffer buffer;
    boost::system::error_code ec;
    ws_.read(buffer, ec);
    if (ec) {
      error = ec;
      return std::nullopt;
    }
    return boost::beast::buffers_to_string(buffer.data());
  }
  // The next message parsed; null on timeout, close or error.
  json receive() {
    auto text = receive_text();
    if (!text) return json();
    return json::parse(*text);
  }
  // A call and its response (the next message).
  json call(const json& request) {
    send(request);
    return receive();
  }
  // A ping frame (its pong is read, and dropped, by the next receive()).
  void ping() { ws_.ping({}); }
  // The close frame's code and reason, once receive() ended on it.
  boost::beast::websocket::close_reason close_reason() const { return ws_.reason(); }
  // Closes the TCP connection without a close frame (a client vanishing).
  void vanish() {
    boost::system::error_code ignored;
    ws_.next_layer().close(ignored);
  }

  boost::system::error_code error;  // why the last receive failed

 private:
  boost::asio::io_context io_;
  boost::beast::websocket::stream<boost::asio::ip::tcp::socket> ws_;
};

}  // namespace simgate::websocket_test

#endif  // SIMGATE_TESTS_WEBSOCKET_WS_TEST_CLIENT_H_
