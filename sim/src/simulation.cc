#include "simgate/sim/simulation.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>

#include "simgate/core/call_context.h"
#include "simgate/core/log.h"
#include "simgate/sim/model_edit.h"
#include "simgate/sim/sim_component.h"
#include "simgate/sim/events.h"

#include "helpers.h"

namespace simgate::sim {

namespace {
using Clock = std::chrono::steady_clock;
}  // namespace

const char* to_string(RunState state) {
  switch (state) {
    case RunState::playing: return "playing";
    case RunState::paused: return "paused";
    case RunState::stepping: return "stepping";
    case RunState::quitting: return "quitting";
  }
  return "unknown";
}

Simulation::Simulation(Model model, SimulationOptions options)
    : model_(std::move(model)),
      gate_(std::make_shared<SimulationGate>()),
      streams_(std::make_shared<StreamHub>(gate_)),
      on_divergence_(options.on_divergence),
      spawn_allowed_dirs_(std::move(options.spawn_allowed_dirs)) {
  if (options.timestep) {
    if (!(*options.timestep > 0) || !std::isfinite(*options.timestep))
      throw std::invalid_argument("simulation: timestep must be a positive number, not " +
                                  std::to_string(*options.timestep));
    m()->opt.timestep = *options.timestep;
  }
  set_realtime_factor(options.realtime_factor);
  paused_ = options.start_paused;
  // Model's constructor ran mj_forward on the initial state
  state_time_ = d()->time;
}

Simulation::~Simulation() {
  try {
    shutdown();
  } catch (const std::exception& e) {
    log::error("simulation: shutdown failed: ", e.what());
  }
}

void Simulation::set_realtime_factor(double factor) {
  if (!(factor >= 0) || !std::isfinite(factor) || (factor > 0 && factor < k_min_realtime_factor))
    throw std::invalid_argument(
        "simulation: realtime_factor must be 0 (as fast as possible) or at least " +
        number(k_min_realtime_factor) + ", not " + number(factor));
  realtime_factor_ = factor;
  // the loop may be asleep until a step scheduled at the old pace
  reschedule_ = true;
  gate_->signal();
}

ComponentEntry& Simulation::add_component(std::unique_ptr<Component> component, std::string type,
                                          std::string robot, bool is_robot) {
  if (!component) throw std::invalid_argument("simulation: add_component(nullptr)");
  if (find(component->name()))
    throw std::invalid_argument("simulation: a component named '" + component->name() +
                                "' already exists");
  auto entry = std::make_unique<ComponentEntry>();
  entry->sim_component = dynamic_cast<SimComponent*>(component.get());
  entry->component = std::move(component);
  entry->type = std::move(type);
  entry->robot = std::move(robot);
  entry->is_robot = is_robot;
  entries_.push_back(std::move(entry));
  return *entries_.back();
}

bool Simulation::remove_component(const std::string& name, const std::string& reason) {
  auto it = std::find_if(entries_.begin(), entries_.end(),
                         [&](const auto& e) { return e->component->name() == name; });
  if (it == entries_.end()) return false;
  for (const auto& manager : managers_) manager->unregister_component(name, reason);
  streams_->remove(name);
  // what still runs on the component without a manager knowing (none in practice)
  AsyncSlot& slot = *(*it)->component->async_slot();
  const Outcome failed = Outcome::failed(Failure::service_error, reason);
  if (slot.busy()) slot.running_completion.finish(failed);
  for (const Completion& call : slot.running_concurrent()) call.finish(failed);
  slot.interrupt = nullptr;  // it calls the component, which goes now
  log::info("simulation: component '", name, "' removed: ", reason);
  if ((*it)->component.get() == events_) events_ = nullptr;
  entries_.erase(it);
  return true;
}

ComponentEntry* Simulation::find(const std::string& name) {
  for (auto& e : entries_)
    if (e->component->name() == name) return e.get();
  return nullptr;
}

std::vector<std::string> Simulation::robot_names() const {
  std::vector<std::string> names;
  for (const auto& e : entries_)
    if (e->is_robot) names.push_back(e->component->name());
  return names;
}

void Simulation::add_request_manager(std::shared_ptr<RequestManager> manager,
                                     std::string transport) {
  manager->set_gate(gate_);
  manager->set_streams(streams_, transport);
  managers_.push_back(std::move(manager));
  manager_names_.push_back(std::move(transport));
}

const RequestManager* Simulation::request_manager(const std::string& transport) const {
  for (std::size_t i = 0; i < managers_.size(); ++i)
    if (manager_names_[i] == transport) return managers_[i].get();
  return nullptr;
}

void Simulation::run_soon(std::function<void()> task) {
  {
    std::lock_guard lock(soon_mutex_);
    soon_.push_back(std::move(task));
  }
  gate_->signal();
}

std::size_t Simulation::process_requests() {
  std::vector<std::function<void()>> tasks;
  {
    std::lock_guard lock(soon_mutex_);
    tasks.swap(soon_);
  }
  if (!tasks.empty()) {
    std::lock_guard lock(*gate_);
    if (observer_) [[unlikely]]
      observer_->tasks_ran(tasks.size());
    for (auto& task : tasks) task();
  }
  std::size_t handled = tasks.size();
  if (streams_->turn_wanted()) {
    // commands that waited for the lock, and first samples for new subscribers (a paused
    // simulation takes no step that would give them)
    std::lock_guard lock(*gate_);
    handled += streams_->apply_commands();
    streams_->publish_due(state_time_);
  }
  for (auto& manager : managers_) handled += manager->process();
  return handled;
}

std::size_t Simulation::soon_count() {
  std::lock_guard lock(soon_mutex_);
  return soon_.size();
}

void Simulation::step() {
  // a step is no part of whatever request made it happen (`simulation step` steps on its
  // caller's thread): default actions see the whole simulation, as on the simulation thread
  const OutsideRequest outside;
  // components act on the state the requests left
  for (auto& e : entries_) {
    if (!e->active) continue;
    try {
      e->component->default_action();
    } catch (const std::exception& error) {
      // a faulty component is switched off; the simulation and everyone else go on
      fail_component(*e, "default_action()", error.what());
    }
  }
  // physics (or only the clock while dynamics are suspended)
  if (dynamics_suspended_) {
    d()->time += m()->opt.timestep;
    // the frozen state, as it is now (a component may have moved a joint): what sensors
    // read is of the current time, as a <clock> sensor says
    forward();
  } else {
    const double time_before = d()->time;
    // what a divergence goes back to: the state this step starts from, or a checkpoint (the
    // state a step started from, kept once that step went well)
    const bool checkpoint_due = on_divergence_ == DivergencePolicy::restore &&
                                (!checkpoint_.fits(m(), model_generation_) ||
                                 time_before >= checkpoint_.time() + k_checkpoint_interval ||
                                 time_before < checkpoint_.time());
    if (on_divergence_ == DivergencePolicy::pause)
      before_step_.capture(m(), d(), model_generation_);
    else if (checkpoint_due)
      next_checkpoint_.capture(m(), d(), model_generation_);
    const std::uint64_t divergences = bad_states_;
    // mj_step evaluates the state it starts from, then integrates (a bad state's recovery
    // below evaluates the restored state anew)
    state_time_ = time_before;
    take_mj_step();
    // undone (pause): no step was taken, nothing new to publish
    if (check_mujoco_warnings(time_before)) return;
    if (checkpoint_due && bad_states_ == divergences)
      std::swap(checkpoint_, next_checkpoint_);  // no allocation
    // RK4 leaves poses from its last intermediate stage and sensors from the start: one
    // evaluation of where the step ended makes them agree (the next step then evaluates
    // only the acceleration stage of it again: take_mj_step)
    if (m()->opt.integrator == mjINT_RK4 && state_time_ != d()->time) forward();
  }
  steps_.fetch_add(1, std::memory_order_relaxed);
  if (observer_) [[unlikely]]
    observer_->stepped();
  // the streams due: samples of the state this step leaves
  streams_->publish_due(state_time_);
}

void Simulation::fail_component(ComponentEntry& entry, const std::string& what,
                                const std::string& reason) {
  const std::string& name = entry.component->name();
  log::error(name, ": ", what, " failed: ", reason, "; the component is deactivated",
             " (simulation activate \"", name, "\" turns it back on)");
  entry.active = false;
  AsyncSlot& slot = *entry.component->async_slot();
  const Outcome failed =
      Outcome::failed(Failure::internal, name + ": " + what + " failed: " + reason);
  if (slot.busy()) slot.running_completion.finish(failed);
  for (const Completion& call : slot.running_concurrent()) call.finish(failed);
}

void Simulation::run() {
  {
    // under the lock: statistics() reads them for a service a transport runs meanwhile
    std::lock_guard lock(*gate_);
    running_ = true;
    run_started_ = Clock::now();
    restart_pace(run_started_);
    reschedule_ = false;
  }
  while (!stop_requested()) {
    // requests first, whenever the loop wakes
    process_requests();
    if (stop_requested()) break;
    // what to do next depends on what the requests just changed (pause, play, step, pace)
    std::unique_lock lock(*gate_);
    if (reschedule_) {
      reschedule_ = false;
      restart_pace(Clock::now());
    }
    if (paused_) {
      if (owed_steps_ > 0) {
        // one at a time, as fast as possible: requests (a cancel) are served between two
        take_owed_steps(Clock::time_point{});
        continue;
      }
      lock.unlock();
      // a request, a step or play wakes it at once
      gate_->wait_for(k_paused_wait);
      continue;
    }
    if (realtime_factor_ == 0) {
      step();
      measure_rate(Clock::now());
      continue;
    }
    auto now = Clock::now();
    if (now >= next_step_) {
      step();
      measure_rate(now);
      next_step_ += std::chrono::duration_cast<Clock::duration>(
          std::chrono::duration<double>(timestep() / realtime_factor_));
      // fell behind (slow machine, long service): resynchronise instead of racing
      if (now - next_step_ > k_max_lag) {
        next_step_ = now;
        ++overruns_;
      }
      continue;
    }
    const auto next = next_step_;
    lock.unlock();
    // sleep until the next step, or until queued work arrives; meanwhile transports run
    // their requests themselves under the simulation lock
    gate_->wait_until(next);
  }
}

void Simulation::restart_pace(Clock::time_point now) {
  next_step_ = now;
  window_start_ = now;
  window_steps_ = steps();
}

void Simulation::measure_rate(Clock::time_point now) {
  const auto elapsed = now - window_start_;
  if (elapsed < k_rate_window) return;
  // steps, not mjData::time: a reset or a restored state moves the clock, not the pace
  const double wall = std::chrono::duration<double>(elapsed).count();
  recent_factor_.store(static_cast<double>(steps() - window_steps_) * timestep() / wall,
                       std::memory_order_relaxed);
  window_start_ = now;
  window_steps_ = steps();
}

RunState Simulation::run_state() const {
  if (stop_requested()) return RunState::quitting;
  if (!paused_) return RunState::playing;
  return owed_steps_ > 0 ? RunState::stepping : RunState::paused;
}

void Simulation::set_paused(bool paused) {
  if (paused == paused_) return;
  paused_ = paused;
  announce(paused ? "paused" : "resumed");
  // time stood still: the pace (and the measured rate) start again from the moment it runs
  if (paused) recent_factor_.store(0, std::memory_order_relaxed);
  reschedule_ = true;
  gate_->signal();
}

void Simulation::owe_steps(std::uint64_t n, std::function<void()> done) {
  owed_steps_ = n;
  owed_done_ = std::move(done);
}

std::uint64_t Simulation::forgive_owed_steps() {
  owed_done_ = nullptr;
  return std::exchange(owed_steps_, 0);
}

std::uint64_t Simulation::take_owed_steps(Clock::time_point until) {
  std::uint64_t taken = 0;
  while (owed_steps_ > 0) {
    step();
    ++taken;
    if (owed_steps_ == 0) break;  // forgiven by a diverging step (on_divergence pause)
    --owed_steps_;
    if (owed_steps_ > 0 && Clock::now() >= until) break;
  }
  if (owed_steps_ > 0) {
    // the rest is the loop's (it may be asleep, paused)
    gate_->signal();
  } else if (owed_done_) {
    std::exchange(owed_done_, nullptr)();
  }
  return taken;
}

void Simulation::request_stop() {
  stop_.store(true, std::memory_order_release);
  gate_->signal();
}

void Simulation::shutdown() {
  if (shut_down_) return;
  shut_down_ = true;
  try {
    // answer what already arrived (the caller of `quit` is answered in its own process())
    process_requests();
    // async requests still running end now, so their clients get a reply before the
    // transports close
    std::unique_lock lock(*gate_);
    for (auto& e : entries_) {
      AsyncSlot& slot = *e->component->async_slot();
      if (slot.busy())
        slot.running_completion.finish(Outcome::failed(
            Failure::shutdown,
            "the simulation stopped before " + slot.running->service + " completed"));
      // calls of concurrent services (every caller's `time sleep`)
      for (const Completion& call : slot.running_concurrent())
        call.finish(Outcome::failed(Failure::shutdown, "the simulation stopped before " +
                                                           call.state()->service + " completed"));
    }
    lock.unlock();
    process_requests();
  } catch (const std::exception& e) {
    log::error("simulation: while answering the last requests: ", e.what());
  }
  // stop the I/O, then destroy the managers (pending requests end with Failure::shutdown)
  for (std::size_t i = 0; i < managers_.size(); ++i) {
    log::debug("simulation: stopping transport '", manager_names_[i], "'");
    managers_[i]->stop();
  }
  managers_.clear();
  manager_names_.clear();
  // components last: the managers referred to their services
  events_ = nullptr;
  entries_.clear();
}

void Simulation::reset() {
  // poses, velocities and controls go back to the start; simulated time does not: it never
  // goes backwards (`time now`, running sleeps and sensor timestamps count on it). Nor do
  // the warning counters: they are the run's diagnostics, and MuJoCo prints a warning's
  // message only while its counter is 0.
  const double time = d()->time;
  std::array<mjWarningStat, mjNWARNING> warnings;
  std::copy(std::begin(d()->warning), std::end(d()->warning), warnings.begin());
  mj_resetData(m(), d());
  d()->time = time;
  std::copy(warnings.begin(), warnings.end(), std::begin(d()->warning));
  forward();
  announce("reset");
  for (auto& e : entries_) {
    if (!e->sim_component) continue;
    try {
      e->sim_component->on_reset();
    } catch (const std::exception& error) {
      // the others are reset all the same (this also runs inside step(), after a bad state)
      fail_component(*e, "on_reset()", error.what());
    }
  }
}

void Simulation::reset_all() {
  // reset() keeps the clock where it is: here, at the start
  d()->time = 0;
  reset();
}

void Simulation::forward() {
  mj_forward(m(), d());
  state_time_ = d()->time;
  if (m()->opt.integrator == mjINT_RK4) evaluated_.capture(m(), d(), model_generation_);
}

void Simulation::take_mj_step() {
  mjModel* model = m();
  mjData* data = d();
  // RK4 ends each step with forward() (Simulation::step): when the state is still the one
  // it evaluated, mj_step's own evaluation of it would compute the same numbers to the bit.
  // With the inputs unchanged too (a batch of steps with the same controls: step_many), none
  // of it is done again; with new controls or applied forces, only the acceleration stage
  // (which reads them): mj_step's parts, in its order. Not with sleeping islands (which
  // change what a stage computes between steps).
  if (model->opt.integrator != mjINT_RK4 || (model->opt.enableflags & mjENBL_SLEEP) != 0) {
    mj_step(model, data);
    return;
  }
  mj_checkPos(model, data);
  mj_checkVel(model, data);
  switch (evaluated_.current(model, data, model_generation_)) {
    case EvaluatedState::Current::all: break;
    case EvaluatedState::Current::positions: mj_forwardSkip(model, data, mjSTAGE_VEL, 0); break;
    case EvaluatedState::Current::nothing: mj_forward(model, data); break;
  }
  mj_checkAcc(model, data);
  if ((model->opt.enableflags & mjENBL_FWDINV) != 0) mj_compareFwdInv(model, data);
  mj_RungeKutta(model, data, 4);
}

void Simulation::announce(const char* event, json fields) {
  if (!events_ || !events_->stream_wanted()) return;
  fields["event"] = event;
  if (!fields.contains("timestamp")) fields["timestamp"] = d()->time;
  if (!fields.contains("step")) fields["step"] = steps();
  if (!fields.contains("by")) {
    // who did it: a client's request (its transport), else the simulation itself
    const CallContext* context = CallContext::current();
    fields["by"] = context ? context->manager().transport_name() : std::string("simulation");
  }
  const double time = fields["timestamp"].get<double>();
  events_->publish(time, std::move(fields));
}

void Simulation::restore_physics(const PhysicsState& state) {
  state.apply(m(), d());
  // what sensors read is of the restored state; the warm start is the saved one whatever
  // mj_forward did with it, so the next step is the one the saved state took
  forward();
  state.apply_warmstart(m(), d());
}

ObjectState::Unmatched Simulation::restore_objects(const ObjectState& state, double time) {
  const ObjectState::Mapping by_name = ObjectState::by_name(m());
  ObjectState::Unmatched unmatched = state.put(m(), d(), by_name);
  d()->time = time;
  forward();
  state.put_warmstart(m(), d(), by_name);  // as restore_physics does
  return unmatched;
}

Model Simulation::replace_model(Model next) {
  const ModelRemap remap = ModelRemap::between(m(), next.model(), -1, true);
  return replace_model(std::move(next), remap);
}

Model Simulation::replace_model(Model next, const ModelRemap& remap) {
  next.model()->opt = m()->opt;
  carry_state(model_, next, remap);
  std::swap(model_, next);
  ++model_generation_;
  forward();
  for (auto& entry : entries_)
    if (entry->sim_component) entry->sim_component->model_changed(remap);
  return next;
}

SimulationStatistics Simulation::statistics() const {
  SimulationStatistics s;
  s.steps = steps();
  s.sim_time = d()->time;
  s.wall_time = running_ ? std::chrono::duration<double>(Clock::now() - run_started_).count() : 0.0;
  s.realtime_factor = s.wall_time > 0 ? s.sim_time / s.wall_time : 0.0;
  s.target_factor = realtime_factor_;
  s.timestep = timestep();
  s.overruns = overruns_;
  s.bad_states = bad_states_;
  s.recent_factor = recent_factor_.load(std::memory_order_relaxed);
  return s;
}

}  // namespace simgate::sim
