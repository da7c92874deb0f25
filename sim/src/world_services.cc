#include "simgate/sim/world_services.h"

namespace simgate::sim {

void add_world_services(SupervisionServices& simulation, Simulation& sim) {
  (void)simulation;
  (void)sim;
}

}  // namespace simgate::sim
