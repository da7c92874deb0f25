// simgate/sim/world_services.h — the world-control services of the `simulation`
// component (issue #19), one group per source file, each registered on the component by
// its add_*_services function through SupervisionServices::offer_service,
// offer_async_service, on_step and on_interrupt.
//
// Groups and their files (docs/world/*.md describes each on the wire):
//   capabilities.cc  get_capabilities: the features the groups below offer, in ROS 2
//                    simulation_interfaces' numbering (read off the registered services)
//   stepping.cc      get_simulation_state, pause, play, step n, and the lockstep barrier's
//                    lockstep_join and lockstep_step (lockstep.cc, sim/src/stepping.h)
//                    (docs/world/stepping.md)
//   world_state.cc   reset scope robot, save_state, restore_state, list_states, drop_state
//                    (docs/world/state.md)
//   entities.cc      set_object_position, get_object_pose, get_object_bbox,
//                    get_object_global_bbox, set_object_dynamics, get_entity_state,
//                    set_entity_state, list_entities (docs/world/entities.md)
//   process_services.cc  terminate, set_log_level (docs/world/entities.md)
//   spawn.cc         spawn_entity, delete_entity (docs/world/spawn.md)
//   snapshot.cc      get_snapshot: a picture of the scene (docs/world/snapshot.md)
//   scene_geometry.cc  get_scene_geometry: bodies, geoms and meshes for a client that draws
//                    the scene itself; the body_poses samples of the `simulation` component's
//                    stream (docs/world/scene_geometry.md)
//
// Threads: simulation thread only, as every service.
#ifndef SIMGATE_SIM_WORLD_SERVICES_H_
#define SIMGATE_SIM_WORLD_SERVICES_H_

#include <functional>
#include <string>

#include "simgate/sim/simulation.h"
#include "simgate/sim/supervision.h"

namespace simgate::sim {

// Registers every group below on `simulation` (SupervisionServices' constructor).
void add_world_services(SupervisionServices& simulation, Simulation& sim);

void add_capability_services(SupervisionServices& simulation, Simulation& sim);
void add_stepping_services(SupervisionServices& simulation, Simulation& sim);
void add_state_services(SupervisionServices& simulation, Simulation& sim);
void add_entity_services(SupervisionServices& simulation, Simulation& sim);
void add_process_services(SupervisionServices& simulation, Simulation& sim);
void add_spawn_services(SupervisionServices& simulation, Simulation& sim);
void add_snapshot_services(SupervisionServices& simulation, Simulation& sim);
void add_scene_geometry_services(SupervisionServices& simulation, Simulation& sim);

// Puts the world back to an earlier state the way `simulation restore_state` does
// (world_state.cc), around `put_back` (which restores physics and returns the simulated time
// it went to): robots' running requests end PREEMPTED with `why` first; then every component
// gets on_reset(), the time component's sleeps end when the clock moved, and the clients that
// watch the world are told "restored" (`fields`). A served replay's seek back uses it too.
// Under the simulation lock.
void jump_back(Simulation& sim, const std::string& why, const std::function<double()>& put_back,
               json fields);

// The part of get_scene_geometry's answer that only changes with the model: the meshes'
// vertices and faces and the heightfields' elevations, which are most of it and slow to
// write. Built once per model (model_generation()) and copied into each answer after; the
// service owns one, so that a repeated call only writes the bodies and geoms under the
// simulation lock. Threads: as the service (simulation lock held).
class SceneGeometryCache {
 public:
  // {meshes: [...], hfields: [...]} of `sim`'s current model: the cached one while the model
  // is the one it was built from, else built now.
  const json& model_data(const Simulation& sim);
  // How many times model_data() has built it (for the tests).
  std::uint64_t builds() const { return builds_; }

 private:
  std::uint64_t generation_ = 0;    // the model_generation() it was built for
  const mjModel* model_ = nullptr;  // and the model (nullptr: nothing built yet)
  json data_;                       // {meshes, hfields}
  std::uint64_t builds_ = 0;        // see builds()
};

// get_scene_geometry's answer: {timestamp, generation, bodies, geoms, meshes, hfields}
// (meshes and hfields [] unless `include_meshes`). Poses are of state_time(), the time every
// sensor stamps. With a `cache`, the meshes and hfields come from it (the same answer).
json scene_geometry(const Simulation& sim, bool include_meshes,
                    SceneGeometryCache* cache = nullptr);
// One sample of the `simulation` component's body_poses stream: {timestamp, generation,
// poses: [[x, y, z, qw, qx, qy, qz] per body, in id order]} (world frame).
json body_poses(const Simulation& sim);

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_WORLD_SERVICES_H_
