// simgate/sim/model.h — ownership of a MuJoCo model and its state (mjModel + mjData).
//
// A Model is loaded from an MJCF file (or an inline string, for tests) and owns both the
// immutable mjModel and the mutable mjData (RAII, move-only). MuJoCo's error and warning
// handlers are replaced process-wide on first use: an engine error becomes a MujocoError
// exception (never a process exit), a warning becomes a log line. Load errors name the
// file and MuJoCo's message.
//
// Threads: a Model is used by one thread at a time (the simulation thread once running).
#ifndef SIMGATE_SIM_MODEL_H_
#define SIMGATE_SIM_MODEL_H_

#include <memory>
#include <stdexcept>
#include <string>

#include <mujoco/mujoco.h>

namespace simgate::sim {

// MuJoCo reported an error (load failure or engine error).
class MujocoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Installs the error/warning handlers (idempotent, thread-safe). Called by Model.
void install_mujoco_handlers();

class Model {
 public:
  // Throws MujocoError("scene '<path>': <MuJoCo's message>").
  static Model load_file(const std::string& path);
  // `name` is used in messages and as the virtual file name (relative includes fail).
  static Model load_string(const std::string& xml, const std::string& name = "inline.xml");

  mjModel* model() const { return model_.get(); }
  mjData* data() const { return data_.get(); }
  const std::string& source() const { return source_; }

  // Name -> id lookups; -1 when missing. body_id also finds an unnamed body by the name
  // body_name() gives it ("body3"), so that a config can bind to it.
  int body_id(const std::string& name) const;
  int joint_id(const std::string& name) const { return mj_name2id(model(), mjOBJ_JOINT, name.c_str()); }
  int actuator_id(const std::string& name) const {
    return mj_name2id(model(), mjOBJ_ACTUATOR, name.c_str());
  }
  // The body's name, or "body<id>" for unnamed bodies.
  std::string body_name(int id) const;
  // Index of the free joint attached to `body`, or -1.
  int free_joint_of(int body) const;

 private:
  struct ModelDeleter { void operator()(mjModel* m) const { mj_deleteModel(m); } };
  struct DataDeleter { void operator()(mjData* d) const { mj_deleteData(d); } };
  Model(mjModel* m, std::string source);

  std::unique_ptr<mjModel, ModelDeleter> model_;  // immutable description
  std::unique_ptr<mjData, DataDeleter> data_;     // mutable state
  std::string source_;                            // file path or inline name, for messages
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_MODEL_H_
