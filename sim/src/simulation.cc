#include "simgate/sim/simulation.h"

#include <cmath>
#include <stdexcept>

#include "simgate/core/log.h"
#include "simgate/sim/sim_component.h"
#include "simgate/sim/supervision.h"

namespace simgate::sim {

namespace {
using Clock = std::chrono::steady_clock;
}  // namespace

Simulation::Simulation(Model model, SimulationOptions options)
    : model_(std::move(model)), gate_(std::make_shared<SimulationGate>()) {
  if (options.timestep) {
    if (!(*options.timestep > 0) || !std::isfinite(*options.timestep))
      throw std::invalid_argument("simulation: timestep must be a positive number, not " +
                                  std::to_string(*options.timestep));
    m()->opt.timestep = *options.timestep;
  }
  set_realtime_factor(options.realtime_factor);
}

Simulation::~Simulation() {
  try {
    shutdown();
  } catch (const std::exception& e) {
    log::error("simulation: shutdown failed: ", e.what());
  }
}

void Simulation::set_realtime_factor(double factor) {
  if (!(factor >= 0) || !std::isfinite(factor))
    throw std::invalid_argument("simulation: realtime_factor must be >= 0 (0 = as fast as possible), not " +
                                std::to_string(factor));
  realtime_factor_ = factor;
}

ComponentEntry& Simulation::add_component(std::unique_ptr<Component> component, std::string type,
                                          std::string robot, bool is_robot) {
  if (!component) throw std::invalid_argument("simulation: add_component(nullptr)");
  if (find(component->name()))
    throw std::invalid_argument("simulation: a component named '" + component->name() + "' already exists");
  auto entry = std::make_unique<ComponentEntry>();
  entry->sim_component = dynamic_cast<SimComponent*>(component.get());
  entry->component = std::move(component);
  entry->type = std::move(type);
  entry->robot = std::move(robot);
  entry->is_robot = is_robot;
  entries_.push_back(std::move(entry));
  return *entries_.back();
}

void Simulation::add_supervision_services() {
  add_component(std::make_unique<SupervisionServices>(*this), "simulation");
  add_component(std::make_unique<TimeServices>(*this), "time");
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

void Simulation::add_request_manager(std::shared_ptr<RequestManager> manager, std::string transport) {
  manager->set_gate(gate_);
  managers_.push_back(std::move(manager));
  manager_names_.push_back(std::move(transport));
}

std::size_t Simulation::process_requests() {
  std::size_t handled = 0;
  for (auto& manager : managers_) handled += manager->process();
  return handled;
}

void Simulation::step() {
  // components act on the state the requests left
  for (auto& e : entries_) {
    if (!e->active) continue;
    try {
      e->component->default_action();
    } catch (const std::exception& error) {
      // a faulty component is switched off; the simulation and everyone else go on
      fail_component(*e, error.what());
    }
  }
  // physics (or only the clock while dynamics are suspended)
  if (dynamics_suspended_) {
    d()->time += m()->opt.timestep;
  } else {
    mj_step(m(), d());
  }
  steps_.fetch_add(1, std::memory_order_relaxed);
}

void Simulation::locked_step() {
  std::lock_guard lock(*gate_);
  step();
}

void Simulation::fail_component(ComponentEntry& entry, const std::string& reason) {
  const std::string& name = entry.component->name();
  log::error(name, ": default_action() failed: ", reason, "; the component is deactivated",
             " (simulation activate \"", name, "\" turns it back on)");
  entry.active = false;
  AsyncSlot& slot = *entry.component->async_slot();
  const Outcome failed = Outcome::failed(Failure::internal, name + ": default_action() failed: " + reason);
  if (slot.busy()) slot.running_completion.finish(failed);
  for (const Completion& call : slot.running_concurrent()) call.finish(failed);
}

void Simulation::run() {
  running_ = true;
  run_started_ = Clock::now();
  auto next_step = run_started_;
  while (!stop_requested()) {
    // requests first, whenever the loop wakes
    process_requests();
    if (stop_requested()) break;
    if (realtime_factor_ == 0) {
      locked_step();
      continue;
    }
    auto now = Clock::now();
    if (now >= next_step) {
      locked_step();
      next_step += std::chrono::duration_cast<Clock::duration>(
          std::chrono::duration<double>(timestep() / realtime_factor_));
      // fell behind (slow machine, long service): resynchronise instead of racing
      if (now - next_step > k_max_lag) {
        next_step = now;
        ++overruns_;
      }
      continue;
    }
    // sleep until the next step, or until queued work arrives; meanwhile transports run
    // their requests themselves under the simulation lock
    gate_->wait_until(next_step);
  }
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
            Failure::shutdown, "the simulation stopped before " + slot.running->service + " completed"));
      // calls of concurrent services (every caller's `time sleep`)
      for (const Completion& call : slot.running_concurrent())
        call.finish(Outcome::failed(Failure::shutdown,
                                    "the simulation stopped before " + call.state()->service + " completed"));
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
  entries_.clear();
}

void Simulation::reset() {
  // poses, velocities and controls go back to the start; simulated time does not: it never
  // goes backwards (`time now`, running sleeps and sensor timestamps count on it)
  const double time = d()->time;
  mj_resetData(m(), d());
  d()->time = time;
  mj_forward(m(), d());
  for (auto& e : entries_)
    if (e->sim_component) e->sim_component->on_reset();
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
  return s;
}

}  // namespace simgate::sim
