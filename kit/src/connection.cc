#include "simgate/kit/connection.h"

#include <malloc.h>

#include <algorithm>
#include <cstdio>
#include <exception>

#include <boost/asio/write.hpp>

#include "simgate/core/log.h"

namespace simgate::kit {

namespace asio = boost::asio;
using boost::system::error_code;

namespace {
// Given back since the last sweep past which the sweep returns free memory to the system.
constexpr std::size_t k_trim_after_bytes = 8 << 20;

bool would_block(const error_code& ec) {
  return ec == asio::error::would_block || ec == asio::error::try_again;
}

// "0.5", "60": a timeout's seconds as the options spell them, for messages.
std::string seconds_text(std::chrono::milliseconds duration) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", static_cast<double>(duration.count()) / 1000.0);
  return text;
}
}  // namespace

// ---- Connection

Connection::Connection(asio::ip::tcp::socket socket, ConnectionServer& server,
                       ConnectionLimits limits, std::string_view who, std::uint64_t number)
    : limits_(limits),
      who_(who),
      socket_(std::move(socket)),
      server_(server),
      number_(number),
      read_buffer_(limits.read_bytes) {
  error_code ec;
  const auto peer = socket_.remote_endpoint(ec);
  label_ = "client #" + std::to_string(number);
  if (!ec) {
    label_ += " (" + to_string(peer) + ")";
    peer_ = peer.address();
  }
  socket_.set_option(asio::ip::tcp::no_delay(true), ec);  // replies are small: no Nagle delay
  socket_.non_blocking(true,
                       ec);  // reads on and writes go straight to the socket while it takes them
  active();  // idle from now on, not from the server's first sweep (a handshake may come first)
}

std::uint32_t Connection::idle_ticks() const {
  if (unanswered_ > 0 || writing_ || !outbox_.empty()) return 0;
  return tick() - active_tick_;
}

std::uint32_t Connection::silent_ticks() const {
  if (writing_ || !outbox_.empty()) return 0;
  return tick() - active_tick_;
}

std::uint32_t Connection::message_ticks() const {
  if (shut_ || !message_unfinished()) return 0;
  return tick() - message_tick_;
}

void Connection::release_if_large(std::string& buffer) {
  if (buffer.capacity() <= k_kept_buffer_bytes) return;
  freed(buffer.capacity());
  std::string().swap(buffer);
}

bool Connection::paused() const {
  return (limits_.pause_at_unanswered > 0 && unanswered_ >= limits_.pause_at_unanswered) ||
         (limits_.pause_at_unsent_bytes > 0 && unsent() > limits_.pause_at_unsent_bytes);
}

// ---- reading

void Connection::start_reading(std::string_view first) {
  started_ = true;
  active();
  if (!first.empty())
    guarded([&] {
      consume(first);
      if (!closed_) server_.on_messages_done(*this, /*read_finished=*/true);
    });
  read_more();
}

void Connection::read_more() {
  if (shut_ || !started_ || reading_ || eof_ || paused())
    return;  // paused: backpressure instead of queues
  reading_ = true;
  if (!closed_ && server_.watch(*this))
    return;  // the server's polling thread reads the socket (read_now)
  read_async();
}

void Connection::read_async() {
  if (shut_) return;
  socket_.async_read_some(
      asio::buffer(read_buffer_),
      [self = shared_from_this()](const error_code& ec, std::size_t n) { self->on_read(ec, n); });
}

bool Connection::read_now() {
  if (shut_) return false;
  error_code ec;
  const std::size_t n = socket_.read_some(asio::buffer(read_buffer_), ec);
  if (would_block(ec)) return false;
  on_read(ec, n);
  return true;
}

template <class Handle>
void Connection::guarded(Handle&& handle) {
  // reading_ stays set until the bytes are handled: a reply sent meanwhile (an error
  // answered in order, a half read run early) must not start the next read, whose bytes
  // would land in read_buffer_ under the messages still being parsed
  reading_ = true;
  try {
    handle();
    server_.write_replies();
  } catch (const std::exception& e) {
    // nothing escapes a handler; the server keeps serving everyone else
    log::error(who_, ": ", label_, ": ", e.what());
    reading_ = false;
    close(std::string("internal error: ") + e.what());
    return;
  }
  reading_ = false;
}

void Connection::on_read(const error_code& ec, std::size_t n) {
  guarded([&] {
    handle_read(ec, n);
    // a large read of a client pipelining alone: if it has sent more already, this read's
    // replies go out with the next read's (would_block when nothing waits); a short read (a
    // client waiting for its answer) is answered at once
    for (int reads = 1; reads < k_reads_in_a_row && n >= ReadSplit::k_min_bytes; ++reads) {
      if (closed_ || eof_ || paused() || !server_.alone(*this)) break;
      error_code again;
      n = socket_.read_some(asio::buffer(read_buffer_), again);
      if (would_block(again)) break;
      handle_read(again, n);
    }
  });
  read_more();
}

void Connection::handle_read(const error_code& ec, std::size_t n) {
  if (shut_) return;
  if (ec == asio::error::eof) {
    input_ended();
    return;
  }
  if (ec) {
    close(ec.message());
    return;
  }
  consume(std::string_view(read_buffer_.data(), n));
  if (!closed_) server_.on_messages_done(*this, /*read_finished=*/true);
}

// ---- writing

bool Connection::room_for_message() {
  if (closed_) return false;
  const std::size_t waiting = unsent();
  if (waiting <= limits_.max_unsent_bytes && (waiting == 0 || !held().over())) return true;
  // the client does not read what it is sent: it may not grow our memory
  if (waiting > limits_.max_unsent_bytes)
    log::warning(who_, ": ", label_, " disconnected: more than ", limits_.max_unsent_bytes,
                 " bytes of replies unread (", limits_.unsent_bytes_key, ")");
  else
    log::warning(who_, ": ", label_, " disconnected: ", waiting,
                 " bytes of its replies unread while the transport holds more than ", held().max(),
                 " for all connections (max_buffered_bytes)");
  close("too many unread replies");
  return false;
}

void Connection::write_or_close() {
  flush_writes();
  if (shut_ || unsent() == 0 || !held().over()) return;
  // its socket did not take the message while the transport is past its cap: a first
  // message may not hold memory for a client that does not read either
  log::warning(who_, ": ", label_, " disconnected: ", unsent(),
               " bytes of its replies unread while the transport holds more than ", held().max(),
               " for all connections (max_buffered_bytes)");
  close("too many unread replies");
}

void Connection::flush_writes() {
  if (shut_ || writing_) return;
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

void Connection::start_write() {
  // everything queued goes out in one write
  in_flight_.swap(outbox_);
  outbox_.clear();
  writing_ = true;
  asio::async_write(
      socket_, asio::buffer(in_flight_),
      [self = shared_from_this()](const error_code& ec, std::size_t) {
        self->writing_ = false;
        if (!self->shut_)
          self->account(-static_cast<std::ptrdiff_t>(self->in_flight_.size()));  // close() took it
        self->in_flight_.clear();
        self->release_if_large(self->in_flight_);
        if (self->shut_) return;
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

void Connection::after_write() {
  // a message written (a reply, a sample) is activity; a pong or a keep-alive ping is not
  if (std::exchange(message_queued_, false)) active();
  maybe_finish();
  if (shut_) return;
  on_written();
  read_more();  // reading paused on unsent bytes resumes
}

void Connection::maybe_finish() {
  if (eof_ && !closed_ && unanswered_ == 0 && !writing_ && outbox_.empty()) close("end of input");
}

// ---- closing

void Connection::finish(std::string_view reason) {
  if (closed_) return;
  closed_ = true;
  log::debug(who_, ": ", label_, " closed: ", reason);
  server_.closed(*this);
}

bool Connection::present_token(std::string_view token) {
  if (server_.auth_.enabled && !server_.auth_.accepts(token)) return false;
  authenticated_ = true;
  return true;
}

void Connection::close(std::string_view reason) {
  if (shut_) return;
  finish(reason);
  shut_ = true;
  error_code ec;
  socket_.shutdown(asio::ip::tcp::socket::shutdown_both, ec);
  socket_.close(ec);
  // what it held is no longer the server's (a write in flight keeps in_flight_ until it ends)
  account(-static_cast<std::ptrdiff_t>(outbox_.size() + in_flight_.size()));
  set_framing_bytes(0);
  freed(outbox_.capacity());
  std::string().swap(outbox_);
  on_close();
}

// ---- ConnectionServer

ConnectionServer::ConnectionServer(std::string who, const TcpOptions& options)
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

void ConnectionServer::add(const std::shared_ptr<Connection>& connection) {
  connection->authenticated_ = !auth_.required_for(connection->peer());
  per_peer_.add(connection->peer());
  connections_.insert(connection);
  connection->open_id_ = open_.insert(connection.get());
  count_.store(connections_.size(), std::memory_order_relaxed);
  log::debug(who_, ": ", connection->label(), " connected");
  schedule_sweep(connection);
  connection->start();
}

void ConnectionServer::closed(Connection& connection) {
  direct_.forget(connection);
  open_.erase(connection.open_id_);  // its ConnectionRefs find nothing from now on
  if (connections_.erase(connection.shared_from_this()) > 0) per_peer_.remove(connection.peer());
  count_.store(connections_.size(), std::memory_order_relaxed);
  on_closed(connection);
}

void ConnectionServer::close_all() {
  auto connections = std::move(connections_);
  connections_.clear();
  per_peer_.clear();
  count_.store(0, std::memory_order_relaxed);
  for (const auto& c : connections) c->close("server stopping");
  open_.clear();
  // nothing of a connection outlives this: the transport's io_context goes next
  touched_.clear();
  direct_ = DirectReads<Connection>{};
  sweep_timer_.reset();
}

std::string ConnectionServer::refusal_reason(const boost::asio::ip::tcp::endpoint& peer) {
  if (full())
    return "too many connections (" + connections_key_ + " " + std::to_string(max_connections_) +
           ")";
  return per_peer_.refusal_reason(peer.address());
}

bool ConnectionServer::full() {
  if (connections_.size() < max_connections_) return false;
  if (idle_evict_.count() <= 0) return true;
  // the connection idle longest makes room, once idle long enough; failing one, the one
  // silent longest though it waits for replies (connection_rules.h)
  return !make_room(connections_, sweep_ticks(idle_evict_), who_, max_connections_);
}

void ConnectionServer::schedule_sweep(const std::shared_ptr<Connection>& any) {
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

void ConnectionServer::sweep() {
  const std::uint32_t tick = ++shared_.tick;
  // closed after the walk: a close changes connections_
  std::vector<std::shared_ptr<Connection>> message_late, idle, all;
  const std::uint32_t message_limit = line_timeout_.count() > 0 ? sweep_ticks(line_timeout_) : 0;
  const std::uint32_t idle_limit = idle_timeout_.count() > 0 ? sweep_ticks(idle_timeout_) : 0;
  all.reserve(connections_.size());
  for (const auto& c : connections_) {
    all.push_back(c);
    if (message_limit && c->message_ticks() >= message_limit)
      message_late.push_back(c);
    else if (idle_limit && c->idle_ticks() >= idle_limit)
      idle.push_back(c);
  }
  // one warning per sweep and rule, each connection at debug level (a flood logs little)
  auto end = [&](std::vector<std::shared_ptr<Connection>>& which, const std::string& why) {
    if (which.empty()) return;
    log::warning(who_, ": closed ", which.size(),
                 which.size() == 1 ? " connection: " : " connections: ", why,
                 which.size() == 1 ? " (" + which.front()->label() + ")" : std::string());
    for (const auto& c : which) c->end(why, Ending::timeout);
  };
  end(message_late,
      "a message not finished within " + seconds_text(line_timeout_) + " s (line_timeout_s)");
  end(idle, "idle for " + seconds_text(idle_timeout_) + " s (idle_timeout_s)");
  for (const auto& c : all)
    if (!c->closed()) c->on_sweep(tick);  // keep-alives
  // the memory a burst used goes back to the system, not only to the allocator
  if (shared_.freed >= k_trim_after_bytes) {
    ::malloc_trim(0);
    log::debug(who_, ": buffers of ", shared_.freed,
               " bytes freed since the last sweep; free memory returned to the system");
    shared_.freed = 0;
  }
  if (!connections_.empty()) schedule_sweep(*connections_.begin());
}

bool ConnectionServer::watch(Connection& connection) {
  // only while the I/O thread polls (it never does with io_spin_us 0), for a client
  // sending alone: others are served by the event loop between direct reads
  if (spin_.count() <= 0 || !read_split_.alone(&connection)) return false;
  direct_.watch(connection.shared_from_this());
  return true;
}

void ConnectionServer::touch(Connection& connection) {
  if (connection.touched_) return;
  connection.touched_ = true;
  touched_.push_back(connection.shared_from_this());  // kept alive until written
}

void ConnectionServer::flush_touched() {
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
