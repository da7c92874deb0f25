// The spawn group of the `simulation` component (docs/world/spawn.md): spawn_entity and
// delete_entity change the world's model at run time. delete_entity removes an entity
// spawned at run time, or a body of the scene no component is bound to or part of; the swap
// then remaps every component's MuJoCo ids (model_remap.h).
//
// Each change edits a copy of the model's specification and compiles it (model_edit.h).
// Compiling takes milliseconds to seconds, far more than a step: it happens on a worker
// thread, off the simulation lock, from copies made under it (a fragment file too is read
// there: under the lock it is only found); once the worker is done it asks the simulation for its
// next turn (Simulation::run_soon: between two steps, or at once while paused), which swaps the new
// model in (Simulation::replace_model carries the state across) and only then completes the
// request. Both services are concurrent async services: neither takes the component's one
// async slot from the other world-control services, and they keep their own rule of one
// change at a time (a second one while one compiles FAILS, naming the one compiling).
#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <memory>
#include <optional>
#include <set>
#include <sstream>

#include "simgate/core/call_context.h"
#include "simgate/core/errors.h"
#include "simgate/core/log.h"
#include "simgate/sim/allowed_files.h"
#include "simgate/sim/bounds.h"
#include "simgate/sim/model_edit.h"
#include "simgate/sim/model_remap.h"
#include "simgate/sim/sim_component.h"
#include "simgate/sim/world_services.h"
#include "bad_state.h"
#include "helpers.h"

namespace simgate::sim {

namespace {

namespace fs = std::filesystem;

// A fragment file larger than this is refused unread (an MJCF body is kilobytes).
constexpr std::uintmax_t k_max_fragment_bytes = 1 << 20;

// What one fragment may add: far more than a robot has (the humanoid: 17 bodies, 21
// joints, 20 geoms), far less than what would slow every step of everyone for good.
constexpr int k_max_fragment_bodies = 1000;
constexpr int k_max_fragment_joints = 1000;
constexpr int k_max_fragment_geoms = 10000;

// A compiled fragment is stepped this many times, from its initial state, on a scratch
// copy before it goes live: one that diverges at once (a gain of 1e300, a spring reference
// of 1e11) is refused instead of resetting the world every step.
constexpr int k_trial_steps = 100;

[[noreturn]] void refuse(const std::string& parameter, const std::string& message) {
  throw ServiceError(message, Failure::bad_arguments, {{"parameter", parameter}});
}

// Refuses a fragment (the last entity of `model`) that is too large, holds a number beyond
// what MuJoCo takes as sound (1e10: mjMAXVAL) in what drives its dynamics, or makes the
// model diverge within k_trial_steps of its initial state (issue #35, item 2). Its block is
// the last one of every array (model.h), its counts measured by with_entity. Any thread
// (a worker's: the model is not live yet).
void check_fragment(const Model& model) {
  const SpawnedEntity& e = model.entities().back();
  const ModelCounts& c = e.counts;
  const std::string who = "mjcf: entity '" + e.name + "'";
  auto cap = [&](int count, int limit, const char* what) {
    if (count > limit)
      refuse("mjcf", who + " has " + std::to_string(count) + " " + what + ": at most " +
                         std::to_string(limit) + " in one fragment");
  };
  cap(c.nbody, k_max_fragment_bodies, "bodies");
  cap(c.njnt, k_max_fragment_joints, "joints");
  cap(c.ngeom, k_max_fragment_geoms, "geoms");

  const mjModel* m = model.model();
  // self-contained: what it adds refers to its own objects (and the world body) only
  auto owned = [&](mjtObj type, int id) {
    if (id < 0) return true;  // none, or the global frame
    switch (type) {
      case mjOBJ_BODY:
      case mjOBJ_XBODY: return id == 0 || id >= m->nbody - c.nbody;
      case mjOBJ_JOINT: return id >= m->njnt - c.njnt;
      case mjOBJ_GEOM: return id >= m->ngeom - c.ngeom;
      case mjOBJ_SITE: return id >= m->nsite - c.nsite;
      case mjOBJ_CAMERA: return id >= m->ncam - c.ncam;
      case mjOBJ_ACTUATOR: return id >= m->nu - c.nu;
      case mjOBJ_TENDON: return id >= m->ntendon - c.ntendon;
      default: return true;
    }
  };
  auto require_owned = [&](const std::string& what, mjtObj type, int id, const char* kind) {
    if (owned(type, id)) return;
    refuse("mjcf", who + ": " + what + " refers to " + name_or_index(m, type, id, kind) +
                       ", which is not the entity's: a fragment's actuators, sensors, tendons and "
                       "equalities refer "
                       "to its own objects only (the scene's would be driven by an entity, and "
                       "left broken when it "
                       "is deleted)");
  };
  for (int i = m->nu - c.nu; i < m->nu; ++i) {
    const std::string what = name_or_index(m, mjOBJ_ACTUATOR, i, "actuator");
    const int* id = m->actuator_trnid + 2 * i;
    switch (m->actuator_trntype[i]) {
      case mjTRN_JOINT:
      case mjTRN_JOINTINPARENT: require_owned(what, mjOBJ_JOINT, id[0], "joint"); break;
      case mjTRN_SLIDERCRANK:
        require_owned(what, mjOBJ_SITE, id[0], "site");
        require_owned(what, mjOBJ_SITE, id[1], "site");
        break;
      case mjTRN_TENDON: require_owned(what, mjOBJ_TENDON, id[0], "tendon"); break;
      case mjTRN_SITE: require_owned(what, mjOBJ_SITE, id[0], "site"); break;
      case mjTRN_BODY: require_owned(what, mjOBJ_BODY, id[0], "body"); break;
      default: break;
    }
  }
  for (int i = m->nsensor - c.nsensor; i < m->nsensor; ++i) {
    const std::string what = name_or_index(m, mjOBJ_SENSOR, i, "sensor");
    const auto type = static_cast<mjtObj>(m->sensor_objtype[i]);
    require_owned(what, type, m->sensor_objid[i], "object");
    require_owned(what, static_cast<mjtObj>(m->sensor_reftype[i]), m->sensor_refid[i], "object");
  }
  for (int i = m->neq - c.neq; i < m->neq; ++i) {
    const std::string what = name_or_index(m, mjOBJ_EQUALITY, i, "equality");
    const mjtObj type = m->eq_type[i] == mjEQ_JOINT    ? mjOBJ_JOINT
                        : m->eq_type[i] == mjEQ_TENDON ? mjOBJ_TENDON
                                                       : mjOBJ_BODY;
    const char* kind = type == mjOBJ_JOINT ? "joint" : type == mjOBJ_TENDON ? "tendon" : "body";
    require_owned(what, type, m->eq_obj1id[i], kind);
    require_owned(what, type, m->eq_obj2id[i], kind);
  }
  for (int t = m->ntendon - c.ntendon; t < m->ntendon; ++t) {
    const std::string what = name_or_index(m, mjOBJ_TENDON, t, "tendon");
    for (int w = m->tendon_adr[t]; w < m->tendon_adr[t] + m->tendon_num[t]; ++w) {
      const int id = m->wrap_objid[w];
      switch (m->wrap_type[w]) {
        case mjWRAP_JOINT: require_owned(what, mjOBJ_JOINT, id, "joint"); break;
        case mjWRAP_SITE: require_owned(what, mjOBJ_SITE, id, "site"); break;
        case mjWRAP_SPHERE:
        case mjWRAP_CYLINDER: require_owned(what, mjOBJ_GEOM, id, "geom"); break;
        default: break;
      }
    }
  }

  // `n` values from `values`, those of object `id`: each finite and within mjMAXVAL
  auto sound = [&](const mjtNum* values, int n, mjtObj type, int id, const char* kind,
                   const char* attribute) {
    for (int k = 0; k < n; ++k) {
      if (std::isfinite(values[k]) && std::abs(values[k]) <= mjMAXVAL) continue;
      refuse("mjcf", who + ": " + name_or_index(m, type, id, kind) + " has " + attribute + " " +
                         number(values[k]) +
                         ", beyond what MuJoCo steps soundly (at most 1e10 in magnitude)");
    }
  };
  // the last `count` of `total` objects, `stride` values each
  auto bounded = [&](const mjtNum* array, int total, int count, int stride, mjtObj type,
                     const char* kind, const char* attribute) {
    for (int i = total - count; i < total; ++i)
      sound(array + static_cast<std::size_t>(i) * stride, stride, type, i, kind, attribute);
  };
  bounded(m->actuator_gainprm, m->nu, c.nu, mjNGAIN, mjOBJ_ACTUATOR, "actuator",
          "a gain parameter");
  bounded(m->actuator_biasprm, m->nu, c.nu, mjNBIAS, mjOBJ_ACTUATOR, "actuator",
          "a bias parameter");
  bounded(m->actuator_gear, m->nu, c.nu, 6, mjOBJ_ACTUATOR, "actuator", "a gear");
  bounded(m->jnt_stiffness, m->njnt, c.njnt, 1, mjOBJ_JOINT, "joint", "a stiffness");
  bounded(m->body_mass, m->nbody, c.nbody, 1, mjOBJ_BODY, "body", "a mass");
  bounded(m->body_inertia, m->nbody, c.nbody, 3, mjOBJ_BODY, "body", "an inertia");
  bounded(m->tendon_stiffness, m->ntendon, c.ntendon, 1, mjOBJ_TENDON, "tendon", "a stiffness");
  bounded(m->tendon_damping, m->ntendon, c.ntendon, 1, mjOBJ_TENDON, "tendon", "a damping");
  bounded(m->eq_data, m->neq, c.neq, mjNEQDATA, mjOBJ_EQUALITY, "equality", "a parameter");
  for (int j = m->njnt - c.njnt; j < m->njnt; ++j) {
    const int nq = m->jnt_type[j] == mjJNT_FREE ? 7 : m->jnt_type[j] == mjJNT_BALL ? 4 : 1;
    const int nv = m->jnt_type[j] == mjJNT_FREE ? 6 : m->jnt_type[j] == mjJNT_BALL ? 3 : 1;
    sound(m->qpos_spring + m->jnt_qposadr[j], nq, mjOBJ_JOINT, j, "joint", "a spring reference");
    sound(m->dof_damping + m->jnt_dofadr[j], nv, mjOBJ_JOINT, j, "joint", "a damping");
    sound(m->dof_armature + m->jnt_dofadr[j], nv, mjOBJ_JOINT, j, "joint", "an armature");
  }

  // the trial: a scratch copy of its initial state, stepped
  std::unique_ptr<mjData, void (*)(mjData*)> d(mj_makeData(m), mj_deleteData);
  if (!d) refuse("mjcf", who + ": MuJoCo could not allocate its state");
  mj_copyData(d.get(), m, model.data());
  for (int step = 0; step < k_trial_steps; ++step) {
    mj_step(m, d.get());
    for (int k = 0; k < mjNWARNING; ++k) {
      if (!resets_the_state(k) || d->warning[k].number == 0) continue;
      const int index = d->warning[k].lastinfo;
      refuse("mjcf", who + " makes the model diverge: stepped from its initial state, step " +
                         std::to_string(step + 1) +
                         " found a NaN, an infinity or a magnitude beyond 1e10 in " +
                         bad_quantity(k, index) + " (" + where_in_state(m, k, index) +
                         "); nothing was spawned");
    }
  }
}

// A name MuJoCo and every transport carry as is, and that no unnamed body answers to
// (Model::body_name calls the unnamed body 3 "body3").
void check_entity_name(const std::string& name) {
  const bool valid_characters = std::all_of(name.begin(), name.end(), [](unsigned char c) {
    return std::isalnum(c) || c == '_' || c == '-' || c == '.';
  });
  if (name.empty() || name.size() > 64 || !valid_characters)
    refuse("name", "name '" + name + "': expected 1 to 64 letters, digits, '_', '-' or '.'");
  if (name.size() > 4 && name.starts_with("body") &&
      name.find_first_not_of("0123456789", 4) == std::string::npos)
    refuse("name", "name '" + name +
                       "': 'body<number>' is how unnamed bodies are called; choose another name");
}

// [x, y, z] or [x, y, z, qx, qy, qz, qw] (get_scene_objects' order) -> MuJoCo's pose.
EntityPose entity_pose(const std::vector<double>& pose) {
  if (pose.size() != 3 && pose.size() != 7)
    refuse("pose", "pose: expected [x, y, z] or [x, y, z, qx, qy, qz, qw], found " +
                       std::to_string(pose.size()) + " numbers");
  EntityPose out;
  const char* axes[] = {"pose[0] (x)", "pose[1] (y)", "pose[2] (z)"};
  for (int i = 0; i < 3; ++i) {
    bounds::require_within(axes[i], pose[i], bounds::position, "m");
    out.position[i] = pose[i];
  }
  if (pose.size() == 3) return out;
  for (int i = 3; i < 7; ++i)
    bounds::require_within("pose[" + std::to_string(i) + "]", pose[i], 1e3, "");
  const double norm =
      std::sqrt(pose[3] * pose[3] + pose[4] * pose[4] + pose[5] * pose[5] + pose[6] * pose[6]);
  if (!(norm > 1e-9))
    refuse("pose", "pose: the orientation quaternion [qx, qy, qz, qw] must not be zero");
  out.orientation =
      std::array<double, 4>{pose[6] / norm, pose[3] / norm, pose[4] / norm, pose[5] / norm};
  return out;
}

// A fragment file to spawn from, found under the allowed directories; read by the worker.
struct FragmentFile {
  fs::path file;      // canonical, inside an allowed directory
  std::string given;  // the path as the client wrote it, for messages
  EntityPose where;

  // The entity's document (entity_document: MJCF or URDF); throws ServiceError as it does,
  // or when the file cannot be read.
  EntityDocument document(const std::string& name) const {
    std::ifstream in(file, std::ios::binary);
    std::stringstream text;
    text << in.rdbuf();
    if (!in && !in.eof()) refuse("mjcf", "mjcf: '" + given + "' could not be read");
    return entity_document(text.str(), name, where);
  }
};

// A component that goes with a deleted body, and the robot it belongs to.
struct RemovedComponent {
  std::string name;   // "robot.motion"
  std::string robot;  // "robot"
};

// The state of the spawn group: the change being compiled, if any.
class Spawner : public std::enable_shared_from_this<Spawner> {
 public:
  explicit Spawner(Simulation& sim) : sim_(sim) {}

  void spawn_entity(Completion done, const std::string& name, const std::string& mjcf,
                    const std::vector<double>& pose, const json& robot) {
    // the arguments themselves first, then what they mean for the world as it is
    check_entity_name(name);
    const EntityPose where = entity_pose(pose);
    if (!robot.is_object())
      refuse("robot",
             "robot: expected an object (a robot section: type, components...), "
             "or {} for a plain body, found " +
                 robot.dump());
    const bool with_robot = !robot.empty();
    if (with_robot) {
      if (!sim_.robot_factory())
        refuse("robot",
               "robot: this simulation builds no robots at run time (it runs without a "
               "configuration)");
      sim_.robot_factory()->check(name, robot);
    }
    const std::size_t first = mjcf.find_first_not_of(" \t\r\n");
    const bool inline_text = first != std::string::npos && mjcf[first] == '<';
    // inline text is checked now; a file is found now and read by the worker (disk I/O has
    // no place under the simulation lock)
    Edit edit;
    if (inline_text)
      edit = [name, document = entity_document(mjcf, name, where)](const EditBase& base) {
        return with_entity(base, name, document);
      };
    else
      edit = [name, file = FragmentFile{fragment_file(mjcf), mjcf, where}](const EditBase& base) {
        return with_entity(base, name, file.document(name));
      };
    refuse_if_busy(name);
    const Model& model = sim_.model();
    if (model.body_id(name) >= 0)
      refuse("name", "name '" + name + "' is taken: the world already has a body called so" +
                         (model.entity(name) ? " (a spawned entity)" : ""));
    start(std::move(done), "spawn_entity", name, std::move(edit), -1, {},
          with_robot ? robot : json());
  }

  void delete_entity(Completion done, const std::string& name) {
    refuse_if_busy(name);
    const Model& model = sim_.model();
    const int body = model.body_id(name);
    if (body == 0) refuse("name", "'" + name + "' is the world body: it cannot be deleted");
    if (body < 0) refuse("name", "no body or entity named '" + name + "'" + spawned_list());
    auto edit = [body, name](const EditBase& base) { return without_body(base, body, name); };
    // the robots whose root body is in its subtree go (a robot spawned with it, or one of
    // the scene), with their components; no other component may be bound to the subtree,
    // nor the body be part of a component's body
    std::set<std::string> robots;
    for (const auto& entry : sim_.components())
      if (const auto* robot = dynamic_cast<const Robot*>(entry->component.get());
          robot && entry->is_robot && in_subtree(sim_.m(), robot->body(), body))
        robots.insert(robot->name());
    std::vector<RemovedComponent> removed;
    for (const auto& entry : sim_.components()) {
      const std::string& component = entry->component->name();
      if (robots.contains(component) || robots.contains(entry->robot)) {
        if (!caller_serves(component))
          refuse("name", "body '" + name +
                             "' holds components this transport does not serve: delete_entity "
                             "cannot remove them");
        removed.push_back({component, robots.contains(component) ? component : entry->robot});
        continue;
      }
      const SimComponent* c = entry->sim_component;
      const int bound = c ? c->bound_body() : -1;
      if (bound <= 0) continue;
      const std::string who = (entry->is_robot ? "robot '" : "component '") + component + "'";
      if (in_subtree(sim_.m(), bound, body))
        refuse("name", "body '" + name + "' holds " + who +
                           (entry->robot.empty() ? "" : " of robot '" + entry->robot + "'") +
                           ", whose robot stays: delete the robot's own body instead");
      if (in_subtree(sim_.m(), body, bound))
        refuse("name", "body '" + name + "' is part of " + who + "'s body '" +
                           model.body_name(bound) +
                           "': delete_entity removes a robot's root body, not a part of it");
    }
    start(std::move(done), "delete_entity", name, std::move(edit), body, std::move(removed));
  }

  // The simulation's turn after a worker ended: swap its model in and complete the request.
  void apply() {
    std::erase_if(abandoned_, [](const std::future<void>& f) { return ready(f); });
    if (!change_ || !ready(change_->compiled)) return;
    Change change = std::move(*change_);
    change_.reset();
    std::optional<Model> next;
    try {
      next.emplace(change.compiled.get());
    } catch (const ServiceError& e) {
      // the fragment file the worker read is no entity (entity_document's refusal)
      change.done.finish(Outcome::failed(e.failure(), e.message(), e.data()));
      return;
    } catch (const std::exception& e) {
      // MuJoCo's message: the fragment does not compile with the scene (a taken joint or
      // geom name, a missing mesh...), and the running model is untouched
      const bool spawning = change.service == "spawn_entity";
      change.done.finish(Outcome::failed(
          spawning ? Failure::bad_arguments : Failure::service_error,
          change.service + " '" + change.name + "': the model does not compile: " + e.what(),
          spawning ? json{{"parameter", "mjcf"}} : json::object()));
      return;
    }
    if (change.done.done()) {
      // cancelled by its client, or ended at shutdown: the world stays as it is
      log::info("simulation: ", change.service, " '", change.name,
                "' ended before its model was ready; dropped");
      return;
    }
    if (sim_.model_generation() != change.generation) {
      change.done.finish(
          Outcome::failed(Failure::service_error,
                          change.service + " '" + change.name +
                              "': the model changed while it compiled; nothing was changed"));
      return;
    }
    // where every object went (a body of the scene removed moves what came after it)
    ModelRemap remap;
    try {
      remap = ModelRemap::between(sim_.m(), next->model(), change.removed_body,
                                  change.service == "spawn_entity");
    } catch (const MujocoError& e) {
      change.done.finish(
          Outcome::failed(Failure::service_error, change.service + " '" + change.name +
                                                      "': the recompiled model does not match the "
                                                      "running one: " +
                                                      e.what() + "; nothing was changed"));
      return;
    }
    // the deleted robots' components first: their requests end, their services go
    for (const RemovedComponent& c : change.removed_components)
      sim_.remove_component(c.name,
                            "robot '" + c.robot + "' was deleted by simulation.delete_entity");
    Model previous = sim_.replace_model(std::move(*next), remap);
    if (!change.robot.is_null() && !build_robot(change, previous)) return;
    log::info("simulation: ", change.service, " '", change.name, "': model generation ",
              sim_.model_generation(), " (", sim_.m()->nbody, " bodies)");
    // every client that watches the world learns what changed in it, and who changed it
    json event = {
        {"name", change.name}, {"model_generation", sim_.model_generation()}, {"by", change.by}};
    std::set<std::string> robots;
    for (const RemovedComponent& c : change.removed_components) robots.insert(c.robot);
    if (change.service == "spawn_entity")
      event["robot"] = !change.robot.is_null();
    else
      event["robots"] = robots;
    sim_.announce(change.service == "spawn_entity" ? "spawned" : "deleted", std::move(event));
    change.done(Status::success,
                json{{"name", change.name}, {"model_generation", sim_.model_generation()}});
  }

 private:
  template <class T>
  static bool ready(const std::future<T>& f) {
    return f.wait_for(std::chrono::seconds(0)) == std::future_status::ready;
  }

  // One change at a time: the next one starts from the model this one makes. A change
  // whose request already ended (cancelled by its client) makes nothing: its worker is left
  // to finish on its own.
  void refuse_if_busy(const std::string& name) {
    if (change_ && change_->done.done()) {
      abandoned_.push_back(std::move(change_->worker));
      change_.reset();
    }
    if (change_)
      throw ServiceError("cannot change entity '" + name + "' now: " + change_->service + " '" +
                             change_->name + "' is compiling; try again when it completes",
                         Failure::busy, {{"running", "simulation." + change_->service}});
  }

  // The fragment file `path` names (allowed_files.h): a file elsewhere gets the answer of a
  // missing one. Only looks (no read).
  fs::path fragment_file(const std::string& path) const {
    const std::vector<std::string>& allowed = sim_.spawn_allowed_dirs();
    if (allowed.empty())
      refuse("mjcf",
             "mjcf: expected MJCF text (a <body>, or a <mujoco> with a <worldbody> holding one "
             "<body>); "
             "fragment files need directories allowed in the config (spawn.allowed_dirs), and it "
             "allows none");
    std::string dirs;
    for (const auto& dir : allowed) dirs += (dirs.empty() ? "" : ", ") + dir;
    const std::string refusal = "mjcf: '" + path +
                                "' is neither MJCF or URDF text nor a fragment file under the " +
                                "directories the config allows (spawn.allowed_dirs: " + dirs + ")";
    const std::optional<fs::path> file = find_allowed_file(allowed, path);
    if (!file) refuse("mjcf", refusal);
    std::error_code ec;
    if (fs::file_size(*file, ec) > k_max_fragment_bytes)
      refuse("mjcf", "mjcf: '" + path + "' is larger than " + std::to_string(k_max_fragment_bytes) +
                         " bytes");
    return *file;
  }

  std::string spawned_list() const {
    std::string names;
    for (const auto& e : sim_.model().entities())
      names += (names.empty() ? "" : ", ") + ("'" + e.name + "'");
    return names.empty() ? " (no entity has been spawned)" : " (spawned: " + names + ")";
  }

  // A change of the model: the running one's copy (EditBase) in, the new model out (or
  // MuJoCo's error); run by a worker.
  using Edit = std::function<Model(const EditBase&)>;

  // Runs `edit` on a worker thread, from copies only (nothing shared with the running
  // simulation but the spec, read-only). `removed_body`: the body the change deletes (-1: a
  // spawn), in the running model; `removed`: the components that go with it (a robot's),
  // removed at the swap. `robot`: the section of the robot a spawn brings (null: none).
  void start(Completion done, std::string service, std::string name, Edit edit,
             int removed_body = -1, std::vector<RemovedComponent> removed = {},
             json robot = json()) {
    const bool spawning = removed_body < 0;
    auto result = std::make_shared<std::promise<Model>>();
    std::future<Model> compiled = result->get_future();
    // the worker: the model (or MuJoCo's error), then a turn of the simulation thread for
    // apply() (the simulation outlives the worker: a Spawner waits for its workers when it
    // goes, through their futures)
    std::future<void> worker = std::async(
        std::launch::async, [&sim = sim_, self = weak_from_this(), result,
                             base = EditBase::of(sim_.model()), edit = std::move(edit), spawning] {
          try {
            Model model = edit(base);
            if (spawning) check_fragment(model);
            result->set_value(std::move(model));
          } catch (...) {
            result->set_exception(std::current_exception());
          }
          sim.run_soon([self] {
            if (auto spawner = self.lock()) spawner->apply();
          });
        });
    // the swap runs outside this request's context: who asked is kept for the announcement
    const CallContext* context = CallContext::current();
    change_.emplace(Change{std::move(done), std::move(service), std::move(name),
                           sim_.model_generation(), removed_body, std::move(removed),
                           std::move(compiled), std::move(worker), std::move(robot),
                           context ? context->manager().transport_name() : "simulation"});
  }

  // A model being compiled, and the request waiting for it.
  struct Change {
    Completion done;           // the request, completed after the swap
    std::string service;       // "spawn_entity" or "delete_entity"
    std::string name;          // the entity
    std::uint64_t generation;  // the model generation it was made from
    int removed_body;          // the body it deletes in that model (-1: none)
    std::vector<RemovedComponent> removed_components;  // a deleted robot's, removed at the swap
    std::future<Model> compiled;                       // the worker's result (or MuJoCo's error)
    std::future<void> worker;  // the worker itself (ready once it has asked for apply())
    json robot;                // spawn_entity's robot section (null: a plain body)
    std::string by;            // the caller's transport (simulation.events' `by`)
  };

  // Builds the robot a spawn brings, its body now in the model. When it cannot be built,
  // nothing of the spawn stays: the model it was spawned into goes back (the state as it is:
  // no step ran between), the request FAILS saying why, and false.
  bool build_robot(Change& change, Model& previous) {
    try {
      sim_.robot_factory()->build(change.name, change.robot);
      return true;
    } catch (const std::exception& e) {
      const ModelRemap back =
          ModelRemap::between(sim_.m(), previous.model(), sim_.model().body_id(change.name), false);
      sim_.replace_model(std::move(previous), back);
      const auto* error = dynamic_cast<const ServiceError*>(&e);
      const std::string why = error ? error->message() : e.what();
      change.done.finish(
          Outcome::failed(error ? error->failure() : Failure::bad_arguments,
                          "spawn_entity '" + change.name + "': " + why + "; nothing was spawned",
                          error ? error->data() : json{{"parameter", "robot"}}));
      return false;
    }
  }

  Simulation& sim_;                           // whose model changes
  std::optional<Change> change_;              // the one being compiled
  std::vector<std::future<void>> abandoned_;  // workers of cancelled changes, until they end
};

}  // namespace

void add_spawn_services(SupervisionServices& simulation, Simulation& sim) {
  auto spawner = std::make_shared<Spawner>(sim);
  simulation
      .offer_async_service(
          "spawn_entity",
          [spawner](Completion done, const std::string& name, const std::string& mjcf,
                    const std::vector<double>& pose, const json& robot) {
            spawner->spawn_entity(std::move(done), name, mjcf, pose, robot);
          },
          {"name", "mjcf", "pose", {"robot", json::object()}})
      .concurrent()
      .doc(
          "Add the MJCF body `mjcf` to the world as `name` at `pose` [x, y, z] or [x, y, z, qx, "
          "qy, qz, qw]; "
          "`robot` (a config's robot section: type, components) makes it a robot with components");
  simulation
      .offer_async_service("delete_entity",
                           [spawner](Completion done, const std::string& name) {
                             spawner->delete_entity(std::move(done), name);
                           },
                           {"name"})
      .concurrent()
      .doc(
          "Remove the body `name` (an entity spawned at run time, or a body of the scene no "
          "component uses) "
          "from the world");
}

}  // namespace simgate::sim
