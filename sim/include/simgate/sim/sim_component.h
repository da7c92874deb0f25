// simgate/sim/sim_component.h — components that live in the MuJoCo world.
//
// SimComponent is a Component with access to the simulation (model, data, clock). Robot is
// the SimComponent of a robot: it is bound to a MuJoCo body (its root), and its components
// (actuators, sensors) find it as their parent. A robot that can drive offers a
// DifferentialDrive (linear and angular velocity commands), which motion_vw and waypoint
// use; the drive turns them into MuJoCo actuator controls.
//
// Threads: everything here runs on the simulation thread (services, default_action(),
// interrupt(), on_reset()).
#ifndef SIMGATE_SIM_SIM_COMPONENT_H_
#define SIMGATE_SIM_SIM_COMPONENT_H_

#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "simgate/core/component.h"
#include "simgate/sim/simulation.h"

namespace simgate::sim {

class SimComponent : public Component {
 public:
  SimComponent(std::string name, Simulation& sim) : Component(std::move(name)), sim_(sim) {}

  // After `simulation reset_objects` restored the initial state, or the simulation
  // recovered from a bad state the same way (simulation.h): drop commands.
  virtual void on_reset() {}

 protected:
  Simulation& sim() const { return sim_; }
  const mjModel* model() const { return sim_.m(); }
  mjData* data() const { return sim_.d(); }

 private:
  Simulation& sim_;  // owns this component
};

// A body's pose in the world frame (valid after the last mj_step / mj_forward).
Eigen::Vector3d body_position(const Simulation& sim, int body);
Eigen::Quaterniond body_orientation(const Simulation& sim, int body);
// Roll, pitch, yaw (ZYX convention: yaw about z, then pitch about y, then roll about x).
Eigen::Vector3d to_roll_pitch_yaw(const Eigen::Quaterniond& q);
Eigen::Quaterniond from_roll_pitch_yaw(double roll, double pitch, double yaw);

// Moves a free-joint body: sets position and orientation, zeroes its velocity, mj_forward.
void set_free_body_pose(Simulation& sim, int free_joint, const Eigen::Vector3d& position,
                        const Eigen::Quaterniond& orientation);

// Linear (m/s) and angular (rad/s, counter-clockwise) velocity commands for a ground robot.
class DifferentialDrive {
 public:
  virtual ~DifferentialDrive() = default;
  virtual void set_velocity(double v, double w) = 0;
  virtual double linear_velocity() const = 0;   // the last command
  virtual double angular_velocity() const = 0;  // the last command
};

class Robot : public SimComponent {
 public:
  Robot(std::string name, Simulation& sim, int body) : SimComponent(std::move(name), sim), body_(body) {}

  // The root body.
  int body() const { return body_; }
  // The drive, or nullptr for robots that cannot drive.
  virtual DifferentialDrive* drive() { return nullptr; }

  Eigen::Vector3d position() const { return body_position(sim(), body_); }
  Eigen::Quaterniond orientation() const { return body_orientation(sim(), body_); }
  double yaw() const { return to_roll_pitch_yaw(orientation()).z(); }

 private:
  int body_;  // MuJoCo body id of the root
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_SIM_COMPONENT_H_
