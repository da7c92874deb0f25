// socket_request_manager.h — the `socket` transport: MORSE's text protocol over TCP.
//
// A SocketRequestManager ("Socket service manager", as in MORSE's error messages) listens
// on a TCP port (default 127.0.0.1:4000) and serves any number of clients speaking the
// line protocol of wire.h. Each line becomes a core request (submit); each outcome comes
// back through on_service_completion and is written to the connection that asked, with the
// client's id. Ids and cancel are scoped to the connection.
//
// Options (plugins/socket/README.md): host, port (0 = ephemeral), success_word
// ("SUCCESS" | "OK"), max_connections, max_message_bytes, max_unsent_bytes, max_in_flight
// (named as on the JSON-RPC transport; the old names max_clients, max_line_bytes,
// max_pending_replies_bytes, max_pending_requests are accepted with a warning until the next
// release), io_spin_us, global_policy ("reject" | "preempt"), on_disconnect ("cancel" |
// "let_run": what becomes of the async requests of a client that leaves, or ends its
// sending side), progress_interval_ms (the shortest time between two progress lines of one
// request, as on the JSON-RPC transport), timeouts ({"default_ms": N, "services":
// {"robot.waypoint.goto": N}}: the calls' deadlines, Call::timeout, since MORSE's lines have
// no place for one; past it the reply is FAILED with the core's message and the async
// service is interrupted), stream_port and stream_queue (the datastreams, below).
//
// Datastreams (issue #21, datastreams.h): the streams the configuration gives this transport
// get a TCP port each, MORSE's socket datastreams (from stream_port, 60000 by default; a
// reader keeps stream_queue samples), and `simulation list_streams`, `get_stream_port`,
// `get_all_stream_ports` say where; `simulation details` names them by MORSE's classes.
//
// Progress (issue #20): nothing changes for a MORSE client. A connection that sends
// `<id> simgate progress` (answered `<id> SUCCESS`) gets `<id> PROGRESS <json>` lines for the
// reports of its async requests sent from then on, before their final reply.
//
// Built on the transport kit: the shared options, the listener (100 ms back-off after
// accept() fails; a connection over max_connections is told why in one line,
// `- FAILED "too many connections (max_connections 1024)"`, then closed) and the I/O thread
// (simgate/kit/tcp_server.h); the connections (simgate/kit/line_connection.h: framing,
// limits, coalesced writes, direct reads). This file is the protocol.
//
// Life cycle: the constructor validates the options and binds the listening socket (a
// port in use fails here, with a clear message); start() launches the I/O thread;
// stop() closes the acceptor and every connection and joins the thread (idempotent; the
// destructor calls it, then finishes requests still pending). start() also opens the
// datastream ports (the streams are known then) and registers their services; stop() closes
// them with the rest.
//
// Threads: one I/O thread runs the io_context (polling a little before it sleeps while
// events come close together: simgate/kit/idle_spin.h, reading a lone client's socket
// itself while it polls: kit::LineServer); it owns the acceptor, every Session and the
// request table, so none of them needs a lock.
//
// The requests found in one read go to the core together (run_or_submit). When the
// simulation lock is free, the I/O thread runs them itself: their outcomes come back to
// on_service_completion on this same thread, are queued on their connections, and one write
// per connection sends them: no thread hand-off at all. When the simulation is stepping,
// they are queued and run on the simulation thread; the core hands their outcomes over to
// the I/O thread (deliver_on_this_thread), which flushes every outcome of the burst at once.
// on_service_completion therefore always runs on the I/O thread. The transport's own error
// replies that must wait for earlier requests travel through the core in order
// (answer_in_order), so a connection's replies keep the order of its requests.
#ifndef SIMGATE_PLUGINS_SOCKET_SOCKET_REQUEST_MANAGER_H_
#define SIMGATE_PLUGINS_SOCKET_SOCKET_REQUEST_MANAGER_H_

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>

#include "datastreams.h"
#include "simgate/morse/params_parser.h"
#include "session.h"
#include "simgate/core/request_manager.h"
#include "simgate/kit/line_connection.h"
#include "simgate/kit/request_slots.h"
#include "simgate/kit/tcp_server.h"
#include "simgate/morse/wire.h"

namespace simgate::socket {

// The transport's options, as parsed (the README lists them).
struct SocketOptions {
  kit::TcpOptions tcp;                   // the keys every TCP transport has (port 4000 by default)
  std::string success_word = "SUCCESS";  // "SUCCESS" (MORSE) or "OK" (MORSE's docs)
  // "timeouts": every call's deadline (zero: none), and per service ("component.service")
  std::chrono::milliseconds default_timeout{0};
  std::map<std::string, std::chrono::milliseconds, std::less<>> service_timeouts;
  // ("stream_port") the first datastream's port; 0: any free port each
  std::uint16_t stream_port = 60000;
  // ("stream_queue") samples a datastream reader keeps (core/streams.h)
  std::size_t stream_queue = 16;

  // Every check of the options, resolving the host but binding nothing. Throws ConfigError.
  static SocketOptions parse(const json& options);
};

class SocketRequestManager : public RequestManager, private kit::LineServer {
 public:
  explicit SocketRequestManager(const json& options);
  ~SocketRequestManager() override;
  // What the constructor checks of `options`, without binding (the plugin's validate).
  static std::vector<std::string> validate_options(const json& options) {
    return SocketOptions::parse(options).tcp.warnings;
  }

  void start() override;
  void stop() override;
  std::vector<std::string> endpoints() const override;
  std::size_t client_count() const override { return connection_count(); }
  // MORSE's classes, what `simulation details` shows in stream_interfaces (pymorse then
  // asks get_stream_port).
  std::string datastream_class(StreamDirection direction) const override;

  // The bound TCP port (useful with port 0).
  std::uint16_t port() const { return listener_.port(); }

 protected:
  void on_service_completion(RequestId id, Outcome&& outcome) override;
  // `<id> PROGRESS <json>` to a request whose connection opted in (`<id> simgate progress`);
  // lost, not queued, when the client lets replies pile up unread
  // (LineConnection::queue_droppable_with).
  void on_service_progress(RequestId id, json&& value) override;
  // A component came or went (a robot spawned or deleted): the datastreams open the ports
  // of new streams (Datastreams::sync, posted to the I/O thread).
  void on_services_changed() override;

 private:
  // kit::LineServer: the protocol (I/O thread)
  void on_line(kit::LineConnection& connection, std::string_view line) override;
  void on_oversized_line(kit::LineConnection& connection, std::string_view prefix,
                         std::size_t bytes) override;
  void on_messages_done(kit::Connection& connection, bool read_finished) override;
  void on_input_ended(kit::LineConnection& connection) override;
  void on_closed(kit::Connection& connection) override;

  // An error reply waiting for the outcomes of the connection's earlier requests.
  struct DeferredReply {
    kit::ConnectionRef<Session> session;  // the connection (null once it closed)
    std::string line;                     // the formatted reply
  };
  // Hands the calls gathered from the current read to the core (run_or_submit); their
  // replies are queued on their connections.
  void run_calls();
  // run_calls(), then writes the replies (flush_touched); called half-way through a read
  // and before anything that must follow the read's calls.
  void run_batch();
  // I/O thread, woken by the core: delivers the outcomes the simulation thread produced,
  // then starts one write per connection.
  void flush_replies();

  explicit SocketRequestManager(SocketOptions options);
  // A new connection (the listener keeps the count under max_connections).
  void accept(boost::asio::ip::tcp::socket socket);
  // The client left (on_disconnect "cancel"): its async requests are cancelled. Those of
  // the read being handled are cancelled once they have gone to the core (run_calls).
  void cancel_requests_of(const Session& session);
  // Queues the reply to `id` on its connection (nothing if the connection is gone). Never
  // throws: a failure is logged.
  void deliver(RequestId id, const Outcome& outcome);
  // A line from a client that must present the token first (kit/auth.h): `auth <token>`
  // answers "auth SUCCESS" (or closes the connection on a wrong token); any other line is
  // answered FAILED, naming what to send.
  void authenticate(Session& session, std::string_view line);
  // Answers FAILED `message` after the connection's earlier requests have been answered.
  void fail_in_order(Session& session, std::string_view id, std::string message);
  // Answers "<id> <status>[ <value>]" after the connection's earlier requests.
  void reply_in_order(Session& session, std::string_view id, std::string_view status,
                      const json* value);
  // `<id> simgate progress [true|false]`: opts the connection in to (or out of) progress
  // lines for the requests it sends from now on; answered SUCCESS, or FAILED for bad params.
  void set_progress(Session& session, const RequestLine& request);
  void close_all();
  // The deadline of a call of `component`.`service` (options_.timeouts).
  std::chrono::milliseconds timeout_for(const std::string& component, const std::string& service);

  // A request sent to the core and not yet answered. Entries of a connection are erased
  // when it closes (on_closed), so the session pointer is valid while its entry is.
  struct Pending {
    Session* session = nullptr;      // the connection that asked
    std::size_t client_id_hash = 0;  // finds the request in the session's pending table
  };

  SocketOptions options_;           // as parsed
  boost::asio::io_context io_;      // runs every handler, on the I/O thread
  kit::TcpListener listener_;       // the listening socket, bound in the constructor
  kit::IoThread io_thread_;         // runs io_
  Datastreams datastreams_;         // the stream ports, opened by start()
  kit::ConnectionLimits limits_;    // per-connection limits, from options_
  bool stopping_ = false;           // close_all() runs: closed sessions cancel nothing (I/O thread)
  std::uint64_t next_session_ = 1;  // numbers sessions in logs
  kit::RequestSlots<Pending>
      requests_;             // unanswered requests, by the ids it gives them (I/O thread)
  std::string scratch_;      // reply formatting buffer (I/O thread)
  std::string timeout_key_;  // "component.service", looked up in service_timeouts (I/O thread)
  // calls of the current read, not yet handed to the core: the first batch_count_ of batch_;
  // the objects are reused from read to read, at most k_kept_calls of them kept (I/O thread)
  static constexpr std::size_t k_kept_calls = 1024;
  std::vector<std::pair<RequestId, Call>> batch_;
  std::size_t batch_count_ = 0;
  std::vector<RequestId>
      cancel_after_batch_;    // cancels of a client that left, after the batch (I/O thread)
  ParamsParse params_error_;  // the last parameters syntax error (I/O thread)
  json progress_params_;      // set_progress's parameters (I/O thread)
  // error replies travelling through the core behind earlier requests, by the
  // new_request_id() their answer_in_order() carries (I/O thread)
  std::unordered_map<RequestId, DeferredReply> deferred_replies_;
};

}  // namespace simgate::socket

#endif  // SIMGATE_PLUGINS_SOCKET_SOCKET_REQUEST_MANAGER_H_
