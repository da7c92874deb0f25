// simgate/sim/worlds.h — the worlds of one process (issue #43, docs/worlds.md) and what acts
// on several at once.
//
// A process may run several worlds: world 0 and w1, w2, ..., each a Simulation of its own
// (its own model, components and simulation lock). Worlds knows them, in order, and offers
// on world 0's `simulation` component:
//
//   step_many(worlds, n, actions, observe, reads, encoding): for each world named (all by
//   default), sets its actuators' controls to its action (one number per actuator, in the
//   model's order; null keeps them, or one), takes n steps, and reads what `observe` names
//   (as JSON numbers, or with encoding "base64" each array's float64 bytes) and the
//   services `reads` names (synchronous ones of its components, as the caller may call
//   them); one reply for all. Every
//   world named is locked first (in order: no two callers can deadlock), the arguments are
//   checked against every world before anything changes (a wrong action size or an
//   out-of-range control refuses the call whole), then the worlds step in parallel on a pool
//   of threads (one per core, the caller's among them) while the locks are held, each world
//   by one thread from start to end: stepping worlds in one call gives exactly the states
//   stepping them one by one gives. A world whose step diverges stops there and says so in
//   its slot (its policy did what it does); the others take their n steps.
//
// Only world 0 offers it (a world's own services hold that world's lock; locking world 0
// from there could deadlock with a caller of world 0).
//
// Threads: step_many runs under world 0's lock (a service); the pool's threads touch a
// world only while the caller holds that world's lock for them.
#ifndef SIMGATE_SIM_WORLDS_H_
#define SIMGATE_SIM_WORLDS_H_

#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#include "simgate/core/config.h"

namespace simgate::sim {

class Simulation;
class SupervisionServices;

// A fixed set of threads that runs a batch of tasks with the calling thread's help and
// returns when all are done.
class TaskPool {
 public:
  // `threads` helpers besides the caller (0: none, everything on the caller).
  explicit TaskPool(std::size_t threads);
  ~TaskPool();
  TaskPool(const TaskPool&) = delete;
  TaskPool& operator=(const TaskPool&) = delete;

  // Runs task(0) ... task(count - 1), each once, spread over the helpers and the caller;
  // returns when every one has returned. Tasks must not throw. One batch at a time.
  void run(std::size_t count, const std::function<void(std::size_t)>& task);
  std::size_t threads() const { return helpers_.size(); }

 private:
  void help();
  // takes and runs tasks of the current batch until none is left
  void drain(std::unique_lock<std::mutex>& lock);

  std::mutex mutex_;
  std::condition_variable work_;  // a batch came, or stop
  std::condition_variable done_;  // a batch's last task ended
  const std::function<void(std::size_t)>* task_ = nullptr;
  std::size_t next_ = 0;     // the next task index to take
  std::size_t count_ = 0;    // tasks in the batch
  std::size_t running_ = 0;  // tasks taken and not yet ended
  std::uint64_t batch_ = 0;  // counts batches (helpers wake for a new one)
  bool stop_ = false;
  std::vector<std::thread> helpers_;
};

class Worlds {
 public:
  // `threads`: the pool's size, the caller included (0: one per core).
  explicit Worlds(std::size_t threads = 0);
  // World `index` joins (world 0 first) / leaves. Before the worlds run, or under world 0's
  // lock (step_many and describe() run under it).
  void add(unsigned index, Simulation& world);
  void remove(unsigned index);
  // Offers step_many on world 0's `simulation` component.
  void add_to(SupervisionServices& world0);

  // The service (see above). Under world 0's lock; throws ServiceError (bad_arguments,
  // naming the parameter) having changed nothing when the arguments do not fit.
  json step_many(const json& worlds, std::int64_t n, const json& actions, const json& observe,
                 const json& reads, const std::string& encoding = "json");
  // What step_many reads when `observe` is not given.
  static const std::vector<std::string>& default_observation();
  // Each world in order: {world, name ("w3"), state, sim_time, steps, actuators (MuJoCo's
  // nu: the length of step_many's action), memory_bytes}, each
  // read under its own lock. Under world 0's lock.
  json describe() const;
  // What MuJoCo holds for all worlds (Simulation::memory_bytes), each read under its own
  // lock. Under world 0's lock.
  std::size_t memory_bytes() const;
  // The worlds' indices, in order, as "0, 1, 3" (for messages).
  std::string index_list() const;

 private:
  // `read(index, world)` for each world in order, under its lock (world 0's: the caller's)
  void each_locked(const std::function<void(unsigned, const Simulation&)>& read) const;

  std::map<unsigned, Simulation*> worlds_;  // by index
  TaskPool pool_;
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_WORLDS_H_
