#include "simgate/sim/model_edit.h"

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <map>
#include <functional>
#include <set>
#include <sstream>
#include <string_view>

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

// The kind of object an MJCF attribute names (references from actuators, sensors,
// tendons, equalities, contact pairs and excludes), or null.
const char* kind_named_by(const tinyxml2::XMLElement& element, const char* attribute) {
  static const std::map<std::string, const char*, std::less<>> kinds = {
      {"joint", "joint"},    {"jointinparent", "joint"}, {"joint1", "joint"},     {"joint2", "joint"},
      {"tendon", "tendon"},  {"tendon1", "tendon"},      {"tendon2", "tendon"},   {"site", "site"},
      {"cranksite", "site"}, {"slidersite", "site"},     {"refsite", "site"},     {"body", "body"},
      {"body1", "body"},     {"body2", "body"},          {"geom", "geom"},        {"geom1", "geom"},
      {"geom2", "geom"},     {"actuator", "actuator"}};
  const std::string_view name = attribute;
  if (name == "objname" || name == "refname") {
    const char* type = element.Attribute(name == "objname" ? "objtype" : "reftype");
    const std::string t = type ? type : "";
    if (t == "body" || t == "xbody") return "body";
    for (const char* k : {"joint", "geom", "site", "camera", "tendon", "actuator"})
      if (t == k) return k;
    return "any";
  }
  auto it = kinds.find(name);
  return it == kinds.end() ? nullptr : it->second;
}

// Names removed, by kind ("body", "joint"...).
using RemovedNames = std::map<std::string, std::set<std::string>, std::less<>>;

bool refers_to(const tinyxml2::XMLElement& element, const RemovedNames& removed) {
  for (const tinyxml2::XMLAttribute* a = element.FirstAttribute(); a; a = a->Next()) {
    const char* kind = kind_named_by(element, a->Name());
    if (!kind) continue;
    for (const auto& [k, names] : removed)
      if ((std::string_view(kind) == "any" || k == kind) && names.contains(a->Value())) return true;
  }
  for (const auto* child = element.FirstChildElement(); child; child = child->NextSiblingElement())
    if (refers_to(*child, removed)) return true;
  return false;
}

// Adds the names of `element`'s subtree (bodies, joints, geoms, sites, cameras, lights).
void collect_names(const tinyxml2::XMLElement& element, RemovedNames& removed) {
  std::string kind = element.Name();
  if (kind == "freejoint") kind = "joint";
  if (const char* name = element.Attribute("name"))
    if (std::set<std::string>{"body", "joint", "geom", "site", "camera", "light"}.contains(kind))
      removed[kind].insert(name);
  for (const auto* child = element.FirstChildElement(); child; child = child->NextSiblingElement())
    collect_names(*child, removed);
}

[[noreturn]] void refuse_body(const std::string& body, const std::string& why) {
  throw ServiceError("body '" + body + "' " + why, Failure::bad_arguments, {{"parameter", "name"}});
}

tinyxml2::XMLElement* find_body(tinyxml2::XMLElement& parent, const std::string& name) {
  for (auto* child = parent.FirstChildElement(); child; child = child->NextSiblingElement()) {
    if (std::strcmp(child->Name(), "body") == 0 && child->Attribute("name", name.c_str())) return child;
    if (auto* found = find_body(*child, name)) return found;
  }
  return nullptr;
}

// Whether the text holds a <key> in a <keyframe> section (parsed: a comment or an attribute
// value that mentions one does not count).
bool has_keyframes(const tinyxml2::XMLDocument& doc) {
  const tinyxml2::XMLElement* root = doc.RootElement();
  for (auto* keys = root ? root->FirstChildElement("keyframe") : nullptr; keys;
       keys = keys->NextSiblingElement("keyframe"))
    if (keys->FirstChildElement("key")) return true;
  return false;
}

std::string printed(const tinyxml2::XMLDocument& doc) {
  tinyxml2::XMLPrinter printer;
  doc.Print(&printer);
  return printer.CStr();
}

// The numbers of a keyframe attribute ("0 0 1.2 1 0 0 0").
std::vector<double> parse_numbers(const char* text) {
  std::vector<double> out;
  std::istringstream in(text ? text : "");
  for (double v; in >> v;) out.push_back(v);
  return out;
}

// MuJoCo 2.2.2 wants each of a keyframe's arrays to be the whole model's size, so a scene's
// keys no longer fit once entities are added. Each array a key gives is padded with the
// added objects' initial state, read off `bare` (the same model compiled without keyframes):
// qpos with qpos0, qvel, act and ctrl with zeros, mpos and mquat with the mocap bodies'
// poses. What a key leaves out, MuJoCo fills itself.
void pad_keyframes(tinyxml2::XMLDocument& doc, const mjModel* bare) {
  std::vector<const double*> mocap_pos, mocap_quat;  // by mocap id
  mocap_pos.resize(bare->nmocap);
  mocap_quat.resize(bare->nmocap);
  for (int b = 0; b < bare->nbody; ++b)
    if (const int id = bare->body_mocapid[b]; id >= 0) {
      mocap_pos[id] = bare->body_pos + 3 * b;
      mocap_quat[id] = bare->body_quat + 4 * b;
    }
  // an array's size in the whole model, and the value of its i-th number when added
  struct Array {
    const char* attribute;
    std::int64_t size;  // mjtSize (64 bits)
    std::function<double(int)> initial;
  };
  const std::vector<Array> arrays = {
      {"qpos", bare->nq, [&](int i) { return bare->qpos0[i]; }},
      {"qvel", bare->nv, [](int) { return 0.0; }},
      {"act", bare->na, [](int) { return 0.0; }},
      {"ctrl", bare->nu, [](int) { return 0.0; }},
      {"mpos", 3 * bare->nmocap, [&](int i) { return mocap_pos[i / 3][i % 3]; }},
      {"mquat", 4 * bare->nmocap, [&](int i) { return mocap_quat[i / 4][i % 4]; }},
  };
  for (auto* keys = doc.RootElement()->FirstChildElement("keyframe"); keys; keys = keys->NextSiblingElement("keyframe"))
    for (auto* key = keys->FirstChildElement("key"); key; key = key->NextSiblingElement("key"))
      for (const Array& a : arrays) {
        const char* given = key->Attribute(a.attribute);
        if (!given) continue;
        std::vector<double> values = parse_numbers(given);
        if (values.size() >= static_cast<std::size_t>(a.size)) continue;  // MuJoCo says what is wrong
        for (int i = static_cast<int>(values.size()); i < a.size; ++i) values.push_back(a.initial(i));
        key->SetAttribute(a.attribute, numbers(values.data(), static_cast<int>(values.size())).c_str());
      }
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

std::shared_ptr<SceneSource> scene_without(const SceneSource& scene, const std::string& body) {
  tinyxml2::XMLDocument doc;
  if (doc.Parse(scene.xml.data(), scene.xml.size()) != tinyxml2::XML_SUCCESS)
    refuse_body(body, std::string("cannot be deleted: the scene's text does not parse: ") + doc.ErrorStr());
  tinyxml2::XMLElement* root = doc.RootElement();
  tinyxml2::XMLElement* element = nullptr;
  for (auto* section = root ? root->FirstChildElement("worldbody") : nullptr; section && !element;
       section = section->NextSiblingElement("worldbody"))
    element = find_body(*section, body);
  if (!element)
    refuse_body(body, "cannot be deleted: it is not written in the scene file '" + scene.file_name +
                "' itself (a body of an included file, or an unnamed body, stays)");
  for (auto* keys = root->FirstChildElement("keyframe"); keys; keys = keys->NextSiblingElement("keyframe"))
    if (keys->FirstChildElement())
      refuse_body(body, "cannot be deleted: the scene has keyframes, whose sizes are the whole model's");

  RemovedNames removed;
  collect_names(*element, removed);
  element->Parent()->DeleteChild(element);
  // what refers to the removed objects goes too, and what refers to that (a tendon, then its actuator)
  static const std::map<std::string, std::string, std::less<>> named_kind = {{"tendon", "tendon"},
                                                                              {"actuator", "actuator"}};
  for (bool changed = true; changed;) {
    changed = false;
    for (auto* section = root->FirstChildElement(); section; section = section->NextSiblingElement()) {
      const std::string section_name = section->Name();
      if (!std::set<std::string>{"actuator", "sensor", "tendon", "equality", "contact"}.contains(section_name))
        continue;
      for (auto* item = section->FirstChildElement(); item;) {
        auto* next = item->NextSiblingElement();
        if (refers_to(*item, removed)) {
          auto kind = named_kind.find(section_name);
          if (const char* name = item->Attribute("name"); name && kind != named_kind.end())
            removed[kind->second].insert(name);
          section->DeleteChild(item);
          changed = true;
        }
        item = next;
      }
    }
  }
  tinyxml2::XMLPrinter printer;
  doc.Print(&printer);
  auto edited = std::make_shared<SceneSource>(scene);
  edited->xml = printer.CStr();
  return edited;
}

Model compile_scene(const std::shared_ptr<const SceneSource>& scene, std::vector<SpawnedEntity> entities,
                    bool last_is_new, SceneSource* measure_scene) {
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
    if (mj_addBufferVFS(vfs.get(), file, text.data(), static_cast<int>(text.size())) != 0)
      throw MujocoError("scene '" + scene->file_name + "': could not create the virtual file '" + file + "'");
  };
  add(k_wrapper_name, wrapper);
  // as if beside the scene file: relative names resolve in its directory
  const std::string path = scene->directory.empty() ? k_wrapper_name : scene->directory + "/" + k_wrapper_name;
  const std::string source = scene->directory.empty() ? scene->file_name : scene->directory + "/" + scene->file_name;
  // compiles the wrapper with `scene_text` as the scene's file
  auto load = [&](const std::string& scene_text) {
    if (mj_containsBufferVFS(vfs.get(), scene->file_name.c_str())) mj_deleteFileVFS(vfs.get(), scene->file_name.c_str());
    add(scene->file_name.c_str(), scene_text);
    char error[1024] = "";
    mjModel* m = mj_loadXML(path.c_str(), vfs.get(), error, sizeof error);
    if (!m) throw MujocoError(error[0] ? error : "MuJoCo could not compile it");
    return m;
  };
  // a scene with keyframes: compiled once without them, to learn the whole model's sizes,
  // then with its keys padded to them (pad_keyframes)
  std::string scene_text = scene->xml;
  if (!entities.empty()) {
    tinyxml2::XMLDocument doc;
    if (doc.Parse(scene->xml.data(), scene->xml.size()) == tinyxml2::XML_SUCCESS && has_keyframes(doc)) {
      tinyxml2::XMLDocument bare_doc;
      doc.DeepCopy(&bare_doc);
      for (auto* keys = bare_doc.RootElement()->FirstChildElement("keyframe"); keys;) {
        auto* next = keys->NextSiblingElement("keyframe");
        bare_doc.RootElement()->DeleteChild(keys);
        keys = next;
      }
      mjModel* bare = load(printed(bare_doc));
      try {
        pad_keyframes(doc, bare);
      } catch (...) {
        mj_deleteModel(bare);
        throw;
      }
      mj_deleteModel(bare);
      scene_text = printed(doc);
    }
  }
  mjModel* m = load(scene_text);

  if (measure_scene) {
    ModelCounts entities_counts;
    for (const auto& e : entities) entities_counts += e.counts;
    measure_scene->counts = ModelCounts::of(m) - entities_counts;
  }
  if (last_is_new && !entities.empty()) {
    ModelCounts before = scene->counts;
    for (std::size_t i = 0; i + 1 < entities.size(); ++i) before += entities[i].counts;
    entities.back().counts = ModelCounts::of(m) - before;
  }
  return Model::adopt(m, source, scene, std::move(entities));
}

void carry_state(const Model& from, Model& to, const ModelRemap& remap) {
  const mjModel* m0 = from.model();
  const mjModel* m1 = to.model();
  const mjData* old = from.data();
  mjData* data = to.data();
  for (int j = 0; j < m0->njnt; ++j) {
    const int k = remap.joint_of(j);
    if (k < 0) continue;
    const int type = m0->jnt_type[j];
    const int nq = type == mjJNT_FREE ? 7 : type == mjJNT_BALL ? 4 : 1;
    const int nv = type == mjJNT_FREE ? 6 : type == mjJNT_BALL ? 3 : 1;
    std::copy_n(old->qpos + m0->jnt_qposadr[j], nq, data->qpos + m1->jnt_qposadr[k]);
    const int from_dof = m0->jnt_dofadr[j], to_dof = m1->jnt_dofadr[k];
    std::copy_n(old->qvel + from_dof, nv, data->qvel + to_dof);
    std::copy_n(old->qacc_warmstart + from_dof, nv, data->qacc_warmstart + to_dof);
    std::copy_n(old->qfrc_applied + from_dof, nv, data->qfrc_applied + to_dof);
  }
  // MuJoCo 2.2.2 keeps the actuators with an activation last: act[i] is actuator nu - na + i's
  const int stateful_from = m0->nu - m0->na, stateful_to = m1->nu - m1->na;
  for (int a = 0; a < m0->nu; ++a) {
    const int k = remap.actuator_of(a);
    if (k < 0) continue;
    data->ctrl[k] = old->ctrl[a];
    if (a >= stateful_from && k >= stateful_to) data->act[k - stateful_to] = old->act[a - stateful_from];
  }
  for (int b = 0; b < m0->nbody; ++b) {
    const int k = remap.body_of(b);
    if (k < 0) continue;
    std::copy_n(old->xfrc_applied + 6 * b, 6, data->xfrc_applied + 6 * k);
    const int mocap = m0->body_mocapid[b], to_mocap = m1->body_mocapid[k];
    if (mocap < 0 || to_mocap < 0) continue;
    std::copy_n(old->mocap_pos + 3 * mocap, 3, data->mocap_pos + 3 * to_mocap);
    std::copy_n(old->mocap_quat + 4 * mocap, 4, data->mocap_quat + 4 * to_mocap);
  }
  data->time = old->time;
  std::copy(std::begin(old->warning), std::end(old->warning), std::begin(data->warning));
}

}  // namespace simgate::sim
