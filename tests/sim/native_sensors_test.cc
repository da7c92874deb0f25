// The native sensors (imu, odometry, laser_scanner, proximity) on a real MuJoCo scene: a
// box robot between two walls at known distances, a turntable spinning at a known rate, a
// ball in free fall, crates to track. Values are checked against the geometry and physics
// they must reproduce; every numeric parameter is refused when it is not a finite number in
// bounds, and the simulation keeps stepping with a finite state.
#include <cmath>
#include <limits>

#include "sim_fixture.h"
#include "simgate/core/errors.h"
#include "simgate/sim/native_sensors.h"

namespace simgate::sim {
namespace {

using ::testing::HasSubstr;
using testing::RecordingManager;

// Inner faces of the walls: x = 3 (east, y from -5 to 5), y = 2 (north, x from -5 to 5).
// The robot's laser site sits at the world's z axis, 0.2 m up, inside the chassis; the mast
// (a second body of the robot) crosses the rays between about 35° and 75°.
constexpr const char* k_native_sensors_scene = R"(
<mujoco model="native-sensors-test">
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 0.1"/>
    <geom name="wall_east" type="box" pos="3.1 0 1" size="0.1 5 1"/>
    <geom name="wall_north" type="box" pos="0 2.1 1" size="5 0.1 1"/>
    <body name="robot" pos="0 0 0.15">
      <freejoint name="robot_root"/>
      <geom name="chassis" type="box" size="0.2 0.15 0.15" mass="5"/>
      <site name="laser" pos="0 0 0.05"/>
      <site name="imu_tilted" euler="90 0 0"/>
      <body name="mast" pos="0.1 0 0.05">
        <geom name="mast" type="box" size="0.02 0.3 0.05" mass="0.1"/>
      </body>
    </body>
    <body name="turntable" pos="-2 -2 0.5">
      <joint name="spin" type="hinge" axis="0 0 1"/>
      <geom type="cylinder" size="0.6 0.05" mass="1"/>
      <site name="rim" pos="0.5 0 0"/>
    </body>
    <body name="ball" pos="-5 5 50">
      <freejoint/>
      <geom type="sphere" size="0.1" mass="1"/>
    </body>
    <body name="crate_a" pos="1 -1 0.05">
      <geom type="box" size="0.05 0.05 0.05"/>
    </body>
    <body name="crate_b" pos="4 -3 0.05">
      <geom type="box" size="0.05 0.05 0.05"/>
    </body>
  </worldbody>
</mujoco>
)";

using testing::k_inf;
using testing::k_nan;
constexpr double k_g = 9.81;

// What the robot's laser must read along `degrees` (from the x axis of a sensor turned by
// `yaw` radians) from (x0, y0): the nearer wall's inner face, or nothing (-1).
double wall_distance(double degrees, double x0 = 0, double y0 = 0, double yaw = 0) {
  const double c = std::cos(degrees * M_PI / 180 + yaw), s = std::sin(degrees * M_PI / 180 + yaw);
  double best = -1;
  if (c > 1e-12) {
    const double t = (3 - x0) / c;
    if (std::abs(y0 + t * s) <= 5) best = t;
  }
  if (s > 1e-12) {
    const double t = (2 - y0) / s;
    if (std::abs(x0 + t * c) <= 5 && (best < 0 || t < best)) best = t;
  }
  return best;
}

class NativeSensorsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    sim_ = std::make_unique<Simulation>(
        Model::load_string(k_native_sensors_scene, "native-sensors-test.xml"),
        SimulationOptions{std::nullopt, 0.0});
    robot_ = add_robot("robot");
    turntable_ = add_robot("turntable");
    add_robot("ball");
    add("robot", "laser", "laser_scanner", {{"site", "laser"}});
    add("robot", "imu", "imu");
    add("robot", "imu_tilted", "imu", {{"site", "imu_tilted"}});
    add("robot", "odometry", "odometry");
    add("robot", "odometry_diff", "odometry", {{"level", "differential"}});
    add("robot", "odometry_raw", "odometry", {{"level", "raw"}});
    add("robot", "proximity", "proximity");
    add("robot", "teleport", "teleport");
    add("turntable", "rim_imu", "imu", {{"site", "rim"}});
    add("turntable", "rim_odometry", "odometry", {{"site", "rim"}});
    add("turntable", "rim_odometry_diff", "odometry", {{"site", "rim"}, {"level", "differential"}});
    add("turntable", "rim_odometry_raw", "odometry", {{"site", "rim"}, {"level", "raw"}});
    add("ball", "imu", "imu");
    add_world_components(*sim_);
    rm_ = std::make_shared<RecordingManager>();
    for (auto& e : sim_->components()) {
      rm_->register_component(*e->component);
      e->interfaces.push_back("test");
    }
    sim_->add_request_manager(rm_, "test");
  }
  void TearDown() override {
    rm_.reset();
    sim_.reset();
  }

  Robot* add_robot(const std::string& name) {
    auto robot = registry_.create(Kind::robot, {name, "robot", name, "robots[" + name + "]"},
                                  json::object(), *sim_, nullptr);
    auto* r = static_cast<Robot*>(robot.get());
    sim_->add_component(std::move(robot), "robot", "", true);
    return r;
  }
  void add(const std::string& robot, const std::string& name, const std::string& type,
           json options = json::object()) {
    sim_->add_component(create(robot, name, type, std::move(options)), type, robot);
  }
  std::unique_ptr<SimComponent> create(const std::string& robot, const std::string& name,
                                       const std::string& type, json options,
                                       const std::string& body = "") {
    auto* r = static_cast<Robot*>(sim_->find(robot)->component.get());
    return registry_.create(
        Kind::component,
        {robot + "." + name, type, body.empty() ? robot : body, "robots[0].components[0]"}, options,
        *sim_, r);
  }

  Outcome call(const std::string& component, const std::string& service,
               json params = json::array()) {
    RequestId id = rm_->call(component, service, std::move(params));
    sim_->process_requests();
    auto o = rm_->outcome(id);
    EXPECT_TRUE(o.has_value()) << component << " " << service << " not answered";
    return o.value_or(Outcome::failed(Failure::internal, "no answer"));
  }
  json data(const std::string& component) {
    Outcome o = call(component, "get_local_data");
    EXPECT_EQ(o.status, Status::success) << component << ": " << o.value.value_or(json()).dump();
    return o.value.value_or(json::object());
  }
  json properties(const std::string& component) {
    return call(component, "get_properties").value.value_or(json::object())["properties"];
  }
  void run_for(double seconds) {
    const int n = static_cast<int>(std::lround(seconds / sim_->timestep()));
    for (int i = 0; i < n; ++i) {
      sim_->process_requests();
      sim_->step();
    }
  }
  // The kinematics of the current qpos (mj_step leaves them one step behind).
  void forward() { mj_forward(sim_->m(), sim_->d()); }
  int dof(const std::string& joint) { return sim_->m()->jnt_dofadr[sim_->model().joint_id(joint)]; }
  void expect_state_finite() {
    const mjModel* m = sim_->m();
    const mjData* d = sim_->d();
    for (int i = 0; i < m->nq; ++i) ASSERT_TRUE(std::isfinite(d->qpos[i])) << "qpos[" << i << "]";
    for (int i = 0; i < m->nv; ++i) ASSERT_TRUE(std::isfinite(d->qvel[i])) << "qvel[" << i << "]";
  }
  static void expect_vector_near(const json& v, double x, double y, double z, double tolerance) {
    ASSERT_EQ(v.size(), 3u) << v;
    EXPECT_NEAR(v[0].get<double>(), x, tolerance) << v;
    EXPECT_NEAR(v[1].get<double>(), y, tolerance) << v;
    EXPECT_NEAR(v[2].get<double>(), z, tolerance) << v;
  }
  static std::string message(const Outcome& o) {
    return o.value && o.value->is_string() ? o.value->get<std::string>()
                                           : o.value.value_or(json()).dump();
  }

  ComponentRegistry registry_ = builtin_registry();
  std::unique_ptr<Simulation> sim_;
  std::shared_ptr<RecordingManager> rm_;
  Robot* robot_ = nullptr;
  Robot* turntable_ = nullptr;
};

// ---- laser_scanner ----------------------------------------------------------------------------

TEST_F(NativeSensorsTest, LaserRangesAreTheWallDistancesAndMaxRangeWhereThereIsNone) {
  run_for(0.5);  // the robot settles on the floor (moving by a micrometre or so)
  const mjData* d = sim_->d();
  const int site = mj_name2id(sim_->m(), mjOBJ_SITE, "laser");
  const double x0 = d->site_xpos[3 * site], y0 = d->site_xpos[3 * site + 1];
  const double yaw = std::atan2(d->site_xmat[9 * site + 3], d->site_xmat[9 * site]);
  json scan = data("robot.laser");
  const json& ranges = scan["range_list"];
  const json& points = scan["point_list"];
  ASSERT_EQ(ranges.size(), 181u);  // MORSE's SICK: 180° every degree, both ends included
  ASSERT_EQ(points.size(), 181u);
  int hits = 0, misses = 0;
  for (int i = 0; i < 181; ++i) {
    const double degrees = -90 + i;
    const double expected = wall_distance(degrees, x0, y0, yaw);
    if (expected < 0) {
      EXPECT_DOUBLE_EQ(ranges[i].get<double>(), 30.0) << degrees << "°";
      expect_vector_near(points[i], 0, 0, 0, 0);
      ++misses;
    } else {
      EXPECT_NEAR(ranges[i].get<double>(), expected, 1e-6) << degrees << "°";
      const double a = degrees * M_PI / 180;
      expect_vector_near(points[i], expected * std::cos(a), expected * std::sin(a), 0, 1e-6);
      ++hits;
    }
  }
  EXPECT_GT(hits, 100);                               // both walls, and
  EXPECT_GT(misses, 20);                              // the open side
  EXPECT_NEAR(ranges[90].get<double>(), 3.0, 1e-4);   // straight ahead: the east wall
  EXPECT_NEAR(ranges[180].get<double>(), 2.0, 1e-4);  // to the left: the north wall
  // the poses it cast from: those the last step started from (timestamps_test.cc)
  EXPECT_EQ(scan["timestamp"].get<double>(), sim_->state_time());
  EXPECT_NEAR(scan["timestamp"].get<double>(), 0.5 - sim_->timestep(), 1e-9);
}

TEST_F(NativeSensorsTest, LaserDoesNotSeeAnyPartOfItsRobot) {
  // mj_ray leaving out the sensor's body alone would stop on the mast at 65°
  const mjModel* m = sim_->m();
  const double a = 65 * M_PI / 180;
  const mjtNum direction[3] = {std::cos(a), std::sin(a), 0};
  const mjtNum* origin = sim_->d()->site_xpos + 3 * mj_name2id(m, mjOBJ_SITE, "laser");
  int geom = -1;
  mj_ray(m, sim_->d(), origin, direction, nullptr, 1, sim_->model().body_id("robot"), &geom,
         nullptr);
  ASSERT_EQ(geom, mj_name2id(m, mjOBJ_GEOM, "mast"));
  // the scanner sees through it, and through the chassis it starts in
  json ranges = data("robot.laser")["range_list"];
  EXPECT_NEAR(ranges[90 + 65].get<double>(), wall_distance(65), 1e-6);
  EXPECT_NEAR(ranges[90].get<double>(), 3.0, 1e-6);
  for (const json& r : ranges) EXPECT_GT(r.get<double>(), 1.0);
}

TEST_F(NativeSensorsTest, LaserMovesWithItsRobot) {
  ASSERT_EQ(call("robot.teleport", "translate", {0.5, 0.0, 0.0}).status, Status::success);
  json ranges = data("robot.laser")["range_list"];
  EXPECT_NEAR(ranges[90].get<double>(), 2.5, 1e-6);
  EXPECT_NEAR(ranges[90 + 30].get<double>(), wall_distance(30, 0.5, 0), 1e-6);
  // turned a quarter left, the sensor's x axis looks at the north wall
  ASSERT_EQ(call("robot.teleport", "rotate", {0.0, 0.0, M_PI / 2}).status, Status::success);
  ranges = data("robot.laser")["range_list"];
  EXPECT_NEAR(ranges[90].get<double>(), 2.0, 1e-6);
  EXPECT_NEAR(ranges[0].get<double>(), 2.5, 1e-6);  // -90°: now the east wall
}

TEST_F(NativeSensorsTest, SetPropertyChangesTheRays) {
  EXPECT_EQ(properties("robot.laser"), json({{"laser_range", 30.0},
                                             {"scan_window", 180.0},
                                             {"resolution", 1.0},
                                             {"ray_count", 181}}));
  ASSERT_EQ(call("robot.laser", "set_property", {"resolution", 5}).status, Status::success);
  json scan = data("robot.laser");
  ASSERT_EQ(scan["range_list"].size(), 37u);
  EXPECT_NEAR(scan["range_list"][18].get<double>(), 3.0, 1e-6);  // 0°
  EXPECT_NEAR(scan["range_list"][36].get<double>(), 2.0, 1e-6);  // 90°
  EXPECT_EQ(properties("robot.laser")["ray_count"], 37);

  // a full turn: one ray per degree, the two ends of the window being the same ray
  ASSERT_EQ(call("robot.laser", "set_property", {"scan_window", 360}).status, Status::success);
  ASSERT_EQ(call("robot.laser", "set_property", {"resolution", 1}).status, Status::success);
  scan = data("robot.laser");
  ASSERT_EQ(scan["range_list"].size(), 360u);
  EXPECT_NEAR(scan["range_list"][180].get<double>(), 3.0, 1e-6);  // -180 + 180 = 0°
  EXPECT_NEAR(scan["range_list"][270].get<double>(), 2.0, 1e-6);  // 90°

  // a shorter range: the east wall is out of reach, the north one is not
  ASSERT_EQ(call("robot.laser", "set_property", {"laser_range", 2.5}).status, Status::success);
  scan = data("robot.laser");
  EXPECT_DOUBLE_EQ(scan["range_list"][180].get<double>(), 2.5);
  expect_vector_near(scan["point_list"][180], 0, 0, 0, 0);
  EXPECT_NEAR(scan["range_list"][270].get<double>(), 2.0, 1e-6);
}

TEST_F(NativeSensorsTest, LaserSeesOnlyTheGeomGroupsItIsGiven) {
  // walls and robot are in group 0: a laser looking at group 1 only sees nothing
  auto laser =
      create("robot", "laser_g1", "laser_scanner", {{"site", "laser"}, {"geom_groups", {1}}});
  auto& scanner = static_cast<LaserScanner&>(*laser);
  scanner.scan();
  for (double r : scanner.ranges()) EXPECT_DOUBLE_EQ(r, 30.0);
}

// ---- imu --------------------------------------------------------------------------------------

TEST_F(NativeSensorsTest, ImuAtRestReadsGravityUpInItsOwnFrame) {
  run_for(1.0);
  json imu = data("robot.imu");
  expect_vector_near(imu["angular_velocity"], 0, 0, 0, 1e-6);
  expect_vector_near(imu["linear_acceleration"], 0, 0, k_g, 1e-3);
  // the tilted site's y axis points up
  json tilted = data("robot.imu_tilted");
  expect_vector_near(tilted["linear_acceleration"], 0, k_g, 0, 1e-3);
  // MuJoCo's default field (0, -0.5, 0) seen from the tilted frame: its z axis is world -y
  expect_vector_near(tilted["magnetic_field"], 0, 0, 0.5, 1e-9);
}

TEST_F(NativeSensorsTest, ImuOnASpinningTurntableReadsTheRateAndTheCentripetalAcceleration) {
  const double w = 2.0, radius = 0.5;
  sim_->d()->qvel[dof("spin")] = w;  // no friction, no damping: it keeps turning
  run_for(0.5);
  json imu = data("turntable.rim_imu");
  expect_vector_near(imu["angular_velocity"], 0, 0, w, 1e-9);
  // towards the centre (-x of the rim's frame), and gravity's reaction up
  expect_vector_near(imu["linear_acceleration"], -w * w * radius, 0, k_g, 1e-6);
}

TEST_F(NativeSensorsTest, ImuInFreeFallReadsNoAcceleration) {
  run_for(0.2);
  json imu = data("ball.imu");
  expect_vector_near(imu["linear_acceleration"], 0, 0, 0, 1e-9);
}

TEST(NativeSensorsImu, AgreesWithMujocosOwnAccelerometerAndGyro) {
  // a scene with MuJoCo's sensors: the step computes cacc itself, the imu uses it as it is
  Simulation sim(Model::load_string(R"(
    <mujoco>
      <worldbody>
        <geom type="plane" size="0 0 0.1"/>
        <body name="box" pos="0 0 1" euler="20 30 40">
          <freejoint/>
          <geom type="box" size="0.2 0.1 0.05" mass="2"/>
          <site name="s" pos="0.1 0.05 0" euler="10 0 -30"/>
        </body>
      </worldbody>
      <sensor>
        <accelerometer name="acc" site="s"/>
        <gyro name="gyro" site="s"/>
      </sensor>
    </mujoco>)"),
                 SimulationOptions{std::nullopt, 0.0});
  auto registry = builtin_registry();
  auto robot = registry.create(Kind::robot, {"box", "robot", "box", "robots[0]"}, json::object(),
                               sim, nullptr);
  auto imu = registry.create(Kind::component, {"box.imu", "imu", "box", "robots[0].components[0]"},
                             json{{"site", "s"}}, sim, static_cast<Robot*>(robot.get()));
  sim.d()->qvel[3] = 3;  // tumbling as it falls onto the floor
  sim.d()->qvel[4] = -1;
  for (int i = 0; i < 400; ++i) {
    sim.step();
    if (i % 50 != 49) continue;
    json reading = static_cast<Imu&>(*imu).get_local_data();
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(reading["linear_acceleration"][k].get<double>(), sim.d()->sensordata[k], 1e-9)
          << i;
      EXPECT_NEAR(reading["angular_velocity"][k].get<double>(), sim.d()->sensordata[3 + k], 1e-9)
          << i;
    }
  }
}

// ---- odometry ---------------------------------------------------------------------------------

TEST_F(NativeSensorsTest, OdometryFollowsATeleportedDisplacement) {
  EXPECT_EQ(properties("robot.odometry")["level"], "integrated");
  data("robot.odometry_diff");  // the differences start here
  ASSERT_EQ(call("robot.teleport", "translate", {1.0, 0.5, 0.0}).status, Status::success);
  json o = data("robot.odometry");
  EXPECT_NEAR(o["x"].get<double>(), 1.0, 1e-9);
  EXPECT_NEAR(o["y"].get<double>(), 0.5, 1e-9);
  EXPECT_NEAR(o["z"].get<double>(), 0.0, 1e-9);
  json d = data("robot.odometry_diff");
  EXPECT_NEAR(d["dx"].get<double>(), 1.0, 1e-9);
  EXPECT_NEAR(d["dy"].get<double>(), 0.5, 1e-9);
  EXPECT_NEAR(data("robot.odometry_raw")["dS"].get<double>(), std::sqrt(1.25), 1e-9);
  // read again: nothing moved since
  d = data("robot.odometry_diff");
  EXPECT_EQ(d["dx"], 0.0);
  EXPECT_EQ(d["dyaw"], 0.0);
  EXPECT_EQ(data("robot.odometry_raw")["dS"], 0.0);

  // turned, then moved forward: in the start frame, along the new heading
  ASSERT_EQ(call("robot.teleport", "rotate", {0.0, 0.0, 0.5}).status, Status::success);
  ASSERT_EQ(call("robot.teleport", "translate", {std::cos(0.5), std::sin(0.5), 0.0}).status,
            Status::success);
  o = data("robot.odometry");
  EXPECT_NEAR(o["yaw"].get<double>(), 0.5, 1e-9);
  EXPECT_NEAR(o["x"].get<double>(), 1.0 + std::cos(0.5), 1e-9);
  EXPECT_NEAR(o["y"].get<double>(), 0.5 + std::sin(0.5), 1e-9);
  d = data("robot.odometry_diff");
  EXPECT_NEAR(d["dyaw"].get<double>(), 0.5, 1e-9);
  EXPECT_NEAR(d["dx"].get<double>(), std::cos(0.5), 1e-9);
}

TEST_F(NativeSensorsTest, OdometryOfASpinningRimCountsEveryTurnAndTheArcLength) {
  const double w = 2.0, radius = 0.5;
  data("turntable.rim_odometry_diff");
  data("turntable.rim_odometry_raw");
  sim_->d()->qvel[dof("spin")] = w;
  run_for(2.5);
  forward();
  const double angle = sim_->d()->qpos[sim_->m()->jnt_qposadr[sim_->model().joint_id("spin")]];
  ASSERT_NEAR(angle, 5.0, 0.01);  // more than half a turn between two readings
  // the differences add up the steps: the whole angle, not angle - 2π
  json d = data("turntable.rim_odometry_diff");
  EXPECT_NEAR(d["dyaw"].get<double>(), angle, 1e-9);
  EXPECT_NEAR(data("turntable.rim_odometry_raw")["dS"].get<double>(), radius * angle, 1e-5);
  // the rim's pose relative to where it started: on the circle about the centre
  json o = data("turntable.rim_odometry");
  EXPECT_NEAR(o["x"].get<double>(), radius * (std::cos(angle) - 1), 1e-9);
  EXPECT_NEAR(o["y"].get<double>(), radius * std::sin(angle), 1e-9);
  EXPECT_NEAR(o["yaw"].get<double>(), std::remainder(angle, 2 * M_PI), 1e-9);
  // velocities in the sensor frame: forward along its y axis (tangent), turning about z
  EXPECT_NEAR(o["vx"].get<double>(), 0.0, 1e-9);
  EXPECT_NEAR(o["vy"].get<double>(), w * radius, 1e-9);
  EXPECT_NEAR(o["wz"].get<double>(), w, 1e-9);
}

TEST_F(NativeSensorsTest, OdometryStartsAgainAfterResetObjects) {
  ASSERT_EQ(call("robot.teleport", "translate", {2.0, 0.0, 0.0}).status, Status::success);
  data("robot.odometry_diff");
  ASSERT_EQ(call("simulation", "reset_objects").status, Status::success);
  // back at the start pose: the jump back is no motion the robot made
  json o = data("robot.odometry");
  EXPECT_NEAR(o["x"].get<double>(), 0.0, 1e-12);
  json d = data("robot.odometry_diff");
  EXPECT_NEAR(d["dx"].get<double>(), 0.0, 1e-12);
  EXPECT_NEAR(data("robot.odometry_raw")["dS"].get<double>(), 0.0, 1e-12);
  // and it counts from there
  ASSERT_EQ(call("robot.teleport", "translate", {0.25, 0.0, 0.0}).status, Status::success);
  EXPECT_NEAR(data("robot.odometry")["x"].get<double>(), 0.25, 1e-9);
  EXPECT_NEAR(data("robot.odometry_diff")["dx"].get<double>(), 0.25, 1e-9);
}

TEST_F(NativeSensorsTest, OdometryLevelsExportMorsesFields) {
  auto keys = [](const json& o) {
    std::vector<std::string> k;
    for (auto& [key, value] : o.items()) k.push_back(key);
    return k;
  };
  using ::testing::UnorderedElementsAre;
  EXPECT_THAT(keys(data("robot.odometry_raw")), UnorderedElementsAre("dS", "timestamp"));
  EXPECT_THAT(keys(data("robot.odometry_diff")),
              UnorderedElementsAre("dx", "dy", "dz", "dyaw", "dpitch", "droll", "timestamp"));
  EXPECT_THAT(keys(data("robot.odometry")),
              UnorderedElementsAre("x", "y", "z", "yaw", "pitch", "roll", "vx", "vy", "vz", "wz",
                                   "wy", "wx", "timestamp"));
}

// ---- proximity --------------------------------------------------------------------------------

TEST_F(NativeSensorsTest, ProximityListsTheOtherRobotsWithinRange) {
  const double to_turntable = std::sqrt(4 + 4 + 0.35 * 0.35);
  json near = data("robot.proximity")["near_objects"];
  // MORSE's default range (100 m) reaches the falling ball too, never the robot itself
  EXPECT_EQ(near.size(), 2u) << near;
  EXPECT_NEAR(near["turntable"].get<double>(), to_turntable, 1e-9);
  EXPECT_TRUE(near.contains("ball"));
  ASSERT_EQ(call("robot.proximity", "set_range", {10.0}).status, Status::success);
  json reading = data("robot.proximity");
  EXPECT_EQ(reading["near_objects"], json({{"turntable", to_turntable}}));
  EXPECT_EQ(reading["near_robots"], reading["near_objects"]);  // MORSE's deprecated alias
  EXPECT_EQ(properties("robot.proximity"), json({{"Range", 10.0}, {"Track", "Robot_Tag"}}));
}

TEST_F(NativeSensorsTest, ProximityTracksBodiesByTheStartOfTheirName) {
  ASSERT_EQ(call("robot.proximity", "set_tracked_tag", {"crate"}).status, Status::success);
  ASSERT_EQ(call("robot.proximity", "set_range", {3.0}).status, Status::success);
  const double to_a = std::sqrt(1 + 1 + 0.1 * 0.1);
  EXPECT_EQ(data("robot.proximity")["near_objects"], json({{"crate_a", to_a}}));
  ASSERT_EQ(call("robot.proximity", "set_property", {"Range", 6.0}).status, Status::success);
  json near = data("robot.proximity")["near_objects"];
  EXPECT_EQ(near.size(), 2u);
  EXPECT_NEAR(near["crate_b"].get<double>(), std::sqrt(16 + 9 + 0.01), 1e-9);
  // back to robots through the property
  ASSERT_EQ(call("robot.proximity", "set_property", {"Track", "Robot_Tag"}).status,
            Status::success);
  EXPECT_TRUE(data("robot.proximity")["near_objects"].contains("turntable"));
}

TEST_F(NativeSensorsTest, ProximityRefusesATagThatTracksNothing) {
  Outcome o = call("robot.proximity", "set_tracked_tag", {"barrel"});
  EXPECT_EQ(o.status, Status::failed);
  EXPECT_THAT(message(o), HasSubstr("no object to track with tag 'barrel'"));
  EXPECT_THAT(message(o),
              HasSubstr("(turntable, ball, crate_a, crate_b)"));  // never the robot itself
  EXPECT_EQ(properties("robot.proximity")["Track"], "Robot_Tag");
  EXPECT_EQ(call("robot.proximity", "set_property", {"Track", 3}).status, Status::failed);
}

// ---- bad input ----------------------------------------------------------------------------------

TEST_F(NativeSensorsTest, EveryNumberThatIsNotFiniteOrInBoundsIsRefused) {
  const json before_laser = properties("robot.laser");
  const json before_proximity = properties("robot.proximity");
  for (json bad : {json(k_nan), json(k_inf), json(-k_inf), json(1e300), json(-1.0), json("far"),
                   json(nullptr)}) {
    for (auto property : {"laser_range", "scan_window", "resolution"}) {
      Outcome o = call("robot.laser", "set_property", {property, bad});
      EXPECT_EQ(o.status, Status::failed) << property << " = " << bad.dump();
    }
    Outcome o = call("robot.proximity", "set_property", {"Range", bad});
    EXPECT_EQ(o.status, Status::failed) << "Range = " << bad.dump();
    o = call("robot.proximity", "set_range", {bad});
    EXPECT_EQ(o.status, Status::failed) << "set_range " << bad.dump();
  }
  Outcome o = call("robot.proximity", "set_range", {k_nan});
  EXPECT_THAT(message(o), HasSubstr("range = nan is out of bounds"));
  o = call("robot.laser", "set_property", {"resolution", 0.0});
  EXPECT_THAT(
      message(o),
      HasSubstr("resolution = 0 is out of bounds: expected a finite number from 0.01 to 360"));
  // nothing changed, nothing reached MuJoCo, and the simulation goes on
  EXPECT_EQ(properties("robot.laser"), before_laser);
  EXPECT_EQ(properties("robot.proximity"), before_proximity);
  run_for(0.1);
  expect_state_finite();
  EXPECT_EQ(data("robot.laser")["range_list"].size(), 181u);
  EXPECT_NEAR(data("robot.laser")["range_list"][90].get<double>(), 3.0, 1e-6);
}

TEST_F(NativeSensorsTest, ConfigurationErrorsNameTheOptionAndWhatIsValid) {
  auto config_error = [&](const std::string& robot, const std::string& type, json options) {
    try {
      create(robot, "bad", type, std::move(options));
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_THAT(
      config_error("robot", "imu", {{"site", "lidar"}}),
      HasSubstr(
          "options.site: expected the name of a site on robot 'robot' (laser, imu_tilted), found "
          "'lidar' (no such site)"));
  EXPECT_THAT(config_error("robot", "laser_scanner", {{"site", "rim"}}),
              HasSubstr("found 'rim', which is on body 'turntable', not on the robot"));
  EXPECT_THAT(config_error("robot", "odometry", {{"level", "integral"}}),
              HasSubstr("options.level"));
  EXPECT_THAT(config_error("robot", "laser_scanner", {{"geom_groups", {0, 7}}}),
              HasSubstr("options.geom_groups"));
  EXPECT_THAT(config_error("robot", "laser_scanner", {{"resolution", 0}}),
              HasSubstr("options.resolution"));
  EXPECT_THAT(config_error("robot", "proximity", {{"track", "barrel"}}),
              HasSubstr("options.track: no object to track with tag 'barrel'"));
  EXPECT_THAT(config_error("robot", "proximity", {{"rnage", 3}}), HasSubstr("rnage"));
}

TEST_F(NativeSensorsTest, EverySensorAnswersMorsesObjectServices) {
  for (auto name :
       {"robot.laser", "robot.imu", "robot.odometry", "robot.proximity", "turntable.rim_imu"}) {
    EXPECT_EQ(call(name, "get_properties").status, Status::success) << name;
    Outcome c = call(name, "get_configurations");
    ASSERT_EQ(c.status, Status::success) << name;
    EXPECT_TRUE(c.value->at("configurations").contains("type")) << name;
  }
  EXPECT_EQ(call("robot.laser", "get_configurations").value->at("configurations")["options"],
            json({{"site", "laser"}}));
}

}  // namespace
}  // namespace simgate::sim
