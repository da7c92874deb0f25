// simgate/sim/model_edit.h — a scene recompiled with entities spawned into it at run time.
//
// MuJoCo 2.2.2 has no model editing API: a changed world is a new model, compiled from the
// scene and the entities' MJCF. A spawned entity is one body subtree (with, optionally, the
// assets, defaults, actuators, sensors, tendons, equalities and contact pairs it uses),
// appended after everything the scene and the earlier entities hold. MuJoCo numbers every
// object in document order, so appending keeps every existing id and address (bodies,
// joints, geoms, sites, actuators, sensors, qpos, dofs...): components bound to the scene
// never notice. Deleting an entity recompiles without it; only the entities after it move.
//
// The recompiled model is a small wrapper, compiled through a MuJoCo virtual file system
// (nothing is written to disk):
//
//   <mujoco model="<scene's name>">
//     <include file="<scene's file name>"/>   (the scene's text as first read, in the VFS)
//     <worldbody><body name="crate" pos="1 2 0.5">...</body></worldbody>
//     <actuator>...</actuator>                  (each entity's sections, in spawn order)
//   </mujoco>
//
// loaded as if it sat beside the scene file: the scene's relative includes, meshes and
// textures resolve where they always did (read from disk there), and so do the relative
// file names of an entity's assets. A fragment may not name files outside them (absolute
// paths, "..") nor <include> anything.
//
// Life cycle of a change (spawn.cc): on the simulation thread, under the simulation lock,
// entity_sections() checks the fragment and the current model's entities are copied; a
// worker thread compiles (compile_scene: slow, no simulation state touched); back on the
// simulation thread, Simulation::replace_model() swaps the models and carry_state() brings
// every surviving object's state across.
//
// Threads: entity_sections() and compile_scene() touch no simulation state and may run on
// any thread; carry_state() reads and writes the two models given (the caller holds the
// simulation lock for the running one).
#ifndef SIMGATE_SIM_MODEL_EDIT_H_
#define SIMGATE_SIM_MODEL_EDIT_H_

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "simgate/sim/model.h"

namespace simgate::sim {

// Where a spawned entity's top body goes, in its parent's (the world's) frame.
struct EntityPose {
  std::array<double, 3> position{0, 0, 0};              // metres
  std::optional<std::array<double, 4>> orientation;     // unit quaternion, MuJoCo order w x y z;
                                                        // none: the fragment's own orientation
};

// The MJCF sections that spawn `fragment` as an entity called `name` at `pose`: its top
// body renamed `name` and placed at `pose`. `fragment` is the MJCF of one <body>, or a
// <mujoco> whose <worldbody> holds exactly one <body> and whose other sections are among
// asset, default, actuator, sensor, tendon, equality, contact. Throws ServiceError
// (Failure::bad_arguments, {"parameter": "mjcf"}) naming what is wrong: XML that does not
// parse, another root, another section, no or several bodies, an <include>, a file name
// that is absolute or climbs out with "..".
std::string entity_sections(const std::string& fragment, const std::string& name, const EntityPose& pose);

// Compiles `scene` with `entities`, in order. When `last_is_new`, the last entity's counts
// are measured (the compiled model's minus everything before it); the others' are kept.
// Throws MujocoError with MuJoCo's message when it does not compile. Any thread.
Model compile_scene(const std::shared_ptr<const SceneSource>& scene, std::vector<SpawnedEntity> entities,
                    bool last_is_new);

// Copies into `to` the state of every object `from` also has (the scene's, and each
// entity both hold, by name): joint positions and velocities, actuator controls and
// activations, mocap poses, applied forces, the warm start; and the clock and MuJoCo's
// warning counters. Objects only `to` has keep their initial state. The caller then runs
// mj_forward (Simulation::forward()).
void carry_state(const Model& from, Model& to);

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_MODEL_EDIT_H_
