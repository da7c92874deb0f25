#include "simgate/sim/model_robots.h"

#include <cctype>
#include <set>

#include "simgate/sim/actuator_kind.h"
#include "simgate/sim/joints.h"
#include "simgate/sim/sim_component.h"

namespace simgate::sim {

namespace {

bool has_actuator(const mjModel* m, int root) {
  for (int a = 0; a < m->nu; ++a)
    if (actuator_in_subtree(m, a, root)) return true;
  return false;
}

bool has_sensor(const mjModel* m, int root) {
  for (int s = 0; s < m->nsensor; ++s)
    if (sensor_in_subtree(m, s, root)) return true;
  return false;
}

// The root body has a free joint of its own: a floating base (a humanoid, a drone, a
// quadruped), whose pose and odometry a user wants.
bool has_floating_base(const mjModel* m, int body) {
  for (int j = m->body_jntadr[body]; j >= 0 && j < m->body_jntadr[body] + m->body_jntnum[body]; ++j)
    if (m->jnt_type[j] == mjJNT_FREE) return true;
  return false;
}

// Nothing acts on it or senses it, and it only slides or floats (no hinge, no ball joint):
// a particle of a <composite>, a <replicate> or a flex (MuJoCo's composite samples were 1000
// robots of 27 000 services), not a robot.
bool is_scenery(const mjModel* m, int root) {
  if (has_actuator(m, root) || has_sensor(m, root)) return false;
  for (int j = 0; j < m->njnt; ++j)
    if ((m->jnt_type[j] == mjJNT_HINGE || m->jnt_type[j] == mjJNT_BALL) &&
        in_subtree(m, m->jnt_bodyid[j], root))
      return false;
  return true;
}

// letters, digits, '_' and '-' only: the deployment's rule for robot names
std::string robot_name_of(const std::string& body) {
  std::string name = body;
  for (char& c : name)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-')) c = '_';
  return name;
}

}  // namespace

std::vector<std::string> generic_components(const mjModel* m, int body) {
  std::vector<std::string> types;
  if (JointSet::of_subtree(m, body).size() > 0) {
    types.push_back("armature");
    types.push_back("armature_pose");
  }
  if (has_actuator(m, body)) types.push_back("actuators");
  if (has_sensor(m, body)) types.push_back("sensors");
  if (!types.empty() && has_floating_base(m, body)) {
    types.push_back("pose");
    types.push_back("odometry");
  }
  return types;
}

std::vector<ModelRobot> find_model_robots(const Model& model) {
  const mjModel* m = model.model();
  std::vector<ModelRobot> robots;
  std::set<std::string> taken{"simulation", "time", "communication"};
  for (int b = 1; b < m->nbody; ++b) {
    if (m->body_parentid[b] != 0) continue;  // top-level bodies only
    if (is_scenery(m, b)) continue;
    std::vector<std::string> components = generic_components(m, b);
    if (components.empty()) continue;
    const std::string base = robot_name_of(model.body_name(b));
    std::string name = base;
    for (int n = 2; taken.count(name); ++n) name = base + "_" + std::to_string(n);
    taken.insert(name);
    robots.push_back({name, model.body_name(b), std::move(components)});
  }
  return robots;
}

}  // namespace simgate::sim
