#include "simgate/sim/sim_component.h"

#include <algorithm>
#include <cmath>

#include "simgate/core/errors.h"
#include "simgate/sim/bounds.h"

namespace simgate::sim {

// ---- MORSE's object services ------------------------------------------------------------------

void SimComponent::add_property(std::string name, std::function<json()> get) {
  properties_.push_back({std::move(name), std::move(get), {}});
}

void SimComponent::add_property(std::string name, std::function<json()> get,
                                std::function<void(const json&)> set) {
  properties_.push_back({std::move(name), std::move(get), std::move(set)});
}

void SimComponent::add_number_property(std::string name, double& value, double low, double high,
                                       std::string unit) {
  std::string parameter = name;
  add_property(
      std::move(name), [&value] { return json(value); },
      [&value, low, high, parameter, unit](const json& v) {
        if (!v.is_number())
          throw ServiceError("property '" + parameter + "' is a number, found " + describe_json(v),
                             Failure::bad_arguments, {{"parameter", "prop_val"}});
        double d = v.get<double>();
        bounds::require_between(parameter, d, low, high, unit);
        value = d;
      });
}

void SimComponent::model_changed(const ModelRemap& remap) {
  body_ = remap.body_of(body_);
  robot_body_ = remap.body_of(robot_body_);
  on_model_changed(remap);
}

void SimComponent::add_object_services(json configuration, int body, int robot_body) {
  configuration_ = std::move(configuration);
  body_ = body;
  robot_body_ = robot_body;
  add_service("get_properties", &SimComponent::get_properties)
      .doc("MORSE's properties of this component: {\"properties\": {name: value}}");
  add_service("set_property", &SimComponent::set_property, {"prop_name", "prop_val"})
      .doc("Sets a property get_properties lists (FAILED for unknown or read-only ones)");
  add_service("get_configurations", &SimComponent::get_configurations)
      .doc("How the component was configured, and its pose on the robot (object_to_robot)");
}

json SimComponent::get_properties() const {
  json out = json::object();
  for (const auto& p : properties_) out[p.name] = p.get();
  return {{"properties", std::move(out)}};
}

void SimComponent::set_property(const std::string& name, const json& value) {
  std::string settable;
  for (const auto& p : properties_)
    if (p.set) settable += (settable.empty() ? "" : ", ") + p.name;
  for (const auto& p : properties_) {
    if (p.name != name) continue;
    if (!p.set)
      throw ServiceError(
          "property '" + name + "' of " + this->name() + " is read-only" +
              (settable.empty() ? " (none can be set)" : " (settable: " + settable + ")"),
          Failure::bad_arguments, {{"parameter", "prop_name"}});
    p.set(value);
    return;
  }
  std::string all;
  for (const auto& p : properties_) all += (all.empty() ? "" : ", ") + p.name;
  throw ServiceError("no property '" + name + "' in " + this->name() +
                         (all.empty() ? " (it has none)" : " (properties: " + all + ")"),
                     Failure::bad_arguments, {{"parameter", "prop_name"}});
}

json SimComponent::get_configurations() const {
  json c = configuration_.is_object() ? configuration_ : json::object();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  Eigen::Quaterniond r = Eigen::Quaterniond::Identity();
  // the robot itself, or a component on the robot's own body: exactly the identity (the
  // product of a rotation and its conjugate is 1 only to rounding)
  if (body_ >= 0 && robot_body_ >= 0 && body_ != robot_body_) {
    Eigen::Quaterniond root = body_orientation(sim_, robot_body_).normalized();
    t = root.conjugate() * (body_position(sim_, body_) - body_position(sim_, robot_body_));
    r = root.conjugate() * body_orientation(sim_, body_);
  }
  c["object_to_robot"] = {{"translation", {t.x(), t.y(), t.z()}},
                          {"rotation", {r.w(), r.x(), r.y(), r.z()}}};
  return {{"configurations", std::move(c)}};
}

Eigen::Vector3d body_position(const Simulation& sim, int body) {
  const mjtNum* p = sim.d()->xpos + 3 * body;
  return {p[0], p[1], p[2]};
}

Eigen::Quaterniond body_orientation(const Simulation& sim, int body) {
  const mjtNum* q = sim.d()->xquat + 4 * body;  // MuJoCo: w, x, y, z
  return Eigen::Quaterniond(q[0], q[1], q[2], q[3]);
}

Eigen::Vector3d to_roll_pitch_yaw(const Eigen::Quaterniond& q) {
  const double w = q.w(), x = q.x(), y = q.y(), z = q.z();
  double roll = std::atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y));
  double sinp = 2 * (w * y - z * x);
  double pitch = std::abs(sinp) >= 1 ? std::copysign(M_PI / 2, sinp) : std::asin(sinp);
  double yaw = std::atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z));
  return {roll, pitch, yaw};
}

Eigen::Quaterniond from_roll_pitch_yaw(double roll, double pitch, double yaw) {
  return Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
         Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
         Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX());
}

bool in_subtree(const mjModel* m, int body, int root) {
  if (body < 0 || body >= m->nbody) return false;
  // body_parentid[0] == 0: the world body ends every walk
  for (int b = body;; b = m->body_parentid[b]) {
    if (b == root) return true;
    if (b == 0) return false;
  }
}

double command_number(const json& command, const std::string& key, std::optional<double> fallback) {
  auto it = command.find(key);
  if (it == command.end()) {
    if (fallback) return *fallback;
    throw ServiceError("the command has no '" + key + "'", Failure::bad_arguments,
                       {{"parameter", key}});
  }
  if (!it->is_number())
    throw ServiceError(key + ": expected a number, found " + describe_json(*it),
                       Failure::bad_arguments, {{"parameter", key}});
  return it->get<double>();
}

void set_free_body_pose(Simulation& sim, int free_joint, const Eigen::Vector3d& position,
                        const Eigen::Quaterniond& orientation) {
  const mjModel* m = sim.m();
  mjData* d = sim.d();
  mjtNum* q = d->qpos + m->jnt_qposadr[free_joint];
  Eigen::Quaterniond o = orientation.normalized();
  q[0] = position.x();
  q[1] = position.y();
  q[2] = position.z();
  q[3] = o.w();
  q[4] = o.x();
  q[5] = o.y();
  q[6] = o.z();
  // a teleported body starts at rest
  mjtNum* v = d->qvel + m->jnt_dofadr[free_joint];
  for (int i = 0; i < 6; ++i) v[i] = 0;
  // what clients read next (poses, sensors) is of the moved body, now
  sim.forward();
}

}  // namespace simgate::sim
