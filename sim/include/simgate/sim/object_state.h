// simgate/sim/object_state.h — a model's state object by object, to put onto another model.
//
// PhysicsState (physics_state.h) copies mjData's state arrays whole: it fits the model it
// was taken from and no other. When the model changes (a spawn, a delete: model_edit.h), the
// state goes across object by object instead:
//  - each joint: its positions and velocities, the solver's warm start and the applied
//    forces of its degrees of freedom;
//  - each actuator: its control and activations (wherever the model keeps them:
//    actuator_actadr);
//  - each body: its applied force (xfrc_applied) and, for a mocap body, its pose;
//  - each equality: whether it is active.
// Where an object goes in the other model is a Mapping: through a ModelRemap (a swap: every
// survivor, named or not, carry_state in model_edit.h) or by name (by_name: a saved state put
// back after the model changed, world_state.cc). Each object is written only where the
// other model has one of the same kind and size (a hinge is not a ball joint).
//
// Names: an object is known by its own name; a joint without one by its body's and its place
// in that body ("crate/0"); an object with neither has no name and goes only through a remap.
//
// Threads: whoever holds the simulation lock for the model it reads or writes.
#ifndef SIMGATE_SIM_OBJECT_STATE_H_
#define SIMGATE_SIM_OBJECT_STATE_H_

#include <functional>
#include <string>
#include <vector>

#include <mujoco/mujoco.h>

#include "simgate/sim/model_remap.h"

namespace simgate::sim {

class ObjectState {
 public:
  // Where the captured object `id` of kind `type` (mjOBJ_JOINT, mjOBJ_ACTUATOR, mjOBJ_BODY,
  // mjOBJ_EQUALITY) is in the model written to; -1: nowhere. `name`: its name when captured
  // ("" when it had none).
  using Mapping = std::function<int(mjtObj type, int id, const std::string& name)>;

  // What put() did not write: the captured objects the other model does not have, and that
  // model's objects nothing was captured for (they keep their state), by kind, by name
  // (unnamed ones as MuJoCo would print them: "joint 3").
  struct Unmatched {
    std::vector<std::string> missing_bodies, missing_joints, missing_actuators;
    std::vector<std::string> kept_bodies, kept_joints, kept_actuators;
    bool empty() const;
  };

  // Copies each object's state from `d` (of `m`), with the objects' names.
  void capture(const mjModel* m, const mjData* d);
  // Writes each captured object's state into `d` (of `m`) where `to` puts it. The computed
  // quantities are not updated (the caller forwards, then put_warmstart()).
  Unmatched put(const mjModel* m, mjData* d, const Mapping& to) const;
  // The warm start alone (mj_forward overwrites it).
  void put_warmstart(const mjModel* m, mjData* d, const Mapping& to) const;

  // Mappings: through a remap (every object it keeps; `remap` must outlive the mapping), or
  // to the object of `m` with the same name (`m` must outlive it).
  static Mapping through(const ModelRemap& remap);
  static Mapping by_name(const mjModel* m);

 private:
  struct Joint {
    std::string name;  // its key (see above)
    int type = 0;      // mjtJoint
    std::vector<mjtNum> qpos, qvel, warmstart, qfrc_applied;
  };
  struct Actuator {
    std::string name;
    mjtNum ctrl = 0;
    std::vector<mjtNum> act;
  };
  struct Body {
    std::string name;
    mjtNum xfrc_applied[6] = {};
    bool mocap = false;
    mjtNum mocap_pos[3] = {}, mocap_quat[4] = {};
  };
  struct Equality {
    std::string name;
    mjtByte active = 0;
  };
  std::vector<Joint> joints_;
  std::vector<Actuator> actuators_;
  std::vector<Body> bodies_;
  std::vector<Equality> equalities_;
};

// A joint's key: its name, or its body's and its place in that body ("crate/0"), or "".
std::string joint_key(const mjModel* m, int joint);

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_OBJECT_STATE_H_
