#include "simgate/sim/joints.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "simgate/core/errors.h"
#include "simgate/core/suggest.h"
#include "helpers.h"

namespace simgate::sim {

namespace {

bool is_armature_joint_type(int type) { return type == mjJNT_HINGE || type == mjJNT_SLIDE; }

std::string_view type_name(int type) {
  switch (type) {
    case mjJNT_FREE: return "a free joint";
    case mjJNT_BALL: return "a ball joint";
    case mjJNT_SLIDE: return "a slide joint";
    default: return "a hinge joint";
  }
}

// numbers per actuator in mjModel::actuator_gear (MuJoCo 2.2.2 names no constant for it)
constexpr int k_gear_size = 6;

ArmatureJoint describe(const mjModel* m, int j) {
  ArmatureJoint out;
  out.name = joint_name(m, j);
  out.id = j;
  out.kind = m->jnt_type[j] == mjJNT_SLIDE ? JointKind::prismatic : JointKind::revolute;
  out.qpos = m->jnt_qposadr[j];
  out.dof = m->jnt_dofadr[j];
  out.limited = m->jnt_limited[j] != 0;
  out.low = m->jnt_range[2 * j];
  out.high = m->jnt_range[2 * j + 1];
  // the first position servo on the joint drives it (several would fight each other)
  for (int a = 0; a < m->nu; ++a) {
    if (m->actuator_trntype[a] != mjTRN_JOINT || m->actuator_trnid[2 * a] != j ||
        !is_position_servo(m, a))
      continue;
    out.servo = a;
    out.gear = m->actuator_gear[k_gear_size * a];
    out.ctrl_limited = m->actuator_ctrllimited[a] != 0;
    out.ctrl_low = m->actuator_ctrlrange[2 * a];
    out.ctrl_high = m->actuator_ctrlrange[2 * a + 1];
    break;
  }
  return out;
}
}  // namespace

std::string_view to_string(JointKind kind) {
  return kind == JointKind::prismatic ? "prismatic" : "revolute";
}

std::string_view unit_of(JointKind kind) { return kind == JointKind::prismatic ? "m" : "rad"; }

std::string joint_name(const mjModel* m, int joint) {
  const char* name = mj_id2name(m, mjOBJ_JOINT, joint);
  return name && *name ? std::string(name) : "joint" + std::to_string(joint);
}

bool is_position_servo(const mjModel* m, int a) {
  const mjtNum* gain = m->actuator_gainprm + a * mjNGAIN;
  const mjtNum* bias = m->actuator_biasprm + a * mjNBIAS;
  // a zero gear would make every target the same ctrl: not a servo of the joint. An
  // integrator (<intvelocity>) has the same gain and bias, but its ctrl is a velocity.
  return m->actuator_trntype[a] == mjTRN_JOINT && m->actuator_dyntype[a] != mjDYN_INTEGRATOR &&
         m->actuator_gaintype[a] == mjGAIN_FIXED && m->actuator_biastype[a] == mjBIAS_AFFINE &&
         gain[0] > 0 && bias[0] == 0 && same(bias[1], -gain[0]) && bias[2] <= 0 &&
         m->actuator_gear[k_gear_size * a] != 0;
}

void JointSet::remap(const mjModel* m, const ModelRemap& remap) {
  for (ArmatureJoint& j : joints_) {
    j.id = remap.joint_of(j.id);
    j.qpos = m->jnt_qposadr[j.id];
    j.dof = m->jnt_dofadr[j.id];
    j.servo = remap.actuator_of(j.servo);
  }
}

JointSet JointSet::of_subtree(const mjModel* m, int root) {
  JointSet set;
  for (int j = 0; j < m->njnt; ++j)
    if (is_armature_joint_type(m->jnt_type[j]) && in_subtree(m, m->jnt_bodyid[j], root))
      set.joints_.push_back(describe(m, j));
  return set;
}

JointSet JointSet::from_config(ComponentContext& c) {
  const mjModel* m = c.sim().m();
  const int root = c.body();
  const std::string body_name = c.sim().model().body_name(root);
  std::optional<json> listed = c.options().get_json("joints");
  if (!listed) {
    JointSet set = of_subtree(m, root);
    if (set.joints_.empty())
      c.fail("body", "body '" + body_name +
                         "' has no hinge or slide joint in its subtree: an armature moves hinge "
                         "(revolute) and slide "
                         "(prismatic) joints; free and ball joints are not armature joints");
    return set;
  }

  const std::string path = c.options().path_of("joints");
  if (!listed->is_array() || listed->empty())
    throw ConfigError(path + ": expected a non-empty list of joint names, found " +
                      describe_json(*listed));
  const JointSet all = of_subtree(m, root);
  const std::vector<std::string> valid = all.names();
  JointSet set;
  for (std::size_t i = 0; i < listed->size(); ++i) {
    const json& item = (*listed)[i];
    const std::string where = path + "[" + std::to_string(i) + "]";
    if (!item.is_string())
      throw ConfigError(where + ": expected a joint name, found " + describe_json(item));
    const std::string name = item.get<std::string>();
    // unnamed joints are listed as "joint<id>", as get_joints shows them
    auto known = std::find(valid.begin(), valid.end(), name);
    int j = mj_name2id(m, mjOBJ_JOINT, name.c_str());
    if (known == valid.end() && j >= 0 && !is_armature_joint_type(m->jnt_type[j]))
      throw ConfigError(where + ": joint '" + name + "' is " +
                        std::string(type_name(m->jnt_type[j])) +
                        ", not an armature joint (armatures move hinge and slide joints)");
    if (known == valid.end() && j >= 0)
      throw ConfigError(where + ": joint '" + name + "' is not in the subtree of body '" +
                        body_name + "' (its joints: " + join(valid) + ")");
    if (known == valid.end())
      throw ConfigError(where + ": no joint '" + name + "' in the subtree of body '" + body_name +
                        "'" + suggestion(name, valid) + " (its joints: " + join(valid) + ")");
    for (const auto& earlier : set.joints_)
      if (earlier.name == name) throw ConfigError(where + ": joint '" + name + "' is listed twice");
    set.joints_.push_back(all.joints_[static_cast<std::size_t>(known - valid.begin())]);
  }
  return set;
}

std::vector<std::string> JointSet::names() const {
  std::vector<std::string> out;
  out.reserve(joints_.size());
  for (const auto& j : joints_) out.push_back(j.name);
  return out;
}

std::size_t JointSet::index_of(const std::string& name, std::string_view parameter) const {
  for (std::size_t i = 0; i < joints_.size(); ++i)
    if (joints_[i].name == name) return i;
  const std::vector<std::string> valid = names();
  throw ServiceError("no joint '" + name + "' in this armature" + suggestion(name, valid) +
                         " (its joints: " + join(valid) + ")",
                     Failure::bad_arguments, {{"parameter", std::string(parameter)}});
}
void KinematicDrive::add(int qpos, int dof, double position, double velocity) {
  wanted_.push_back({qpos, dof, position, velocity});
}

void KinematicDrive::apply(const mjModel* m, mjData* d) {
  const int n = static_cast<int>(wanted_.size());
  if (n == 0) return;
  const int nv = m->nv;
  const auto nn = static_cast<std::size_t>(n);
  const auto size = nn * static_cast<std::size_t>(nv);
  units_.assign(size, 0);
  columns_.resize(size);
  gram_.resize(nn * nn);
  missing_.resize(nn);
  impulse_.resize(nn);
  // the columns of M^-1 of the joints' dofs, and how much velocity each joint misses
  for (int k = 0; k < n; ++k) {
    units_[static_cast<std::size_t>(k * nv + wanted_[k].dof)] = 1;
    missing_[k] = wanted_[k].velocity - d->qvel[wanted_[k].dof];
  }
  mj_solveM(m, d, columns_.data(), units_.data(), n);
  // the impulses that give each joint its velocity: (M^-1)_SS lambda = missing
  for (int k = 0; k < n; ++k)
    for (int l = 0; l < n; ++l)
      gram_[static_cast<std::size_t>(k * n + l)] =
          columns_[static_cast<std::size_t>(l * nv + wanted_[k].dof)];
  if (mju_cholFactor(gram_.data(), n, mjMINVAL) == n) {
    mju_cholSolve(impulse_.data(), gram_.data(), missing_.data(), n);
    for (int l = 0; l < n; ++l)
      mju_addToScl(d->qvel, &columns_[static_cast<std::size_t>(l * nv)], impulse_[l], nv);
  }
  // exactly where and how fast they were asked to be (the impulse gets there up to rounding;
  // a joint listed twice or a singular inertia falls back to the plain write)
  for (const Wanted& w : wanted_) {
    d->qpos[w.qpos] = w.position;
    d->qvel[w.dof] = w.velocity;
  }
  wanted_.clear();
}

}  // namespace simgate::sim
