#include "simgate/kit/websocket_connection.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <utility>
#include <vector>

#include <boost/asio/write.hpp>
#include <boost/beast/http/read.hpp>
#include <boost/beast/http/write.hpp>
#include <boost/beast/websocket/rfc6455.hpp>

#include "simgate/core/log.h"

namespace simgate::kit {

bool is_valid_close_code(std::uint16_t code) {
  // 1004-1006 and 1015 are reserved (never sent), 1016-2999 unassigned; 3000-4999 are for
  // libraries and applications
  return (code >= 1000 && code <= 1003) || (code >= 1007 && code <= 1014) ||
         (code >= 3000 && code <= 4999);
}

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace ws = beast::websocket;
using asio::ip::tcp;
using boost::system::error_code;

std::optional<std::string> upgrade_token(const HttpRequest& request) {
  if (std::optional<std::string> token = bearer_token(request)) return token;
  const std::string_view target(request.target().data(), request.target().size());
  const std::size_t query = target.find('?');
  if (query == std::string_view::npos) return std::nullopt;
  std::string_view rest = target.substr(query + 1);
  while (!rest.empty()) {
    const std::size_t end = rest.find('&');
    const std::string_view parameter = rest.substr(0, end);
    rest = end == std::string_view::npos ? std::string_view() : rest.substr(end + 1);
    if (!parameter.starts_with("token=")) continue;
    // percent-decoded; '+' is a plus (tokens have no spaces)
    const std::string_view value = parameter.substr(6);
    std::string token;
    for (std::size_t i = 0; i < value.size(); ++i) {
      const auto hex = [](char c) {
        return c >= '0' && c <= '9'   ? c - '0'
               : c >= 'a' && c <= 'f' ? c - 'a' + 10
               : c >= 'A' && c <= 'F' ? c - 'A' + 10
                                      : -1;
      };
      if (value[i] == '%' && i + 2 < value.size() && hex(value[i + 1]) >= 0 &&
          hex(value[i + 2]) >= 0) {
        token.push_back(static_cast<char>(hex(value[i + 1]) * 16 + hex(value[i + 2])));
        i += 2;
      } else {
        token.push_back(value[i]);
      }
    }
    return token;
  }
  return std::nullopt;
}

WebSocketOptions WebSocketOptions::take(json& options) {
  WebSocketOptions s;
  s.origins = OriginPolicy::take(options);
  if (!options.is_object()) return s;
  if (auto it = options.find("keepalive_s"); it != options.end()) {
    json mine = {{"keepalive_s", *it}};
    options.erase(it);
    ConfigObject config(mine, "");
    // up to a day: a longer silence is a client gone, not one thinking
    s.keepalive = std::chrono::milliseconds(
        std::llround(config.get_number("keepalive_s", 150, 0, 86'400) * 1000));
    config.finish();
  }
  return s;
}

std::string WebSocketOptions::refuse_upgrade(const HttpRequest& request, std::string_view who,
                                             std::string_view server) const {
  std::optional<std::string_view> origin;
  if (auto it = request.find(http::field::origin); it != request.end())
    origin = std::string_view(it->value().data(), it->value().size());
  if (origins.allows(origin)) return {};
  const std::string shown = std::string(origin->substr(0, 200));
  log::warning(who, ": WebSocket upgrade from a page of origin '", shown,
               "' refused (allowed_origins: ", origins.describe(), ")");
  return plain_http_response(request, http::status::forbidden,
                             std::string(server) +
                                 ": WebSocket connections from pages of origin '" + shown +
                                 "' are not allowed (allowed: " + origins.describe() +
                                 "; the transport's option allowed_origins, docs/security.md)\n",
                             server);
}

WebSocketConnection::WebSocketConnection(tcp::socket socket, WebSocketServer& server,
                                         ConnectionLimits limits,
                                         std::chrono::milliseconds keepalive, std::string_view who,
                                         std::uint64_t number)
    : Connection(std::move(socket), server, limits, who, number),
      host_(server),
      keepalive_(keepalive),
      frames_(limits.max_message_bytes, server.binary_messages()),
      timer_(executor()) {}

// ---- the HTTP request and the upgrade (Beast)

void WebSocketConnection::start() {
  // the HTTP request first: an upgrade becomes the WebSocket, anything else gets the host's answer
  parser_.emplace();
  parser_->header_limit(k_max_request_bytes);
  parser_->body_limit(k_max_request_bytes);
  timer_.expires_after(k_handshake_timeout);
  timer_.async_wait([self = shared_self()](const error_code& ec) {
    if (!ec && !self->upgraded_) self->close("no WebSocket handshake within the handshake timeout");
  });
  http::async_read(
      socket(), http_buffer_, *parser_,
      [self = shared_self()](const error_code& ec, std::size_t) { self->on_request(ec); });
}

void WebSocketConnection::on_request(const error_code& ec) {
  if (closed()) return;
  if (ec) {
    close("bad HTTP request: " + ec.message());
    return;
  }
  const bool upgrade = ws::is_upgrade(parser_->get());
  if (upgrade) {
    http_response_ = HttpResponse{authenticate_upgrade(parser_->get())};
    if (http_response_.head.empty())
      http_response_ = HttpResponse{host_.refuse_upgrade(parser_->get())};
  }
  if (!upgrade || !http_response_.head.empty()) {
    // plain HTTP, or a refused upgrade: the host's answer, then the connection closes
    if (!upgrade) http_response_ = host_.on_http_request(parser_->get());
    parser_.reset();
    set_framing_bytes(http_response_.own_bytes());  // its own bytes, until written
    std::vector<asio::const_buffer> buffers{asio::buffer(http_response_.head)};
    if (http_response_.body) buffers.push_back(asio::buffer(*http_response_.body));
    asio::async_write(socket(), buffers, [self = shared_self()](const error_code&, std::size_t) {
      self->close("HTTP request answered");
    });
    return;
  }
  // Beast checks the upgrade and answers it (101, or 400 with the reason); the frames are ours
  upgrade_.emplace(socket());
  subprotocol_ = host_.subprotocol(parser_->get());
  upgrade_->set_option(
      ws::stream_base::decorator([subprotocol = subprotocol_](ws::response_type& response) {
        response.set(http::field::server, "simgate websocket transport");
        if (!subprotocol.empty()) response.set(http::field::sec_websocket_protocol, subprotocol);
      }));
  auto request = parser_->release();
  parser_.reset();
  upgrade_->async_accept(request,
                         [self = shared_self()](const error_code& ec) { self->on_upgraded(ec); });
}

std::string WebSocketConnection::authenticate_upgrade(const HttpRequest& request) {
  const std::optional<std::string> token = upgrade_token(request);
  if (token ? present_token(*token) : (authenticated() || host_.login_after_upgrade())) return {};
  log::warning(label(), ": WebSocket upgrade refused: ",
               token ? "a wrong token" : "no token (the transport's \"auth\" requires one)");
  return plain_http_response(
      request, http::status::unauthorized,
      token ? "simgate: wrong token\n"
            : "simgate: this transport requires a token: ws://HOST:PORT/?token=TOKEN, or the "
              "header Authorization: Bearer TOKEN (docs/security.md)\n",
      "simgate");
}

void WebSocketConnection::on_upgraded(const error_code& ec) {
  upgrade_.reset();
  if (shut()) return;
  if (ec) {
    close("WebSocket handshake failed: " + ec.message());
    return;
  }
  upgraded_ = true;
  timer_.cancel();
  heard_tick_ = tick();
  host_.on_open(*this);
  // bytes the client sent after its request (its first frames) are the first to parse
  const auto early = http_buffer_.cdata();
  const std::string first(static_cast<const char*>(early.data()), early.size());
  http_buffer_ = beast::flat_buffer();
  start_reading(first);
  flush_writes();
}

// ---- reading

void WebSocketConnection::consume(std::string_view data) {
  heard_tick_ = tick();  // the keep-alive's clock: any frame, a pong too
  pinged_ = false;
  delivered_ = false;
  // after a protocol error (1002 queued) the client's next bytes end the connection
  if (frames_.failed()) {
    protocol_error(frames_.error());
    return;
  }
  const bool was_idle = frames_.idle();
  frames_.feed(data, *this);
  if (shut()) return;
  // a message (or a frame head) begun in this read: line_timeout_s counts from now
  if (!frames_.idle() && (was_idle || delivered_)) message_begun();
  set_framing_bytes(frames_.message_bytes_held());
  if (!closed() && frames_.message_bytes_held() > 0 && held().over()) [[unlikely]] {
    // the message it is sending may not take the transport's memory past its cap
    log::warning(who_, ": ", label_, " disconnected: its unfinished message (",
                 frames_.message_bytes_held(), " bytes so far) takes the transport past ",
                 held().max(), " bytes held for all connections (max_buffered_bytes)");
    close_with(ws::close_code::try_again_later,
               "the server holds too much for its clients (max_buffered_bytes)");
    set_framing_bytes(frames_.message_bytes_held());  // its message was let go
  }
}

void WebSocketConnection::on_text(std::string_view text) {
  delivered_ = true;
  active();  // a message, not a ping: pings keep no place at max_connections (issue #35, item 9)
  host_.on_message(*this, text);
}

void WebSocketConnection::on_binary(std::string_view data) {
  delivered_ = true;
  active();
  host_.on_binary_message(*this, data);
}

void WebSocketConnection::on_refused(std::size_t bytes, bool binary) {
  delivered_ = true;
  active();
  host_.on_refused_message(*this, bytes, binary);
}

void WebSocketConnection::on_control(std::uint8_t opcode, std::string_view payload) {
  if (opcode == FrameParser::k_ping) {
    if (!close_queued_) queue_frame(FrameParser::k_pong, payload);
    return;
  }
  if (opcode == FrameParser::k_pong)
    return;  // the answer to a keep-alive ping (heard_tick_ is set)
  // a close frame: the handshake's end when we began it, else answered with its code
  if (payload.size() == 1) {
    protocol_error("a close frame of one byte");
    return;
  }
  client_closed_ = true;
  if (close_sent_) {
    close("closed");
    return;
  }
  closing("client closed the WebSocket");
  if (!close_queued_) {
    close_queued_ = true;
    // its code echoed, when it is one a peer may send (RFC 6455 7.4): else 1002
    std::string_view code = payload.substr(0, std::min<std::size_t>(payload.size(), 2));
    if (code.size() == 2 &&
        !is_valid_close_code(static_cast<std::uint16_t>((static_cast<unsigned char>(code[0]) << 8) |
                                                        static_cast<unsigned char>(code[1]))))
      code = std::string_view("\x03\xea", 2);  // 1002, protocol error
    queue_frame(FrameParser::k_close, code);
  }
  flush_writes();
}

void WebSocketConnection::protocol_error(std::string_view reason) {
  log::debug(who_, ": ", label_, ": WebSocket protocol error: ", reason);
  if (close_queued_)
    close(reason);
  else
    close_with(ws::close_code::protocol_error, reason);
}

void WebSocketConnection::on_sweep(std::uint32_t tick) {
  if (!upgraded_ || keepalive_.count() <= 0) return;
  const std::uint32_t silent = tick - heard_tick_;
  if (silent >= sweep_ticks(2 * keepalive_)) {
    log::debug(who_, ": ", label_, " sent nothing for ", 2 * keepalive_.count() / 1000.0,
               " s and answered no ping (keepalive_s)");
    close("the client went silent");
    return;
  }
  if (!pinged_ && !close_queued_ && silent >= sweep_ticks(keepalive_)) {
    pinged_ = true;
    queue_frame(FrameParser::k_ping, {});
    flush_writes();
  }
}

// ---- writing

void WebSocketConnection::append_frame(std::string& out, std::uint8_t opcode,
                                       std::string_view payload) {
  append_frame_head(out, opcode, payload.size());
  out.append(payload);
}

void WebSocketConnection::append_frame_head(std::string& out, std::uint8_t opcode,
                                            std::uint64_t n) {
  char header[10];
  std::size_t size = 2;
  header[0] = static_cast<char>(0x80 | opcode);
  if (n < 126) {
    header[1] = static_cast<char>(n);
  } else if (n <= 0xFFFF) {
    header[1] = 126;
    header[2] = static_cast<char>(n >> 8);
    header[3] = static_cast<char>(n);
    size = 4;
  } else {
    header[1] = 127;
    for (int i = 0; i < 8; ++i) header[2 + i] = static_cast<char>(n >> (56 - 8 * i));
    size = 10;
  }
  out.append(header, size);
}

void WebSocketConnection::on_written() {
  if (!close_queued_ || close_sent_ || unsent() > 0) return;
  // our close frame is out: the client answers with its own (its messages are ignored
  // meanwhile), or it already did
  close_sent_ = true;
  if (client_closed_) {
    close("closed");
    return;
  }
  timer_.expires_after(k_close_timeout);
  timer_.async_wait([self = shared_self()](const error_code& ec) {
    if (!ec) self->close("no close frame from the client within the close timeout");
  });
}

// ---- closing

void WebSocketConnection::close_with(ws::close_code code, std::string_view reason) {
  if (closed()) return;
  closing(reason);
  if (!upgraded_) {
    close(reason);
    return;
  }
  // after the messages queued: the close frame, its code and (at most 123 bytes of) reason
  std::string payload;
  const auto value = static_cast<std::uint16_t>(code);
  payload.push_back(static_cast<char>(value >> 8));
  payload.push_back(static_cast<char>(value & 0xFF));
  payload.append(reason.substr(0, 123));
  close_queued_ = true;
  queue_frame(FrameParser::k_close, payload);
  flush_writes();
}

void WebSocketConnection::end(std::string_view reason, Ending how) {
  close_with(how == Ending::timeout ? ws::close_code::going_away : ws::close_code::policy_error,
             reason);
}

void WebSocketConnection::on_close() {
  frames_.stop();  // nothing more is parsed, not even the rest of this read
  timer_.cancel();
}

}  // namespace simgate::kit
