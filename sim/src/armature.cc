// The armature actuator: MORSE's armature services on the hinge and slide joints of a body
// subtree, driven through their position servos or kinematically (armature.h).
#include "simgate/sim/armature.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "simgate/core/errors.h"
#include "simgate/sim/bounds.h"
#include "simgate/sim/supervision.h"
#include "helpers.h"

namespace simgate::sim {

namespace {

// "rotation" or "translation", as MORSE's services name the two kinds of motion
std::string motion_word(JointKind kind) {
  return kind == JointKind::prismatic ? "translation" : "rotation";
}

}  // namespace

Armature::Armature(ComponentContext& c)
    : SimComponent(c.name(), c.sim()), joints_(JointSet::from_config(c)) {
  auto& o = c.options();
  radial_speed_ = o.get_number("radial_speed", 0.8, 1e-6, bounds::angular_speed);
  linear_speed_ = o.get_number("linear_speed", 0.05, 1e-6, bounds::linear_speed);
  angle_tolerance_ = o.get_number("angle_tolerance", 0.01, 1e-9, 1);
  distance_tolerance_ = o.get_number("distance_tolerance", 0.005, 1e-9, 1);
  settle_timeout_ = o.get_number("settle_timeout", 2.0, 0, 1e6);
  path_of_.assign(joints_.size(), -1);
  hold_.assign(joints_.size(), std::nullopt);

  add_property("joints", [this] { return json(joints_.names()); });
  add_number_property("radial_speed", radial_speed_, 1e-6, bounds::angular_speed, "rad/s");
  add_number_property("linear_speed", linear_speed_, 1e-6, bounds::linear_speed, "m/s");
  add_number_property("angle_tolerance", angle_tolerance_, 1e-9, 1, "rad");
  add_number_property("distance_tolerance", distance_tolerance_, 1e-9, 1, "m");
  add_number_property("settle_timeout", settle_timeout_, 0, 1e6, "s");

  add_service("get_joints", &Armature::get_joints)
      .doc("The joints' names, from the root to the tip");
  add_service("get_dofs", &Armature::get_dofs)
      .doc("{joint: its axis [x, y, z] in its body's frame}");
  add_service("get_IK_limits", &Armature::get_IK_limits, {"joint"})
      .doc("[low, high] of a limited joint (rad or m); null when unlimited");
  add_service("list_IK_targets", &Armature::list_IK_targets).doc("IK targets: none ([])");
  add_service("set_rotation", &Armature::set_rotation, {"joint", "rotation"})
      .doc("Set a revolute joint to `rotation` radians at once");
  add_service("set_rotations", &Armature::set_rotations, {"rotations"})
      .doc("Set revolute joints at once: a list in get_joints' order, or {joint: radians}");
  add_service("set_translation", &Armature::set_translation, {"joint", "translation"})
      .doc("Set a prismatic joint to `translation` metres at once");
  add_service("set_translations", &Armature::set_translations, {"translations"})
      .doc("Set prismatic joints at once: a list in get_joints' order, or {joint: metres}");
  add_async_service("rotate", &Armature::rotate, {"joint", "rotation", {"speed", nullptr}})
      .interruptible()
      .doc("Turn a revolute joint to `rotation` rad at `speed` rad/s (default radial_speed)");
  add_async_service("rotate_joints", &Armature::rotate_joints,
                    {"joint_rotations", {"speed", nullptr}})
      .interruptible()
      .doc("Turn revolute joints {joint: rad}, each at `speed` rad/s (default radial_speed)");
  add_async_service("translate", &Armature::translate, {"joint", "translation", {"speed", nullptr}})
      .interruptible()
      .doc("Slide a prismatic joint to `translation` m at `speed` m/s (default linear_speed)");
  add_async_service("translate_joints", &Armature::translate_joints,
                    {"joint_translations", {"speed", nullptr}})
      .interruptible()
      .doc("Slide prismatic joints {joint: m}, each at `speed` m/s (default linear_speed)");
  add_async_service("trajectory", &Armature::trajectory, {"trajectory"})
      .doc(
          "Follow {starttime?, points: [{positions, velocities?, time_from_start}]} in simulated "
          "time");
  // MORSE's armature datastream: {joint: position}, radians or metres by the joint's kind
  declare_input_stream("joint_positions", joints_.names(),
                       [this](const json& command) { set_positions(command); });
}

void Armature::set_positions(const json& positions) {
  std::vector<Target> targets;
  for (auto it = positions.begin(); it != positions.end(); ++it) {
    if (it.key() == "timestamp") continue;  // an armature_pose sample written back
    const std::size_t i = joints_.index_of(it.key(), it.key());
    const double value = command_number(positions, it.key());
    require_reachable(joints_[i], value, it.key());
    targets.push_back({i, value, it.key()});
  }
  apply_now(targets);
}

// ---- sync services -------------------------------------------------------------------------

std::vector<std::string> Armature::get_joints() const { return joints_.names(); }

json Armature::get_dofs() const {
  json out = json::object();
  for (const auto& j : joints_.joints()) {
    const mjtNum* axis = model()->jnt_axis + 3 * j.id;
    out[j.name] = {axis[0], axis[1], axis[2]};
  }
  return out;
}

json Armature::get_IK_limits(const std::string& joint) const {
  const ArmatureJoint& j = joints_[joints_.index_of(joint, "joint")];
  if (!j.limited) return nullptr;
  return {j.low, j.high};
}

std::size_t Armature::joint_of_kind(const std::string& name, JointKind kind,
                                    const std::string& parameter) const {
  const std::size_t i = joints_.index_of(name, parameter);
  const ArmatureJoint& j = joints_[i];
  if (j.kind != kind)
    throw ServiceError(
        "joint '" + j.name + "' is " + std::string(to_string(j.kind)) + " (a " +
            (j.kind == JointKind::prismatic ? "slide joint, metres" : "hinge joint, radians") +
            "): a " + motion_word(kind) + " needs a " + std::string(to_string(kind)) +
            " joint; use the " + motion_word(j.kind) + " services",
        Failure::bad_arguments, {{"parameter", parameter}});
  return i;
}

std::vector<Armature::Target> Armature::targets_from(const json& values, JointKind kind,
                                                     const std::string& parameter) const {
  std::vector<Target> out;
  const std::string unit(unit_of(kind));
  if (values.is_object()) {
    for (auto it = values.begin(); it != values.end(); ++it) {
      const std::string where = parameter + "." + it.key();
      const std::size_t i = joint_of_kind(it.key(), kind, where);
      if (!it->is_number())
        throw ServiceError(
            where + ": expected a number of " + unit + ", found " + describe_json(*it),
            Failure::bad_arguments, {{"parameter", where}});
      out.push_back({i, it->get<double>(), where});
    }
  } else if (values.is_array()) {
    // MORSE: one value per joint from the root; a shorter list sets the first joints
    if (values.size() > joints_.size())
      throw ServiceError(parameter + " has " + std::to_string(values.size()) +
                             " values; this armature has " + std::to_string(joints_.size()) +
                             " joints (get_joints)",
                         Failure::bad_arguments, {{"parameter", parameter}});
    for (std::size_t i = 0; i < values.size(); ++i) {
      const std::string where = parameter + "[" + std::to_string(i) + "]";
      joint_of_kind(joints_[i].name, kind, where);
      if (!values[i].is_number())
        throw ServiceError(
            where + ": expected a number of " + unit + ", found " + describe_json(values[i]),
            Failure::bad_arguments, {{"parameter", where}});
      out.push_back({i, values[i].get<double>(), where});
    }
  } else {
    throw ServiceError(parameter + ": expected a list of " + unit +
                           " (one per joint, in get_joints' order) or an " +
                           "object {joint: " + unit + "}, found " + describe_json(values),
                       Failure::bad_arguments, {{"parameter", parameter}});
  }
  if (out.empty())
    throw ServiceError(parameter + " is empty: expected at least one joint", Failure::bad_arguments,
                       {{"parameter", parameter}});
  for (const auto& t : out) require_reachable(joints_[t.joint], t.value, t.parameter);
  return out;
}

void Armature::require_not_moving(const Target& target) const {
  if (motion_ && path_of_[target.joint] >= 0)
    throw ServiceError("joint '" + joints_[target.joint].name + "' is being moved by " +
                           running_service() + ": cancel it or wait for it to end",
                       Failure::busy, {{"parameter", target.parameter}});
}

void Armature::apply_now(const std::vector<Target>& targets) {
  for (const auto& t : targets) require_not_moving(t);
  mjData* d = data();
  for (const auto& t : targets) {
    const ArmatureJoint& j = joints_[t.joint];
    d->qpos[j.qpos] = t.value;
    d->qvel[j.dof] = 0;
    if (j.servo >= 0) d->ctrl[j.servo] = j.gear * t.value;
    hold_[t.joint] = t.value;
  }
  // what the client reads next (poses, sensors) reflects the new configuration
  sim().forward();
}

void Armature::set_rotation(const std::string& joint, double rotation) {
  const std::size_t i = joint_of_kind(joint, JointKind::revolute, "joint");
  require_reachable(joints_[i], rotation, "rotation");
  apply_now({{i, rotation, "rotation"}});
}

void Armature::set_translation(const std::string& joint, double translation) {
  const std::size_t i = joint_of_kind(joint, JointKind::prismatic, "joint");
  require_reachable(joints_[i], translation, "translation");
  apply_now({{i, translation, "translation"}});
}

void Armature::set_rotations(const json& rotations) {
  apply_now(targets_from(rotations, JointKind::revolute, "rotations"));
}

void Armature::set_translations(const json& translations) {
  apply_now(targets_from(translations, JointKind::prismatic, "translations"));
}

// ---- async services ------------------------------------------------------------------------

void Armature::start_moves(const std::vector<Target>& targets, JointKind kind,
                           std::optional<double> speed) {
  const bool prismatic = kind == JointKind::prismatic;
  double v = prismatic ? linear_speed_ : radial_speed_;
  if (speed) {
    bounds::require_between("speed", *speed, 0,
                            prismatic ? bounds::linear_speed : bounds::angular_speed,
                            prismatic ? "m/s" : "rad/s");
    if (*speed == 0)
      throw ServiceError("speed must be positive (null: the armature's " +
                             std::string(prismatic ? "linear_speed" : "radial_speed") + ")",
                         Failure::bad_arguments, {{"parameter", "speed"}});
    v = *speed;
  }
  // each joint goes straight to its target at the same speed, and arrives on its own time
  const double now = data()->time;
  Motion motion;
  for (const auto& t : targets) {
    const double from = joints_.position(data(), t.joint);
    motion.paths.push_back(
        {t.joint, {{now, from, 0}, {now + std::abs(t.value - from) / v, t.value, 0}}});
  }
  begin(std::move(motion));
}

void Armature::rotate(const std::string& joint, double rotation, std::optional<double> speed) {
  const std::size_t i = joint_of_kind(joint, JointKind::revolute, "joint");
  require_reachable(joints_[i], rotation, "rotation");
  start_moves({{i, rotation, "rotation"}}, JointKind::revolute, speed);
}

void Armature::translate(const std::string& joint, double translation,
                         std::optional<double> speed) {
  const std::size_t i = joint_of_kind(joint, JointKind::prismatic, "joint");
  require_reachable(joints_[i], translation, "translation");
  start_moves({{i, translation, "translation"}}, JointKind::prismatic, speed);
}

void Armature::rotate_joints(const std::map<std::string, double>& joint_rotations,
                             std::optional<double> speed) {
  start_moves(targets_from(json(joint_rotations), JointKind::revolute, "joint_rotations"),
              JointKind::revolute, speed);
}

void Armature::translate_joints(const std::map<std::string, double>& joint_translations,
                                std::optional<double> speed) {
  start_moves(targets_from(json(joint_translations), JointKind::prismatic, "joint_translations"),
              JointKind::prismatic, speed);
}

void Armature::trajectory(const json& trajectory) {
  // starttime is on the scale of `time now` (MORSE's gettime()), when the simulation has it
  double offset = 0;
  if (auto* entry = sim().find("time"))
    if (auto* time = dynamic_cast<TimeServices*>(entry->component.get()))
      offset = time->now() - data()->time;
  std::vector<double> from(joints_.size());
  for (std::size_t i = 0; i < joints_.size(); ++i) from[i] = joints_.position(data(), i);
  begin(parse_trajectory(trajectory, joints_, data()->time, offset, from));
}

void Armature::begin(Motion motion) {
  motion_ = std::move(motion);
  std::fill(path_of_.begin(), path_of_.end(), -1);
  for (std::size_t k = 0; k < motion_->paths.size(); ++k)
    path_of_[motion_->paths[k].joint] = static_cast<int>(k);
}

// ---- stepping ------------------------------------------------------------------------------

double Armature::tolerance_of(std::size_t i) const {
  return joints_[i].kind == JointKind::prismatic ? distance_tolerance_ : angle_tolerance_;
}

std::vector<std::size_t> Armature::not_arrived() const {
  std::vector<std::size_t> out;
  for (const auto& path : motion_->paths) {
    const ArmatureJoint& j = joints_[path.joint];
    // kinematic joints are where their path puts them, by construction
    if (j.servo < 0) continue;
    if (std::abs(joints_.position(data(), path.joint) - path.knots.back().position) >
        tolerance_of(path.joint))
      out.push_back(path.joint);
  }
  return out;
}

void Armature::drive(std::size_t i, double p, double p_next) {
  const ArmatureJoint& j = joints_[i];
  // a Hermite segment may overshoot between two points inside the range: stay inside it
  if (j.limited) {
    p = std::clamp(p, j.low, j.high);
    p_next = std::clamp(p_next, j.low, j.high);
  }
  mjData* d = data();
  if (j.servo >= 0) {
    double ctrl = j.gear * p_next;
    if (j.ctrl_limited) ctrl = std::clamp(ctrl, j.ctrl_low, j.ctrl_high);
    d->ctrl[j.servo] = ctrl;
    return;
  }
  kinematic_.add(j.qpos, j.dof, p, (p_next - p) / model()->opt.timestep);
}

void Armature::default_action() {
  const double t = data()->time, dt = model()->opt.timestep;
  for (std::size_t i = 0; i < joints_.size(); ++i) {
    if (motion_ && path_of_[i] >= 0) {
      const JointPath& path = motion_->paths[static_cast<std::size_t>(path_of_[i])];
      drive(i, sample(path, motion_->hermite, t).position,
            sample(path, motion_->hermite, t + dt).position);
    } else if (hold_[i]) {
      drive(i, *hold_[i], *hold_[i]);
    }
  }
  drive_kinematic();
  if (motion_ && progress_due()) report_progress(t);
  if (!motion_ || t < motion_->end_time()) return;

  // past the last knot: done once every servo joint has arrived, FAILED if one never does
  const std::vector<std::size_t> late = not_arrived();
  const bool timed_out = t >= motion_->end_time() + settle_timeout_;
  if (!late.empty() && !timed_out) return;
  std::string failure;
  for (std::size_t i : late)
    failure += (failure.empty() ? "" : "; ") + std::string("joint '") + joints_[i].name +
               "' is at " + number(joints_.position(data(), i)) + " " +
               std::string(unit_of(joints_[i].kind)) + ", target " +
               number(motion_->paths[static_cast<std::size_t>(path_of_[i])].knots.back().position);
  // the joints stay commanded to their targets either way
  for (const auto& path : motion_->paths) hold_[path.joint] = path.knots.back().position;
  motion_.reset();
  std::fill(path_of_.begin(), path_of_.end(), -1);
  if (!has_running_request()) return;
  if (failure.empty())
    completed(Status::success);
  else
    completed(Status::failed,
              failure + " (" + number(settle_timeout_) +
                  " s after the motion's end: its position servo cannot get there; blocked, or too "
                  "weak against the load?)");
}

void Armature::report_progress(double t) {
  // every path has as many knots: its start, then one per trajectory point (or its target);
  // a point is reached once every joint's knot of it is past (moves of several joints at
  // one speed arrive one by one)
  const std::size_t points = motion_->paths.front().knots.size() - 1;
  std::size_t reached = 0;
  while (reached < points &&
         std::all_of(
             motion_->paths.begin(), motion_->paths.end(),
             [&](const JointPath& p) { return p.knots[reached + 1].time <= t; }))
    ++reached;
  progress({{"points_reached", reached},
            {"points", points},
            {"time_left", std::max(0.0, motion_->end_time() - t)}});
}

void Armature::interrupt() {
  // MORSE: the joints stay where they are now, from this moment (servos get their new ctrl
  // before anyone reads it)
  if (motion_)
    for (const auto& path : motion_->paths) {
      hold_[path.joint] = joints_.position(data(), path.joint);
      drive(path.joint, *hold_[path.joint], *hold_[path.joint]);
    }
  drive_kinematic();
  motion_.reset();
  std::fill(path_of_.begin(), path_of_.end(), -1);
  Component::interrupt();
}

void Armature::on_reset() {
  // the initial state is back: nothing is held any more, and the motion's start is gone
  motion_.reset();
  std::fill(path_of_.begin(), path_of_.end(), -1);
  std::fill(hold_.begin(), hold_.end(), std::nullopt);
  if (has_running_request())
    completed(Status::preempted,
              "the simulation was reset (simulation reset_objects, or the recovery from a bad "
              "state): the motion was dropped");
}

SIMGATE_BUILTIN_TYPE(
    armature, builtin_type<Armature>(
                  "armature", Kind::component,
                  "moves hinge and slide joints: set_rotations, rotate_joints, trajectory...",
                  "docs/components/armature.md",
                  {{"joints",
                    {{"$ref", "#/$defs/armature_joints"}},
                    "only these joints of its subtree, in this order"},
                   {"radial_speed",
                    {{"type", "number"}, {"minimum", 1e-6}, {"maximum", 1000}, {"default", 0.8}},
                    "rad/s when a rotation's speed is null"},
                   {"linear_speed",
                    {{"type", "number"}, {"minimum", 1e-6}, {"maximum", 1000}, {"default", 0.05}},
                    "m/s when a translation's speed is null"},
                   {"angle_tolerance",
                    {{"type", "number"}, {"minimum", 1e-9}, {"maximum", 1}, {"default", 0.01}},
                    "radians: arrival of a servo-driven revolute joint"},
                   {"distance_tolerance",
                    {{"type", "number"}, {"minimum", 1e-9}, {"maximum", 1}, {"default", 0.005}},
                    "metres: arrival of a servo-driven prismatic joint"},
                   {"settle_timeout",
                    {{"type", "number"}, {"minimum", 0}, {"maximum", 1e6}, {"default", 2}},
                    "seconds a servo-driven joint may take to arrive after a motion's end"}}));

}  // namespace simgate::sim
