// gateway_worlds.cc — the worlds after world 0 (issue #43, docs/worlds.md): built at start
// from the config's `worlds`, made and deleted at run time (`simulation create_world`,
// `delete_world`), listed (`list_worlds`), served through every transport under "w<k>/",
// each looping on a thread of its own.
//
// Locks: create_world and delete_world are world 0's services, so they run under world 0's
// lock, one at a time, never beside step_many (which locks the worlds it steps after world
// 0's). worlds_mutex_ guards the map for stop() and the loops' threads; it is never held
// while waiting for a world's lock or thread.
#include <limits>
#include <string>

#include "simgate/core/errors.h"
#include "simgate/core/log.h"
#include "simgate/core/simulation_gate.h"
#include "simgate/gateway/gateway.h"
#include "simgate/sim/supervision.h"

namespace simgate::gateway {

namespace {

std::string world_name(unsigned index) { return "w" + std::to_string(index); }

}  // namespace

void Gateway::build_worlds(ConfigErrors& errors) {
  for (unsigned k = 1; k < deployment_.worlds; ++k) {
    try {
      worlds_.emplace(k, make_world(k));
    } catch (const std::exception& e) {
      errors.add("worlds: world " + world_name(k) + ": " + e.what());
      return;
    }
  }
  next_world_ = deployment_.worlds;
  all_worlds_ = std::make_unique<sim::Worlds>(deployment_.world_threads);
  all_worlds_->add(0, *simulation_);
  for (auto& [index, world] : worlds_) all_worlds_->add(index, *world->sim);
  all_worlds_->add_to(supervision());
  supervision()
      .offer_service("create_world", [this] { return create_world(); })
      .not_replayed()
      .doc(
          "makes a world: the scene and the config's robots again, in a simulation of its own "
          "(paused or playing as the config starts worlds), served as w<k>/... through every "
          "transport; {world, name, count, max}; refused at the config's worlds.max");
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
          "every world: {worlds: [{world, name, state, sim_time, steps, actuators, "
          "memory_bytes}], count, max}");
  if (!worlds_.empty())
    log::info("worlds: ", worlds_.size() + 1, " (w0 and w1..w", worlds_.size(),
              ", each a simulation under its own lock; docs/worlds.md)");
}

std::unique_ptr<Gateway::World> Gateway::make_world(unsigned index) {
  auto world = std::make_unique<World>();
  world->index = index;
  try {
    world->sim =
        std::make_unique<sim::Simulation>(sim::Model::load_file(deployment_.mjcf), sim_options_);
  } catch (const std::exception& e) {
    throw std::runtime_error("the scene did not load again: " + std::string(e.what()));
  }
  // the robots as world 0 has them (their generic components found there already)
  ConfigErrors errors;
  for (const auto& r : deployment_.robots) build_robot(*world->sim, r, errors);
  if (!errors.errors().empty()) {
    std::string all;
    for (const std::string& e : errors.errors()) all += (all.empty() ? "" : "; ") + e;
    throw std::runtime_error(all);
  }
  add_world_components(*world->sim);
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
      log::error("world ", world_name(world.index), ": ", e.what());
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
  std::lock_guard lock(worlds_mutex_);
  for (auto& [index, world] : worlds_) world->sim->request_stop();
}

void Gateway::stop_worlds() {
  if (!simulation_) return;
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
  world.sim->shutdown();
}

json Gateway::create_world() {
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
    index = next_world_++;
  }
  std::unique_ptr<World> world;
  try {
    world = make_world(index);
  } catch (const std::exception& e) {
    throw ServiceError("simulation create_world: world " + world_name(index) + ": " + e.what());
  }
  serve_world(*world);
  all_worlds_->add(index, *world->sim);
  std::size_t count = 0;
  {
    std::lock_guard lock(worlds_mutex_);
    World& added = *worlds_.emplace(index, std::move(world)).first->second;
    if (world_loops_) start_loop(added);
    count = worlds_.size() + 1;
  }
  log::info("worlds: ", world_name(index), " made (", count, " worlds now)");
  return json{{"world", index},
              {"name", world_name(index)},
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
      std::string here = "w0";
      json names = json::array({"w0"});
      for (const auto& [k, w] : worlds_) {
        here += ", " + world_name(k);
        names.push_back(world_name(k));
      }
      throw ServiceError("simulation delete_world: no world " + std::to_string(index) +
                             " (the worlds here: " + here + ")",
                         Failure::bad_arguments, {{"parameter", "world"}, {"worlds", names}});
    }
    world = std::move(it->second);
    worlds_.erase(it);
    count = worlds_.size() + 1;
  }
  all_worlds_->remove(world->index);
  leave(*world);
  log::info("worlds: ", world_name(world->index), " deleted (", count,
            count == 1 ? " world left)" : " worlds left)");
  return json{{"world", world->index}, {"name", world_name(world->index)}, {"count", count}};
}

json Gateway::list_worlds() {
  json worlds = all_worlds_->describe();
  const std::size_t count = worlds.size();
  return json{{"worlds", std::move(worlds)}, {"count", count}, {"max", deployment_.max_worlds}};
}

}  // namespace simgate::gateway
