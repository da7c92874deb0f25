// simgate/kit/connection.h — one client connection of a TCP transport, whatever its framing,
// and the server-side bookkeeping every TCP transport keeps about its connections.
//
// Every TCP transport of simgate (socket and jsonrpc: lines; websocket: RFC 6455 frames)
// reads, writes, budgets and times out its connections the same way; only the framing
// differs. A Connection does the framing-agnostic part once:
//   - Reading: one read at a time into a fixed buffer (ConnectionLimits::read_bytes), whose
//     bytes go to the framing (consume(), a subclass's). Reading pauses while the
//     connection owes `pause_at_unanswered` replies (expect_reply/replied) or has more than
//     `pause_at_unsent_bytes` unsent (0: never), and resumes when that clears.
//   - Reads in a row (read_split.h): after a large read of a client sending alone, while
//     bytes are already waiting, up to k_reads_in_a_row reads follow at once and their
//     replies go out together (ConnectionServer::write_replies).
//   - Direct reads (idle_spin.h): when the server watches the connection (a lone client while
//     the I/O thread polls) no async read is started; the polling thread calls read_now()
//     until it parks the connection (read_async()).
//   - Writing: queue_with() appends a message, framed by the caller; the connection is
//     touched (ConnectionServer::touch) and written once per burst (flush_writes), straight
//     to the non-blocking socket while it takes everything, through one async write
//     otherwise; messages queued meanwhile go in the next write (coalesced). A burst past
//     k_coalesce_bytes is written at once.
//   - A client that does not read: a message that finds more than max_unsent_bytes already
//     waiting closes the connection (one message larger than the limit still goes to a
//     client that reads); a droppable one (progress, a stream sample) is dropped instead once
//     more than k_droppable_unsent_bytes wait.
//   - Memory of all connections together (held_bytes.h, max_buffered_bytes): unsent bytes and
//     what the framing keeps of an unfinished message (set_framing_bytes) are counted; a
//     message that finds the cap passed while its connection has bytes unsent closes it, and
//     so does one its socket does not take at once while the cap is passed.
//   - Timers, on the server's sweep clock (connection_rules.h): idle_ticks (nothing owed,
//     unsent or read), silent_ticks (the same while replies are owed), message_ticks (since
//     the unfinished message began: line_timeout_s bounds it whatever the framing).
//   - Auth state (auth.h), the peer's address, a label for logs, a number within the
//     transport (what calls carry as Call::client).
//   - End of input: the framing is told (input_ended); closing: close() shuts the socket at
//     once; end() is the protocol's goodbye (WebSocket: a close frame after what is queued).
//   - A handler that throws closes its connection with the error logged; the server keeps
//     serving everyone else.
//
// A framing derives from Connection (line_connection.h: lines; the websocket plugin: frames)
// and implements consume(), input_ended() and message_unfinished(); a transport's manager
// derives from ConnectionServer (or LineServer) and implements what its protocol does with
// the messages. docs/writing-a-transport.md shows one of each.
//
// Life cycle: created on accept, ConnectionServer::add()ed (which start()s it), kept alive by
// its pending handlers (shared_from_this) and by the server's set; close() ends it
// (idempotent). Threads: every member function runs on the transport's single I/O thread.
//
// Where a reply goes: a ConnectionRef names a connection without sharing its ownership. A
// protocol keeps one per request (the JSON-RPC engine's replies, the socket transport's
// deferred error replies) instead of a weak_ptr: making, copying and dropping it are plain
// copies, and get() looks the connection up in its server's table of open ones (an index
// and a compare), where a weak_ptr costs four atomic operations per reply (its weak count
// taken and given back, the lock and its release). A connection is open from add() until
// its server is told it closed: a reply that comes after its client left (an outcome from
// the simulation thread, an async service's completion, handed over to the I/O thread by
// the core) finds nothing and is dropped.
#ifndef SIMGATE_KIT_CONNECTION_H_
#define SIMGATE_KIT_CONNECTION_H_

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_set>
#include <utility>  // before Asio: Boost 1.74 needs std::exchange in C++20 mode
#include <vector>

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>

#include "simgate/kit/connection_rules.h"
#include "simgate/kit/held_bytes.h"
#include "simgate/kit/idle_spin.h"
#include "simgate/kit/read_split.h"
#include "simgate/kit/request_slots.h"
#include "simgate/kit/tcp_server.h"

namespace simgate::kit {

class Connection;
class ConnectionServer;

// A connection named without owning it (see the file's comment): `T` is the connection's
// class or another base of it (the JSON-RPC engine's Session), whose object lives as long
// as the connection. get() is the object while the connection is open, null once its
// server was told it closed (Connection::closed()) and for a ref made by default or before
// ConnectionServer::add(). get() reads the server's table: call it on the server's I/O
// thread, or once that thread has ended (a transport finishing what the core still holds
// at stop), never on another thread meanwhile. The server must outlive every get().
template <class T>
class ConnectionRef {
 public:
  ConnectionRef() = default;
  // `object` is `connection` or part of the same object (another base of its class).
  ConnectionRef(const Connection& connection, T& object);

  T* get() const { return open_ && open_->contains(id_) ? object_ : nullptr; }

 private:
  T* object_ = nullptr;                              // valid while id_ is open
  const RequestSlots<Connection*>* open_ = nullptr;  // its server's open connections
  RequestId id_ = 0;                                 // its slot there (0: none)
};

struct ConnectionLimits {
  std::size_t max_message_bytes = 1 << 20;  // longest message accepted
  std::size_t max_unsent_bytes = 8 << 20;   // unsent bytes a message may find before disconnecting
  std::size_t pause_at_unanswered = 0;      // replies owed that pause reading (0: never)
  std::size_t pause_at_unsent_bytes = 0;    // unsent bytes that pause reading (0: never)
  std::size_t read_bytes = 16384;           // the most one read takes
  const char* message_bytes_key = "max_message_bytes";  // the options' spelling, for messages
  const char* unsent_bytes_key = "max_unsent_bytes";    // the options' spelling, for messages

  // The byte limits of `options` (max_message_bytes, max_unsent_bytes, under their keys'
  // spelling); what pauses reading is the transport's choice.
  static ConnectionLimits from(const TcpOptions& options) {
    ConnectionLimits limits;
    limits.max_message_bytes = options.max_message_bytes;
    limits.max_unsent_bytes = options.max_unsent_bytes;
    limits.message_bytes_key = options.message_bytes_key;
    limits.unsent_bytes_key = options.unsent_bytes_key;
    return limits;
  }
};

class Connection : public std::enable_shared_from_this<Connection> {
 public:
  // `who` names the transport in logs ("Socket service manager"); `number` the connection
  // ("client #3 (127.0.0.1:51234)"). The socket is made non-blocking, without Nagle's delay.
  Connection(boost::asio::ip::tcp::socket socket, ConnectionServer& server, ConnectionLimits limits,
             std::string_view who, std::uint64_t number);
  virtual ~Connection() = default;
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  // Begins: a framing with no handshake starts reading (start_reading()).
  virtual void start() = 0;
  // Watched by the server: reads what is waiting, without waiting, and handles it as an
  // async read's completion would; false when nothing was waiting.
  bool read_now();
  // No longer watched: waits for its next bytes through the event loop (an async read).
  void read_async();

  // Queues the bytes `format(std::string& out)` appends to `out` (one message, framed by the
  // caller) for the next flush_writes(), formatted straight into the outbox; the budgets of
  // the file's comment apply (the connection may be closed instead).
  template <class Format>
  void queue_with(Format&& format) {
    const std::size_t waiting = unsent();
    // the usual case inline: open, within both budgets (room_for_message() says the rest)
    if (closed_ || waiting > limits_.max_unsent_bytes || (waiting > 0 && held().over()))
        [[unlikely]] {
      if (!room_for_message()) return;
    }
    message_queued_ = true;
    append_with(std::forward<Format>(format));
  }
  // queue_with() of a message the client may miss (a progress report, a stream sample):
  // dropped instead when more than k_droppable_unsent_bytes already wait unsent, so that a
  // client that does not read loses old reports, never a reply, and is not disconnected for
  // them. True if queued.
  static constexpr std::size_t k_droppable_unsent_bytes = 64 << 10;
  template <class Format>
  bool queue_droppable_with(Format&& format) {
    if (!room_for_droppable()) return false;
    queue_with(std::forward<Format>(format));
    return true;
  }
  // Whether a droppable message would be queued now.
  bool room_for_droppable() const { return !closed_ && unsent() <= k_droppable_unsent_bytes; }
  // Writes what was queued, unless a write is in flight (it takes them next).
  void flush_writes();

  // The protocol owes the client a reply (a request read), or one fewer (answered or
  // dropped). Reading pauses at pause_at_unanswered; end of input closes once none is owed.
  void expect_reply() { ++unanswered_; }
  void replied() {
    if (unanswered_ > 0) --unanswered_;
    active();
    if (!reading_) read_more();  // reading paused on unanswered requests resumes
    if (eof_) maybe_finish();
  }
  std::size_t unanswered() const { return unanswered_; }

  // Closes the socket at once and tells the server (once); idempotent.
  void close(std::string_view reason);
  // Ends the connection the protocol's way (the server's timeouts, a wrong token): close()
  // unless the framing says goodbye first (a WebSocket close frame with `how`'s code).
  virtual void end(std::string_view reason, Ending /*how*/) { close(reason); }
  // The server was told it closed: no message is read or queued any more.
  bool closed() const { return closed_; }
  // Sweeps (of the server) since it last read a message (blank lines and pings keep nothing
  // alive), wrote one or was owed a reply; 0 while it owes one or has bytes unsent.
  std::uint32_t idle_ticks() const;
  // The same even while it owes replies (a client waiting for calls that do not end); 0
  // while it has bytes unsent.
  std::uint32_t silent_ticks() const;
  // Sweeps since its unfinished message began (line_timeout_s); 0 when there is none.
  std::uint32_t message_ticks() const;
  boost::asio::ip::tcp::socket::executor_type executor() { return socket_.get_executor(); }

  // This connection as the kit's (for a class that derives from it and from another base).
  Connection& connection() { return *this; }
  // A reference to it (or to `object`, another base of its class) that does not own it:
  // where a reply goes (ConnectionRef).
  ConnectionRef<Connection> ref() { return {*this, *this}; }

  // "client #3 (127.0.0.1:51234)", for log messages.
  const std::string& label() const { return label_; }
  // Its number within the transport (3 above): what its calls carry as Call::client.
  std::uint64_t number() const { return number_; }
  // The client's address (unspecified when the socket had none).
  const boost::asio::ip::address& peer() const { return peer_; }

  // Whether the client may call services: true from the start unless the transport's
  // "auth" requires a token from this peer (auth.h, ConnectionServer::add); the protocol
  // sets it when the client presents the right one.
  bool authenticated() const { return authenticated_; }
  void set_authenticated() { authenticated_ = true; }
  // The client presents `token` (how is the protocol's affair): true, and authenticated from
  // now on, when it is the transport's token or the transport takes none; false when wrong.
  bool present_token(std::string_view token);

  // Reads in a row of a client sending alone before going back to the event loop.
  static constexpr int k_reads_in_a_row = 4;
  // Bytes queued in one burst past which they are written without waiting for its end.
  static constexpr std::size_t k_coalesce_bytes = 256 * 1024;
  // A buffer with more capacity than this is given back once a burst has emptied it.
  static constexpr std::size_t k_kept_buffer_bytes = 256 * 1024;

 protected:
  // ---- the framing's part
  // The bytes of one read (or of the handshake's leftovers): parse them, hand the messages
  // to the transport. May close the connection.
  virtual void consume(std::string_view data) = 0;
  // The client shut down its sending side: what then (answer what it asked, or close).
  virtual void input_ended() = 0;
  // A message has begun and not ended (message_ticks counts from message_begun()).
  virtual bool message_unfinished() const = 0;
  // The socket closed (close()): let go of what the framing holds. Default: nothing.
  virtual void on_close() {}
  // Everything queued is written. Default: nothing.
  virtual void on_written() {}
  // Every sweep of the server, with its clock (a keep-alive). Default: nothing.
  virtual void on_sweep(std::uint32_t /*tick*/) {}

  // ---- for the framing
  // Reads from now on; `first`: bytes that came before (with a handshake) are consumed first.
  void start_reading(std::string_view first = {});
  // The protocol is over for this connection: the server is told (once), no message is
  // read or queued any more; the socket stays open for a goodbye (queue_control) until
  // close().
  void finish(std::string_view reason);
  // The end of input was read: the connection closes once every reply owed is written.
  void end_of_input() {
    eof_ = true;
    maybe_finish();
  }
  // Appends bytes that are no message (a pong, a close frame): no budget, no activity;
  // nothing once the socket is closed.
  template <class Format>
  void queue_control(Format&& format) {
    if (shut_) return;
    append_with(std::forward<Format>(format));
  }
  // Bytes queued and not yet written.
  std::size_t unsent() const { return outbox_.size() + in_flight_.size(); }
  // An unfinished message began now (message_ticks).
  void message_begun() { message_tick_ = tick(); }
  // What the framing keeps now of the message being received (max_buffered_bytes).
  void set_framing_bytes(std::size_t bytes) {
    account(static_cast<std::ptrdiff_t>(bytes) - static_cast<std::ptrdiff_t>(framing_bytes_));
    framing_bytes_ = bytes;
  }
  // A message arrived (or a reply was owed): the connection is not idle.
  void active() { active_tick_ = tick(); }
  // A buffer a burst grew large is given back once empty.
  void release_if_large(std::string& buffer);
  // Large buffers let go of (the server returns memory to the system after many).
  void freed(std::size_t bytes);
  HeldBytes& held();
  std::uint32_t tick() const;
  bool shut() const { return shut_; }
  boost::asio::ip::tcp::socket& socket() { return socket_; }
  ConnectionServer& server() { return server_; }

  const ConnectionLimits limits_;  // from the transport options
  const std::string who_;          // the transport, for logs
  std::string label_;              // the client, for logs

 private:
  friend class ConnectionServer;
  template <class T>
  friend class ConnectionRef;
  template <class Format>
  void append_with(Format&& format) {
    const std::size_t before = outbox_.size();
    format(outbox_);
    account(static_cast<std::ptrdiff_t>(outbox_.size() - before));
    if (held().over()) [[unlikely]]
      write_or_close();
    else if (outbox_.size() >= k_coalesce_bytes) [[unlikely]]
      flush_writes();  // a large burst goes out as it grows
    else if (!touched_)
      touch();
  }
  void touch();
  void read_more();
  void on_read(const boost::system::error_code& ec, std::size_t n);
  // on_read() without starting the next read: the bytes, end of input or error.
  void handle_read(const boost::system::error_code& ec, std::size_t n);
  // Runs `handle` (bytes to consume), then writes the replies; a throw closes the
  // connection. reading_ is set meanwhile.
  template <class Handle>
  void guarded(Handle&& handle);
  // Whether a message may be queued: false when closed, or closes it when the client does
  // not read what it is sent.
  bool room_for_message();
  // A message took the server's connections past max_buffered_bytes: written now, and the
  // connection closed when its socket leaves some of it unsent.
  void write_or_close();
  void start_write();
  void after_write();
  void maybe_finish();
  bool paused() const;
  void account(std::ptrdiff_t bytes) { held().add(bytes); }

  boost::asio::ip::tcp::socket socket_;  // the connection
  ConnectionServer& server_;             // the transport (outlives every connection)
  std::uint64_t number_;                 // the connection's number within its transport
  RequestId open_id_ = 0;                // its slot among the server's open connections (add)
  boost::asio::ip::address peer_;        // the client's address
  bool authenticated_ = true;            // may call services (ConnectionServer::add decides)
  std::vector<char> read_buffer_;        // one read's bytes (ConnectionLimits::read_bytes)
  bool started_ = false;                 // start_reading() was called
  bool reading_ = false;                 // a read is in flight, or its bytes are being handled
  bool eof_ = false;                     // the client will send nothing more
  bool closed_ = false;                  // finish() or close() was called (the server was told)
  bool shut_ = false;                    // close() was called (the socket is closed)
  std::string outbox_;                   // bytes waiting for the next write
  std::string in_flight_;                // bytes being written
  bool writing_ = false;                 // a write is in flight
  bool message_queued_ = false;    // a message (not only control bytes) queued since the last write
  std::size_t unanswered_ = 0;     // replies the protocol owes
  std::size_t framing_bytes_ = 0;  // what the framing keeps of an unfinished message
  bool touched_ = false;           // in its server's touched list
  std::uint32_t active_tick_ = 0;  // the sweep of its last message read or written, or reply owed
  std::uint32_t message_tick_ = 0;  // the sweep its unfinished message began in
};

// The connections of one transport and what it does with all of them, on its I/O thread:
// the set (and its size for other threads), per-peer counts and eviction at
// max_connections, the connections touched by a burst of replies, the lone-client rules
// (ReadSplit, DirectReads), and the resource rules (a sweep every k_sweep while connections
// are open: message and idle timeouts, the buffers given back).
// A transport's manager derives from it and implements what its protocol does.
class ConnectionServer {
 public:
  // How often the connections are checked: timeouts are this precise.
  static constexpr std::chrono::milliseconds k_sweep = k_connection_sweep;

  // `who` names the transport in logs; `options`: its io_spin_us (0: the I/O thread never
  // polls, nothing is watched), max_connections, max_connections_per_peer, the timeouts,
  // max_buffered_bytes and auth.
  ConnectionServer(std::string who, const TcpOptions& options);
  virtual ~ConnectionServer() = default;

  // ---- the protocol's part (I/O thread)
  // The messages passed since the last call may go to the core together: half-way through
  // a large read (`read_finished` false: run and answer them now if the client sends alone,
  // read_split.h, or wait for the end) and at the end of every read.
  virtual void on_messages_done(Connection& connection, bool read_finished) = 0;
  // The connection closed (error, peer gone, limit exceeded, goodbye, server stopping): it
  // is already forgotten by the server; forget what the protocol keeps of it.
  virtual void on_closed(Connection& connection) = 0;
  // The connection stops reading for now: write the replies queued since the last write.
  virtual void write_replies() { flush_touched(); }

  // Adds an accepted connection (unauthenticated when auth requires a token from its peer)
  // and starts it.
  void add(const std::shared_ptr<Connection>& connection);
  // Closes every connection ("server stopping"; on_closed() runs for each) and lets go of
  // them all and of the sweep's timer. A transport calls it on its I/O thread when it
  // stops, before its io_context is destroyed (a base class outlives the members, the
  // io_context among them).
  void close_all();
  std::size_t connection_count() const { return count_.load(std::memory_order_relaxed); }
  // Calls `fn(Connection&)` for every open connection (I/O thread): a server that tells all
  // its clients something (a catalog change, a time). `fn` may close the one it is given.
  template <class Fn>
  void for_each_connection(Fn&& fn) {
    std::vector<std::shared_ptr<Connection>> all(connections_.begin(), connections_.end());
    for (const auto& c : all)
      if (!c->closed()) fn(*c);
  }
  // For the listener (TcpListener::Handlers::refuse): why a connection from `peer` is
  // refused, or "": max_connections are open and none of them has been idle for idle_evict_s
  // (the one idle longest is closed to make room when one has; failing one, the one silent
  // longest while it waits for replies, whose calls end as its client's leaving ends them),
  // or its non-loopback address holds max_connections_per_peer.
  std::string refusal_reason(const boost::asio::ip::tcp::endpoint& peer);
  // True while max_connections are open (after eviction, as above).
  bool full();
  // The thread that polls reads the watched connection through this (IoThread::start).
  DirectReads<Connection>& direct_reads() { return direct_; }
  // Writes the bytes of every touched connection (the end of a burst).
  void flush_touched();
  // Whether `connection` is the only one sending: a large read's first half runs early.
  bool alone(const Connection& connection) { return read_split_.alone(&connection); }
  // What all connections hold (max_buffered_bytes).
  HeldBytes& held() { return shared_.held; }

 private:
  friend class Connection;
  template <class T>
  friend class ConnectionRef;
  // The connection is about to wait for its next bytes: true when the polling thread will
  // read its socket itself (read_now) until it parks it (read_async).
  bool watch(Connection& connection);
  // The connection has bytes queued: write them at the end of the burst.
  void touch(Connection& connection);
  // The connection finished: forgotten, then on_closed().
  void closed(Connection& connection);
  void schedule_sweep(const std::shared_ptr<Connection>& any);
  void sweep();

  // What every connection of the server shares (the I/O thread).
  struct Shared {
    std::uint32_t tick = 0;  // sweeps so far: the connections' clock
    HeldBytes held;          // unfinished messages and unsent bytes, all connections
    std::size_t freed = 0;   // large buffers given back since the last sweep
  };
  Shared shared_;
  std::string who_;                 // for logs
  std::chrono::microseconds spin_;  // io_spin_us
  std::size_t max_connections_;     // max_connections
  std::string connections_key_;     // its key as the options spell it
  PeerCounts per_peer_;             // max_connections_per_peer (connection_rules.h)
  TokenAuth auth_;                  // who must present a token
  std::chrono::milliseconds idle_timeout_, idle_evict_, line_timeout_;  // 0: never
  std::unordered_set<std::shared_ptr<Connection>> connections_;         // open connections
  RequestSlots<Connection*> open_;     // the same, for ConnectionRef: a slot from add to closed
  std::atomic<std::size_t> count_{0};  // connections_.size(), for any thread
  std::vector<std::shared_ptr<Connection>> touched_;  // bytes queued, not yet written
  ReadSplit read_split_;                              // the lone client's large reads
  DirectReads<Connection> direct_;                    // the lone client read without the event loop
  std::optional<boost::asio::steady_timer> sweep_timer_;  // while connections are open
  bool sweeping_ = false;                                 // a sweep is scheduled
};

inline HeldBytes& Connection::held() { return server_.shared_.held; }
inline std::uint32_t Connection::tick() const { return server_.shared_.tick; }
inline void Connection::freed(std::size_t bytes) { server_.shared_.freed += bytes; }
inline void Connection::touch() { server_.touch(*this); }

template <class T>
ConnectionRef<T>::ConnectionRef(const Connection& connection, T& object)
    : object_(&object), open_(&connection.server_.open_), id_(connection.open_id_) {}

}  // namespace simgate::kit

#endif  // SIMGATE_KIT_CONNECTION_H_
