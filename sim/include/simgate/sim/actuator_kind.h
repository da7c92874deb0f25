// simgate/sim/actuator_kind.h — what a MuJoCo actuator is, and what of a robot it moves.
//
// MuJoCo compiles every actuator element (<motor>, <position>, <velocity>, <muscle>, ...)
// into one <general> form: a transmission (joint, tendon, site, slider-crank, body), a
// dynamics type, a gain and a bias. The element's name is gone from the compiled model;
// actuator_type() recognises it again from the parameters each shortcut sets (MuJoCo
// XML reference), so a <general> written in the shape of a <position> is reported
// as "position" — it behaves as one.
//
// Ownership: an actuator belongs to a robot when what it moves is attached to a body of the
// robot's subtree (in_subtree, sim_component.h): the joint's body, the site's body, the
// crank site's body of a slider-crank, the body of an adhesion, and for a tendon any of the
// bodies along its path (a tendon between two robots belongs to both).
//
// Threads: none of its own (pure functions of the immutable mjModel).
#ifndef SIMGATE_SIM_ACTUATOR_KIND_H_
#define SIMGATE_SIM_ACTUATOR_KIND_H_

#include <string>

#include <mujoco/mujoco.h>

namespace simgate::sim {

// The MJCF element actuator `a` matches: "motor", "position", "velocity", "intvelocity",
// "damper", "cylinder", "muscle", "adhesion", or "general" for any other combination.
const char* actuator_type(const mjModel* m, int a);

// A velocity servo, the shape of <velocity kv="..">: fixed gain kv, affine bias -kv times the
// velocity, nothing of the position (whatever the dynamics).
bool is_velocity_actuator(const mjModel* m, int a);
// A position servo, the shape of <position kp="..">: fixed gain kp, affine bias -kp times the
// position, no internal dynamics.
bool is_position_actuator(const mjModel* m, int a);

// What an actuator is, from its gain and bias, for error messages: "a motor (torque: fixed
// gain, no bias)", "a position servo (kp=10: ...)", "a general actuator (gaintype ...)".
std::string describe_actuator(const mjModel* m, int a);

// True when the tendon's path holds a joint, site or geom attached to a body of `root`'s
// subtree (the world body itself never counts: every spatial tendon may start on it).
bool tendon_in_subtree(const mjModel* m, int tendon, int root);
// True when what actuator `a` moves is attached to a body of `root`'s subtree (see above).
bool actuator_in_subtree(const mjModel* m, int a, int root);
// True when MJCF sensor `s` is the robot's: its object (site, joint, body, geom, camera) is
// attached to a body of `root`'s subtree; a tendon or actuator sensor follows its tendon or
// actuator (above). A sensor on no object (<clock>) is nobody's.
bool sensor_in_subtree(const mjModel* m, int s, int root);

// The body an object is attached to (`type`: mjOBJ_BODY, mjOBJ_XBODY, mjOBJ_JOINT, mjOBJ_GEOM,
// mjOBJ_SITE or mjOBJ_CAMERA), or -1 for other types and ids < 0.
int object_body(const mjModel* m, int type, int id);

// The object's MJCF name, or "<kind><id>" ("joint3", "site0") when it has none, as
// Model::body_name does for bodies. `type`: an mjtObj.
std::string mujoco_name(const mjModel* m, int type, int id);

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_ACTUATOR_KIND_H_
