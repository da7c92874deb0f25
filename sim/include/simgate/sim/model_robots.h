// simgate/sim/model_robots.h — the robots of any MJCF model, found without a hand-written
// component list: what `simgate run --model FILE.xml` serves, and what a robot of "type":
// "mjcf" in a config gets.
//
// Rules (documented in docs/configuration.md, "Your own model"):
//  - generic components: a robot rooted at a body gets `armature` and `armature_pose` when
//    its subtree has hinge or slide joints (joints.h), `actuators` when actuators act on it
//    (actuator_kind.h), `sensors` when MJCF <sensor>s are attached to it
//    (actuators_sensors.h), and `pose` and `odometry` when the root body has a free joint
//    of its own (a floating base: a humanoid, a quadruped, a drone); each is named
//    "<robot>.<type>".
//  - robots of a model: every top-level body (a child of the world body) that gets at
//    least one generic component and is not scenery. A body with nothing but a free joint
//    (a box, a ball) is an object, not a robot; one that nothing acts on or senses and that
//    only slides or floats (no hinge, no ball joint: a particle of a <composite>,
//    <replicate> or flex) is scenery.
//  - names: the body's MJCF name, with every character other than a letter, a digit, '_'
//    or '-' replaced by '_' (a '.' would split the component names); an unnamed body is
//    "body<id>"; a name already taken (an earlier robot, "simulation", "time") gets "_2",
//    "_3", ... The order is MuJoCo's body order, so the names are stable for a given model.
//
// Threads: none of its own (pure functions of the immutable mjModel).
#ifndef SIMGATE_SIM_MODEL_ROBOTS_H_
#define SIMGATE_SIM_MODEL_ROBOTS_H_

#include <string>
#include <vector>

#include "simgate/sim/model.h"

namespace simgate::sim {

// The generic component types of the robot rooted at `body`, in this order: armature,
// armature_pose, actuators, sensors, pose, odometry (those it has).
std::vector<std::string> generic_components(const mjModel* m, int body);

struct ModelRobot {
  std::string name;                     // the robot's name (see the rules)
  std::string body;                     // its root body, as Model::body_name spells it
  std::vector<std::string> components;  // generic_components() of that body
};

// Every robot of `model`, in body order.
std::vector<ModelRobot> find_model_robots(const Model& model);

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_MODEL_ROBOTS_H_
