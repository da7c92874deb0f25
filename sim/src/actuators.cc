#include <algorithm>
#include <cmath>

#include "simgate/core/errors.h"
#include "simgate/core/log.h"
#include "simgate/sim/bounds.h"
#include "simgate/sim/components.h"
#include "helpers.h"

namespace simgate::sim {

// ---- motion_vw -------------------------------------------------------------------------------

MotionVW::MotionVW(ComponentContext& c) : SimComponent(c.name(), c.sim()), drive_(c.drive()) {
  add_service("set_speed", &MotionVW::set_speed, {"v", "w"})
      .doc("Linear speed v (m/s) and angular speed w (rad/s, counter-clockwise)");
  add_service("stop", &MotionVW::stop).doc("Stop the robot");
  // MORSE's motion_vw datastream: {"v": m/s, "w": rad/s}
  declare_input_stream("velocity", {"v", "w"}, [this](const json& command) {
    set_speed(command_number(command, "v"), command_number(command, "w"));
  });
}

void MotionVW::set_speed(double v, double w) {
  // refused, not scaled: the drive's own wheel limit is for sane commands, not for 1e300
  bounds::require_within("v", v, bounds::linear_speed, "m/s");
  bounds::require_within("w", w, bounds::angular_speed, "rad/s");
  drive_.set_velocity(v, w);
}

void MotionVW::stop() { drive_.set_velocity(0, 0); }

// ---- waypoint --------------------------------------------------------------------------------

Waypoint::Waypoint(ComponentContext& c)
    : SimComponent(c.name(), c.sim()), robot_(c.robot()), drive_(c.drive()) {
  max_angular_speed_ = c.options().get_number("max_angular_speed", 1.5, 1e-3, 100);
  heading_gain_ = c.options().get_number("heading_gain", 2.0, 1e-3, 100);
  add_number_property("max_angular_speed", max_angular_speed_, 1e-3, 100, "rad/s");
  add_number_property("heading_gain", heading_gain_, 1e-3, 100, "rad/s per rad");
  add_property("target", [this] { return json{target_.x(), target_.y(), target_.z()}; });
  add_property("tolerance", [this] { return json(tolerance_); });
  add_property("speed", [this] { return json(speed_); });
  add_async_service("goto", &Waypoint::go_to, {"x", "y", "z", {"tolerance", 0.5}, {"speed", 1.0}})
      .interruptible()
      .doc(
          "Drive to (x, y, z); completes SUCCESS \"Arrived\" within tolerance (metres, ground "
          "plane)");
  add_service("setdest", &Waypoint::setdest, {"x", "y", "z", {"tolerance", 0.5}, {"speed", 1.0}})
      .doc("Set a new destination; false when already within tolerance");
  add_service("stop", &Waypoint::stop).doc("Halt; a running goto stays pending (status Stop)");
  add_service("resume", &Waypoint::resume).doc("Continue towards the destination (status Transit)");
  add_service("get_status", &Waypoint::get_status).doc("Transit, Arrived or Stop");
  // MORSE's waypoint datastream: a new destination, as setdest
  declare_input_stream(
      "waypoint", {"x", "y", "z", "tolerance", "speed"}, [this](const json& command) {
        setdest(command_number(command, "x"), command_number(command, "y"),
                command_number(command, "z", 0.0), command_number(command, "tolerance", 0.5),
                command_number(command, "speed", 1.0));
      });
}

void Waypoint::set_target(double x, double y, double z, double tolerance, double speed) {
  bounds::require_within("x", x, bounds::position, "m");
  bounds::require_within("y", y, bounds::position, "m");
  bounds::require_within("z", z, bounds::position, "m");
  bounds::require_between("tolerance", tolerance, 0, bounds::position, "m");
  bounds::require_between("speed", speed, 0, bounds::linear_speed, "m/s");
  if (speed == 0)
    throw ServiceError("speed must be positive", Failure::bad_arguments, {{"parameter", "speed"}});
  target_ = {x, y, z};
  tolerance_ = tolerance;
  speed_ = speed;
}

double Waypoint::distance() const {
  Eigen::Vector3d p = robot_.position();
  return std::hypot(target_.x() - p.x(), target_.y() - p.y());
}

void Waypoint::go_to(double x, double y, double z, double tolerance, double speed) {
  set_target(x, y, z, tolerance, speed);
  // completion (possibly immediate) happens in default_action()
  state_ = State::transit;
}

bool Waypoint::setdest(double x, double y, double z, double tolerance, double speed) {
  set_target(x, y, z, tolerance, speed);
  if (distance() <= tolerance_) {
    state_ = State::arrived;
    drive_.set_velocity(0, 0);
    return false;
  }
  state_ = State::transit;
  return true;
}

std::string Waypoint::stop() {
  state_ = State::stop;
  drive_.set_velocity(0, 0);
  return "Stop";
}

std::string Waypoint::resume() {
  state_ = State::transit;
  return "Transit";
}

std::string Waypoint::get_status() const {
  switch (state_) {
    case State::transit: return "Transit";
    case State::stop: return "Stop";
    case State::arrived: break;
  }
  return "Arrived";
}

void Waypoint::default_action() {
  if (state_ != State::transit) return;
  Eigen::Vector3d p = robot_.position();
  double dx = target_.x() - p.x(), dy = target_.y() - p.y();
  double dist = std::hypot(dx, dy);
  // arrived: halt and finish the goto, if one is waiting
  if (dist <= tolerance_) {
    state_ = State::arrived;
    drive_.set_velocity(0, 0);
    if (has_running_request()) completed(Status::success, "Arrived");
    return;
  }
  // a client that asked for progress learns how far it still is (issue #20)
  if (progress_due()) progress(json{{"distance_left", dist}});
  // steer towards the target; drive forward only when roughly facing it, slower near it
  double error = wrap_angle(std::atan2(dy, dx) - robot_.yaw());
  double w = std::clamp(heading_gain_ * error, -max_angular_speed_, max_angular_speed_);
  double v = speed_ * std::max(0.0, std::cos(error));
  v = std::min(v, std::max(0.1, 1.5 * dist));
  drive_.set_velocity(v, w);
}

void Waypoint::interrupt() {
  // MORSE: the destination becomes the current position, the robot stops
  state_ = State::arrived;
  target_ = robot_.position();
  drive_.set_velocity(0, 0);
  Component::interrupt();
}

void Waypoint::on_reset() {
  if (state_ == State::transit) return;  // a goto in progress keeps going from the new pose
  drive_.set_velocity(0, 0);
}

// ---- teleport --------------------------------------------------------------------------------

Teleport::Teleport(ComponentContext& c)
    : SimComponent(c.name(), c.sim()), body_(c.body()), free_joint_(c.free_joint()) {
  add_service("translate", &Teleport::translate, {"x", {"y", 0.0}, {"z", 0.0}})
      .doc("Move by (x, y, z) metres in the world frame, instantly");
  add_service("rotate", &Teleport::rotate, {"roll", {"pitch", 0.0}, {"yaw", 0.0}})
      .doc("Turn by roll, pitch, yaw radians (body frame), instantly");
  // MORSE's teleport datastream: an absolute pose in the world frame
  declare_input_stream("teleport", {"x", "y", "z", "roll", "pitch", "yaw"},
                       [this](const json& command) { place(command); });
}

void Teleport::place(const json& command) {
  const Eigen::Vector3d now = body_position(sim(), body_);
  Eigen::Vector3d position(command_number(command, "x", now.x()),
                           command_number(command, "y", now.y()),
                           command_number(command, "z", now.z()));
  const char* axes[] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k) bounds::require_within(axes[k], position[k], bounds::position, "m");
  double rpy[3];
  const char* angles[] = {"roll", "pitch", "yaw"};
  for (int k = 0; k < 3; ++k) {
    rpy[k] = command_number(command, angles[k], 0.0);
    bounds::require_within(angles[k], rpy[k], bounds::angle, "rad");
  }
  set_free_body_pose(sim(), free_joint_, position, from_roll_pitch_yaw(rpy[0], rpy[1], rpy[2]));
}

void Teleport::translate(double x, double y, double z) {
  bounds::require_within("x", x, bounds::position, "m");
  bounds::require_within("y", y, bounds::position, "m");
  bounds::require_within("z", z, bounds::position, "m");
  // relative moves add up: each one in bounds may still end beyond the world's edge
  const Eigen::Vector3d destination = body_position(sim(), body_) + Eigen::Vector3d(x, y, z);
  const std::string body = "body '" + sim().model().body_name(body_) + "'";
  bounds::require_inside_world("x", x, body, "x", destination.x());
  bounds::require_inside_world("y", y, body, "y", destination.y());
  bounds::require_inside_world("z", z, body, "z", destination.z());
  set_free_body_pose(sim(), free_joint_, destination, body_orientation(sim(), body_));
}

void Teleport::rotate(double roll, double pitch, double yaw) {
  bounds::require_within("roll", roll, bounds::angle, "rad");
  bounds::require_within("pitch", pitch, bounds::angle, "rad");
  bounds::require_within("yaw", yaw, bounds::angle, "rad");
  set_free_body_pose(sim(), free_joint_, body_position(sim(), body_),
                     body_orientation(sim(), body_) * from_roll_pitch_yaw(roll, pitch, yaw));
}

SIMGATE_BUILTIN_TYPE(motion_vw,
                     builtin_type<MotionVW>("motion_vw", Kind::component,
                                            "linear/angular velocity actuator: set_speed v w, stop",
                                            "docs/configuration.md", {}));
SIMGATE_BUILTIN_TYPE(
    waypoint,
    builtin_type<Waypoint>(
        "waypoint", Kind::component,
        "drives to a destination: goto, setdest, stop, resume, get_status", "docs/configuration.md",
        {{"max_angular_speed",
          {{"type", "number"}, {"minimum", 1e-3}, {"maximum", 100}, {"default", 1.5}},
          "rad/s"},
         {"heading_gain",
          {{"type", "number"}, {"minimum", 1e-3}, {"maximum", 100}, {"default", 2.0}},
          "angular speed per radian of heading error"}}));
SIMGATE_BUILTIN_TYPE(teleport,
                     builtin_type<Teleport>("teleport", Kind::component,
                                            "moves the robot instantly: translate, rotate",
                                            "docs/configuration.md", {}));

}  // namespace simgate::sim
