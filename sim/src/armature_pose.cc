// The armature pose sensor: MORSE's armature_pose services on the joints an armature moves.
#include <algorithm>
#include <cmath>

#include "simgate/sim/armature.h"

namespace simgate::sim {

namespace {

// The length of the segment a joint moves (MORSE: its bone's length, head to tail): from
// the joint's anchor to the anchor of the next joint down the chain (the first joint of a
// body below its own: where that joint is attached), or, at a tip, to the far side of the
// farthest geom of its body. From the current poses (world frame), metres; a rigid segment
// has the same length in every pose.
double segment_length(const mjModel* m, const mjData* d, int joint) {
  const int body = m->jnt_bodyid[joint];
  // MuJoCo places a slide joint's anchor before its own displacement: the segment starts
  // where the displacement takes it
  mjtNum anchor[3];
  const int q = m->jnt_qposadr[joint];
  const mjtNum shift = m->jnt_type[joint] == mjJNT_SLIDE ? d->qpos[q] - m->qpos0[q] : 0;
  for (int k = 0; k < 3; ++k)
    anchor[k] = d->xanchor[3 * joint + k] + shift * d->xaxis[3 * joint + k];
  auto distance = [&anchor](const mjtNum* p) {
    return std::sqrt((p[0] - anchor[0]) * (p[0] - anchor[0]) +
                     (p[1] - anchor[1]) * (p[1] - anchor[1]) +
                     (p[2] - anchor[2]) * (p[2] - anchor[2]));
  };
  for (int j = 0; j < m->njnt; ++j) {
    const int b = m->jnt_bodyid[j];
    if (b != body && in_subtree(m, b, body)) return distance(d->xanchor + 3 * j);
  }
  double reach = 0;
  for (int g = 0; g < m->ngeom; ++g)
    if (m->geom_bodyid[g] == body)
      reach = std::max(reach, distance(d->geom_xpos + 3 * g) + m->geom_rbound[g]);
  return reach;
}

}  // namespace

ArmaturePose::ArmaturePose(ComponentContext& c)
    : SimComponent(c.name(), c.sim()), joints_(JointSet::from_config(c)) {
  // get_local_data puts its timestamp beside the joints
  for (const auto& j : joints_.joints())
    if (j.name == "timestamp")
      c.fail("options.joints",
             "a joint named 'timestamp' would collide with get_local_data's timestamp; list the "
             "other joints in options.joints");
  add_property("joints", [this] { return json(joints_.names()); });
  add_service("get_joints", &ArmaturePose::get_joints)
      .doc("The joints' names, from the root to the tip");
  add_service("get_state", &ArmaturePose::get_state)
      .doc(
          "{joint: {position (rad or m), velocity (rad/s or m/s), effort (N m or N, from its "
          "actuators)}}");
  add_service("get_joint", &ArmaturePose::get_joint, {"joint"})
      .doc("A joint's position (rad or m)");
  add_service("get_joints_length", &ArmaturePose::get_joints_length)
      .doc("{joint: length of the segment it moves (m)}");
  add_service("get_local_data", &ArmaturePose::get_local_data)
      .doc("{joint: position, ..., timestamp: simulated seconds}");
  declare_output_stream("joint_state", [this] { return get_local_data(); });
}

std::vector<std::string> ArmaturePose::get_joints() const { return joints_.names(); }

json ArmaturePose::get_state() const {
  json out = json::object();
  for (std::size_t i = 0; i < joints_.size(); ++i)
    out[joints_[i].name] = {{"position", joints_.position(data(), i)},
                            {"velocity", joints_.velocity(data(), i)},
                            {"effort", joints_.effort(data(), i)}};
  return out;
}

double ArmaturePose::get_joint(const std::string& joint) const {
  return joints_.position(data(), joints_.index_of(joint, "joint"));
}

json ArmaturePose::get_joints_length() const {
  json out = json::object();
  for (const auto& j : joints_.joints()) out[j.name] = segment_length(model(), data(), j.id);
  return out;
}

json ArmaturePose::get_local_data() const {
  json out = json::object();
  for (std::size_t i = 0; i < joints_.size(); ++i)
    out[joints_[i].name] = joints_.position(data(), i);
  // qpos is the integrated state, of the current time, not one of the quantities mj_step
  // evaluated before integrating (Simulation::state_time(), the other sensors' timestamp)
  out["timestamp"] = sim().sim_time();
  return out;
}

SIMGATE_BUILTIN_TYPE(
    armature_pose,
    builtin_type<ArmaturePose>("armature_pose", Kind::component,
                               "joint state: get_joints, get_state, get_joint, get_local_data",
                               "docs/components/armature.md",
                               {{"joints",
                                 {{"$ref", "#/$defs/armature_joints"}},
                                 "only these joints of its subtree, in this order"}}));

}  // namespace simgate::sim
