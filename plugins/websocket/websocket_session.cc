#include "websocket_session.h"

#include <boost/beast/core/buffers_to_string.hpp>
#include <boost/beast/http/read.hpp>
#include <boost/beast/http/write.hpp>
#include <boost/beast/websocket/rfc6455.hpp>

#include "simgate/core/log.h"
#include "simgate/kit/tcp_server.h"

namespace simgate::websocket {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace ws = beast::websocket;
using asio::ip::tcp;
using boost::system::error_code;

WsSession::WsSession(tcp::socket socket, WsHost& host, WsLimits limits, std::string_view who, std::uint64_t number)
    : ws_(std::move(socket)), host_(host), limits_(limits), who_(who), handshake_timer_(ws_.get_executor()) {
  active();
  label_ = "client #" + std::to_string(number);
  error_code ec;
  const tcp::endpoint peer = ws_.next_layer().remote_endpoint(ec);
  if (!ec) {
    label_ += " (" + kit::to_string(peer) + ")";
    peer_ = peer.address();
  }
}

void WsSession::start() {
  // the HTTP request first: an upgrade becomes the WebSocket, anything else gets the host's answer
  parser_.emplace();
  parser_->header_limit(k_max_request_bytes);
  parser_->body_limit(k_max_request_bytes);
  handshake_timer_.expires_after(k_handshake_timeout);
  handshake_timer_.async_wait([self = shared()](const error_code& ec) {
    if (!ec && !self->upgraded_) self->abort("no WebSocket handshake within the handshake timeout");
  });
  http::async_read(ws_.next_layer(), buffer_, *parser_,
                   [self = shared()](const error_code& ec, std::size_t) { self->on_request(ec); });
}

void WsSession::on_request(const error_code& ec) {
  if (closed_) return;
  if (ec) {
    abort("bad HTTP request: " + ec.message());
    return;
  }
  const bool upgrade = ws::is_upgrade(parser_->get());
  if (upgrade) http_response_ = host_.refuse_upgrade(parser_->get());
  if (!upgrade || !http_response_.empty()) {
    // plain HTTP, or a refused upgrade: the host's answer, then the connection closes
    if (!upgrade) http_response_ = host_.on_http_request(parser_->get());
    parser_.reset();
    asio::async_write(ws_.next_layer(), asio::buffer(http_response_),
                      [self = shared()](const error_code&, std::size_t) { self->abort("HTTP request answered"); });
    return;
  }
  // the WebSocket: Beast's timeouts (handshake, idle pings) from now on
  ws_.set_option(ws::stream_base::timeout::suggested(beast::role_type::server));
  ws_.set_option(ws::stream_base::decorator([](ws::response_type& response) {
    response.set(http::field::server, "simgate websocket transport");
  }));
  // the limit is ours (the rest of an oversized message is skipped, the connection stays)
  ws_.read_message_max(0);
  ws_.auto_fragment(false);
  // a ping or a pong is activity too (a client keeping its connection alive is not idle)
  ws_.control_callback([this](ws::frame_type, beast::string_view) { active(); });
  auto request = parser_->release();
  parser_.reset();
  ws_.async_accept(request, [self = shared()](const error_code& ec) {
    if (self->closed_) return;
    if (ec) {
      self->abort("WebSocket handshake failed: " + ec.message());
      return;
    }
    self->upgraded_ = true;
    self->handshake_timer_.cancel();
    self->buffer_.clear();
    self->read_more();
    self->flush_writes();
  });
}

void WsSession::read_more() {
  if (reading_ || closed_ || !upgraded_ || unsent_ > limits_.pause_at_unsent_bytes) return;
  reading_ = true;
  ws_.async_read_some(buffer_, k_read_bytes,
                      [self = shared()](const error_code& ec, std::size_t n) { self->on_read(ec, n); });
}

void WsSession::on_read(const error_code& ec, std::size_t /*n*/) {
  reading_ = false;
  if (closed_) return;
  active();
  if (ec) {
    // the close handshake (Beast answered it), the peer gone, or a protocol error
    abort(ec == ws::error::closed ? "client closed the WebSocket" : "read failed: " + ec.message());
    return;
  }
  try {
    if (skipped_ > 0 || buffer_.size() > limits_.max_message_bytes) {
      // an oversized message: skipped to its end, answered once
      skipped_ += buffer_.size();
      buffer_.clear();
    }
    if (ws_.is_message_done()) {
      if (skipped_ > 0) {
        host_.on_refused_message(*this, skipped_, false);
      } else if (ws_.got_binary()) {
        host_.on_refused_message(*this, buffer_.size(), true);
      } else {
        const auto data = buffer_.cdata();
        host_.on_message(*this, std::string_view(static_cast<const char*>(data.data()), data.size()));
      }
      skipped_ = 0;
      buffer_.clear();
      if (buffer_.capacity() > k_read_bytes * 4) buffer_ = beast::flat_buffer();  // keep no large buffer
      host_.on_read_done(*this);
    }
  } catch (const std::exception& e) {
    log::error(who_, ": ", label_, ": ", e.what(), "; connection closed");
    abort("handler failed");
    return;
  }
  read_more();
}

void WsSession::queue_owned(std::string text) {
  if (closed_) return;
  if (unsent_ > limits_.max_unsent_bytes) {
    log::warning(who_, ": ", label_, " does not read its replies (", unsent_, " bytes unsent, max_unsent_bytes ",
                 limits_.max_unsent_bytes, "); connection closed");
    abort("client does not read");
    return;
  }
  unsent_ += text.size();
  outbox_.push_back(std::move(text));
  if (!touched) host_.touch(*this);
}

void WsSession::flush_writes() {
  if (writing_ || outbox_.empty() || !upgraded_ || ws_.next_layer().is_open() == false) return;
  start_write();
}

void WsSession::start_write() {
  writing_ = true;
  ws_.text(true);
  ws_.async_write(asio::buffer(outbox_.front()), [self = shared()](const error_code& ec, std::size_t) {
    self->on_write(ec);
  });
}

void WsSession::on_write(const error_code& ec) {
  writing_ = false;
  if (ec || !ws_.next_layer().is_open()) {
    // the buffer written is let go only now that no operation reads it
    outbox_.clear();
    unsent_ = 0;
    if (ec) abort("write failed: " + ec.message());
    return;
  }
  unsent_ -= outbox_.front().size();
  outbox_.pop_front();
  active();
  if (!outbox_.empty()) {
    start_write();
    return;
  }
  if (close_after_writes_) {
    auto [code, reason] = std::move(*close_after_writes_);
    close_after_writes_.reset();
    ws_.async_close(ws::close_reason(code, reason), [self = shared()](const error_code&) { self->abort("closed"); });
    return;
  }
  read_more();  // reading paused on unsent replies resumes
}

void WsSession::close_with(ws::close_code code, std::string_view reason) {
  if (closed_) return;
  log::debug(who_, ": ", label_, " closed: ", reason);
  closed_ = true;
  host_.on_closed(*this);
  if (!upgraded_) {
    abort(reason);
    return;
  }
  // a close frame's reason holds at most 123 bytes
  std::string text(reason.substr(0, 123));
  if (writing_ || !outbox_.empty()) {
    close_after_writes_.emplace(code, std::move(text));
    if (!writing_) start_write();
    return;
  }
  ws_.async_close(ws::close_reason(code, text), [self = shared()](const error_code&) { self->abort("closed"); });
}

void WsSession::abort(std::string_view reason) {
  if (!closed_) {
    log::debug(who_, ": ", label_, " closed: ", reason);
    closed_ = true;
    host_.on_closed(*this);
  }
  handshake_timer_.cancel();
  error_code ignored;
  auto& socket = ws_.next_layer();
  if (socket.is_open()) {
    socket.shutdown(tcp::socket::shutdown_both, ignored);
    socket.close(ignored);
  }
  // a write in flight still reads the front message: on_write lets it go
  if (!writing_) {
    outbox_.clear();
    unsent_ = 0;
  }
}

}  // namespace simgate::websocket
