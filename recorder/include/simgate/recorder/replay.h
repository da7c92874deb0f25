// simgate/recorder/replay.h — re-running a recording (recorder.h, format.h): `simgate replay
// FILE [--verify]` (docs/recording.md).
//
// A replay builds the recorded run's simulation (the gateway, from the deployment the
// recording carries, with no transport), puts back the state it started from, then takes the
// recorded inputs at their steps, in their order, and steps in between, as fast as possible:
// requests through a request manager of its own that serves every component (the services
// that act on the loop rather than the world, ServiceDescriptor::replayed false, are not
// called: their steps are in the recording as steps), interruptions as cancels, commands
// applied to their input streams, off-lock work (a spawned entity's model) taken in where it
// was. After every step it compares the state's fingerprint with the recorded one; the first
// step where they differ is named with the quantities that differ and the inputs taken just
// before it (every step is fingerprinted: no bisection is needed to find it).
//
// What cannot be replayed is refused before anything runs: a recording made with another
// MuJoCo (both versions named), a model whose state differs in size from the recording's, a
// recording that began after the model changed (a spawn or a delete before start_recording).
// A recording begun mid-run (start_recording) replays from its physics state; components'
// own state (an odometry's integral, a goto under way) starts afresh, which --verify reports
// as a divergence if it matters.
//
// Served (`simgate replay --serve`), the replayed run goes out through the deployment's
// transports as a live one would, paced at its real-time factor: Foxglove, the web app or
// pymorse watch it and may query it; what a client changes departs from the recording (logged).
// A served replay seeks (`simulation seek`, add_services(); the foxglove transport's playback
// bar uses it): forward, it replays as fast as possible up to the step sought; back, it goes
// to the recording's first state the way `simulation restore_state` does (components reset,
// robots' requests ended, clients told "restored"), then forward. Every step sought is the
// recorded run's own, components' state included, since it is reached by replaying the
// inputs from the start; the cost is the replay of the span (about 40 000 demo steps a second).
//
// Threads: Replayer::run() on one thread, which drives the simulation (it is the simulation
// thread while it runs; the simulation's loop must not run).
#ifndef SIMGATE_RECORDER_REPLAY_H_
#define SIMGATE_RECORDER_REPLAY_H_

#include <atomic>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <mujoco/mujoco.h>

#include "simgate/core/service.h"
#include "simgate/core/status.h"
#include "simgate/mcap/writer.h"
#include "simgate/sim/simulation.h"
#include "simgate/sim/supervision.h"

namespace simgate::recorder {

// What a recording holds, read whole (its stream samples aside).
struct Recording {
  std::string path;
  mcap::Metadata metadata;    // the "simgate" metadata record
  json deployment = nullptr;  // the deployment attachment, if any
  std::uint64_t first_step = 0;
  std::uint64_t generation = 0;  // the model generation it began at
  double initial_time = 0;
  std::vector<mjtNum> initial_state;  // mjSTATE_INTEGRATION
  std::vector<json> inputs;           // in order
  std::vector<json> outcomes;         // in order
  struct HashBlock {
    std::uint64_t first_step = 0;
    std::uint64_t steps = 0;
    std::optional<double> sim_time;  // after its last step (recordings since 2026-11-30)
    std::vector<std::string> quantities;
    std::vector<std::uint32_t> hashes;  // quantities.size() per step
  };
  std::vector<HashBlock> hashes;
  std::uint64_t last_step = 0;  // the last step fingerprinted (first_step if none)
  bool complete = false;        // the file was whole (else: cut, truncation says where)
  std::string truncation;

  // Reads `path`. Throws mcap::ReadError (not MCAP, corrupt: the offset named) or
  // std::runtime_error (MCAP, but no simgate recording: what is missing).
  static Recording read(const std::string& path);

  // The recorded run's step count at simulated time `t`: the first step whose time (after it)
  // reaches `t` within half a timestep, from the blocks' times (a reset or a restore in the
  // run makes a time occur more than once: the first is taken); `timestep` fills in for a
  // recording whose blocks carry no time. Clamped to [first_step, last_step].
  std::uint64_t step_at(double t, double timestep) const;
  // The simulated time after its last step.
  double end_time(double timestep) const;
};

// The first step where the replay's state differs from the recording's.
struct StepMismatch {
  std::uint64_t step = 0;               // the recorded run's step count after it
  double sim_time = 0;                  // the replay's simulated time after it
  std::vector<std::string> quantities;  // those whose fingerprints differ
  std::vector<json> inputs;             // the inputs taken between the step before and it
};

struct ReplayReport {
  std::uint64_t steps = 0;               // steps taken
  std::uint64_t inputs_applied = 0;      // requests, interruptions, commands, task batches
  std::uint64_t inputs_skipped = 0;      // requests of services a replay does not call
  std::uint64_t steps_compared = 0;      // steps whose fingerprints were compared
  std::uint64_t outcomes_differing = 0;  // requests whose status differs from the recorded
  std::optional<StepMismatch> mismatch;
  double wall_seconds = 0;
  // {"steps", "inputs_applied", "inputs_skipped", "steps_compared", "outcomes_differing",
  //  "mismatch": null or {"step", "sim_time", "quantities", "inputs"}, "wall_seconds"}
  json to_json() const;
};

struct ReplayOptions {
  // Stop at the first step whose fingerprint differs (`simgate replay --verify`).
  bool stop_at_mismatch = true;
  // Serving (`simgate replay --serve`): the simulation's transports are up and nobody else runs
  // its loop. After every step the replay serves their requests (Simulation::process_requests),
  // keeps the simulation's pace (its real-time factor: the deployment's, or a client's `time
  // set_time_scale`; 0: none) and honours a pause (simulation pause: it waits, a client's
  // `simulation step` steps); a difference is logged once, not a stop (a client's request
  // changed the world); at the end it keeps serving the last state, paused, until `stop` is
  // set or `simulation quit`.
  bool serve = false;
  const std::atomic<bool>* stop = nullptr;  // serve: set (with a gate signal) to end it
};

class Replayer {
 public:
  // Checks that `recording` can be replayed on `simulation` (built from its deployment, not
  // running); throws std::runtime_error saying why not (versions, model).
  Replayer(sim::Simulation& simulation, const Recording& recording);

  // Offers `seek` and `get_replay_status` on `simulation` (the replay served: before the
  // transports register it; served replays only).
  void add_services(sim::SupervisionServices& simulation);

  // Replays the whole recording (see ReplayOptions).
  ReplayReport run(const ReplayOptions& options = {});

 private:
  // How stepping to an input's step ended: it got there, a stop, a seek back.
  enum class Progress { reached, stopped, rewind };
  // A seek asked for and not reached yet (under the simulation lock).
  struct Seek {
    std::uint64_t step = 0;  // the recorded run's step count to reach
    Completion done;         // simulation seek's answer
  };
  // The recorded step the simulation is at (under the lock, or on the replay's thread).
  std::uint64_t step_now() const {
    return recording_.first_step + simulation_.steps() - steps_base_;
  }
  // simulation seek (under the lock)
  void seek(double sim_time, std::int64_t step, Completion done);
  json status() const;  // get_replay_status (under the lock)
  // Under the lock, after a step: answers the seek it reached.
  void reached(std::uint64_t step);
  // serve: requests served and the pace kept until the next step is due (or a stop)
  void serve_until_due(const ReplayOptions& options);
  // serve, after the last step: the last state served, paused, until a stop (false) or a seek
  // back (true)
  bool serve_to_the_end(const ReplayOptions& options);
  // serve: what a seek under way asks of the next step: none, forward (as fast as possible,
  // no pause), back (to the first state first). Takes the lock.
  enum class SeekAction { none, forward, back };
  SeekAction seek_action();
  // serve: Ctrl-C (options.stop) or `simulation quit`
  bool stopping(const ReplayOptions& options) const {
    return (options.stop && options.stop->load(std::memory_order_acquire)) ||
           simulation_.stop_requested();
  }

  sim::Simulation& simulation_;
  const Recording& recording_;
  // serve: the pace's origin (wall, simulated), restarted after a pause
  std::chrono::steady_clock::time_point pace_wall_{};
  double pace_sim_ = 0;
  double pace_factor_ = 0;
  // sim.steps() when the recording's first state was last put back (a seek back)
  std::uint64_t steps_base_ = 0;
  std::optional<Seek> seek_;               // under the lock
  bool restart_pace_ = false;              // a seek was reached (under the lock)
  std::optional<std::uint64_t> departed_;  // the step the served run departed at (under the lock)
};

}  // namespace simgate::recorder

#endif  // SIMGATE_RECORDER_REPLAY_H_
