// simgate/sim/physics_state.h — a copy of everything MuJoCo's next step reads.
//
// MuJoCo's own mjSTATE_INTEGRATION: time, qpos, qvel, act, ctrl, the solver's warm start,
// the applied forces (qfrc_applied, xfrc_applied), the mocap poses, userdata, eq_active, the
// plugins' state, the history buffers and the plastic state. Put back
// (Simulation::restore_physics) and stepped, it gives bit for bit what stepping from the
// moment it was captured gave. It belongs to the model it was captured from: fits() says
// whether it still does (the model generation and the sizes: a spawn or a delete since
// makes it unusable).
//
// The simulation's saved states (simulation save_state, world_state.cc) and its recovery
// from a diverging step (scene.on_divergence: the state before the step, or the last
// checkpoint) are such copies. capture() into a PhysicsState that already holds one of the
// same model reuses its memory: the simulation takes one before every step without
// allocating.
//
// Threads: whoever holds the simulation lock (it reads and writes mjData).
#ifndef SIMGATE_SIM_PHYSICS_STATE_H_
#define SIMGATE_SIM_PHYSICS_STATE_H_

#include <cstddef>
#include <cstdint>
#include <vector>

#include <mujoco/mujoco.h>

namespace simgate::sim {

class PhysicsState {
 public:
  // Copies `d`'s state; `generation`: Simulation::model_generation() of `m`.
  void capture(const mjModel* m, const mjData* d, std::uint64_t generation);
  // Whether a state was captured and fits `m` of `generation`.
  bool fits(const mjModel* m, std::uint64_t generation) const;
  // Writes the state into `d` (which it fits), time included. The computed quantities are
  // not updated: Simulation::restore_physics forwards, then puts the warm start back.
  void apply(const mjModel* m, mjData* d) const;
  // Puts the captured warm start back into `d` (mj_forward overwrites it).
  void apply_warmstart(const mjModel* m, mjData* d) const;

  double time() const { return time_; }
  std::uint64_t generation() const { return generation_; }

  // The captured arrays, as mj_getState(mjSTATE_INTEGRATION) writes them (empty before a
  // capture): what a recording stores of its initial state.
  const std::vector<mjtNum>& values() const { return values_; }
  // A state read back from such values (a recording's): it fits `m` of `generation` when
  // there are as many as `m`'s state has (fits() says).
  static PhysicsState from_values(std::vector<mjtNum> values, std::uint64_t generation);

 private:
  bool captured_ = false;
  std::uint64_t generation_ = 0;  // Simulation::model_generation() when captured
  double time_ = 0;               // simulated time
  std::vector<mjtNum> values_;    // the arrays, one after the other (physics_state.cc)
};

// What one evaluation (Simulation::forward) saw of a state, to tell how much of it is still
// current: the state its position and velocity stages depend on (time, qpos, qvel, act,
// history, plastic and plugin state, mocap poses, eq_active) and the inputs only its
// acceleration stage reads (controls, applied forces, user data, and the constraint solver's
// warm start). While both are the ones it saw, everything it computed in mjData is still the
// state's and an RK4 step from it need evaluate nothing again; while only the first is, the
// acceleration stage alone (Simulation::take_mj_step).
class EvaluatedState {
 public:
  enum class Current {
    nothing,    // the state changed (or another model): a whole evaluation
    positions,  // the position and velocity stages' results: the acceleration stage again
    all,        // the whole evaluation
  };
  // The state of `d` now (`generation`: Simulation::model_generation() of `m`).
  void capture(const mjModel* m, const mjData* d, std::uint64_t generation);
  // How much of the evaluation captured is still `d`'s, bit for bit, of the same model.
  Current current(const mjModel* m, const mjData* d, std::uint64_t generation);

 private:
  // The state's elements compared: the common ones where they are in mjData (time, qpos,
  // qvel, act, mocap poses; controls, applied forces, warm start), the others through
  // mj_getState (history, plastic and plugin state, eq_active; user data), since a copy
  // through mj_getState costs more than the comparison for a small model (a cartpole's
  // step is ~5 µs).
  static constexpr int k_through_get_state =
      mjSTATE_HISTORY | mjSTATE_PLASTIC | mjSTATE_PLUGIN | mjSTATE_EQ_ACTIVE | mjSTATE_USERDATA;
  static constexpr int k_inputs = mjSTATE_USERDATA;  // of k_through_get_state's
  // One element: where its values are in values_ (and for one read where it is, in mjData),
  // and whether it is an input.
  struct Element {
    mjtNum* mjData::* array = nullptr;  // null: one of mj_getState(k_through_get_state)'s
    std::size_t offset = 0, size = 0;
    bool input = false;
  };
  void lay_out(const mjModel* m);   // elements_ and values_'s size, for `m`
  const mjModel* model_ = nullptr;  // null: none captured
  std::uint64_t generation_ = 0;
  std::vector<Element> elements_;      // of model_ (non-empty ones)
  std::size_t through_get_state_ = 0;  // where mj_getState(k_through_get_state)'s values start
  std::vector<mjtNum> values_;         // d->time, then each element's values, at the capture
  std::vector<mjtNum> now_;            // current()'s, kept between calls (no allocation)
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_PHYSICS_STATE_H_
