// simgate/sim/armature.h — MORSE's armature actuator and armature pose sensor on MuJoCo
// joints (docs/components/armature.md has every service with wire examples).
//
// Terms (joints.h has the joint terms: armature joint, kind, order, position servo):
//  - target: where a service asked a joint to be, radians or metres.
//  - motion: what an async service (rotate, rotate_joints, translate, translate_joints,
//    trajectory) asked for: one path per moved joint, a list of knots (simulated time,
//    position, velocity) interpolated linearly, or by cubic Hermite when a trajectory gives
//    velocities. A rotate's path goes from where the joint is at `speed` to its target.
//  - hold: a joint the armature commanded stays at its last target (or, after a cancel or
//    a preemption, where it was then) until it is commanded again or the simulation is
//    reset: its servo keeps that ctrl, or, for a kinematic joint, qpos is set there each
//    step with qvel 0 (a KinematicDrive: the velocity through an impulse along the joint,
//    joints.h). Joints never commanded are left to the physics and to other components.
//  - driving (each step, before the physics step at simulated time t with time step dt):
//    a joint with a position servo gets ctrl = gear * p(t + dt); any other joint is set
//    kinematically, as MORSE sets its Blender bones: qpos = p(t) and
//    qvel = (p(t + dt) - p(t)) / dt, so that the step lands on p(t + dt); the velocity
//    is reached by an impulse along the driven joints (KinematicDrive, joints.h), so the
//    rest of the robot takes the reaction and no energy is made.
//  - arrival: a motion ends once simulated time has passed its last knot and every servo
//    joint is within angle_tolerance / distance_tolerance of its target (kinematic joints
//    are there by construction): SUCCESS. A servo joint that has not arrived
//    settle_timeout seconds later ends the request FAILED, naming it.
//
// Life cycle: created by the registry (type "armature" / "armature_pose"), bound to a body
// whose subtree holds the joints. Async requests: at most one per component; the rotate
// and translate services are interruptible (a new one preempts the running one), the
// trajectory has no local policy (MORSE's). interrupt() (cancel, preemption) holds the
// moved joints where they are; on_reset() drops the motion and every hold and ends the
// running request PREEMPTED.
//
// Threads: simulation thread only (services, default_action, interrupt, on_reset).
#ifndef SIMGATE_SIM_ARMATURE_H_
#define SIMGATE_SIM_ARMATURE_H_

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "simgate/sim/joints.h"
#include "simgate/sim/registry.h"
#include "simgate/sim/sim_component.h"

namespace simgate::sim {

// One point of a joint's path: at simulated time `time` (mjData::time, seconds) the joint
// is at `position` moving at `velocity` (used by Hermite interpolation only).
struct Knot {
  double time = 0;
  double position = 0;
  double velocity = 0;
};

// The path of one joint of a motion.
struct JointPath {
  std::size_t joint = 0;    // index in the armature's JointSet
  std::vector<Knot> knots;  // non-decreasing times; at least one
};

// Where a path puts its joint at a time.
struct PathSample {
  double position = 0;  // rad or m
  double velocity = 0;  // rad/s or m/s (the derivative of the interpolation)
};

// Samples a path at simulated time t: the first knot's position before it, the last
// one's after it, and in between the linear (hermite = false) or cubic Hermite
// interpolation of the two knots around t. Knots sharing a time are a jump at that time.
PathSample sample(const JointPath& path, bool hermite, double t);

// What an async service asked for.
struct Motion {
  std::vector<JointPath> paths;  // one per moved joint
  bool hermite = false;          // interpolation (see sample)
  // The latest last knot of the paths: when the motion is over.
  double end_time() const;
};

// Builds the motion of a MORSE trajectory (armature_trajectory.cc):
//   {"starttime"?: s, "joint_names"?: [...], "points": [{"positions": [...],
//    "velocities"?: [...], "accelerations"?: [...], "effort"?: [...],
//    "time_from_start": s}, ...]}
// `joints`: the armature's; `now`: simulated time (mjData::time); `clock_offset`: what
// `time now` reads minus mjData::time (starttime is on `time now`'s scale, as MORSE's);
// `from`: each joint's position now (the paths start there, at starttime). Throws
// ServiceError (Failure::bad_arguments) naming the field ("points[2].time_from_start")
// and what was expected; nothing is kept from a refused trajectory.
Motion parse_trajectory(const json& trajectory, const JointSet& joints, double now,
                        double clock_offset, const std::vector<double>& from);

// Refuses a target of joint j unless it is finite, within the sane bound of its kind
// (bounds.h), inside the joint's range when it is limited, and inside its servo's
// ctrlrange when that is limited: ServiceError naming `parameter`, the joint and the range.
void require_reachable(const ArmatureJoint& joint, double target, const std::string& parameter);

class Armature : public SimComponent {
 public:
  // Options: joints (list of names), radial_speed (0.8 rad/s), linear_speed (0.05 m/s),
  // angle_tolerance (0.01 rad), distance_tolerance (0.005 m), settle_timeout (2 s).
  explicit Armature(ComponentContext& context);

  // ---- sync services ----
  // The joints' names, root to tip (MORSE's get_joints).
  std::vector<std::string> get_joints() const;
  // {joint: its axis [x, y, z] in its body's frame} (MORSE: [bool, bool, bool]).
  json get_dofs() const;
  // [low, high] of a limited joint (rad or m), null for an unlimited one.
  json get_IK_limits(const std::string& joint) const;
  // No IK targets: always [].
  std::vector<std::string> list_IK_targets() const { return {}; }
  void set_rotation(const std::string& joint, double rotation);
  void set_translation(const std::string& joint, double translation);
  // A list (one value per joint, in get_joints' order; a shorter list sets the first
  // joints) or an object {joint: value}.
  void set_rotations(const json& rotations);
  void set_translations(const json& translations);
  // The input stream's command: {joint: position}, each in its joint's unit.
  void set_positions(const json& positions);

  // ---- async services (completed from default_action) ----
  void rotate(const std::string& joint, double rotation, std::optional<double> speed);
  void translate(const std::string& joint, double translation, std::optional<double> speed);
  void rotate_joints(const std::map<std::string, double>& joint_rotations,
                     std::optional<double> speed);
  void translate_joints(const std::map<std::string, double>& joint_translations,
                        std::optional<double> speed);
  void trajectory(const json& trajectory);

  void default_action() override;
  void interrupt() override;
  void on_reset() override;
  void on_model_changed(const ModelRemap& remap) override { joints_.remap(model(), remap); }

  const JointSet& joints() const { return joints_; }

 private:
  // The running motion's progress at simulated time t, to a client that asked (issue #20):
  // {"points_reached", "points", "time_left"}.
  void report_progress(double t);
  // One requested target: joint index, value, and the parameter that named it.
  struct Target {
    std::size_t joint;
    double value;
    std::string parameter;
  };
  // Looks a joint up and checks its kind for `service` (FAILED naming it and its kind).
  std::size_t joint_of_kind(const std::string& name, JointKind kind,
                            const std::string& parameter) const;
  // Targets of set_rotations / set_translations (list or object), checked.
  std::vector<Target> targets_from(const json& values, JointKind kind,
                                   const std::string& parameter) const;
  // Refuses to teleport a joint the running motion drives.
  void require_not_moving(const Target& target) const;
  // Sets the targets at once and holds them (set_rotation & co).
  void apply_now(const std::vector<Target>& targets);
  // Starts a rotate/translate motion at `speed` (default: radial_speed / linear_speed).
  void start_moves(const std::vector<Target>& targets, JointKind kind, std::optional<double> speed);
  // Begins `motion` (refused requests never get here).
  void begin(Motion motion);
  // Drives joint i to position p at time t (p_next: where it should be at t + dt): a servo
  // joint's ctrl at once, a kinematic joint's at the next drive_kinematic().
  void drive(std::size_t i, double p, double p_next);
  // Sets the kinematic joints drive() was given since the last call (KinematicDrive).
  void drive_kinematic() { kinematic_.apply(model(), data()); }
  // Servo joints of the motion not yet within tolerance of their final target.
  std::vector<std::size_t> not_arrived() const;
  double tolerance_of(std::size_t i) const;

  JointSet joints_;                          // what it moves, in order
  double radial_speed_ = 0.8;                // rad/s, default speed of rotations (MORSE)
  double linear_speed_ = 0.05;               // m/s, default speed of translations (MORSE)
  double angle_tolerance_ = 0.01;            // rad, arrival of a revolute servo joint (MORSE)
  double distance_tolerance_ = 0.005;        // m, arrival of a prismatic servo joint (MORSE)
  double settle_timeout_ = 2.0;              // s after the last knot before FAILED
  std::optional<Motion> motion_;             // what the running request asked for
  std::vector<int> path_of_;                 // joint -> index in motion_->paths, or -1
  std::vector<std::optional<double>> hold_;  // joint -> position held when not in motion
  KinematicDrive kinematic_;                 // this step's kinematic joints
};

// MORSE's armature pose sensor.
class ArmaturePose : public SimComponent {
 public:
  // Options: joints (list of names).
  explicit ArmaturePose(ComponentContext& context);

  std::vector<std::string> get_joints() const;
  // {joint: {"position", "velocity", "effort"}}.
  json get_state() const;
  double get_joint(const std::string& joint) const;
  json get_joints_length() const;
  // {joint: position, ..., "timestamp": simulated seconds}.
  json get_local_data() const;
  void on_model_changed(const ModelRemap& remap) override { joints_.remap(model(), remap); }

 private:
  JointSet joints_;  // what it reads, in order
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_ARMATURE_H_
