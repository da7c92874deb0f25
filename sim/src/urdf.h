// sim/src/urdf.h — URDF scenes (issue #36): MuJoCo's own URDF parser, and an actuator for
// each joint a ROS <transmission> drives. Private to libsimgate_sim (model.cc, model_edit.cc).
//
// MuJoCo reads URDF itself (links, joints, limits, inertials, collision and visual
// geometry, meshes; its <mujoco><compiler .../></mujoco> extension sets compiler options such
// as meshdir) but makes no actuators: URDF declares them in <transmission> elements, which
// ros2_control and Gazebo read. simgate adds one MuJoCo actuator per transmission joint, by
// its hardware interface, limits taken from the joint's <limit> (joint-side, as URDF gives
// them):
//   position  -> <position>: ctrlrange the joint's [lower, upper], kp = effort / 0.1 (the
//                whole effort at 0.1 rad or m from the target; 100 without an effort),
//                critically damped (dampratio 1), forcerange +-effort
//   velocity  -> <velocity>: ctrlrange +-velocity, kv = effort / 1 (10 without), forcerange
//   effort    -> <motor>: ctrlrange +-effort
// named after the transmission's <actuator name="...">, else "<joint>_actuator". The
// generic `actuators` component then serves them like any MJCF robot's.
#ifndef SIMGATE_SIM_SRC_URDF_H_
#define SIMGATE_SIM_SRC_URDF_H_

#include <string>

#include <mujoco/mujoco.h>

namespace simgate::sim {

// Whether `text` is a URDF document: its root element is <robot>.
bool is_urdf(const std::string& text);

// Adds to `spec`, MuJoCo's parse of the URDF text `text`, an actuator for each joint its
// transmissions drive. Throws MujocoError starting with `source` ("scene 'arm.urdf'", "entity
// 'rover'"): a transmission naming a joint the robot does not have, or a hardware interface
// simgate does not know.
void add_transmission_actuators(mjSpec* spec, const std::string& source, const std::string& text);

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_SRC_URDF_H_
