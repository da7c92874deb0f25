#include "simgate/recorder/replay.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <map>
#include <set>
#include <stdexcept>
#include <thread>
#include <utility>

#include "simgate/core/base64.h"
#include "simgate/core/errors.h"
#include "simgate/core/log.h"
#include "simgate/core/request_manager.h"
#include "simgate/mcap/reader.h"
#include "simgate/recorder/format.h"
#include "simgate/sim/physics_state.h"
#include "simgate/sim/state_hash.h"
#include "simgate/sim/world_services.h"

namespace simgate::recorder {

namespace {

// The longest a replay waits for off-lock work the recording says was taken in (a spawned
// entity's model compiling on a worker thread).
constexpr std::chrono::seconds k_task_wait{60};
// A seek served: the clients' requests between every this many steps taken to get there, a
// progress report every this many steps.
constexpr std::uint64_t k_seek_serve_steps = 256;
constexpr std::uint64_t k_seek_progress_steps = 2000;

// A seek's answer when it is not reached: `status` (PREEMPTED, FAILED) for `failure`.
Outcome seek_ended(Status status, Failure failure, std::string message) {
  Outcome o = Outcome::failed(failure, "simulation seek: " + std::move(message));
  o.status = status;
  return o;
}

json parse_message(const mcap::Message& m, const std::string& path, const char* topic) {
  try {
    return json::parse(m.data);
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": a " + topic + " message is not JSON: " + e.what());
  }
}

// Serves every component for the replay and keeps each request's outcome.
class ReplayManager final : public RequestManager {
 public:
  ReplayManager() : RequestManager("Replay service manager") {}
  void arrive(std::uint64_t client) { client_arrived(client); }
  std::map<RequestId, Status> statuses;  // each request's outcome, by its id here

  // Saved states' handles: a served replay that went back saves the recording's states
  // again under other handles (the simulation's count goes on), so the recording's handles
  // are told apart from the replay's. `id` is a simulation save_state of `client` whose
  // recorded answer was `recorded`.
  void expect_handle(RequestId id, std::int64_t recorded, std::uint64_t client) {
    saves_[id] = {recorded, client};
  }
  // simulation restore_state's and drop_state's `params` ({"handle": h} or [h]) with the
  // replay's handle for the recording's.
  void map_handle(json& params) const {
    json* h = params.is_object()  ? (params.contains("handle") ? &params["handle"] : nullptr)
              : params.is_array() ? (params.empty() ? nullptr : &params[0])
                                  : nullptr;
    if (!h || !h->is_number_integer()) return;
    if (auto it = handles_.find(h->get<std::int64_t>()); it != handles_.end())
      *h = it->second.first;
  }
  // Drops every state the replay saved (going back to the recording's start, where none was).
  void drop_saved() {
    std::vector<std::pair<RequestId, Call>> drops;
    for (const auto& [recorded, saved] : handles_) {
      Call call{"simulation", "drop_state", json{{"handle", saved.first}}};
      call.client = saved.second;
      drops.emplace_back(new_request_id(), std::move(call));
    }
    handles_.clear();
    run_or_submit(std::move(drops));
    process();
  }

 protected:
  void on_service_completion(RequestId id, Outcome&& outcome) override {
    statuses[id] = outcome.status;
    if (auto it = saves_.find(id); it != saves_.end()) {
      if (outcome.status == Status::success && outcome.value && outcome.value->is_number_integer())
        handles_[it->second.first] = {outcome.value->get<std::int64_t>(), it->second.second};
      saves_.erase(it);
    }
  }

 private:
  // save_state calls under way: (the recording's handle, the client)
  std::map<RequestId, std::pair<std::int64_t, std::uint64_t>> saves_;
  // the recording's handle -> (the replay's, the client that saved it)
  std::map<std::int64_t, std::pair<std::int64_t, std::uint64_t>> handles_;
};

}  // namespace

Recording Recording::read(const std::string& path) {
  Recording r;
  r.path = path;
  mcap::Reader reader(path);
  mcap::Item item;
  bool has_state = false, has_metadata = false;
  while (reader.next(item)) {
    if (auto* meta = std::get_if<mcap::MetadataRecord>(&item)) {
      if (meta->name == k_metadata_name) {
        r.metadata = meta->metadata;
        has_metadata = true;
      }
    } else if (auto* a = std::get_if<mcap::Attachment>(&item)) {
      if (a->name == k_deployment_attachment) {
        try {
          r.deployment = json::parse(a->data);
        } catch (const std::exception& e) {
          throw std::runtime_error(path + ": its deployment attachment is not JSON: " + e.what());
        }
      }
    } else if (auto* m = std::get_if<mcap::Message>(&item)) {
      const mcap::Channel* channel = reader.channel(m->channel_id);
      if (!channel) continue;
      const std::string& topic = channel->topic;
      if (topic == k_inputs_topic) {
        r.inputs.push_back(parse_message(*m, path, k_inputs_topic));
      } else if (topic == k_outcomes_topic) {
        r.outcomes.push_back(parse_message(*m, path, k_outcomes_topic));
      } else if (topic == k_hashes_topic) {
        const json block = parse_message(*m, path, k_hashes_topic);
        HashBlock b;
        b.first_step = block.at("first_step").get<std::uint64_t>();
        b.steps = block.at("steps").get<std::uint64_t>();
        b.quantities = block.at("quantities").get<std::vector<std::string>>();
        b.hashes = block.at("hashes").get<std::vector<std::uint32_t>>();
        if (block.contains("sim_time")) b.sim_time = block["sim_time"].get<double>();
        if (b.hashes.size() != b.steps * b.quantities.size())
          throw std::runtime_error(path + ": a state_hashes block holds " +
                                   std::to_string(b.hashes.size()) + " hashes for " +
                                   std::to_string(b.steps) + " steps of " +
                                   std::to_string(b.quantities.size()) + " quantities");
        r.last_step = std::max(r.last_step, b.first_step + b.steps - 1);
        r.hashes.push_back(std::move(b));
      } else if (topic == k_initial_state_topic) {
        const json state = parse_message(*m, path, k_initial_state_topic);
        r.first_step = state.at("step").get<std::uint64_t>();
        r.generation = state.at("generation").get<std::uint64_t>();
        r.initial_time = state.at("sim_time").get<double>();
        const std::vector<std::uint8_t> bytes =
            base64_decode(state.at("values").get<std::string>());
        if (bytes.size() % sizeof(mjtNum) != 0)
          throw std::runtime_error(path + ": its initial state is not a whole number of values");
        r.initial_state.resize(bytes.size() / sizeof(mjtNum));
        std::memcpy(r.initial_state.data(), bytes.data(), bytes.size());
        has_state = true;
      }
    }
  }
  r.complete = reader.complete();
  r.truncation = reader.truncation();
  if (!has_metadata || !has_state)
    throw std::runtime_error(path + ": an MCAP file, but not a simgate recording (no '" +
                             std::string(k_metadata_name) + "' metadata or no " +
                             k_initial_state_topic + " message)");
  if (r.last_step < r.first_step) r.last_step = r.first_step;
  return r;
}

std::uint64_t Recording::step_at(double t, double timestep) const {
  // each block's steps are timestep apart up to its end time (a jump within a block is
  // off by less than the block)
  for (const HashBlock& b : hashes) {
    if (!b.sim_time) break;
    const double first = *b.sim_time - static_cast<double>(b.steps - 1) * timestep;
    if (t > *b.sim_time + timestep / 2) continue;
    // (before the block's first step: the step before it, at most back to the recording's start)
    const auto k = static_cast<std::int64_t>(std::round((t - first) / timestep));
    const std::int64_t step =
        static_cast<std::int64_t>(b.first_step) + std::max<std::int64_t>(k, -1);
    return std::clamp(static_cast<std::uint64_t>(std::max<std::int64_t>(step, 0)), first_step,
                      b.first_step + b.steps - 1);
  }
  if (!hashes.empty() && hashes.back().sim_time) return last_step;  // past the end
  const double steps = std::round((t - initial_time) / timestep);
  const std::uint64_t step =
      steps <= 0 ? first_step : first_step + static_cast<std::uint64_t>(steps);
  return std::clamp(step, first_step, last_step);
}

double Recording::end_time(double timestep) const {
  if (!hashes.empty() && hashes.back().sim_time) return *hashes.back().sim_time;
  return initial_time + static_cast<double>(last_step - first_step) * timestep;
}

json ReplayReport::to_json() const {
  json m = nullptr;
  if (mismatch)
    m = {{"step", mismatch->step},
         {"sim_time", mismatch->sim_time},
         {"quantities", mismatch->quantities},
         {"inputs", mismatch->inputs}};
  return {{"steps", steps},
          {"inputs_applied", inputs_applied},
          {"inputs_skipped", inputs_skipped},
          {"steps_compared", steps_compared},
          {"outcomes_differing", outcomes_differing},
          {"mismatch", m},
          {"wall_seconds", wall_seconds}};
}

Replayer::Replayer(sim::Simulation& simulation, const Recording& recording)
    : simulation_(simulation), recording_(recording) {
  const auto said = [&](const char* key) {
    auto it = recording.metadata.find(key);
    return it == recording.metadata.end() ? std::string("unknown") : it->second;
  };
  const std::string mujoco = mj_versionString();
  if (said("mujoco_version") != mujoco)
    throw std::runtime_error(recording.path + ": recorded with MuJoCo " + said("mujoco_version") +
                             ", this simgate runs MuJoCo " + mujoco +
                             ": a replay would not be the same run");
  if (recording.generation != 0)
    throw std::runtime_error(recording.path +
                             ": the recording began after the model changed (a spawn or a delete: "
                             "model generation " +
                             std::to_string(recording.generation) +
                             "); a replay builds the model the configuration describes");
  const mjModel* m = simulation.m();
  const auto size = static_cast<std::size_t>(mj_stateSize(m, mjSTATE_INTEGRATION));
  if (size != recording.initial_state.size())
    throw std::runtime_error(recording.path + ": the model is not the recording's: its state has " +
                             std::to_string(size) + " numbers, the recording's " +
                             std::to_string(recording.initial_state.size()) +
                             " (the scene's files changed since?)");
  if (const auto it = recording.metadata.find("model_hash");
      it != recording.metadata.end() && it->second != std::to_string(sim::model_hash(m)))
    throw std::runtime_error(recording.path +
                             ": the model is not the recording's: it compiles to another model "
                             "(the scene's files changed since the recording)");
}

void Replayer::add_services(sim::SupervisionServices& simulation) {
  simulation
      .offer_async_service("seek",
                           [this](Completion done, double sim_time, std::int64_t step) {
                             seek(sim_time, step, std::move(done));
                           },
                           {{"sim_time", -1.0}, {"step", -1}})
      .concurrent()
      .not_replayed()
      .doc(
          "A served replay only: go to the recorded run's state at simulated time sim_time (or "
          "at its step count `step`), replaying from its start if it is behind; answers {step, "
          "sim_time} once there, progress {step, target} on the way");
  simulation.offer_service("get_replay_status", [this] { return status(); })
      .not_replayed()
      .doc(
          "A served replay: {file, step, first_step, last_step, sim_time, start_time, end_time, "
          "seeking, departed_at}");
}

void Replayer::seek(double sim_time, std::int64_t step, Completion done) {
  const Recording& rec = recording_;
  if ((sim_time < 0) == (step < 0))
    throw ServiceError(
        "simulation seek: give sim_time (seconds) or step (the recorded run's step "
        "count), one of them",
        Failure::bad_arguments);
  const std::uint64_t target =
      step >= 0 ? std::clamp(static_cast<std::uint64_t>(step), rec.first_step, rec.last_step)
                : rec.step_at(sim_time, simulation_.timestep());
  if (target < step_now() && simulation_.model_generation() != 0)
    throw ServiceError(
        "simulation seek: the model changed since the recording's start (a spawn or a delete): "
        "a served replay seeks forward only from here",
        Failure::service_error, {{"step", step_now()}});
  if (seek_)
    seek_->done.finish(seek_ended(Status::preempted, Failure::preempted,
                                  "another seek came before it was reached"));
  seek_ = Seek{target, std::move(done)};
  reached(step_now());
  simulation_.gate()->signal();  // the replay may be waiting for its next step's time
}

void Replayer::reached(std::uint64_t step) {
  if (!seek_) return;
  if (seek_->step != step) {
    if (step % k_seek_progress_steps == 0)
      seek_->done.progress(json{{"step", step}, {"target", seek_->step}});
    return;
  }
  seek_->done(Status::success, json{{"step", step}, {"sim_time", simulation_.sim_time()}});
  seek_.reset();
  restart_pace_ = true;  // the pace starts anew from here (serve_until_due)
}

Replayer::SeekAction Replayer::seek_action() {
  std::lock_guard lock(*simulation_.gate());
  if (!seek_) return SeekAction::none;
  return seek_->step < step_now() ? SeekAction::back : SeekAction::forward;
}

json Replayer::status() const {
  const Recording& rec = recording_;
  return {{"file", rec.path},
          {"step", step_now()},
          {"first_step", rec.first_step},
          {"last_step", rec.last_step},
          {"sim_time", simulation_.sim_time()},
          {"start_time", rec.initial_time},
          {"end_time", rec.end_time(simulation_.timestep())},
          {"seeking", seek_ ? json(seek_->step) : json(nullptr)},
          {"departed_at", departed_ ? json(*departed_) : json(nullptr)}};
}

void Replayer::serve_until_due(const ReplayOptions& options) {
  sim::Simulation& sim = simulation_;
  for (;;) {
    sim.process_requests();
    if (stopping(options)) return;
    // what the clients may change is read under the lock (their requests run on their threads)
    bool paused = false, stepped = false;
    double time = 0, timestep = 0, factor = 0;
    {
      std::lock_guard lock(*sim.gate());
      if (seek_) return;  // a seek takes the next steps as fast as it can
      if (std::exchange(restart_pace_, false)) pace_wall_ = {};
      paused = sim.paused();
      // a client paused it: its requests are served; a `simulation step` of its own steps
      if (paused && sim.owed_steps() > 0)
        stepped = sim.take_owed_steps(std::chrono::steady_clock::now() +
                                      std::chrono::milliseconds(2)) > 0;
      time = sim.sim_time();
      timestep = sim.timestep();
      factor = sim.realtime_factor();  // the deployment's, or a client's time set_time_scale
    }
    if (paused) {
      if (!stepped) sim.gate()->wait_for(std::chrono::milliseconds(100));
      pace_wall_ = {};  // playing again: the pace starts anew
      continue;
    }
    if (factor <= 0) return;  // as fast as possible
    const auto now = std::chrono::steady_clock::now();
    if (pace_wall_ == std::chrono::steady_clock::time_point{} || factor != pace_factor_) {
      pace_wall_ = now;
      pace_sim_ = time;
      pace_factor_ = factor;
    }
    const auto due =
        pace_wall_ + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                         std::chrono::duration<double>((time + timestep - pace_sim_) / factor));
    if (now >= due) return;
    sim.gate()->wait_until(due);
  }
}

bool Replayer::serve_to_the_end(const ReplayOptions& options) {
  sim::Simulation& sim = simulation_;
  double time = 0;
  {
    std::lock_guard lock(*sim.gate());
    sim.set_paused(true);
    time = sim.sim_time();
  }
  log::info("replay: the recording ends at sim time ", time,
            " s; its last state is served, paused, until Ctrl-C (or a seek back)");
  while (!stopping(options)) {
    serve_until_due(options);
    if (seek_action() == SeekAction::back) return true;
  }
  return false;
}

ReplayReport Replayer::run(const ReplayOptions& options) {
  const bool stop_at_mismatch = options.stop_at_mismatch && !options.serve;
  const auto wall_start = std::chrono::steady_clock::now();
  ReplayReport report;
  sim::Simulation& sim = simulation_;
  const Recording& rec = recording_;

  auto manager = std::make_shared<ReplayManager>();
  for (const auto& entry : sim.components()) manager->register_component(*entry->component);
  sim.add_request_manager(manager, "replay");
  {
    std::lock_guard lock(*sim.gate());
    sim.restore_physics(sim::PhysicsState::from_values(rec.initial_state, sim.model_generation()));
    steps_base_ = sim.steps();
    // served, the recording sets the pace (a deployment that starts paused for its clients to
    // step it was stepped so in the recording); a client's pause holds it from here on
    if (options.serve) sim.set_paused(false);
  }
  // the recorded fingerprints, by step
  sim::StateHasher hasher(sim.m());
  std::vector<std::uint32_t> now;
  std::size_t block = 0;
  std::vector<json> inputs_since_step;
  const auto compare = [&](std::uint64_t step) -> bool {
    while (block < rec.hashes.size() &&
           rec.hashes[block].first_step + rec.hashes[block].steps <= step)
      ++block;
    if (block >= rec.hashes.size() || rec.hashes[block].first_step > step) return true;
    const auto& b = rec.hashes[block];
    if (!hasher.fits(sim.m())) hasher = sim::StateHasher(sim.m());
    if (hasher.quantities() != b.quantities) return true;  // another model: nothing to compare
    now.resize(b.quantities.size());
    hasher.hash(sim.m(), sim.d(), now);
    ++report.steps_compared;
    const std::size_t at = (step - b.first_step) * b.quantities.size();
    StepMismatch mismatch;
    for (std::size_t q = 0; q < b.quantities.size(); ++q)
      if (now[q] != b.hashes[at + q]) mismatch.quantities.push_back(b.quantities[q]);
    if (mismatch.quantities.empty()) return true;
    if (!report.mismatch) {
      mismatch.step = step;
      mismatch.sim_time = sim.sim_time();
      mismatch.inputs = inputs_since_step;
      report.mismatch = std::move(mismatch);
    }
    return false;
  };
  // steps until the recorded run's step count is `target`
  const auto step_to = [&](std::uint64_t target) -> Progress {
    std::uint64_t forward = 0;  // steps taken as fast as possible for a seek
    while (step_now() < target) {
      if (options.serve) {
        SeekAction seeking = seek_action();
        if (seeking == SeekAction::none) {
          serve_until_due(options);
          seeking = seek_action();
        } else if (++forward % k_seek_serve_steps == 0) {
          sim.process_requests();  // seeking: no pace, no pause, but the clients are served
        }
        if (stopping(options)) return Progress::stopped;
        if (seeking == SeekAction::back) return Progress::rewind;
      }
      const bool had_mismatch = report.mismatch.has_value();
      bool same = true;
      {
        // served, the clients' requests run on their threads between two steps
        std::lock_guard lock(*sim.gate());
        sim.step();
        const std::uint64_t step = step_now();
        same = compare(step);
        if (options.serve) {
          if (!same && !had_mismatch) departed_ = step;
          reached(step);
        }
      }
      ++report.steps;
      inputs_since_step.clear();
      if (!same && stop_at_mismatch) return Progress::stopped;
      if (!same && options.serve && !had_mismatch)
        log::warning("replay: from step ", report.mismatch->step,
                     " the served run departs from the recording (a client's request changed "
                     "the world?)");
    }
    return Progress::reached;
  };

  // the services a replay does not call (unknown ones are: their refusal is the same)
  std::set<std::pair<std::string, std::string>> not_replayed;
  for (const ServiceDescriptor& d : manager->descriptors())
    if (!d.replayed) not_replayed.emplace(d.component, d.name);
  // (transport, id) of the recording -> the replay's request id, and its recorded outcome;
  // (transport, client) -> client
  std::map<std::pair<std::string, RequestId>, RequestId> ids;
  std::map<std::pair<std::string, RequestId>, const json*> recorded_outcomes;
  for (const json& o : rec.outcomes)
    recorded_outcomes[{o.value("transport", ""), o.value("id", RequestId{0})}] = &o;
  std::map<std::pair<std::string, std::uint64_t>, std::uint64_t> clients;

  const auto apply = [&](const json& in) {
    const std::string type = in.value("type", "");
    if (type == "request") {
      Call call;
      call.component = in.value("component", "");
      call.service = in.value("service", "");
      call.params = in.contains("params") ? in["params"] : json(nullptr);
      const std::string transport = in.value("transport", "");
      if (const std::uint64_t client = in.value("client", std::uint64_t{0}); client != 0) {
        auto [it, added] = clients.try_emplace({transport, client}, clients.size() + 1);
        if (added) manager->arrive(it->second);
        call.client = it->second;
      }
      if (not_replayed.contains({call.component, call.service})) {
        ++report.inputs_skipped;  // acts on the loop: its steps are in the recording as steps
        return;
      }
      const RequestId id = manager->new_request_id();
      const RequestId recorded = in.value("id", RequestId{0});
      ids[{transport, recorded}] = id;
      if (call.component == "simulation") {
        if (call.service == "save_state") {
          const auto o = recorded_outcomes.find({transport, recorded});
          if (o != recorded_outcomes.end() && o->second->contains("value") &&
              (*o->second)["value"].is_number_integer())
            manager->expect_handle(id, (*o->second)["value"].get<std::int64_t>(), call.client);
        } else if (call.service == "restore_state" || call.service == "drop_state") {
          manager->map_handle(call.params);
        }
      }
      inputs_since_step.push_back(in);
      manager->run_or_submit(id, std::move(call));
      ++report.inputs_applied;
    } else if (type == "interrupt") {
      auto it = ids.find({in.value("transport", ""), in.value("id", RequestId{0})});
      if (it == ids.end()) return;  // a request the recording did not start
      inputs_since_step.push_back(in);
      manager->cancel(it->second);
      manager->process();
      ++report.inputs_applied;
    } else if (type == "command") {
      inputs_since_step.push_back(in);
      sim.streams().publish(in.value("component", ""), StreamHub::k_every_transport,
                            in.contains("command") ? in["command"] : json::object());
      ++report.inputs_applied;
    } else if (type == "tasks") {
      const std::size_t count = in.value("count", std::size_t{0});
      if (options.serve) return;  // served: process_requests takes them in when they come
      const auto until = std::chrono::steady_clock::now() + k_task_wait;
      while (sim.soon_count() < count && std::chrono::steady_clock::now() < until)
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      if (sim.soon_count() < count)
        throw std::runtime_error(rec.path + ": the off-lock work the recording took in at step " +
                                 std::to_string(in.value("step", 0)) + " did not come within " +
                                 std::to_string(k_task_wait.count()) + " s");
      inputs_since_step.push_back(in);
      sim.process_requests();
      ++report.inputs_applied;
    }
  };
  // served, a seek back: the first state put back the way `simulation restore_state` puts a
  // state back (robots' requests ended, components reset, clients told), the replay taken
  // again from the recording's start
  const auto rewind = [&] {
    manager->drop_saved();
    std::lock_guard lock(*sim.gate());
    jump_back(sim, "simulation seek: the replay went back to the recording's start",
              [&] {
                sim.restore_physics(
                    sim::PhysicsState::from_values(rec.initial_state, sim.model_generation()));
                return sim.sim_time();
              },
              {{"seek", seek_ ? json(seek_->step) : json(nullptr)}});
    steps_base_ = sim.steps();
    ids.clear();
    manager->statuses.clear();
    block = 0;
    inputs_since_step.clear();
    report.mismatch.reset();
    departed_.reset();
    reached(step_now());
  };

  std::size_t next = 0;  // the next recorded input
  for (;;) {
    const bool more = next < rec.inputs.size();
    const Progress progress =
        step_to(more ? rec.inputs[next].at("step").get<std::uint64_t>() : rec.last_step);
    if (progress == Progress::stopped) break;
    if (progress == Progress::rewind) {
      rewind();
      next = 0;
      continue;
    }
    if (more) {
      apply(rec.inputs[next++]);
      continue;
    }
    manager->process();  // outcomes finished by the last steps
    if (!options.serve || stopping(options) || !serve_to_the_end(options)) break;
    rewind();
    next = 0;
  }
  // each recorded outcome against the replay's of the same request
  for (const json& o : rec.outcomes) {
    const auto id = ids.find({o.value("transport", ""), o.value("id", RequestId{0})});
    if (id == ids.end()) continue;
    const auto status = manager->statuses.find(id->second);
    if (status != manager->statuses.end() && o.value("status", "") != to_string(status->second))
      ++report.outcomes_differing;
  }
  if (options.serve) {
    std::lock_guard lock(*sim.gate());
    if (seek_)
      seek_->done.finish(seek_ended(Status::failed, Failure::shutdown, "the replay ended"));
    seek_.reset();
  }
  manager->abandon_pending("the replay ended");
  report.wall_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  return report;
}

}  // namespace simgate::recorder
