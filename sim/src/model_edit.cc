#include "simgate/sim/model_edit.h"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <functional>
#include <set>

#include <tinyxml2.h>

#include "simgate/core/errors.h"
#include "simgate/sim/object_state.h"
#include "urdf.h"

namespace simgate::sim {

namespace {

// The sections of a <mujoco> fragment that can belong to one entity. Not <option>,
// <compiler>, <size>, <visual>, <statistic>: they are the scene's; not <keyframe>: a key
// is a state of the whole world (MuJoCo extends the scene's keys with the entity's initial state).
const std::set<std::string, std::less<>> k_entity_sections = {
    "asset", "default", "worldbody", "actuator", "sensor", "tendon", "equality", "contact"};

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
  if (std::strcmp(element.Name(), "include") == 0)
    refuse("<include> is not allowed in a spawned fragment");
  for (const tinyxml2::XMLAttribute* a = element.FirstAttribute(); a; a = a->Next()) {
    if (std::strncmp(a->Name(), "file", 4) != 0) continue;
    const std::string file = a->Value();
    if (file.starts_with('/') || file == ".." || file.starts_with("../") ||
        file.find("/../") != std::string::npos || file.ends_with("/.."))
      refuse(
          "<" + std::string(element.Name()) + " " + a->Name() + "=\"" + file +
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

}  // namespace

std::string entity_mjcf(const std::string& fragment, const std::string& name,
                        const EntityPose& pose) {
  tinyxml2::XMLDocument doc;
  if (doc.Parse(fragment.data(), fragment.size()) != tinyxml2::XML_SUCCESS)
    refuse(std::string("not well-formed XML: ") + doc.ErrorStr());
  tinyxml2::XMLElement* root = doc.RootElement();
  if (!root)
    refuse("expected MJCF text: a <body>, or a <mujoco> with a <worldbody> holding one <body>");
  if (root->NextSiblingElement()) refuse("expected one root element, found several");
  check_files(*root);

  const std::string root_name = root->Name();
  if (root_name == "body") {
    place(*root, name, pose);
    return "<mujoco><worldbody>" + text_of(*root) + "</worldbody></mujoco>";
  }
  if (root_name != "mujoco")
    refuse("expected a <body> or a <mujoco> root element (or a URDF <robot>), found <" + root_name +
           ">");

  tinyxml2::XMLElement* body = nullptr;
  for (auto* section = root->FirstChildElement(); section;
       section = section->NextSiblingElement()) {
    const std::string section_name = section->Name();
    if (!k_entity_sections.contains(section_name))
      refuse("<" + section_name +
             "> cannot be spawned: a fragment's sections are asset, default, worldbody, actuator, "
             "sensor, "
             "tendon, equality, contact");
    if (section_name == "worldbody") {
      for (auto* child = section->FirstChildElement(); child; child = child->NextSiblingElement()) {
        if (std::strcmp(child->Name(), "body") != 0 || body)
          refuse(
              "the <worldbody> of a spawned fragment holds exactly one <body> (the entity), found "
              "<" +
              std::string(child->Name()) + ">" + (body ? " beside it" : ""));
        body = child;
      }
    }
  }
  if (!body) refuse("a <mujoco> fragment needs a <worldbody> holding one <body>");
  place(*body, name, pose);
  return text_of(*root);
}

EntityDocument entity_document(const std::string& fragment, const std::string& name,
                               const EntityPose& pose) {
  if (!is_urdf(fragment)) return {entity_mjcf(fragment, name, pose), false, pose};
  // MuJoCo's URDF parser keeps file names' base names only (strippath): a mesh resolves in
  // the scene's mesh directory, wherever the URDF says it is
  return {fragment, true, pose};
}

EditBase EditBase::of(const Model& model) {
  return {model.spec(), model.source(), model.entities(), ModelCounts::of(model.model())};
}

namespace {

// Copies the spec an edit starts from.
std::shared_ptr<mjSpec> copy_of(const EditBase& base) {
  install_mujoco_handlers();
  mjSpec* copy = mj_copySpec(base.spec.get());
  if (!copy) throw MujocoError("MuJoCo could not copy the model's specification");
  return Model::own(copy);
}

// The frame of the world an entity is attached to (MuJoCo attaches a body to a frame), named
// so that deleting the entity deletes it too (nothing else is in it): without that, every
// spawn and delete would leave an empty frame, and the spec would grow for good.
std::string entity_frame(const std::string& entity) { return "simgate-entity:" + entity; }

// The root link of a parsed URDF robot, named `name` and placed at `document.pose`, with an
// actuator per transmission joint.
mjsBody* urdf_root(mjSpec* entity, const std::string& name, const EntityDocument& document) {
  const std::string source = "entity '" + name + "'";
  add_transmission_actuators(entity, source, document.text);
  mjsBody* world = mjs_findBody(entity, "world");
  mjsElement* root = world ? mjs_firstChild(world, mjOBJ_BODY, 0) : nullptr;
  if (!root || mjs_nextChild(world, root, 0))
    throw MujocoError(
        source +
        ": a spawned URDF robot has one root link (one link no joint has as its child), "
        "found " +
        std::string(root ? "several" : "none"));
  mjsBody* body = mjs_asBody(root);
  mjs_setName(root, name.c_str());
  std::copy(document.pose.position.begin(), document.pose.position.end(), body->pos);
  if (document.pose.orientation) {
    std::copy(document.pose.orientation->begin(), document.pose.orientation->end(), body->quat);
    body->alt.type = mjORIENTATION_QUAT;
  }
  return body;
}

}  // namespace

Model with_entity(const EditBase& base, const std::string& name, const EntityDocument& document) {
  std::shared_ptr<mjSpec> spec = copy_of(base);
  std::shared_ptr<mjSpec> entity = parse_spec(name, &document.text, "");
  // its files resolve where the scene's do
  mjs_setString(entity->modelfiledir, mjs_getString(spec->modelfiledir));
  mjs_setString(entity->compiler.meshdir, mjs_getString(spec->compiler.meshdir));
  mjs_setString(entity->compiler.texturedir, mjs_getString(spec->compiler.texturedir));
  mjsBody* body = document.urdf ? urdf_root(entity.get(), name, document)
                                : mjs_findBody(entity.get(), name.c_str());
  mjsBody* world = mjs_findBody(spec.get(), "world");
  if (!body || !world)
    throw MujocoError("the entity's body '" + name + "' is missing from its own document");
  // after everything the world holds, its names as written (no prefix)
  mjsFrame* frame = mjs_addFrame(world, nullptr);
  mjs_setName(frame->element, entity_frame(name).c_str());
  if (!mjs_attach(frame->element, body->element, "", ""))
    throw MujocoError(mjs_getError(spec.get()));
  mjModel* m = compile_spec(spec.get(), "");
  std::vector<SpawnedEntity> entities = base.entities;
  entities.push_back({name, ModelCounts::of(m) - base.counts});
  return Model::adopt(m, base.source, std::move(spec), std::move(entities));
}

Model without_body(const EditBase& base, int body, const std::string& name) {
  std::shared_ptr<mjSpec> spec = copy_of(base);
  // the element the running model numbered `body` (a copy keeps the ids of the last compile)
  mjsElement* element = mjs_firstElement(spec.get(), mjOBJ_BODY);
  while (element && mjs_getId(element) != body) element = mjs_nextElement(spec.get(), element);
  if (!element) throw MujocoError("body '" + name + "' is not in the model's specification");
  if (mjs_delete(spec.get(), element) != 0) throw MujocoError(mjs_getError(spec.get()));
  // a spawned entity's frame, empty now
  if (mjsElement* frame = mjs_findElement(spec.get(), mjOBJ_FRAME, entity_frame(name).c_str()))
    if (mjs_delete(spec.get(), frame) != 0) throw MujocoError(mjs_getError(spec.get()));
  mjModel* m = compile_spec(spec.get(), "");
  std::vector<SpawnedEntity> entities = base.entities;
  std::erase_if(entities, [&](const SpawnedEntity& e) { return e.name == name; });
  return Model::adopt(m, base.source, std::move(spec), std::move(entities));
}

void carry_state(const Model& from, Model& to, const ModelRemap& remap) {
  ObjectState state;
  state.capture(from.model(), from.data());
  state.put(to.model(), to.data(), ObjectState::through(remap));
  const mjData* old = from.data();
  to.data()->time = old->time;
  std::copy(std::begin(old->warning), std::end(old->warning), std::begin(to.data()->warning));
}

}  // namespace simgate::sim
