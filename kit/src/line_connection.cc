#include "simgate/kit/line_connection.h"

#include <malloc.h>

#include <algorithm>
#include <exception>

#include <boost/asio/write.hpp>

#include "simgate/core/log.h"
#include "simgate/kit/tcp_server.h"

namespace simgate::kit {

namespace asio = boost::asio;
using boost::system::error_code;

namespace {
// How much of an oversized line the host sees (enough for the client's id).
constexpr std::size_t k_oversized_prefix = 1024;
// A buffer with more capacity than this is given back once a burst has emptied it.
constexpr std::size_t k_kept_buffer_bytes = 256 * 1024;
// Given back since the last sweep past which the sweep returns free memory to the system.
constexpr std::size_t k_trim_after_bytes = 8 << 20;

bool would_block(const error_code& ec) { return ec == asio::error::would_block || ec == asio::error::try_again; }
}  // namespace

// ---- LineConnection

LineConnection::LineConnection(asio::ip::tcp::socket socket, LineHost& host, LineLimits limits, std::string_view who,
                               std::uint64_t number)
    : socket_(std::move(socket)), host_(host), limits_(limits), who_(who), number_(number),
      read_buffer_(limits.read_bytes) {
  error_code ec;
  const auto peer = socket_.remote_endpoint(ec);
  label_ = "client #" + std::to_string(number);
  if (!ec) {
    label_ += " (" + to_string(peer) + ")";
    peer_ = peer.address();
  }
  socket_.set_option(asio::ip::tcp::no_delay(true), ec);  // replies are small: no Nagle delay
  socket_.non_blocking(true, ec);  // reads on and writes go straight to the socket while it takes them
}

void LineConnection::start() {
  active();
  read_more();
}

std::uint32_t LineConnection::idle_ticks() const {
  if (unanswered_ > 0 || writing_ || !outbox_.empty()) return 0;
  return host_.shared_.tick - active_tick_;
}

std::uint32_t LineConnection::silent_ticks() const {
  if (writing_ || !outbox_.empty()) return 0;
  return host_.shared_.tick - active_tick_;
}

std::uint32_t LineConnection::line_ticks() const {
  if (partial_.empty() && !discarding_) return 0;
  return host_.shared_.tick - line_tick_;
}

bool LineConnection::grow_line(std::string_view data) {
  if (!host_.shared_.held.fits(data.size())) {
    log::warning(who_, ": ", label_, " disconnected: its unfinished line would take the transport past ",
                 host_.shared_.held.max(), " bytes held for all connections (max_buffered_bytes)");
    close("max_buffered_bytes reached");
    return false;
  }
  if (partial_.empty()) line_tick_ = host_.shared_.tick;
  partial_.append(data);
  account(static_cast<std::ptrdiff_t>(data.size()));
  return true;
}

std::string LineConnection::take_line(std::string_view end) {
  account(-static_cast<std::ptrdiff_t>(partial_.size()));
  partial_.append(end);
  // freed by the caller once handled: counted now for the sweep's trim
  if (partial_.capacity() > k_kept_buffer_bytes) host_.shared_.freed += partial_.capacity();
  std::string line = std::move(partial_);
  partial_ = std::string();
  return line;
}

void LineConnection::release_if_large(std::string& buffer) {
  if (buffer.capacity() <= k_kept_buffer_bytes) return;
  host_.shared_.freed += buffer.capacity();
  std::string().swap(buffer);
}

bool LineConnection::paused() const {
  return (limits_.pause_at_unanswered > 0 && unanswered_ >= limits_.pause_at_unanswered) ||
         (limits_.pause_at_unsent_bytes > 0 && outbox_.size() + in_flight_.size() > limits_.pause_at_unsent_bytes);
}

void LineConnection::read_more() {
  if (closed_ || reading_ || eof_ || paused()) return;  // paused: backpressure instead of queues
  reading_ = true;
  if (host_.watch(*this)) return;  // the host's polling thread reads the socket (read_now)
  read_async();
}

void LineConnection::read_async() {
  if (closed_) return;
  socket_.async_read_some(asio::buffer(read_buffer_), [self = shared_from_this()](const error_code& ec, std::size_t n) {
    self->on_read(ec, n);
  });
}

bool LineConnection::read_now() {
  if (closed_) return false;
  error_code ec;
  const std::size_t n = socket_.read_some(asio::buffer(read_buffer_), ec);
  if (would_block(ec)) return false;
  on_read(ec, n);
  return true;
}

void LineConnection::on_read(const error_code& ec, std::size_t n) {
  // reading_ stays set until this read's lines are handled: a reply sent meanwhile (an
  // error answered in order, a half read run early) must not start the next read, whose
  // bytes would land in read_buffer_ under the lines still being parsed
  try {
    handle_read(ec, n);
    // a large read of a client pipelining alone: if it has sent more already, this read's
    // replies go out with the next read's (would_block when nothing waits); a short read (a
    // client waiting for its answer) is answered at once
    for (int reads = 1; reads < k_reads_in_a_row && n >= ReadSplit::k_min_bytes; ++reads) {
      if (closed_ || eof_ || paused() || !host_.alone(*this)) break;
      error_code again;
      n = socket_.read_some(asio::buffer(read_buffer_), again);
      if (would_block(again)) break;
      handle_read(again, n);
    }
    host_.write_replies();
  } catch (const std::exception& e) {
    // nothing escapes a handler; the server keeps serving everyone else
    log::error(who_, ": ", label_, ": ", e.what());
    reading_ = false;
    close(std::string("internal error: ") + e.what());
    return;
  }
  reading_ = false;
  read_more();
}

void LineConnection::handle_read(const error_code& ec, std::size_t n) {
  if (closed_) return;
  if (ec == asio::error::eof) {
    // the client finished sending: answer what it asked, then close
    if (!partial_.empty() && !discarding_) {
      const std::string last = take_line();
      deliver(last);
      if (closed_) return;
      host_.on_lines_done(*this, /*read_finished=*/true);
    }
    eof_ = true;
    host_.on_input_ended(*this);
    maybe_finish();
    return;
  }
  if (ec) {
    close(ec.message());
    return;
  }
  consume(std::string_view(read_buffer_.data(), n));
  if (!closed_) host_.on_lines_done(*this, /*read_finished=*/true);
}

void LineConnection::consume(std::string_view data) {
  // a large read is offered to the host in two halves (LineHost::on_lines_done)
  std::size_t half_left = data.size() >= ReadSplit::k_min_bytes ? data.size() / 2 : 0;
  while (!data.empty() && !closed_) {
    if (half_left && data.size() <= half_left) {
      half_left = 0;
      host_.on_lines_done(*this, /*read_finished=*/false);
      // its replies may have closed the connection (the client does not read them): the
      // rest of the read is dropped, not taken as requests of a closed connection
      if (closed_) return;
    }
    const std::size_t nl = data.find('\n');
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
        oversized(data, partial_.size() + data.size());
        discarding_ = true;
        line_tick_ = host_.shared_.tick;  // its rest must come within line_timeout_s too
      } else {
        grow_line(data);
      }
      return;
    }
    const std::string_view piece = data.substr(0, nl);
    data.remove_prefix(nl + 1);
    if (partial_.size() + piece.size() > limits_.max_message_bytes) {
      oversized(piece, partial_.size() + piece.size());
    } else if (partial_.empty()) {
      deliver(piece);  // fast path: the whole line is in this read
    } else {
      const std::string line = take_line(piece);
      deliver(line);
    }
  }
}

void LineConnection::deliver(std::string_view line) {
  if (!is_http_request_line(line)) {
    // a blank line is no request: a client sending only those is idle (it does not keep
    // its place at max_connections, issue #35 item 9)
    if (line.find_first_not_of(" \t\r") != std::string_view::npos) active();
    host_.on_line(*this, line);
    return;
  }
  // a web page posting to this port (fetch with mode "no-cors"): its headers and its body
  // would be read as lines of this protocol, so nothing more is read
  if (line.back() == '\r') line.remove_suffix(1);
  log::warning(who_, ": ", label_, ": closed on an HTTP request line (", log::quoted_prefix(line),
               "): this port does not speak HTTP; nothing that followed it was run");
  close("an HTTP request line");
}

void LineConnection::oversized(std::string_view start, std::size_t bytes) {
  // the host sees the line's first KiB; what was kept of it goes back to the allocator
  std::string prefix = take_line();
  if (prefix.size() < k_oversized_prefix)
    prefix.append(start.substr(0, std::min(start.size(), k_oversized_prefix - prefix.size())));
  else
    prefix.resize(k_oversized_prefix);
  host_.on_oversized_line(*this, prefix, bytes);
}

bool LineConnection::room_for_reply() {
  if (closed_) return false;
  const std::size_t waiting = outbox_.size() + in_flight_.size();
  if (waiting <= limits_.max_unsent_bytes && (waiting == 0 || !host_.shared_.held.over())) return true;
  // the client does not read its replies: it may not grow our memory
  if (waiting > limits_.max_unsent_bytes)
    log::warning(who_, ": ", label_, " disconnected: more than ", limits_.max_unsent_bytes,
                 " bytes of replies unread (", limits_.unsent_bytes_key, ")");
  else
    log::warning(who_, ": ", label_, " disconnected: ", waiting, " bytes of its replies unread while the transport holds more than ",
                 host_.shared_.held.max(), " for all connections (max_buffered_bytes)");
  close("too many unread replies");
  return false;
}

void LineConnection::write_or_close() {
  flush_writes();
  if (closed_ || (outbox_.empty() && in_flight_.empty()) || !host_.shared_.held.over()) return;
  // its socket did not take the reply while the transport is past its cap: a first reply
  // may not hold memory for a client that does not read either
  log::warning(who_, ": ", label_, " disconnected: ", outbox_.size() + in_flight_.size(),
               " bytes of its replies unread while the transport holds more than ", host_.shared_.held.max(),
               " for all connections (max_buffered_bytes)");
  close("too many unread replies");
}

void LineConnection::flush_writes() {
  if (closed_ || writing_) return;
  if (outbox_.empty()) {
    maybe_finish();
    return;
  }
  // straight to the socket while it takes everything (the usual case); the rest, if any,
  // through an async write
  error_code ec;
  std::size_t n = socket_.write_some(asio::buffer(outbox_), ec);
  if (would_block(ec)) {
    n = 0;
    ec = {};
  }
  if (ec) {
    close(ec.message());
    return;
  }
  account(-static_cast<std::ptrdiff_t>(n));
  if (n == outbox_.size()) {
    outbox_.clear();
    release_if_large(outbox_);
    after_write();
    return;
  }
  outbox_.erase(0, n);
  start_write();
}

void LineConnection::start_write() {
  // everything queued goes out in one write
  in_flight_.swap(outbox_);
  outbox_.clear();
  writing_ = true;
  asio::async_write(socket_, asio::buffer(in_flight_), [self = shared_from_this()](const error_code& ec, std::size_t) {
    self->writing_ = false;
    if (!self->closed_) self->account(-static_cast<std::ptrdiff_t>(self->in_flight_.size()));  // close() took it
    self->in_flight_.clear();
    self->release_if_large(self->in_flight_);
    if (self->closed_) return;
    if (ec) {
      self->close(ec.message());
      return;
    }
    if (!self->outbox_.empty())
      self->start_write();
    else
      self->after_write();
  });
}

void LineConnection::after_write() {
  active();
  maybe_finish();
  read_more();  // reading paused on unsent bytes resumes
}

void LineConnection::maybe_finish() {
  if (eof_ && !closed_ && unanswered_ == 0 && !writing_ && outbox_.empty()) close("end of input");
}

void LineConnection::close(std::string_view reason) {
  if (closed_) return;
  closed_ = true;
  log::debug(who_, ": ", label_, " closed: ", reason);
  error_code ec;
  socket_.shutdown(asio::ip::tcp::socket::shutdown_both, ec);
  socket_.close(ec);
  // what it held is no longer the host's (a write in flight keeps in_flight_ until it ends)
  account(-static_cast<std::ptrdiff_t>(partial_.size() + outbox_.size() + in_flight_.size()));
  host_.shared_.freed += partial_.capacity() + outbox_.capacity();
  std::string().swap(outbox_);
  std::string().swap(partial_);
  host_.on_closed(*this);
}

// ---- LineServer

LineServer::LineServer(std::string who, const TcpOptions& options)
    : who_(std::move(who)),
      spin_(options.io_spin),
      max_connections_(options.max_connections),
      connections_key_(options.connections_key),
      per_peer_(options.max_connections_per_peer),
      auth_(options.auth),
      idle_timeout_(options.idle_timeout),
      idle_evict_(options.idle_evict),
      line_timeout_(options.line_timeout) {
  shared_.held.set_max(options.max_buffered_bytes);
}

void LineServer::add(const std::shared_ptr<LineConnection>& connection) {
  connection->authenticated_ = !auth_.required_for(connection->peer());
  per_peer_.add(connection->peer());
  connections_.insert(connection);
  count_.store(connections_.size(), std::memory_order_relaxed);
  log::debug(who_, ": ", connection->label(), " connected");
  schedule_sweep(connection);
  connection->start();
}

void LineServer::forget(LineConnection& connection) {
  direct_.forget(connection);
  if (connections_.erase(connection.shared_from_this()) > 0) per_peer_.remove(connection.peer());
  count_.store(connections_.size(), std::memory_order_relaxed);
}

void LineServer::close_all() {
  auto connections = std::move(connections_);
  connections_.clear();
  per_peer_.clear();
  count_.store(0, std::memory_order_relaxed);
  for (const auto& c : connections) c->close("server stopping");
  // nothing of a connection outlives this: the transport's io_context goes next
  touched_.clear();
  direct_ = DirectReads<LineConnection>{};
  sweep_timer_.reset();
}

std::string LineServer::refusal_reason(const boost::asio::ip::tcp::endpoint& peer) {
  if (full())
    return "too many connections (" + connections_key_ + " " + std::to_string(max_connections_) + ")";
  return per_peer_.refusal_reason(peer.address());
}

bool LineServer::full() {
  if (connections_.size() < max_connections_) return false;
  if (idle_evict_.count() <= 0) return true;
  // the connection idle longest makes room, once idle long enough; failing one, the one
  // silent longest though it waits for replies (connection_rules.h)
  return !make_room(connections_, ticks(idle_evict_), who_, max_connections_);
}

void LineServer::schedule_sweep(const std::shared_ptr<LineConnection>& any) {
  if (sweeping_) return;
  if (!sweep_timer_) sweep_timer_.emplace(any->executor());
  sweeping_ = true;
  sweep_timer_->expires_after(k_sweep);
  sweep_timer_->async_wait([this](const error_code& ec) {
    sweeping_ = false;
    if (ec) return;  // close_all(): the server stops
    sweep();
  });
}

void LineServer::sweep() {
  ++shared_.tick;
  // closed after the walk: a close changes connections_
  std::vector<std::shared_ptr<LineConnection>> line_late, idle;
  const std::uint32_t line_limit = line_timeout_.count() > 0 ? ticks(line_timeout_) : 0;
  const std::uint32_t idle_limit = idle_timeout_.count() > 0 ? ticks(idle_timeout_) : 0;
  for (const auto& c : connections_) {
    if (line_limit && c->line_ticks() >= line_limit)
      line_late.push_back(c);
    else if (idle_limit && c->idle_ticks() >= idle_limit)
      idle.push_back(c);
  }
  // one warning per sweep and rule, each connection at debug level (a flood logs little)
  auto close = [&](std::vector<std::shared_ptr<LineConnection>>& which, const std::string& why) {
    if (which.empty()) return;
    log::warning(who_, ": closed ", which.size(), which.size() == 1 ? " connection: " : " connections: ", why,
                 which.size() == 1 ? " (" + which.front()->label() + ")" : std::string());
    for (const auto& c : which) c->close(why);
  };
  close(line_late, "a line not finished within " + std::to_string(line_timeout_.count() / 1000.0) + " s (line_timeout_s)");
  close(idle, "idle for " + std::to_string(idle_timeout_.count() / 1000.0) + " s (idle_timeout_s)");
  // the memory a burst used goes back to the system, not only to the allocator
  if (shared_.freed >= k_trim_after_bytes) {
    ::malloc_trim(0);
    log::debug(who_, ": buffers of ", shared_.freed, " bytes freed since the last sweep; free memory returned to the system");
    shared_.freed = 0;
  }
  if (!connections_.empty()) schedule_sweep(*connections_.begin());
}

bool LineServer::watch(LineConnection& connection) {
  // only while the I/O thread polls (it never does with io_spin_us 0), for a client
  // sending alone: others are served by the event loop between direct reads
  if (spin_.count() <= 0 || !read_split_.alone(&connection)) return false;
  direct_.watch(connection.shared_from_this());
  return true;
}

void LineServer::touch(LineConnection& connection) {
  if (connection.touched_) return;
  connection.touched_ = true;
  touched_.push_back(connection.shared_from_this());  // kept alive until written
}

void LineServer::flush_touched() {
  // one write per connection; a write may touch or close others: take the list first
  auto touched = std::move(touched_);
  touched_.clear();
  for (const auto& c : touched) {
    c->touched_ = false;
    c->flush_writes();
  }
  if (touched_.empty()) {
    touched.clear();
    touched_.swap(touched);  // keep the capacity
  }
}

}  // namespace simgate::kit
