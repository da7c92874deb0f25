#include "websocket_session.h"

#include <algorithm>
#include <cstring>
#include <utility>

#include <boost/asio/write.hpp>
#include <boost/beast/http/read.hpp>
#include <boost/beast/http/write.hpp>
#include <boost/beast/websocket/rfc6455.hpp>

#include "simgate/core/log.h"
#include "simgate/kit/connection_rules.h"
#include "simgate/kit/tcp_server.h"

namespace simgate::websocket {

bool is_valid_close_code(std::uint16_t code) {
  // 1004-1006 and 1015 are reserved (never sent), 1016-2999 unassigned; 3000-4999 are for
  // libraries and applications
  return (code >= 1000 && code <= 1003) || (code >= 1007 && code <= 1014) || (code >= 3000 && code <= 4999);
}

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace ws = beast::websocket;
using asio::ip::tcp;
using boost::system::error_code;

WsSession::WsSession(tcp::socket socket, WsHost& host, WsLimits limits, std::string_view who, std::uint64_t number)
    : socket_(std::move(socket)),
      host_(host),
      limits_(limits),
      who_(who),
      number_(number),
      frames_(limits.max_message_bytes),
      timer_(socket_.get_executor()) {
  active();
  heard_tick_ = active_tick_;
  label_ = "client #" + std::to_string(number);
  error_code ec;
  const tcp::endpoint peer = socket_.remote_endpoint(ec);
  if (!ec) {
    label_ += " (" + kit::to_string(peer) + ")";
    peer_ = peer.address();
  }
}

// ---- the HTTP request and the upgrade (Beast)

void WsSession::start() {
  // the HTTP request first: an upgrade becomes the WebSocket, anything else gets the host's answer
  parser_.emplace();
  parser_->header_limit(k_max_request_bytes);
  parser_->body_limit(k_max_request_bytes);
  timer_.expires_after(k_handshake_timeout);
  timer_.async_wait([self = shared()](const error_code& ec) {
    if (!ec && !self->upgraded_) self->abort("no WebSocket handshake within the handshake timeout");
  });
  http::async_read(socket_, http_buffer_, *parser_,
                   [self = shared()](const error_code& ec, std::size_t) { self->on_request(ec); });
}

void WsSession::on_request(const error_code& ec) {
  if (closed_) return;
  if (ec) {
    abort("bad HTTP request: " + ec.message());
    return;
  }
  const bool upgrade = ws::is_upgrade(parser_->get());
  if (upgrade) http_response_ = HttpResponse{host_.refuse_upgrade(parser_->get())};
  if (!upgrade || !http_response_.head.empty()) {
    // plain HTTP, or a refused upgrade: the host's answer, then the connection closes
    if (!upgrade) http_response_ = host_.on_http_request(parser_->get());
    parser_.reset();
    recount();  // its own bytes, until written
    std::vector<asio::const_buffer> buffers{asio::buffer(http_response_.head)};
    if (http_response_.body) buffers.push_back(asio::buffer(*http_response_.body));
    asio::async_write(socket_, buffers,
                      [self = shared()](const error_code&, std::size_t) { self->abort("HTTP request answered"); });
    return;
  }
  // Beast checks the upgrade and answers it (101, or 400 with the reason); the frames are ours
  upgrade_.emplace(std::move(socket_));
  upgrade_->set_option(ws::stream_base::decorator([](ws::response_type& response) {
    response.set(http::field::server, "simgate websocket transport");
  }));
  auto request = parser_->release();
  parser_.reset();
  // bytes the client sent after its request (its first frames) are the first to parse
  in_.resize(k_read_bytes);
  const auto early = http_buffer_.cdata();
  if (early.size() > 0) {
    in_end_ = std::min(early.size(), in_.size());
    std::memcpy(in_.data(), early.data(), in_end_);
  }
  http_buffer_ = beast::flat_buffer();
  upgrade_->async_accept(request, [self = shared()](const error_code& ec) { self->on_upgraded(ec); });
}

void WsSession::on_upgraded(const error_code& ec) {
  socket_ = std::move(upgrade_->next_layer());
  upgrade_.reset();
  if (closed_) {
    abort("closed");
    return;
  }
  if (ec) {
    abort("WebSocket handshake failed: " + ec.message());
    return;
  }
  upgraded_ = true;
  timer_.cancel();
  error_code ignored;
  socket_.non_blocking(true, ignored);  // direct reads and writes (read_now, start_write)
  active();
  heard_tick_ = active_tick_;
  if (in_end_ > 0) handle_read({}, 0);  // frames that came with the request
  read_more();
  flush_writes();
}

// ---- reading

void WsSession::read_more() {
  if (reading_ || handling_ || aborted_ || !upgraded_ || paused()) return;
  if (!closed_ && host_.watch(*this)) return;  // the polling thread reads it (read_now)
  read_async();
}

void WsSession::read_async() {
  if (reading_ || handling_ || aborted_ || !upgraded_ || paused()) return;
  reading_ = true;  // into the whole of in_: the parser took every byte of the last read
  socket_.async_read_some(asio::buffer(in_.data(), in_.size()),
                          [self = shared()](const error_code& ec, std::size_t n) { self->on_read(ec, n); });
}

bool WsSession::read_now() {
  if (reading_ || handling_ || aborted_ || !upgraded_ || paused()) return false;
  error_code ec;
  const std::size_t n = socket_.read_some(asio::buffer(in_.data(), in_.size()), ec);
  if (ec == asio::error::would_block || ec == asio::error::try_again) return false;
  on_read(ec, n);
  return true;
}

void WsSession::on_read(const error_code& ec, std::size_t n) {
  reading_ = false;
  handle_read(ec, n);
  read_more();
}

void WsSession::handle_read(const error_code& ec, std::size_t n) {
  if (aborted_) return;
  if (ec) {
    abort(ec == asio::error::eof ? "client left" : "read failed: " + ec.message());
    return;
  }
  in_end_ += n;
  heard_tick_ = host_.tick();  // the keep-alive's clock: any frame, a pong too
  pinged_ = false;
  delivered_ = false;
  handling_ = true;  // no read starts before these frames are parsed (they are in in_)
  try {
    if (consume() && delivered_) host_.on_read_done(*this);
  } catch (const std::exception& e) {
    log::error(who_, ": ", label_, ": ", e.what(), "; connection closed");
    abort("handler failed");
  }
  handling_ = false;
  recount();
  if (!closed_ && frames_.message_bytes_held() > 0 && host_.held().over()) [[unlikely]] {
    // the message it is sending may not take the transport's memory past its cap
    log::warning(who_, ": ", label_, " disconnected: its unfinished message (", frames_.message_bytes_held(),
                 " bytes so far) takes the transport past ", host_.held().max(),
                 " bytes held for all connections (max_buffered_bytes)");
    close_with(ws::close_code::try_again_later, "the server holds too much for its clients (max_buffered_bytes)");
    recount();  // its message was let go
  }
}

bool WsSession::consume() {
  const std::string_view bytes(in_.data(), in_end_);
  in_end_ = 0;
  // after a protocol error (1002 queued) the client's next bytes end the connection
  if (frames_.failed()) return protocol_error(frames_.error());
  return frames_.feed(bytes, *this);
}

void WsSession::on_text(std::string_view text) {
  delivered_ = true;
  active();  // a message, not a ping: pings keep no place at max_connections (issue #35, item 9)
  host_.on_message(*this, text);
}

void WsSession::on_refused(std::size_t bytes, bool binary) {
  delivered_ = true;
  active();
  host_.on_refused_message(*this, bytes, binary);
}

void WsSession::on_control(std::uint8_t opcode, std::string_view payload) {
  if (opcode == FrameParser::k_ping) {
    if (!close_queued_) {
      append_frame(FrameParser::k_pong, payload);
      if (!touched) host_.touch(*this);
    }
    return;
  }
  if (opcode == FrameParser::k_pong) return;  // the answer to a keep-alive ping (heard_tick_ is set)
  // a close frame: the handshake's end when we began it, else answered with its code
  if (payload.size() == 1) {
    protocol_error("a close frame of one byte");
    return;
  }
  client_closed_ = true;
  if (close_sent_) {
    abort("closed");
    return;
  }
  if (!closed_) {
    log::debug(who_, ": ", label_, " closed: client closed the WebSocket");
    closing();
    host_.on_closed(*this);
  }
  if (!close_queued_) {
    close_queued_ = true;
    // its code echoed, when it is one a peer may send (RFC 6455 7.4): else 1002
    std::string_view code = payload.substr(0, std::min<std::size_t>(payload.size(), 2));
    if (code.size() == 2 &&
        !is_valid_close_code(static_cast<std::uint16_t>((static_cast<unsigned char>(code[0]) << 8) |
                                                        static_cast<unsigned char>(code[1]))))
      code = std::string_view("\x03\xea", 2);  // 1002, protocol error
    append_frame(FrameParser::k_close, code);
  }
  flush_writes();
}

bool WsSession::protocol_error(std::string_view reason) {
  log::debug(who_, ": ", label_, ": WebSocket protocol error: ", reason);
  if (close_queued_)
    abort(reason);
  else
    close_with(ws::close_code::protocol_error, reason);
  return false;
}

void WsSession::keep_alive(std::uint32_t tick) {
  if (!upgraded_ || aborted_ || limits_.keepalive.count() <= 0) return;
  const std::uint32_t silent = tick - heard_tick_;
  if (silent >= kit::sweep_ticks(2 * limits_.keepalive)) {
    log::debug(who_, ": ", label_, " sent nothing for ", 2 * limits_.keepalive.count() / 1000.0,
               " s and answered no ping (keepalive_s)");
    abort("the client went silent");
    return;
  }
  if (!pinged_ && !close_queued_ && silent >= kit::sweep_ticks(limits_.keepalive)) {
    pinged_ = true;
    append_frame(FrameParser::k_ping, {});
    flush_writes();
  }
}

// ---- writing

void WsSession::append_frame(std::uint8_t opcode, std::string_view payload) {
  char header[10];
  std::size_t size = 2;
  header[0] = static_cast<char>(0x80 | opcode);
  const std::uint64_t n = payload.size();
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
  outbox_.append(header, size);
  outbox_.append(payload);
}

void WsSession::queue_message(std::string_view text) {
  if (closed_) return;
  if (unsent() > limits_.max_unsent_bytes) {
    log::warning(who_, ": ", label_, " does not read its replies (", unsent(), " bytes unsent, max_unsent_bytes ",
                 limits_.max_unsent_bytes, "); connection closed");
    abort("client does not read");
    return;
  }
  if (unsent() > 0 && host_.held().over()) {
    close_past_the_cap();
    return;
  }
  append_frame(FrameParser::k_text, text);
  message_queued_ = true;
  recount();
  if (host_.held().over())
    write_or_close();
  else if (outbox_.size() >= k_coalesce_bytes)
    flush_writes();  // a large burst goes out as it grows
  else if (!touched)
    host_.touch(*this);
}

void WsSession::write_or_close() {
  flush_writes();
  // its socket did not take the message while the transport is past its cap: a first
  // message may not hold memory for a client that does not read either
  if (!aborted_ && unsent() > 0 && host_.held().over()) close_past_the_cap();
}

void WsSession::close_past_the_cap() {
  log::warning(who_, ": ", label_, " does not read its replies (", unsent(),
               " bytes unsent) while the transport holds more than ", host_.held().max(),
               " for all connections (max_buffered_bytes); connection closed");
  abort("client does not read");
}

void WsSession::recount() {
  const std::size_t now =
      aborted_ ? 0 : unsent() + frames_.message_bytes_held() + (upgraded_ ? 0 : http_response_.own_bytes());
  host_.held().add(static_cast<std::ptrdiff_t>(now) - static_cast<std::ptrdiff_t>(counted_));
  counted_ = now;
}

void WsSession::flush_writes() {
  if (writing_ || outbox_.empty() || !upgraded_ || aborted_) return;
  start_write();
}

void WsSession::start_write() {
  sending_.swap(outbox_);
  outbox_.clear();
  sent_ = 0;
  // straight to the socket while it takes everything (the usual case: a reply)
  error_code ec;
  while (sent_ < sending_.size()) {
    const std::size_t n = socket_.write_some(asio::buffer(sending_.data() + sent_, sending_.size() - sent_), ec);
    if (ec) break;
    sent_ += n;
  }
  if (ec == asio::error::would_block || ec == asio::error::try_again) {
    // the rest when the client reads
    recount();
    writing_ = true;
    asio::async_write(socket_, asio::buffer(sending_.data() + sent_, sending_.size() - sent_),
                      [self = shared()](const error_code& ec, std::size_t n) {
                        self->writing_ = false;
                        self->sent_ += n;
                        if (ec) {
                          self->abort("write failed: " + ec.message());
                          return;
                        }
                        self->after_write();
                      });
    return;
  }
  if (ec) {
    abort("write failed: " + ec.message());
    return;
  }
  after_write();
}

void WsSession::after_write() {
  if (aborted_) return;
  // a message written (a reply, a sample) is activity; a pong or a keep-alive ping is not
  if (std::exchange(message_queued_, false)) active();
  if (sending_.capacity() > k_coalesce_bytes * 4) std::string().swap(sending_);  // keep no large buffer
  sending_.clear();
  sent_ = 0;
  recount();
  if (!outbox_.empty()) {
    start_write();
    return;
  }
  if (close_queued_ && !close_sent_) {
    after_close_sent();
    return;
  }
  read_more();  // reading paused on unsent replies resumes
}

void WsSession::after_close_sent() {
  close_sent_ = true;
  if (client_closed_) {
    abort("closed");
    return;
  }
  // the client answers with its close frame (read_more ignores its messages meanwhile)
  timer_.expires_after(k_close_timeout);
  timer_.async_wait([self = shared()](const error_code& ec) {
    if (!ec) self->abort("no close frame from the client within the close timeout");
  });
  read_more();
}

void WsSession::close_with(ws::close_code code, std::string_view reason) {
  if (closed_) return;
  log::debug(who_, ": ", label_, " closed: ", reason);
  closing();
  host_.on_closed(*this);
  if (!upgraded_) {
    abort(reason);
    return;
  }
  // after the messages queued: the close frame, its code and (at most 123 bytes of) reason
  std::string payload;
  const auto value = static_cast<std::uint16_t>(code);
  payload.push_back(static_cast<char>(value >> 8));
  payload.push_back(static_cast<char>(value & 0xFF));
  payload.append(reason.substr(0, 123));
  close_queued_ = true;
  append_frame(FrameParser::k_close, payload);
  flush_writes();
}

void WsSession::abort(std::string_view reason) {
  if (!closed_) {
    log::debug(who_, ": ", label_, " closed: ", reason);
    closing();
    host_.on_closed(*this);
  }
  aborted_ = true;
  frames_.stop();  // nothing more is parsed, not even the rest of this read
  timer_.cancel();
  error_code ignored;
  if (upgrade_) {
    upgrade_->next_layer().close(ignored);
  } else if (socket_.is_open()) {
    socket_.shutdown(tcp::socket::shutdown_both, ignored);
    socket_.close(ignored);
  }
  // a write in flight still reads sending_: its completion lets it go
  outbox_.clear();
  if (!writing_) {
    std::string().swap(sending_);
    sent_ = 0;
  }
  recount();  // to 0: what it holds is no longer the transport's
}

}  // namespace simgate::websocket
