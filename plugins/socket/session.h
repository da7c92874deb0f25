// session.h — one client connection of the socket transport.
//
// A Session owns its TCP socket, turns the byte stream into lines and writes replies.
//   - Reading: bytes accumulate until '\n', so a request split over several TCP segments
//     works and several requests in one segment are all seen. A line longer than
//     `max_message_bytes` is answered FAILED by the host (on_oversized_line) and skipped up to
//     its '\n'; the connection keeps working. Reading pauses while the connection has
//     `max_in_flight` unanswered requests (backpressure instead of unbounded queues).
//     After a large read from a client sending alone, the session reads on while bytes
//     are already waiting (k_reads_in_a_row), and the host writes the replies of those
//     reads together (SessionHost::write_replies). When the host watches the session
//     (SessionHost::watch: a lone client while the I/O thread polls), no async read is
//     started: the polling thread calls read_now() until it parks the session
//     (read_async()).
//   - Writing: flush_writes() writes what was queued straight to the socket (non-blocking)
//     while the socket takes it all; otherwise one async write in flight, and replies
//     queued meanwhile are written together in the next one (coalesced). The host may
//     queue() several replies and flush_writes() once. If the unsent bytes exceed
//     `max_unsent_bytes` the client is not reading: the session is closed and forgotten.
//   - Pending requests: the client's ids of requests not yet answered, mapped to the core's
//     RequestId, so ids and cancel are scoped to the connection.
//   - End of input (client shut down its sending side, or closed): the host is told
//     (on_input_ended: it may cancel the async requests of a client that left), and the
//     session stays open until every pending reply has been written, then closes (so
//     `echo req | nc` gets its answer).
//
// Life cycle: created by the acceptor, start()ed, kept alive by its own pending handlers
// (shared_from_this) and by the host's session set; close() ends it (idempotent).
// Threads: every member function runs on the host's single I/O thread (io_context::run).
#ifndef SIMGATE_PLUGINS_SOCKET_SESSION_H_
#define SIMGATE_PLUGINS_SOCKET_SESSION_H_

#include <array>
#include <cstddef>
#include <memory>
#include <string>
#include <string_view>
#include <utility>  // before Asio: Boost 1.74 needs std::exchange in C++20 mode

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>

#include "simgate/kit/id_table.h"
#include "simgate/kit/read_split.h"
#include "simgate/core/status.h"

namespace simgate::socket {

class Session;

// What a session needs from the server that owns it (the SocketRequestManager).
class SessionHost {
 public:
  virtual ~SessionHost() = default;
  // One complete line, without '\n'.
  virtual void on_line(const std::shared_ptr<Session>& session, std::string_view line) = 0;
  // The lines passed to on_line/on_oversized_line since the last call may go to the core
  // together: half-way through a read of at least kit::ReadSplit::k_min_bytes, where the host
  // may run the first half and write its replies before parsing the rest
  // (simgate/kit/read_split.h), or wait for the end; and at the end of every read
  // (`read_finished`), where it runs them and keeps their replies for write_replies().
  virtual void on_lines_done(const std::shared_ptr<Session>& session, bool read_finished) = 0;
  // The session stops reading for now (nothing more is waiting, or it read enough in a
  // row): write the replies kept since the last write.
  virtual void write_replies() = 0;
  // Whether `session` is the only connection sending (kit::ReadSplit::alone): then, after a
  // large read, it reads on while bytes are waiting before the replies are written.
  virtual bool alone(const Session& session) = 0;
  // The session is about to wait for its next bytes: true when the host's polling thread
  // will read its socket itself (read_now) instead of an async read, until it parks it
  // (read_async). For a lone client waiting for each answer (idle_spin.h).
  virtual bool watch(Session& session) = 0;
  // A line exceeded the limit; `prefix` is its beginning (to find the client's id).
  virtual void on_oversized_line(const std::shared_ptr<Session>& session, std::string_view prefix) = 0;
  // The client shut down its sending side (or closed): it will send nothing more. The
  // session stays open until its pending replies are written, then closes.
  virtual void on_input_ended(const std::shared_ptr<Session>& session) = 0;
  // The session closed (error, peer gone, limit exceeded or server stopping).
  virtual void on_session_closed(const std::shared_ptr<Session>& session) = 0;
};

struct SessionLimits {
  std::size_t max_message_bytes = 1 << 20;        // longest request line accepted
  std::size_t max_unsent_bytes = 8 << 20;         // unsent replies before disconnecting
  std::size_t max_in_flight = 1024;               // unanswered requests before pausing reads
  const char* message_bytes_key = "max_message_bytes";  // the options' spelling, for messages
  const char* unsent_bytes_key = "max_unsent_bytes";    // the options' spelling, for messages
};

class Session : public std::enable_shared_from_this<Session> {
 public:

  Session(boost::asio::ip::tcp::socket socket, SessionHost& host, SessionLimits limits,
          std::uint64_t number);

  // Starts reading.
  void start();
  // Watched by the host (SessionHost::watch): reads what is waiting, without waiting, and
  // handles it as an async read's completion would; false when nothing was waiting.
  bool read_now();
  // No longer watched: waits for its next bytes through the event loop (an async read).
  void read_async();
  // Queues reply bytes (whole lines) and writes them as soon as possible.
  void send(std::string_view bytes);
  // Queues reply bytes without starting a write (several replies, then one flush_writes()).
  void queue(std::string_view bytes);
  // Starts writing what queue() gathered, unless a write is in flight (it takes them next).
  void flush_writes();
  // Closes the socket and tells the host; idempotent.
  void close(std::string_view reason);
  bool closed() const { return closed_; }

  // Pending requests of this connection, by the client's id.
  const kit::IdTable::Entry* find_pending(std::string_view client_id) const { return pending_.find(client_id); }
  // Registers a request under the client's id: returns its entry, whose `id` the caller
  // sets at once (the pointer is valid until the table next changes), or null when that id
  // is already pending here.
  kit::IdTable::Entry* add_pending(std::string_view client_id) { return pending_.insert(client_id); }
  // Forgets a request that will get no answer of its own (its line was refused).
  void drop_pending(std::string_view client_id) { pending_.erase(client_id); }
  // Queues the reply "<client id> <status>[ <value>]" to the pending request `id`, whose
  // client id hashes to `client_id_hash` (its entry's hash), and forgets the request;
  // resumes reading if it was paused. The write starts at the next flush_writes().
  void answer(std::size_t client_id_hash, RequestId id, std::string_view status, const json* value);
  const kit::IdTable& pending() const { return pending_; }
  // A reply the host made itself (an error) but that must follow the replies of earlier
  // requests travels through the core in order: defer_reply() when it leaves,
  // queue_deferred_reply() when it comes back.
  void defer_reply();
  void queue_deferred_reply(std::string_view bytes);
  // Requests or deferred replies not answered yet: a new error reply must wait for them.
  bool has_unanswered() const { return !pending_.empty() || deferred_replies_ > 0; }

  // "client #3 (127.0.0.1:51234)", for log messages.
  const std::string& label() const { return label_; }

 private:
  void read_more();
  void on_read(const boost::system::error_code& ec, std::size_t n);
  // A large read's next read is often waiting already (a client pipelining alone): it is
  // read at once, without going back to the event loop, and the replies of both are
  // written together. At most this many reads in a row.
  static constexpr int k_reads_in_a_row = 4;
  // on_read() without starting the next read: the lines, end of input or error.
  void handle_read(const boost::system::error_code& ec, std::size_t n);
  void consume(std::string_view data);
  void start_write();
  void maybe_finish();
  // Closes the session when its unsent replies exceed the limit (the client does not read).
  void check_unsent();

  boost::asio::ip::tcp::socket socket_;   // the connection
  SessionHost& host_;                     // the server (outlives every session)
  SessionLimits limits_;                  // from the transport options
  std::string label_;                     // for logs
  std::array<char, 16384> read_buffer_;   // one read's bytes
  std::string partial_;                   // the start of an unfinished line
  bool discarding_ = false;               // skipping the rest of an oversized line
  bool reading_ = false;                  // a read is in flight, or its lines are being handled
  bool eof_ = false;                      // the client will send nothing more
  bool closed_ = false;                   // close() was called
  std::string outbox_;                    // replies waiting for the next write
  std::string in_flight_;                 // replies being written
  bool writing_ = false;                  // a write is in flight
  kit::IdTable pending_;                       // client id -> core request id
  std::size_t deferred_replies_ = 0;      // host error replies travelling behind earlier requests
};

}  // namespace simgate::socket

#endif  // SIMGATE_PLUGINS_SOCKET_SESSION_H_
