// simgate/gateway/gateway.h — a running deployment: the simulation and its transports.
//
// Building a Gateway validates everything before anything starts: the deployment file
// (see deployment.h), the MJCF scene, every component (type, bodies, actuators, options)
// and every transport plugin (found, ABI-compatible, options valid: the plugin's own
// validate()), then the TCP transports together (no two on one port, addresses of this
// machine: src/listeners.h); all errors at once. In check mode it stops there; otherwise it creates
// each transport, gives it its allow and deny lists (RequestManager::set_access), shares the
// simulation's gate with it and registers the components mapped to it. start() opens the
// transports; run() is the simulation loop on the calling thread, until stop() or `simulation
// quit`; the destructor (or shutdown()) answers pending clients, stops the transports, destroys
// them and then the components.
//
// Threads: construct, start(), run() and shutdown() from one thread at a time (run() makes
// it the simulation thread); stop() from any thread (signal handlers use a thread).
#ifndef SIMGATE_GATEWAY_GATEWAY_H_
#define SIMGATE_GATEWAY_GATEWAY_H_

#include <atomic>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "simgate/core/plugin_loader.h"
#include "simgate/gateway/deployment.h"
#include "simgate/recorder/recording_services.h"
#include "simgate/sim/registry.h"
#include "simgate/sim/simulation.h"
#include "simgate/sim/supervision.h"
#include "simgate/sim/worlds.h"

namespace simgate::gateway {

struct GatewayOptions {
  bool check_only = false;                // validate, create nothing that listens
  std::optional<double> realtime_factor;  // overrides the deployment's
  std::vector<std::string> plugin_dirs;  // searched before the defaults (after SIMGATE_PLUGIN_PATH)
  // Where clients' recordings go (simulation start_recording; recording_services.h); "":
  // clients may not record.
  std::string record_dir{};
  // Called once the simulation and its components exist, before any transport registers their
  // services (not called without a scene): `simgate replay` builds its replayer there, which
  // offers the `simulation` services of a served replay.
  std::function<void(sim::Simulation&, sim::SupervisionServices&)> on_simulation_built{};
};

class Gateway {
 public:
  // Throws one ConfigError carrying every problem it finds (each path-precise), or a
  // TransportError when a transport with valid options cannot start (a port in use).
  // `registry`: the component types (the built-ins); the deployment's component libraries
  // are added to the gateway's own copy of it. `earlier`: the errors of the deployment's
  // structure (parse_deployment's recording form), reported first with the gateway's own;
  // with any, nothing is created. Without a scene (`mjcf` empty or not loadable) only the
  // components' types are checked: their bodies and options need it.
  Gateway(const Deployment& deployment, const sim::ComponentRegistry& registry,
          GatewayOptions options = {}, ConfigErrors earlier = {});
  ~Gateway();
  Gateway(const Gateway&) = delete;
  Gateway& operator=(const Gateway&) = delete;

  // Starts every transport (no-op in check mode).
  void start();
  // transport name -> endpoints ("tcp://127.0.0.1:4000"), once started.
  std::map<std::string, std::vector<std::string>> endpoints() const;
  // transport name -> the components it serves.
  const std::map<std::string, std::vector<std::string>>& served() const { return served_; }
  // Likely mistakes that are not errors (the deployment's, then the mapping's: a component
  // no transport serves that clients need). `simgate check` prints them, `run` logs them.
  const std::vector<std::string>& warnings() const { return warnings_; }

  // The simulation loop; returns after stop() or `simulation quit`.
  void run();
  // Any thread.
  void stop();
  // Answers pending requests, stops and destroys the transports, then the components.
  void shutdown();

  // Records the run to `path` (an MCAP file, recorder.h) from now on: before run(), from its
  // first step (`simgate run --record`). Throws std::runtime_error when the file cannot be
  // created. Not in check mode.
  void start_recording(const std::string& path);

  sim::Simulation& simulation() { return *simulation_; }
  const Deployment& deployment() const { return deployment_; }

 private:
  struct Transport {
    std::string name;                         // key in "transports"
    const TransportConfig* config = nullptr;  // its entry in deployment_
    std::shared_ptr<TransportPlugin> plugin;  // keeps the library loaded
    std::shared_ptr<RequestManager> manager;  // null in check mode
  };
  // A world after world 0 (docs/worlds.md). Its fields are set before it is in worlds_ and
  // stay until it is destroyed.
  struct World {
    unsigned index = 0;  // k of "w<k>/"
    // its MJCF file as create_world was given it, or as the config's worlds.scenes resolves
    // it ("": the config's scene)
    std::string scene;
    std::unique_ptr<sim::Simulation> sim;  // its model, components, loop
    // the manager serving it through each transport (RequestManager::attach_world), in
    // transports_'s order (null for a transport without a manager)
    std::vector<std::shared_ptr<RequestManager>> managers;
    std::thread loop;                  // its loop, once the worlds run
    std::atomic<bool> leaving{false};  // deleted: its loop's end stops nothing else
  };

  // Loads the deployment's component libraries into registry_ (recording errors).
  void load_component_libraries(ConfigErrors& errors);
  // The directories plugins and component libraries are searched in (after
  // SIMGATE_PLUGIN_PATH): --plugin-path, then the config's directory.
  std::vector<std::string> plugin_dirs() const;
  // A robot of type "mjcf" gets the generic components its subtree has (model_robots.h),
  // unless the config names a component so already.
  void add_generic_components(sim::Simulation& world, RobotConfig& r);
  // Each records its errors and goes on with the next robot, component or transport.
  void build_components(ConfigErrors& errors);
  // Creates robot `r` and its components in the simulation (recording errors; a robot that
  // cannot be made skips its components); returns the names of those made.
  std::vector<std::string> build_robot(sim::Simulation& world, const RobotConfig& r,
                                       ConfigErrors& errors);
  // ---- worlds (gateway_worlds.cc)
  // The worlds after world 0 (deployment_.worlds), and what acts on several (step_many,
  // create_world, delete_world, list_worlds on world 0's `simulation`).
  void build_worlds(ConfigErrors& errors);
  // World `index`: the scene (the config's, or the MJCF file `scene`), the config's robots
  // and the pseudo-components, in a simulation of its own. Throws std::runtime_error saying
  // what did not build.
  std::unique_ptr<World> make_world(unsigned index, const std::string& scene = "");
  // Serves `world` through every transport under "w<index>/" (its components as the
  // config's mapping says of their names).
  void serve_world(World& world);
  // Starts `world`'s loop on a thread of its own; its end (quit, an error) stops every world
  // unless the world is leaving.
  void start_loop(World& world);
  // run(): every world's loop from now on (worlds_mutex_ taken).
  void start_world_loops();
  // No call reaches `world` any more (every transport detaches it), its loop has ended, it
  // answers what it holds (Failure::shutdown) and destroys its components.
  void leave(World& world);
  // The services (under world 0's lock).
  json create_world(const json& scene);
  // create_world's `scene`: the MJCF file it names under the config's spawn.allowed_dirs
  // (allowed_files.h), or "" for null (the config's scene). Throws ServiceError
  // (bad_arguments, parameter "scene") otherwise.
  std::string scene_file(const json& scene) const;
  json delete_world(std::int64_t index);
  json list_worlds();
  // A world's RobotFactory (gateway.cc): robots spawned at run time into `sim`, the
  // simulation of `world` (null: world 0).
  class SpawnedRobots;
  std::shared_ptr<sim::Simulation::RobotFactory> robot_factory(sim::Simulation& sim, World* world);
  // A robot spawned at run time in `sim`, world `world`'s simulation (null: world 0;
  // checked by SpawnedRobots): built, its streams added (world 0) and its components served
  // as the config's mapping says of their names; under that world's lock. Throws
  // ServiceError (parameter "robot") having added nothing when it cannot be built.
  void add_spawned_robot(sim::Simulation& sim, World* world, RobotConfig r);
  // Without a scene: that each robot's and component's type is one of the registry's.
  void check_component_types(ConfigErrors& errors) const;
  // The data streams the "streams" section asks for of the components of `sim` (world 0's
  // or another world's): a component named there that has none is an error; a frequency on
  // one without an output stream a warning.
  void add_streams(sim::Simulation& sim, ConfigErrors& errors);
  // The stream of `component` of `sim`, if the "streams" section maps it; `frequency`: the
  // rate the configuration gives (the rule's, else the component's own), `fallback` without
  // one.
  void add_stream(sim::Simulation& sim, const Component& component, const std::string& type,
                  std::optional<double> frequency, double fallback, ConfigErrors& errors);
  // Of `transports`, those that may carry `component`'s stream: their allow/deny lists let
  // through every service of the component (an input stream) or its get_local_data (an
  // output stream); each other one is a warning.
  std::vector<std::string> carriers(const sim::Simulation& sim, const Component& component,
                                    const std::vector<std::string>& transports);
  // A warning of the config, kept (warnings()) when building world 0: the other worlds
  // build the same config again.
  void config_warning(const sim::Simulation& sim, std::string warning);
  // The stream rate the configuration gives component `c`: its "streams" rule's frequency,
  // else its own "frequency"; none when neither says.
  std::optional<double> stream_frequency(const ComponentConfig& c) const;
  void load_plugins(ConfigErrors& errors);
  // simulation start_recording, stop_recording, get_recording_status (recording_services.h)
  void add_recording_services();
  sim::SupervisionServices& supervision();  // the `simulation` component
  // Adds warnings for components clients need that no transport serves, and those of
  // warn_about_access_lists().
  void warn_about_mapping();
  // Adds a warning for every allow or deny pattern that matches no service its transport
  // serves (a typo in a deny list would leave the service it meant callable).
  void warn_about_access_lists();
  // Creates every transport (binding its sockets) and registers its components.
  void create_transports();
  // Stops the loops of the worlds after world 0 and waits for their threads; no world is
  // made or deleted after it.
  void stop_worlds();
  // Serves `entry`'s component on `transport` through `manager` (the transport's own for
  // world 0, the world's for another); its interfaces name the transport.
  void serve_on(Transport& transport, sim::ComponentEntry& entry, RequestManager& manager);

  Deployment deployment_;   // validated configuration
  GatewayOptions options_;  // how it was built
  // the types components are created from, and the libraries whose code they run: it must
  // outlive simulation_ (declared first, destroyed last)
  sim::ComponentRegistry registry_;
  // every world, for the services acting on several (simulation step_many); with a scene
  std::unique_ptr<sim::Worlds> all_worlds_;
  std::unique_ptr<sim::Simulation> simulation_;  // model, components, loop (world 0)
  sim::SimulationOptions sim_options_;           // every world's
  // the worlds after world 0 by index (docs/worlds.md); made and deleted under world 0's
  // lock. worlds_mutex_ guards the map and the two flags (others read it under world 0's
  // lock, or after stop_worlds()).
  std::map<unsigned, std::unique_ptr<World>> worlds_;
  std::mutex worlds_mutex_;
  unsigned next_world_ = 1;     // the index the next world gets (an index is never reused)
  bool world_loops_ = false;    // run() started the worlds' loops
  bool worlds_closed_ = false;  // stop_worlds() ran: no world is made or deleted any more
  // simulation start_recording and its kin; a recording ends before the simulation does
  std::shared_ptr<recorder::RecordingServices> recording_;
  std::vector<Transport> transports_;                       // in name order
  std::map<std::string, std::vector<std::string>> served_;  // transport -> components
  std::vector<std::string> warnings_;                       // see warnings()
};

}  // namespace simgate::gateway

#endif  // SIMGATE_GATEWAY_GATEWAY_H_
