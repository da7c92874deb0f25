#include "simgate/sim/world_services.h"

namespace simgate::sim {

void add_world_services(SupervisionServices& simulation, Simulation& sim) {
  // (get_capabilities reads the registered services when it is called)
  add_capability_services(simulation, sim);
  add_stepping_services(simulation, sim);
  add_state_services(simulation, sim);
  add_entity_services(simulation, sim);
  add_process_services(simulation, sim);
  add_spawn_services(simulation, sim);
  add_snapshot_services(simulation, sim);
  add_scene_geometry_services(simulation, sim);
}

}  // namespace simgate::sim
