#include "simgate/sim/model.h"

#include <dlfcn.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "simgate/core/log.h"
#include "urdf.h"

namespace simgate::sim {

namespace {

// A warning MuJoCo gives each time simgate attaches a spawned entity (model_edit.cc): its
// objects keep their names, unprefixed, which only matters to a model saved back as MJCF
// (simgate saves none).
constexpr std::string_view k_attach_without_prefix = "Attaching a spec with an empty prefix";

// MuJoCo calls this instead of exit(1). It must not return: were it to, mju_error would
// return to the engine code that found the error, which carries on with the broken state. The
// engine is built with unwind tables, so the exception propagates through its C frames to the
// caller of mj_step / mj_forward.
void on_mujoco_error(const char* message) {
  throw MujocoError(std::string("MuJoCo error: ") + message);
}

void on_mujoco_warning(const char* message) {
  if (std::string_view(message).starts_with(k_attach_without_prefix)) return;
  log::warning("MuJoCo: ", message);
}

// The directory of MuJoCo's engine plugins: $SIMGATE_MUJOCO_PLUGIN_DIR, else the first of
// the layouts beside the libmujoco this process runs on that exists; "" when none does.
std::string engine_plugin_directory() {
  if (const char* dir = std::getenv("SIMGATE_MUJOCO_PLUGIN_DIR"); dir && *dir) return dir;
  Dl_info info{};
  if (dladdr(reinterpret_cast<void*>(&mj_version), &info) == 0 || !info.dli_fname) return "";
  const std::filesystem::path lib_dir = std::filesystem::path(info.dli_fname).parent_path();
  for (const auto& dir :
       {lib_dir / "plugin", lib_dir / "mujoco_plugin", lib_dir / ".." / "bin" / "mujoco_plugin"}) {
    std::error_code ec;
    if (std::filesystem::is_directory(dir, ec)) return dir.lexically_normal().string();
  }
  return "";
}

EnginePlugins load_engine_plugins() {
  EnginePlugins plugins;
  plugins.directory = engine_plugin_directory();
  if (plugins.directory.empty()) {
    log::debug("MuJoCo engine plugins: no plugin directory beside libmujoco");
    return plugins;
  }
  const int before = mjp_pluginCount();
  mj_loadAllPluginLibraries(plugins.directory.c_str(), nullptr);
  for (int slot = before; slot < mjp_pluginCount(); ++slot)
    if (const mjpPlugin* p = mjp_getPluginAtSlot(slot); p && p->name)
      plugins.names.emplace_back(p->name);
  log::debug("MuJoCo engine plugins from ", plugins.directory, ": ", plugins.names.size());
  return plugins;
}

}  // namespace

void install_mujoco_handlers() {
  static std::once_flag once;
  std::call_once(once, [] {
    mju_user_error = &on_mujoco_error;
    mju_user_warning = &on_mujoco_warning;
  });
  engine_plugins();
}

const EnginePlugins& engine_plugins() {
  static const EnginePlugins plugins = load_engine_plugins();  // once, thread-safe
  return plugins;
}

Model::Model(mjModel* m, std::string source) : model_(m), source_(std::move(source)) {
  data_.reset(mj_makeData(m));
  if (!data_) throw MujocoError("scene '" + source_ + "': could not allocate mjData");
  mj_forward(model(), data());
}

std::shared_ptr<mjSpec> Model::own(mjSpec* spec) {
  return std::shared_ptr<mjSpec>(spec, mj_deleteSpec);
}

namespace {

// "<source>: <message>", or the message alone without a source.
std::string from(const std::string& source, const std::string& message) {
  return source.empty() ? message : source + ": " + message;
}

}  // namespace

std::shared_ptr<mjSpec> parse_spec(const std::string& path, const std::string* text,
                                   const std::string& source) {
  install_mujoco_handlers();
  char error[1024] = "";
  mjSpec* spec = nullptr;
  try {
    spec = text ? mj_parseXMLString(text->c_str(), nullptr, error, sizeof error)
                : mj_parseXML(path.c_str(), nullptr, error, sizeof error);
  } catch (const MujocoError& e) {
    throw MujocoError(from(source, e.what()));
  }
  if (!spec) throw MujocoError(from(source, error[0] ? error : "MuJoCo could not parse it"));
  return Model::own(spec);
}

mjModel* compile_spec(mjSpec* spec, const std::string& source) {
  mjModel* m = nullptr;
  try {
    m = mj_compile(spec, nullptr);
  } catch (const MujocoError& e) {
    throw MujocoError(from(source, e.what()));
  }
  if (!m) throw MujocoError(from(source, mjs_getError(spec)));
  if (mjs_isWarning(spec))
    log::warning(source.empty() ? "MuJoCo" : source, ": ", mjs_getError(spec));
  return m;
}

Model Model::load_file(const std::string& path) {
  install_mujoco_handlers();
  std::ifstream file(path, std::ios::binary);
  std::stringstream read;
  read << file.rdbuf();
  const std::string source = "scene '" + path + "'";
  std::shared_ptr<mjSpec> spec = parse_spec(path, nullptr, source);
  // MuJoCo reads URDF too, but makes no actuators of its transmissions
  if (file && is_urdf(read.str())) add_transmission_actuators(spec.get(), source, read.str());
  mjModel* m = compile_spec(spec.get(), source);
  return adopt(m, path, std::move(spec), {});
}

Model Model::load_string(const std::string& xml, const std::string& name) {
  install_mujoco_handlers();
  const std::string source = "scene '" + name + "'";
  std::shared_ptr<mjSpec> spec = parse_spec(name, &xml, source);
  mjModel* m = compile_spec(spec.get(), source);
  return adopt(m, name, std::move(spec), {});
}

Model Model::adopt(mjModel* m, std::string source, SharedSpec spec,
                   std::vector<SpawnedEntity> entities) {
  Model model(m, std::move(source));
  model.spec_ = std::move(spec);
  model.entities_ = std::move(entities);
  return model;
}

const SpawnedEntity* Model::entity(const std::string& name) const {
  for (const auto& e : entities_)
    if (e.name == name) return &e;
  return nullptr;
}

ModelCounts ModelCounts::of(const mjModel* m) {
  ModelCounts c;
  c.nbody = m->nbody, c.njnt = m->njnt, c.ngeom = m->ngeom, c.nsite = m->nsite, c.ncam = m->ncam;
  c.nlight = m->nlight, c.nmocap = m->nmocap, c.nq = m->nq, c.nv = m->nv, c.na = m->na,
  c.nu = m->nu;
  c.nsensor = m->nsensor, c.ntendon = m->ntendon, c.neq = m->neq;
  return c;
}

ModelCounts& ModelCounts::operator+=(const ModelCounts& o) {
  nbody += o.nbody, njnt += o.njnt, ngeom += o.ngeom, nsite += o.nsite, ncam += o.ncam,
      nlight += o.nlight;
  nmocap += o.nmocap, nq += o.nq, nv += o.nv, na += o.na, nu += o.nu, nsensor += o.nsensor;
  ntendon += o.ntendon, neq += o.neq;
  return *this;
}

ModelCounts ModelCounts::operator-(const ModelCounts& o) const {
  ModelCounts c = *this;
  c.nbody -= o.nbody, c.njnt -= o.njnt, c.ngeom -= o.ngeom, c.nsite -= o.nsite, c.ncam -= o.ncam;
  c.nlight -= o.nlight, c.nmocap -= o.nmocap, c.nq -= o.nq, c.nv -= o.nv, c.na -= o.na,
      c.nu -= o.nu;
  c.nsensor -= o.nsensor, c.ntendon -= o.ntendon, c.neq -= o.neq;
  return c;
}

int Model::body_id(const std::string& name) const {
  const int id = mj_name2id(model(), mjOBJ_BODY, name.c_str());
  if (id >= 0 || name.size() <= 4 || name.compare(0, 4, "body") != 0) return id;
  // "body<id>": only for an unnamed body, and only in body_name()'s spelling ("body03" is not)
  const std::string digits = name.substr(4);
  if (digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos) return -1;
  const int n = std::stoi(digits);
  if (n < 0 || n >= model()->nbody || std::to_string(n) != digits) return -1;
  const char* own = mj_id2name(model(), mjOBJ_BODY, n);
  return own && *own ? -1 : n;
}

std::string Model::body_name(int id) const {
  const char* n = mj_id2name(model(), mjOBJ_BODY, id);
  return n && *n ? std::string(n) : "body" + std::to_string(id);
}

int Model::free_joint_of(int body) const {
  const mjModel* m = model();
  for (int j = m->body_jntadr[body]; j >= 0 && j < m->body_jntadr[body] + m->body_jntnum[body]; ++j)
    if (m->jnt_type[j] == mjJNT_FREE) return j;
  return -1;
}

}  // namespace simgate::sim
