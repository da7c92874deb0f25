// simgate/core/streams.h — data streams: sensors' samples out, actuators' commands in,
// carried by any transport (MORSE's datastreams).
//
// Terms:
//  - stream: a component's StreamDeclaration (component.h) as the configuration set it up:
//    the transports that carry it and, for an output stream, its frequency in samples per
//    simulated second (MORSE's `frequency`).
//  - sample: what an output stream's component gives at one moment (its get_local_data),
//    stamped with a sequence number and the simulated time. Produced once, shared by every
//    subscriber; its JSON text is written once, by the first transport that needs it.
//  - subscription: one subscriber's queue of samples (a socket connection to a stream port,
//    a JSON-RPC client's subscribe, a DDS writer). It keeps the latest `capacity` samples:
//    a subscriber that falls behind loses its oldest ones, counted (dropped()), and logged
//    once; the simulation and the other subscribers never wait for it.
//  - pushed stream: an output stream whose component pushes its samples when it has them
//    (Component::push_sample, under the simulation lock), instead of the hub reading one
//    when it is due: a camera's images, which exist only once the render thread has
//    rendered them. The hub never asks it for a sample; the component asks whether the
//    stream is wanted (StreamOutlet::wanted: it has subscribers) and keeps its own rate.
//    A pushed sample goes to every subscriber (it is due by definition, and is a new
//    subscriber's first), through the same queues, drops, counters and wakes.
//  - payload: a sample may carry bytes instead of JSON (an image's pixels, raw), with a
//    small JSON description of them. Typed transports (DDS) read the bytes as they are;
//    JSON transports read data(), made from the payload by its to_json once, on the first
//    transport thread that asks (an image's PNG, base64, is encoded there, never under the
//    simulation lock).
//  - command: what a client writes to an input stream (a JSON object whose keys are among
//    the stream's fields, or "timestamp": the hub refuses any other at once). The latest
//    wins: a command not yet applied when a newer one comes is replaced (counted).
//
// The StreamHub runs every stream of one simulation. The simulation calls publish_due()
// after each step (a sample for each output stream that has subscribers and is due by its
// frequency, plus a first one for each new subscriber, so that a client of a paused
// simulation is not left waiting) and apply_commands() on each of its turns. Transports
// find their streams with streams(transport), subscribe to output streams and publish to
// input streams; they never touch a component.
//
// Threads: add(), remove(), publish_due() and apply_commands() under the simulation lock
// (or before the transports start). Everything else is thread-safe: transports call it from
// their own threads. A subscription's `wake` is called on the thread that holds the
// simulation lock, once each time its queue goes from empty to not empty: it must only post
// to the transport's thread (asio::post, a DDS guard condition).
#ifndef SIMGATE_CORE_STREAMS_H_
#define SIMGATE_CORE_STREAMS_H_

#include <array>
#include <atomic>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "simgate/core/component.h"
#include "simgate/core/simulation_gate.h"

namespace simgate {

// Bytes a sample carries as they are (see payload above). Core knows nothing of what they
// are: `content` and `description` say it, and the transports that know that content read
// them (DDS writes an "image" as its Image type); every other transport sees to_json's.
struct StreamPayload {
  std::string content;              // what the bytes are: "image"
  json description;                 // their shape, a few keys (an image: width, height,
                                    // encoding, step, is_bigendian, intrinsic_matrix)
  std::vector<std::uint8_t> bytes;  // the data
  // The sample as JSON transports send it (an image: its record, PNG in base64). Called at
  // most once per sample, by StreamSample::data(), on the first thread that asks.
  std::function<json(const StreamPayload&)> to_json;
};

class StreamHub;

// A pushed stream's link between its component (StreamDeclaration::outlet) and the hub that
// runs it: StreamHub::add() connects it, remove() (or the hub's end) disconnects it.
class StreamOutlet {
 public:
  explicit StreamOutlet(std::string component) : component_(std::move(component)) {}
  StreamOutlet(const StreamOutlet&) = delete;
  StreamOutlet& operator=(const StreamOutlet&) = delete;

  // Whether the stream has subscribers now. Any thread; one atomic read.
  bool wanted() const { return wanted_.load(std::memory_order_acquire); }
  // Gives the hub one sample (JSON, or `payload` when not null) of simulated time `time`.
  // Under the simulation lock. False when no hub runs the stream or nobody subscribes.
  bool push(double time, json data, std::shared_ptr<const StreamPayload> payload);
  // A sample that was due and will never be pushed (the component could not make it in
  // time): counted (StreamStatistics::skipped, and among the dropped). Under the simulation
  // lock; ignored when no hub runs the stream.
  void note_skipped();

 private:
  friend class StreamHub;
  const std::string component_;
  std::atomic<bool> wanted_{false};  // written by the hub under its mutex
  StreamHub* hub_ = nullptr;  // written by add(), remove(), ~StreamHub: under the simulation lock
};

// What a transport knows of a stream.
struct StreamInfo {
  std::string component;  // "robot.pose"
  StreamDirection direction = StreamDirection::out;
  std::string kind;                 // StreamDeclaration::kind: "pose", "velocity"...
  std::string type;                 // the component's type name ("pose", "motion_vw")
  double frequency = 0;             // out: samples per simulated second (an event stream: 0); in: 0
  bool pushed = false;              // out: its component pushes its samples (see above)
  std::vector<std::string> fields;  // in: the keys a command takes
  std::vector<std::string> transports;  // the transports that carry it
};

// One sample of an output stream. Immutable once published; shared by every subscriber.
// Either JSON (the component's get_local_data), or a record: numbers named by the stream's
// fields (StreamDeclaration::produce_record), or a payload: bytes (StreamPayload). A
// record's or a payload's JSON is made only when a transport asks for data() or text().
// The hub reuses a record sample that only direct subscribers had (it never left the
// simulation thread) for its stream's next one: no allocation per sample there.
class StreamSample {
 public:
  StreamSample(std::uint64_t seq, double time, json data)
      : seq_(seq), time_(time), data_(std::move(data)) {}
  // A record: `fields` names the numbers (their values are written by the hub, before the
  // sample is shared).
  StreamSample(std::uint64_t seq, double time,
               std::shared_ptr<const std::vector<std::string>> fields)
      : seq_(seq), time_(time), fields_(std::move(fields)) {}
  // A payload (not null).
  StreamSample(std::uint64_t seq, double time, std::shared_ptr<const StreamPayload> payload)
      : seq_(seq), time_(time), payload_(std::move(payload)) {}

  std::uint64_t seq() const { return seq_; }  // 1, 2, ... per stream
  double time() const { return time_; }       // simulated seconds the data is of
  // The component's sample as JSON (a record's made once, by whichever thread asks first).
  const json& data() const;
  // data() as compact JSON text, written once (by whichever thread asks first).
  const std::string& text() const;
  bool is_record() const { return fields_ != nullptr; }
  // The bytes it carries, or null (a JSON or record sample).
  const StreamPayload* payload() const { return payload_.get(); }
  // The number named `key`: from the record without JSON, else from the JSON object. Throws
  // std::out_of_range when the sample has no such number.
  double number(std::string_view key) const;
  // The numbers named by `keys` into `out` (as many), as number() would read each; a record's
  // are looked for from where the previous key was found, so keys in the record's own order
  // cost one comparison each (a typed transport filling its struct).
  void numbers(std::span<const std::string_view> keys, std::span<double> out) const;

 private:
  friend class StreamHub;
  std::span<double> record_values() { return {values_.data(), fields_ ? fields_->size() : 0}; }
  // Makes a record sample that no other thread ever had the next one, of `time` (its JSON
  // and text are made again when asked).
  void reuse(double time);

  std::uint64_t seq_;
  double time_;
  std::shared_ptr<const std::vector<std::string>> fields_;  // a record's (null: JSON)
  std::shared_ptr<const StreamPayload> payload_;            // a payload's (null: JSON)
  std::array<double, k_max_record_fields> values_{};        // a record's, fields_->size() of them
  // the JSON and text, made once by whichever thread asks first (not std::once_flag: a
  // reused sample makes them again)
  mutable std::mutex made_mutex_;               // guards making them
  mutable std::atomic<bool> data_made_{false};  // a record's or payload's data_ is made
  mutable std::atomic<bool> text_made_{false};  // text_ is made
  mutable json data_;
  mutable std::string text_;
};
using SamplePtr = std::shared_ptr<const StreamSample>;

// How a transport subscribes.
struct SubscriberOptions {
  std::size_t capacity = 16;  // samples kept; older ones are dropped (at least 1)
  // (every member has a default initializer, so that {capacity, label, wake} leaves the
  // rest default without -Wmissing-field-initializers)
  std::string label{};           // who it is, for the log: "socket client #3 (127.0.0.1:5123)"
  std::function<void()> wake{};  // the queue went from empty to not empty (see above)
  // Set: a direct subscriber. Each sample it gets is handed to `deliver` right after it is
  // made, on the thread that holds the simulation lock, instead of being queued: no queue,
  // no wake, no hand-off to the transport's thread. Only for a write that is short and never
  // waits (DDS's best-effort writer of a small typed sample): it is called under the hub's
  // mutex, so it must not call the hub. Returns false when the sample was not sent (counted
  // as dropped, like a queue's drop). Never called again once unsubscribe() (or the
  // stream's removal) has returned. `capacity` and `wake` are unused.
  std::function<bool(const StreamSample&)> deliver{};
  // What the subscriber calls the stream when that is not its component's name in the hub:
  // a world's stream reached through StreamDirectory ("w3/robot.pose"). component() gives it.
  std::string address{};
};

// One subscriber's queue.
class StreamSubscription {
 public:
  StreamSubscription(std::string component, SubscriberOptions options)
      : component_(options.address.empty() ? component : options.address),
        stream_(std::move(component)),
        options_(std::move(options)) {}

  // The stream's name as the subscriber gave it (a world's: "w3/robot.pose").
  const std::string& component() const { return component_; }
  const std::string& label() const { return options_.label; }
  // Appends every queued sample to `out`, oldest first; returns how many. The next sample
  // wakes the subscriber again.
  std::size_t take(std::vector<SamplePtr>& out);
  // The transport lost `n` samples itself (a client whose socket is full): counted with the
  // queue's own drops.
  void note_dropped(std::uint64_t n);
  std::uint64_t dropped() const;
  std::uint64_t delivered() const;  // samples queued for it so far (dropped ones included)
  // The stream is gone (its component deleted) or the hub unsubscribed it: nothing more
  // comes. The transport ends the subscription on its side (closes a stream connection).
  bool closed() const;

 private:
  friend class StreamHub;
  // Hub side (under the simulation lock and the hub mutex): a queue takes `sample` when it
  // is `due` or the first this subscriber waits for (wake: the subscriber must be woken); a
  // direct subscriber is to be given it by deliver() at once.
  enum class Pushed : std::uint8_t { no, queued, wake, deliver };
  Pushed push(const SamplePtr& sample, bool due);
  // A direct subscriber's delivery, when `due` or its first (under the simulation lock and
  // the hub mutex: one lock for the fan-out and the write; its own mutex is not taken).
  void deliver(const StreamSample& sample, bool due);
  void close();
  void wake() const {
    if (options_.wake) options_.wake();
  }
  // Logs the first drop (once per subscriber).
  void log_first_drop();

  const std::string component_;  // as the subscriber names it
  const std::string stream_;     // its component's name in the hub
  const SubscriberOptions options_;
  mutable std::mutex mutex_;     // guards what follows, up to the counters
  std::deque<SamplePtr> queue_;  // oldest first
  bool wake_armed_ = true;       // the next push wakes
  bool closed_ = false;
  bool drop_logged_ = false;
  bool failure_logged_ = false;  // a direct delivery threw (logged once; under the hub mutex)
  bool wants_first_ = true;      // gets a sample at the hub's next turn, due or not (also
                                 // under the hub mutex: push() and deliver() are)
  std::atomic<std::uint64_t> dropped_{0};
  std::atomic<std::uint64_t> delivered_{0};
};

// Counters of one stream (simulation get_stream_statistics).
struct StreamStatistics {
  StreamInfo info;
  std::uint64_t samples = 0;    // out: samples produced
  std::size_t subscribers = 0;  // out: subscriptions now
  // out: samples subscribers lost, now and before (skipped ones included)
  std::uint64_t dropped = 0;
  std::uint64_t skipped = 0;   // out, pushed: samples due that the component never made
                               // (a camera's render thread behind); every subscriber lost them
  std::uint64_t commands = 0;  // in: commands applied
  std::uint64_t replaced = 0;  // in: commands replaced by a newer one before being applied
  std::uint64_t refused = 0;   // in: commands the component refused
  std::string last_refusal;    // in: why the last refused one was
};

// What publish() did with a command.
struct PublishResult {
  bool ok = false;       // applied, or queued for the simulation's next turn
  bool applied = false;  // applied at once (the simulation lock was free)
  // why not (no such input stream here, not an object, the component refused it)
  std::string error;
};

// What a transport reaches streams through: the streams of one simulation (a StreamHub), or
// of every world a transport serves (RequestManager::streams(): world 0's under their names,
// world k's as "w<k>/<component>", docs/worlds.md). Thread-safe; see StreamHub for each call.
class StreamDirectory {
 public:
  virtual ~StreamDirectory() = default;

  // The streams `transport` carries, in the order they were added (world by world).
  virtual std::vector<StreamInfo> streams(std::string_view transport) const = 0;
  // One stream, if `transport` carries it.
  virtual std::optional<StreamInfo> find(std::string_view component,
                                         std::string_view transport) const = 0;
  // Subscribes to the output stream of `component` carried by `transport`; null when there
  // is none. The first sample comes at the simulation's next turn.
  virtual std::shared_ptr<StreamSubscription> subscribe(std::string_view component,
                                                        std::string_view transport,
                                                        SubscriberOptions options) = 0;
  // Ends a subscription (idempotent; null is ignored).
  virtual void unsubscribe(const std::shared_ptr<StreamSubscription>& subscription) = 0;
  // A command for the input stream of `component` carried by `transport` (StreamHub::publish).
  virtual PublishResult publish(std::string_view component, std::string_view transport,
                                json command) = 0;
  // A command the transport could not read, counted as refused (StreamHub::note_refused).
  virtual bool note_refused(std::string_view component, std::string_view transport,
                            std::string reason) = 0;
  // One sample of the output stream of `component` read now (StreamHub::sample_now). Under
  // the simulation lock of the transport's manager (world 0's); a world's stream is read
  // under that world's lock too, taken here (world 0's, then a world's: step_many's order).
  virtual std::optional<json> sample_now(std::string_view component) const = 0;
  // The simulated time of the last turn (world 0's). Any thread.
  virtual double time() const = 0;
};

class StreamHub final : public StreamDirectory {
 public:
  // `gate`: the simulation's (signalled when a command or a subscriber waits for its turn).
  explicit StreamHub(std::shared_ptr<SimulationGate> gate);
  ~StreamHub();
  StreamHub(const StreamHub&) = delete;
  StreamHub& operator=(const StreamHub&) = delete;

  // Default frequency of an output stream (MORSE's: the game engine's 60 Hz).
  static constexpr double k_default_frequency = 60;

  // ---- setting up (before the transports start, or under the simulation lock) ----

  // The stream `component` declared (Component::stream(); throws std::invalid_argument when
  // it declared none, or it is added already), carried by `transports`, at `frequency`
  // (out; > 0). `type`: the component's type name. The component must outlive it (remove()).
  void add(const Component& component, std::string type, std::vector<std::string> transports,
           double frequency = k_default_frequency);
  // The component leaves (deleted at run time): its subscriptions close (their subscribers
  // are woken to see it) and its pending command is dropped. False when it had no stream.
  bool remove(const std::string& component);
  // Every stream leaves (its simulation goes: a world deleted), as remove() each.
  void remove_all();

  // ---- the simulation (under the lock) ----

  // After a step, `time` being the simulated time the components' data is of: one sample
  // for each output stream that is due and has subscribers, to all of them; one for each
  // new subscriber of a stream that is not due, to it alone. Also on a turn without a step
  // (new subscribers of a paused simulation get theirs).
  void publish_due(double time);
  // Applies the commands waiting; returns how many. The loop's turn: apply_commands(), then
  // publish_due() (in that order: this clears turn_wanted()).
  std::size_t apply_commands();
  // Whether a turn without a step has anything to do: a command waits, or a new subscriber
  // its first sample (a cheap look, for the loop's every turn).
  bool turn_wanted() const { return turn_wanted_.load(std::memory_order_acquire); }

  // One sample of the output stream of `component` read now, as the JSON its subscribers
  // see (what it produces, a record as its object), for a transport that describes the
  // stream by an example (Foxglove's channel schemas). Under the simulation lock. Nothing
  // for a pushed stream (its samples come when the component has them), an input stream,
  // no such stream, or a component that failed to produce one.
  std::optional<json> sample_now(std::string_view component) const override;
  // A sample of the pushed stream of `component` (StreamOutlet::push, under the simulation
  // lock): to every subscriber. False when it has none.
  bool push(const std::string& component, double time, json data,
            std::shared_ptr<const StreamPayload> payload);
  // A sample of the pushed stream of `component` that was due and never comes
  // (StreamOutlet::note_skipped, under the simulation lock): counted, logged once per stream.
  void note_skipped(const std::string& component);

  // ---- transports (any thread) ----

  // What a subscriber that is no transport (a recorder) names as its transport: every
  // stream, whichever transports carry it.
  static constexpr std::string_view k_every_transport = "*";

  // The streams `transport` carries, in the order they were added.
  std::vector<StreamInfo> streams(std::string_view transport) const override;
  // One stream, if `transport` carries it.
  std::optional<StreamInfo> find(std::string_view component,
                                 std::string_view transport) const override;
  // Subscribes to the output stream of `component` carried by `transport`; null when there
  // is none. The first sample comes at the simulation's next turn.
  std::shared_ptr<StreamSubscription> subscribe(std::string_view component,
                                                std::string_view transport,
                                                SubscriberOptions options) override;
  // Ends a subscription (idempotent; null is ignored).
  void unsubscribe(const std::shared_ptr<StreamSubscription>& subscription) override;
  // A command for the input stream of `component` carried by `transport`: applied at once
  // when the simulation lock is free (so that `error` says whether the component took it),
  // else kept for the simulation's next turn (replacing one not yet applied).
  // A command that is not a JSON object is refused and counted too, when the stream is there.
  PublishResult publish(std::string_view component, std::string_view transport,
                        json command) override;
  // Why `command` (an object) does not fit the input stream `info` (a key that is none of
  // its fields, nor "timestamp"), or "": what publish() refuses at once. Public for the
  // fuzz target line_decoders.
  static std::string unknown_key(const StreamInfo& info, const json& command);
  // A command for the input stream of `component` carried by `transport` that the transport
  // could not even read (a socket line that is not JSON, too long; a DDS sample that is not
  // a JSON object): counted as refused, `reason` kept as its last_refusal, as if the
  // component had refused it. Not logged: the transport logs it in its own terms (once per
  // connection, per reader). False when there is no such input stream.
  bool note_refused(std::string_view component, std::string_view transport,
                    std::string reason) override;

  // The simulated time of the simulation's last turn (publish_due's `time`), for a
  // transport that tells its clients the time between samples (Foxglove's time messages).
  // 0 before the first turn. Any thread.
  double time() const override { return time_.load(std::memory_order_relaxed); }

  // Every stream's counters (those `transport` carries; empty: all).
  std::vector<StreamStatistics> statistics(std::string_view transport = {}) const;
  // Totals over every stream: samples produced, samples dropped.
  std::uint64_t total_samples() const;
  std::uint64_t total_dropped() const;

 private:
  struct Stream;
  struct Due;
  Stream* find_locked(std::string_view component);
  const Stream* find_locked(std::string_view component) const;
  // The input stream of `component`, if `transport` carries it (under the hub mutex).
  Stream* find_input_locked(std::string_view component, std::string_view transport);
  // Applies `command` to `stream` (under the simulation lock, without the hub mutex: the
  // component runs with no transport waiting on it); counts it; the refusal, if any.
  std::string apply(Stream& stream, const json& command);
  // Counts a refusal of `stream` (under the hub mutex); logs the stream's first when `log`.
  static void count_refusal_locked(Stream& stream, std::string reason, bool log);
  // Gives `sample` to the subscribers of `stream` (under the hub mutex): queued ones and
  // direct ones now, those to wake noted for after_fan_out(). True when a queue took it
  // (another thread may read it from then on).
  bool fan_out(Stream& stream, const SamplePtr& sample, bool due);
  // Without the hub mutex: wakes the subscribers noted by fan_out.
  void after_fan_out();

  std::shared_ptr<SimulationGate> gate_;
  // guards streams_, their subscribers, pending commands and counters; never held while a
  // component's produce() or apply() runs (those hold the simulation lock, which add() and
  // remove() need too), so a transport thread never waits on a component. streams_ and the
  // streams' schedules change only under the simulation lock as well: publish_due, which
  // holds it, picks the due streams without this mutex
  mutable std::mutex mutex_;
  std::vector<std::unique_ptr<Stream>> streams_;  // in the order added
  std::uint64_t dropped_by_removed_ = 0;          // drops of subscriptions that ended
  // subscriptions now, all streams (publish_due's fast path)
  std::atomic<std::size_t> subscribers_{0};
  std::atomic<bool> turn_wanted_{false};  // see turn_wanted()
  std::atomic<double> time_{0};           // see time()
  // publish_due's buffers, kept between calls (it runs under the simulation lock only)
  std::vector<Due> due_;
  std::vector<std::shared_ptr<StreamSubscription>> to_wake_;
};

}  // namespace simgate

#endif  // SIMGATE_CORE_STREAMS_H_
