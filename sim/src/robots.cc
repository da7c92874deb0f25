#include <cmath>
#include <cstdio>

#include "simgate/core/errors.h"
#include "simgate/sim/actuator_kind.h"
#include "simgate/sim/actuators_sensors.h"
#include "simgate/sim/armature.h"
#include "simgate/sim/bounds.h"
#include "simgate/sim/components.h"
#include "simgate/sim/native_sensors.h"

namespace simgate::sim {

namespace {
// The actuator named by option `key`, refused unless it is velocity-controlled: a wheel
// driven by torque with a speed for a command accelerates without bound.
int velocity_actuator_option(ComponentContext& c, const std::string& key,
                             const std::string& fallback) {
  const int id = c.actuator_option(key, fallback);
  const mjModel* m = c.sim().m();
  if (!is_velocity_actuator(m, id)) {
    const char* name = mj_id2name(m, mjOBJ_ACTUATOR, id);
    throw ConfigError(
        c.options().path_of(key) + ": actuator '" + (name ? name : "?") + "' is " +
        describe_actuator(m, id) + "; " + c.spec().type +
        " drives its wheels by velocity: expected a <velocity kv=\"...\"> actuator (or a "
        "<general> one with gaintype=\"fixed\" gainprm=\"kv\", biastype=\"affine\" and "
        "biasprm=\"0 0 -kv\")");
  }
  return id;
}
}  // namespace

// ---- ground_robot ------------------------------------------------------------------------

GroundRobot::GroundRobot(ComponentContext& c) : Robot(c.name(), c.sim(), c.body()) {
  const std::string& body = c.spec().body;
  left_ = velocity_actuator_option(c, "left_actuator", body + "_left_motor");
  right_ = velocity_actuator_option(c, "right_actuator", body + "_right_motor");
  wheel_radius_ = c.options().get_number("wheel_radius", 0.1, 1e-4, 100);
  separation_ = c.options().get_number("wheel_separation", 0.42, 1e-4, 100);
  max_wheel_speed_ = c.options().get_number("max_wheel_speed", 30, 1e-3, 1e6);
  if (left_ == right_)
    c.fail("options.right_actuator", "expected an actuator other than the left one");
  add_number_property("wheel_radius", wheel_radius_, 1e-4, 100, "m");
  add_number_property("wheel_separation", separation_, 1e-4, 100, "m");
  add_number_property("max_wheel_speed", max_wheel_speed_, 1e-3, 1e6, "rad/s");
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

Human::Human(ComponentContext& c)
    : Robot(c.name(), c.sim(), c.body()), free_joint_(c.free_joint()) {
  add_service("move", &Human::move, {"speed", "rotation"})
      .doc("Step `speed` metres forward and turn `rotation` radians (counter-clockwise)");
}

void Human::move(double speed, double rotation) {
  // MORSE's own refusal first, word for word (a finite negative speed)
  if (speed < 0 && std::isfinite(speed))
    throw ServiceError("Our human cannot walk at negative speed!");
  bounds::require_between("speed", speed, 0, bounds::position, "m");
  bounds::require_within("rotation", rotation, bounds::angle, "rad");
  // forward along the human's heading (in the ground plane), then turn about the vertical
  Eigen::Quaterniond q = orientation();
  double heading = yaw();
  Eigen::Vector3d p = position() + speed * Eigen::Vector3d(std::cos(heading), std::sin(heading), 0);
  // steps add up: each one in bounds may still end beyond the world's edge
  const std::string body = "body '" + sim().model().body_name(this->body()) + "'";
  bounds::require_inside_world("speed", speed, body, "x", p.x());
  bounds::require_inside_world("speed", speed, body, "y", p.y());
  q = Eigen::AngleAxisd(rotation, Eigen::Vector3d::UnitZ()) * q;
  // body position == free joint position for a root body with a free joint
  set_free_body_pose(sim(), free_joint_, p, q);
}

// ---- robot -----------------------------------------------------------------------------------

PlainRobot::PlainRobot(ComponentContext& c) : Robot(c.name(), c.sim(), c.body()) {}

// ---- registration ----------------------------------------------------------------------------

SIMGATE_BUILTIN_TYPE(
    ground_robot,
    builtin_type<GroundRobot>(
        "ground_robot", Kind::robot, "differential-drive robot with two actuated wheels",
        "docs/configuration.md",
        {{"left_actuator",
          {{"type", "string"}},
          "the left wheel's velocity actuator (default <body>_left_motor)"},
         {"right_actuator",
          {{"type", "string"}},
          "the right wheel's velocity actuator (default <body>_right_motor)"},
         {"wheel_radius",
          {{"type", "number"}, {"minimum", 1e-4}, {"maximum", 100}, {"default", 0.1}},
          "m"},
         {"wheel_separation",
          {{"type", "number"}, {"minimum", 1e-4}, {"maximum", 100}, {"default", 0.42}},
          "m between the wheels"},
         {"max_wheel_speed",
          {{"type", "number"}, {"minimum", 1e-3}, {"maximum", 1e6}, {"default", 30}},
          "rad/s"}}));
SIMGATE_BUILTIN_TYPE(human, builtin_type<Human>("human", Kind::robot,
                                                "a human that steps with `move speed rotation`",
                                                "docs/configuration.md", {}));
SIMGATE_BUILTIN_TYPE(robot, builtin_type<PlainRobot>("robot", Kind::robot,
                                                     "a robot body with no services of its own",
                                                     "docs/configuration.md", {}));
// the gateway adds the generic components (model_robots.h); the robot itself is plain
SIMGATE_BUILTIN_TYPE(
    mjcf,
    builtin_type<PlainRobot>(
        "mjcf", Kind::robot,
        "any MJCF robot: armature, armature_pose, actuators and sensors for what its subtree has",
        "docs/configuration.md", {}));

}  // namespace simgate::sim
