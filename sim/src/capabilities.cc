// `simulation get_capabilities`: which world-control features this simulator offers, named
// and numbered as ROS 2's simulation_interfaces (msg/SimulatorFeatures.msg) numbers them, so
// that a client written for that standard (or any client) can adapt before it calls.
//
// A feature is listed when the services that provide it are registered on `simulation`
// right now, and the caller's transport lets it call them: the answer is read off the
// component, never a list kept by hand beside it, so it cannot claim what is not there.
#include <string>
#include <vector>

#include "simgate/core/call_context.h"
#include "simgate/sim/world_services.h"

namespace simgate::sim {
namespace {

struct Feature {
  int id;                             // SimulatorFeatures.msg's constant
  const char* name;                   // and its name
  std::vector<const char*> services;  // of `simulation`, all needed
  const char* what;                   // for people
};

// The features simgate can provide, in SimulatorFeatures.msg's order. The world-control
// groups (world_services.h) provide the services; features of that message with no
// equivalent here (named poses, tags, categories, worlds) are not listed at all.
const std::vector<Feature>& features() {
  static const std::vector<Feature> all = {
      {0, "SPAWNING", {"spawn_entity"}, "spawn_entity: MJCF added to the running scene"},
      {1,
       "DELETING",
       {"delete_entity"},
       "delete_entity: an entity spawned at run time, a body of the scene or a robot removed"},
      {5,
       "ENTITY_BOUNDS",
       {"get_object_bbox", "get_object_global_bbox"},
       "axis-aligned bounding boxes of any body"},
      {9,
       "SPAWNING_RESOURCE_STRING",
       {"spawn_entity"},
       "spawn_entity takes MJCF or URDF text inline"},
      {10,
       "ENTITY_STATE_GETTING",
       {"get_entity_state"},
       "pose and twist of any body in the world frame"},
      {11, "ENTITY_STATE_SETTING", {"set_entity_state"}, "set pose and twist of any free body"},
      {12, "ENTITY_INFO_GETTING", {"list_entities"}, "list_entities with a name filter"},
      {20, "SIMULATION_RESET", {"reset"}, "reset with a scope"},
      {21, "SIMULATION_RESET_TIME", {"reset"}, "reset's scope 'all' sets simulated time back to 0"},
      {22,
       "SIMULATION_RESET_STATE",
       {"reset"},
       "reset's scopes 'state' and 'robot' restore state, time going on"},
      {24,
       "SIMULATION_STATE_GETTING",
       {"get_simulation_state"},
       "playing, paused, stepping or quitting, time, steps"},
      {25, "SIMULATION_STATE_SETTING", {"pause", "play", "quit"}, "pause, play, quit"},
      {26,
       "SIMULATION_STATE_PAUSE",
       {"pause"},
       "pause stops physics and time; requests are still served"},
      {31, "STEP_SIMULATION_SINGLE", {"step"}, "step: one physics step while paused"},
      {32, "STEP_SIMULATION_MULTIPLE", {"step"}, "step n: n physics steps while paused"},
      {33,
       "STEP_SIMULATION_ACTION",
       {"step"},
       "step is async: cancel or preemption stops it early"},
  };
  return all;
}

bool offers(const Component& simulation, const char* service) {
  for (const auto& s : simulation.services())
    if (s->descriptor().name == service) return caller_may_call(simulation.name(), service);
  return false;
}

}  // namespace

void add_capability_services(SupervisionServices& simulation, Simulation&) {
  const Component& self = simulation;
  simulation
      .offer_service(
          "get_capabilities",
          [&self]() {
            json listed = json::array();
            bool spawns = false;
            for (const Feature& f : features()) {
              bool all = true;
              for (const char* s : f.services) all = all && offers(self, s);
              if (!all) continue;
              spawns = spawns || f.id == 0;
              listed.push_back(
                  {{"id", f.id}, {"name", f.name}, {"services", f.services}, {"what", f.what}});
            }
            return json{{"features", std::move(listed)},
                        {"spawn_formats", spawns ? json::array({"mjcf", "urdf"}) : json::array()},
                        {"standard", "ROS 2 simulation_interfaces, msg/SimulatorFeatures.msg"}};
          })
      .doc(
          "The world-control features offered here, numbered and named as ROS 2's "
          "simulation_interfaces "
          "SimulatorFeatures: {features: [{id, name, services, what}], spawn_formats}");
}

}  // namespace simgate::sim
