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
// How often the writer takes what waits for it (inputs, stream samples): nobody wakes it per
// message (a wake-up per sample cost the simulation thread a twentieth of its time)...
constexpr std::chrono::milliseconds k_writer_period{20};
// ... unless this much input waits.
constexpr std::size_t k_wake_bytes = std::size_t{1} << 20;

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
  prepare_head(simulation_);
  bytes_written_ = writer_->bytes_written();
  find_streams();
  hasher_ = std::make_shared<const sim::StateHasher>(simulation_.m());
  block_first_step_ = first_step_ + 1;
  if (body_poses_found_) queue_geometry();
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

void Recorder::prepare_head(const sim::Simulation& simulation) {
  mcap::Writer& w = *writer_;
  const mjModel* m = simulation.m();
  head_metadata_ = {{"simgate_version", SIMGATE_VERSION},
                    {"mujoco_version", mj_versionString()},
                    {"timestep", json(m->opt.timestep).dump()},
                    {"first_step", std::to_string(first_step_)},
                    {"model_generation", std::to_string(generation_)},
                    {"hash_block", std::to_string(options_.hash_block)},
                    {"model_hash", std::to_string(sim::model_hash(m))}};
  head_time_ = time_ns(simulation.sim_time());
  inputs_channel_ = w.add_channel(0, k_inputs_topic, "json");
  outcomes_channel_ = w.add_channel(0, k_outcomes_topic, "json");
  hashes_channel_ = w.add_channel(0, k_hashes_topic, "json");
  state_channel_ = w.add_channel(0, k_initial_state_topic, "json");
  // the state the run starts from, all of it (physics_state.h)
  sim::PhysicsState state;
  state.capture(m, simulation.d(), generation_);
  const auto& values = state.values();
  initial_state_ =
      json{{"step", first_step_},
           {"sim_time", simulation.sim_time()},
           {"generation", generation_},
           {"signature", "mjSTATE_INTEGRATION"},
           {"values", base64_encode(std::span(reinterpret_cast<const std::uint8_t*>(values.data()),
                                              values.size() * sizeof(mjtNum)))}}
          .dump();
}

void Recorder::write_head() {
  mcap::Writer& w = *writer_;
  w.add_metadata(k_metadata_name, head_metadata_);
  if (!options_.deployment.is_null())
    w.attach(head_time_, head_time_, k_deployment_attachment, "application/json",
             options_.deployment.dump(2));
  for (const auto& file : options_.attachments) {
    try {
      w.attach(head_time_, head_time_, std::filesystem::path(file).filename().string(),
               file.ends_with(".xml") ? "application/xml" : "application/octet-stream",
               read_file(file));
    } catch (const std::exception& e) {
      log::warning("recording ", options_.path, ": ", file, " not attached: ", e.what());
    }
  }
  w.write(state_channel_, 1, head_time_, head_time_, initial_state_);
  w.flush_chunk();  // what a replay needs first is in the file at once
  initial_state_.clear();
}

void Recorder::find_streams() {
  StreamHub& hub = simulation_.streams();
  for (const StreamInfo& info : hub.streams(StreamHub::k_every_transport)) {
    if (info.direction != StreamDirection::out || subscribed_.contains(info.component)) continue;
    Stream stream;
    stream.component = info.component;
    stream.kind = info.kind;
    stream.type = info.type;
    stream.body_poses = info.kind == "body_poses" && !body_poses_found_;
    if (!stream.body_poses && foxglove::sensor_channels(info.kind).empty()) {
      stream.as_json = true;
      stream.sample_schema = json::object();
      if (auto sample = hub.sample_now(info.component))
        stream.sample_schema = foxglove::schema_of(*sample);
    }
    SubscriberOptions subscriber;
    subscriber.capacity = info.pushed ? options_.pushed_stream_capacity : options_.stream_capacity;
    subscriber.label = "recorder (" + options_.path + ")";  // no wake: the writer looks in time
    stream.subscription =
        hub.subscribe(info.component, StreamHub::k_every_transport, std::move(subscriber));
    if (!stream.subscription) continue;
    subscribed_.insert(info.component);
    body_poses_found_ = body_poses_found_ || stream.body_poses;
    if (!thread_.joinable()) {
      add_stream(std::move(stream));
      continue;
    }
    Pending p;
    p.kind = Pending::Kind::stream;
    p.sim_time = simulation_.sim_time();
    p.stream = std::make_unique<Stream>(std::move(stream));
    p.bytes = 1024;
    enqueue(std::move(p));
  }
}

void Recorder::add_stream(Stream stream) {
  mcap::Writer& w = *writer_;
  const std::string topic = foxglove::topic_of(stream.component);
  if (stream.body_poses) {
    // the bodies' poses as Foxglove's 3D panel reads them, as the foxglove transport shows
    // them: /tf for every sample (the poses: nothing else in it), /scene once per model
    tf_channel_ = w.add_channel(w.add_schema(foxglove::k_frame_transforms, "jsonschema",
                                             foxglove::frame_transforms_schema().dump()),
                                "/tf", "json");
    scene_channel_ = w.add_channel(w.add_schema(foxglove::k_scene_update, "jsonschema",
                                                foxglove::scene_update_schema().dump()),
                                   "/scene", "json");
  } else if (stream.as_json) {
    json& schema = stream.sample_schema;
    schema["title"] = "simgate." + stream.kind;
    schema["description"] = stream.component + ": " + stream.type + " (" + stream.kind + ")";
    stream.json_channel = w.add_channel(
        w.add_schema("simgate." + stream.kind, "jsonschema", schema.dump()), topic, "json");
  } else {
    for (const foxglove::SensorChannel& c : foxglove::sensor_channels(stream.kind)) {
      const std::uint16_t schema = w.add_schema(foxglove::schema_name(c.message), "jsonschema",
                                                foxglove::sensor_schema(c.message).dump());
      stream.sensor_channels.emplace_back(
          w.add_channel(schema, topic + std::string(c.suffix), "json"), c.message);
    }
  }
  std::lock_guard lock(mutex_);
  streams_.push_back(std::move(stream));
}

std::uint64_t Recorder::time_ns(double sim_time) {
  return sim_time > 0 ? static_cast<std::uint64_t>(std::llround(sim_time * 1e9)) : 0;
}

std::uint64_t Recorder::step() const { return simulation_.steps(); }

void Recorder::input(Pending p) {
  p.seq = ++input_seq_;
  p.step = step();
  p.sim_time = simulation_.sim_time();
  p.bytes += 128;
  enqueue(std::move(p));
}

void Recorder::enqueue(Pending p) {
  bool wake = false;
  {
    std::lock_guard lock(mutex_);
    if (!error_.empty() || finishing_) return;
    if (queue_bytes_ + p.bytes > options_.max_queue_bytes) {
      error_ = "the writer fell " + std::to_string(queue_bytes_ >> 20) +
               " MiB behind (the disk is too slow)";
      log::error("recording ", options_.path, " stopped: ", error_);
      return;
    }
    if (p.kind <= Pending::Kind::tasks) ++inputs_;
    wake = queue_bytes_ < k_wake_bytes && queue_bytes_ + p.bytes >= k_wake_bytes;
    queue_bytes_ += p.bytes;
    queue_.push_back(std::move(p));
  }
  if (wake) cv_.notify_one();
}

void Recorder::request_started(const RequestManager& manager, RequestId id, const Call& call) {
  open_[&manager].insert(id);
  Pending p;
  p.kind = Pending::Kind::request;
  p.transport = manager.transport_name();
  p.client = call.client;
  p.id = id;
  p.component = call.component;
  p.service = call.service;
  p.value = call.params;  // copied here, written by the writer thread
  input(std::move(p));
}

void Recorder::request_ended(const RequestManager& manager, RequestId id, const Outcome& outcome) {
  auto it = open_.find(&manager);
  if (it == open_.end() || it->second.erase(id) == 0) return;  // not one recorded as started
  Pending p;
  p.kind = Pending::Kind::outcome;
  p.step = step();
  p.sim_time = simulation_.sim_time();
  p.transport = manager.transport_name();
  p.id = id;
  p.status = outcome.status;
  p.failure = outcome.failure;
  p.text = outcome.message;
  std::size_t budget = k_max_recorded_value;
  if (outcome.value && small_value(*outcome.value, budget)) p.value = *outcome.value;
  p.bytes = 128 + k_max_recorded_value - budget + p.text.size();
  enqueue(std::move(p));
}

void Recorder::request_interrupted(const RequestManager& manager, RequestId id, Failure reason) {
  Pending p;
  p.kind = Pending::Kind::interrupt;
  p.transport = manager.transport_name();
  p.id = id;
  p.failure = reason;
  input(std::move(p));
}

void Recorder::command_applied(std::string_view component, const json& command,
                               const std::string& refusal) {
  Pending p;
  p.kind = Pending::Kind::command;
  p.component = component;
  p.value = command;
  p.text = refusal;
  input(std::move(p));
}

void Recorder::tasks_ran(std::size_t count) {
  Pending p;
  p.kind = Pending::Kind::tasks;
  p.count = count;
  input(std::move(p));
}

std::uint16_t Recorder::channel_of(const Pending& p) const {
  switch (p.kind) {
    case Pending::Kind::outcome: return outcomes_channel_;
    case Pending::Kind::hashes: return hashes_channel_;
    case Pending::Kind::geometry: return scene_channel_;
    default: return inputs_channel_;
  }
}

json Recorder::to_json(Pending& p) {
  using Kind = Pending::Kind;
  // an input: what every one has, then its type's own fields
  const auto input = [&p](const char* type,
                          std::initializer_list<std::pair<const char*, json>> fields) {
    json event{{"seq", p.seq}, {"step", p.step}, {"sim_time", p.sim_time}, {"type", type}};
    for (const auto& [key, value] : fields) event[key] = value;
    return event;
  };
  switch (p.kind) {
    case Kind::request:
      return input("request", {{"transport", std::move(p.transport)},
                               {"client", p.client},
                               {"id", p.id},
                               {"component", std::move(p.component)},
                               {"service", std::move(p.service)},
                               {"params", std::move(p.value)}});
    case Kind::interrupt:
      return input("interrupt",
                   {{"transport", std::move(p.transport)},
                    {"id", p.id},
                    {"reason", p.failure == Failure::timeout ? "timeout" : "cancelled"}});
    case Kind::command:
      return input("command", {{"component", std::move(p.component)},
                               {"command", std::move(p.value)},
                               {"refusal", std::move(p.text)}});
    case Kind::tasks: return input("tasks", {{"count", p.count}});
    case Kind::outcome: {
      json o{{"step", p.step},
             {"sim_time", p.sim_time},
             {"transport", std::move(p.transport)},
             {"id", p.id},
             {"status", to_string(p.status)},
             {"failure", to_string(p.failure)},
             {"message", std::move(p.text)}};
      if (!p.value.is_null()) o["value"] = std::move(p.value);
      return o;
    }
    case Kind::hashes: {
      const std::size_t size = p.hasher->state_size(), n = p.hasher->quantities().size();
      std::vector<std::uint32_t> hashes(p.count * n);
      for (std::size_t i = 0; i < p.count; ++i)
        p.hasher->hash_state(std::span<const mjtNum>(p.states).subspan(i * size, size),
                             std::span(hashes).subspan(i * n, n));
      return {{"first_step", p.step},
              {"steps", p.count},
              {"sim_time", p.sim_time},
              {"generation", p.generation},
              {"quantities", p.hasher->quantities()},
              {"hashes", std::move(hashes)}};
    }
    case Kind::geometry:
    case Kind::stream: break;  // not messages of their own (write_geometry, add_stream)
  }
  return nullptr;
}

void Recorder::stepped() {
  const mjModel* m = simulation_.m();
  if (simulation_.model_generation() != generation_) {
    // a spawn or a delete: the state has other quantities from here on
    flush_hashes();
    generation_ = simulation_.model_generation();
    hasher_ = std::make_shared<const sim::StateHasher>(m);
    find_streams();  // a spawned robot's
    if (body_poses_found_) queue_geometry();
  }
  if (block_steps_ == 0) block_first_step_ = step();
  const std::size_t n = hasher_->state_size();
  state_block_.resize(state_block_.size() + n);
  mj_getState(m, simulation_.d(), state_block_.data() + state_block_.size() - n,
              mjSTATE_INTEGRATION);
  steps_recorded_.store(steps_recorded_.load(std::memory_order_relaxed) + 1,
                        std::memory_order_relaxed);
  if (++block_steps_ >= options_.hash_block) flush_hashes();
}

void Recorder::queue_geometry() {
  Pending p;
  p.kind = Pending::Kind::geometry;
  p.sim_time = simulation_.sim_time();
  p.value = sim::scene_geometry(simulation_, /*include_meshes=*/true);
  p.bytes = 4096;
  enqueue(std::move(p));
}

void Recorder::write_geometry(Pending& p) {
  geometry_ = std::move(p.value);
  frames_ = foxglove::SceneFrames::from_geometry(geometry_);
  const std::string update = foxglove::scene_update(geometry_, frames_);
  if (!update.empty())
    writer_->write(scene_channel_, 0, time_ns(p.sim_time), time_ns(p.sim_time), update);
}

void Recorder::flush_hashes() {
  if (block_steps_ == 0) return;
  Pending p;
  p.kind = Pending::Kind::hashes;
  p.step = block_first_step_;
  p.count = block_steps_;
  p.sim_time = simulation_.sim_time();
  p.generation = generation_;
  p.hasher = hasher_;
  p.bytes = state_block_.size() * sizeof(mjtNum);
  p.states.swap(state_block_);
  {
    // a block the writer has hashed, its capacity kept: no allocation per block here
    std::lock_guard lock(mutex_);
    if (!spare_states_.empty()) {
      state_block_ = std::move(spare_states_.back());
      spare_states_.pop_back();
    }
  }
  state_block_.reserve(p.states.size());
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
    const std::uint64_t ns = time_ns(sample->time());
    ++stream.sequence;
    if (stream.body_poses) {
      if (frames_.known()) {
        const std::string tf = foxglove::frame_transforms(sample->data(), frames_);
        if (!tf.empty()) w.write(tf_channel_, stream.sequence, ns, ns, tf);
      }
    } else if (stream.as_json) {
      w.write(stream.json_channel, stream.sequence, ns, ns, sample->text());
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
  std::vector<std::vector<mjtNum>> spare;  // hashed blocks, for spare_states_
  std::vector<SamplePtr> samples;
  auto chunk_due = std::chrono::steady_clock::now() + k_chunk_interval;
  std::string failure;
  try {
    write_head();  // the files read and written here, not under the simulation lock
  } catch (const std::exception& e) {
    failure = e.what();
  }
  std::unique_lock lock(mutex_);
  if (!failure.empty()) {
    error_ = failure;
    log::error("recording ", options_.path, " stopped: ", failure, " (the simulation goes on)");
  }
  for (;;) {
    // no wake-up per sample or input: the writer looks every k_writer_period (sooner when
    // the inputs pile up, or at the end)
    cv_.wait_until(lock, std::min(chunk_due, std::chrono::steady_clock::now() + k_writer_period),
                   [this] { return queue_bytes_ >= k_wake_bytes || finishing_; });
    batch.swap(queue_);
    queue_bytes_ = 0;
    const bool last = finishing_;
    const bool failed = !error_.empty();
    lock.unlock();
    failure.clear();
    if (!failed) {
      try {
        for (Pending& p : batch) {
          if (p.kind == Pending::Kind::geometry) {
            write_geometry(p);
            continue;
          }
          if (p.kind == Pending::Kind::stream) {
            add_stream(std::move(*p.stream));
            continue;
          }
          const std::uint64_t ns = time_ns(p.sim_time);
          writer_->write(channel_of(p), static_cast<std::uint32_t>(p.seq), ns, ns,
                         to_json(p).dump());
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
    // the hashed blocks go back to the simulation thread for its next ones
    for (Pending& p : batch)
      if (p.kind == Pending::Kind::hashes && p.states.capacity() > 0) {
        p.states.clear();
        spare.push_back(std::move(p.states));
      }
    batch.clear();
    lock.lock();
    while (!spare.empty() && spare_states_.size() < k_spare_state_blocks) {
      spare_states_.push_back(std::move(spare.back()));
      spare.pop_back();
    }
    spare.clear();
    bytes_written_ = writer_->bytes_written();
    if (!failure.empty() && error_.empty()) {
      error_ = failure;
      log::error("recording ", options_.path, " stopped: ", failure, " (the simulation goes on)");
    }
    if (last && queue_.empty()) return;
  }
}

}  // namespace simgate::recorder
