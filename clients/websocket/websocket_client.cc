// websocket_client.cc — WebSocketClient (simgate/client/websocket_client.h): JSON-RPC 2.0
// over WebSocket text messages, Boost.Beast, blocking.
//
// Deadlines: the socket's receive timeout (SO_RCVTIMEO) bounds each read; a read that times
// out leaves the WebSocket unusable, so the client is closed then.
#include "simgate/client/websocket_client.h"

#include <sys/socket.h>
#include <sys/time.h>

#include <utility>  // before Asio: Boost 1.74 needs std::exchange in C++20 mode

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/websocket.hpp>

#include "simgate/client/jsonrpc_client.h"

namespace simgate::client {

namespace {

namespace asio = boost::asio;
namespace ws = boost::beast::websocket;
using Clock = std::chrono::steady_clock;

}  // namespace

struct WebSocketClient::Connection {
  asio::io_context io;                           // the socket's (blocking calls only)
  ws::stream<asio::ip::tcp::socket> stream{io};  // the connection
  bool failed = false;                           // a read failed or timed out: unusable

  // The receive timeout of the next reads; milliseconds::max(): none.
  void set_timeout(std::chrono::milliseconds timeout) {
    timeval tv{};
    if (timeout != std::chrono::milliseconds::max()) {
      tv.tv_sec = static_cast<time_t>(timeout.count() / 1000);
      tv.tv_usec = static_cast<suseconds_t>((timeout.count() % 1000) * 1000);
      if (tv.tv_sec == 0 && tv.tv_usec == 0) tv.tv_usec = 1000;  // 0 would mean no timeout
    }
    if (stream.next_layer().is_open())
      ::setsockopt(stream.next_layer().native_handle(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  }
};

WebSocketClient::WebSocketClient(const std::string& host, std::uint16_t port,
                                 std::chrono::milliseconds timeout)
    : connection_(std::make_unique<Connection>()), peer_(host + ":" + std::to_string(port)) {
  try {
    asio::ip::tcp::resolver resolver(connection_->io);
    auto endpoints = resolver.resolve(host, std::to_string(port));
    connection_->set_timeout(timeout);
    asio::connect(connection_->stream.next_layer(), endpoints);
    connection_->stream.next_layer().set_option(asio::ip::tcp::no_delay(true));
    connection_->set_timeout(timeout);
    connection_->stream.handshake(peer_, "/");
    connection_->stream.text(true);
  } catch (const boost::system::system_error& e) {
    throw ClientError("websocket client: " + peer_ + ": " + e.what());
  }
}

WebSocketClient::~WebSocketClient() = default;

Outcome WebSocketClient::call(const std::string& component, const std::string& service,
                              const json& params, std::chrono::milliseconds timeout) {
  return JsonRpcClient::to_outcome(request(component + "." + service, params, timeout));
}

json WebSocketClient::list_services(std::chrono::milliseconds timeout) {
  json response = request("rpc.discover", nullptr, timeout);
  if (!response.contains("result"))
    throw ClientError("websocket client: " + peer_ + ": rpc.discover failed: " + response.dump());
  return JsonRpcClient::services_of(response["result"]);
}

void WebSocketClient::login(const std::string& token, std::chrono::milliseconds timeout) {
  const json response =
      request("rpc.login", json{{"token", token}}, timeout);  // refused: AuthError
  if (response.value("result", json()) != true)
    throw ClientError("websocket client: " + peer_ + ": rpc.login failed: " + response.dump());
}

json WebSocketClient::request(const std::string& method, const json& params,
                              std::chrono::milliseconds timeout) {
  if (closed()) throw ClientError("websocket client: " + peer_ + ": the connection is closed");
  const json id = ++next_id_;
  json message = {{"jsonrpc", "2.0"}, {"id", id}, {"method", method}};
  if (!params.is_null()) message["params"] = params;
  const auto deadline = Clock::now() + timeout;
  try {
    connection_->stream.write(
        asio::buffer(message.dump(-1, ' ', false, json::error_handler_t::replace)));
  } catch (const boost::system::system_error& e) {
    connection_->failed = true;
    throw ClientError("websocket client: " + peer_ + ": " + e.what());
  }
  // the response; what comes before it (notifications, other ids) is kept for receive()
  std::deque<json> kept;
  for (;;) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
    std::optional<json> next;
    if (left.count() > 0) next = read(left);
    if (!next)
      throw ClientError("websocket client: " + peer_ + ": no response to " + method + " within " +
                        std::to_string(timeout.count()) + " ms");
    if (next->is_object() && next->contains("id") && (*next)["id"] == id) {
      early_.insert(early_.end(), kept.begin(), kept.end());
      JsonRpcClient::throw_if_unauthorized(*next, "websocket client: " + peer_);
      return std::move(*next);
    }
    kept.push_back(std::move(*next));
  }
}

std::optional<json> WebSocketClient::receive(std::chrono::milliseconds timeout) {
  if (!early_.empty()) {
    json first = std::move(early_.front());
    early_.pop_front();
    return first;
  }
  return read(timeout);
}

std::optional<json> WebSocketClient::read(std::chrono::milliseconds timeout) {
  if (closed()) throw ClientError("websocket client: " + peer_ + ": the connection is closed");
  connection_->set_timeout(timeout);
  boost::beast::flat_buffer buffer;
  boost::system::error_code ec;
  connection_->stream.read(buffer, ec);
  if (ec) connection_->failed = true;  // Beast's stream is unusable after a failed read
  if (ec == asio::error::would_block || ec == asio::error::try_again ||
      ec == asio::error::timed_out)
    return std::nullopt;
  if (ec) throw ClientError("websocket client: " + peer_ + ": " + ec.message());
  const auto data = buffer.cdata();
  json message =
      json::parse(std::string_view(static_cast<const char*>(data.data()), data.size()), nullptr,
                  /*allow_exceptions=*/false);
  if (message.is_discarded())
    throw ClientError("websocket client: " + peer_ + ": a message is not JSON");
  return message;
}

bool WebSocketClient::closed() const {
  return connection_->failed || !connection_->stream.next_layer().is_open();
}

int WebSocketClient::native_handle() {
  return connection_->stream.next_layer().is_open()
             ? connection_->stream.next_layer().native_handle()
             : -1;
}

std::unique_ptr<Client> make_websocket_client(const json& options) {
  const std::string host = options.value("host", "127.0.0.1");
  const auto port = options.value("port", 8090);
  if (port < 1 || port > 65535)
    throw ClientError("websocket client: port " + std::to_string(port) + " out of range");
  return std::make_unique<WebSocketClient>(host, static_cast<std::uint16_t>(port),
                                           std::chrono::seconds(5));
}

}  // namespace simgate::client
