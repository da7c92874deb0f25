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

// The state an evaluation's position and velocity stages depend on (time, qpos, qvel, act,
// history, plastic and plugin state, mocap poses, eq_active), as one evaluation
// (Simulation::forward) saw it: while the state is still that one, those stages' results in
// mjData are still the state's, and an RK4 step from it need only evaluate the acceleration
// stage again (Simulation::take_mj_step). Controls and applied forces are not in it: only
// the acceleration stage reads them.
class EvaluatedState {
 public:
  // The state of `d` now (`generation`: Simulation::model_generation() of `m`).
  void capture(const mjModel* m, const mjData* d, std::uint64_t generation);
  // Whether `d`'s state is the one captured, bit for bit, of the same model.
  bool is_current(const mjModel* m, const mjData* d, std::uint64_t generation);

 private:
  static constexpr int k_signature =
      mjSTATE_FULLPHYSICS | mjSTATE_MOCAP_POS | mjSTATE_MOCAP_QUAT | mjSTATE_EQ_ACTIVE;
  const mjModel* model_ = nullptr;  // null: none captured
  std::uint64_t generation_ = 0;
  std::vector<mjtNum> values_;  // mj_getState(k_signature)
  std::vector<mjtNum> now_;     // is_current's, kept between calls (no allocation)
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_PHYSICS_STATE_H_
