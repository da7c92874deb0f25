#include <algorithm>
#include <array>

#include "simgate/sim/components.h"

namespace simgate::sim {

namespace {
// a pose sample's numbers (MORSE's pose sensor), in the order Pose::read writes them
const std::vector<std::string> k_pose_fields{"x", "y", "z", "roll", "pitch", "yaw", "timestamp"};
}  // namespace

Pose::Pose(ComponentContext& c) : SimComponent(c.name(), c.sim()), body_(c.body()) {
  add_service("get_local_data", &Pose::get_local_data)
      .doc(
          "Position (x, y, z metres) and orientation (roll, pitch, yaw radians) in the world "
          "frame");
  // a record: streamed without building JSON (a DDS Pose is written from it as it is)
  declare_output_stream("pose", k_pose_fields, [this](std::span<double> values) { read(values); });
}

void Pose::read(std::span<double> values) const {
  const Eigen::Vector3d p = body_position(sim(), body_);
  const Eigen::Vector3d rpy = to_roll_pitch_yaw(body_orientation(sim(), body_));
  const std::array<double, 7> numbers{
      p.x(), p.y(), p.z(), rpy.x(), rpy.y(), rpy.z(), sim().state_time()};
  std::copy(numbers.begin(), numbers.end(), values.begin());
}

json Pose::get_local_data() const {
  std::array<double, 7> values;
  read(values);
  return record_json(k_pose_fields, values);
}

SIMGATE_BUILTIN_TYPE(pose,
                     builtin_type<Pose>("pose", Kind::component, "pose sensor: get_local_data",
                                        "docs/configuration.md", {}));

}  // namespace simgate::sim
