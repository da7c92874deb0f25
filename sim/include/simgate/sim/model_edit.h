// simgate/sim/model_edit.h — a model edited at run time: an entity spawned into it, a body
// deleted from it, through MuJoCo's model specification (mjSpec).
//
// Every Model keeps the mjSpec it was compiled from (model.h). An edit copies it
// (mj_copySpec), changes the copy and compiles it into a new model:
//  - spawning parses the entity's MJCF (entity_mjcf: one body subtree with, optionally, the
//    assets, defaults, actuators, sensors, tendons, equalities and contact pairs it uses) into
//    a spec of its own and attaches its body to the world (mjs_attach), after everything the
//    world holds. MuJoCo numbers every object in tree and document order, so appending keeps
//    every existing id and address (bodies, joints, geoms, sites, actuators, sensors, qpos,
//    dofs...). The entity's defaults stay its own, and its file names (meshes, textures)
//    resolve as the scene's do: relative to the scene file's directory, meshdir and texturedir;
//  - deleting removes a body's subtree (mjs_delete), and MuJoCo removes with it what refers to
//    it (an actuator on one of its joints, a sensor of that actuator...) and shortens the
//    keyframes. Everything numbered after what was removed moves down: the simulation then
//    tells every component where its objects went (a ModelRemap, model_remap.h;
//    SimComponent::on_model_changed), and components re-resolve their ids.
// The scene file is never read again (a file changed since does not leak in) and nothing is
// written to disk.
//
// Life cycle of a change (spawn.cc): on the simulation thread, under the simulation lock,
// entity_mjcf() checks the fragment and EditBase::of() copies what the edit starts from; a
// worker thread edits and compiles (with_entity, without_body: slow, no simulation state
// touched); back on the simulation thread, the ModelRemap between the two models is computed,
// Simulation::replace_model() swaps them, carry_state() brings every surviving object's state
// across and the components re-resolve their ids.
//
// Threads: entity_mjcf(), with_entity() and without_body() touch no simulation state and may
// run on any thread (the spec they start from is shared read-only); carry_state() reads and
// writes the two models given (the caller holds the simulation lock for the running one).
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
  std::array<double, 3> position{0, 0, 0};           // metres
  std::optional<std::array<double, 4>> orientation;  // unit quaternion, MuJoCo order w x y z;
                                                     // none: the fragment's own orientation
};

// The MJCF document that spawns `fragment` as an entity called `name` at `pose`: a <mujoco>
// holding the fragment's sections, its top body renamed `name` and placed at `pose`.
// `fragment` is the MJCF of one <body>, or a <mujoco> whose <worldbody> holds exactly one
// <body> and whose other sections are among asset, default, actuator, sensor, tendon,
// equality, contact. Throws ServiceError (Failure::bad_arguments, {"parameter": "mjcf"})
// naming what is wrong: XML that does not parse, another root, another section, no or
// several bodies, an <include>, a file name that is absolute or climbs out with "..".
std::string entity_mjcf(const std::string& fragment, const std::string& name,
                        const EntityPose& pose);

// What spawns an entity: MJCF named and placed (entity_mjcf), or a URDF robot as written,
// whose root link becomes the entity's body (named and placed in the spec by with_entity).
struct EntityDocument {
  std::string text;
  bool urdf = false;
  EntityPose pose;  // URDF: where its root link goes
};

// The document that spawns `fragment` as entity `name` at `pose`: URDF when its root element
// is <robot> (checked as XML that parses), else entity_mjcf's. Throws ServiceError as
// entity_mjcf does.
EntityDocument entity_document(const std::string& fragment, const std::string& name,
                               const EntityPose& pose);

// What an edit starts from: the running model's spec, name and entities, copied under the
// simulation lock so that a worker edits without touching the running model.
struct EditBase {
  SharedSpec spec;                      // the running model's, shared read-only
  std::string source;                   // its file or inline name, for messages
  std::vector<SpawnedEntity> entities;  // spawned into it, in order
  ModelCounts counts;                   // its size: where a spawned entity's block starts

  static EditBase of(const Model& model);
};

// `base` with the entity `name` (`document`) attached to the world after everything it holds;
// the entity's counts measured. A URDF robot gets an actuator per transmission joint, as a
// URDF scene does (urdf.h). Throws MujocoError with MuJoCo's message when it does not parse
// or compile with the world (a joint name taken, a missing mesh), or a URDF that has not one
// root link. Any thread.
Model with_entity(const EditBase& base, const std::string& name, const EntityDocument& document);

// `base` without the body numbered `body` (named `name`: a spawned entity, or any body of the
// scene, in its file or in one it includes) and its subtree, and without what MuJoCo removes
// with them (what refers to them). Throws MujocoError when MuJoCo refuses. Any thread.
Model without_body(const EditBase& base, int body, const std::string& name);

// Copies into `to` the state of every object `from` also has, found through `remap`
// (model_remap.h): each object's part of the state (object_state.h: joint positions and
// velocities, actuator controls and activations, mocap poses, applied forces, the warm
// start, active equalities); and the clock and MuJoCo's warning counters. Objects only `to`
// has keep their initial state. The caller then runs mj_forward (Simulation::forward()).
void carry_state(const Model& from, Model& to, const ModelRemap& remap);

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_MODEL_EDIT_H_
