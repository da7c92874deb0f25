// simgate/sim/simulation.h — the simulation: a MuJoCo model, its components, the request
// managers that serve them, and the step loop.
//
// Terms:
//  - step: process requests, default_action() of every active component, mj_step, then a
//    look at MuJoCo's warning counters (see "bad states").
//  - pacing: real time times `realtime_factor` (1 = real time, 2 = twice as fast), or as
//    fast as possible when the factor is 0. Changeable at run time (time set_time_scale):
//    the next step is scheduled anew from the change.
//  - run state: playing (the loop steps on its own, paced), paused (it takes no step of its
//    own: neither time nor physics move, and every request is still served), stepping
//    (paused, taking the steps a client asked for with `simulation step`, as fast as
//    possible), quitting. Unlike dynamics suspended (MORSE's suspend_dynamics: time goes
//    on, physics frozen), a pause stops the clock too. docs/world/stepping.md.
//  - owed steps: the steps `simulation step n` asked for (or a lockstep barrier's, once
//    every participant has asked: sim/src/stepping.h). The thread that runs the request
//    takes them at once (take_owed_steps, no hand-off to the simulation thread for a client
//    that drives the simulation step by step); what is left after a short budget the loop
//    takes, one per iteration, with requests processed between two, so that a long run of
//    steps can be cancelled and never holds a transport's thread.
//  - model generation: a counter bumped whenever the model is replaced (a spawn or a delete
//    recompiles it); what was saved of another generation (a snapshot) cannot be restored
//    into it.
//  - entry: a component plus what the simulation knows about it (type name, robot, body,
//    active flag, the transports that serve it).
//
// Life cycle: construct from a Model; add_component() for every robot and component (the
// `simulation`, `simulation.events`, `time` and `communication` pseudo-components are added
// by add_world_components(), supervision.h);
// add_request_manager() for every transport (the simulation gives each one its gate);
// run() until request_stop() (any thread, or the `simulation quit` service); while it runs,
// replace_model() swaps a recompiled model in (the components re-resolve their ids) and
// remove_component() takes a deleted robot's components out; shutdown() answers what is
// left, stops the transports and destroys them, then the components.
//
// Bad states: MuJoCo 2.2.2 resets mjData in the middle of mj_step when qpos, qvel or qacc
// holds a NaN, an infinity or a magnitude beyond 1e10 (mjMAXVAL): the initial state, time
// back to 0, and a message the first time only. After every step the simulation compares
// the warning counters (and the clock) with what it saw last; a bad state is logged at
// warning level (its kind, the joint, the simulated time; every one of the first ten, then
// the 100th, 1000th...: a flood cannot fill a disk) and recovered through reset(), the path
// `simulation reset_objects` takes, so components get on_reset() and simulated time goes
// on. A bad control (ctrl: MuJoCo applies zero for that step) is logged and set to 0; the
// other warnings (too many contacts or constraints, singular inertia) are logged alike.
// `time statistics` counts the bad states. Client input never gets there (bounds.h).
//
// Threads: simulation state (MuJoCo data, every component and service) is touched only
// under the simulation lock of the shared SimulationGate. run() is the simulation thread:
// it takes the lock for each step() and each manager's process(), and releases it while it
// waits for the next step; in that time a transport thread may take it to run its requests
// at once (RequestManager::run_or_submit). So a request is served as soon as it arrives,
// never "at the next frame", and never makes the physics step early. Called directly,
// step() expects the caller to hold the lock or to be the only thread. request_stop(),
// stop_requested() and steps() may be called from any thread.
#ifndef SIMGATE_SIM_SIMULATION_H_
#define SIMGATE_SIM_SIMULATION_H_

#include <array>
#include <atomic>
#include <chrono>
#include <functional>
#include <mutex>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "simgate/core/component.h"
#include "simgate/core/request_manager.h"
#include "simgate/core/simulation_gate.h"
#include "simgate/core/streams.h"
#include "simgate/sim/model.h"
#include "simgate/sim/model_remap.h"
#include "simgate/sim/object_state.h"
#include "simgate/sim/physics_state.h"
#include "simgate/sim/run_policy.h"

namespace simgate::sim {

class SimComponent;
class SimulationEvents;

// One divergence, as clients are told of it.
struct Divergence {
  double time = 0;         // the simulated time the diverging step started from
  std::uint64_t step = 0;  // steps taken before it
  std::string quantity;    // the bad number: "qacc[12]"
  std::string where;       // what it belongs to: "joint 'knee' of body 'shin'"
  DivergencePolicy action = DivergencePolicy::pause;  // what was done
  double resumed_at = 0;  // the simulated time the world was put back to
};
// As clients read it: get_simulation_state's last_divergence, the "diverged" event's fields.
// {"sim_time", "step", "quantity", "where", "action", "resumed_at"}
json to_json(const Divergence& divergence);

struct SimulationOptions {
  std::optional<double> timestep;  // seconds; overrides the MJCF's <option timestep>
  double realtime_factor = 1.0;    // sim seconds per wall second; 0 = as fast as possible
  bool start_paused = false;       // lockstep: clients drive the simulation with `simulation step`
  // Directories `simulation spawn_entity` may read fragment files from (absolute; none: inline MJCF
  // only).
  std::vector<std::string> spawn_allowed_dirs = {};
  DivergencePolicy on_divergence = DivergencePolicy::pause;  // scene.on_divergence
};

// What the loop is doing (simulation get_simulation_state).
enum class RunState : std::uint8_t {
  playing,   // it steps on its own, paced by the real-time factor
  paused,    // no step of its own: time and physics stand still; requests are served
  stepping,  // paused, taking the steps a client asked for (simulation step)
  quitting,  // request_stop() was called
};
// "playing", "paused", "stepping", "quitting": the words on the wire.
const char* to_string(RunState state);

// What the simulation knows about one component.
struct ComponentEntry {
  std::unique_ptr<Component> component;   // owned
  SimComponent* sim_component = nullptr;  // the same object when it is a SimComponent
  std::string type;                       // registry type name, "simulation", "time"
  std::string robot;                      // owning robot ("" for robots and pseudo-components)
  bool is_robot = false;                  // a robot (top-level object of `details`)
  bool active = true;                     // default_action() runs (simulation activate/deactivate)
  std::vector<std::string> interfaces;    // names of the transports that serve it
};

// Counters for `time statistics` and benchmarks.
struct SimulationStatistics {
  std::uint64_t steps = 0;     // physics steps since start
  double sim_time = 0;         // simulated seconds (mjData::time)
  double wall_time = 0;        // wall seconds since run() started
  double realtime_factor = 0;  // measured sim_time / wall_time over the run
  double target_factor = 0;    // configured factor (0 = as fast as possible)
  double timestep = 0;         // physics step, seconds
  std::uint64_t overruns = 0;  // times the loop fell behind real time and resynchronised
  std::uint64_t bad_states =
      0;                     // steps in which MuJoCo found a bad state (divergences: on_divergence)
  double recent_factor = 0;  // measured over the last second of playing (0 while paused)
};

class Simulation {
 public:
  Simulation(Model model, SimulationOptions options = {});
  ~Simulation();
  Simulation(const Simulation&) = delete;
  Simulation& operator=(const Simulation&) = delete;

  Model& model() { return model_; }
  const Model& model() const { return model_; }
  mjModel* m() const { return model_.model(); }
  mjData* d() const { return model_.data(); }

  // Behind real time by more than this, the paced loop stops catching up: it resumes from
  // now and counts an overrun.
  static constexpr std::chrono::milliseconds k_max_lag{100};

  // The measured real-time factor is taken over windows of this much wall time.
  static constexpr std::chrono::seconds k_rate_window{1};
  // While paused with nothing to do, the loop still looks up this often (a request or a
  // step wakes it at once: this only bounds a wait nobody signals).
  static constexpr std::chrono::seconds k_paused_wait{1};
  // How long the thread that runs `simulation step` steps before it leaves the rest to the
  // loop (take_owed_steps): a transport's thread is not held longer than this.
  static constexpr std::chrono::milliseconds k_inline_step_budget{2};

  double timestep() const { return m()->opt.timestep; }
  double realtime_factor() const { return realtime_factor_; }
  // The slowest pace (run_policy.h).
  static constexpr double k_min_realtime_factor = sim::k_min_realtime_factor;
  // 0 = as fast as possible, else at least k_min_realtime_factor (std::invalid_argument
  // otherwise). Under the simulation lock (or before run()); the loop schedules its next
  // step from now, at the new pace.
  void set_realtime_factor(double factor);

  // ---- components (before run(), or on the simulation thread) ----

  // Takes ownership; names must be unique (throws std::invalid_argument otherwise).
  ComponentEntry& add_component(std::unique_ptr<Component> component, std::string type,
                                std::string robot = "", bool is_robot = false);
  // The simulation.events pseudo-component (events.h) announce() publishes to; the world's
  // pseudo-components are added by add_world_components() (supervision.h).
  void set_events(SimulationEvents* events) { events_ = events; }
  ComponentEntry* find(const std::string& name);
  // Removes the component `name` at run time (a robot deleted with its body,
  // simulation delete_entity): every request manager stops serving it
  // (RequestManager::unregister_component: its requests running there end FAILED with
  // `reason`, later calls are unknown services, the transports' catalogs are published
  // anew), then it is destroyed. Under the simulation lock, on the simulation's turn (a
  // run_soon task), never from a service or default_action() of the component itself.
  // Returns false when there is no such component.
  bool remove_component(const std::string& name, const std::string& reason);
  const std::vector<std::unique_ptr<ComponentEntry>>& components() const { return entries_; }
  // Names of the robots, in order.
  std::vector<std::string> robot_names() const;

  // ---- transports ----

  // The simulation processes `manager` every step and shares its gate with it.
  void add_request_manager(std::shared_ptr<RequestManager> manager, std::string transport);
  const std::shared_ptr<SimulationGate>& gate() const { return gate_; }
  // The data streams (streams.h): the components' streams are added by whoever builds the
  // simulation (the gateway, from the configuration); each step publishes what is due, each
  // turn applies the commands that waited. Every request manager gets it.
  StreamHub& streams() { return *streams_; }
  const StreamHub& streams() const { return *streams_; }
  const std::vector<std::shared_ptr<RequestManager>>& request_managers() const { return managers_; }
  // The manager added as `transport`, or null.
  const RequestManager* request_manager(const std::string& transport) const;

  // ---- the loop (simulation thread) ----

  // Runs until request_stop(). Exceptions from MuJoCo or components propagate.
  void run();
  // One step without pacing or request processing: default actions, then physics, then
  // the bad-state check (see above). A component whose default_action() throws is
  // deactivated (logged, its running request FAILED); MuJoCo errors propagate.
  void step();
  // process() of every request manager; returns the events handled.
  std::size_t process_requests();
  // Any thread: `task` runs under the simulation lock on the simulation's next turn (the
  // start of the next process_requests(), which the loop calls at once when woken, playing
  // or paused), and the loop is woken for it. For work finished off the lock (a model
  // compiled on a worker thread) that must then touch the simulation: it does not wait for
  // a step, which a paused simulation does not take.
  void run_soon(std::function<void()> task);
  // Answers what is still queued, ends the async requests still running (those of
  // concurrent services too) FAILED, stops every transport, destroys the transports, then
  // the components. Idempotent; called by the destructor.
  void shutdown();

  // Any thread.
  void request_stop();
  bool stop_requested() const { return stop_.load(std::memory_order_acquire); }
  std::uint64_t steps() const { return steps_.load(std::memory_order_relaxed); }

  // ---- supervision (simulation thread) ----

  double sim_time() const { return d()->time; }
  // What MuJoCo holds for this world: its model and its data with their buffers and arena
  // (bytes; the components' own few are not counted). Under the simulation lock.
  std::size_t memory_bytes() const {
    return sizeof(mjModel) + static_cast<std::size_t>(m()->nbuffer) + sizeof(mjData) +
           static_cast<std::size_t>(d()->nbuffer) + static_cast<std::size_t>(d()->narena);
  }
  // The simulated time of the state that mjData's computed quantities describe: body and
  // site poses (xpos, xquat, site_xpos...), velocities (cvel), accelerations (cacc),
  // actuator forces and the MJCF sensors' values (sensordata): what every sensor reads, so
  // what its `timestamp` says. mj_step computes them for the state it starts from, then
  // integrates qpos, qvel, act and time: after a step they describe the state one timestep
  // before sim_time() (this returns the time the step started from, exactly, so that a
  // <clock> sensor reads the same number). After construction, reset(), forward(), each
  // step while dynamics are suspended (which evaluates the frozen state at the new time)
  // and each step of the RK4 integrator (whose last intermediate stage leaves poses that
  // are of neither time: step() evaluates the state it ended in) they describe the current
  // state: state_time() == sim_time(). qpos, qvel, act and ctrl themselves are always of
  // sim_time().
  double state_time() const { return state_time_; }
  // mj_forward on the current state, which becomes the state the computed quantities
  // describe (state_time() = sim_time()). For a component that changed qpos or qvel
  // between two steps (a teleport, a joint set at once) so that what clients read next
  // reflects the change. Never call mj_forward directly: state_time() would not know.
  void forward();
  // Restores the initial state of every object (poses, velocities, controls); simulated
  // time goes on from where it was, and so do MuJoCo's warning counters. Components get
  // on_reset(). Also the recovery from a bad state.
  void reset();
  // While suspended, step() advances the clock and evaluates the state (mj_forward)
  // without integrating it: nothing moves unless a component moves it.
  void set_dynamics_suspended(bool suspended) { dynamics_suspended_ = suspended; }
  bool dynamics_suspended() const { return dynamics_suspended_; }
  // reset() with simulated time back to 0 as well (the world as it started).
  void reset_all();
  // Puts `state` (which fits the model: PhysicsState::fits) back, time included, and
  // evaluates it; the next step is the one taken from it when it was captured. Components
  // are not told (the caller decides: on_reset() after a jump).
  void restore_physics(const PhysicsState& state);
  // A state saved from an older model (a spawn or a delete since) put back object by object,
  // matched by name (object_state.h), simulated time `time` included; then as
  // restore_physics. Returns what did not match. Under the lock.
  ObjectState::Unmatched restore_objects(const ObjectState& state, double time);
  SimulationStatistics statistics() const;

  // ---- observing the run (under the simulation lock) ----

  // What a recorder (issue #39) is told of besides the inputs (input_tap.h): each step taken
  // (after it, the state it left in mjData; a step undone by the divergence policy `pause`
  // is not one) and each batch of run_soon tasks run (work finished off the lock, a spawned
  // entity's model, takes effect there). Called on the thread that holds the lock; must not
  // block.
  class Observer {
   public:
    virtual ~Observer() = default;
    virtual void stepped() = 0;
    virtual void tasks_ran(std::size_t count) = 0;
  };
  // `observer` (not owned; null: none) from now on.
  void set_observer(Observer* observer) { observer_ = observer; }
  // run_soon tasks waiting for the simulation's next turn (a replay waits for those the
  // recording says ran before the next step). Any thread.
  std::size_t soon_count();

  // ---- divergence (simulation thread) ----

  // Under the restore policy, a checkpoint is taken after each this much simulated time
  // without a divergence.
  static constexpr double k_checkpoint_interval = 1.0;
  DivergencePolicy on_divergence() const { return on_divergence_; }
  void set_on_divergence(DivergencePolicy policy);
  // The latest divergence, if any, and how many there were (statistics().bad_states).
  const std::optional<Divergence>& last_divergence() const { return last_divergence_; }
  std::uint64_t divergences() const { return bad_states_; }

  // ---- events (under the simulation lock) ----

  // Tells the subscribers of simulation.events (supervision.h) that `event` happened now:
  // {"event", "timestamp": simulated time (unless `fields` has one), "step": steps taken,
  // ...fields}. The simulation announces "diverged" (fields: to_json(Divergence),
  // "divergences", "message"; its timestamp the diverging step's start), then what
  // its policy did: "paused" (set_paused) or "reset" (reset()); and "paused", "resumed",
  // "reset" whoever causes them, and "restored" (fields: "handle") for restore_state. Every event
  // has "by": the transport of the client request that caused it, or "simulation" (its own policy,
  // the host). Costs one atomic read when nobody subscribes.
  void announce(const char* event, json fields = json::object());

  // ---- playing, pausing and stepping (under the simulation lock) ----

  RunState run_state() const;
  bool paused() const { return paused_; }
  // Paused, the loop takes no step of its own (owed steps aside) and sleeps until a request
  // or a step arrives. Playing again resumes the pace from now: the paused time is not
  // caught up. Owed steps are not touched (the stepping service settles them).
  void set_paused(bool paused);
  // `simulation step n`: the simulation owes n more steps, taken while paused (by
  // take_owed_steps on the thread that asks, then by the loop); `done` runs under the lock
  // once the last is taken. Replaces what was owed before (forgive_owed_steps first).
  void owe_steps(std::uint64_t n, std::function<void()> done);
  std::uint64_t owed_steps() const { return owed_steps_; }
  // Forgets the steps still owed (their `done` never runs); returns how many there were.
  std::uint64_t forgive_owed_steps();
  // Takes owed steps on the calling thread until none is left or `until` has passed (one at
  // least, if any is owed); returns how many it took. Steps left wake the loop.
  std::uint64_t take_owed_steps(std::chrono::steady_clock::time_point until);

  // ---- the model itself (simulation thread) ----

  // Counts the changes of the model (spawned or deleted entities): 0 for the model the
  // simulation started with. What was saved of one model (a snapshot's state arrays) does
  // not fit another.
  std::uint64_t model_generation() const { return model_generation_; }
  // Makes `next`, the current model recompiled with entities added or removed, or a body
  // of the scene removed (model_edit.h), the simulation's model: the state of every object
  // both hold is carried across through `remap` (carry_state), and so are the clock and the
  // physics options (a timestep set by the config or at run time); bumps
  // model_generation(), then forward(), then tells every SimComponent where its objects
  // went (SimComponent::on_model_changed): a body removed from the middle moves the ids of
  // everything after it. The caller has removed the components whose objects go. Returns
  // the model replaced (a spawn whose robot cannot be built swaps it back).
  Model replace_model(Model next, const ModelRemap& remap);
  // The same for a model that only adds objects after the current ones (a spawn): the
  // remap is computed here (ModelRemap::between; throws MujocoError when `next` does not
  // start with the current model's objects).
  Model replace_model(Model next);
  // SimulationOptions::spawn_allowed_dirs.
  const std::vector<std::string>& spawn_allowed_dirs() const { return spawn_allowed_dirs_; }

  // Builds the robots `simulation spawn_entity` brings (its `robot` parameter): set by the
  // host that knows the configuration (the gateway: component types, the transports that
  // serve a name, stream rules). Without one, a spawn with a robot is refused.
  class RobotFactory {
   public:
    virtual ~RobotFactory() = default;
    // Checks robot `name`'s section before anything is compiled (its structure, names,
    // component types): throws ServiceError (bad_arguments, parameter "robot") saying what
    // is wrong. Under the simulation lock.
    virtual void check(const std::string& name, const json& section) const = 0;
    // Creates robot `name` (its body, the spawned entity's, is in the model now) and its
    // components, adds them to the simulation and serves them on the transports the
    // configuration maps them to, with their streams. Under the simulation lock. Throws
    // (ServiceError, parameter "robot") having added nothing when a component cannot be made.
    virtual void build(const std::string& name, const json& section) = 0;
  };
  void set_robot_factory(std::shared_ptr<RobotFactory> factory) {
    robot_factory_ = std::move(factory);
  }
  RobotFactory* robot_factory() const { return robot_factory_.get(); }

 private:
  // After a step taken while playing: the measured real-time factor, window by window.
  void measure_rate(std::chrono::steady_clock::time_point now);
  // Restarts the pace and the rate window from now (play, a new factor).
  void restart_pace(std::chrono::steady_clock::time_point now);
  // Deactivates a component whose `what` ("default_action()", "on_reset()") threw; fails
  // its running request.
  void fail_component(ComponentEntry& entry, const std::string& what, const std::string& reason);
  // After mj_step: reports what MuJoCo warned about since the last look, and recovers from
  // a bad state (MuJoCo's reset) by the divergence policy (diverged()). `time_before`: the
  // simulated time the step started from. True when the step was undone (pause).
  bool check_mujoco_warnings(double time_before);
  // mj_step; for an RK4 model from the state forward() last evaluated (evaluated_, which
  // nothing moved since), mj_step's own parts with its evaluation's position and velocity
  // stages left out: they would compute what is in mjData already, to the same bits.
  void take_mj_step();
  // Applies the divergence policy to the step from `time_before` that MuJoCo found `what`
  // in (`quantity` of `where`); true when the step was undone.
  bool diverged(double time_before, const std::string& what, std::string quantity,
                std::string where);
  // Ends every async request in flight (each component's running one, and its concurrent
  // calls) FAILED with `reason`, then interrupts what they were doing.
  void fail_requests(const std::string& reason);
  // Sets every bad control to 0 and names their actuators.
  std::string drop_bad_controls();

  Model model_;                                           // mjModel + mjData
  double realtime_factor_;                                // 0 = as fast as possible
  bool paused_ = false;                                   // no step of the loop's own
  std::uint64_t owed_steps_ = 0;                          // `simulation step` steps left
  std::function<void()> owed_done_;                       // runs after the last owed step
  std::uint64_t model_generation_ = 0;                    // see model_generation()
  bool reschedule_ = false;                               // the loop restarts its pace from now
  std::chrono::steady_clock::time_point next_step_{};     // when the paced loop steps next
  std::chrono::steady_clock::time_point window_start_{};  // wall start of the rate window
  std::uint64_t window_steps_ = 0;                        // steps_ at the window's start
  std::atomic<double> recent_factor_{0};                  // measured over the last window
  std::shared_ptr<SimulationGate> gate_;                  // shared with every manager
  std::shared_ptr<StreamHub> streams_;       // the data streams, shared with every manager
  std::mutex soon_mutex_;                    // guards soon_
  std::vector<std::function<void()>> soon_;  // run_soon tasks, in order
  std::vector<std::unique_ptr<ComponentEntry>> entries_;   // every component, in order
  std::vector<std::shared_ptr<RequestManager>> managers_;  // every transport
  std::vector<std::string> manager_names_;                 // transport name of each manager
  std::atomic<bool> stop_{false};                          // run() returns when set
  std::atomic<std::uint64_t> steps_{0};                    // physics steps taken
  bool dynamics_suspended_ = false;                        // step() skips mj_step
  double state_time_ = 0;                                  // see state_time()
  // wall start of run(), and whether it started: written and read under the lock
  std::chrono::steady_clock::time_point run_started_{};
  bool running_ = false;
  std::uint64_t overruns_ = 0;  // pacing resynchronisations
  bool shut_down_ = false;      // shutdown() done
  // mjData::warning[k].number after the last look (0 or 1: rebased each time, so MuJoCo's
  // int never overflows and its own message, printed when the counter is 0, comes once)
  std::array<int, mjNWARNING> warnings_seen_{};
  std::array<std::uint64_t, mjNWARNING>
      warning_totals_{};                       // occurrences of each warning since start
  std::uint64_t bad_states_ = 0;               // divergences since start
  DivergencePolicy on_divergence_;             // see SimulationOptions
  std::optional<Divergence> last_divergence_;  // see last_divergence()
  PhysicsState before_step_;                   // pause: the state the step started from
  EvaluatedState evaluated_;                   // RK4: the state forward() last evaluated
  PhysicsState checkpoint_;                    // restore: the last checkpoint
  PhysicsState next_checkpoint_;  // restore: the one being taken (kept if its step goes well)
  std::vector<std::string> spawn_allowed_dirs_;  // see SimulationOptions
  std::shared_ptr<RobotFactory> robot_factory_;  // see set_robot_factory
  SimulationEvents* events_ = nullptr;  // simulation.events (owned by entries_), once added
  Observer* observer_ = nullptr;        // see set_observer
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_SIMULATION_H_
