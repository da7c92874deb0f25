#include "session.h"

#include <boost/asio/write.hpp>

#include "simgate/core/log.h"
#include "wire.h"

namespace simgate::socket {

namespace asio = boost::asio;
using boost::system::error_code;

Session::Session(asio::ip::tcp::socket socket, SessionHost& host, SessionLimits limits,
                 std::uint64_t number)
    : socket_(std::move(socket)), host_(host), limits_(limits) {
  error_code ec;
  auto peer = socket_.remote_endpoint(ec);
  label_ = "client #" + std::to_string(number);
  if (!ec) label_ += " (" + peer.address().to_string() + ":" + std::to_string(peer.port()) + ")";
  socket_.set_option(asio::ip::tcp::no_delay(true), ec);  // replies are small: no Nagle delay
  socket_.non_blocking(true, ec);  // flush_writes() writes directly while the socket takes it
}

void Session::start() { read_more(); }

void Session::read_more() {
  if (closed_ || reading_ || eof_) return;
  // backpressure: a client with too many unanswered requests waits for answers
  if (pending_.size() >= limits_.max_in_flight) return;
  reading_ = true;
  if (host_.watch(*this)) return;  // the host's polling thread reads the socket (read_now)
  read_async();
}

void Session::read_async() {
  if (closed_) return;
  socket_.async_read_some(asio::buffer(read_buffer_),
                          [self = shared_from_this()](const error_code& ec, std::size_t n) {
                            self->on_read(ec, n);
                          });
}

bool Session::read_now() {
  if (closed_) return false;
  error_code ec;
  std::size_t n = socket_.read_some(asio::buffer(read_buffer_), ec);
  if (ec == asio::error::would_block || ec == asio::error::try_again) return false;
  on_read(ec, n);
  return true;
}

void Session::on_read(const error_code& ec, std::size_t n) {
  // reading_ stays set until this read's lines are handled: a reply sent meanwhile (an
  // error answered in order, a batch run early) must not start the next read, whose bytes
  // would land in read_buffer_ under the lines still being parsed
  handle_read(ec, n);
  // a large read of a client pipelining alone: if it has sent more already, this read's
  // replies go out with the next read's (the socket is non-blocking: would_block when
  // nothing waits); a short read (a client waiting for its answer) is answered at once
  for (int reads = 1; reads < k_reads_in_a_row && n >= kit::ReadSplit::k_min_bytes; ++reads) {
    if (closed_ || eof_ || pending_.size() >= limits_.max_in_flight || !host_.alone(*this)) break;
    error_code again;
    n = socket_.read_some(asio::buffer(read_buffer_), again);
    if (again == asio::error::would_block || again == asio::error::try_again) break;
    handle_read(again, n);
  }
  host_.write_replies();
  reading_ = false;
  read_more();
}

void Session::handle_read(const error_code& ec, std::size_t n) {
  if (closed_) return;
  if (ec == asio::error::eof) {
    // the client finished sending: answer what it asked, then close
    if (!partial_.empty() && !discarding_) {
      // a last request without its '\n' still counts (telnet users, `printf` without \n)
      std::string last = std::move(partial_);
      partial_.clear();
      host_.on_line(shared_from_this(), last);
      host_.on_lines_done(shared_from_this(), /*read_finished=*/true);
    }
    eof_ = true;
    host_.on_input_ended(shared_from_this());
    maybe_finish();
    return;
  }
  if (ec) {
    close(ec.message());
    return;
  }
  consume(std::string_view(read_buffer_.data(), n));
  host_.on_lines_done(shared_from_this(), /*read_finished=*/true);
}

void Session::consume(std::string_view data) {
  auto self = shared_from_this();
  // a large read is offered to the host in two halves (see SessionHost::on_lines_done)
  std::size_t half_left = data.size() >= kit::ReadSplit::k_min_bytes ? data.size() / 2 : 0;
  while (!data.empty() && !closed_) {
    if (half_left && data.size() <= half_left) {
      half_left = 0;
      host_.on_lines_done(self, /*read_finished=*/false);
      // its replies may have closed the connection (the client does not read them): the
      // rest of the read is dropped, not taken as requests of a closed connection
      if (closed_) return;
    }
    std::size_t nl = data.find('\n');
    if (discarding_) {
      // the tail of an oversized line: skip to its end
      if (nl == std::string_view::npos) return;
      discarding_ = false;
      data.remove_prefix(nl + 1);
      continue;
    }
    if (nl == std::string_view::npos) {
      // an unfinished line: keep it, unless it is already too long
      if (partial_.size() + data.size() > limits_.max_message_bytes) {
        partial_.append(data.substr(0, std::min<std::size_t>(data.size(), 1024)));
        host_.on_oversized_line(self, partial_);
        partial_.clear();
        discarding_ = true;
      } else {
        partial_.append(data);
      }
      return;
    }
    std::string_view piece = data.substr(0, nl);
    data.remove_prefix(nl + 1);
    if (partial_.size() + piece.size() > limits_.max_message_bytes) {
      partial_.append(piece.substr(0, std::min<std::size_t>(piece.size(), 1024)));
      host_.on_oversized_line(self, partial_);
      partial_.clear();
      continue;
    }
    if (partial_.empty()) {
      host_.on_line(self, piece);  // fast path: the whole line is in this read
    } else {
      partial_.append(piece);
      std::string line = std::move(partial_);
      partial_.clear();
      host_.on_line(self, line);
    }
  }
}

void Session::send(std::string_view bytes) {
  queue(bytes);
  flush_writes();
}

void Session::queue(std::string_view bytes) {
  if (closed_) return;
  outbox_.append(bytes);
  check_unsent();
}

void Session::check_unsent() {
  if (outbox_.size() + in_flight_.size() > limits_.max_unsent_bytes) {
    // the client does not read its replies: it may not grow our memory
    log::warning("Socket service manager: ", label_, " disconnected: more than ",
                 limits_.max_unsent_bytes, " bytes of replies unread (", limits_.unsent_bytes_key, ")");
    close("too many unread replies");
  }
}

void Session::flush_writes() {
  if (closed_ || writing_ || outbox_.empty()) return;
  // straight to the socket while it takes everything (the usual case); the rest, if any,
  // through an async write
  error_code ec;
  std::size_t n = socket_.write_some(asio::buffer(outbox_), ec);
  if (ec == asio::error::would_block || ec == asio::error::try_again) {
    n = 0;
    ec = {};
  }
  if (ec) {
    close(ec.message());
    return;
  }
  if (n == outbox_.size()) {
    outbox_.clear();
    maybe_finish();
    return;
  }
  outbox_.erase(0, n);
  start_write();
}

void Session::start_write() {
  // everything queued goes out in one write
  in_flight_.swap(outbox_);
  outbox_.clear();
  writing_ = true;
  asio::async_write(socket_, asio::buffer(in_flight_),
                    [self = shared_from_this()](const error_code& ec, std::size_t) {
                      self->writing_ = false;
                      self->in_flight_.clear();
                      if (self->closed_) return;
                      if (ec) {
                        self->close(ec.message());
                        return;
                      }
                      if (!self->outbox_.empty())
                        self->start_write();
                      else
                        self->maybe_finish();
                    });
}

void Session::maybe_finish() {
  if (eof_ && !has_unanswered() && !writing_ && outbox_.empty()) close("end of input");
}

void Session::close(std::string_view reason) {
  if (closed_) return;
  closed_ = true;
  log::debug("Socket service manager: ", label_, " closed: ", reason);
  error_code ec;
  socket_.shutdown(asio::ip::tcp::socket::shutdown_both, ec);
  socket_.close(ec);
  outbox_.clear();
  partial_.clear();
  host_.on_session_closed(shared_from_this());
  pending_.clear();
}

void Session::answer(std::size_t client_id_hash, RequestId id, std::string_view status,
                     const json* value) {
  if (closed_) return;
  const kit::IdTable::Entry* entry = pending_.find(client_id_hash, id);
  if (!entry) {
    log::error("Socket service manager: ", label_, ": no pending request ", id, " to answer (reply dropped)");
    return;
  }
  // written straight into the outbox, then forgotten, then checked: the limit may close
  // the session
  append_reply(outbox_, entry->key, status, value);
  pending_.erase(entry);
  check_unsent();
  if (closed_) return;
  read_more();
  maybe_finish();
}

void Session::defer_reply() { ++deferred_replies_; }

void Session::queue_deferred_reply(std::string_view bytes) {
  if (deferred_replies_ > 0) --deferred_replies_;
  queue(bytes);
  maybe_finish();
}

}  // namespace simgate::socket
