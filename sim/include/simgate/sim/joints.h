// simgate/sim/joints.h — the joints of a robot an armature moves and an armature pose reads.
//
// Terms:
//  - armature joint: a hinge or slide joint of a body in the subtree of the component's body
//    (its robot's root body unless the config binds it elsewhere). MORSE's armatures are
//    chains of revolute and prismatic joints, and these are the two one-number MuJoCo
//    joints. A free joint (a floating base) or a ball joint (a quaternion) is not an
//    armature joint: it is skipped when joints are found, and refused by name in the
//    `joints` option. Move a floating base with `teleport`.
//  - kind: "revolute" (hinge; its position is an angle in radians, speeds in rad/s) or
//    "prismatic" (slide; metres, m/s), MORSE's words.
//  - position: the joint's MuJoCo qpos (for a hinge, the angle from the joint's reference
//    configuration, MJCF `ref`, normally 0); velocity: its qvel.
//  - order: MuJoCo's joint order, which is the depth-first order of the bodies and, within
//    a body, the order of the MJCF: from the root to the tip of each chain, as MORSE lists
//    an armature's joints (get_joints, and the order set_rotations and trajectory use).
//  - position servo: an actuator with a joint transmission on the joint whose force is
//    kp * (ctrl - gear * qpos) - kv * gear * qvel (MJCF <position>, or a <general> of that
//    shape: fixed gain kp, affine bias 0, -kp, -kv with kv >= 0; no integrator dynamics,
//    which make an <intvelocity> whose ctrl is a velocity). An armature drives a joint that
//    has one through its ctrl (ctrl = gear * target), the others kinematically: motors,
//    muscles and tendon or slider-crank transmissions are not position servos of a joint.
//  - names: a joint's MJCF name, or "joint<id>" for an unnamed one (Debian's
//    slider_crank.xml names none), stable for a given model.
//  - kinematic drive: joints set to a position and velocity, not driven by a force
//    (KinematicDrive below). The velocity is given by an impulse along the joints' own
//    degrees of freedom, so the rest of the robot takes its reaction as from the joints'
//    own torques; writing one qvel alone would not, and adds energy (see KinematicDrive).
//
// Life cycle: a JointSet is built once, when its component is created (it reads the
// `joints` option), and only reads the model afterwards; when the model is replaced, its
// component remaps it (remap()).
//
// Threads: simulation thread (or the thread building the simulation).
#ifndef SIMGATE_SIM_JOINTS_H_
#define SIMGATE_SIM_JOINTS_H_

#include <string>
#include <string_view>
#include <vector>

#include <mujoco/mujoco.h>

#include "simgate/sim/model_remap.h"
#include "simgate/sim/registry.h"

namespace simgate::sim {

enum class JointKind { revolute, prismatic };

// "revolute" or "prismatic".
std::string_view to_string(JointKind kind);
// "rad" or "m"; the speed unit is this plus "/s".
std::string_view unit_of(JointKind kind);

// One armature joint: what the model says about it, looked up once.
struct ArmatureJoint {
  std::string name;  // MJCF name, or "joint<id>"
  int id = -1;       // MuJoCo joint id
  JointKind kind = JointKind::revolute;
  int qpos = -1;         // address in mjData::qpos
  int dof = -1;          // address in mjData::qvel (and qfrc_*)
  bool limited = false;  // jnt_limited: position confined to [low, high]
  double low = 0;        // jnt_range, radians or metres (meaningful when limited)
  double high = 0;
  int servo = -1;             // the position servo driving it, or -1 (kinematic)
  double gear = 1;            // the servo's gear: its ctrl is gear * position
  bool ctrl_limited = false;  // the servo's ctrlrange applies
  double ctrl_low = 0;        // the servo's ctrlrange (meaningful when ctrl_limited)
  double ctrl_high = 0;
};

// The joint's name as armatures show it: its MJCF name, or "joint<id>".
std::string joint_name(const mjModel* m, int joint);

// True when actuator `a` is a position servo (see the terms above) on a joint.
bool is_position_servo(const mjModel* m, int a);

// Sets joints kinematically, as a lock of those joints to a path would: qvel of each
// becomes its wanted velocity through one impulse along their own degrees of freedom
// (M dv = sum_k e_k lambda_k, the lambdas such that each joint gets exactly its velocity),
// whose reaction the other degrees of freedom take as they would take the joints' torques,
// then qpos of each is set. An impulse of this form never adds kinetic energy to reach a
// velocity of 0 (it removes what the joint had, with what coupling carries of it) and
// keeps a floating robot's momentum. Overwriting a joint's qvel alone does neither: with
// the joint's coupling to a free base (M's off-diagonal terms), zeroing it every step
// fed the base's spin. Debian's humanoid, abdomen_y held at 0.3 rad against its joint
// spring, spun up until MuJoCo's accelerations passed 1e10 within 0.4 to 2.1 s
// (docs/components/armature.md, "Holding").
// Uses M's factorisation (qLD) as the last mj_step or mj_forward left it.
// Keeps its buffers between calls (it runs every step): one per component.
class KinematicDrive {
 public:
  // Asks for dof `dof` at position `position` (qpos address `qpos`) with velocity `velocity`.
  void add(int qpos, int dof, double position, double velocity);
  // Sets every joint asked for since the last apply (none: nothing), then forgets them.
  void apply(const mjModel* m, mjData* d);

 private:
  struct Wanted {
    int qpos, dof;
    double position, velocity;
  };
  std::vector<Wanted> wanted_;   // since the last apply
  std::vector<mjtNum> units_;    // n unit vectors of size nv, then M^-1 times them
  std::vector<mjtNum> columns_;  // M^-1 e_k, n × nv
  std::vector<mjtNum> gram_;     // (M^-1)_SS, n × n, then its Cholesky factor
  std::vector<mjtNum> missing_;  // wanted velocity minus qvel, per joint
  std::vector<mjtNum> impulse_;  // lambda, per joint
};

class JointSet {
 public:
  // The armature joints of the component's body subtree, in MuJoCo's order, or, when the
  // component's option `joints` lists names, those joints in that order. Throws
  // ConfigError naming "<path>.options.joints[i]" for an unknown name (with the valid
  // ones), a joint outside the subtree, a free or ball joint, or a repeated name; and
  // "<path>.body" when the subtree has no hinge or slide joint.
  static JointSet from_config(ComponentContext& context);
  // Every armature joint of `root`'s subtree (tests, tools).
  static JointSet of_subtree(const mjModel* m, int root);

  // After the model changed: ids through `remap`, addresses re-read from `m` (the new model).
  void remap(const mjModel* m, const ModelRemap& remap);

  const std::vector<ArmatureJoint>& joints() const { return joints_; }
  std::size_t size() const { return joints_.size(); }
  const ArmatureJoint& operator[](std::size_t i) const { return joints_[i]; }
  std::vector<std::string> names() const;

  // Index of the joint called `name`. Throws ServiceError (Failure::bad_arguments,
  // detail {"parameter": parameter}) naming the joint, the closest name ("did you mean")
  // and every valid name.
  std::size_t index_of(const std::string& name, std::string_view parameter) const;

  // Position (rad or m), velocity (rad/s or m/s) and actuator effort (N·m or N:
  // qfrc_actuator of its dof, the generalised force of every actuator on it) of joint i.
  double position(const mjData* d, std::size_t i) const { return d->qpos[joints_[i].qpos]; }
  double velocity(const mjData* d, std::size_t i) const { return d->qvel[joints_[i].dof]; }
  double effort(const mjData* d, std::size_t i) const { return d->qfrc_actuator[joints_[i].dof]; }

 private:
  std::vector<ArmatureJoint> joints_;  // in the armature's order
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_JOINTS_H_
