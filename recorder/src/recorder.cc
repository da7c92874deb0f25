#include "simgate/recorder/recorder.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "simgate/core/base64.h"
#include "simgate/core/log.h"
#include "simgate/core/request_manager.h"
#include "simgate/foxglove/protocol.h"
#include "simgate/recorder/format.h"
#include "simgate/sim/physics_state.h"
#include "simgate/sim/state_hash.h"
#include "simgate/sim/world_services.h"

#ifndef SIMGATE_VERSION
#define SIMGATE_VERSION "unknown"
#endif

namespace simgate::recorder {

namespace {

// A value small enough to record with its outcome: at most `budget` bytes of strings and
// numbers (an image's record is not: its status and message say enough).
bool small_value(const json& value, std::size_t& budget) {
  const auto take = [&budget](std::size_t n) {
    if (n > budget) return false;
    budget -= n;
    return true;
  };
  switch (value.type()) {
    case json::value_t::string: return take(value.get_ref<const std::string&>().size() + 2);
    case json::value_t::array:
      for (const auto& v : value)
        if (!take(1) || !small_value(v, budget)) return false;
      return true;
    case json::value_t::object:
      for (const auto& [k, v] : value.items())
        if (!take(k.size() + 3) || !small_value(v, budget)) return false;
      return true;
    default: return take(8);
  }
}

constexpr std::size_t k_max_recorded_value = 4096;

// The longest the writer keeps records in an open chunk: what a crash (kill -9) can lose.
constexpr std::chrono::seconds k_chunk_interval{1};

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read '" + path + "'");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace

Recorder::Recorder(sim::Simulation& simulation, RecordingOptions options)
    : simulation_(simulation), options_(std::move(options)) {
  mcap::WriterOptions writer_options;
  writer_options.compression = options_.compression;
  writer_ = std::make_unique<mcap::Writer>(options_.path, writer_options);
  first_step_ = simulation_.steps();
  generation_ = simulation_.model_generation();
  write_head(simulation_);
  bytes_written_ = writer_->bytes_written();
  subscribe_streams(simulation_);
  hasher_ = std::make_unique<sim::StateHasher>(simulation_.m());
  block_first_step_ = first_step_ + 1;
  if (scene_channel_ != 0) queue_geometry();
  simulation_.gate()->set_input_tap(this);
  simulation_.set_observer(this);
  attached_ = true;
  thread_ = std::thread([this] { writer_loop(); });
  log::info("recording to ", options_.path);
}

Recorder::~Recorder() {
  try {
    finish();
  } catch (const std::exception& e) {
    log::error("recording ", options_.path, ": ", e.what());
  }
}

void Recorder::write_head(const sim::Simulation& simulation) {
  mcap::Writer& w = *writer_;
  const mjModel* m = simulation.m();
  w.add_metadata(k_metadata_name, {{"simgate_version", SIMGATE_VERSION},
                                   {"mujoco_version", mj_versionString()},
                                   {"timestep", json(m->opt.timestep).dump()},
                                   {"first_step", std::to_string(first_step_)},
                                   {"model_generation", std::to_string(generation_)},
                                   {"hash_block", std::to_string(options_.hash_block)},
                                   {"model_hash", std::to_string(sim::model_hash(m))}});
  const std::uint64_t start = now_ns();
  if (!options_.deployment.is_null())
    w.attach(start, start, k_deployment_attachment, "application/json",
             options_.deployment.dump(2));
  for (const auto& file : options_.attachments) {
    try {
      w.attach(start, start, std::filesystem::path(file).filename().string(),
               file.ends_with(".xml") ? "application/xml" : "application/octet-stream",
               read_file(file));
    } catch (const std::exception& e) {
      log::warning("recording ", options_.path, ": ", file, " not attached: ", e.what());
    }
  }
  inputs_channel_ = w.add_channel(0, k_inputs_topic, "json");
  outcomes_channel_ = w.add_channel(0, k_outcomes_topic, "json");
  hashes_channel_ = w.add_channel(0, k_hashes_topic, "json");
  state_channel_ = w.add_channel(0, k_initial_state_topic, "json");
  // the state the run starts from, all of it (physics_state.h)
  sim::PhysicsState state;
  state.capture(m, simulation.d(), generation_);
  const auto& values = state.values();
  const json initial{
      {"step", first_step_},
      {"sim_time", simulation.sim_time()},
      {"generation", generation_},
      {"signature", "mjSTATE_INTEGRATION"},
      {"values", base64_encode(std::span(reinterpret_cast<const std::uint8_t*>(values.data()),
                                         values.size() * sizeof(mjtNum)))}};
  w.write(state_channel_, 1, start, start, initial.dump());
  w.flush_chunk();  // what a replay needs first is in the file at once
}

void Recorder::subscribe_streams(sim::Simulation& simulation) {
  StreamHub& hub = simulation.streams();
  mcap::Writer& w = *writer_;
  for (const StreamInfo& info : hub.streams(StreamHub::k_every_transport)) {
    if (info.direction != StreamDirection::out) continue;
    Stream stream;
    stream.component = info.component;
    stream.kind = info.kind;
    const std::string topic = foxglove::topic_of(info.component);
    for (const foxglove::SensorChannel& c : foxglove::sensor_channels(info.kind)) {
      const std::uint16_t schema = w.add_schema(foxglove::schema_name(c.message), "jsonschema",
                                                foxglove::sensor_schema(c.message).dump());
      stream.sensor_channels.emplace_back(
          w.add_channel(schema, topic + std::string(c.suffix), "json"), c.message);
    }
    if (stream.sensor_channels.empty()) {
      json schema = json::object();
      if (auto sample = hub.sample_now(info.component)) schema = foxglove::schema_of(*sample);
      schema["title"] = "simgate." + info.kind;
      schema["description"] = info.component + ": " + info.type + " (" + info.kind + ")";
      stream.json_channel = w.add_channel(
          w.add_schema("simgate." + info.kind, "jsonschema", schema.dump()), topic, "json");
      stream.as_json = true;
    }
    if (info.kind == "body_poses" && tf_channel_ == 0) {
      // the bodies and geoms for Foxglove's 3D panel, as the foxglove transport shows them
      stream.body_poses = true;
      tf_channel_ = w.add_channel(w.add_schema(foxglove::k_frame_transforms, "jsonschema",
                                               foxglove::frame_transforms_schema().dump()),
                                  "/tf", "json");
      scene_channel_ = w.add_channel(w.add_schema(foxglove::k_scene_update, "jsonschema",
                                                  foxglove::scene_update_schema().dump()),
                                     "/scene", "json");
    }
    SubscriberOptions subscriber;
    subscriber.capacity = options_.stream_capacity;
    subscriber.label = "recorder (" + options_.path + ")";
    subscriber.wake = [this] {
      {
        std::lock_guard lock(mutex_);
        samples_waiting_ = true;
      }
      cv_.notify_one();
    };
    stream.subscription =
        hub.subscribe(info.component, StreamHub::k_every_transport, std::move(subscriber));
    if (stream.subscription) streams_.push_back(std::move(stream));
  }
}

std::uint64_t Recorder::now_ns() const {
  const double t = simulation_.sim_time();
  return t > 0 ? static_cast<std::uint64_t>(std::llround(t * 1e9)) : 0;
}

std::uint64_t Recorder::step() const { return simulation_.steps(); }

void Recorder::input(json event) {
  event["seq"] = ++input_seq_;
  event["step"] = step();
  event["sim_time"] = simulation_.sim_time();
  Pending p;
  p.channel = inputs_channel_;
  p.sequence = static_cast<std::uint32_t>(input_seq_);
  p.time_ns = now_ns();
  p.bytes = 256;
  p.value = std::move(event);
  enqueue(std::move(p));
}

void Recorder::enqueue(Pending p) {
  {
    std::lock_guard lock(mutex_);
    if (!error_.empty() || finishing_) return;
    if (queue_bytes_ + p.bytes > options_.max_queue_bytes) {
      error_ = "the writer fell " + std::to_string(queue_bytes_ >> 20) +
               " MiB behind (the disk is too slow)";
      log::error("recording ", options_.path, " stopped: ", error_);
    } else {
      if (p.channel == inputs_channel_) ++inputs_;
      queue_bytes_ += p.bytes;
      queue_.push_back(std::move(p));
    }
  }
  cv_.notify_one();
}

void Recorder::request_started(const RequestManager& manager, RequestId id, const Call& call) {
  open_[&manager].insert(id);
  // a call's params: copied here, written by the writer thread
  input({{"type", "request"},
         {"transport", manager.transport_name()},
         {"client", call.client},
         {"id", id},
         {"component", call.component},
         {"service", call.service},
         {"params", call.params}});
}

void Recorder::request_ended(const RequestManager& manager, RequestId id, const Outcome& outcome) {
  auto it = open_.find(&manager);
  if (it == open_.end() || it->second.erase(id) == 0) return;  // not one recorded as started
  json event{{"step", step()},
             {"sim_time", simulation_.sim_time()},
             {"transport", manager.transport_name()},
             {"id", id},
             {"status", to_string(outcome.status)},
             {"failure", to_string(outcome.failure)},
             {"message", outcome.message}};
  std::size_t budget = k_max_recorded_value;
  if (outcome.value && small_value(*outcome.value, budget)) event["value"] = *outcome.value;
  Pending p;
  p.channel = outcomes_channel_;
  p.time_ns = now_ns();
  p.bytes = 256 + k_max_recorded_value - budget;
  p.value = std::move(event);
  enqueue(std::move(p));
}

void Recorder::request_interrupted(const RequestManager& manager, RequestId id, Failure reason) {
  input({{"type", "interrupt"},
         {"transport", manager.transport_name()},
         {"id", id},
         {"reason", reason == Failure::timeout ? "timeout" : "cancelled"}});
}

void Recorder::command_applied(std::string_view component, const json& command,
                               const std::string& refusal) {
  input(
      {{"type", "command"}, {"component", component}, {"command", command}, {"refusal", refusal}});
}

void Recorder::tasks_ran(std::size_t count) { input({{"type", "tasks"}, {"count", count}}); }

void Recorder::stepped() {
  const mjModel* m = simulation_.m();
  if (simulation_.model_generation() != generation_) {
    // a spawn or a delete: the state has other quantities from here on
    flush_hashes();
    generation_ = simulation_.model_generation();
    hasher_ = std::make_unique<sim::StateHasher>(m);
    if (scene_channel_ != 0) queue_geometry();
  }
  if (block_steps_ == 0) block_first_step_ = step();
  const std::size_t n = hasher_->quantities().size();
  hash_block_.resize(hash_block_.size() + n);
  hasher_->hash(m, simulation_.d(), std::span(hash_block_).subspan(hash_block_.size() - n, n));
  steps_recorded_.store(steps_recorded_.load(std::memory_order_relaxed) + 1,
                        std::memory_order_relaxed);
  if (++block_steps_ >= options_.hash_block) flush_hashes();
}

void Recorder::queue_geometry() {
  Pending p;
  p.channel = scene_channel_;
  p.time_ns = now_ns();
  p.value = sim::scene_geometry(simulation_, /*include_meshes=*/true);
  p.bytes = 4096;
  p.geometry = true;
  enqueue(std::move(p));
}

void Recorder::write_geometry(const Pending& p) {
  geometry_ = p.value;
  frames_ = foxglove::SceneFrames::from_geometry(geometry_);
  const std::string update = foxglove::scene_update(geometry_, frames_);
  if (!update.empty()) writer_->write(scene_channel_, 0, p.time_ns, p.time_ns, update);
}

void Recorder::flush_hashes() {
  if (block_steps_ == 0) return;
  Pending p;
  p.channel = hashes_channel_;
  p.time_ns = now_ns();
  p.bytes = hash_block_.size() * 12;
  p.value = json{{"first_step", block_first_step_},
                 {"steps", block_steps_},
                 {"generation", generation_},
                 {"quantities", hasher_->quantities()},
                 {"hashes", hash_block_}};
  hash_block_.clear();
  block_steps_ = 0;
  enqueue(std::move(p));
}

void Recorder::detach() {
  if (!attached_) return;
  attached_ = false;
  flush_hashes();
  if (simulation_.gate()->input_tap() == this) simulation_.gate()->set_input_tap(nullptr);
  simulation_.set_observer(nullptr);
  for (auto& s : streams_) simulation_.streams().unsubscribe(s.subscription);
  {
    std::lock_guard lock(mutex_);
    finishing_ = true;
  }
  cv_.notify_one();
}

json Recorder::finish() {
  if (attached_) {
    std::lock_guard lock(*simulation_.gate());
    detach();
  }
  if (thread_.joinable()) thread_.join();
  if (!finished_) {
    finished_ = true;
    try {
      writer_->close();
    } catch (const std::exception& e) {
      std::lock_guard lock(mutex_);
      if (error_.empty()) {  // else logged when it stopped
        error_ = e.what();
        log::error("recording ", options_.path, ": ", e.what());
      }
    }
    {
      std::lock_guard lock(mutex_);
      bytes_written_ = writer_->bytes_written();
    }
    const json s = status();
    log::info("recording ", options_.path, " closed: ", s["steps"].get<std::uint64_t>(), " steps, ",
              s["inputs"].get<std::uint64_t>(), " inputs, ", s["samples"].get<std::uint64_t>(),
              " samples, ", s["bytes"].get<std::uint64_t>(), " bytes");
  }
  return status();
}

std::string Recorder::error() const {
  std::lock_guard lock(mutex_);
  return error_;
}

json Recorder::status() const {
  std::lock_guard lock(mutex_);
  std::uint64_t dropped = 0;
  for (const auto& s : streams_)
    if (s.subscription) dropped += s.subscription->dropped();
  return {{"path", options_.path},
          {"recording", !finishing_ && error_.empty()},
          {"error", error_.empty() ? json(nullptr) : json(error_)},
          {"steps", steps_recorded_.load(std::memory_order_relaxed)},
          {"inputs", inputs_},
          {"samples", samples_},
          {"samples_dropped", dropped},
          {"bytes", bytes_written_}};
}

void Recorder::write_samples(Stream& stream, std::vector<SamplePtr>& samples) {
  mcap::Writer& w = *writer_;
  for (const SamplePtr& sample : samples) {
    const double t = sample->time();
    const std::uint64_t ns = t > 0 ? static_cast<std::uint64_t>(std::llround(t * 1e9)) : 0;
    ++stream.sequence;
    if (stream.as_json) {
      w.write(stream.json_channel, stream.sequence, ns, ns, sample->text());
      if (stream.body_poses && frames_.known()) {
        const std::string tf = foxglove::frame_transforms(sample->data(), frames_);
        if (!tf.empty()) w.write(tf_channel_, stream.sequence, ns, ns, tf);
      }
    } else {
      for (const auto& [channel, message] : stream.sensor_channels) {
        const std::string text =
            foxglove::sensor_message(message, *sample, stream.component, stream.arc);
        if (!text.empty()) w.write(channel, stream.sequence, ns, ns, text);
      }
    }
  }
  std::lock_guard lock(mutex_);
  samples_ += samples.size();
}

void Recorder::writer_loop() {
  std::deque<Pending> batch;
  std::vector<SamplePtr> samples;
  auto chunk_due = std::chrono::steady_clock::now() + k_chunk_interval;
  std::unique_lock lock(mutex_);
  for (;;) {
    cv_.wait_until(lock, chunk_due,
                   [this] { return !queue_.empty() || samples_waiting_ || finishing_; });
    batch.swap(queue_);
    queue_bytes_ = 0;
    samples_waiting_ = false;
    const bool last = finishing_;
    const bool failed = !error_.empty();
    lock.unlock();
    std::string failure;
    if (!failed) {
      try {
        for (Pending& p : batch) {
          if (p.geometry) {
            write_geometry(p);
            continue;
          }
          if (p.text.empty()) p.text = p.value.dump();
          writer_->write(p.channel, p.sequence, p.time_ns, p.time_ns, p.text);
        }
        for (Stream& s : streams_) {
          samples.clear();
          if (s.subscription && s.subscription->take(samples) > 0) write_samples(s, samples);
        }
        // at least every k_chunk_interval what was written reaches the file: a crash loses
        // no more than that
        if (const auto now = std::chrono::steady_clock::now(); now >= chunk_due) {
          writer_->flush_chunk();
          chunk_due = now + k_chunk_interval;
        }
        if (!writer_->error().empty()) failure = "cannot write: " + writer_->error();
      } catch (const std::exception& e) {
        failure = e.what();
      }
    }
    batch.clear();
    lock.lock();
    bytes_written_ = writer_->bytes_written();
    if (!failure.empty() && error_.empty()) {
      error_ = failure;
      log::error("recording ", options_.path, " stopped: ", failure, " (the simulation goes on)");
    }
    if (last && queue_.empty()) return;
  }
}

}  // namespace simgate::recorder
