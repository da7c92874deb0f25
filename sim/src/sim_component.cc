#include "simgate/sim/sim_component.h"

#include <cmath>

namespace simgate::sim {

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
  return Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
         Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX());
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
  mj_forward(m, d);
}

}  // namespace simgate::sim
