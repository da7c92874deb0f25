// simgate/dds — the Cyclone DDS transport: request/reply over DDS topics, and a catalog.
//
// Terms (wire types in simgate_dds.idl, design in docs/transports/dds.md):
//  - Request / Reply topics: a client writes Request{id = (client, seq), component,
//    service, params JSON, timeout_ms}; the server answers on the Reply topic (Reply.client
//    = the client's id). Async calls get ST_ACCEPTED first, then one terminal reply; a call
//    past its timeout_ms (Call::timeout) ends ST_FAILED, FL_TIMEOUT, its service interrupted.
//  - Client: one request writer; its id is that writer's GUID (a request that claims another
//    id is refused). The server learns of it when the writer matches its request reader and
//    forgets it when the writer leaves (and its calls are over).
//  - Reply writer: one per client, in the partition "<partition>/<client id hex>" where only
//    that client's reply reader listens. A reader that stops acknowledging (never takes,
//    frozen process) can only fill its own writer's history: the server's writes to it fail
//    at once (max_blocking_time 0) and that client alone loses replies.
//  - Progress topic: the reports of a call that asked (Request.progress), as Reply samples
//    with ST_RUNNING, written by a second writer of the client's (created at its first such
//    call), best effort and keep-last 1: a client that does not take them loses old ones
//    and holds up nothing, its replies least of all.
//  - Data streams (issue #21): sensors' samples and actuators' commands on topics of their
//    own, and their catalog simgate_Streams: dds_streams.h.
//  - Catalog topic (TRANSIENT_LOCAL): one CatalogEntry per served component, so a client
//    that joins late still sees what it can call. Published anew when a component stops
//    being served (on_services_changed: a robot deleted at run time), its entry disposed.
//  - Partition: every endpoint lives in the partition named by the "partition" option (the
//    reply writers in their sub-partitions), so several simulations share a domain without
//    crosstalk.
//  - In flight: a client's request from its take until its final reply has gone to the
//    client's reply writer (running, queued, or that reply parked). Past max_in_flight a
//    request is refused Overloaded without running, so that a client writing requests
//    faster than it acknowledges replies gets a final reply to each (issue #35: those past
//    max_samples parked were dropped). Consecutive refusals share one parked entry.
//  - Parked reply: a reply not written yet, in order behind the client's earlier ones:
//    its reply reader has not matched (discovery is asymmetric: written as soon as it
//    matches, or anyway after park_timeout_ms), or its writer is full (retried with backoff,
//    dropped after park_timeout_ms, logged at most every 10 s per client).
//
// Life cycle: the constructor validates the options and creates every DDS entity (so a bad
// Cyclone XML fails at load time); start() writes the catalog and starts the DDS thread;
// stop() joins it, answers every pending request FAILED (shutdown) and deletes the
// participant.
//
// Threads: all DDS I/O happens on the transport's own thread (the DDS thread), which waits
// on a waitset (requests, a guard condition, match-status changes). Nothing runs on
// Cyclone's listener threads.
//  - The requests of one dds_take go to the core together with run_or_submit(): when the
//    simulation lock is free (the loop waits for its next step), the DDS thread runs them
//    itself, so on_service_completion() is called on the DDS thread; it keeps the outcome
//    behind anything kept before, and the DDS thread writes the replies as
//    soon as run_or_submit() returns, outside the simulation lock: no thread hand-off
//    between a request and its reply. Cancels are run the same way.
//  - When the lock is busy (the loop is stepping), the requests are queued and the
//    simulation thread runs them: the core hands their outcomes over to the DDS thread
//    (deliver_on_this_thread: it triggers the guard condition once per burst, never waiting
//    on DDS); the DDS thread wakes, takes them (deliver_handed_over) and writes the replies.
//    Async completions from other threads take this path too.
//  - Order: the replies of a client leave in the order they were produced; an async call's
//    ST_ACCEPTED is written before the call runs, so before its terminal reply; replies the
//    transport writes itself (bad requests, cancel answers) wait for the calls before them.
// stop() writes the final (shutdown) replies from the calling thread, after the DDS thread
// has been joined.
#ifndef SIMGATE_PLUGINS_DDS_DDS_REQUEST_MANAGER_H_
#define SIMGATE_PLUGINS_DDS_DDS_REQUEST_MANAGER_H_

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <unordered_map>
#include <utility>
#include <vector>

#include "dds_streams.h"
#include "dds_support.h"
#include "simgate/core/request_manager.h"

namespace simgate::dds {

// Longest component or service name a request may carry, in bytes (longer: FL_BAD_REQUEST).
inline constexpr std::size_t k_max_name_bytes = 256;
// Longest Request.timeout_ms accepted (a signed 32-bit count of ms, about 24.8 days; more:
// FL_BAD_ARGUMENTS), as on the other transports.
inline constexpr std::uint32_t k_max_timeout_ms = 2'147'483'647;

// `value` as JSON text, invalid UTF-8 replaced rather than thrown (a catalog's services, a
// reply's result and data).
inline std::string dump(const json& value) {
  return value.dump(-1, ' ', false, json::error_handler_t::replace);
}

// The transport's options ("transports.<name>" in a deployment file).
struct DdsOptions {
  uint32_t domain = 0;                // DDS domain id (0..230)
  std::string partition = "simgate";  // one per simulation
  std::string config;                 // Cyclone XML or file:// URI; "" = loopback; "env"
  int32_t max_samples = 1024;         // resource limit: queued requests, parked replies per client
  // requests of one client taken and not yet answered (in the core, or their final reply
  // parked); past it a request is refused Overloaded without running. 1 .. max_samples / 3
  // (so that a client's parked replies, refusals included, stay within max_samples);
  // default max_samples / 4
  int32_t max_in_flight = 256;
  std::chrono::milliseconds park_timeout{
      10000};                        // how long a reply waits for its reader (or writer)
  std::size_t max_params = 1 << 20;  // largest accepted params text, in bytes
  std::size_t max_depth = 128;       // deepest [/{ nesting accepted in params (2..10000)
  GlobalPolicy global_policy = GlobalPolicy::reject;  // async calls without a local policy
  std::chrono::milliseconds progress_interval{50};    // shortest time between two reports of a call
  bool cancel_on_disconnect = true;  // "on_disconnect": a client that leaves has its async calls
      // cancelled ("cancel") or left to run, replies dropped ("let_run")
  bool direct_stream_writes = true;  // "stream_writes": small typed samples (pose, odometry, imu)
                                     // written by the simulation thread as they are made ("direct")
                                     // or handed to the DDS thread like the others ("thread")

  // Reads and validates `options` (unknown keys are errors). Throws ConfigError.
  static DdsOptions parse(const json& options);
};

class DdsRequestManager : public RequestManager {
 public:
  // Host thread. Throws ConfigError (bad options) or std::runtime_error (DDS failed).
  explicit DdsRequestManager(const json& options);
  ~DdsRequestManager() override;
  // What the constructor checks of `options`, and the Cyclone settings as far as that is
  // free of side effects (cyclone_config.h): no participant, no traffic (the plugin's
  // validate, `simgate check`).
  static void validate_options(const json& options);
  // Request writers matched now (one per client program).
  std::size_t client_count() const override {
    return client_count_.load(std::memory_order_relaxed);
  }

  void start() override;
  void stop() override;
  // {"dds:domain=<id>;partition=<name>"}
  std::vector<std::string> endpoints() const override;

  const DdsOptions& options() const { return options_; }

 protected:
  // On the DDS thread (the core hands other threads' outcomes over): keeps the outcome for
  // the write that follows (write_finished). Never blocks on DDS.
  void on_service_completion(RequestId id, Outcome&& outcome) override;
  // On the DDS thread, like outcomes: keeps the report of a call that asked for progress
  // for the write that follows (write_finished, on the progress topic). Never blocks on DDS.
  void on_service_progress(RequestId id, json&& value) override;

 private:
  // A reply not yet written (parked, or queued from the simulation thread).
  struct ReplyData {
    std::uint64_t seq = 0;                            // the request it answers
    simgate_ReplyStatus status = simgate_ST_SUCCESS;  // wire status
    simgate_Failure failure = simgate_FL_NONE;        // why, for failures
    bool last = true;                                 // final reply of the request
    std::string result;                               // JSON text or ""
    std::string message;                              // human-readable reason
    std::string data;                                 // JSON object text or ""
    // an Overloaded refusal (overloaded_reply) may stand for the requests seq .. seq_end,
    // whose refusals are the same but for their seq: one parked entry for a run of them
    std::uint64_t seq_end = 0;
    std::chrono::steady_clock::time_point deadline;  // parked: when to give up waiting
    // A result with images (Outcome::attachments): `result` is written from it when the reply
    // goes (prepare_images), so that whether the client reads its images raw is known then.
    std::shared_ptr<Outcome> images;
    std::size_t images_done = 0;  // its records whose image was written (or stays a PNG)
  };
  // A request handed to the core and not yet completed, or a cancel waiting for its answer.
  struct Pending {
    ClientId client;             // who asked
    std::uint64_t seq = 0;       // their sequence number
    bool is_async = false;       // cancelled if the client disappears
    bool cancel_answer = false;  // the answer to a cancel (outcome value: whether it was running)
  };
  // What the server knows about one client (DDS thread only), from the match of its request
  // writer until that writer left and its calls are over.
  struct ClientState {
    dds_instance_handle_t writer = 0;  // its request writer (GUID = its id)
    dds_entity_t reply_publisher = 0;  // in "<partition>/<id>"; owns reply_writer
    dds_entity_t reply_writer = 0;     // its replies, to its reader alone
    dds_entity_t progress_writer = 0;  // its progress reports (at its first call asking)
    dds_entity_t image_writer = 0;     // its replies' images, raw (simgate_ReplyImage)
    bool reader_matched = false;       // a reader announcing its id is matched
    // whether an image reader announcing its id is matched (takes_images_raw), as of the
    // image writer's match counts below (the set of matches changed when either moved)
    bool images_raw = false;
    std::uint32_t image_matches_total = 0, image_matches_current = 0;
    // seq -> its pending request: a call in the core, or a cancel not answered yet (a seq in
    // here is refused to any new request until that one's final reply is out)
    std::unordered_map<std::uint64_t, RequestId> calls;
    std::deque<ReplyData> parked;                    // replies not written yet, in order
    std::size_t parked_finals = 0;                   // of them, final replies counted in flight
    bool stalled = false;                            // its writer was full at the last write
    bool images_stalled = false;                     // ... its image writer (not worth a log line)
    std::chrono::steady_clock::time_point retry_at;  // stalled: next write attempt
    std::chrono::milliseconds retry_delay{0};        // stalled: backoff, doubling
    std::chrono::steady_clock::time_point progressed_at;  // its writer last took a parked reply
    std::size_t dropped = 0;                              // replies dropped, not yet logged
    std::chrono::steady_clock::time_point logged_at;      // the last "dropped" log line
    bool gone = false;                                    // its request writer disappeared
  };

  void create_entities();
  void run();
  // DDS thread: writes one entry per component served now, and disposes the entries of
  // components no longer served (so that late joiners do not see them).
  void publish_catalog();
  // A component was unregistered (a robot deleted at run time): the DDS thread publishes
  // the catalog anew (catalog_changed_, the guard condition). Under the simulation lock.
  void on_services_changed() override;
  void take_requests();
  // One request taken: its client (by its writer), its id, a seq still pending, the
  // client's requests in flight; then the call or the cancel.
  void handle_request(const simgate_Request& request, dds_instance_handle_t writer);
  // OP_CALL: checked (call_refusal), then into batch_ (an async one acknowledged at once).
  void handle_call(const simgate_Request& request, const ClientId& client_id, ClientState& client);
  // OP_CANCEL: answered like a completion, in order with them.
  void handle_cancel(const simgate_Request& request, const ClientId& client_id,
                     ClientState& client);
  // Why a call is refused before it runs (names, params' size, depth and JSON, timeout), or
  // nothing; fills `call` from the request as it checks.
  std::optional<std::pair<simgate_Failure, std::string>> call_refusal(
      const simgate_Request& request, Call& call) const;
  // A failure reply to `seq`, after the replies of the requests taken before it.
  void refuse(const ClientId& client_id, std::uint64_t seq, simgate_Failure failure,
              std::string message);
  // DDS thread: hands batch_ (and pending cancels) to run_or_submit(), then writes the
  // replies it produced. Called after each take, and before any reply that must follow them.
  void run_batch();
  // DDS thread: writes the progress reports (progress_), then the replies of the outcomes
  // delivered so far (finished_).
  void write_finished();
  // DDS thread: writes progress_ on the callers' progress writers (a failed write drops it).
  void write_progress();
  // The client's progress writer, created in its reply partition at its first call asking
  // for progress; false (logged) if it cannot be created.
  bool ensure_progress_writer(const ClientId& id, ClientState& client);
  // When the client has an image reader (announcing its id) matched: writes the images of
  // `reply` (its attachments) not written yet on its image writer, in order, each as a
  // simgate::stream::Image with the call's seq, and leaves their PNG out of their records
  // (format "raw"). False when the image writer is full (the images before not yet
  // acknowledged: Cyclone's WhcHigh): the rest wait for a retry. Never blocks.
  bool send_images(const ClientId& id, ClientState& client, ReplyData& reply);
  // Before `reply` is written: its images (send_images) and its result's text. False while
  // its images wait for room; `give_up`: the images left keep their PNGs (with_png).
  bool prepare_images(const ClientId& id, ClientState& client, ReplyData& reply, bool give_up);
  // Whether the client reads its replies' images raw (an image reader announcing its id is
  // matched, as send_images asks): its calls are made with Call::raw_attachments, so that
  // the camera leaves the PNG out. Cached until the image writer's matches change.
  bool takes_images_raw(const ClientId& id, ClientState& client);
  // Whether a reader announcing the client's id is matched to `writer` (one of its own).
  static bool announced_reader_matched(dds_entity_t writer, const ClientId& id);
  // Writes the replies of `batch` (emptied); `final_flush`: at stop(), without parking.
  void write_finished(std::vector<std::pair<RequestId, Outcome>>& batch, bool final_flush);
  // The request writers matched now: new ones become clients, missing ones are gone.
  void sweep_clients();
  void add_client(dds_instance_handle_t writer);
  void client_gone(const ClientId& id, ClientState& client);
  void forget_client(const ClientId& id);
  // Deletes a forgotten client's reply publisher once its writer holds nothing unacknowledged:
  // now if it can, else at a later pass (retire_pending). Cyclone's dds_delete of a writer
  // that still holds samples waits for their acknowledgements, up to WriterLingerDuration
  // (1 s by default): a peer that withdraws its request writer while its reply reader stays
  // matched and silent would hold the DDS thread that long, once per such client. (A Cyclone
  // peer whose reader is full cannot get that far: its receive thread is stuck, and so is
  // its own deletion; a crafted peer can.)
  // `writer` and `image_writer` (0: none): the reliable writers under `publisher` whose
  // acknowledgements are awaited (its reply writer, and its image writer).
  void retire(dds_entity_t publisher, dds_entity_t writer, dds_entity_t image_writer);
  void retire_pending();
  // Whether a reader announcing the client's id matches its reply writer (reads the status).
  void refresh_reader_match(const ClientId& id, ClientState& client);
  void send_reply(const ClientId& client, ReplyData reply, bool final_flush = false);
  // Writes what the client's writer takes of its parked replies; drops the expired ones
  // it does not take.
  void flush_parked(const ClientId& id, ClientState& client,
                    std::chrono::steady_clock::time_point now);
  // When a parked reply is given up: park_timeout_ms after it was parked or after its
  // writer last took one, whichever is later (a client that reads, however slowly, loses
  // nothing to a queue longer than park_timeout_ms allows at full speed).
  std::chrono::steady_clock::time_point parked_expiry(const ClientState& client,
                                                      const ReplyData& reply) const {
    return std::max(reply.deadline, client.progressed_at + options_.park_timeout);
  }
  // Every client's flush_parked; returns when the next parked reply needs attention.
  std::chrono::steady_clock::time_point flush_all_parked();
  // DDS_RETCODE_TIMEOUT: the writer is full (its reader does not acknowledge); never blocks.
  // A run of Overloaded refusals (seq_end) is written one sample per seq; `reply.seq` is
  // left at the first one the writer did not take.
  dds_return_t write_reply(const ClientId& id, const ClientState& client, ReplyData& reply);
  void drop_reply(const ClientId& id, ClientState& client, const ReplyData& reply);
  bool lookup_async(const std::string& component, const std::string& service);
  static ReplyData to_reply(std::uint64_t seq, const Outcome& outcome);
  static ReplyData failure_reply(std::uint64_t seq, simgate_Failure failure, std::string message);
  // The number a client's calls carry as Call::client: its 16-byte id folded to 64 bits
  // (never 0).
  static std::uint64_t client_number(const ClientId& id) {
    std::uint64_t halves[2];
    std::memcpy(halves, id.data(), sizeof halves);
    return (halves[0] ^ halves[1]) | 1;
  }
  // Requests of `client` taken and not answered yet: pending in the core (calls, cancels)
  // or with their final reply parked. At max_in_flight, a request is refused Overloaded.
  static std::size_t in_flight(const ClientState& client) {
    return client.calls.size() + client.parked_finals;
  }
  // The refusal of a request past max_in_flight (ST_FAILED, FL_BUSY, "Overloaded: ...").
  ReplyData overloaded_reply(std::uint64_t seq) const;
  // A final reply counted in flight while parked (not an Overloaded refusal).
  static bool counted(const ReplyData& reply) { return reply.last && reply.seq_end == 0; }

  DdsOptions options_;                        // validated options
  std::unique_ptr<Participant> participant_;  // owns every entity below
  dds_entity_t publisher_ = 0;                // in our partition
  dds_entity_t subscriber_ = 0;               // in our partition
  dds_entity_t request_reader_ = 0;           // simgate_Request
  dds_entity_t reply_topic_ = 0;              // simgate_Reply (a writer per client)
  QosPtr reply_qos_;                          // of every reply writer
  dds_entity_t progress_topic_ = 0;           // simgate_Progress (a writer per client asking)
  QosPtr progress_qos_;                       // of every progress writer
  dds_entity_t image_topic_ = 0;              // simgate_ReplyImage (a writer per client)
  QosPtr image_qos_;                          // of every image writer
  dds_entity_t catalog_writer_ = 0;           // simgate_Catalog (transient-local)
  dds_entity_t waitset_ = 0;                  // what the DDS thread waits on
  dds_entity_t guard_ = 0;                    // raised by the sim thread and by stop()
  dds_entity_t read_condition_ = 0;           // requests available
  std::string server_id_;                     // our participant GUID, hex
  std::unique_ptr<DdsStreams> streams_;       // the data streams (null: none carried)
  std::thread thread_;                        // the DDS thread
  std::atomic<bool> stopping_{false};         // asks the DDS thread to leave
  std::atomic<bool> stopped_{false};          // stop() ran
  std::atomic<bool> started_{false};          // start() ran

  // outcomes delivered (on_service_completion), not yet written (DDS thread; at stop(),
  // under the simulation lock)
  std::vector<std::pair<RequestId, Outcome>> finished_;
  // being written (DDS thread; stop() after the join)
  std::vector<std::pair<RequestId, Outcome>> draining_;
  // progress reports delivered (on_service_progress), not yet written (DDS thread; ignored
  // once stopping)
  std::vector<std::pair<RequestId, json>> progress_;
  std::string progress_text_;  // write_progress's JSON buffer (DDS thread)

  // ---- DDS thread only ----
  std::unordered_map<RequestId, Pending> pending_;     // requests in the core
  std::map<ClientId, ClientState> clients_;            // known clients
  std::map<dds_instance_handle_t, ClientId> writers_;  // request writer -> its client
  std::map<dds_entity_t, ClientId> reply_writers_;     // reply writer -> its client
  // a forgotten client's publisher to delete once its reliable writers hold nothing unacknowledged
  struct Retiring {
    dds_entity_t publisher;     // deleted with its writers
    dds_entity_t writer;        // its reply writer
    dds_entity_t image_writer;  // its image writer (0: none)
  };
  std::vector<Retiring> retiring_;
  std::atomic<std::size_t> client_count_{0};              // matched request writers, for any thread
  std::unordered_map<std::string, bool> async_services_;  // "component.service" -> is_async
  std::set<std::string> published_;                       // components with a catalog entry written
  std::uint32_t catalog_revision_ = 0;  // of the last catalog published (CatalogEntry.revision)
  std::atomic<bool> catalog_changed_{false};       // publish the catalog anew (any thread)
  std::string lookup_key_;                         // lookup_async's key buffer
  std::vector<std::pair<RequestId, Call>> batch_;  // calls taken, not yet given to the core
  bool run_pending_ = false;                       // a cancel was queued: run_batch() runs it
  std::size_t parked_count_ = 0;                   // replies parked over all clients
};

}  // namespace simgate::dds

#endif  // SIMGATE_PLUGINS_DDS_DDS_REQUEST_MANAGER_H_
