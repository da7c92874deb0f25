// websocket_client.cc — a client of the websocket transport: JSON-RPC 2.0, one message per
// WebSocket text message (Boost.Beast, blocking). The Client interface only (one call at a
// time with a deadline: `simgate call`, `simgate list`); the responses are read as
// JsonRpcClient reads them (to_outcome, services_of): the protocol is the jsonrpc one.
//
// Deadlines: the socket's receive timeout (SO_RCVTIMEO) bounds each read; a read that times
// out leaves the WebSocket unusable, so the client is closed then (ClientError).
#include <sys/socket.h>
#include <sys/time.h>

#include <utility>  // before Asio: Boost 1.74 needs std::exchange in C++20 mode

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/websocket.hpp>

#include "simgate/client/client.h"
#include "simgate/client/jsonrpc_client.h"

namespace simgate::client {

namespace {

namespace asio = boost::asio;
namespace ws = boost::beast::websocket;
using Clock = std::chrono::steady_clock;

class WebSocketClient : public Client {
 public:
  WebSocketClient(const std::string& host, std::uint16_t port, std::chrono::milliseconds timeout)
      : peer_(host + ":" + std::to_string(port)), stream_(io_) {
    try {
      asio::ip::tcp::resolver resolver(io_);
      auto endpoints = resolver.resolve(host, std::to_string(port));
      set_timeout(timeout);
      asio::connect(stream_.next_layer(), endpoints);
      stream_.next_layer().set_option(asio::ip::tcp::no_delay(true));
      set_timeout(timeout);
      stream_.handshake(peer_, "/");
      stream_.text(true);
    } catch (const boost::system::system_error& e) {
      throw ClientError("websocket client: " + peer_ + ": " + e.what());
    }
  }

  Outcome call(const std::string& component, const std::string& service, const json& params,
               std::chrono::milliseconds timeout) override {
    return JsonRpcClient::to_outcome(request(component + "." + service, params, timeout));
  }

  json list_services(std::chrono::milliseconds timeout) override {
    json response = request("rpc.discover", nullptr, timeout);
    if (!response.contains("result"))
      throw ClientError("websocket client: " + peer_ + ": rpc.discover failed: " + response.dump());
    return JsonRpcClient::services_of(response["result"]);
  }

 private:
  // Sends one call and returns its response (notifications and other ids skipped).
  json request(const std::string& method, const json& params, std::chrono::milliseconds timeout) {
    const json id = ++next_id_;
    json message = {{"jsonrpc", "2.0"}, {"id", id}, {"method", method}};
    if (!params.is_null()) message["params"] = params;
    const auto deadline = Clock::now() + timeout;
    try {
      stream_.write(asio::buffer(message.dump(-1, ' ', false, json::error_handler_t::replace)));
      for (;;) {
        const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
        if (left.count() <= 0)
          throw ClientError("websocket client: " + peer_ + ": no response to " + method + " in time");
        set_timeout(left);
        boost::beast::flat_buffer buffer;
        boost::system::error_code ec;
        stream_.read(buffer, ec);
        if (ec == asio::error::would_block || ec == asio::error::try_again || ec == asio::error::timed_out)
          throw ClientError("websocket client: " + peer_ + ": no response to " + method + " within " +
                            std::to_string(timeout.count()) + " ms");
        if (ec) throw ClientError("websocket client: " + peer_ + ": " + ec.message());
        const auto data = buffer.cdata();
        json response = json::parse(std::string_view(static_cast<const char*>(data.data()), data.size()), nullptr,
                                    /*allow_exceptions=*/false);
        if (response.is_discarded()) throw ClientError("websocket client: " + peer_ + ": a message is not JSON");
        if (response.is_object() && response.contains("id") && response["id"] == id) return response;
      }
    } catch (const boost::system::system_error& e) {
      throw ClientError("websocket client: " + peer_ + ": " + e.what());
    }
  }

  void set_timeout(std::chrono::milliseconds timeout) {
    timeval tv{};
    tv.tv_sec = static_cast<time_t>(timeout.count() / 1000);
    tv.tv_usec = static_cast<suseconds_t>((timeout.count() % 1000) * 1000);
    if (tv.tv_sec == 0 && tv.tv_usec == 0) tv.tv_usec = 1000;
    if (stream_.next_layer().is_open())
      ::setsockopt(stream_.next_layer().native_handle(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  }

  std::string peer_;                                      // "host:port", for messages
  asio::io_context io_;                                   // the socket's (blocking calls only)
  ws::stream<asio::ip::tcp::socket> stream_;              // the connection
  std::int64_t next_id_ = 0;                              // last id used
};

}  // namespace

std::unique_ptr<Client> make_websocket_client(const json& options) {
  const std::string host = options.value("host", "127.0.0.1");
  const auto port = options.value("port", 8090);
  if (port < 1 || port > 65535) throw ClientError("websocket client: port " + std::to_string(port) + " out of range");
  return std::make_unique<WebSocketClient>(host, static_cast<std::uint16_t>(port), std::chrono::seconds(5));
}

}  // namespace simgate::client
