#include "simgate/sim/model_edit.h"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <set>

#include <tinyxml2.h>

#include "simgate/core/errors.h"

namespace simgate::sim {

namespace {

// The file name the wrapper model has in the VFS: beside the scene, under a name no scene uses.
constexpr const char* k_wrapper_name = "__simgate_spawned_entities__.xml";

// The sections of a <mujoco> fragment that can belong to one entity. Not <option>,
// <compiler>, <size>, <visual>, <statistic>: they are the scene's; not <keyframe>: the
// scene's keyframes are sized by its own state.
const std::set<std::string, std::less<>> k_entity_sections = {"asset",    "default", "worldbody", "actuator",
                                                               "sensor",   "tendon",  "equality",  "contact"};

[[noreturn]] void refuse(const std::string& message) {
  throw ServiceError("mjcf: " + message, Failure::bad_arguments, {{"parameter", "mjcf"}});
}

std::string text_of(const tinyxml2::XMLElement& element) {
  tinyxml2::XMLPrinter printer(nullptr, /*compact=*/true);
  element.Accept(&printer);
  return printer.CStr();
}

std::string numbers(const double* values, int n) {
  std::string out;
  char text[32];
  for (int i = 0; i < n; ++i) {
    std::snprintf(text, sizeof text, "%.17g", values[i]);
    out += (i ? " " : "") + std::string(text);
  }
  return out;
}

// An entity reads files beside the scene only: no <include>, no absolute or climbing file names.
void check_files(const tinyxml2::XMLElement& element) {
  if (std::strcmp(element.Name(), "include") == 0) refuse("<include> is not allowed in a spawned fragment");
  for (const tinyxml2::XMLAttribute* a = element.FirstAttribute(); a; a = a->Next()) {
    if (std::strncmp(a->Name(), "file", 4) != 0) continue;
    const std::string file = a->Value();
    if (file.starts_with('/') || file == ".." || file.starts_with("../") || file.find("/../") != std::string::npos ||
        file.ends_with("/.."))
      refuse("<" + std::string(element.Name()) + " " + a->Name() + "=\"" + file +
             "\">: a spawned fragment names files relative to the scene's directories, without '..'");
  }
  for (const auto* child = element.FirstChildElement(); child; child = child->NextSiblingElement())
    check_files(*child);
}

// Names the top body and places it.
void place(tinyxml2::XMLElement& body, const std::string& name, const EntityPose& pose) {
  body.SetAttribute("name", name.c_str());
  body.SetAttribute("pos", numbers(pose.position.data(), 3).c_str());
  if (!pose.orientation) return;
  // one orientation only: MuJoCo refuses a body with two
  for (const char* other : {"axisangle", "euler", "xyaxes", "zaxis"}) body.DeleteAttribute(other);
  body.SetAttribute("quat", numbers(pose.orientation->data(), 4).c_str());
}

std::string escaped(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

template <class T>
void copy_block(const T* from, int from_start, T* to, int to_start, int count, int width) {
  std::copy_n(from + from_start * width, count * width, to + to_start * width);
}

// Copies one block (the scene's, or one entity's) between two models, starting at
// `from_at` in the first and `to_at` in the second.
void copy_state_block(const mjData* from, const ModelCounts& from_at, mjData* to, const ModelCounts& to_at,
                      const ModelCounts& size) {
  copy_block(from->qpos, from_at.nq, to->qpos, to_at.nq, size.nq, 1);
  copy_block(from->qvel, from_at.nv, to->qvel, to_at.nv, size.nv, 1);
  copy_block(from->qacc_warmstart, from_at.nv, to->qacc_warmstart, to_at.nv, size.nv, 1);
  copy_block(from->qfrc_applied, from_at.nv, to->qfrc_applied, to_at.nv, size.nv, 1);
  copy_block(from->act, from_at.na, to->act, to_at.na, size.na, 1);
  copy_block(from->ctrl, from_at.nu, to->ctrl, to_at.nu, size.nu, 1);
  copy_block(from->mocap_pos, from_at.nmocap, to->mocap_pos, to_at.nmocap, size.nmocap, 3);
  copy_block(from->mocap_quat, from_at.nmocap, to->mocap_quat, to_at.nmocap, size.nmocap, 4);
  copy_block(from->xfrc_applied, from_at.nbody, to->xfrc_applied, to_at.nbody, size.nbody, 6);
}

bool same_state_size(const ModelCounts& a, const ModelCounts& b) {
  return a.nq == b.nq && a.nv == b.nv && a.na == b.na && a.nu == b.nu && a.nmocap == b.nmocap && a.nbody == b.nbody;
}

// Where each entity's block starts in a model compiled from `scene` and `entities`.
std::vector<ModelCounts> block_starts(const SceneSource& scene, const std::vector<SpawnedEntity>& entities) {
  std::vector<ModelCounts> starts;
  ModelCounts at = scene.counts;
  for (const auto& e : entities) {
    starts.push_back(at);
    at += e.counts;
  }
  return starts;
}

}  // namespace

std::string entity_sections(const std::string& fragment, const std::string& name, const EntityPose& pose) {
  tinyxml2::XMLDocument doc;
  if (doc.Parse(fragment.data(), fragment.size()) != tinyxml2::XML_SUCCESS)
    refuse(std::string("not well-formed XML: ") + doc.ErrorStr());
  tinyxml2::XMLElement* root = doc.RootElement();
  if (!root) refuse("expected MJCF text: a <body>, or a <mujoco> with a <worldbody> holding one <body>");
  if (root->NextSiblingElement()) refuse("expected one root element, found several");
  check_files(*root);

  const std::string root_name = root->Name();
  if (root_name == "body") {
    place(*root, name, pose);
    return "<worldbody>" + text_of(*root) + "</worldbody>";
  }
  if (root_name != "mujoco")
    refuse("expected a <body> or a <mujoco> root element, found <" + root_name + ">");

  std::string sections;
  tinyxml2::XMLElement* body = nullptr;
  for (auto* section = root->FirstChildElement(); section; section = section->NextSiblingElement()) {
    const std::string section_name = section->Name();
    if (!k_entity_sections.contains(section_name))
      refuse("<" + section_name +
             "> cannot be spawned: a fragment's sections are asset, default, worldbody, actuator, sensor, "
             "tendon, equality, contact");
    if (section_name == "worldbody") {
      for (auto* child = section->FirstChildElement(); child; child = child->NextSiblingElement()) {
        if (std::strcmp(child->Name(), "body") != 0 || body)
          refuse("the <worldbody> of a spawned fragment holds exactly one <body> (the entity), found <" +
                 std::string(child->Name()) + ">" + (body ? " beside it" : ""));
        body = child;
      }
    }
  }
  if (!body) refuse("a <mujoco> fragment needs a <worldbody> holding one <body>");
  place(*body, name, pose);
  for (auto* section = root->FirstChildElement(); section; section = section->NextSiblingElement())
    sections += text_of(*section);
  return sections;
}

Model compile_scene(const std::shared_ptr<const SceneSource>& scene, std::vector<SpawnedEntity> entities,
                    bool last_is_new) {
  install_mujoco_handlers();
  std::string wrapper = "<mujoco model=\"" + escaped(scene->model_name) + "\"><include file=\"" +
                        escaped(scene->file_name) + "\"/>";
  for (const auto& e : entities) wrapper += e.sections;
  wrapper += "</mujoco>";

  // the scene's text and the wrapper in a virtual file system (mjVFS is large: off the stack)
  auto vfs = std::make_unique<mjVFS>();
  mj_defaultVFS(vfs.get());
  struct Release {
    mjVFS* vfs;
    ~Release() { mj_deleteVFS(vfs); }
  } release{vfs.get()};
  auto add = [&](const char* file, const std::string& text) {
    if (mj_makeEmptyFileVFS(vfs.get(), file, static_cast<int>(text.size())) != 0)
      throw MujocoError("scene '" + scene->file_name + "': could not create the virtual file '" + file + "'");
    std::memcpy(vfs->filedata[mj_findFileVFS(vfs.get(), file)], text.data(), text.size());
  };
  add(scene->file_name.c_str(), scene->xml);
  add(k_wrapper_name, wrapper);
  // as if beside the scene file: relative names resolve in its directory
  const std::string path = scene->directory.empty() ? k_wrapper_name : scene->directory + "/" + k_wrapper_name;
  const std::string source = scene->directory.empty() ? scene->file_name : scene->directory + "/" + scene->file_name;
  char error[1024] = "";
  mjModel* m = mj_loadXML(path.c_str(), vfs.get(), error, sizeof error);
  if (!m) throw MujocoError(error[0] ? error : "MuJoCo could not compile it");

  if (last_is_new && !entities.empty()) {
    ModelCounts before = scene->counts;
    for (std::size_t i = 0; i + 1 < entities.size(); ++i) before += entities[i].counts;
    entities.back().counts = ModelCounts::of(m) - before;
  }
  return Model::adopt(m, source, scene, std::move(entities));
}

void carry_state(const Model& from, Model& to) {
  const mjData* old = from.data();
  mjData* data = to.data();
  const SceneSource& scene = *to.scene();
  // the scene's block starts every model
  copy_state_block(old, ModelCounts{}, data, ModelCounts{}, scene.counts);
  // each entity both hold, wherever it sits in each
  const std::vector<ModelCounts> from_starts = block_starts(*from.scene(), from.entities());
  const std::vector<ModelCounts> to_starts = block_starts(scene, to.entities());
  for (std::size_t i = 0; i < to.entities().size(); ++i) {
    const SpawnedEntity& entity = to.entities()[i];
    for (std::size_t j = 0; j < from.entities().size(); ++j) {
      const SpawnedEntity& was = from.entities()[j];
      if (was.name != entity.name || !same_state_size(was.counts, entity.counts)) continue;
      copy_state_block(old, from_starts[j], data, to_starts[i], entity.counts);
    }
  }
  data->time = old->time;
  std::copy(std::begin(old->warning), std::end(old->warning), std::begin(data->warning));
}

}  // namespace simgate::sim
