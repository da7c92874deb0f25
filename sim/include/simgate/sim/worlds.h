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
//   them); one reply for all.
//
// It is an asynchronous (concurrent) service. Where the call arrives (under world 0's lock)
// only what needs no world is checked (the worlds named exist, n, observe, encoding, the
// reads' shape and the caller's right to call them), the call takes its turn on each world
// (calls that name a world step it in the order they came), and the pool takes it: the
// caller's thread is free at once (a transport goes on reading and answering). On the pool,
// the call's first task waits for its turn on each world, then checks it under that world's
// lock (a wrong action size or an out-of-range control refuses the call whole before
// anything changes); then one task per world steps it, from start to end under its lock:
// stepping worlds in one call gives exactly the states stepping them one by one gives. A
// world whose step diverges stops there and says so in its slot (its policy did what it
// does); the others take their n steps. A world whose model was replaced between the check
// and its steps (a spawn), or that was deleted, is not stepped and says so in its slot. A
// call that ends before its worlds are done (its client cancelled it or left, its deadline
// passed, simgate stops) stops each world at its next step; so does delete_world.
//
// Only world 0 offers it: its lock orders the calls (their turns are taken under it).
//
// Threads and locks: the pool's threads touch a world only under its lock, one lock at a
// time, and wait for nothing while they hold it. A thread that holds world 0's lock may wait
// for another world's (describe()) or for the pool thread using a world (remove(): it stops
// at its next step), never the reverse. mutex_ guards the worlds' turns and uses; it is
// never held while waiting for a world's lock.
#ifndef SIMGATE_SIM_WORLDS_H_
#define SIMGATE_SIM_WORLDS_H_

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <vector>

#include "simgate/core/config.h"
#include "simgate/sim/task_pool.h"

namespace simgate {
class Completion;
}

namespace simgate::sim {

class Simulation;
class SupervisionServices;

class Worlds {
 public:
  // `threads`: the pool's threads, those that step worlds (0: one per core).
  explicit Worlds(std::size_t threads = 0);
  // request_stop(), and waits for the pool to be idle (stop() first while the worlds exist).
  ~Worlds();
  // World `index` joins (world 0 first) / leaves. Before the worlds run, or under world 0's
  // lock (step_many and describe() run under it). remove() stops a call stepping the world
  // at its next step, and returns once none steps it (its slot says it was deleted).
  void add(unsigned index, Simulation& world);
  void remove(unsigned index);
  // Offers step_many on world 0's `simulation` component.
  void add_to(SupervisionServices& world0);
  // Calls under way stop at their next step, those queued step nothing, step_many refuses
  // every call from now on; returns at once. Any thread.
  void request_stop();
  // request_stop(), and returns when the pool is idle: before the worlds shut down. Not under
  // world 0's lock (it takes it).
  void stop();

  // The service (see above). Under world 0's lock; throws ServiceError (bad_arguments,
  // naming the parameter) having changed nothing when the arguments do not fit; `done`
  // finishes the call with the reply.
  void step_many(const Completion& done, const json& worlds, std::int64_t n, json actions,
                 const json& observe, json reads, const std::string& encoding = "json");
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

  struct World;
  struct Call;
  // A call's first task (a pool thread): waits for the call's turn on each of its worlds,
  // then checks its arguments in each, under the world's lock.
  void check_call(Call& call);
  // A call's task for its slot `i` (a pool thread), once check_call() is done: the world's
  // steps, under its lock; then the world's turn passes to the next call.
  void step_slot(Call& call, std::size_t i);
  // Counts `world` as used unless it is leaving (then false). Under mutex_. release() ends
  // the use, and passes the world's turn on if `pass_turn`.
  bool take(World& world);
  void release(World& world, bool pass_turn);

  // by index; changed under world 0's lock and mutex_, read under either
  std::map<unsigned, std::shared_ptr<World>> worlds_;
  std::mutex mutex_;                 // the worlds' turns and uses, the calls' checked flags
  std::condition_variable changed_;  // a turn passed, a use ended, a check ended, stop()
  std::atomic<bool> stopping_{false};
  TaskPool pool_;  // last: its threads end before the rest goes
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_WORLDS_H_
