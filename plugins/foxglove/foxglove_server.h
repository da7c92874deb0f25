// plugins/foxglove/foxglove_server.h — the foxglove transport: Foxglove's WebSocket protocol
// (simgate/foxglove/protocol.h) on the kit's WebSocket connections, so that Foxglove and
// Lichtblick open a running simulation at ws://127.0.0.1:8765 (Foxglove's default port).
//
// What a client gets (docs/transports/foxglove.md):
//   - serverInfo (capabilities clientPublish, parameters, parametersSubscribe, services and
//     time; encoding `json`), then one channel per
//     output stream the transport carries (topic "/robot/pose" for robot.pose, JSON messages,
//     a JSON Schema made from one sample read when the channel appears), then one service per
//     simgate service it serves ("/robot/motion/set_speed": a JSON object of the parameters
//     in, the result out). Channels and services appear and disappear as components do
//     (advertise / unadvertise, advertiseServices / unadvertiseServices). The simulation's
//     body_poses stream also makes /tf and /scene (foxglove.FrameTransforms and
//     foxglove.SceneUpdate, simgate/foxglove/scene.h) for the 3D panel. World k's streams
//     and services are world 0's under "/w<k>/" (/w1/robot/pose, /w1/tf), its frame ids
//     "w<k>/..." (a tree of its own), its scene asked of it. (catalog.cc)
//   - subscribe / unsubscribe: each sample as a binary Message Data, its log time the
//     simulated time of the sample; a Time message whenever the simulated time moved (with
//     the samples, and `time_hz` times per second of wall time between them), so that
//     panels follow simulated time through pauses and time scales. Sensors' streams go in
//     Foxglove's schemas (sensors.h: cameras, laser, odometry, joints), and /log carries the
//     log's lines. (streams.cc, with the client channels below)
//   - a service call (binary request, JSON encoding): answered by a Service Call Response
//     with the result, or a serviceCallFailure naming the status and the reason; a long call
//     when it finishes. A client that leaves has its calls cancelled (`on_disconnect`).
//   - client channels on input streams' topics (clientPublish): each message a command
//     (a geometry_msgs/Twist read as {v, w} for a velocity stream).
//   - parameters: the components' properties as /<component>/<property>, got, set and
//     subscribed to (parameters.cc).
//   - playback control (capability playbackControl, when it serves simulation play, pause
//     and time set_time_scale): the app's playback bar pauses, plays, sets the time scale and
//     seeks back to automatic snapshots (playback.cc; options rewind_interval_s, 1, and
//     rewind_states, 60), or, in a served replay, anywhere in the recording.
//   - bad input (text that is not JSON, an unknown op, a subscription to no channel, a
//     reused subscription id, a bad binary opcode): a status message saying what was wrong;
//     the connection and every other client go on.
//
// Options: the kit's (kit::TcpOptions: host, port 8765, limits, timeouts, auth: the token
// in the upgrade, see login_after_upgrade), every
// WebSocket transport's (kit::WebSocketOptions: allowed_origins, keepalive_s), and
// `stream_queue` (samples kept per subscription, 4: a slow client gets the newest, never a
// backlog), `time_hz` (Time messages per wall second between samples, 30; 0: only with
// samples). A client must offer the subprotocol foxglove.websocket.v1 or foxglove.sdk.v1
// (else 400).
//
// Threads: one I/O thread (connections, subscriptions, pending calls, channels, services);
// the schemas' samples are read under the simulation lock (a task posted to the core).
#ifndef SIMGATE_PLUGINS_FOXGLOVE_FOXGLOVE_SERVER_H_
#define SIMGATE_PLUGINS_FOXGLOVE_FOXGLOVE_SERVER_H_

#include <atomic>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>

#include "simgate/core/log.h"
#include "simgate/core/request_manager.h"
#include "simgate/foxglove/protocol.h"
#include "simgate/foxglove/scene.h"
#include "simgate/foxglove/sensors.h"
#include "simgate/kit/tcp_server.h"
#include "simgate/kit/websocket_connection.h"

namespace simgate::foxglove {

// Foxglove's default port.
inline constexpr std::uint16_t k_default_port = 8765;
// The log's channel (foxglove.Log).
inline constexpr const char* k_log_topic = "/log";

class FoxgloveServer : public RequestManager, private kit::WebSocketServer {
 public:
  // Parses the options and binds; throws ConfigError or std::runtime_error.
  explicit FoxgloveServer(const json& options);
  ~FoxgloveServer() override;
  // What the constructor checks of `options`, without binding (the plugin's validate).
  static std::vector<std::string> validate_options(const json& options);

  void start() override;
  void stop() override;
  // {"ws://127.0.0.1:<port>/"} with the bound port.
  std::vector<std::string> endpoints() const override;
  std::size_t client_count() const override { return connection_count(); }

 protected:
  void on_service_completion(RequestId id, Outcome&& outcome) override;
  void on_services_changed() override;

 private:
  struct Settings {
    kit::TcpOptions tcp;
    kit::WebSocketOptions websocket;
    std::size_t stream_queue = 4;
    double time_hz = 30;
    double rewind_interval_s = 1;    // simulated s between automatic snapshots (0: none)
    std::size_t rewind_states = 60;  // snapshots kept for seeking back
    static Settings parse(const json& options);
  };
  class Client;
  // What a channel's messages are made of: the stream's samples as they are, the
  // simulation's body_poses samples in Foxglove's schemas (scene.h), a sensor's samples in
  // one of Foxglove's schemas (sensors.h), or the log's lines (no stream).
  enum class Shape : std::uint8_t { sample, frame_transforms, scene_update, sensor, log };
  // A channel as advertised: the stream's component, its shape and what clients were told.
  struct ChannelEntry {
    std::string component;
    Shape shape = Shape::sample;
    SensorMessage message = SensorMessage::log;  // Shape::sensor: which message
    Channel channel;
  };
  // A sensor channel's last message, made once for every subscriber, and its laser's arc.
  struct SensorCache {
    std::uint64_t seq = 0;  // the sample it was made of (0: none)
    std::string text;       // "": the sample had not the message's shape
    LaserArc arc;
  };
  // The scene a body_poses stream's /tf and /scene channels are made from: its world's
  // get_scene_geometry answer, its frames named with the world's prefix (world_prefix).
  struct Scene {
    json geometry;
    SceneFrames frames;
    RequestId call = 0;    // the request under way (0: none)
    bool wanted = false;   // a sample of another model came: ask again
    bool refused = false;  // the world's answer was a refusal (logged once)
  };
  // Where a service call's answer goes.
  struct PendingCall {
    std::weak_ptr<Client> client;
    std::uint32_t service_id = 0;
    std::uint32_t call_id = 0;
  };
  // The Server header of its HTTP answers, and serverInfo's name.
  static constexpr std::string_view k_server = "simgate foxglove transport";

  explicit FoxgloveServer(Settings settings);

  // ---- kit::WebSocketServer (I/O thread)
  void on_open(kit::WebSocketConnection& connection) override;
  void on_message(kit::WebSocketConnection& connection, std::string_view text) override;
  bool binary_messages() const override { return true; }
  void on_binary_message(kit::WebSocketConnection& connection, std::string_view data) override;
  void on_refused_message(kit::WebSocketConnection& connection, std::size_t bytes,
                          bool binary) override;
  void on_messages_done(kit::Connection& connection, bool read_finished) override;
  void on_closed(kit::Connection& connection) override;
  kit::HttpResponse on_http_request(const kit::HttpRequest& request) override;
  std::string refuse_upgrade(const kit::HttpRequest& request) override;
  std::string subprotocol(const kit::HttpRequest& request) const override;
  // Foxglove's protocol has no login: a client the "auth" option asks a token of presents
  // it in the upgrade (ws://host:8765/?token=..., or Authorization: Bearer), else 401.
  bool login_after_upgrade() const override { return false; }

  void accept(boost::asio::ip::tcp::socket socket);
  void shutdown_io();
  // The outcomes the simulation thread produced, and the replies of the burst (I/O thread).
  void flush_replies();

  // ---- the protocol (I/O thread)
  // serverInfo's capabilities: those of every connection, playbackControl when offered.
  std::vector<std::string> capabilities() const;
  void subscribe(Client& client, const Subscribe& request);
  void unsubscribe(Client& client, const Unsubscribe& request);
  void call_service(Client& client, const ServiceCallRequest& request);
  // Client channels on input streams' topics (clientPublish), and their messages.
  void advertise_publications(Client& client, const ClientAdvertise& request);
  void publish(Client& client, const ClientMessageData& message);
  // Parameters: the components' properties (get_properties, set_property), named
  // "/<component>/<property>".
  struct ParameterQuery;
  void get_parameters(Client& client, const GetParameters& request);
  void set_parameters(Client& client, const SetParameters& request);
  // Asks every component with properties (those whose get_properties this transport serves)
  // for them; `query` is answered once all have.
  void query_parameters(const std::shared_ptr<ParameterQuery>& query);
  void finish_query(ParameterQuery& query);
  // The component and property a parameter names, or nullopt.
  std::optional<std::pair<std::string, std::string>> parameter_of(const std::string& name) const;
  // Reads the subscribed parameters again and tells their subscribers what changed.
  void poll_parameters();
  // A completion of one of the parameters' calls; false when `id` is none of theirs.
  bool parameter_completion(RequestId id, Outcome& outcome);
  // ---- playback control (playback.cc): the app's playback bar drives the simulation
  struct PlaybackRequest;
  // An automatic snapshot (simulation save_state) to seek back to.
  struct Rewind {
    std::uint64_t handle = 0;
    double time = 0;  // simulated s
  };
  // The span serverInfo gives the playback bar: the oldest snapshot to an hour past now.
  static constexpr double k_playback_horizon_s = 3600;
  // Whether this transport serves what play/pause/speed need, seeking back to snapshots too,
  // and seeking in a served replay's recording (which rules out the snapshots).
  bool playback_offered() const;
  bool rewind_offered() const;
  bool seek_offered() const;
  // Whether this transport serves `component`'s `service`.
  bool serves(std::string_view component, std::string_view service) const;
  // A served replay: asks the recording's span (replay_range_) once, at start.
  void ask_replay_range();
  std::pair<std::uint64_t, std::uint64_t> playback_range();
  // The simulated time now (after a seek while paused: the time restored).
  double simulated_time();
  void control_playback(Client& client, const PlaybackControlRequest& request);
  // A time tick: a snapshot when rewind_interval_s has passed since the last.
  void take_rewind_snapshot();
  void drop_rewind(std::uint64_t handle);
  // A completion of one of playback's calls; false when `id` is none of theirs.
  bool playback_completion(RequestId id, Outcome& outcome);
  // Tells `client` (status level error/warning) what was wrong with its message.
  void complain(Client& client, Level level, std::string_view message);

  // ---- channels and services
  // The catalog changed (or the transport starts): services now, channels once their
  // samples were read under the simulation lock.
  void refresh_catalog();
  void refresh_services();
  // Under the simulation lock: the channels of the streams now, with their schemas.
  std::vector<ChannelEntry> read_channels() const;
  // I/O thread: advertises what is new, unadvertises what is gone, to every client.
  void apply_channels(std::vector<ChannelEntry> channels);
  // Sends `text` to every client.
  void broadcast(const std::string& text);

  // ---- samples and time (I/O thread, woken by the core)
  void wake_streams();
  void drain_streams();
  // The message /tf or /scene channel `entry` sends for `sample` ("": none now); `scene_sent`:
  // the model generation the subscription's client last got a scene of.
  std::string convert(const ChannelEntry& entry, const StreamSample& sample,
                      std::uint64_t& scene_sent);
  // The message sensor channel `entry` sends for `sample` (made once for every subscriber;
  // "": none).
  const std::string& convert_sensor(const ChannelEntry& entry, const StreamSample& sample);
  // The log: lines come on any thread (log_line, a log observer), the I/O thread sends them to
  // /log's subscribers (drain_log) and keeps the last k_log_backlog for new ones.
  void log_line(log::Level level, std::string_view text);
  void drain_log();
  // Asks `component`'s world for its scene (<world>simulation get_scene_geometry: `component`
  // is the body_poses stream's) unless a request is under way.
  void request_geometry(const std::string& component, Scene& scene);
  // "w<k>/" when `component` is world k's (its channels' topics begin "/w<k>/", its frame ids
  // "w<k>/"); "" for world 0's.
  static std::string world_prefix(std::string_view component);
  // Queues a Message Data of subscription `subscription`, its log time `time` (simulated s);
  // false when the client's budget dropped it.
  bool queue_message(Client& client, std::uint32_t subscription, double time,
                     const std::string& text);
  // A Time message to `client` if the simulated time moved since it was told.
  void send_time(Client& client, std::uint64_t time_ns);
  void tick_time();

  Settings settings_;
  boost::asio::io_context io_;
  kit::TcpListener listener_;  // bound in the constructor
  kit::IoThread io_thread_;
  boost::asio::steady_timer time_timer_;
  std::string session_id_;                   // serverInfo's sessionId: this process's start
  bool stopping_ = false;                    // shutdown_io() ran: nothing is started any more
  std::uint64_t next_client_ = 1;            // numbers connections (I/O thread)
  std::atomic<bool> catalog_wanted_{false};  // a refresh is posted
  std::atomic<bool> streams_woken_{false};   // a drain is posted
  std::vector<ChannelEntry> channels_;       // advertised, by channel id order
  std::uint32_t next_channel_id_ = 1;
  // every channel ever advertised by topic: an id is reused only for the same channel
  std::map<std::string, Channel> channel_history_;
  std::vector<ServiceDef> services_;  // advertised
  std::map<std::string, ServiceDef> service_history_;
  std::uint32_t next_service_id_ = 1;
  std::unordered_map<RequestId, PendingCall> pending_;  // calls not answered yet
  std::vector<std::pair<RequestId, Call>> calls_;       // read, not yet run
  std::vector<SamplePtr> samples_;                      // drain's buffer
  std::map<std::uint32_t, SensorCache> sensor_cache_;   // by channel id
  // the log channel's lines: those not yet sent (any thread, under log_mutex_), and the last
  // ones sent (I/O thread), each {simulated time, foxglove.Log text}
  static constexpr std::size_t k_log_backlog = 100;
  std::mutex log_mutex_;
  std::vector<std::pair<double, std::string>> log_incoming_;
  std::deque<std::pair<double, std::string>> log_backlog_;
  std::atomic<bool> log_woken_{false};  // a drain_log is posted
  std::uint64_t log_observer_ = 0;      // log::add_observer's handle (0: none)
  // the scenes the /tf and /scene channels are made from, by body_poses component
  // ("simulation", "w1/simulation"); one goes with its channels (its world deleted)
  std::map<std::string, Scene> scenes_;
  // the parameters' calls under way: get_properties (a query's) and set_property
  struct ParameterCall {
    std::shared_ptr<ParameterQuery> query;  // get_properties: the query it answers
    std::string component;
    std::weak_ptr<Client> setter;  // set_property: who set it (told of a refusal)
    std::string name;              // set_property: the parameter
  };
  std::unordered_map<RequestId, ParameterCall> parameter_calls_;
  std::map<std::string, json> parameters_known_;  // the values last read (the poll's diff)
  bool parameters_polling_ = false;               // a poll is under way
  // playback: the automatic snapshots (oldest first), the save_state under way, the calls of
  // playback requests under way, what the bar was last told
  std::deque<Rewind> rewinds_;
  RequestId rewind_call_ = 0;
  std::unordered_map<RequestId, std::shared_ptr<PlaybackRequest>> playback_calls_;
  bool playing_ = true;
  float speed_ = 1;
  // after a seek: (the streams' time then, the time restored) until the simulation steps
  std::optional<std::pair<double, double>> seek_hold_;
  // a served replay: the recording's span (simulated s, from get_replay_status), its call
  std::optional<std::pair<double, double>> replay_range_;
  RequestId replay_status_call_ = 0;
  std::uint32_t ticks_ = 0;  // tick_time()s so far (the poll's clock)
};

}  // namespace simgate::foxglove

#endif  // SIMGATE_PLUGINS_FOXGLOVE_FOXGLOVE_SERVER_H_
