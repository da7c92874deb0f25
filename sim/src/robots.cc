#include <cmath>

#include "simgate/core/errors.h"
#include "simgate/sim/components.h"

namespace simgate::sim {

namespace {
void require_finite(const char* what, double value) {
  if (!std::isfinite(value)) throw ServiceError(std::string(what) + " must be a finite number");
}
}  // namespace

// ---- ground_robot ------------------------------------------------------------------------

GroundRobot::GroundRobot(ComponentContext& c) : Robot(c.name(), c.sim(), c.body()) {
  const std::string& body = c.spec().body;
  left_ = c.actuator_option("left_actuator", body + "_left_motor");
  right_ = c.actuator_option("right_actuator", body + "_right_motor");
  wheel_radius_ = c.options().get_number("wheel_radius", 0.1, 1e-4, 100);
  separation_ = c.options().get_number("wheel_separation", 0.42, 1e-4, 100);
  max_wheel_speed_ = c.options().get_number("max_wheel_speed", 30, 1e-3, 1e6);
  if (left_ == right_) c.fail("options.right_actuator", "expected an actuator other than the left one");
}

void GroundRobot::set_velocity(double v, double w) {
  v_ = v;
  w_ = w;
  // wheel angular speeds of a differential drive (left wheel on +y)
  double left = (v - w * separation_ / 2) / wheel_radius_;
  double right = (v + w * separation_ / 2) / wheel_radius_;
  // keep the turn radius when a wheel would exceed its limit
  double peak = std::max(std::abs(left), std::abs(right));
  if (peak > max_wheel_speed_) {
    left *= max_wheel_speed_ / peak;
    right *= max_wheel_speed_ / peak;
  }
  data()->ctrl[left_] = left;
  data()->ctrl[right_] = right;
}

// ---- human ---------------------------------------------------------------------------------

Human::Human(ComponentContext& c) : Robot(c.name(), c.sim(), c.body()), free_joint_(c.free_joint()) {
  add_service("move", &Human::move, {"speed", "rotation"})
      .doc("Step `speed` metres forward and turn `rotation` radians (counter-clockwise)");
}

void Human::move(double speed, double rotation) {
  require_finite("speed", speed);
  require_finite("rotation", rotation);
  if (speed < 0) throw ServiceError("Our human cannot walk at negative speed!");
  // forward along the human's heading (in the ground plane), then turn about the vertical
  Eigen::Quaterniond q = orientation();
  double heading = yaw();
  Eigen::Vector3d p = position() + speed * Eigen::Vector3d(std::cos(heading), std::sin(heading), 0);
  q = Eigen::AngleAxisd(rotation, Eigen::Vector3d::UnitZ()) * q;
  // body position == free joint position for a root body with a free joint
  set_free_body_pose(sim(), free_joint_, p, q);
}

// ---- robot -----------------------------------------------------------------------------------

PlainRobot::PlainRobot(ComponentContext& c) : Robot(c.name(), c.sim(), c.body()) {}

// ---- registration ----------------------------------------------------------------------------

void register_builtin_components(ComponentRegistry& r) {
  r.add<GroundRobot>("ground_robot", Kind::robot, "differential-drive robot with two actuated wheels");
  r.add<Human>("human", Kind::robot, "a human that steps with `move speed rotation`");
  r.add<PlainRobot>("robot", Kind::robot, "a robot body with no services of its own");
  r.add<MotionVW>("motion_vw", Kind::component, "linear/angular velocity actuator: set_speed v w, stop");
  r.add<Waypoint>("waypoint", Kind::component, "drives to a destination: goto, setdest, stop, resume, get_status");
  r.add<Teleport>("teleport", Kind::component, "moves the robot instantly: translate, rotate");
  r.add<Pose>("pose", Kind::component, "pose sensor: get_local_data");
}

}  // namespace simgate::sim
