// gateway_worlds.cc — the worlds after world 0 (issue #43, docs/worlds.md): built at start
// from the config's `worlds`, made and deleted at run time (`simulation create_world`,
// `delete_world`), listed (`list_worlds`), served through every transport under "w<k>/",
// each looping on a thread of its own.
//
// Locks: create_world and delete_world are world 0's services, so they run under world 0's
// lock, one at a time, never beside step_many (which locks the worlds it steps after world
// 0's). worlds_mutex_ guards the map for stop() and the loops' threads; it is never held
// while waiting for a world's lock or thread.
#include <cstdint>
#include <limits>
#include <string>

#include "simgate/core/config.h"
#include "simgate/core/errors.h"
#include "simgate/core/log.h"
#include "simgate/core/simulation_gate.h"
#include "simgate/core/text.h"
#include "simgate/gateway/gateway.h"
#include "simgate/sim/allowed_files.h"
#include "simgate/sim/supervision.h"

namespace simgate::gateway {

namespace {

// "14.9 MB"
std::string megabytes(std::uint64_t bytes) {
  const std::uint64_t tenths = (bytes + 50'000) / 100'000;
  return std::to_string(tenths / 10) + "." + std::to_string(tenths % 10) + " MB";
}

}  // namespace

void Gateway::build_worlds(ConfigErrors& errors) {
  const std::size_t errors_before = errors.errors().size();
  for (unsigned k = 1; k < deployment_.worlds; ++k) {
    const auto given = deployment_.world_scenes.find(k);
    const std::string scene = given == deployment_.world_scenes.end() ? "" : given->second;
    try {
      auto world = make_world(k, scene);
      world->scene = scene;
      worlds_.emplace(k, std::move(world));
    } catch (const std::exception& e) {
      if (scene.empty()) {
        errors.add("worlds: world " + RequestManager::world_name(k) + ": " + e.what());
        return;  // the config's scene: every world after would say the same
      }
      errors.add("worlds.scenes." + std::to_string(k) + ": expected a scene world " +
                 RequestManager::world_name(k) +
                 " can be built from with the config's robots, found '" + scene + "': " + e.what());
    }
  }
  if (errors.errors().size() > errors_before) return;
  next_world_ = deployment_.worlds;
  all_worlds_ = std::make_unique<sim::Worlds>(deployment_.world_threads);
  all_worlds_->add(0, *simulation_);
  for (auto& [index, world] : worlds_) all_worlds_->add(index, *world->sim);
  if (const std::uint64_t max = deployment_.max_world_memory_bytes) {
    const std::uint64_t total = all_worlds_->memory_bytes();  // nothing runs yet
    if (total > max)
      errors.add("worlds.max_memory_mb: the " + std::to_string(deployment_.worlds) +
                 " worlds at start hold " + megabytes(total) + " (MuJoCo's model and data), more " +
                 "than the " + megabytes(max) + " allowed");
  }
  all_worlds_->add_to(supervision());
  supervision()
      .offer_service("create_world", [this](json scene) { return create_world(scene); },
                     {Param("scene", nullptr)})
      .not_replayed()
      .doc(
          "makes a world: the scene (or `scene`, an MJCF file under the config's "
          "spawn.allowed_dirs) and the config's robots, in a simulation of its own (paused or "
          "playing as the config starts worlds), served as w<k>/... through every transport; "
          "{world, name, count, max}; refused at the config's worlds.max or max_memory_mb");
  supervision()
      .offer_service("delete_world", [this](std::int64_t world) { return delete_world(world); },
                     {"world"})
      .not_replayed()
      .doc(
          "deletes world k (not world 0): its calls are answered FAILED (shutdown), its "
          "services leave every listing; {world, name, count}");
  supervision()
      .offer_service("list_worlds", [this] { return list_worlds(); })
      .doc(
          "every world: {worlds: [{world, name, scene, state, sim_time, steps, actuators, "
          "memory_bytes}], count, max, memory_bytes, max_memory_bytes}");
  if (!worlds_.empty())
    log::info("worlds: ", worlds_.size() + 1, " (w0 and w1..w", worlds_.size(),
              ", each a simulation under its own lock; docs/worlds.md)");
  for (const auto& [index, scene] : deployment_.world_scenes)
    log::info("worlds: ", RequestManager::world_name(index), " runs scene ", scene);
}

std::unique_ptr<Gateway::World> Gateway::make_world(unsigned index, const std::string& scene) {
  auto world = std::make_unique<World>();
  world->index = index;
  try {
    world->sim = std::make_unique<sim::Simulation>(
        sim::Model::load_file(scene.empty() ? deployment_.mjcf : scene), sim_options_);
  } catch (const std::exception& e) {
    throw std::runtime_error(
        (scene.empty() ? "the scene did not load again: " : "the scene did not load: ") +
        std::string(e.what()));
  }
  // the robots as world 0 has them (their generic components found there already)
  ConfigErrors errors;
  for (const auto& r : deployment_.robots) build_robot(*world->sim, r, errors);
  if (errors.errors().empty()) {
    add_world_components(*world->sim);
    add_streams(*world->sim, errors);  // the config's "streams", as world 0 has them
  }
  if (!errors.errors().empty()) {
    std::string all;
    for (const std::string& e : errors.errors()) all += (all.empty() ? "" : "; ") + e;
    throw std::runtime_error(all);
  }
  world->sim->set_robot_factory(robot_factory(*world->sim, world.get()));
  return world;
}

void Gateway::serve_world(World& world) {
  world.managers.resize(transports_.size());
  for (std::size_t i = 0; i < transports_.size(); ++i) {
    Transport& t = transports_[i];
    if (!t.manager) continue;
    // its gate and components before any call can reach it
    world.managers[i] =
        t.manager->attach_world(world.index, [&](const std::shared_ptr<RequestManager>& manager) {
          for (const auto& name : served_[t.name])
            if (sim::ComponentEntry* entry = world.sim->find(name)) serve_on(t, *entry, *manager);
          world.sim->add_request_manager(manager, t.name);
        });
  }
}

void Gateway::start_loop(World& world) {
  world.loop = std::thread([this, &world] {
    try {
      world.sim->run();
    } catch (const std::exception& e) {
      log::error("world ", RequestManager::world_name(world.index), ": ", e.what());
    }
    if (!world.leaving.load(std::memory_order_acquire)) stop();
  });
}

void Gateway::start_world_loops() {
  std::lock_guard lock(worlds_mutex_);
  world_loops_ = true;
  for (auto& [index, world] : worlds_) start_loop(*world);
}

void Gateway::stop() {
  if (simulation_) simulation_->request_stop();
  // a step_many under way stops at its next step: it may hold a world's lock for long
  if (all_worlds_) all_worlds_->request_stop();
  std::lock_guard lock(worlds_mutex_);
  for (auto& [index, world] : worlds_) world->sim->request_stop();
}

void Gateway::stop_worlds() {
  if (!simulation_) return;
  // no step_many steps a world any more (those under way stop at their next step): a world's
  // loop may wait for its lock
  all_worlds_->stop();
  {
    // under world 0's lock: no create_world or delete_world is half done
    std::lock_guard gate(*simulation_->gate());
    std::lock_guard lock(worlds_mutex_);
    worlds_closed_ = true;
  }
  // the map changes no more
  for (auto& [index, world] : worlds_) world->sim->request_stop();
  for (auto& [index, world] : worlds_)
    if (world->loop.joinable()) world->loop.join();
}

void Gateway::leave(World& world) {
  for (auto& t : transports_)
    if (t.manager) t.manager->detach_world(world.index);
  world.leaving.store(true, std::memory_order_release);
  world.sim->request_stop();
  if (world.loop.joinable()) world.loop.join();
  {
    // its subscribers hear their streams end (a transport closes them as a component's)
    std::lock_guard lock(*world.sim->gate());
    world.sim->streams().remove_all();
  }
  world.sim->shutdown();
}

std::string Gateway::scene_file(const json& scene) const {
  if (scene.is_null()) return "";
  const auto refuse = [](const std::string& message) {
    throw ServiceError("simulation create_world: scene: " + message, Failure::bad_arguments,
                       {{"parameter", "scene"}});
  };
  const std::vector<std::string>& allowed = deployment_.spawn_allowed_dirs;
  if (!scene.is_string())
    refuse("expected an MJCF file name (or null: the config's scene), found " +
           describe_json(scene));
  if (allowed.empty())
    refuse(
        "scene files need directories allowed in the config (spawn.allowed_dirs), and it "
        "allows none");
  const std::string& name = scene.get_ref<const std::string&>();
  const auto file = sim::find_allowed_file(allowed, name);
  if (!file) {
    std::string dirs;
    for (const auto& dir : allowed) dirs += (dirs.empty() ? "" : ", ") + dir;
    refuse("'" + name + "' is no file under the directories the config allows " +
           "(spawn.allowed_dirs: " + dirs + ")");
  }
  return file->string();
}

json Gateway::create_world(const json& scene) {
  const std::string mjcf = scene_file(scene);
  unsigned index = 0;
  {
    std::lock_guard lock(worlds_mutex_);
    if (worlds_closed_) throw ServiceError("simulation create_world: simgate is stopping");
    const std::size_t count = worlds_.size() + 1;
    if (count >= deployment_.max_worlds)
      throw ServiceError("simulation create_world: " + std::to_string(count) +
                             " worlds run, the most this simgate allows (the config's "
                             "\"worlds\": {\"max\": " +
                             std::to_string(deployment_.max_worlds) +
                             "}): delete one first (simulation delete_world)",
                         Failure::service_error,
                         {{"count", count}, {"max", deployment_.max_worlds}});
    index = next_world_;  // taken once the world is made (create_world runs one at a time)
  }
  std::unique_ptr<World> world;
  try {
    world = make_world(index, mjcf);
    world->scene = mjcf.empty() ? "" : scene.get<std::string>();  // as the client named it
  } catch (const std::exception& e) {
    // the client's scene, or the config's that loaded at start
    throw ServiceError(
        "simulation create_world: world " + RequestManager::world_name(index) + ": " + e.what(),
        mjcf.empty() ? Failure::service_error : Failure::bad_arguments,
        mjcf.empty() ? json::object() : json{{"parameter", "scene"}});
  }
  // the memory bound, before any client can reach it (never served, it goes quietly)
  if (const std::uint64_t max = deployment_.max_world_memory_bytes) {
    const std::uint64_t used = all_worlds_->memory_bytes();
    const std::uint64_t needed = world->sim->memory_bytes();
    if (used + needed > max)
      throw ServiceError(
          "simulation create_world: a world of this scene holds " + megabytes(needed) +
              " and the worlds hold " + megabytes(used) + " of the " + megabytes(max) +
              " the config allows (\"worlds\": {\"max_memory_mb\"}): delete one "
              "first (simulation delete_world)",
          Failure::service_error,
          {{"memory_bytes", used}, {"world_memory_bytes", needed}, {"max_memory_bytes", max}});
  }
  serve_world(*world);
  all_worlds_->add(index, *world->sim);
  std::size_t count = 0;
  {
    std::lock_guard lock(worlds_mutex_);
    World& added = *worlds_.emplace(index, std::move(world)).first->second;
    next_world_ = index + 1;
    if (world_loops_) start_loop(added);
    count = worlds_.size() + 1;
  }
  log::info("worlds: ", RequestManager::world_name(index), " made (", count, " worlds now)");
  return json{{"world", index},
              {"name", RequestManager::world_name(index)},
              {"count", count},
              {"max", deployment_.max_worlds}};
}

json Gateway::delete_world(std::int64_t index) {
  std::unique_ptr<World> world;
  std::size_t count = 0;
  {
    std::lock_guard lock(worlds_mutex_);
    if (worlds_closed_) throw ServiceError("simulation delete_world: simgate is stopping");
    if (index == 0)
      throw ServiceError(
          "simulation delete_world: world 0 is the simulation itself: it cannot "
          "be deleted (simulation quit ends simgate)",
          Failure::bad_arguments, {{"parameter", "world"}});
    const auto it = index > 0 && index <= std::numeric_limits<unsigned>::max()
                        ? worlds_.find(static_cast<unsigned>(index))
                        : worlds_.end();
    if (it == worlds_.end()) {
      std::vector<std::string> names{"w0"};
      for (const auto& [k, w] : worlds_) names.push_back(RequestManager::world_name(k));
      throw ServiceError("simulation delete_world: no world " + std::to_string(index) +
                             " (the worlds here: " + join(names) + ")",
                         Failure::bad_arguments, {{"parameter", "world"}, {"worlds", names}});
    }
    world = std::move(it->second);
    worlds_.erase(it);
    count = worlds_.size() + 1;
  }
  all_worlds_->remove(world->index);
  leave(*world);
  log::info("worlds: ", RequestManager::world_name(world->index), " deleted (", count,
            count == 1 ? " world left)" : " worlds left)");
  return json{{"world", world->index},
              {"name", RequestManager::world_name(world->index)},
              {"count", count}};
}

json Gateway::list_worlds() {
  json worlds = all_worlds_->describe();
  const std::size_t count = worlds.size();
  std::uint64_t memory = 0;
  for (json& w : worlds) {
    memory += w["memory_bytes"].get<std::uint64_t>();
    // the scene the config's worlds.scenes or create_world gave (null: the config's); the map
    // changes under world 0's lock only, which this service holds
    const auto it = worlds_.find(w["world"].get<unsigned>());
    w["scene"] =
        it == worlds_.end() || it->second->scene.empty() ? json() : json(it->second->scene);
  }
  const std::uint64_t max_memory = deployment_.max_world_memory_bytes;
  return json{{"worlds", std::move(worlds)},
              {"count", count},
              {"max", deployment_.max_worlds},
              {"memory_bytes", memory},
              {"max_memory_bytes", max_memory ? json(max_memory) : json()}};
}

}  // namespace simgate::gateway
