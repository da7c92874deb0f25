// Built by install_test.sh against an installed simgate with nothing but
// `pkg-config --cflags --libs simgate`: uses core, sim (and MuJoCo, Eigen through its
// headers) and clients, and prints where libsimgate_core looks for transport plugins.
#include <mujoco/mujoco.h>

#include <iostream>

#include <simgate/client/client.h>
#include <simgate/core/plugin_loader.h>
#include <simgate/sim/model.h>
#include <simgate/sim/registry.h>

int main() {
  for (const auto& dir : simgate::plugin_search_path()) std::cout << "plugin dir: " << dir << "\n";
  auto registry = simgate::sim::builtin_registry();
  std::cout << "robot types: " << registry.names(simgate::sim::Kind::robot).size() << "\n";
  std::cout << "mujoco: " << mj_version() << "\n";
  try {
    simgate::client::make_client("carrier-pigeon", simgate::json::object());
  } catch (const simgate::client::ClientError& e) {
    std::cout << "client: " << e.what() << "\n";
  }
  return 0;
}
