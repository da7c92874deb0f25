// simgate/sim/model_remap.h — where every object of a model went in its recompiled successor.
//
// MuJoCo numbers bodies, joints, geoms, sites, cameras, lights, tendons, actuators, sensors
// and equalities in document order. Spawning appends (every id stays), but deleting a body
// of the scene removes its subtree, and everything that referred to it, from the middle:
// what came after it moves down. A ModelRemap says, per kind of object, where each object of
// the old model is in the new one (its new id), or that it was removed (-1). Survivors keep
// their relative order, so the remap is computed by walking both models in step, leaving
// out what the removal takes:
//  - the removed body's subtree (its bodies, and their joints, geoms, sites, cameras,
//    lights, mocap slots);
//  - then, until nothing more goes: tendons that wrap a removed joint, site or geom;
//    actuators whose transmission is a removed joint, tendon, site or body; sensors whose
//    object or reference frame is removed; equalities between removed objects.
// It is verified: every survivor that has a name has the same name in the new model, and
// the counts add up (the new model holds the survivors, then, for a spawn, the objects
// appended after them). A mismatch throws MujocoError saying what does not match: the
// caller then keeps the old model.
//
// qpos, qvel and sensordata addresses follow from the ids (the new model's jnt_qposadr,
// jnt_dofadr, sensor_adr): a component re-reads them from the new model.
//
// Threads: between() reads two models and nothing else; the simulation thread computes it
// when it swaps the new model in (Simulation::replace_model), under the simulation lock.
#ifndef SIMGATE_SIM_MODEL_REMAP_H_
#define SIMGATE_SIM_MODEL_REMAP_H_

#include <vector>

#include <mujoco/mujoco.h>

namespace simgate::sim {

struct ModelRemap {
  // old id -> new id, -1 when removed; one entry per object of the old model
  std::vector<int> body, joint, geom, site, camera, light, tendon, actuator, sensor, equality;

  // The remap from `from` to `to`, `to` being `from` recompiled without the subtree of
  // `removed_body` (-1: nothing removed) and with objects appended after the survivors
  // when `appended` (a spawn). Throws MujocoError when the models do not match so.
  static ModelRemap between(const mjModel* from, const mjModel* to, int removed_body,
                            bool appended);
  // Nothing moves: every id of `m` maps to itself.
  static ModelRemap identity(const mjModel* m);

  // The new id of an old one: -1 for -1 (none) and for a removed object.
  static int of(const std::vector<int>& ids, int old) {
    return old >= 0 && old < static_cast<int>(ids.size()) ? ids[old] : -1;
  }
  int body_of(int old) const { return of(body, old); }
  int joint_of(int old) const { return of(joint, old); }
  int geom_of(int old) const { return of(geom, old); }
  int site_of(int old) const { return of(site, old); }
  int tendon_of(int old) const { return of(tendon, old); }
  int actuator_of(int old) const { return of(actuator, old); }
  int sensor_of(int old) const { return of(sensor, old); }
  // Whether anything moved or went (false after a spawn: ids are kept).
  bool moves_ids() const;
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_MODEL_REMAP_H_
