#include "simgate/sim/components.h"

namespace simgate::sim {

Pose::Pose(ComponentContext& c) : SimComponent(c.name(), c.sim()), body_(c.body()) {
  add_service("get_local_data", &Pose::get_local_data)
      .doc("Position (x, y, z metres) and orientation (roll, pitch, yaw radians) in the world frame");
  declare_output_stream("pose", [this] { return get_local_data(); });
}

json Pose::get_local_data() const {
  Eigen::Vector3d p = body_position(sim(), body_);
  Eigen::Vector3d rpy = to_roll_pitch_yaw(body_orientation(sim(), body_));
  return {{"x", p.x()},       {"y", p.y()},         {"z", p.z()},
          {"roll", rpy.x()},  {"pitch", rpy.y()},   {"yaw", rpy.z()},
          {"timestamp", sim().state_time()}};
}

}  // namespace simgate::sim
