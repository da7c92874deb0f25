// The entities group of `simulation` (docs/world/entities.md): any body of the scene, by
// name, whichever robot it belongs to. MORSE's set_object_position and
// set_object_dynamics; get_object_pose, get_object_bbox and get_object_global_bbox; and
// ROS 2 simulation_interfaces' entity state (pose and twist in the world frame) and
// listing.
//
// Conventions: positions in metres in the world frame; orientations as get_scene_objects
// gives them, quaternions [qx, qy, qz, qw], or MORSE's [roll, pitch, yaw] in radians where
// MORSE takes those (set_object_position). A body is placed through its free joint (the
// robot's root included: set_free_body_pose, so its components read the moved body at
// once) or, for a mocap body, its mocap pose; a body hanging from another by joints, or
// welded to the world, cannot be placed on its own and the request FAILS saying so.
//
// Frozen bodies (set_object_dynamics false): each step, before physics, the free joint is
// put back where the body was frozen and its velocity zeroed, so physics never moves it.
// Whoever places it meanwhile (set_object_position, set_entity_state, reset_objects, a
// teleport) moves where it is held: the hook compares the pose clients read (xpos/xquat,
// which mj_step evaluated before integrating, and which every placement re-evaluates
// through Simulation::forward) with the held one and adopts a new one. Bodies are held by
// name, so a model rebuilt around them keeps them frozen.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "simgate/core/errors.h"
#include "simgate/core/suggest.h"
#include "simgate/sim/bounds.h"
#include "simgate/sim/sim_component.h"
#include "simgate/sim/world_services.h"

namespace simgate::sim {

namespace {

[[noreturn]] void refuse(const std::string& parameter, const std::string& message,
                         const std::string& expected) {
  throw ServiceError(message, Failure::bad_arguments,
                     {{"parameter", parameter}, {"expected", expected}});
}

// '*' any run of characters, '?' any one; linear in practice (one backtrack point), so
// that a client's pattern cannot make it explode.
bool glob_matches(const std::string& pattern, const std::string& name) {
  std::size_t p = 0, n = 0, star = std::string::npos, resume = 0;
  while (n < name.size()) {
    if (p < pattern.size() && (pattern[p] == '?' || pattern[p] == name[n])) {
      ++p;
      ++n;
    } else if (p < pattern.size() && pattern[p] == '*') {
      star = p++;
      resume = n;
    } else if (star != std::string::npos) {
      p = star + 1;
      n = ++resume;
    } else {
      return false;
    }
  }
  while (p < pattern.size() && pattern[p] == '*') ++p;
  return p == pattern.size();
}

// ---- reading a client's numbers --------------------------------------------------------

// [x, y, z] within the world bound, named `parameter` ("position", "state.twist.linear").
Eigen::Vector3d vector3(const json& value, const std::string& parameter, double bound,
                        const std::string& unit) {
  const std::string expected = "an array of 3 numbers [x, y, z] in " + unit;
  if (!value.is_array() || value.size() != 3)
    refuse(parameter, parameter + ": expected " + expected + ", found " + describe_json(value),
           expected);
  Eigen::Vector3d v;
  for (int i = 0; i < 3; ++i) {
    const std::string at = parameter + "[" + std::to_string(i) + "]";
    if (!value[i].is_number())
      refuse(at, at + ": expected a number, found " + describe_json(value[i]), "a number");
    v[i] = value[i].get<double>();
    bounds::require_within(at, v[i], bound, unit);
  }
  return v;
}

// [qx, qy, qz, qw] (get_scene_objects' order), normalised. A norm far from 1 (a zero
// quaternion, Euler angles in the wrong field) is refused rather than guessed at.
Eigen::Quaterniond quaternion(const json& value, const std::string& parameter) {
  const std::string expected =
      "a rotation quaternion [qx, qy, qz, qw] of finite numbers with a norm from 0.5 to 2";
  if (!value.is_array() || value.size() != 4)
    refuse(parameter, parameter + ": expected " + expected + ", found " + describe_json(value),
           expected);
  std::array<double, 4> q;
  for (int i = 0; i < 4; ++i) {
    const std::string at = parameter + "[" + std::to_string(i) + "]";
    if (!value[i].is_number())
      refuse(at, at + ": expected a number, found " + describe_json(value[i]), "a number");
    q[i] = value[i].get<double>();
    bounds::require_within(at, q[i], 2, "");  // a component of a norm of at most 2
  }
  const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  if (!(norm >= 0.5 && norm <= 2))
    refuse(parameter, parameter + " = " + value.dump() + " is not a rotation: expected " + expected,
           expected);
  return Eigen::Quaterniond(q[3], q[0], q[1], q[2]).normalized();
}

json to_json(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
json to_json(const Eigen::Quaterniond& q) { return {q.x(), q.y(), q.z(), q.w()}; }

// The members of `object` (named `parameter`) are among `allowed`.
void require_keys(const json& object, const std::string& parameter,
                  const std::vector<std::string>& allowed) {
  std::string list;
  for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
  const std::string expected = "an object with any of " + list;
  if (!object.is_object())
    refuse(parameter, parameter + ": expected " + expected + ", found " + describe_json(object),
           expected);
  for (auto it = object.begin(); it != object.end(); ++it)
    if (std::find(allowed.begin(), allowed.end(), it.key()) == allowed.end())
      refuse(parameter + "." + it.key(),
             parameter + ": unknown member '" + it.key() + "'" + did_you_mean(it.key(), allowed) +
                 ", expected " + expected,
             expected);
}

// ---- bounding boxes --------------------------------------------------------------------

// The farthest a geom reaches along `u` (a unit vector of its own frame) from its centre;
// nullopt for an infinite plane.
std::optional<double> geom_support(const mjModel* m, int g, const Eigen::Vector3d& u) {
  const mjtNum* s = m->geom_size + 3 * g;
  const Eigen::Vector3d a = u.cwiseAbs();
  switch (m->geom_type[g]) {
    case mjGEOM_PLANE:
      if (s[0] <= 0 || s[1] <= 0) return std::nullopt;
      return a.x() * s[0] + a.y() * s[1];
    case mjGEOM_HFIELD: {
      const mjtNum* h = m->hfield_size + 4 * m->geom_dataid[g];  // x, y, top, bottom
      return a.x() * h[0] + a.y() * h[1] + (u.z() > 0 ? u.z() * h[2] : -u.z() * h[3]);
    }
    case mjGEOM_SPHERE: return s[0];
    case mjGEOM_CAPSULE: return s[0] + a.z() * s[1];
    case mjGEOM_ELLIPSOID:
      return std::sqrt(std::pow(s[0] * u.x(), 2) + std::pow(s[1] * u.y(), 2) +
                       std::pow(s[2] * u.z(), 2));
    case mjGEOM_CYLINDER: return a.z() * s[1] + s[0] * std::sqrt(u.x() * u.x() + u.y() * u.y());
    case mjGEOM_BOX: return a.x() * s[0] + a.y() * s[1] + a.z() * s[2];
    case mjGEOM_MESH: {
      const int mesh = m->geom_dataid[g];
      const float* v = m->mesh_vert + 3 * m->mesh_vertadr[mesh];
      double best = -std::numeric_limits<double>::infinity();
      for (int i = 0; i < m->mesh_vertnum[mesh]; ++i, v += 3)
        best = std::max(best, u.x() * v[0] + u.y() * v[1] + u.z() * v[2]);
      return best;
    }
    default: return 0.0;
  }
}

}  // namespace

// The services' state: the simulation and the bodies held frozen.
class EntityServices {
 public:
  explicit EntityServices(Simulation& sim) : sim_(sim) {}

  void set_object_position(const std::string& object_name, const std::array<double, 3>& position,
                           const json& orientation) {
    const int body = find_body(object_name, "object_name");
    Eigen::Vector3d p;
    for (int i = 0; i < 3; ++i) {
      bounds::require_within("position[" + std::to_string(i) + "]", position[i], bounds::position,
                             "m");
      p[i] = position[i];
    }
    Eigen::Quaterniond q = body_orientation(sim_, body);
    // MORSE: `if orientation:` -- null and [] keep it
    if (!orientation.is_null() && !(orientation.is_array() && orientation.empty())) {
      const std::string expected = "[roll, pitch, yaw] in radians, or null to keep the orientation";
      if (!orientation.is_array() || orientation.size() != 3)
        refuse("orientation",
               "orientation: expected " + expected + ", found " + describe_json(orientation),
               expected);
      std::array<double, 3> rpy;
      for (int i = 0; i < 3; ++i) {
        const std::string at = "orientation[" + std::to_string(i) + "]";
        if (!orientation[i].is_number())
          refuse(at, at + ": expected a number, found " + describe_json(orientation[i]),
                 "a number");
        rpy[i] = orientation[i].get<double>();
        bounds::require_within(at, rpy[i], bounds::angle, "rad");
      }
      q = from_roll_pitch_yaw(rpy[0], rpy[1], rpy[2]);
    }
    place(body, object_name, "object_name", p, q);
  }

  json get_object_pose(const std::string& object_name) const {
    const int body = find_body(object_name, "object_name");
    return {to_json(body_position(sim_, body)), to_json(body_orientation(sim_, body))};
  }

  json get_object_bbox(const std::string& object_name) const {
    const int body = find_body(object_name, "object_name");
    return bbox(body, object_name, body_position(sim_, body),
                body_orientation(sim_, body).toRotationMatrix());
  }

  json get_object_global_bbox(const std::string& object_name) const {
    const int body = find_body(object_name, "object_name");
    return bbox(body, object_name, Eigen::Vector3d::Zero(), Eigen::Matrix3d::Identity());
  }

  bool set_object_dynamics(const std::string& object_name, bool state) {
    const int body = find_body(object_name, "object_name");
    const int joint = free_joint(body, object_name, "object_name", "have its dynamics switched");
    const std::string name = sim_.model().body_name(body);
    const mjModel* m = sim_.m();
    mjData* d = sim_.d();
    mjtNum* qvel = d->qvel + m->jnt_dofadr[joint];
    if (!state) {
      if (frozen_.count(name)) return state;
      // held where clients see it; its velocity is given back when it is released (MORSE)
      Frozen f;
      std::copy(d->xpos + 3 * body, d->xpos + 3 * body + 3, f.pose.begin());
      std::copy(d->xquat + 4 * body, d->xquat + 4 * body + 4, f.pose.begin() + 3);
      std::copy(qvel, qvel + 6, f.velocity.begin());
      frozen_.emplace(name, f);
      hold(body, joint, frozen_.at(name));
    } else if (auto it = frozen_.find(name); it != frozen_.end()) {
      std::copy(it->second.velocity.begin(), it->second.velocity.end(), qvel);
      frozen_.erase(it);
      sim_.forward();
    }
    return state;
  }

  json get_entity_state(const std::string& name) const {
    const int body = find_body(name, "name");
    // 6D velocity at the body's origin, world axes: angular first
    mjtNum v[6];
    mj_objectVelocity(sim_.m(), sim_.d(), mjOBJ_BODY, body, v, 0);
    return {{"pose",
             {{"position", to_json(body_position(sim_, body))},
              {"orientation", to_json(body_orientation(sim_, body))}}},
            {"twist", {{"linear", {v[3], v[4], v[5]}}, {"angular", {v[0], v[1], v[2]}}}}};
  }

  json set_entity_state(const std::string& name, const json& state) {
    const int body = find_body(name, "name");
    // everything is read and checked before anything changes
    require_keys(state, "state", {"pose", "twist"});
    if (state.empty())
      refuse("state", "state: expected at least one of pose, twist, found {}", "pose and/or twist");
    std::optional<Eigen::Vector3d> position, linear, angular;
    std::optional<Eigen::Quaterniond> orientation;
    if (auto pose = state.find("pose"); pose != state.end()) {
      require_keys(*pose, "state.pose", {"position", "orientation"});
      if (pose->contains("position"))
        position = vector3(pose->at("position"), "state.pose.position", bounds::position, "m");
      if (pose->contains("orientation"))
        orientation = quaternion(pose->at("orientation"), "state.pose.orientation");
    }
    if (auto twist = state.find("twist"); twist != state.end()) {
      require_keys(*twist, "state.twist", {"linear", "angular"});
      if (twist->contains("linear"))
        linear = vector3(twist->at("linear"), "state.twist.linear", bounds::linear_speed, "m/s");
      if (twist->contains("angular"))
        angular =
            vector3(twist->at("angular"), "state.twist.angular", bounds::angular_speed, "rad/s");
    }
    const bool moving = (linear && !linear->isZero()) || (angular && !angular->isZero());
    const bool mocap = sim_.m()->body_mocapid[body] >= 0;
    if (moving && mocap)
      refuse("state.twist",
             "state.twist: body '" + name +
                 "' is a mocap body: it has no velocity (expected none, or zeros)",
             "no twist, or zeros");
    if (moving && frozen_.count(sim_.model().body_name(body)))
      refuse("state.twist",
             "state.twist: body '" + name +
                 "' is frozen (simulation set_object_dynamics): it cannot move (expected none, or "
                 "zeros)",
             "no twist, or zeros");

    // what is not given keeps its current value, in the world frame
    const Eigen::Vector3d p = position.value_or(body_position(sim_, body));
    const Eigen::Quaterniond q = orientation.value_or(body_orientation(sim_, body));
    if (mocap) {
      place(body, name, "name", p, q);
      return get_entity_state(name);
    }
    const int joint = free_joint(body, name, "name", "be placed");
    mjtNum v[6];
    mj_objectVelocity(sim_.m(), sim_.d(), mjOBJ_BODY, body, v, 0);
    const Eigen::Vector3d w = angular.value_or(Eigen::Vector3d(v[0], v[1], v[2]));
    const Eigen::Vector3d l = linear.value_or(Eigen::Vector3d(v[3], v[4], v[5]));
    set_free_body_pose(sim_, joint, p, q);
    if (!l.isZero() || !w.isZero()) {
      // a free joint's velocity: linear in the world frame, angular in the body's
      mjtNum* qvel = sim_.d()->qvel + sim_.m()->jnt_dofadr[joint];
      const Eigen::Vector3d local = q.normalized().conjugate() * w;
      for (int i = 0; i < 3; ++i) {
        qvel[i] = l[i];
        qvel[3 + i] = local[i];
      }
      sim_.forward();
    }
    return get_entity_state(name);
  }

  std::vector<std::string> list_entities(const std::string& filter) const {
    const bool glob = filter.find_first_of("*?") != std::string::npos;
    std::vector<std::string> out;
    for (int b = 1; b < sim_.m()->nbody; ++b) {
      std::string name = sim_.model().body_name(b);
      if (glob ? glob_matches(filter, name) : name.find(filter) != std::string::npos)
        out.push_back(std::move(name));
    }
    return out;
  }

  // on_step: puts every frozen body back where it is held.
  void hold_frozen() {
    for (auto it = frozen_.begin(); it != frozen_.end();) {
      const int body = sim_.model().body_id(it->first);
      const int joint = body > 0 ? sim_.model().free_joint_of(body) : -1;
      if (joint < 0) {
        it = frozen_.erase(it);  // gone from a rebuilt model
        continue;
      }
      hold(body, joint, it->second);
      ++it;
    }
  }

 private:
  // A frozen body.
  struct Frozen {
    std::array<mjtNum, 7> pose;      // where it is held: x, y, z, then w, x, y, z (its qpos)
    std::array<mjtNum, 6> velocity;  // its free joint's qvel when it was frozen
  };

  // A body other than the world, by the name get_scene_objects and list_entities give it.
  int find_body(const std::string& name, const std::string& parameter) const {
    const int body = sim_.model().body_id(name);
    if (body > 0) return body;
    std::vector<std::string> names;
    for (int b = 1; b < sim_.m()->nbody; ++b) names.push_back(sim_.model().body_name(b));
    const auto close = closest_match(name, names);
    // MORSE's text, then ours
    refuse(parameter,
           "Object '" + name + "' does not appear in the scene." +
               (close ? " Did you mean '" + *close + "'?"
                      : std::string(" simulation list_entities lists them.")),
           "the name of a body (simulation list_entities)");
  }

  // The free joint of `body`, or FAILED saying why the body cannot `what`.
  int free_joint(int body, const std::string& name, const std::string& parameter,
                 const std::string& what) const {
    const int joint = sim_.model().free_joint_of(body);
    if (joint >= 0) return joint;
    const mjModel* m = sim_.m();
    std::string why;
    if (m->body_mocapid[body] >= 0)
      why =
          "it is a mocap body, moved only by its mocap pose (set_object_position places it; it has "
          "no dynamics)";
    else if (m->body_jntnum[body] > 0)
      why = "it hangs from '" + sim_.model().body_name(m->body_parentid[body]) + "' by joint '" +
            mj_id2name(m, mjOBJ_JOINT, m->body_jntadr[body]) +
            "' (its robot's components drive it; place the body with the free joint above it)";
    else if (m->body_parentid[body] == 0)
      why = "it is fixed to the world (no free joint)";
    else
      why = "it is welded to '" + sim_.model().body_name(m->body_parentid[body]) +
            "' (no joint of its own; place the body with the free joint above it)";
    refuse(parameter, "Object '" + name + "' cannot " + what + ": " + why,
           "a body with a free joint" + std::string(what == "be placed" ? " or a mocap body" : ""));
  }

  // Places `body` through its free joint (at rest) or its mocap pose.
  void place(int body, const std::string& name, const std::string& parameter,
             const Eigen::Vector3d& p, const Eigen::Quaterniond& q) {
    const mjModel* m = sim_.m();
    if (const int mocap = m->body_mocapid[body]; mocap >= 0) {
      mjData* d = sim_.d();
      const Eigen::Quaterniond n = q.normalized();
      for (int i = 0; i < 3; ++i) d->mocap_pos[3 * mocap + i] = p[i];
      d->mocap_quat[4 * mocap] = n.w();
      d->mocap_quat[4 * mocap + 1] = n.x();
      d->mocap_quat[4 * mocap + 2] = n.y();
      d->mocap_quat[4 * mocap + 3] = n.z();
      sim_.forward();
      return;
    }
    set_free_body_pose(sim_, free_joint(body, name, parameter, "be placed"), p, q);
  }

  // Holds a frozen body: adopts where it was placed since the last step, puts its free
  // joint there and stops it.
  void hold(int body, int joint, Frozen& f) {
    const mjModel* m = sim_.m();
    mjData* d = sim_.d();
    const mjtNum* xpos = d->xpos + 3 * body;
    const mjtNum* xquat = d->xquat + 4 * body;
    if (!std::equal(xpos, xpos + 3, f.pose.begin()) ||
        !std::equal(xquat, xquat + 4, f.pose.begin() + 3)) {
      std::copy(xpos, xpos + 3, f.pose.begin());
      std::copy(xquat, xquat + 4, f.pose.begin() + 3);
    }
    std::copy(f.pose.begin(), f.pose.end(), d->qpos + m->jnt_qposadr[joint]);
    std::fill(d->qvel + m->jnt_dofadr[joint], d->qvel + m->jnt_dofadr[joint] + 6, 0.0);
  }

  // [[min x, y, z], [max x, y, z]] of every geom of `body`'s subtree, in the frame at
  // `origin` with axes `axes` (columns, world coordinates).
  json bbox(int body, const std::string& name, const Eigen::Vector3d& origin,
            const Eigen::Matrix3d& axes) const {
    const mjModel* m = sim_.m();
    const mjData* d = sim_.d();
    Eigen::Vector3d low = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector3d high = -low;
    bool any = false;
    for (int g = 0; g < m->ngeom; ++g) {
      if (!in_subtree(m, m->geom_bodyid[g], body)) continue;
      const Eigen::Map<const Eigen::Matrix<mjtNum, 3, 3, Eigen::RowMajor>> world_rotation(
          d->geom_xmat + 9 * g);
      const Eigen::Map<const Eigen::Vector3d> world_centre(d->geom_xpos + 3 * g);
      const Eigen::Matrix3d rotation =
          axes.transpose() * world_rotation;  // geom frame -> box frame
      const Eigen::Vector3d centre = axes.transpose() * (world_centre - origin);
      std::array<double, 3> up, down;
      bool finite = true;
      for (int k = 0; k < 3 && finite; ++k) {
        // the box's axis k, in the geom's frame
        const Eigen::Vector3d u = rotation.row(k).transpose();
        const auto plus = geom_support(m, g, u), minus = geom_support(m, g, -u);
        finite = plus && minus;
        if (finite) up[k] = *plus, down[k] = *minus;
      }
      if (!finite) continue;  // an infinite plane bounds nothing
      for (int k = 0; k < 3; ++k) {
        high[k] = std::max(high[k], centre[k] + up[k]);
        low[k] = std::min(low[k], centre[k] - down[k]);
      }
      any = true;
    }
    if (!any)
      refuse("object_name",
             "Object '" + name +
                 "' has no geom (nor has any body attached to it): it has no bounding box",
             "a body with geoms");
    return {to_json(low), to_json(high)};
  }

  Simulation& sim_;                       // whose bodies
  std::map<std::string, Frozen> frozen_;  // bodies held by set_object_dynamics false, by name
};

void add_entity_services(SupervisionServices& simulation, Simulation& sim) {
  auto e = std::make_shared<EntityServices>(sim);
  simulation
      .offer_service("set_object_position",
                     [e](const std::string& object_name, const std::array<double, 3>& position,
                         const json& orientation) {
                       e->set_object_position(object_name, position, orientation);
                     },
                     {"object_name", "position", {"orientation", json()}})
      .doc(
          "Place a body (free joint or mocap) at [x, y, z], optionally [roll, pitch, yaw]; it "
          "starts at rest");
  simulation
      .offer_service(
          "get_object_pose",
          [e](const std::string& object_name) { return e->get_object_pose(object_name); },
          {"object_name"})
      .doc("[[x, y, z], [qx, qy, qz, qw]] of a body in the world frame");
  simulation
      .offer_service(
          "get_object_bbox",
          [e](const std::string& object_name) { return e->get_object_bbox(object_name); },
          {"object_name"})
      .doc(
          "[[min x, y, z], [max x, y, z]] of a body and the bodies attached to it, in its own "
          "frame");
  simulation
      .offer_service(
          "get_object_global_bbox",
          [e](const std::string& object_name) { return e->get_object_global_bbox(object_name); },
          {"object_name"})
      .doc(
          "[[min x, y, z], [max x, y, z]] of a body and the bodies attached to it, in the world "
          "frame");
  simulation
      .offer_service("set_object_dynamics",
                     [e](const std::string& object_name, bool state) {
                       return e->set_object_dynamics(object_name, state);
                     },
                     {"object_name", "state"})
      .doc(
          "false: hold a free body where it is (physics no longer moves it); true: release it with "
          "its velocity");
  simulation
      .offer_service("get_entity_state",
                     [e](const std::string& name) { return e->get_entity_state(name); }, {"name"})
      .doc(
          "{pose: {position, orientation [qx, qy, qz, qw]}, twist: {linear, angular}} of a body, "
          "world frame");
  simulation
      .offer_service("set_entity_state",
                     [e](const std::string& name, const json& state) {
                       return e->set_entity_state(name, state);
                     },
                     {"name", "state"})
      .doc(
          "Set any of a body's pose and twist (world frame; what is left out is kept); returns the "
          "new state");
  simulation
      .offer_service("list_entities",
                     [e](const std::string& filter) { return e->list_entities(filter); },
                     {{"filter", ""}})
      .doc("Names of the bodies containing `filter`, or matching it as a glob when it has * or ?");
  simulation.on_step([e] { e->hold_frozen(); });
}

}  // namespace simgate::sim
