// simgate/sim/components.h — the built-in robots, actuators and sensors (MORSE names).
//
// Robots:
//  - ground_robot: a differential-drive robot; its two wheels are driven through MuJoCo
//    velocity actuators (<velocity kv>, or a <general> of that shape: fixed gain kv, affine
//    bias 0 0 -kv; anything else is a ConfigError naming the actuator). Options: left_actuator,
//    right_actuator (default "<body>_left_motor" / "<body>_right_motor"), wheel_radius
//    (0.1 m), wheel_separation (0.42 m), max_wheel_speed (30 rad/s).
//  - human: `move speed rotation` (MORSE's HumanClass example): steps `speed` metres
//    forward and turns `rotation` radians; refuses negative speeds. Needs a free joint.
//  - robot: a body with no services of its own.
// Components (named "<robot>.<name>"):
//  - motion_vw: `set_speed v w`, `stop`.
//  - waypoint: async `goto x y z [tolerance=0.5 speed=1.0]` (interruptible, completes
//    SUCCESS "Arrived"), `setdest`, `stop` (goto stays pending, status "Stop"), `resume`
//    ("Transit"), `get_status`. Options: max_angular_speed (1.5 rad/s), heading_gain (2.0).
//  - teleport: `translate x [y z]`, `rotate roll [pitch yaw]` (relative). Needs a free joint.
//  - pose: `get_local_data` -> {x, y, z, roll, pitch, yaw}.
//
// Every number a client gives to move or drive something is checked against bounds.h
// (finite, within a sane bound, and destinations inside the world): FAILED naming the
// parameter, its value and the bound, and nothing changes.
//
// Threads: simulation thread only.
#ifndef SIMGATE_SIM_COMPONENTS_H_
#define SIMGATE_SIM_COMPONENTS_H_

#include <string>

#include "simgate/sim/registry.h"
#include "simgate/sim/sim_component.h"

namespace simgate::sim {

class GroundRobot : public Robot, public DifferentialDrive {
 public:
  explicit GroundRobot(ComponentContext& context);

  DifferentialDrive* drive() override { return this; }
  void set_velocity(double v, double w) override;
  double linear_velocity() const override { return v_; }
  double angular_velocity() const override { return w_; }
  void on_reset() override { set_velocity(0, 0); }
  void on_model_changed(const ModelRemap& remap) override {
    Robot::on_model_changed(remap);
    left_ = remap.actuator_of(left_), right_ = remap.actuator_of(right_);
  }

 private:
  int left_;                // left wheel actuator id
  int right_;               // right wheel actuator id
  double wheel_radius_;     // metres
  double separation_;       // distance between the wheels, metres
  double max_wheel_speed_;  // rad/s, commands are scaled down to respect it
  double v_ = 0, w_ = 0;    // last command
};

class Human : public Robot {
 public:
  explicit Human(ComponentContext& context);
  void move(double speed, double rotation);
  void on_model_changed(const ModelRemap& remap) override {
    Robot::on_model_changed(remap);
    free_joint_ = remap.joint_of(free_joint_);
  }

 private:
  int free_joint_;  // the human's free joint
};

class PlainRobot : public Robot {
 public:
  explicit PlainRobot(ComponentContext& context);
};

class MotionVW : public SimComponent {
 public:
  explicit MotionVW(ComponentContext& context);
  void set_speed(double v, double w);
  void stop();

 private:
  DifferentialDrive& drive_;  // the robot's wheels
};

class Waypoint : public SimComponent {
 public:
  explicit Waypoint(ComponentContext& context);

  void go_to(double x, double y, double z, double tolerance, double speed);
  bool setdest(double x, double y, double z, double tolerance, double speed);
  std::string stop();
  std::string resume();
  std::string get_status() const;

  void default_action() override;
  void interrupt() override;
  void on_reset() override;

 private:
  enum class State { arrived, transit, stop };
  void set_target(double x, double y, double z, double tolerance, double speed);
  double distance() const;

  Robot& robot_;                     // whose pose is controlled
  DifferentialDrive& drive_;         // how
  double max_angular_speed_;         // rad/s
  double heading_gain_;              // rad/s per rad of heading error
  Eigen::Vector3d target_{0, 0, 0};  // destination (world frame)
  double tolerance_ = 0.5;           // metres (distance in the ground plane)
  double speed_ = 1.0;               // m/s
  State state_ = State::arrived;     // MORSE's status
};

class Teleport : public SimComponent {
 public:
  explicit Teleport(ComponentContext& context);
  void translate(double x, double y, double z);
  void rotate(double roll, double pitch, double yaw);
  // The input stream's command: an absolute pose {x, y, z, roll, pitch, yaw} (a position
  // missing keeps the current one, an angle missing is 0).
  void place(const json& command);
  void on_model_changed(const ModelRemap& remap) override {
    body_ = remap.body_of(body_), free_joint_ = remap.joint_of(free_joint_);
  }

 private:
  int body_;        // moved body
  int free_joint_;  // its free joint
};

class Pose : public SimComponent {
 public:
  explicit Pose(ComponentContext& context);
  json get_local_data() const;
  void on_model_changed(const ModelRemap& remap) override { body_ = remap.body_of(body_); }

 private:
  // x, y, z, roll, pitch, yaw, timestamp: the stream's record, get_local_data's object
  void read(std::span<double> values) const;
  int body_;  // measured body
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_COMPONENTS_H_
