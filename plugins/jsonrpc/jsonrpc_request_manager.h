// plugins/jsonrpc/jsonrpc_request_manager.h — JSON-RPC 2.0 over TCP (newline-delimited).
//
// What: a RequestManager whose clients speak JSON-RPC 2.0, one message (request or batch)
// per `\n`-terminated line, in both directions. Method "component.service" (split at the
// last dot); params positional (array) or named (object). Sync calls answer after they
// ran; async calls answer when they complete, out of order, matched by id. Reserved
// methods: rpc.discover (OpenRPC document of the services served here), rpc.cancel
// {"id": X} (cancels the caller's own pending call), rpc.login {"token"} (with the "auth"
// option, clients that must authenticate (kit/auth.h) get -32005 for anything else first),
// and the data streams' rpc.streams, rpc.subscribe, rpc.unsubscribe, rpc.publish
// (jsonrpc_streams.cc; samples come as rpc.sample notifications). Wire details and the error table:
// docs/transports/jsonrpc.md.
//
// Terms:
//  - session: one accepted TCP connection; call ids are scoped to it.
//  - pending call: submitted to the core, its reply not yet produced.
//  - unsent bytes: replies queued on a session and not yet accepted by the kernel.
//
// Life cycle: the constructor reads the options (ConfigError on bad ones) and binds the
// listening socket (std::runtime_error if the port is taken); start() launches the I/O
// thread; stop() closes every connection, joins the thread and finishes what is still
// pending with Failure::shutdown. stop() is idempotent and the destructor calls it.
//
// Threads: one I/O thread runs the io_context (accept, read, parse, hand over, write),
// polling a little before it sleeps while events come close together and reading a lone
// client's socket itself meanwhile (simgate/kit/idle_spin.h).
// The calls of one read go to the core together with run_or_submit: if the simulation
// lock is free, the I/O thread runs them itself and on_service_completion is called on it
// (the reply is queued at once). If the lock is held, the simulation thread runs them later
// and the core hands their outcomes over to the I/O thread (deliver_on_this_thread): one
// drain_completions() per burst. on_service_completion always runs on the I/O thread, and a
// connection's replies keep the order in which outcomes were produced.
// Sessions, pending calls and batches are touched by the I/O thread only.
#ifndef SIMGATE_PLUGINS_JSONRPC_JSONRPC_REQUEST_MANAGER_H_
#define SIMGATE_PLUGINS_JSONRPC_JSONRPC_REQUEST_MANAGER_H_

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <unordered_set>
#include <vector>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>

#include "protocol.h"
#include "session.h"
#include "simgate/core/request_manager.h"
#include "simgate/kit/line_connection.h"
#include "simgate/kit/recycling_map.h"
#include "simgate/kit/tcp_server.h"

namespace simgate::jsonrpc {

// The transport's options (plugin option keys in parentheses).
struct Options {
  // the keys every TCP transport has; here: port 4001, max_message_bytes 8 MiB (one line,
  // batch included), max_unsent_bytes 16 MiB, max_connections 512, max_in_flight 1024
  kit::TcpOptions tcp;
  std::size_t max_depth = 128;  // ("max_depth") bracket nesting of one message
  std::size_t stream_queue = 16;  // ("stream_queue") samples a subscription keeps for a slow client

  // Reads and checks `options`; unknown keys are errors (ConfigError naming the key).
  static Options parse(const json& options);
};

class JsonRpcRequestManager : public RequestManager, private kit::LineServer {
 public:
  // Parses the options and binds; throws ConfigError or std::runtime_error.
  explicit JsonRpcRequestManager(const json& options);
  ~JsonRpcRequestManager() override;
  // What the constructor checks of `options`, without binding (the plugin's validate).
  static void validate_options(const json& options) { (void)Options::parse(options); }
  std::size_t client_count() const override { return connection_count(); }

  void start() override;
  void stop() override;
  // {"tcp://127.0.0.1:<port>"} with the bound port.
  std::vector<std::string> endpoints() const override;

  const Options& options() const { return options_; }
  std::uint16_t port() const { return listener_.port(); }

 protected:
  // On the I/O thread (the core hands outcomes of other threads over): queues the reply.
  void on_service_completion(RequestId id, Outcome&& outcome) override;
  // rpc.progress {id, status: "RUNNING", data} to a call that asked (_meta.progress); lost,
  // not queued, when the client lets replies pile up unread (LineConnection::queue_droppable_with).
  void on_service_progress(RequestId id, json&& value) override;

 private:
  struct Batch;

  explicit JsonRpcRequestManager(Options options);

  // kit::LineHost: the protocol (I/O thread)
  void on_line(kit::LineConnection& connection, std::string_view line) override;
  void on_oversized_line(kit::LineConnection& connection, std::string_view prefix, std::size_t bytes) override;
  void on_lines_done(kit::LineConnection& connection, bool read_finished) override;
  void on_input_ended(kit::LineConnection& connection) override;
  void on_closed(kit::LineConnection& connection) override;

  // Where the response of one call goes.
  struct ReplyTo {
    std::weak_ptr<Session> session;  // gone when the client left
    json id;                         // JSON-RPC id (null for notifications)
    bool notification = false;       // no response at all
    std::shared_ptr<Batch> batch;    // set for batch entries
    std::size_t index = 0;           // entry index inside the batch
    std::string id_text;             // the id's exact text when dump() would round it (float_id_texts)
  };
  // A call submitted to the core and not yet finished (or an rpc.cancel waiting for its answer).
  struct Pending {
    ReplyTo to;          // where the response goes
    std::string method;  // "component.service", for error data
    std::string id_key;  // the session's key for the id, dump(id) ("" when untracked)
    bool cancel = false;  // an rpc.cancel waiting for the core's answer (outcome value: found)
    // when its table node is kept for reuse: drop the references, keep the strings' capacity
    void recycle() { to = ReplyTo{}; }
  };

  // I/O thread.
  // A new connection (the listener keeps the count under max_connections).
  void accept(boost::asio::ip::tcp::socket socket);
  void handle_message(const std::shared_ptr<Session>& session, std::string_view line);
  // Handles one request object: answers at once (into `to`), or queues a call in to_submit_.
  void handle_request(const std::shared_ptr<Session>& session, json& message, ReplyTo to);
  // Handles one valid request (its params and id_text are moved from).
  void dispatch(const std::shared_ptr<Session>& session, Request& request, ReplyTo to);
  // rpc.login {"token"}: the connection may call services (kit/auth.h); a wrong token is
  // answered -32005 and closes the connection.
  void handle_login(const std::shared_ptr<Session>& session, const json& params, ReplyTo to);
  void handle_cancel(const std::shared_ptr<Session>& session, const std::string& method,
                     const json& params, ReplyTo to);
  // Hands the calls gathered from the current read to the core (run_or_submit).
  void flush_submissions();
  // I/O thread, woken by the core: finishes the outcomes the simulation thread produced,
  // then one write per connection.
  void drain_completions();
  void finish_call(RequestId id, Outcome&& outcome);
  // Queues `response` where `to` says (into its batch, or on its connection); written at the
  // end of the burst (flush_touched).
  void reply(ReplyTo& to, std::optional<json> response);
  void shutdown_io();

  // ---- data streams (jsonrpc_streams.cc)
  // One subscription of a connection to an output stream.
  struct StreamSub {
    std::uint64_t id = 0;                               // what rpc.subscribe answered
    std::weak_ptr<Session> session;                     // its connection
    std::shared_ptr<StreamSubscription> subscription;  // the core's queue
  };
  // The streams this transport carries, as rpc.streams lists them.
  json stream_list() const;
  // rpc.streams, rpc.subscribe, rpc.unsubscribe, rpc.publish; false for any other method.
  bool handle_stream_method(const std::shared_ptr<Session>& session, const std::string& method, const json& params,
                            ReplyTo& to);
  void subscribe(const std::shared_ptr<Session>& session, const json& params, ReplyTo& to);
  bool unsubscribe(Session& session, std::uint64_t id);
  void publish(const json& params, ReplyTo& to);
  // A subscription has samples (the thread that holds the simulation lock): one post per burst.
  void wake_streams();
  // Sends every subscription's samples as rpc.sample notifications; ends those whose
  // component was deleted (rpc.unsubscribed) or whose connection is gone.
  void drain_streams();
  // Ends the subscriptions of `session` (and those of connections gone); null: all.
  void end_subscriptions(const Session* session);

  Options options_;                                  // as parsed
  boost::asio::io_context io_;                       // all sockets; declared first, destroyed last
  kit::TcpListener listener_;                        // the listening socket, bound in the constructor
  kit::IoThread io_thread_;                          // runs io_
  bool stopping_ = false;                            // shutdown_io() ran (I/O thread)
  std::uint64_t next_session_ = 1;                   // numbers connections in logs (I/O thread)
  static constexpr std::size_t k_spare_nodes = 256;  // table nodes kept for reuse (per manager, per connection)
  kit::RecyclingMap<RequestId, Pending> pending_{k_spare_nodes};  // submitted calls (I/O thread)
  Request request_;                                  // the message being read by the fast path (I/O thread)
  // calls of the current read, handed over together: the first to_submit_count_ of
  // to_submit_; the objects are refilled from read to read (I/O thread)
  static constexpr std::size_t k_kept_calls = 1024;
  std::vector<std::pair<RequestId, Call>> to_submit_;
  std::size_t to_submit_count_ = 0;
  std::string line_;                                 // a response being built (I/O thread; capacity reused)
  std::vector<StreamSub> stream_subs_;               // every connection's subscriptions (I/O thread)
  std::uint64_t next_subscription_ = 1;              // rpc.subscribe's numbers (I/O thread)
  std::vector<SamplePtr> samples_;                   // drain_streams' scratch (I/O thread)
  std::atomic<bool> streams_woken_{false};           // a drain_streams is posted
};

}  // namespace simgate::jsonrpc

#endif  // SIMGATE_PLUGINS_JSONRPC_JSONRPC_REQUEST_MANAGER_H_
