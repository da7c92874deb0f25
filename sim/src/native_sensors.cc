// The native sensors' frame, and imu, odometry and proximity (laser_scanner.cc has the
// laser). What each measures and in which frame: native_sensors.h.
#include "simgate/sim/native_sensors.h"

#include <cmath>

#include "simgate/core/errors.h"
#include "simgate/sim/bounds.h"
#include "helpers.h"

namespace simgate::sim {

namespace {
std::string join_names(const std::vector<std::string>& names, std::size_t at_most) {
  std::string out;
  for (std::size_t i = 0; i < names.size() && i < at_most; ++i) out += (i ? ", " : "") + names[i];
  if (names.size() > at_most) out += ", ... (" + std::to_string(names.size()) + " in all)";
  return out;
}
}  // namespace

// ---- the sensor frame -------------------------------------------------------------------------

SensorFrame SensorFrame::from(ComponentContext& c) {
  const mjModel* m = c.sim().m();
  if (!c.options().has("site")) return SensorFrame(c.body(), -1);
  const std::string site = c.options().get_string("site", "");
  const int robot_body = c.robot().body();
  // the sites a robot may measure from: those on its own bodies
  std::vector<std::string> robot_sites;
  for (int s = 0; s < m->nsite; ++s)
    if (in_subtree(m, m->site_bodyid[s], robot_body)) {
      const char* name = mj_id2name(m, mjOBJ_SITE, s);
      if (name) robot_sites.push_back(name);
    }
  const std::string expected =
      "expected the name of a site on robot '" + c.robot().name() + "' (" +
      (robot_sites.empty() ? std::string("it has none") : join_names(robot_sites, 20)) + ")";
  const int id = mj_name2id(m, mjOBJ_SITE, site.c_str());
  if (id < 0)
    throw ConfigError(c.options().path_of("site") + ": " + expected + ", found '" + site +
                      "' (no such site)");
  if (!in_subtree(m, m->site_bodyid[id], robot_body))
    throw ConfigError(c.options().path_of("site") + ": " + expected + ", found '" + site +
                      "', which is on body '" + c.sim().model().body_name(m->site_bodyid[id]) +
                      "', not on the robot");
  return SensorFrame(m->site_bodyid[id], id);
}

const mjtNum* SensorFrame::position(const mjData* d) const {
  return site_ >= 0 ? d->site_xpos + 3 * site_ : d->xpos + 3 * body_;
}

const mjtNum* SensorFrame::rotation(const mjData* d) const {
  return site_ >= 0 ? d->site_xmat + 9 * site_ : d->xmat + 9 * body_;
}

Eigen::Vector3d SensorFrame::world_position(const mjData* d) const {
  const mjtNum* p = position(d);
  return {p[0], p[1], p[2]};
}

Eigen::Matrix3d SensorFrame::world_rotation(const mjData* d) const {
  // MuJoCo's matrices are row-major
  return Eigen::Map<const Eigen::Matrix<mjtNum, 3, 3, Eigen::RowMajor>>(rotation(d));
}

// ---- imu ------------------------------------------------------------------------------------

namespace {
// True when mj_step's own sensor pass computes cacc (MuJoCo 2.2.2's mj_sensorAcc runs
// mj_rnePostConstraint for accelerometers, force and torque sensors, unless sensors are
// disabled).
bool step_computes_cacc(const mjModel* m) {
  if (m->opt.disableflags & mjDSBL_SENSOR) return false;
  for (int s = 0; s < m->nsensor; ++s) {
    const int type = m->sensor_type[s];
    if (type == mjSENS_ACCELEROMETER || type == mjSENS_FORCE || type == mjSENS_TORQUE) return true;
  }
  return false;
}
}  // namespace

Imu::Imu(ComponentContext& c)
    : SimComponent(c.name(), c.sim()),
      frame_(SensorFrame::from(c)),
      step_computes_cacc_(step_computes_cacc(c.sim().m())) {
  add_service("get_local_data", &Imu::get_local_data)
      .doc(
          "angular_velocity (rad/s), linear_acceleration (m/s², gravity included) and "
          "magnetic_field in the "
          "sensor frame");
  declare_output_stream("imu", [this] { return get_local_data(); });
}

void Imu::on_model_changed(const ModelRemap& remap) {
  frame_.remap(remap);
  step_computes_cacc_ = step_computes_cacc(model());
}

json Imu::get_local_data() const {
  const mjModel* m = model();
  mjData* d = data();
  mjtNum velocity[6], acceleration[6];  // MuJoCo's order: angular, then linear
  mj_objectVelocity(m, d, frame_.object_type(), frame_.object_id(), velocity, 1);
  // cacc (the bodies' accelerations, gravity as an upward acceleration of the world: what
  // an accelerometer reads) is left stale by mj_step unless the model has acceleration
  // sensors. mj_rnePostConstraint recomputes it from the last step's accelerations and
  // constraint forces; it writes only cacc, cfrc_int and cfrc_ext, which no later stage
  // reads. (It combines them with qvel, which mj_step has already advanced: a difference
  // of one step's velocity change in the Coriolis term, nothing at constant velocity.)
  if (!step_computes_cacc_) mj_rnePostConstraint(m, d);
  mj_objectAcceleration(m, d, frame_.object_type(), frame_.object_id(), acceleration, 1);
  // the scene's magnetic field, as MuJoCo's magnetometer reads it: turned into the frame
  Eigen::Vector3d field =
      frame_.world_rotation(d).transpose() *
      Eigen::Vector3d(m->opt.magnetic[0], m->opt.magnetic[1], m->opt.magnetic[2]);
  return {{"angular_velocity", {velocity[0], velocity[1], velocity[2]}},
          {"linear_acceleration", {acceleration[3], acceleration[4], acceleration[5]}},
          {"magnetic_field", {field.x(), field.y(), field.z()}},
          {"timestamp", sim().state_time()}};
}

// ---- odometry ---------------------------------------------------------------------------------

Odometry::Odometry(ComponentContext& c)
    : SimComponent(c.name(), c.sim()), frame_(SensorFrame::from(c)) {
  level_name_ =
      c.options().get_choice("level", "integrated", {"raw", "differential", "integrated"});
  level_ = level_name_ == "raw"            ? Level::raw
           : level_name_ == "differential" ? Level::differential
                                           : Level::integrated;
  restart();
  add_service("get_local_data", &Odometry::get_local_data)
      .doc(level_ == Level::raw ? "dS: distance travelled (m) since the previous reading"
           : level_ == Level::differential
               ? "dx, dy, dz (m), dyaw, dpitch, droll (rad) since the previous reading"
               : "x, y, z, yaw, pitch, roll since start; vx, vy, vz, wz, wy, wx in the "
                 "sensor frame");
  add_property("level", [this] { return json(level_name_); });
  // its samples' shape depends on the level: "odometry" is the integrated pose and twist
  // (typed topics carry it), the other levels' differences are kinds of their own
  declare_output_stream(level_ == Level::integrated ? "odometry" : "odometry_" + level_name_,
                        [this] { return get_local_data(); });
}

void Odometry::relative_pose(Eigen::Vector3d& position, Eigen::Vector3d& rpy) const {
  const Eigen::Matrix3d to_origin = origin_rotation_.transpose();
  position = to_origin * (frame_.world_position(data()) - origin_position_);
  rpy = to_roll_pitch_yaw(Eigen::Quaterniond(to_origin * frame_.world_rotation(data())));
}

void Odometry::restart() {
  origin_position_ = frame_.world_position(data());
  origin_rotation_ = frame_.world_rotation(data());
  last_position_.setZero();
  last_rpy_.setZero();
  ds_ = 0;
  dposition_.setZero();
  drpy_.setZero();
}

void Odometry::update() {
  Eigen::Vector3d position, rpy;
  relative_pose(position, rpy);
  // summed step by step: the path's length, and angles that turn more than half a turn
  // between two readings
  const Eigen::Vector3d step = position - last_position_;
  ds_ += step.norm();
  dposition_ += step;
  for (int k = 0; k < 3; ++k) drpy_[k] += wrap_angle(rpy[k] - last_rpy_[k]);
  last_position_ = position;
  last_rpy_ = rpy;
}

json Odometry::get_local_data() {
  update();
  const double time = sim().state_time();
  json out;
  switch (level_) {
    case Level::raw: out = {{"dS", ds_}, {"timestamp", time}}; break;
    case Level::differential:
      out = {{"dx", dposition_.x()}, {"dy", dposition_.y()}, {"dz", dposition_.z()},
             {"dyaw", drpy_.z()},    {"dpitch", drpy_.y()},  {"droll", drpy_.x()},
             {"timestamp", time}};
      break;
    case Level::integrated: {
      mjtNum velocity[6];  // angular, then linear, in the sensor frame
      mj_objectVelocity(model(), data(), frame_.object_type(), frame_.object_id(), velocity, 1);
      out = {{"x", last_position_.x()}, {"y", last_position_.y()}, {"z", last_position_.z()},
             {"yaw", last_rpy_.z()},    {"pitch", last_rpy_.y()},  {"roll", last_rpy_.x()},
             {"vx", velocity[3]},       {"vy", velocity[4]},       {"vz", velocity[5]},
             {"wz", velocity[2]},       {"wy", velocity[1]},       {"wx", velocity[0]},
             {"timestamp", time}};
      break;
    }
  }
  // the next reading's differences start here
  ds_ = 0;
  dposition_.setZero();
  drpy_.setZero();
  return out;
}

// ---- proximity ------------------------------------------------------------------------------

Proximity::Proximity(ComponentContext& c)
    : SimComponent(c.name(), c.sim()), frame_(SensorFrame::from(c)), robot_body_(c.robot().body()) {
  range_ = c.options().get_number("range", 100, 0, bounds::position);
  const std::string tag = c.options().get_string("track", k_robot_tag);
  try {
    set_tracked_tag(tag);
  } catch (const ServiceError& e) {
    throw ConfigError(c.options().path_of("track") + ": " + e.message());
  }
  add_service("get_local_data", &Proximity::get_local_data)
      .doc("near_objects: {name: distance (m)} of the tracked objects within range of the sensor");
  declare_output_stream("proximity", [this] { return get_local_data(); });
  add_service("set_range", &Proximity::set_range, {"range"}).doc("The detection range, metres");
  add_service("set_tracked_tag", &Proximity::set_tracked_tag, {"tag"})
      .doc("What is tracked: 'Robot_Tag' (the other robots) or the start of top-level body names");
  add_number_property("Range", range_, 0, bounds::position, "m");
  add_property(
      "Track", [this] { return json(tag_); },
      [this](const json& v) {
        if (!v.is_string())
          throw ServiceError("property 'Track' is a string, found " + describe_json(v),
                             Failure::bad_arguments, {{"parameter", "prop_val"}});
        set_tracked_tag(v.get<std::string>());
      });
}

std::vector<int> Proximity::bodies_tagged(const std::string& tag) const {
  const mjModel* m = model();
  std::vector<int> out;
  for (int b = 1; b < m->nbody; ++b) {
    if (m->body_parentid[b] != 0 || in_subtree(m, b, robot_body_)) continue;
    if (sim().model().body_name(b).rfind(tag, 0) == 0) out.push_back(b);
  }
  return out;
}

void Proximity::set_range(double range) {
  bounds::require_between("range", range, 0, bounds::position, "m");
  range_ = range;
}

void Proximity::set_tracked_tag(const std::string& tag) {
  if (tag == k_robot_tag) {
    tracked_.clear();
    tag_ = tag;
    return;
  }
  std::vector<int> bodies = bodies_tagged(tag);
  if (bodies.empty()) {
    // a tag that tracks nothing is a typo: say what could be tracked
    std::vector<std::string> names;
    for (int b : bodies_tagged("")) names.push_back(sim().model().body_name(b));
    throw ServiceError(
        "no object to track with tag '" + tag + "': expected '" + k_robot_tag +
            "' (the simulation's other robots) or the start of the name of a top-level body (" +
            (names.empty() ? std::string("there is none") : join_names(names, 20)) + ")",
        Failure::bad_arguments, {{"parameter", "tag"}});
  }
  tracked_ = std::move(bodies);
  tag_ = tag;
}

void Proximity::on_model_changed(const ModelRemap& remap) {
  frame_.remap(remap);
  robot_body_ = remap.body_of(robot_body_);
  // the top-level bodies of the tag as they are now: a deleted one goes, a spawned one joins
  if (tag_ != k_robot_tag) tracked_ = bodies_tagged(tag_);
}

json Proximity::get_local_data() const {
  const mjModel* m = model();
  const mjData* d = data();
  const Eigen::Vector3d here = frame_.world_position(d);
  json near = json::object();
  auto consider = [&](const std::string& name, int body) {
    const double distance = (body_position(sim(), body) - here).norm();
    if (distance <= range_) near[name] = distance;
  };
  if (tag_ == k_robot_tag) {
    // the robots of the simulation, by robot name, measured to their root bodies
    for (const auto& e : sim().components()) {
      if (!e->is_robot) continue;
      const auto* robot = dynamic_cast<const Robot*>(e->component.get());
      if (robot && !in_subtree(m, robot->body(), robot_body_))
        consider(robot->name(), robot->body());
    }
  } else {
    for (int b : tracked_) consider(sim().model().body_name(b), b);
  }
  // near_robots: MORSE's deprecated name of the same dictionary, kept for its old clients
  return {{"near_objects", near}, {"near_robots", near}, {"timestamp", sim().state_time()}};
}

SIMGATE_BUILTIN_TYPE(
    imu, builtin_type<Imu>(
             "imu", Kind::component,
             "inertial measurement unit: get_local_data (angular_velocity, linear_acceleration)",
             "docs/components/native-sensors.md",
             {{"site",
               {{"type", "string"}},
               "a MuJoCo site on the robot: the sensor's frame (default: the body's frame)"}}));
SIMGATE_BUILTIN_TYPE(
    odometry, builtin_type<Odometry>(
                  "odometry", Kind::component,
                  "odometry (level raw, differential or integrated): get_local_data",
                  "docs/components/native-sensors.md",
                  {{"site",
                    {{"type", "string"}},
                    "a MuJoCo site on the robot: the sensor's frame (default: the body's frame)"},
                   {"level",
                    {{"enum", {"raw", "differential", "integrated"}}, {"default", "integrated"}},
                    "MORSE's functional level"}}));
SIMGATE_BUILTIN_TYPE(
    proximity, builtin_type<Proximity>(
                   "proximity", Kind::component,
                   "objects within range: get_local_data, set_range, set_tracked_tag",
                   "docs/components/native-sensors.md",
                   {{"site",
                     {{"type", "string"}},
                     "a MuJoCo site on the robot: the sensor's frame (default: the body's frame)"},
                    {"range",
                     {{"type", "number"}, {"minimum", 0}, {"maximum", 1e6}, {"default", 100}},
                     "metres"},
                    {"track",
                     {{"type", "string"}, {"default", "Robot_Tag"}},
                     "Robot_Tag (the other robots) or the start of top-level body names"}}));

}  // namespace simgate::sim
