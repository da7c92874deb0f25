#include "simgate/sim/model_remap.h"

#include <string>

#include "simgate/sim/model.h"

namespace simgate::sim {

namespace {

// What a removal takes from the old model, per kind (true: removed).
struct Removed {
  std::vector<bool> body, joint, geom, site, camera, light, tendon, actuator, sensor, equality;

  bool of(int type, int id) const {
    if (id < 0) return false;
    switch (type) {
      case mjOBJ_BODY:
      case mjOBJ_XBODY: return body[id];
      case mjOBJ_JOINT: return joint[id];
      case mjOBJ_GEOM: return geom[id];
      case mjOBJ_SITE: return site[id];
      case mjOBJ_CAMERA: return camera[id];
      case mjOBJ_LIGHT: return light[id];
      case mjOBJ_TENDON: return tendon[id];
      case mjOBJ_ACTUATOR: return actuator[id];
      default: return false;
    }
  }
};

// Marks the subtree of `root`, its objects, then what refers to them until nothing more goes.
Removed removal(const mjModel* m, int root) {
  Removed r;
  r.body.assign(m->nbody, false), r.joint.assign(m->njnt, false), r.geom.assign(m->ngeom, false);
  r.site.assign(m->nsite, false), r.camera.assign(m->ncam, false), r.light.assign(m->nlight, false);
  r.tendon.assign(m->ntendon, false), r.actuator.assign(m->nu, false),
      r.sensor.assign(m->nsensor, false);
  r.equality.assign(m->neq, false);
  if (root <= 0) return r;  // nothing, and never the world
  for (int b = 1; b < m->nbody; ++b) {
    int up = b;
    while (up > 0 && up != root) up = m->body_parentid[up];
    r.body[b] = up == root;
  }
  for (int i = 0; i < m->njnt; ++i) r.joint[i] = r.body[m->jnt_bodyid[i]];
  for (int i = 0; i < m->ngeom; ++i) r.geom[i] = r.body[m->geom_bodyid[i]];
  for (int i = 0; i < m->nsite; ++i) r.site[i] = r.body[m->site_bodyid[i]];
  for (int i = 0; i < m->ncam; ++i) r.camera[i] = r.body[m->cam_bodyid[i]];
  for (int i = 0; i < m->nlight; ++i) r.light[i] = r.body[m->light_bodyid[i]];
  for (bool changed = true; changed;) {
    changed = false;
    auto mark = [&](std::vector<bool>& set, int i, bool gone) {
      if (gone && !set[i]) set[i] = changed = true;
    };
    for (int t = 0; t < m->ntendon; ++t) {
      bool gone = false;
      for (int w = m->tendon_adr[t]; w < m->tendon_adr[t] + m->tendon_num[t]; ++w) {
        const int id = m->wrap_objid[w];
        switch (m->wrap_type[w]) {
          case mjWRAP_JOINT: gone |= r.of(mjOBJ_JOINT, id); break;
          case mjWRAP_SITE: gone |= r.of(mjOBJ_SITE, id); break;
          case mjWRAP_SPHERE:
          case mjWRAP_CYLINDER: gone |= r.of(mjOBJ_GEOM, id); break;
          default: break;
        }
      }
      mark(r.tendon, t, gone);
    }
    for (int a = 0; a < m->nu; ++a) {
      const int id = m->actuator_trnid[2 * a], second = m->actuator_trnid[2 * a + 1];
      bool gone = false;
      switch (m->actuator_trntype[a]) {
        case mjTRN_JOINT:
        case mjTRN_JOINTINPARENT: gone = r.of(mjOBJ_JOINT, id); break;
        case mjTRN_SLIDERCRANK: gone = r.of(mjOBJ_SITE, id) || r.of(mjOBJ_SITE, second); break;
        case mjTRN_TENDON: gone = r.of(mjOBJ_TENDON, id); break;
        case mjTRN_SITE: gone = r.of(mjOBJ_SITE, id); break;
        case mjTRN_BODY: gone = r.of(mjOBJ_BODY, id); break;
        default: break;
      }
      mark(r.actuator, a, gone);
    }
    for (int s = 0; s < m->nsensor; ++s)
      mark(r.sensor, s,
           r.of(m->sensor_objtype[s], m->sensor_objid[s]) ||
               r.of(m->sensor_reftype[s], m->sensor_refid[s]));
    for (int e = 0; e < m->neq; ++e) {
      int type = mjOBJ_UNKNOWN;
      switch (m->eq_type[e]) {
        case mjEQ_CONNECT:
        case mjEQ_WELD: type = mjOBJ_BODY; break;
        case mjEQ_JOINT: type = mjOBJ_JOINT; break;
        case mjEQ_TENDON: type = mjOBJ_TENDON; break;
        default: break;
      }
      mark(r.equality, e, r.of(type, m->eq_obj1id[e]) || r.of(type, m->eq_obj2id[e]));
    }
  }
  return r;
}

// Maps the survivors of one kind in order and checks names and counts.
std::vector<int> walk(const mjModel* from, const mjModel* to, int type, const char* kind,
                      int n_from, int n_to, const std::vector<bool>& removed, bool appended) {
  std::vector<int> ids(n_from, -1);
  int next = 0;
  for (int i = 0; i < n_from; ++i) {
    if (removed[i]) continue;
    if (next >= n_to)
      throw MujocoError(std::string("the recompiled model has fewer ") + kind +
                        "s than expected (" + std::to_string(n_to) + ")");
    const char* was = mj_id2name(from, type, i);
    const char* is = mj_id2name(to, type, next);
    if (was && *was && (!is || std::string(was) != is))
      throw MujocoError(std::string(kind) + " " + std::to_string(i) + " '" + was +
                        "' is not where expected in the "
                        "recompiled model (found " +
                        (is && *is ? "'" + std::string(is) + "'" : "an unnamed one") + ")");
    ids[i] = next++;
  }
  if (appended ? next > n_to : next != n_to)
    throw MujocoError(std::string("the recompiled model has ") + std::to_string(n_to) + " " + kind +
                      "s, expected " + std::to_string(next) + (appended ? " or more" : ""));
  return ids;
}

}  // namespace

ModelRemap ModelRemap::between(const mjModel* from, const mjModel* to, int removed_body,
                               bool appended) {
  const Removed r = removal(from, removed_body);
  ModelRemap map;
  map.body = walk(from, to, mjOBJ_BODY, "body", from->nbody, to->nbody, r.body, appended);
  map.joint = walk(from, to, mjOBJ_JOINT, "joint", from->njnt, to->njnt, r.joint, appended);
  map.geom = walk(from, to, mjOBJ_GEOM, "geom", from->ngeom, to->ngeom, r.geom, appended);
  map.site = walk(from, to, mjOBJ_SITE, "site", from->nsite, to->nsite, r.site, appended);
  map.camera = walk(from, to, mjOBJ_CAMERA, "camera", from->ncam, to->ncam, r.camera, appended);
  map.light = walk(from, to, mjOBJ_LIGHT, "light", from->nlight, to->nlight, r.light, appended);
  map.tendon =
      walk(from, to, mjOBJ_TENDON, "tendon", from->ntendon, to->ntendon, r.tendon, appended);
  map.actuator = walk(from, to, mjOBJ_ACTUATOR, "actuator", from->nu, to->nu, r.actuator, appended);
  map.sensor =
      walk(from, to, mjOBJ_SENSOR, "sensor", from->nsensor, to->nsensor, r.sensor, appended);
  map.equality =
      walk(from, to, mjOBJ_EQUALITY, "equality", from->neq, to->neq, r.equality, appended);
  // a joint keeps its type (so its qpos and dof widths)
  for (int j = 0; j < from->njnt; ++j)
    if (map.joint[j] >= 0 && from->jnt_type[j] != to->jnt_type[map.joint[j]])
      throw MujocoError("joint " + std::to_string(j) + " changed type in the recompiled model");
  return map;
}

ModelRemap ModelRemap::identity(const mjModel* m) {
  auto same = [](int n) {
    std::vector<int> ids(n);
    for (int i = 0; i < n; ++i) ids[i] = i;
    return ids;
  };
  ModelRemap map;
  map.body = same(m->nbody), map.joint = same(m->njnt), map.geom = same(m->ngeom),
  map.site = same(m->nsite);
  map.camera = same(m->ncam), map.light = same(m->nlight), map.tendon = same(m->ntendon);
  map.actuator = same(m->nu), map.sensor = same(m->nsensor), map.equality = same(m->neq);
  return map;
}

bool ModelRemap::moves_ids() const {
  for (const auto* ids :
       {&body, &joint, &geom, &site, &camera, &light, &tendon, &actuator, &sensor, &equality})
    for (int i = 0; i < static_cast<int>(ids->size()); ++i)
      if ((*ids)[i] != i) return true;
  return false;
}

}  // namespace simgate::sim
