#include "simgate/sim/actuator_kind.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "simgate/sim/sim_component.h"
#include "helpers.h"

namespace simgate::sim {

namespace {
const mjtNum* gain_of(const mjModel* m, int a) { return m->actuator_gainprm + a * mjNGAIN; }
const mjtNum* bias_of(const mjModel* m, int a) { return m->actuator_biasprm + a * mjNBIAS; }

// fixed gain k, affine bias -k times the length (position), and -kv times its velocity
// (kv >= 0: MuJoCo 3.x's <position kv=".."> or dampratio, compiled to kv): what <position>
// and <intvelocity> compile to
bool has_position_servo_shape(const mjModel* m, int a) {
  const mjtNum* gain = gain_of(m, a);
  const mjtNum* bias = bias_of(m, a);
  return m->actuator_gaintype[a] == mjGAIN_FIXED && m->actuator_biastype[a] == mjBIAS_AFFINE &&
         gain[0] > 0 && bias[0] == 0 && same(bias[1], -gain[0]) && bias[2] <= 0;
}

}  // namespace

int object_body(const mjModel* m, int type, int id) {
  if (id < 0) return -1;
  switch (type) {
    case mjOBJ_BODY:
    case mjOBJ_XBODY: return id;
    case mjOBJ_JOINT: return m->jnt_bodyid[id];
    case mjOBJ_GEOM: return m->geom_bodyid[id];
    case mjOBJ_SITE: return m->site_bodyid[id];
    case mjOBJ_CAMERA: return m->cam_bodyid[id];
    default: return -1;
  }
}

const char* actuator_type(const mjModel* m, int a) {
  const int dyn = m->actuator_dyntype[a], gain = m->actuator_gaintype[a],
            bias = m->actuator_biastype[a];
  const mjtNum* g = gain_of(m, a);
  const mjtNum* b = bias_of(m, a);
  if (dyn == mjDYN_MUSCLE || gain == mjGAIN_MUSCLE || bias == mjBIAS_MUSCLE) return "muscle";
  if (m->actuator_trntype[a] == mjTRN_BODY) return "adhesion";
  if (dyn == mjDYN_NONE) {
    if (gain == mjGAIN_FIXED && bias == mjBIAS_NONE) return "motor";
    if (has_position_servo_shape(m, a)) return "position";
    if (is_velocity_actuator(m, a)) return "velocity";
    // <damper kv>: force = -kv * velocity * ctrl
    if (gain == mjGAIN_AFFINE && bias == mjBIAS_NONE && g[0] == 0 && g[1] == 0 && g[2] < 0)
      return "damper";
  }
  if (dyn == mjDYN_INTEGRATOR && has_position_servo_shape(m, a)) return "intvelocity";
  // <cylinder area bias>: a first-order filter of the pressure, times the area
  if (dyn == mjDYN_FILTER && gain == mjGAIN_FIXED && bias == mjBIAS_AFFINE && b[1] == 0 &&
      b[2] == 0)
    return "cylinder";
  return "general";
}

bool is_velocity_actuator(const mjModel* m, int a) {
  const mjtNum* gain = gain_of(m, a);
  const mjtNum* bias = bias_of(m, a);
  return m->actuator_gaintype[a] == mjGAIN_FIXED && m->actuator_biastype[a] == mjBIAS_AFFINE &&
         gain[0] > 0 && bias[1] == 0 && same(bias[2], -gain[0]);
}

bool is_position_actuator(const mjModel* m, int a) {
  return m->actuator_dyntype[a] == mjDYN_NONE && has_position_servo_shape(m, a);
}

std::string describe_actuator(const mjModel* m, int a) {
  const mjtNum* gain = gain_of(m, a);
  const mjtNum* bias = bias_of(m, a);
  const int gain_type = m->actuator_gaintype[a], bias_type = m->actuator_biastype[a];
  if (gain_type == mjGAIN_MUSCLE || bias_type == mjBIAS_MUSCLE) return "a muscle";
  if (gain_type == mjGAIN_FIXED && bias_type == mjBIAS_NONE)
    return "a motor (torque: fixed gain, no bias)";
  if (has_position_servo_shape(m, a))
    return "a position servo (kp=" + number(gain[0]) +
           (bias[2] < 0 ? ", kv=" + number(-bias[2]) : std::string()) +
           ": fixed gain, bias -kp times the position" +
           (bias[2] < 0 ? " and -kv times its velocity)" : ")");
  auto type_name = [](int t, bool is_gain) -> std::string {
    if (t == (is_gain ? int(mjGAIN_FIXED) : int(mjBIAS_NONE))) return is_gain ? "fixed" : "none";
    if (t == (is_gain ? int(mjGAIN_AFFINE) : int(mjBIAS_AFFINE))) return "affine";
    if (t == (is_gain ? int(mjGAIN_MUSCLE) : int(mjBIAS_MUSCLE))) return "muscle";
    return "user";
  };
  return "a general actuator (gaintype " + type_name(gain_type, true) + ", gainprm " +
         number(gain[0]) + " " + number(gain[1]) + " " + number(gain[2]) + "; biastype " +
         type_name(bias_type, false) + ", biasprm " + number(bias[0]) + " " + number(bias[1]) +
         " " + number(bias[2]) + ")";
}

bool tendon_in_subtree(const mjModel* m, int tendon, int root) {
  if (tendon < 0 || tendon >= m->ntendon) return false;
  const int first = m->tendon_adr[tendon], end = first + m->tendon_num[tendon];
  for (int w = first; w < end; ++w) {
    int body = -1;
    switch (m->wrap_type[w]) {
      case mjWRAP_JOINT: body = object_body(m, mjOBJ_JOINT, m->wrap_objid[w]); break;
      case mjWRAP_SITE: body = object_body(m, mjOBJ_SITE, m->wrap_objid[w]); break;
      case mjWRAP_SPHERE:
      case mjWRAP_CYLINDER: body = object_body(m, mjOBJ_GEOM, m->wrap_objid[w]); break;
      default: break;  // a pulley divides the path, it is attached to nothing
    }
    if (body > 0 && in_subtree(m, body, root)) return true;
  }
  return false;
}

bool actuator_in_subtree(const mjModel* m, int a, int root) {
  if (a < 0 || a >= m->nu) return false;
  const int target = m->actuator_trnid[2 * a];
  switch (m->actuator_trntype[a]) {
    case mjTRN_JOINT:
    case mjTRN_JOINTINPARENT: return in_subtree(m, object_body(m, mjOBJ_JOINT, target), root);
    // the crank site is on the moving part; the slider site is often on the world
    case mjTRN_SLIDERCRANK:
    case mjTRN_SITE: return in_subtree(m, object_body(m, mjOBJ_SITE, target), root);
    case mjTRN_TENDON: return tendon_in_subtree(m, target, root);
    case mjTRN_BODY: return in_subtree(m, target, root);
    default: return false;
  }
}

std::string mujoco_name(const mjModel* m, int type, int id) {
  // a body's regular frame (xbody) has the body's name
  if (type == mjOBJ_XBODY) type = mjOBJ_BODY;
  const char* name = mj_id2name(m, type, id);
  if (name && *name) return name;
  return mju_type2Str(type) + std::to_string(id);
}

bool sensor_in_subtree(const mjModel* m, int s, int root) {
  const int type = m->sensor_objtype[s], id = m->sensor_objid[s];
  if (type == mjOBJ_TENDON) return tendon_in_subtree(m, id, root);
  if (type == mjOBJ_ACTUATOR) return actuator_in_subtree(m, id, root);
  return in_subtree(m, object_body(m, type, id), root);
}

}  // namespace simgate::sim
