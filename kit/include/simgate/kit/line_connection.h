// simgate/kit/line_connection.h — one client connection of a line-based TCP transport, and
// the server-side bookkeeping every such transport keeps about its connections.
//
// Both TCP transports speak one message per '\n'-terminated line in both directions; what
// differs is only what a line means. A LineConnection does everything else, once:
//   - Framing: bytes accumulate until '\n', so a message split over TCP segments works and
//     several in one segment are all seen. A line longer than max_message_bytes is handed
//     to the host as its first KiB (LineHost::on_oversized_line: the protocol answers it)
//     and skipped up to its '\n'; the connection keeps working. At end of input a last line
//     without its '\n' still counts (telnet, `printf` without \n).
//   - Reading: one async read at a time into a fixed buffer; reading pauses while the
//     connection owes `pause_at_unanswered` replies (expect_reply/replied) or has more than
//     `pause_at_unsent_bytes` unsent (0: never), and resumes when that clears.
//   - Large reads of a client sending alone (read_split.h): the host is offered the first
//     half (on_lines_done(false)) to run and answer it before the rest is parsed; after the
//     read, while bytes are already waiting, up to k_reads_in_a_row reads follow at once and
//     their replies go out together (LineHost::write_replies).
//   - Direct reads (idle_spin.h): when the host watches the connection (a lone client while
//     the I/O thread polls) no async read is started; the polling thread calls read_now()
//     until it parks the connection (read_async()).
//   - Writing: queue() appends a reply; the connection is touched (LineServer::touch) and
//     written once per burst (flush_writes), straight to the non-blocking socket while it
//     takes everything, through one async write otherwise; replies queued meanwhile go in the
//     next write (coalesced). A burst past k_coalesce_bytes is written at once.
//   - A client that does not read: a reply that finds more than max_unsent_bytes already
//     waiting closes the connection (one reply larger than the limit still goes to a client
//     that reads).
//   - End of input: the host is told (on_input_ended: it may cancel what the client left
//     running); the connection stays open until every reply it owes is written, then closes
//     (so `echo req | nc` gets its answer).
//   - A handler that throws closes its connection with the error logged; the server keeps
//     serving everyone else.
//   - Cross-site requests: a line that is an HTTP request line ("POST / HTTP/1.1": what a
//     browser sends first when a web page posts to the port) closes the connection before
//     the host sees it, so neither the headers nor the body that follow are ever taken as
//     requests (is_http_request_line).
//   - Resources held without use (LineServer, the transport's options): a line begun must
//     end within line_timeout_s; a connection idle (nothing owed, nothing unsent, nothing
//     read) for idle_timeout_s is closed; at max_connections the connection idle longest
//     makes room for a new one once idle for idle_evict_s; the unfinished lines and unsent
//     replies of all connections together stay under max_buffered_bytes (held_bytes.h: the
//     connection that would pass it is closed, a first reply included); buffers grown by a
//     burst are given back after it.
//
// A transport derives its session from LineConnection (adding its per-connection state:
// pending ids) and its manager from LineServer (implementing the LineHost calls that are
// its protocol); docs/writing-a-transport.md shows one.
//
// Life cycle: created on accept, start()ed, kept alive by its pending handlers
// (shared_from_this) and by the server's set; close() ends it (idempotent).
// Threads: every member function runs on the transport's single I/O thread.
#ifndef SIMGATE_KIT_LINE_CONNECTION_H_
#define SIMGATE_KIT_LINE_CONNECTION_H_

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <memory>
#include <string>
#include <string_view>
#include <unordered_set>
#include <utility>  // before Asio: Boost 1.74 needs std::exchange in C++20 mode
#include <vector>

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>

#include "simgate/kit/connection_rules.h"
#include "simgate/kit/held_bytes.h"
#include "simgate/kit/http_line.h"
#include "simgate/kit/idle_spin.h"
#include "simgate/kit/read_split.h"
#include "simgate/kit/tcp_server.h"

namespace simgate::kit {

class LineConnection;

// What a connection needs from the transport that owns it: its protocol. LineServer
// implements the last four; a transport implements the rest.
class LineHost {
 public:
  virtual ~LineHost() = default;
  // One complete line, without its '\n' (a '\r' before it is kept: the protocol decides).
  virtual void on_line(LineConnection& connection, std::string_view line) = 0;
  // A line exceeded max_message_bytes: `prefix` is its first KiB (to find the client's id),
  // `bytes` how much of it had arrived. Its rest is skipped.
  virtual void on_oversized_line(LineConnection& connection, std::string_view prefix, std::size_t bytes) = 0;
  // The lines passed since the last call may go to the core together: half-way through a
  // large read (`read_finished` false: run and answer them now if the client sends alone,
  // read_split.h, or wait for the end) and at the end of every read (run them; their replies
  // are written at write_replies()).
  virtual void on_lines_done(LineConnection& connection, bool read_finished) = 0;
  // The client shut down its sending side (or closed): it will send nothing more.
  virtual void on_input_ended(LineConnection& connection) = 0;
  // The connection closed (error, peer gone, limit exceeded or server stopping): forget it.
  virtual void on_closed(LineConnection& connection) = 0;

  // The connection stops reading for now: write the replies queued since the last write.
  virtual void write_replies() = 0;
  // Whether `connection` is the only one sending (ReadSplit::alone).
  virtual bool alone(const LineConnection& connection) = 0;
  // The connection is about to wait for its next bytes: true when the host's polling thread
  // will read its socket itself (read_now) until it parks it (read_async).
  virtual bool watch(LineConnection& connection) = 0;
  // The connection has replies queued: write them at the end of the burst.
  virtual void touch(LineConnection& connection) = 0;

 protected:
  friend class LineConnection;
  // What every connection of the host shares, kept by LineServer (the I/O thread).
  struct Shared {
    std::uint32_t tick = 0;                  // sweeps so far: the connections' clock
    HeldBytes held;                          // unfinished lines and unsent replies, all connections
    std::size_t freed = 0;                   // large buffers given back since the last sweep
  };
  Shared shared_;
};

struct LineLimits {
  std::size_t max_message_bytes = 1 << 20;    // longest line accepted
  std::size_t max_unsent_bytes = 8 << 20;     // unsent replies a reply may find before disconnecting
  std::size_t pause_at_unanswered = 0;        // replies owed that pause reading (0: never)
  std::size_t pause_at_unsent_bytes = 0;      // unsent bytes that pause reading (0: never)
  std::size_t read_bytes = 16384;             // the most one read takes
  const char* message_bytes_key = "max_message_bytes";  // the options' spelling, for messages
  const char* unsent_bytes_key = "max_unsent_bytes";    // the options' spelling, for messages

  // The byte limits of `options` (max_message_bytes, max_unsent_bytes, under their keys'
  // spelling); what pauses reading is the transport's choice.
  static LineLimits from(const TcpOptions& options) {
    LineLimits limits;
    limits.max_message_bytes = options.max_message_bytes;
    limits.max_unsent_bytes = options.max_unsent_bytes;
    limits.message_bytes_key = options.message_bytes_key;
    limits.unsent_bytes_key = options.unsent_bytes_key;
    return limits;
  }
};

class LineConnection : public std::enable_shared_from_this<LineConnection> {
 public:
  // `who` names the transport in logs ("Socket service manager"); `number` the connection
  // ("client #3 (127.0.0.1:51234)").
  LineConnection(boost::asio::ip::tcp::socket socket, LineHost& host, LineLimits limits, std::string_view who,
                 std::uint64_t number);
  virtual ~LineConnection() = default;
  LineConnection(const LineConnection&) = delete;
  LineConnection& operator=(const LineConnection&) = delete;

  // Starts reading.
  void start();
  // Watched by the host: reads what is waiting, without waiting, and handles it as an async
  // read's completion would; false when nothing was waiting.
  bool read_now();
  // No longer watched: waits for its next bytes through the event loop (an async read).
  void read_async();

  // Queues reply bytes (whole lines, '\n' included) for the next flush_writes(); a reply
  // that finds more than max_unsent_bytes already waiting (or the host's connections holding
  // more than max_buffered_bytes, this one some of them) closes the connection instead, and
  // so does one that takes the total past max_buffered_bytes and is not taken at once by
  // the socket (held_bytes.h).
  void queue(std::string_view bytes) {
    queue_with([bytes](std::string& out) { out.append(bytes); });
  }
  // queue() of what `format(std::string& out)` appends to `out`: a reply formatted straight
  // into the connection's outbox, without a copy.
  template <class Format>
  void queue_with(Format&& format) {
    const std::size_t waiting = outbox_.size() + in_flight_.size();
    // the usual case inline: open, within both budgets (room_for_reply() says the rest)
    if (closed_ || waiting > limits_.max_unsent_bytes || (waiting > 0 && host_.shared_.held.over())) [[unlikely]] {
      if (!room_for_reply()) return;
    }
    const std::size_t before = outbox_.size();
    format(outbox_);
    account(static_cast<std::ptrdiff_t>(outbox_.size() - before));
    if (host_.shared_.held.over()) [[unlikely]]
      write_or_close();
    else if (outbox_.size() >= k_coalesce_bytes) [[unlikely]]
      flush_writes();  // a large burst goes out as it grows
    else if (!touched_)
      host_.touch(*this);
  }
  // queue() of a line the client may miss (a progress report): dropped instead when more
  // than k_droppable_unsent_bytes already wait unsent, so that a client that does not read
  // loses old reports, never a reply, and is not disconnected for them. True if queued.
  static constexpr std::size_t k_droppable_unsent_bytes = 64 << 10;
  template <class Format>
  bool queue_droppable_with(Format&& format) {
    if (closed_ || outbox_.size() + in_flight_.size() > k_droppable_unsent_bytes) return false;
    queue_with(std::forward<Format>(format));
    return true;
  }
  // Writes what queue() gathered, unless a write is in flight (it takes them next).
  void flush_writes();
  // queue() and flush_writes().
  void send(std::string_view bytes) {
    queue(bytes);
    flush_writes();
  }

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

  // Closes the socket and tells the host; idempotent.
  void close(std::string_view reason);
  bool closed() const { return closed_; }
  // Sweeps (of LineServer) since it last read a line that is not blank, wrote or was owed
  // a reply; 0 while it owes one or has replies unsent (it is not idle then). Blank lines
  // keep nothing alive: a client sending only those is idle.
  std::uint32_t idle_ticks() const;
  // Sweeps since it last read a line that is not blank, wrote or was answered, even while
  // it owes replies (a client waiting for calls that do not end); 0 while it has replies
  // unsent.
  std::uint32_t silent_ticks() const;
  // Sweeps since its unfinished line began; 0 when there is none.
  std::uint32_t line_ticks() const;
  boost::asio::ip::tcp::socket::executor_type executor() { return socket_.get_executor(); }

  // "client #3 (127.0.0.1:51234)", for log messages.
  const std::string& label() const { return label_; }
  // Its number within the transport (3 above): what its calls carry as Call::client.
  std::uint64_t number() const { return number_; }
  // The client's address (unspecified when the socket had none).
  const boost::asio::ip::address& peer() const { return peer_; }

  // Whether the client may call services: true from the start unless the transport's
  // "auth" requires a token from this peer (auth.h); the protocol sets it when the client
  // presents the right one. `auth_required()`: it had to.
  bool authenticated() const { return authenticated_; }
  void set_authenticated() { authenticated_ = true; }

  // Reads in a row of a client sending alone before going back to the event loop.
  static constexpr int k_reads_in_a_row = 4;
  // Replies queued in one burst past which they are written without waiting for its end.
  static constexpr std::size_t k_coalesce_bytes = 256 * 1024;

 private:
  friend class LineServer;
  void read_more();
  void on_read(const boost::system::error_code& ec, std::size_t n);
  // on_read() without starting the next read: the lines, end of input or error.
  void handle_read(const boost::system::error_code& ec, std::size_t n);
  void consume(std::string_view data);
  void deliver(std::string_view line);  // to the host, unless it is an HTTP request line
  void oversized(std::string_view start, std::size_t bytes);
  // Whether a reply may be queued: false when closed, or closes it when the client does not
  // read its replies.
  bool room_for_reply();
  // A reply took the host's connections past max_buffered_bytes: written now, and the
  // connection closed when its socket leaves some of it unsent.
  void write_or_close();
  void start_write();
  void after_write();
  void maybe_finish();
  bool paused() const;
  // Adds to (or takes from) the bytes the host's connections hold; the partial line grows
  // only within max_buffered_bytes (false: the connection was closed instead).
  void account(std::ptrdiff_t bytes) { host_.shared_.held.add(bytes); }
  bool grow_line(std::string_view data);
  // The unfinished line with `end` appended, taken out of the connection.
  std::string take_line(std::string_view end = {});
  // A buffer a burst grew large is given back once empty.
  void release_if_large(std::string& buffer);
  void active() { active_tick_ = host_.shared_.tick; }

  boost::asio::ip::tcp::socket socket_;  // the connection
  LineHost& host_;                       // the transport (outlives every connection)
  LineLimits limits_;                    // from the transport options
  std::string who_;                      // the transport, for logs
  std::string label_;                    // the client, for logs
  std::uint64_t number_;                 // the connection's number within its transport
  boost::asio::ip::address peer_;        // the client's address
  bool authenticated_ = true;            // may call services (LineServer::add decides)
  std::vector<char> read_buffer_;        // one read's bytes (LineLimits::read_bytes)
  std::string partial_;                  // the start of an unfinished line
  bool discarding_ = false;              // skipping the rest of an oversized line
  bool reading_ = false;                 // a read is in flight, or its lines are being handled
  bool eof_ = false;                     // the client will send nothing more
  bool closed_ = false;                  // close() was called
  std::string outbox_;                   // replies waiting for the next write
  std::string in_flight_;                // replies being written
  bool writing_ = false;                 // a write is in flight
  std::size_t unanswered_ = 0;           // replies the protocol owes
  bool touched_ = false;                 // in its LineServer's touched list
  std::uint32_t active_tick_ = 0;        // the sweep of its last read, write or reply owed
  std::uint32_t line_tick_ = 0;          // the sweep its unfinished line began in
};

// The connections of one transport and what it does with all of them, on its I/O thread:
// the set (and its size for other threads), the connections touched by a burst of replies,
// the lone-client rules (ReadSplit, DirectReads), and the resource rules (a sweep every
// k_sweep while connections are open: line and idle timeouts, the buffers given back).
// A transport's manager derives from it and implements the protocol's LineHost calls.
class LineServer : public LineHost {
 public:
  // How often the connections are checked: timeouts are this precise.
  static constexpr std::chrono::milliseconds k_sweep = k_connection_sweep;

  // `who` names the transport in logs; `options`: its io_spin_us (0: the I/O thread never
  // polls, nothing is watched), max_connections, max_connections_per_peer, the timeouts,
  // max_buffered_bytes and auth.
  LineServer(std::string who, const TcpOptions& options);

  // Adds an accepted connection (unauthenticated when auth requires a token from its peer)
  // and starts it.
  void add(const std::shared_ptr<LineConnection>& connection);
  // Closes every connection ("server stopping"; on_closed() runs for each) and lets go of
  // them all and of the sweep's timer. A transport calls it on its I/O thread when it
  // stops, before its io_context is destroyed (a base class outlives the members, the
  // io_context among them).
  void close_all();
  std::size_t connection_count() const { return count_.load(std::memory_order_relaxed); }
  // For the listener (TcpListener::Handlers::refuse): why a connection from `peer` is
  // refused, or "": max_connections are open and none of them has been idle for idle_evict_s
  // (the one idle longest is closed to make room when one has; failing one, the one silent
  // longest while it waits for replies, whose calls end as its client's leaving ends them),
  // or its non-loopback address holds max_connections_per_peer.
  std::string refusal_reason(const boost::asio::ip::tcp::endpoint& peer);
  // True while max_connections are open (after eviction, as above).
  bool full();
  // The thread that polls reads the watched connection through this (IoThread::start).
  DirectReads<LineConnection>& direct_reads() { return direct_; }
  // Writes the replies of every touched connection (the end of a burst).
  void flush_touched();
  // Whether `connection` is the only one sending: a large read's first half runs early.
  bool alone(const LineConnection& connection) override { return read_split_.alone(&connection); }

  void write_replies() override { flush_touched(); }
  bool watch(LineConnection& connection) override;
  void touch(LineConnection& connection) override;

 protected:
  // Forgets `connection` (call from on_closed).
  void forget(LineConnection& connection);

 private:
  void schedule_sweep(const std::shared_ptr<LineConnection>& any);
  void sweep();
  std::uint32_t ticks(std::chrono::milliseconds duration) const { return sweep_ticks(duration); }

  std::string who_;                                             // for logs
  std::chrono::microseconds spin_;                              // io_spin_us
  std::size_t max_connections_;                                 // max_connections
  std::string connections_key_;                                 // its key as the options spell it
  PeerCounts per_peer_;                                         // max_connections_per_peer (connection_rules.h)
  TokenAuth auth_;                                              // who must present a token
  std::chrono::milliseconds idle_timeout_, idle_evict_, line_timeout_;  // 0: never
  std::unordered_set<std::shared_ptr<LineConnection>> connections_;  // open connections
  std::atomic<std::size_t> count_{0};                           // connections_.size(), for any thread
  std::vector<std::shared_ptr<LineConnection>> touched_;        // replies queued, not yet written
  ReadSplit read_split_;                                        // the lone client's large reads
  DirectReads<LineConnection> direct_;                          // the lone client read without the event loop
  std::optional<boost::asio::steady_timer> sweep_timer_;        // while connections are open
  bool sweeping_ = false;                                       // a sweep is scheduled
};

}  // namespace simgate::kit

#endif  // SIMGATE_KIT_LINE_CONNECTION_H_
