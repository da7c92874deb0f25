// plugins/mcp/mcp_server.h — the mcp transport: the Model Context Protocol (revision
// 2025-11-25, and 2025-06-18, 2025-03-26) over streamable HTTP, on the kit's HTTP connections,
// so that AI agents drive the simulation through tools generated from its services.
//
// What an agent gets (docs/transports/mcp.md):
//   - POST <path> (default /mcp) with one JSON-RPC message: `initialize` makes a session
//     (its id in the Mcp-Session-Id header, which every later request carries; 400 without
//     it, 404 for one unknown or ended); `ping`; `tools/list`: one tool per service the
//     transport serves (simgate/mcp/protocol.h: name, title, description, the parameters'
//     JSON Schema); `tools/call`: the service called, its outcome as the tool's result
//     (structured content and text, images as image content; failures as isError).
//     Notifications and responses are answered 202.
//   - A call of an async service (a goto, a step of many steps) by a client that accepts
//     text/event-stream is answered as a stream: notifications/progress while it runs (when
//     the call has a progressToken), then the result. notifications/cancelled cancels it
//     (the stream then ends without a result, as the spec asks); the argument deadline_ms
//     bounds it. A stream whose connection drops can be resumed (GET with Last-Event-ID,
//     call_streams.cc) within resume_window_s; not resumed, its call is cancelled
//     (`on_disconnect`).
//   - Resources (resources.cc): the scene (simgate://scene: simulation get_scene_objects) and
//     each output stream the transport carries (simgate://streams/<component>: its latest
//     sample; a camera's as image/png), read, and subscribed to (notifications/resources/
//     updated, at most every k_update_interval per resource).
//   - GET <path> opens the session's stream of notifications: tools/list_changed and
//     resources/list_changed when components come or go, resources/updated. DELETE ends the
//     session (its calls cancelled, its subscriptions ended).
//   - Safety: the transport's allow and deny lists decide which tools exist (a denied
//     service is no tool and is called as an unknown one); the kit's `auth` token in
//     `Authorization: Bearer` on every request (401 without it, 403 for a wrong one, then the
//     connection closes); the Origin header checked against allowed_origins on every request
//     (403: DNS rebinding); a rate limit per session (max_calls_per_s, 429); sessions at most
//     max_sessions (503), idle ones ended after session_timeout_s.
//   - Bad input: a body that is not JSON (-32700), not a request (-32600; batches included),
//     an unknown method (-32601), an unknown tool or arguments that are not an object
//     (-32602), each with HTTP 400 or 200 as the spec says; the kit's limits on the request's
//     size (413), its header (431), its time (line_timeout_s).
//
// Options: the kit's (kit::TcpOptions: host, port 8808, limits, timeouts, auth),
// allowed_origins (kit::OriginPolicy), path, max_sessions, session_timeout_s,
// max_calls_per_s, resume_window_s.
//
// Threads: one I/O thread (connections, sessions, pending calls, the tools); the core's
// outcomes and progress reports are handed to it (deliver_on_this_thread).
#ifndef SIMGATE_PLUGINS_MCP_MCP_SERVER_H_
#define SIMGATE_PLUGINS_MCP_MCP_SERVER_H_

#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <unordered_map>
#include <utility>  // before Asio: Boost 1.74 needs std::exchange in C++20 mode
#include <vector>

#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>

#include "simgate/core/request_manager.h"
#include "simgate/core/streams.h"
#include "simgate/kit/http_connection.h"
#include "simgate/kit/origin_policy.h"
#include "simgate/kit/tcp_server.h"
#include "simgate/mcp/protocol.h"

namespace simgate::mcp {

// The port of the demo's MCP endpoint (http://127.0.0.1:8808/mcp).
inline constexpr std::uint16_t k_default_port = 8808;

class McpServer : public RequestManager, private kit::HttpServer {
 public:
  // Parses the options and binds; throws ConfigError or std::runtime_error.
  explicit McpServer(const json& options);
  ~McpServer() override;
  // What the constructor checks of `options`, without binding (the plugin's validate).
  static std::vector<std::string> validate_options(const json& options);

  void start() override;
  void stop() override;
  // {"http://127.0.0.1:<port>/mcp"}
  std::vector<std::string> endpoints() const override;
  // Sessions open now.
  std::size_t client_count() const override {
    return session_count_.load(std::memory_order_relaxed);
  }

 private:
  struct Settings {
    kit::TcpOptions tcp;
    kit::OriginPolicy origins;
    std::string path = "/mcp";                       // the endpoint's path
    std::size_t max_sessions = 64;                   // sessions open at once
    std::chrono::seconds session_timeout{1800};      // a session unused this long ends
    double max_calls_per_s = 50;                     // tools/call per second per session
    std::chrono::milliseconds resume_window{30000};  // a dropped stream may be resumed this long
    static Settings parse(const json& options);
  };
  // A tools/call answered as a stream of events (call_streams.cc). Its events are kept (the
  // last k_kept_events, the result always) so that a client whose connection dropped resumes
  // it with a GET carrying Last-Event-ID ("<stream>-<event>") within resume_window_s; not
  // resumed by then, the call is cancelled.
  struct CallStream {
    RequestId request = 0;                                     // the call
    std::weak_ptr<kit::HttpConnection> connection;             // where its events go
    std::deque<std::pair<std::uint64_t, std::string>> events;  // (number, message) sent
    std::uint64_t next_event = 1;                              // the next event's number
    bool done = false;                                         // the call ended: the last event
    std::chrono::steady_clock::time_point detached{};  // its connection dropped (epoch: did not)
  };
  // One agent's session (Mcp-Session-Id), over any number of its connections.
  struct Session {
    std::string id;                                  // what Mcp-Session-Id says
    std::uint64_t number = 0;                        // Call::client of its calls
    std::string version;                             // the revision agreed
    std::chrono::steady_clock::time_point used;      // its last request
    double tokens = 0;                               // the rate limit's bucket
    std::chrono::steady_clock::time_point refilled;  // when tokens was last topped up
    std::map<std::string, RequestId> calls;          // its calls running: dumped id -> request
    std::weak_ptr<kit::HttpConnection> events;       // its GET stream: notifications
    std::set<std::string> watched;                   // the streams it subscribed to (components)
    std::map<std::uint64_t, CallStream> streams;     // its calls answered as streams, by number
    std::uint64_t next_stream = 1;                   // the next one's number
  };
  // A tools/call submitted and not yet answered.
  struct Pending {
    std::weak_ptr<kit::HttpConnection> connection;  // where its answer goes
    std::string session;                            // its session's id
    json id;                                        // the JSON-RPC id
    json progress_token;                            // null: no progress wanted
    bool events = false;        // answered as a stream: an async call, a client that takes one
    std::uint64_t reports = 0;  // progress notifications sent
    bool cancelled = false;     // the client sent notifications/cancelled for it
    std::string resource;       // a resources/read of this URI (not a tool call)
    std::uint64_t stream = 0;   // its CallStream in the session (0: answered as JSON)
  };
  // A resources/read of a stream waiting for its next sample.
  struct PendingRead {
    std::weak_ptr<kit::HttpConnection> connection;
    json id;
  };
  // The transport's subscription to one stream a resource is made of (resources.cc): shared
  // by the sessions subscribed to it and by the reads waiting for a sample; ended when none is
  // left.
  struct StreamWatch {
    std::shared_ptr<StreamSubscription> subscription;
    SamplePtr latest;                                // the newest sample taken
    std::set<std::string> sessions;                  // subscribed (resources/subscribe), by id
    std::vector<PendingRead> reads;                  // resources/read waiting for a sample
    std::chrono::steady_clock::time_point notified;  // the last notifications/resources/updated
    bool updated = false;                            // a sample came since that notification
  };

  explicit McpServer(Settings settings);

  // ---- RequestManager (the I/O thread)
  void on_service_completion(RequestId id, Outcome&& outcome) override;
  void on_service_progress(RequestId id, json&& value) override;
  void on_services_changed() override;

  // ---- kit (the I/O thread)
  void on_request(kit::HttpConnection& connection, kit::HttpRequest&& request) override;
  void on_messages_done(kit::Connection& connection, bool read_finished) override;
  void on_closed(kit::Connection& connection) override;

  void accept(boost::asio::ip::tcp::socket socket);
  void shutdown_io();
  // The end of a burst of outcomes handed over: delivered, written.
  void flush_replies();
  // A POST's JSON-RPC message.
  void on_post(kit::HttpConnection& connection, const kit::HttpRequest& request);
  // `initialize`: a new session.
  void initialize(kit::HttpConnection& connection, const json& id, const json& params);
  // A request of session `session` (tools/list, tools/call, ping).
  void on_method(kit::HttpConnection& connection, Session& session, const json& id,
                 const std::string& method, json& params);
  void call_tool(kit::HttpConnection& connection, Session& session, bool events, const json& id,
                 json& params);
  // A notification of `session` (notifications/cancelled; the others are taken note of).
  void on_notification(Session& session, const std::string& method, const json& params);
  // The session ends: its calls cancelled, forgotten.
  void end_session(const std::string& id, const char* why);
  // Ends the sessions unused for session_timeout (a timer, every k_session_sweep).
  void sweep_sessions();
  // The tools of the services callable now (rebuilt after on_services_changed).
  const std::map<std::string, Tool>& tools();
  // Whether the session may make one more call now (the rate limit), taking a token.
  bool take_call_token(Session& session);

  // ---- resources (resources.cc): the scene, and each output stream the transport carries
  // resources/list's resources.
  json resource_list() const;
  // resources/read: the scene (a call of simulation get_scene_objects) or a stream's latest
  // sample (the next one when no session watches it).
  void read_resource(kit::HttpConnection& connection, const json& id, const json& params);
  // resources/subscribe and resources/unsubscribe of a stream's resource.
  void watch_resource(kit::HttpConnection& connection, Session& session, const json& id,
                      const json& params, bool subscribe);
  // The watch of `component`'s stream, made when there is none; null when the transport
  // carries no such output stream.
  StreamWatch* watch(const std::string& component);
  // Ends `component`'s watch when no session and no read needs it any more.
  void release_watch(const std::string& component);
  // The session's subscriptions end (it ended).
  void unwatch_all(Session& session);
  // GET: the session's stream of notifications (tools and resources changed, updated).
  void open_events(kit::HttpConnection& connection, const kit::HttpRequest& request);
  // A notification on the session's GET stream (none when it has none open).
  void notify(Session& session, const json& message);
  // The services or streams changed (on_services_changed, posted): every session is told.
  void announce_changes();
  // A watched stream has samples (the thread that holds the simulation lock): one post.
  void wake_streams();
  // Takes the samples, answers the reads, notifies the subscribed sessions (at most every
  // k_update_interval per resource).
  void drain_streams();
  // A resources/read's answer: the scene's call outcome.
  void finish_resource_read(kit::HttpConnection& connection, const Pending& pending,
                            Outcome&& outcome);

  static constexpr std::chrono::milliseconds k_update_interval{100};

  // Answers with a JSON body.
  void respond_json(kit::HttpConnection& connection, unsigned status, const json& body,
                    const std::string& headers = {});
  // Answers with a JSON-RPC error (HTTP `status`).
  void respond_error(kit::HttpConnection& connection, unsigned status, const json& id, int code,
                     std::string message);

  // ---- streams of calls (call_streams.cc)
  // The call of `pending` answers as a stream on `connection` (begun): its CallStream.
  void begin_call_stream(RequestId request, Pending& pending, kit::HttpConnection& connection);
  // Sends `message` as the next event of `pending`'s stream (kept for a resume); a droppable
  // one (progress) is dropped for a client that does not read.
  void stream_event(const Pending& pending, std::string message, bool droppable);
  // The call ended (its result sent, or not for a cancelled one): the stream ends, or waits
  // for its client to resume it when it is detached.
  void end_call_stream(const Pending& pending);
  // `connection` closed: the streams it carried are detached (resumable for resume_window).
  void detach_streams(const kit::Connection& connection);
  // GET with Last-Event-ID: the events after it replayed, the stream continued there.
  void resume_stream(kit::HttpConnection& connection, Session& session, std::string_view last);
  // Detached streams older than resume_window: their calls cancelled, forgotten.
  void expire_streams(std::chrono::steady_clock::time_point now);
  static constexpr std::size_t k_kept_events = 256;

  static constexpr std::chrono::seconds k_session_sweep{10};
  std::chrono::milliseconds sweep_interval_{k_session_sweep};  // min(10 s, resume_window)

  Settings settings_;
  boost::asio::io_context io_;
  kit::TcpListener listener_;  // bound in the constructor
  kit::IoThread io_thread_;    // runs io_
  boost::asio::steady_timer session_timer_;
  std::unordered_map<std::string, Session> sessions_;  // by id (I/O thread)
  std::atomic<std::size_t> session_count_{0};
  std::unordered_map<RequestId, Pending> pending_;  // tools/call in flight (I/O thread)
  std::vector<std::pair<RequestId, Call>> calls_;   // read, not yet handed to the core
  std::vector<RequestId> submitted_;                // calls_' ids, for the streams begun after
  std::map<std::string, Tool> tools_;               // by name (I/O thread)
  std::vector<std::string> skipped_tools_;          // services without a tool (name clash)
  std::atomic<bool> tools_stale_{true};             // the services changed since tools_
  std::map<std::string, StreamWatch> watches_;      // by component (I/O thread)
  std::atomic<bool> streams_woken_{false};
  std::atomic<bool> changes_posted_{
      false};  // an announce_changes is posted          // a drain_streams is posted
  std::vector<SamplePtr> samples_;  // drain_streams' scratch
  std::uint64_t next_connection_ = 1;
  std::uint64_t next_session_ = 1;
  bool stopping_ = false;
};

}  // namespace simgate::mcp

#endif  // SIMGATE_PLUGINS_MCP_MCP_SERVER_H_
