// simgate/jsonrpc/engine.h — JSON-RPC 2.0 served over any framing: the protocol
// both JSON-RPC transports share (newline-delimited over TCP: the `jsonrpc` plugin;
// WebSocket text messages: the `websocket` plugin).
//
// What: a RequestManager whose clients speak JSON-RPC 2.0, one message (request or batch)
// per frame (a line, a WebSocket message), in both directions. Method "component.service"
// (split at the last dot); params positional (array) or named (object). Sync calls answer
// after they ran; async calls answer when they complete, out of order, matched by id.
// Reserved methods: rpc.discover (OpenRPC document of the services served here),
// rpc.cancel {"id": X} (cancels the caller's own pending call), rpc.login {"token"} (with
// the "auth" option, clients that must authenticate (kit/auth.h) get -32005 for anything
// else first), and the data streams' rpc.streams, rpc.subscribe, rpc.unsubscribe,
// rpc.publish (engine_streams.cc; samples come as rpc.sample notifications). Wire
// details and the error table: docs/transports/jsonrpc.md.
//
// The engine knows nothing of sockets. A transport derives from JsonRpcEngine (and from a
// kit server: kit::LineServer, kit::WebSocketServer), owns the listener and the
// connections, hands each received message to handle_message() and the end of each read to
// flush_submissions(), and writes the replies the engine queued on its sessions when
// flush_replies() is called (once per burst). Its connection type derives from the kit's
// connection of its framing and from jsonrpc::Session, whose one call of its own,
// queue_message(), frames a message the transport's way (a line, a WebSocket text message).
// The engine is compiled once (libsimgate_protocol_jsonrpc), for every framing.
//
// Terms:
//  - session: one client connection; call ids are scoped to it.
//  - pending call: submitted to the core, its reply not yet produced.
//
// Threads: every member runs on the transport's one I/O thread, except wake_streams() (the
// thread that holds the simulation lock). The calls of one read go to the core together
// with run_or_submit: if the simulation lock is free, the I/O thread runs them itself and
// on_service_completion is called on it (the reply is queued at once). If the lock is
// held, the simulation thread runs them later and the core hands their outcomes over to
// the I/O thread (deliver_on_this_thread, posted to io_): one drain_completions() per
// burst. A connection's replies keep the order in which outcomes were produced.
#ifndef SIMGATE_JSONRPC_ENGINE_H_
#define SIMGATE_JSONRPC_ENGINE_H_

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>  // before Asio: Boost 1.74 needs std::exchange in C++20 mode
#include <vector>

#include <boost/asio/io_context.hpp>

#include "simgate/core/request_manager.h"
#include "simgate/jsonrpc/protocol.h"
#include "simgate/kit/connection.h"
#include "simgate/kit/id_table.h"
#include "simgate/kit/request_slots.h"
#include "simgate/kit/tcp_server.h"

namespace simgate::jsonrpc {

// The options of a JSON-RPC transport (plugin option keys in parentheses).
struct Options {
  // the keys every TCP transport has; JSON-RPC's defaults: max_message_bytes 8 MiB (one
  // message, batch included), max_unsent_bytes 16 MiB, max_connections 512, max_in_flight
  // 1024; the port is the transport's (jsonrpc 4001, websocket 8090)
  kit::TcpOptions tcp;
  std::size_t max_depth = 128;    // ("max_depth") bracket nesting of one message
  std::size_t stream_queue = 16;  // ("stream_queue") samples a subscription keeps for a slow client

  // Reads and checks `options` of the transport `transport` (its name, for warnings)
  // whose default port is `port`; unknown keys are errors (ConfigError naming the key).
  static Options parse(const json& options, std::string_view transport = "jsonrpc",
                       std::uint16_t port = 4001);
};

// What a session keeps of its pending calls: the client's id (its dumped JSON) -> the
// core's request id, so that ids and rpc.cancel are scoped to the connection.
class SessionCalls {
 public:
  // Remembers the call `id` under the client's id: the key's hash (for forget_call), or
  // nullopt (nothing changed) when a pending call has that id already.
  std::optional<std::size_t> track(std::string_view key, RequestId id) {
    kit::IdTable::Entry* entry = calls_.insert(key);
    if (!entry) return std::nullopt;
    entry->id = id;
    return entry->hash;
  }
  std::optional<RequestId> find(const std::string& key) const {
    const kit::IdTable::Entry* entry = calls_.find(key);
    if (!entry) return std::nullopt;
    return entry->id;
  }
  // The call `id`, tracked under a key of hash `key_hash`, finished: found without hashing
  // or comparing the key again.
  void forget_call(std::size_t key_hash, RequestId id) {
    if (const kit::IdTable::Entry* entry = calls_.find(key_hash, id)) calls_.erase(entry);
  }
  // The calls to cancel when the client leaves.
  std::vector<RequestId> pending_calls() const {
    std::vector<RequestId> ids;
    ids.reserve(calls_.size());
    calls_.for_each([&](const kit::IdTable::Entry& e) { ids.push_back(e.id); });
    return ids;
  }

 private:
  kit::IdTable calls_;  // dumped JSON-RPC id -> the core's request id
};

// One client connection as the engine sees it: the kit's connection of the transport's
// framing (`connection`), the ids of its pending calls (SessionCalls), and how a message is
// framed on it (queue_message, the transport's).
class Session : public SessionCalls {
 public:
  explicit Session(kit::Connection& connection) : connection_(connection) {}
  virtual ~Session() = default;
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

  // Queues one message (request answer, notification); the transport adds its framing.
  virtual void queue_message(std::string_view text) = 0;
  // Queues the message `format(std::string&)` appends, unless the client lets messages pile
  // up unread (kit::Connection::k_droppable_unsent_bytes): false, dropped.
  template <class Format>
  bool queue_droppable_message(Format&& format) {
    if (!connection_.room_for_droppable()) return false;
    droppable_.clear();
    format(droppable_);
    queue_message(droppable_);
    if (droppable_.capacity() > kit::Connection::k_kept_buffer_bytes)
      std::string().swap(droppable_);
    return true;
  }
  // This session, sharing its connection's ownership (what outlives the I/O thread's
  // handler: a posted task).
  std::shared_ptr<Session> shared() {
    return std::shared_ptr<Session>(connection_.shared_from_this(), this);
  }
  // This session as a reply remembers it: null once its connection closed, no atomic
  // operation (kit::ConnectionRef; the I/O thread's).
  kit::ConnectionRef<Session> ref() { return {connection_, *this}; }

  // Calls, notifications and cancels in flight (max_in_flight), each until done().
  std::size_t in_flight() const { return connection_.unanswered(); }
  void add_in_flight() { connection_.expect_reply(); }
  // A call (or cancel) in flight produced its reply (its id, if tracked, is forgotten by
  // forget_call).
  void done() { connection_.replied(); }
  bool authenticated() const { return connection_.authenticated(); }
  void set_authenticated() { connection_.set_authenticated(); }
  const std::string& label() const { return connection_.label(); }
  std::uint64_t number() const { return connection_.number(); }
  bool closed() const { return connection_.closed(); }
  void flush_writes() { connection_.flush_writes(); }
  void end(std::string_view reason, kit::Ending how) { connection_.end(reason, how); }

 private:
  kit::Connection& connection_;  // the session's connection (its other base)
  std::string droppable_;        // a droppable message being formatted
};

class JsonRpcEngine : public RequestManager {
 public:
  const Options& options() const { return options_; }

 protected:
  // `who` names the transport in logs ("JSON-RPC service manager"); `tag` is its plugin
  // name ("jsonrpc"), for short log lines.
  JsonRpcEngine(std::string who, std::string tag, Options options);

  // On the I/O thread (the core hands outcomes of other threads over): queues the reply.
  void on_service_completion(RequestId id, Outcome&& outcome) override;
  // rpc.progress {id, status: "RUNNING", data} to a call that asked (_meta.progress); lost,
  // not queued, when the client lets replies pile up unread (queue_droppable_message).
  void on_service_progress(RequestId id, json&& value) override;

  // ---- for the transport (I/O thread)
  // Writes the replies queued on every session since the last call (once per burst).
  virtual void flush_replies() = 0;
  // Names the I/O thread as the one outcomes are delivered on (call it first on that thread).
  void deliver_here();
  // One message received from `session` (a line without its '\n', a text message).
  void handle_message(Session& session, std::string_view text);
  // Hands the calls gathered from the current read to the core (run_or_submit).
  void flush_submissions();
  // The client will send nothing more: under "on_disconnect": "cancel" its calls end.
  void input_ended(Session& session);
  // The connection closed: its subscriptions end, and its calls unless stopping.
  void session_closed(Session& session);
  // Stopping (on the I/O thread, before the connections close): ends every subscription.
  void stop_io();
  // After the I/O thread ended: finish what the core still holds with Failure::shutdown.
  void finish_stop();

  Options options_;             // as parsed
  boost::asio::io_context io_;  // all sockets; a base's member: destroyed after the transport's
  std::string tag_;             // "jsonrpc", "websocket"
  bool stopping_ = false;       // stop_io() ran (I/O thread)

 private:
  struct Batch;

  // Where the response of one call goes.
  struct ReplyTo {
    kit::ConnectionRef<Session> session;  // null once its connection closed (I/O thread)
    json id;                              // JSON-RPC id (null for notifications)
    bool notification = false;            // no response at all
    std::shared_ptr<Batch> batch;         // set for batch entries
    std::size_t index = 0;                // entry index inside the batch
    std::string id_text;  // the id's exact text when dump() would round it (float_id_texts)
  };
  // A call submitted to the core and not yet finished (or an rpc.cancel waiting for its answer).
  struct Pending {
    ReplyTo to;               // where the response goes
    std::string method;       // "component.service", for error data
    std::string id_key;       // the session's key for the id, dump(id) ("" when untracked)
    std::size_t id_hash = 0;  // the key's hash in the session's table (SessionCalls::track)
    bool cancel = false;      // an rpc.cancel waiting for the core's answer (outcome value: found)
    // when its table node is kept for reuse: drop the references, keep the strings' capacity
    // (a string id goes: it may be large; a number or null stays until overwritten)
    void recycle() {
      to.session = {};
      to.batch.reset();
      if (to.id.is_string()) to.id = nullptr;
    }
  };

  // Handles one request object: answers at once (into `to`), or queues a call in to_submit_.
  void handle_request(Session& session, json& message, ReplyTo to);
  // Handles one valid request (its params and id_text are moved from).
  void dispatch(Session& session, Request& request, ReplyTo&& to);
  // rpc.login {"token"}: the connection may call services (kit/auth.h); a wrong token is
  // answered -32005 and closes the connection.
  void handle_login(Session& session, const json& params, ReplyTo to);
  void handle_cancel(Session& session, const std::string& method, const json& params, ReplyTo to);
  // I/O thread, woken by the core: finishes the outcomes the simulation thread produced,
  // then one write per connection.
  void drain_completions();
  void finish_call(RequestId id, Outcome&& outcome);
  // Queues `response` where `to` says (into its batch, or on its connection); written at the
  // end of the burst (flush_replies).
  void reply(ReplyTo& to, std::optional<json> response);

  // ---- data streams (engine_streams.cc)
  // One subscription of a connection to an output stream.
  struct StreamSub {
    std::uint64_t id = 0;                              // what rpc.subscribe answered
    std::weak_ptr<Session> session;                    // its connection
    std::shared_ptr<StreamSubscription> subscription;  // the core's queue
  };
  // The streams this transport carries, as rpc.streams lists them.
  json stream_list() const;
  // rpc.streams, rpc.subscribe, rpc.unsubscribe, rpc.publish; false for any other method.
  bool handle_stream_method(Session& session, const std::string& method, const json& params,
                            ReplyTo& to);
  void subscribe(Session& session, const json& params, ReplyTo& to);
  bool unsubscribe(Session& session, std::uint64_t id);
  void publish(const json& params, ReplyTo& to);
  // A subscription has samples (the thread that holds the simulation lock): one post per burst.
  void wake_streams();
  // Sends every subscription's samples as rpc.sample notifications; ends those whose
  // component was deleted (rpc.unsubscribed) or whose connection is gone.
  void drain_streams();
  // Ends the subscriptions of `session` (and those of connections gone); null: all.
  void end_subscriptions(const Session* session);

  // A pending call's slot (its id names it: no hashing), recycled when a spare one is kept.
  RequestId add_pending();
  // Gives back the slot of a call refused after add_pending().
  void drop_pending(RequestId id);
  static constexpr std::size_t k_spare_pending = 256;  // Pending objects kept for reuse
  // submitted calls and cancels, by the ids their slots give them (I/O thread); each Pending
  // in its own object, so that one being answered stays valid while the table changes
  kit::RequestSlots<std::unique_ptr<Pending>> pending_;
  std::vector<std::unique_ptr<Pending>> spare_pending_;  // answered, reset, for the next calls
  Request request_;  // the message being read by the fast path (I/O thread)
  // calls of the current read, handed over together: the first to_submit_count_ of
  // to_submit_; the objects are refilled from read to read (I/O thread)
  static constexpr std::size_t k_kept_calls = 1024;
  // A batch refused for max_in_flight answers each of its requests with its own id when it
  // has at most this many entries (one error with a null id when larger: issue #17's batch of
  // a million `1`s must not build a million error objects).
  static constexpr std::size_t k_refused_batch_answered_by_entry = 1024;
  std::vector<std::pair<RequestId, Call>> to_submit_;
  std::size_t to_submit_count_ = 0;
  std::string line_;                        // a response being built (I/O thread; capacity reused)
  std::vector<StreamSub> stream_subs_;      // every connection's subscriptions (I/O thread)
  std::uint64_t next_subscription_ = 1;     // rpc.subscribe's numbers (I/O thread)
  std::vector<SamplePtr> samples_;          // drain_streams' scratch (I/O thread)
  std::atomic<bool> streams_woken_{false};  // a drain_streams is posted
};

}  // namespace simgate::jsonrpc

#endif  // SIMGATE_JSONRPC_ENGINE_H_
