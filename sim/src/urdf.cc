// URDF scenes: MuJoCo's parser, plus an actuator per transmission joint (urdf.h).
#include "urdf.h"

#include <algorithm>
#include <cctype>
#include <vector>

#include <tinyxml2.h>

#include "simgate/core/log.h"
#include "simgate/sim/model.h"

namespace simgate::sim {

namespace {

enum class Interface { position, velocity, effort };

// One joint a transmission (or a ros2_control block) drives.
struct Drive {
  std::string joint;
  std::string actuator;  // the actuator's name
  Interface interface;
  // the joint's <limit> (0 when absent)
  double lower = 0, upper = 0, effort = 0, velocity = 0;
  bool has_range = false;
};

std::string lowercase(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

const char* element_text(const tinyxml2::XMLElement* e) {
  return e && e->GetText() ? e->GetText() : "";
}
std::string attribute(const tinyxml2::XMLElement* e, const char* name) {
  const char* value = e ? e->Attribute(name) : nullptr;
  return value ? value : "";
}

// position, velocity or effort, by name ("hardware_interface/PositionJointInterface",
// ros2_control's "position"...); false when it is none of them
bool interface_of(const std::string& name, Interface& out) {
  const std::string n = lowercase(name);
  if (n.find("position") != std::string::npos)
    out = Interface::position;
  else if (n.find("velocity") != std::string::npos)
    out = Interface::velocity;
  else if (n.find("effort") != std::string::npos)
    out = Interface::effort;
  else
    return false;
  return true;
}

// The joints the URDF's <transmission> and <ros2_control> elements drive, in order, each once.
std::vector<Drive> drives_of(const tinyxml2::XMLElement* robot, const std::string& source) {
  std::vector<Drive> drives;
  auto add = [&](const std::string& joint, const std::string& actuator,
                 const std::string& interface, const std::string& where) {
    if (joint.empty()) throw MujocoError(source + ": " + where + " names no joint");
    for (const Drive& d : drives)
      if (d.joint == joint) return;  // a joint in both a transmission and ros2_control
    Drive d;
    d.joint = joint;
    d.actuator = actuator.empty() ? joint + "_actuator" : actuator;
    if (!interface_of(interface, d.interface))
      throw MujocoError(source + ": " + where + " drives joint '" + joint + "' through '" +
                        interface + "': simgate knows position, velocity and effort interfaces");
    drives.push_back(std::move(d));
  };
  for (auto* t = robot->FirstChildElement("transmission"); t;
       t = t->NextSiblingElement("transmission")) {
    const std::string where = "transmission '" + attribute(t, "name") + "'";
    const auto* actuator = t->FirstChildElement("actuator");
    for (auto* j = t->FirstChildElement("joint"); j; j = j->NextSiblingElement("joint")) {
      // the interface is the joint's (ROS 1 Kinetic on), or the actuator's (older URDF)
      std::string interface = element_text(j->FirstChildElement("hardwareInterface"));
      if (interface.empty() && actuator)
        interface = element_text(actuator->FirstChildElement("hardwareInterface"));
      add(attribute(j, "name"), attribute(actuator, "name"), interface, where);
    }
  }
  for (auto* block = robot->FirstChildElement("ros2_control"); block;
       block = block->NextSiblingElement("ros2_control")) {
    for (auto* j = block->FirstChildElement("joint"); j; j = j->NextSiblingElement("joint")) {
      const auto* command = j->FirstChildElement("command_interface");
      if (!command) continue;  // state only: nothing drives it
      const std::string joint = attribute(j, "name");
      add(joint, "", attribute(command, "name"), "ros2_control joint '" + joint + "'");
    }
  }
  // each joint's limits
  for (Drive& d : drives) {
    for (auto* j = robot->FirstChildElement("joint"); j; j = j->NextSiblingElement("joint")) {
      if (!j->Attribute("name", d.joint.c_str())) continue;
      if (const auto* limit = j->FirstChildElement("limit")) {
        d.effort = limit->DoubleAttribute("effort", 0.0);
        d.velocity = limit->DoubleAttribute("velocity", 0.0);
        d.lower = limit->DoubleAttribute("lower", 0.0);
        d.upper = limit->DoubleAttribute("upper", 0.0);
        // a continuous joint has no range (nor does a limit with lower == upper)
        d.has_range = !j->Attribute("type", "continuous") && d.lower < d.upper;
      }
      break;
    }
  }
  return drives;
}

void add_actuator(mjSpec* spec, const Drive& d, const std::string& source) {
  if (!mjs_findElement(spec, mjOBJ_JOINT, d.joint.c_str()))
    throw MujocoError(source + ": a transmission drives joint '" + d.joint +
                      "', which the robot does not have");
  mjsActuator* a = mjs_addActuator(spec, nullptr);
  mjs_setName(a->element, d.actuator.c_str());
  a->trntype = mjTRN_JOINT;
  mjs_setString(a->target, d.joint.c_str());
  const char* error = nullptr;
  switch (d.interface) {
    case Interface::position: {
      double dampratio[1] = {1.0};
      error = mjs_setToPosition(a, d.effort > 0 ? d.effort / 0.1 : 100.0, nullptr, dampratio,
                                nullptr, 0.0);
      if (d.has_range) {
        a->ctrllimited = mjLIMITED_TRUE;
        a->ctrlrange[0] = d.lower, a->ctrlrange[1] = d.upper;
      }
      break;
    }
    case Interface::velocity:
      error = mjs_setToVelocity(a, d.effort > 0 ? d.effort : 10.0);
      if (d.velocity > 0) {
        a->ctrllimited = mjLIMITED_TRUE;
        a->ctrlrange[0] = -d.velocity, a->ctrlrange[1] = d.velocity;
      }
      break;
    case Interface::effort:
      error = mjs_setToMotor(a);
      if (d.effort > 0) {
        a->ctrllimited = mjLIMITED_TRUE;
        a->ctrlrange[0] = -d.effort, a->ctrlrange[1] = d.effort;
      }
      break;
  }
  if (error && *error) throw MujocoError(source + ": actuator '" + d.actuator + "': " + error);
  if (d.effort > 0 && d.interface != Interface::effort) {
    a->forcelimited = mjLIMITED_TRUE;
    a->forcerange[0] = -d.effort, a->forcerange[1] = d.effort;
  }
}

}  // namespace

bool is_urdf(const std::string& text) {
  tinyxml2::XMLDocument doc;
  if (doc.Parse(text.data(), text.size()) != tinyxml2::XML_SUCCESS) return false;
  const auto* root = doc.RootElement();
  return root && std::string(root->Name()) == "robot";
}

void add_transmission_actuators(mjSpec* spec, const std::string& source, const std::string& text) {
  tinyxml2::XMLDocument doc;
  doc.Parse(text.data(), text.size());
  const std::vector<Drive> drives = drives_of(doc.RootElement(), source);
  for (const Drive& d : drives) add_actuator(spec, d, source);
  if (!drives.empty())
    log::info(source, ": ", drives.size(), " actuator(s) from its transmissions");
}

}  // namespace simgate::sim
