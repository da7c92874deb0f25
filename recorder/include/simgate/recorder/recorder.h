// simgate/recorder/recorder.h — the flight recorder (issue #39): a run written to an MCAP file
// as it happens, so that `simgate replay` can re-run it bit for bit and say where two runs
// part (replay.h; docs/recording.md).
//
// What a recording holds (format.h names the channels):
//  - the inputs, in the order they took effect, each with the step count at that moment: every
//    request a service ran, from every transport (client, arguments), every interruption of a
//    running request from outside (a cancel, a deadline), every command applied to an input
//    stream, every batch of finished off-lock work (a spawned entity's model) taken in;
//  - the outcome of each request (status, message, a small value);
//  - a fingerprint of the state after every step (state_hash.h), in blocks;
//  - the physics state it started from, and what the run was made of: the deployment document,
//    the MJCF scene as an attachment, MuJoCo's and simgate's versions as metadata;
//  - every output stream's samples (Foxglove's schemas where one fits: sensors.h, the same
//    encoders as the foxglove transport), so that Foxglove or Lichtblick play the run back.
//
// Threads: the recorder is both the gate's input tap and the simulation's observer: those calls
// come under the simulation lock and only copy what they need into a queue (plain fields, no
// JSON). Its own writer thread takes the queue and the stream samples every 20 ms (nothing wakes
// it per message), encodes and writes, so the simulation never waits for the disk. Memory is
// bounded: stream subscriptions keep up to 1024 samples (a camera's 16; a slow disk drops
// samples, counted, as for any subscriber), and the inputs' queue
// at most RecordingOptions::max_queue_bytes; past that, or on a write error (a full disk), the
// recording stops with a logged error and the simulation goes on.
#ifndef SIMGATE_RECORDER_RECORDER_H_
#define SIMGATE_RECORDER_RECORDER_H_

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "simgate/core/input_tap.h"
#include "simgate/core/streams.h"
#include "simgate/foxglove/scene.h"
#include "simgate/foxglove/sensors.h"
#include "simgate/mcap/writer.h"
#include "simgate/sim/simulation.h"
#include "simgate/sim/state_hash.h"

namespace simgate::recorder {

struct RecordingOptions {
  std::string path;  // the MCAP file (created or truncated)
  mcap::Compression compression = mcap::Compression::zstd;
  // What the run was made of (format.h: the deployment attachment): {"document", "base_dir",
  // "file"}; null: not said (a replay then needs a config).
  json deployment = nullptr;
  // Files the recording carries as attachments (the MJCF scene), by absolute path.
  std::vector<std::string> attachments;
  // The most the inputs waiting for the writer may take; past it the recording stops.
  std::size_t max_queue_bytes = std::size_t{256} << 20;
  // Steps per block of state fingerprints.
  std::uint32_t hash_block = 100;
  // Samples each stream subscription keeps for the writer, which takes them every
  // k_writer_period (older ones are dropped, counted): enough for a 60 Hz stream of a
  // simulation a hundred times faster than real time; a pushed stream (a camera's images,
  // large) keeps fewer.
  std::size_t stream_capacity = 1024;
  std::size_t pushed_stream_capacity = 16;
};

class Recorder final : public InputTap, public sim::Simulation::Observer {
 public:
  // Starts recording `simulation` from now: writes the file's head (metadata, attachments,
  // the initial state), subscribes to every output stream, and sets itself as the gate's
  // input tap and the simulation's observer. Under the simulation lock. Throws
  // std::runtime_error naming the file when it cannot be created.
  Recorder(sim::Simulation& simulation, RecordingOptions options);
  // finish() if not done (the caller must not hold the simulation lock).
  ~Recorder() override;
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  // Stops taking inputs and samples (the tap, the observer and the subscriptions are removed).
  // Under the simulation lock. Idempotent.
  void detach();
  // After detach(): the writer writes what is left and closes the file (the summary, the
  // footer). Without the simulation lock (it waits for the writer). Returns the status.
  json finish();

  // {"path", "recording": bool, "error": why it stopped early (or null), "steps", "inputs",
  //  "samples", "samples_dropped", "bytes"}. Any thread.
  json status() const;
  const std::string& path() const { return options_.path; }
  // The error that stopped the recording early, or "" (any thread).
  std::string error() const;

  // ---- InputTap and Simulation::Observer (under the simulation lock) ----
  void request_started(const RequestManager& manager, RequestId id, const Call& call) override;
  void request_ended(const RequestManager& manager, RequestId id, const Outcome& outcome) override;
  void request_interrupted(const RequestManager& manager, RequestId id, Failure reason) override;
  void command_applied(std::string_view component, const json& command,
                       const std::string& refusal) override;
  void stepped() override;
  void tasks_ran(std::size_t count) override;

 private:
  // A stream the recorder subscribed to, and the channels its samples go to.
  struct Stream {
    std::string component;
    std::string kind;
    std::shared_ptr<StreamSubscription> subscription;
    std::uint16_t json_channel = 0;  // the component's JSON samples (when no sensor schema fits)
    bool as_json = false;
    std::vector<std::pair<std::uint16_t, foxglove::SensorMessage>> sensor_channels;
    LaserArc arc;  // a laser's (simgate/core/laser_arc.h)
    std::uint32_t sequence = 0;
    bool body_poses = false;  // the simulation's: also /tf (and /scene per model)
    std::string type;         // the component's type (its JSON schema's description)
    json sample_schema;       // the JSON channel's schema, from a sample read when subscribed
  };

  // One message for the writer, made under the lock: plain fields (copies of strings that fit
  // in place, mostly), which the writer thread turns into JSON: what a request costs the
  // simulation thread is a few copies, no JSON object built.
  struct Pending {
    enum class Kind : std::uint8_t {
      request,
      interrupt,
      command,
      tasks,
      outcome,
      hashes,
      geometry,
      stream,  // a stream to record from now on (a spawned robot's)
    };
    Kind kind = Kind::request;
    std::uint64_t seq = 0;   // inputs: 1, 2, ...
    std::uint64_t step = 0;  // the step count when it took effect
    double sim_time = 0;
    std::string transport;            // request, interrupt, outcome
    std::uint64_t client = 0;         // request
    RequestId id = 0;                 // request, interrupt, outcome
    std::string component;            // request, command
    std::string service;              // request
    std::string text;                 // command: the refusal; outcome: the message
    json value;                       // request: params; command: the command; outcome: the value
                                      // (if small); geometry: the scene's
    Status status = Status::success;  // outcome
    Failure failure = Failure::none;  // outcome; interrupt: the reason
    std::size_t count = 0;            // tasks
    std::vector<mjtNum> states;       // hashes: each step's state, in turn
    std::shared_ptr<const sim::StateHasher> hasher;  // hashes: what hashes them (writer thread)
    std::uint64_t generation = 0;                    // hashes
    std::unique_ptr<Stream> stream;                  // stream
    std::size_t bytes = 0;                           // what it takes in the queue, roughly
  };
  // The message's channel and JSON (writer thread).
  std::uint16_t channel_of(const Pending& p) const;
  static json to_json(Pending& p);

  // Under the simulation lock: the channels, and what the file's head says (the metadata, the
  // initial state), kept for write_head().
  void prepare_head(const sim::Simulation& simulation);
  // The writer thread, first: the metadata, the attachments (files read here, off the lock) and
  // the initial state, handed to the file at once.
  void write_head();
  // Under the simulation lock: every output stream not subscribed to yet (all at the start, a
  // spawned robot's later) subscribed and handed to the writer (add_stream): at once before the
  // writer runs, queued after.
  void find_streams();
  // The writer's side (or before it runs): the stream's channels; it is taken from then on.
  void add_stream(Stream stream);
  // An input on the inputs channel: `p` gets its seq, step and sim_time.
  void input(Pending p);
  // Queues `p` for the writer (which looks every k_writer_period, or at once past
  // k_wake_bytes: no wake-up per message); stops the recording when the queue is too full.
  void enqueue(Pending p);
  void flush_hashes();
  void writer_loop();
  void write_samples(Stream& stream, std::vector<SamplePtr>& samples);
  // The scene's geometry for /scene and /tf (at the start, and after each model change): a
  // Pending for the writer. Under the simulation lock.
  void queue_geometry();
  // The writer's side: the frames /tf names, /scene's entities (writer thread).
  void write_geometry(Pending& p);
  static std::uint64_t time_ns(double sim_time);  // a message's log time
  std::uint64_t step() const;

  sim::Simulation& simulation_;
  RecordingOptions options_;
  std::unique_ptr<mcap::Writer> writer_;  // the writer thread's, once started
  std::uint16_t inputs_channel_ = 0, outcomes_channel_ = 0, hashes_channel_ = 0, state_channel_ = 0;
  bool attached_ = false;         // under the simulation lock
  mcap::Metadata head_metadata_;  // prepare_head() -> write_head()
  std::string initial_state_;     // prepare_head() -> write_head()
  std::uint64_t head_time_ = 0;   // prepare_head() -> write_head()

  // under the simulation lock: the requests recorded as started and not yet ended, by manager
  std::unordered_map<const RequestManager*, std::unordered_set<RequestId>> open_;
  std::uint64_t input_seq_ = 0;
  std::uint64_t first_step_ = 0;
  std::uint64_t generation_ = 0;
  std::shared_ptr<const sim::StateHasher> hasher_;
  // the block being filled: each step's state (mjSTATE_INTEGRATION), hashed by the writer
  // thread (a copy costs the simulation thread less than its hash)
  std::vector<mjtNum> state_block_;
  std::uint64_t block_first_step_ = 0;
  std::uint32_t block_steps_ = 0;
  std::atomic<std::uint64_t> steps_recorded_{0};  // written under the simulation lock

  std::unordered_set<std::string> subscribed_;  // under the simulation lock: their components
  bool body_poses_found_ = false;               // under the lock: the body_poses stream is taken
  // the writer thread's; added to under mutex_ (status() reads the subscriptions' counters)
  std::vector<Stream> streams_;
  std::uint16_t tf_channel_ = 0, scene_channel_ = 0;  // when the body_poses stream is there
  json geometry_;                 // the writer thread's: the last geometry queued
  foxglove::SceneFrames frames_;  // the writer thread's: its frames

  mutable std::mutex mutex_;  // guards what follows
  std::condition_variable cv_;
  std::deque<Pending> queue_;
  // state blocks the writer has hashed, emptied, for the simulation thread to fill again
  static constexpr std::size_t k_spare_state_blocks = 4;
  std::vector<std::vector<mjtNum>> spare_states_;
  std::size_t queue_bytes_ = 0;
  bool finishing_ = false;
  std::string error_;
  std::uint64_t inputs_ = 0, samples_ = 0;
  std::uint64_t bytes_written_ = 0;
  bool finished_ = false;
  std::thread thread_;
};

}  // namespace simgate::recorder

#endif  // SIMGATE_RECORDER_RECORDER_H_
