// simgate/gateway/gateway.h — a running deployment: the simulation and its transports.
//
// Building a Gateway validates everything before anything starts: the deployment file
// (see deployment.h), the MJCF scene, every component (type, bodies, actuators, options)
// and every transport plugin (found, ABI-compatible, options known). In check mode it stops
// there; otherwise it creates each transport, shares the simulation's gate with it and
// registers the components mapped to it. start() opens the transports; run() is the
// simulation loop on the calling thread, until stop() or `simulation quit`; the destructor
// (or shutdown()) answers pending clients, stops the transports, destroys them and then
// the components.
//
// Threads: construct, start(), run() and shutdown() from one thread at a time (run() makes
// it the simulation thread); stop() from any thread (signal handlers use a thread).
#ifndef SIMGATE_GATEWAY_GATEWAY_H_
#define SIMGATE_GATEWAY_GATEWAY_H_

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "simgate/core/plugin_loader.h"
#include "simgate/gateway/deployment.h"
#include "simgate/sim/registry.h"
#include "simgate/sim/simulation.h"

namespace simgate::gateway {

struct GatewayOptions {
  bool check_only = false;                 // validate, create nothing that listens
  std::optional<double> realtime_factor;   // overrides the deployment's
  std::vector<std::string> plugin_dirs;    // searched before the defaults (after SIMGATE_PLUGIN_PATH)
};

class Gateway {
 public:
  // Throws ConfigError (path-precise) for every problem it finds.
  Gateway(const Deployment& deployment, const sim::ComponentRegistry& registry, GatewayOptions options = {});
  ~Gateway();
  Gateway(const Gateway&) = delete;
  Gateway& operator=(const Gateway&) = delete;

  // Starts every transport (no-op in check mode).
  void start();
  // transport name -> endpoints ("tcp://127.0.0.1:4000"), once started.
  std::map<std::string, std::vector<std::string>> endpoints() const;
  // transport name -> the components it serves.
  const std::map<std::string, std::vector<std::string>>& served() const { return served_; }

  // The simulation loop; returns after stop() or `simulation quit`.
  void run();
  // Any thread.
  void stop();
  // Answers pending requests, stops and destroys the transports, then the components.
  void shutdown();

  sim::Simulation& simulation() { return *simulation_; }
  const Deployment& deployment() const { return deployment_; }

 private:
  struct Transport {
    std::string name;                          // key in "transports"
    std::shared_ptr<TransportPlugin> plugin;   // keeps the library loaded
    std::shared_ptr<RequestManager> manager;   // null in check mode
  };

  void build_components(const sim::ComponentRegistry& registry);
  void load_transports();

  Deployment deployment_;                             // validated configuration
  GatewayOptions options_;                            // how it was built
  std::unique_ptr<sim::Simulation> simulation_;       // model, components, loop
  std::vector<Transport> transports_;                 // in name order
  std::map<std::string, std::vector<std::string>> served_;  // transport -> components
};

}  // namespace simgate::gateway

#endif  // SIMGATE_GATEWAY_GATEWAY_H_
