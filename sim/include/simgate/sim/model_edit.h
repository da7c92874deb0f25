// simgate/sim/model_edit.h — a scene recompiled with entities spawned into it at run time.
//
// MuJoCo 2.2.2 has no model editing API: a changed world is a new model, compiled from the
// scene and the entities' MJCF. A spawned entity is one body subtree (with, optionally, the
// assets, defaults, actuators, sensors, tendons, equalities and contact pairs it uses),
// appended after everything the scene and the earlier entities hold. MuJoCo numbers every
// object in document order, so appending keeps every existing id and address (bodies,
// joints, geoms, sites, actuators, sensors, qpos, dofs...). Deleting an entity recompiles
// without it, and deleting a body of the scene recompiles an edited copy of the scene's
// text (scene_without): everything numbered after what was removed moves down. The
// simulation then tells every component where its objects went (a ModelRemap,
// model_remap.h; SimComponent::on_model_changed), and components re-resolve their ids.
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
// entity_sections() checks the fragment (or scene_without() edits the scene's text) and the
// current model's entities are copied; a worker thread compiles (compile_scene: slow, no
// simulation state touched); back on the simulation thread, the ModelRemap between the two
// models is computed, Simulation::replace_model() swaps them, carry_state() brings every
// surviving object's state across and the components re-resolve their ids.
//
// Threads: entity_sections(), scene_without() and compile_scene() touch no simulation state
// and may run on any thread; carry_state() reads and writes the two models given (the caller holds the
// simulation lock for the running one).
#ifndef SIMGATE_SIM_MODEL_EDIT_H_
#define SIMGATE_SIM_MODEL_EDIT_H_

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "simgate/sim/model.h"
#include "simgate/sim/model_remap.h"

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

// The scene without its body `body` (named in the scene file's own text, anywhere in its
// <worldbody>): the body's subtree goes, and so does every element of the actuator, sensor,
// tendon, equality and contact sections that names one of its bodies, joints, geoms,
// sites, cameras or lights, or a tendon or actuator removed that way (a tendon that loses
// a joint goes, then the actuator on that tendon, then a sensor of that actuator). Counts
// are left to compile_scene (measure_scene). Throws ServiceError (Failure::bad_arguments,
// {"parameter": "name"}) when the body is not in the scene file's text (only in a file it
// includes, or unnamed), or when the scene has keyframes (sized to the whole model). Any
// thread.
std::shared_ptr<SceneSource> scene_without(const SceneSource& scene, const std::string& body);

// Compiles `scene` with `entities`, in order. A scene whose keyframes give arrays (MuJoCo
// 2.2.2 wants them sized to the whole model) is compiled once without them, then with each
// key padded with the entities' initial state (qpos0, zero velocities, activations and
// controls, the mocap bodies' poses). When `last_is_new`, the last entity's counts
// are measured (the compiled model's minus everything before it); the others' are kept.
// `measure_scene` (the same object as `scene`, freshly edited and not yet shared): its
// counts are measured too (the compiled model's minus the entities'). Throws MujocoError
// with MuJoCo's message when it does not compile. Any thread.
Model compile_scene(const std::shared_ptr<const SceneSource>& scene, std::vector<SpawnedEntity> entities,
                    bool last_is_new, SceneSource* measure_scene = nullptr);

// Copies into `to` the state of every object `from` also has, found through `remap`
// (model_remap.h): joint positions and velocities, actuator controls and activations,
// mocap poses, applied forces, the warm start; and the clock and MuJoCo's warning
// counters. Objects only `to` has keep their initial state. The caller then runs
// mj_forward (Simulation::forward()).
void carry_state(const Model& from, Model& to, const ModelRemap& remap);

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_MODEL_EDIT_H_
