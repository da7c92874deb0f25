// simgate/sim/native_sensors.h — sensors computed from MuJoCo's state, with MORSE's names
// and data fields: imu, odometry, laser_scanner, proximity.
//
// Each belongs to a robot and measures in a frame of it: the frame of a MuJoCo site (option
// `site`; it must be on the robot's body or one of its descendants) or else the frame of
// the component's body (its "body" in the config, default the robot's root body; MuJoCo's
// regular body frame, not the inertial one). Every value is expressed in that frame, in SI
// units (m, rad, s), as MORSE does; `get_local_data` adds `timestamp`: the simulated time of
// the state the values describe, Simulation::state_time() (one timestep before mjData::time
// after a step).
//
//  - imu: angular_velocity [3] (rad/s), linear_acceleration [3] (m/s², the specific force:
//    gravity included, +9.81 on z when level at rest, 0 in free fall) and magnetic_field
//    [3] (the scene's <option magnetic>, in its units) — MuJoCo's own gyro, accelerometer
//    and magnetometer, exact at the last computed state.
//  - odometry: MORSE's three levels (option `level`): "raw" {dS}, "differential" {dx, dy,
//    dz, dyaw, dpitch, droll}, "integrated" (default) {x, y, z, yaw, pitch, roll, vx, vy,
//    vz, wz, wy, wx}. Poses are relative to the sensor's pose at start (and after each
//    `simulation reset_objects`). The raw and differential values are what happened since
//    the previous get_local_data (MORSE: since the previous tick), accumulated step by step.
//  - laser_scanner: a fan of mj_ray rays in the x-y plane of the frame, from -scan_window/2
//    to +scan_window/2 every `resolution` degrees (counter-clockwise about z); range_list
//    (m, laser_range when nothing is hit) and point_list ([x, y, z] in the sensor frame,
//    [0, 0, 0] when nothing is hit, as MORSE). The robot's own geoms are not seen.
//  - proximity: near_objects {name: distance (m)} of the tracked objects within `Range` of
//    the sensor: with MORSE's default tag "Robot_Tag" the simulation's other robots, with
//    any other tag the top-level bodies (children of the world body) whose name starts
//    with it, outside the sensor's robot. Services set_range, set_tracked_tag.
//
// docs/components/native-sensors.md has the options, properties and wire examples.
//
// Threads: simulation thread only (services, default_action(), on_reset()).
#ifndef SIMGATE_SIM_NATIVE_SENSORS_H_
#define SIMGATE_SIM_NATIVE_SENSORS_H_

#include <array>
#include <string>
#include <vector>

#include "simgate/sim/registry.h"
#include "simgate/sim/sim_component.h"

namespace simgate::sim {

// Where a native sensor measures: a site's frame or a body's (regular) frame.
class SensorFrame {
 public:
  // From the context: option `site` when given (a site on the robot's subtree), else the
  // component's body. Throws ConfigError naming the path and the robot's sites.
  static SensorFrame from(ComponentContext& context);

  // MuJoCo object type for mj_objectVelocity / mj_objectAcceleration: mjOBJ_SITE or
  // mjOBJ_XBODY (the body frame; mjOBJ_BODY would be the inertial frame).
  int object_type() const { return site_ >= 0 ? mjOBJ_SITE : mjOBJ_XBODY; }
  int object_id() const { return site_ >= 0 ? site_ : body_; }
  // The body carrying the frame.
  int body() const { return body_; }
  // World position and orientation (3x3 row-major, sensor axes in the world's columns),
  // valid after the last mj_step / mj_forward.
  const mjtNum* position(const mjData* d) const;
  const mjtNum* rotation(const mjData* d) const;
  Eigen::Vector3d world_position(const mjData* d) const;
  Eigen::Matrix3d world_rotation(const mjData* d) const;
  // The frame as SimComponent::sensing_frame gives it.
  SimComponent::SensingFrame sensing(const mjData* d) const {
    return {body_, world_position(d), Eigen::Quaterniond(world_rotation(d))};
  }
  // After the model changed (SimComponent::on_model_changed).
  void remap(const ModelRemap& remap) {
    body_ = remap.body_of(body_), site_ = remap.site_of(site_);
  }

 private:
  SensorFrame(int body, int site) : body_(body), site_(site) {}
  int body_;  // MuJoCo body id
  int site_;  // MuJoCo site id, -1 when the frame is the body's
};

class Imu : public SimComponent {
 public:
  explicit Imu(ComponentContext& context);
  json get_local_data() const;
  void on_model_changed(const ModelRemap& remap) override;
  std::optional<SensingFrame> sensing_frame() const override { return frame_.sensing(data()); }

 private:
  SensorFrame frame_;
  // The model has sensors of the acceleration stage: MuJoCo's step then computes cacc
  // itself (mj_sensorAcc); otherwise get_local_data runs mj_rnePostConstraint for it.
  bool step_computes_cacc_;
};

class Odometry : public SimComponent {
 public:
  explicit Odometry(ComponentContext& context);
  json get_local_data();

  void default_action() override { update(); }
  void on_reset() override { restart(); }
  void on_model_changed(const ModelRemap& remap) override { frame_.remap(remap); }
  std::optional<SensingFrame> sensing_frame() const override { return frame_.sensing(data()); }

 private:
  enum class Level { raw, differential, integrated };
  // Adds the motion since the last update to the raw and differential sums.
  void update();
  // The pose at start becomes the current pose, the sums zero.
  void restart();
  // Position and roll, pitch, yaw of the frame relative to origin.
  void relative_pose(Eigen::Vector3d& position, Eigen::Vector3d& rpy) const;

  SensorFrame frame_;
  Level level_;
  std::string level_name_;              // as configured, for get_properties
  Eigen::Vector3d origin_position_;     // world, at start or last reset
  Eigen::Matrix3d origin_rotation_;     // world from origin frame
  Eigen::Vector3d last_position_;       // relative pose at the last update
  Eigen::Vector3d last_rpy_;            // roll, pitch, yaw at the last update
  double ds_ = 0;                       // curvilinear distance since the last read, m
  Eigen::Vector3d dposition_{0, 0, 0};  // displacement since the last read, origin frame, m
  Eigen::Vector3d drpy_{0, 0, 0};       // droll, dpitch, dyaw since the last read, rad
};

class LaserScanner : public SimComponent {
 public:
  explicit LaserScanner(ComponentContext& context);

  // Casts every ray now and keeps the results (ranges(), points()). What get_local_data
  // does before it converts them to JSON; public for the benchmark.
  void scan();
  json get_local_data();
  void on_model_changed(const ModelRemap& remap) override;
  std::optional<SensingFrame> sensing_frame() const override { return frame_.sensing(data()); }

  const std::vector<double>& ranges() const { return ranges_; }
  // x, y, z of each ray's hit point in the sensor frame, flattened.
  const std::vector<double>& points() const { return points_; }
  std::size_t ray_count() const { return directions_.size() / 3; }
  // The rays' unit directions in the sensor frame, flattened x, y, z.
  const std::vector<double>& directions() const { return directions_; }
  const SensorFrame& frame() const { return frame_; }
  // The mj_ray group filter (mjNGROUP flags).
  const mjtByte* geom_groups() const { return geom_groups_.data(); }

 private:
  // Rebuilds directions_ from scan_window_ and resolution_.
  void build_rays();
  // Distance to the first geom outside the robot along `direction` (world, unit) from
  // `origin`, or -1 when none within laser_range_.
  double cast(const mjtNum* origin, const mjtNum* direction) const;

  SensorFrame frame_;
  double laser_range_;                         // m
  double scan_window_;                         // degrees
  double resolution_;                          // degrees between rays
  std::array<mjtByte, mjNGROUP> geom_groups_;  // the geom groups the laser sees
  std::vector<char> own_geom_;                 // per geom: belongs to the robot (not seen)
  int own_geom_count_ = 0;                     // bounds the re-casts through the robot
  std::vector<double> directions_;             // sensor frame, 3 per ray
  std::vector<double> ranges_;                 // m, one per ray
  std::vector<double> points_;                 // sensor frame, 3 per ray
};

class Proximity : public SimComponent {
 public:
  explicit Proximity(ComponentContext& context);

  void set_range(double range);
  void set_tracked_tag(const std::string& tag);
  json get_local_data() const;
  void on_model_changed(const ModelRemap& remap) override;
  std::optional<SensingFrame> sensing_frame() const override { return frame_.sensing(data()); }

 private:
  // Top-level bodies outside the robot whose name starts with `tag`.
  std::vector<int> bodies_tagged(const std::string& tag) const;

  SensorFrame frame_;
  int robot_body_;            // the sensor's robot's root body (never tracked)
  double range_;              // m
  std::string tag_;           // "Robot_Tag" or a body-name prefix
  std::vector<int> tracked_;  // bodies of the tag (empty for Robot_Tag: robots are looked up)
};

// The tag MORSE gives every robot, the proximity sensor's default.
inline constexpr const char* k_robot_tag = "Robot_Tag";

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_NATIVE_SENSORS_H_
