#include "simgate/sim/object_state.h"

#include <algorithm>
#include <map>
#include <memory>

namespace simgate::sim {

namespace {

int qpos_size(int type) { return type == mjJNT_FREE ? 7 : type == mjJNT_BALL ? 4 : 1; }
int dof_size(int type) { return type == mjJNT_FREE ? 6 : type == mjJNT_BALL ? 3 : 1; }

std::string name_of(const mjModel* m, mjtObj type, int id) {
  const char* name = mj_id2name(m, type, id);
  return name ? name : "";
}

// How a report names an object: its name, else MuJoCo's kind and id ("joint 3").
std::string printed(const std::string& name, const char* kind, int id) {
  return name.empty() ? std::string(kind) + " " + std::to_string(id) : name;
}

}  // namespace

std::string joint_key(const mjModel* m, int joint) {
  if (std::string name = name_of(m, mjOBJ_JOINT, joint); !name.empty()) return name;
  const int body = m->jnt_bodyid[joint];
  const std::string body_name = name_of(m, mjOBJ_BODY, body);
  if (body_name.empty()) return "";
  return body_name + "/" + std::to_string(joint - m->body_jntadr[body]);
}

bool ObjectState::Unmatched::empty() const {
  return missing_bodies.empty() && missing_joints.empty() && missing_actuators.empty() &&
         kept_bodies.empty() && kept_joints.empty() && kept_actuators.empty();
}

void ObjectState::capture(const mjModel* m, const mjData* d) {
  joints_.assign(m->njnt, {});
  for (int j = 0; j < m->njnt; ++j) {
    Joint& s = joints_[j];
    s.name = joint_key(m, j);
    s.type = m->jnt_type[j];
    const mjtNum* qpos = d->qpos + m->jnt_qposadr[j];
    const int dof = m->jnt_dofadr[j], nv = dof_size(s.type);
    s.qpos.assign(qpos, qpos + qpos_size(s.type));
    s.qvel.assign(d->qvel + dof, d->qvel + dof + nv);
    s.warmstart.assign(d->qacc_warmstart + dof, d->qacc_warmstart + dof + nv);
    s.qfrc_applied.assign(d->qfrc_applied + dof, d->qfrc_applied + dof + nv);
  }
  actuators_.assign(m->nu, {});
  for (int a = 0; a < m->nu; ++a) {
    Actuator& s = actuators_[a];
    s.name = name_of(m, mjOBJ_ACTUATOR, a);
    s.ctrl = d->ctrl[a];
    if (const int n = m->actuator_actnum[a]; n > 0)
      s.act.assign(d->act + m->actuator_actadr[a], d->act + m->actuator_actadr[a] + n);
  }
  bodies_.assign(m->nbody, {});
  for (int b = 0; b < m->nbody; ++b) {
    Body& s = bodies_[b];
    s.name = name_of(m, mjOBJ_BODY, b);
    std::copy_n(d->xfrc_applied + 6 * b, 6, s.xfrc_applied);
    if (const int mocap = m->body_mocapid[b]; mocap >= 0) {
      s.mocap = true;
      std::copy_n(d->mocap_pos + 3 * mocap, 3, s.mocap_pos);
      std::copy_n(d->mocap_quat + 4 * mocap, 4, s.mocap_quat);
    }
  }
  equalities_.assign(m->neq, {});
  for (int e = 0; e < m->neq; ++e) {
    equalities_[e].name = name_of(m, mjOBJ_EQUALITY, e);
    equalities_[e].active = d->eq_active[e];
  }
}

ObjectState::Unmatched ObjectState::put(const mjModel* m, mjData* d, const Mapping& to) const {
  Unmatched out;
  std::vector<bool> joint_written(m->njnt), actuator_written(m->nu), body_written(m->nbody);
  for (std::size_t i = 0; i < joints_.size(); ++i) {
    const Joint& s = joints_[i];
    const int k = to(mjOBJ_JOINT, static_cast<int>(i), s.name);
    if (k < 0 || k >= m->njnt || m->jnt_type[k] != s.type) {
      out.missing_joints.push_back(printed(s.name, "joint", static_cast<int>(i)));
      continue;
    }
    joint_written[k] = true;
    std::copy(s.qpos.begin(), s.qpos.end(), d->qpos + m->jnt_qposadr[k]);
    const int dof = m->jnt_dofadr[k];
    std::copy(s.qvel.begin(), s.qvel.end(), d->qvel + dof);
    std::copy(s.warmstart.begin(), s.warmstart.end(), d->qacc_warmstart + dof);
    std::copy(s.qfrc_applied.begin(), s.qfrc_applied.end(), d->qfrc_applied + dof);
  }
  for (std::size_t i = 0; i < actuators_.size(); ++i) {
    const Actuator& s = actuators_[i];
    const int k = to(mjOBJ_ACTUATOR, static_cast<int>(i), s.name);
    if (k < 0 || k >= m->nu || m->actuator_actnum[k] != static_cast<int>(s.act.size())) {
      out.missing_actuators.push_back(printed(s.name, "actuator", static_cast<int>(i)));
      continue;
    }
    actuator_written[k] = true;
    d->ctrl[k] = s.ctrl;
    std::copy(s.act.begin(), s.act.end(), d->act + std::max(0, m->actuator_actadr[k]));
  }
  for (std::size_t i = 1; i < bodies_.size(); ++i) {  // the world body has no state
    const Body& s = bodies_[i];
    const int k = to(mjOBJ_BODY, static_cast<int>(i), s.name);
    if (k <= 0 || k >= m->nbody) {
      out.missing_bodies.push_back(printed(s.name, "body", static_cast<int>(i)));
      continue;
    }
    body_written[k] = true;
    std::copy_n(s.xfrc_applied, 6, d->xfrc_applied + 6 * k);
    if (const int mocap = m->body_mocapid[k]; s.mocap && mocap >= 0) {
      std::copy_n(s.mocap_pos, 3, d->mocap_pos + 3 * mocap);
      std::copy_n(s.mocap_quat, 4, d->mocap_quat + 4 * mocap);
    }
  }
  for (std::size_t i = 0; i < equalities_.size(); ++i) {
    const int k = to(mjOBJ_EQUALITY, static_cast<int>(i), equalities_[i].name);
    if (k >= 0 && k < m->neq) d->eq_active[k] = equalities_[i].active;
  }
  for (int j = 0; j < m->njnt; ++j)
    if (!joint_written[j]) out.kept_joints.push_back(printed(joint_key(m, j), "joint", j));
  for (int a = 0; a < m->nu; ++a)
    if (!actuator_written[a])
      out.kept_actuators.push_back(printed(name_of(m, mjOBJ_ACTUATOR, a), "actuator", a));
  for (int b = 1; b < m->nbody; ++b)
    if (!body_written[b]) out.kept_bodies.push_back(printed(name_of(m, mjOBJ_BODY, b), "body", b));
  return out;
}

void ObjectState::put_warmstart(const mjModel* m, mjData* d, const Mapping& to) const {
  for (std::size_t i = 0; i < joints_.size(); ++i) {
    const Joint& s = joints_[i];
    const int k = to(mjOBJ_JOINT, static_cast<int>(i), s.name);
    if (k >= 0 && k < m->njnt && m->jnt_type[k] == s.type)
      std::copy(s.warmstart.begin(), s.warmstart.end(), d->qacc_warmstart + m->jnt_dofadr[k]);
  }
}

ObjectState::Mapping ObjectState::through(const ModelRemap& remap) {
  return [&remap](mjtObj type, int id, const std::string&) {
    switch (type) {
      case mjOBJ_JOINT: return remap.joint_of(id);
      case mjOBJ_ACTUATOR: return remap.actuator_of(id);
      case mjOBJ_BODY: return remap.body_of(id);
      case mjOBJ_EQUALITY: return ModelRemap::of(remap.equality, id);
      default: return -1;
    }
  };
}

ObjectState::Mapping ObjectState::by_name(const mjModel* m) {
  // the joints by key, once (mj_name2id finds the rest)
  auto joints = std::make_shared<std::map<std::string, int>>();
  for (int j = 0; j < m->njnt; ++j)
    if (std::string key = joint_key(m, j); !key.empty()) joints->emplace(std::move(key), j);
  return [m, joints](mjtObj type, int, const std::string& name) {
    if (name.empty()) return -1;
    if (type != mjOBJ_JOINT) return mj_name2id(m, type, name.c_str());
    auto it = joints->find(name);
    return it == joints->end() ? -1 : it->second;
  };
}

}  // namespace simgate::sim
