// sim/src/bad_state.h — naming what MuJoCo found wrong in a state (private to libsimgate_sim).
//
// MuJoCo flags a NaN, an infinity or a magnitude beyond 1e10 in qpos, qvel or qacc with a
// warning (mjWARN_BADQPOS, BADQVEL, BADQACC) whose lastinfo is the address, and resets its
// data. The simulation's recovery (simulation.cc) and the trial a spawned fragment must
// pass (spawn.cc) say where, in these words. Pure functions; any thread.
#ifndef SIMGATE_SIM_SRC_BAD_STATE_H_
#define SIMGATE_SIM_SRC_BAD_STATE_H_

#include <string>

#include <mujoco/mujoco.h>

namespace simgate::sim {

// "joint 'knee'", or "joint 3" for an unnamed one.
inline std::string name_or_index(const mjModel* m, mjtObj type, int id, const char* kind) {
  const char* name = mj_id2name(m, type, id);
  return name && *name ? std::string(kind) + " '" + name + "'"
                       : std::string(kind) + " " + std::to_string(id);
}

// "joint 'robot_root' of body 'robot'" for a qpos address (qpos) or a dof (qvel, qacc).
inline std::string where_in_state(const mjModel* m, int warning, int index) {
  int joint = -1;
  if (warning == mjWARN_BADQPOS) {
    for (int j = 0; j < m->njnt; ++j)
      if (m->jnt_qposadr[j] <= index) joint = j;  // addresses grow with the joint index
  } else if (index >= 0 && index < m->nv) {
    joint = m->dof_jntid[index];
  }
  if (joint < 0 || joint >= m->njnt) return "an unknown joint";
  return name_or_index(m, mjOBJ_JOINT, joint, "joint") + " of " +
         name_or_index(m, mjOBJ_BODY, m->jnt_bodyid[joint], "body");
}

// Whether MuJoCo resets its data on this warning (a bad state, not a bad control).
inline bool resets_the_state(int warning) {
  return warning == mjWARN_BADQPOS || warning == mjWARN_BADQVEL || warning == mjWARN_BADQACC;
}

// The mjData array a state warning is about.
inline const char* state_array(int warning) {
  return warning == mjWARN_BADQPOS ? "qpos" : warning == mjWARN_BADQVEL ? "qvel" : "qacc";
}

// "qacc[12]"
inline std::string bad_quantity(int warning, int index) {
  return std::string(state_array(warning)) + "[" + std::to_string(index) + "]";
}

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_SRC_BAD_STATE_H_
