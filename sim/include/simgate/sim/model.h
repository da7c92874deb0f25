// simgate/sim/model.h — ownership of a MuJoCo model and its state (mjModel + mjData).
//
// A Model is loaded from an MJCF file (or an inline string, for tests) and owns both the
// immutable mjModel and the mutable mjData (RAII, move-only). MuJoCo's error and warning
// handlers are replaced process-wide on first use: an engine error becomes a MujocoError
// exception (never a process exit), a warning becomes a log line. Load errors name the
// file and MuJoCo's message.
//
// A Model keeps what it was compiled from: MuJoCo's model specification (mjSpec), which an
// edit copies and changes (spawn, delete: model_edit.h) so that the scene file is never read
// again, and the names of the entities spawned into it at run time, in order. Each entity's
// objects come after those of the model it was spawned into, in every MuJoCo array (bodies,
// joints, geoms, sites, actuators, sensors, qpos...): an entity is a block, whose size is its
// ModelCounts when it was spawned.
//
// Threads: a Model is used by one thread at a time (the simulation thread once running).
#ifndef SIMGATE_SIM_MODEL_H_
#define SIMGATE_SIM_MODEL_H_

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <mujoco/mujoco.h>

namespace simgate::sim {

// MuJoCo reported an error (load failure or engine error).
class MujocoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Installs the error/warning handlers and loads MuJoCo's engine plugins (idempotent,
// thread-safe). Called by Model.
void install_mujoco_handlers();

// MuJoCo's engine plugins (the PID actuator, SDF collisions, touch-grid sensors...), loaded
// once, before the first model: every library in the plugin directory beside libmujoco —
// the PyPI wheel's mujoco/plugin/, an installed simgate's lib/mujoco_plugin/, a MuJoCo
// release's bin/mujoco_plugin/ — or in $SIMGATE_MUJOCO_PLUGIN_DIR when set. A model using
// a plugin none of them registers is refused by MuJoCo, naming it.
struct EnginePlugins {
  std::string directory;           // where they were looked for ("" when nowhere)
  std::vector<std::string> names;  // the plugins registered, e.g. "mujoco.pid"
};
const EnginePlugins& engine_plugins();

// How many objects of each kind a model, or one block of it, holds.
struct ModelCounts {
  int nbody = 0, njnt = 0, ngeom = 0, nsite = 0, ncam = 0, nlight = 0, nmocap = 0;
  int nq = 0, nv = 0, na = 0, nu = 0, nsensor = 0, ntendon = 0, neq = 0;

  static ModelCounts of(const mjModel* m);
  ModelCounts& operator+=(const ModelCounts& other);
  ModelCounts operator-(const ModelCounts& other) const;
};

// An entity spawned at run time (model_edit.h).
struct SpawnedEntity {
  std::string name;    // its top body's name
  ModelCounts counts;  // its block when it was spawned (the last one of every array then)
};

// MuJoCo's model specification, shared read-only between the models compiled from it and the
// workers that copy it (mj_copySpec) to edit the copy.
using SharedSpec = std::shared_ptr<const mjSpec>;

// MuJoCo's parser on the file `path`, or on `*text` when given; mj_compile of a spec. Each
// throws MujocoError "<source>: <MuJoCo's message>" (the message alone when `source` is
// empty: "scene 'arm.xml'"); compile_spec logs MuJoCo's compile warning. Any thread.
std::shared_ptr<mjSpec> parse_spec(const std::string& path, const std::string* text,
                                   const std::string& source);
mjModel* compile_spec(mjSpec* spec, const std::string& source);

class Model {
 public:
  // Throws MujocoError("scene '<path>': <MuJoCo's message>").
  static Model load_file(const std::string& path);
  // `name` is used in messages and as the virtual file name (relative includes fail).
  static Model load_string(const std::string& xml, const std::string& name = "inline.xml");

  mjModel* model() const { return model_.get(); }
  mjData* data() const { return data_.get(); }
  const std::string& source() const { return source_; }
  // What it was compiled from (see above): never changed once compiled (an edit copies it).
  const SharedSpec& spec() const { return spec_; }
  const std::vector<SpawnedEntity>& entities() const { return entities_; }
  // The spawned entity called `name`, or null.
  const SpawnedEntity* entity(const std::string& name) const;

  // A model compiled from `spec` (an edited copy, model_edit.cc), which it keeps: takes `m`,
  // makes its data.
  static Model adopt(mjModel* m, std::string source, SharedSpec spec,
                     std::vector<SpawnedEntity> entities);
  // Wraps a spec MuJoCo made (mj_parseXML, mj_copySpec...): mj_deleteSpec when the last owner goes.
  static std::shared_ptr<mjSpec> own(mjSpec* spec);

  // Name -> id lookups; -1 when missing. body_id also finds an unnamed body by the name
  // body_name() gives it ("body3"), so that a config can bind to it.
  int body_id(const std::string& name) const;
  int joint_id(const std::string& name) const {
    return mj_name2id(model(), mjOBJ_JOINT, name.c_str());
  }
  int actuator_id(const std::string& name) const {
    return mj_name2id(model(), mjOBJ_ACTUATOR, name.c_str());
  }
  // The body's name, or "body<id>" for unnamed bodies.
  std::string body_name(int id) const;
  // Index of the free joint attached to `body`, or -1.
  int free_joint_of(int body) const;

 private:
  struct ModelDeleter {
    void operator()(mjModel* m) const { mj_deleteModel(m); }
  };
  struct DataDeleter {
    void operator()(mjData* d) const { mj_deleteData(d); }
  };
  Model(mjModel* m, std::string source);

  std::unique_ptr<mjModel, ModelDeleter> model_;  // immutable description
  std::unique_ptr<mjData, DataDeleter> data_;     // mutable state
  std::string source_;                            // file path or inline name, for messages
  SharedSpec spec_;                               // what it was compiled from
  std::vector<SpawnedEntity> entities_;           // spawned into it, in order
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_MODEL_H_
