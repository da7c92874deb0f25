// The ros2 transport's mapping (protocols/ros2/ros2_mapping.h, ros2_types.h): names, time,
// rotations, the frame tree and its transforms, samples, the types announced by name only.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>

#include "ros2_mapping.h"
#include "ros2_msgs.h"
#include "ros2_types.h"

namespace simgate::ros2 {
namespace {

constexpr double k_eps = 1e-12;

// q = a * b, (w, x, y, z): written here apart from the mapping's own
std::array<double, 4> hamilton(const std::array<double, 4>& a, const std::array<double, 4>& b) {
  return {a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
          a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
          a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
          a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]};
}

std::array<double, 4> about(int axis, double angle) {
  std::array<double, 4> q{std::cos(angle / 2), 0, 0, 0};
  q[static_cast<std::size_t>(axis) + 1] = std::sin(angle / 2);
  return q;
}

void expect_near(const std::array<double, 4>& a, const std::array<double, 4>& b) {
  for (std::size_t i = 0; i < 4; ++i) EXPECT_NEAR(a[i], b[i], k_eps) << "component " << i;
}

// Three bodies: world, a base at (1, 0, 0) turned 90° about z, a wheel 1 m along the base's x.
json geometry(std::uint64_t generation) {
  return {
      {"generation", generation},
      {"bodies",
       {{{"id", 0}, {"name", "world"}, {"parent", 0}},
        {{"id", 1}, {"name", "base"}, {"parent", 0}},
        {{"id", 2}, {"name", "wheel"}, {"parent", 1}}}},
      {"frames",
       {{{"name", "rover.lidar"}, {"body", 1}, {"pos", {0.1, 0, 0.2}}, {"quat", {1, 0, 0, 0}}}}}};
}

json body_poses(std::uint64_t generation) {
  const double c = std::cos(M_PI / 4), s = std::sin(M_PI / 4);
  return {{"generation", generation},
          {"timestamp", 1.5},
          {"poses", {{0, 0, 0, 1, 0, 0, 0}, {1, 0, 0, c, 0, 0, s}, {1, 1, 0, c, 0, 0, s}}}};
}

TEST(Ros2MappingTest, TimeSplitsIntoSecondsAndNanoseconds) {
  EXPECT_EQ(to_ros_time(1.5).sec, 1);
  EXPECT_EQ(to_ros_time(1.5).nanosec, 500'000'000u);
  EXPECT_EQ(to_ros_time(2.0).sec, 2);
  EXPECT_EQ(to_ros_time(2.0).nanosec, 0u);
  EXPECT_EQ(to_ros_time(0.002).nanosec, 2'000'000u);
}

TEST(Ros2MappingTest, TimeRoundedUpToTheNextSecondCarries) {
  const RosTime t = to_ros_time(3.9999999999);
  EXPECT_EQ(t.sec, 4);
  EXPECT_EQ(t.nanosec, 0u);
}

TEST(Ros2MappingTest, TimeOutOfRangeIsClamped) {
  EXPECT_EQ(to_ros_time(-1).sec, 0);
  EXPECT_EQ(to_ros_time(std::nan("")).sec, 0);
  EXPECT_EQ(to_ros_time(std::numeric_limits<double>::infinity()).sec, 0);
  EXPECT_EQ(to_ros_time(1e12).sec, std::numeric_limits<std::int32_t>::max());
  EXPECT_EQ(to_ros_time(1e12).nanosec, 999'999'999u);
}

TEST(Ros2MappingTest, NamesBecomeRosTokens) {
  EXPECT_TRUE(is_ros_token("robot_1"));
  EXPECT_FALSE(is_ros_token("1robot"));
  EXPECT_FALSE(is_ros_token("my-robot"));
  EXPECT_FALSE(is_ros_token(""));
  EXPECT_EQ(to_ros_token("robot"), "robot");
  EXPECT_EQ(to_ros_token("my-robot.x"), "my_robot_x");
  EXPECT_EQ(to_ros_token("2d"), "_2d");
  EXPECT_EQ(to_ros_token(""), "_");
}

TEST(Ros2MappingTest, TopicNamesTakeTheRtPrefix) {
  EXPECT_EQ(dds_topic_name("/robot/odom"), "rt/robot/odom");
  EXPECT_EQ(dds_topic_name("/clock"), "rt/clock");
  EXPECT_EQ(dds_topic_name("tf"), "rt/tf");
}

TEST(Ros2MappingTest, ComponentsNameTheirRobotAndFrame) {
  EXPECT_EQ(robot_of("robot.pose"), "robot");
  EXPECT_EQ(robot_of("arm.gripper.left"), "arm");
  EXPECT_EQ(robot_of("simulation"), "");
  EXPECT_EQ(component_frame("robot.odometry"), "robot/odometry");
  EXPECT_EQ(component_frame("arm.cam-1"), "arm/cam_1");
}

TEST(Ros2MappingTest, RollPitchYawComposeAsRzRyRx) {
  const double roll = 0.3, pitch = -0.2, yaw = 1.1;
  expect_near(quaternion_from_rpy(roll, pitch, yaw),
              hamilton(hamilton(about(2, yaw), about(1, pitch)), about(0, roll)));
  expect_near(quaternion_from_rpy(0, 0, M_PI / 2), about(2, M_PI / 2));
}

TEST(Ros2MappingTest, RelativePoseIsInTheParentsFrame) {
  Pose parent{{1, 0, 0}, about(2, M_PI / 2)};
  Pose child{{1, 1, 0}, about(2, M_PI / 2)};
  const Pose relative = relative_pose(parent, child);
  EXPECT_NEAR(relative.position[0], 1, k_eps);  // 1 m along the parent's x (world y)
  EXPECT_NEAR(relative.position[1], 0, k_eps);
  EXPECT_NEAR(relative.position[2], 0, k_eps);
  expect_near(relative.rotation, {1, 0, 0, 0});
}

TEST(Ros2MappingTest, FrameTreeNamesBodiesAndTheWorld) {
  const FrameTree tree = FrameTree::from_geometry(geometry(3), "map");
  EXPECT_EQ(tree.generation, 3u);
  EXPECT_EQ(tree.names, (std::vector<std::string>{"map", "base", "wheel"}));
  EXPECT_EQ(tree.parents, (std::vector<int>{0, 0, 1}));
  ASSERT_EQ(tree.fixed.size(), 1u);
  EXPECT_EQ(tree.fixed[0].name, "rover/lidar");
  EXPECT_EQ(tree.fixed[0].body, 1);
  const std::vector<FrameTransform> fixed = fixed_transforms(tree);
  ASSERT_EQ(fixed.size(), 1u);
  EXPECT_EQ(*fixed[0].parent, "base");
  EXPECT_EQ(*fixed[0].child, "rover/lidar");
  EXPECT_NEAR(fixed[0].pose.position[2], 0.2, k_eps);
}

TEST(Ros2MappingTest, FrameTreeRefusesAParentThatIsNoEarlierBody) {
  json bad = geometry(0);
  bad["bodies"][1]["parent"] = 2;
  EXPECT_THROW(FrameTree::from_geometry(bad, "world"), std::invalid_argument);
  bad = geometry(0);
  bad["bodies"] = json::array();
  EXPECT_THROW(FrameTree::from_geometry(bad, "world"), std::invalid_argument);
}

TEST(Ros2MappingTest, BodyTransformsChainParentToChild) {
  const FrameTree tree = FrameTree::from_geometry(geometry(1), "world");
  std::vector<FrameTransform> out;
  ASSERT_TRUE(body_transforms(body_poses(1), tree, out));
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(*out[0].parent, "world");
  EXPECT_EQ(*out[0].child, "base");
  EXPECT_NEAR(out[0].pose.position[0], 1, k_eps);
  expect_near(out[0].pose.rotation, about(2, M_PI / 2));
  EXPECT_EQ(*out[1].parent, "base");
  EXPECT_EQ(*out[1].child, "wheel");
  EXPECT_NEAR(out[1].pose.position[0], 1, k_eps);
  EXPECT_NEAR(out[1].pose.position[1], 0, k_eps);
}

TEST(Ros2MappingTest, BodyTransformsOfAnotherModelAreRefused) {
  const FrameTree tree = FrameTree::from_geometry(geometry(1), "world");
  std::vector<FrameTransform> out;
  EXPECT_FALSE(body_transforms(body_poses(2), tree, out));
  json short_sample = body_poses(1);
  short_sample["poses"].erase(2);
  EXPECT_FALSE(body_transforms(short_sample, tree, out));
  json bad_pose = body_poses(1);
  bad_pose["poses"][1][3] = "one";
  EXPECT_FALSE(body_transforms(bad_pose, tree, out));
  EXPECT_TRUE(out.empty());
  EXPECT_FALSE(body_transforms(body_poses(1), FrameTree{}, out));
}

TEST(Ros2MappingTest, JointPositionsLeaveTheTimestampOut) {
  const JointPositions joints =
      joint_positions({{"elbow", 0.5}, {"shoulder", -1.0}, {"timestamp", 2.0}});
  EXPECT_EQ(joints.names, (std::vector<std::string>{"elbow", "shoulder"}));
  EXPECT_EQ(joints.positions, (std::vector<double>{0.5, -1.0}));
  EXPECT_THROW(joint_positions({{"elbow", "up"}}), std::invalid_argument);
  EXPECT_THROW(joint_positions(json::array()), std::invalid_argument);
}

TEST(Ros2MappingTest, IntegratedOdometryKeepsItsTwist) {
  const OdometryValues v =
      odometry_from_integrated({1, 2, 3, 0, 0, M_PI / 2, 0.5, 0.1, 0, 0.01, 0.02, 0.3});
  EXPECT_EQ(v.pose.position, (std::array<double, 3>{1, 2, 3}));
  expect_near(v.pose.rotation, about(2, M_PI / 2));
  EXPECT_EQ(v.linear, (std::array<double, 3>{0.5, 0.1, 0}));
  EXPECT_EQ(v.angular, (std::array<double, 3>{0.01, 0.02, 0.3}));
  EXPECT_TRUE(v.twist_known);
}

TEST(Ros2MappingTest, PoseOdometryHasNoTwist) {
  const OdometryValues v = odometry_from_pose({1, 2, 3, 0, 0, 0});
  EXPECT_FALSE(v.twist_known);
  EXPECT_EQ(v.linear, (std::array<double, 3>{0, 0, 0}));
}

TEST(Ros2MappingTest, TwistBecomesAVelocityCommand) {
  EXPECT_EQ(velocity_command(0.5, -0.25), (json{{"v", 0.5}, {"w", -0.25}}));
}

TEST(Ros2MappingTest, JointCommandKeepsTheArmaturesJointsAndNamesTheOthers) {
  const JointCommand c =
      joint_command({"elbow", "wrist", "shoulder"}, {0.5, 1.0, -0.25}, {"shoulder", "elbow"});
  EXPECT_EQ(c.positions, (json{{"elbow", 0.5}, {"shoulder", -0.25}}));
  EXPECT_EQ(c.unknown, (std::vector<std::string>{"wrist"}));
}

TEST(Ros2MappingTest, JointCommandWithoutPositionsIsEmptyAndOtherCountsAreRefused) {
  EXPECT_TRUE(joint_command({"elbow"}, {}, {"elbow"}).positions.empty());
  EXPECT_THROW(joint_command({"elbow", "shoulder"}, {0.5}, {"elbow"}), std::invalid_argument);
  EXPECT_THROW(joint_command({}, {0.5}, {"elbow"}), std::invalid_argument);
}

// A camera's payload as cameras.cc makes it: 2x1 pixels.
StreamPayload camera_payload(const std::string& encoding, std::size_t pixel) {
  StreamPayload p;
  p.content = "image";
  p.description = {{"width", 2},
                   {"height", 1},
                   {"encoding", encoding},
                   {"step", 2 * pixel},
                   {"is_bigendian", false},
                   {"intrinsic_matrix", {{100, 0, 1}, {0, 110, 0.5}, {0, 0, 1}}}};
  p.bytes.assign(2 * pixel, 7);
  return p;
}

TEST(Ros2MappingTest, ImageShapeIsThePayloadsAndItsSizeIsChecked) {
  const ImageShape rgb = image_shape(camera_payload("rgb8", 3));
  EXPECT_EQ(rgb.width, 2u);
  EXPECT_EQ(rgb.height, 1u);
  EXPECT_EQ(rgb.step, 6u);
  EXPECT_EQ(rgb.encoding, "rgb8");
  EXPECT_FALSE(rgb.is_bigendian);
  EXPECT_EQ(image_shape(camera_payload("32FC1", 4)).step, 8u);
  StreamPayload short_one = camera_payload("rgb8", 3);
  short_one.bytes.pop_back();
  EXPECT_THROW(image_shape(short_one), std::invalid_argument);
  StreamPayload other = camera_payload("rgb8", 3);
  other.content = "audio";
  EXPECT_THROW(image_shape(other), std::invalid_argument);
}

TEST(Ros2MappingTest, CameraInfoIsAPinholeWithNoDistortion) {
  const CameraInfoValues v = camera_info_values(camera_payload("rgb8", 3).description);
  EXPECT_EQ(v.width, 2u);
  EXPECT_EQ(v.height, 1u);
  EXPECT_EQ(v.k, (std::array<double, 9>{100, 0, 1, 0, 110, 0.5, 0, 0, 1}));
  EXPECT_EQ(v.p, (std::array<double, 12>{100, 0, 1, 0, 0, 110, 0.5, 0, 0, 0, 1, 0}));
  EXPECT_EQ(v.r, (std::array<double, 9>{1, 0, 0, 0, 1, 0, 0, 0, 1}));
  EXPECT_EQ(v.d, (std::array<double, 5>{}));
  EXPECT_STREQ(k_distortion_model, "plumb_bob");
  EXPECT_THROW(camera_info_values({{"intrinsic_matrix", {{1, 0}, {0, 1}}}}), std::invalid_argument);
}

// 5 rays from -60° every 30°, those in `hits` hitting at 2 m, the others missing (range 10).
json scan(std::initializer_list<int> hits) {
  json points = json::array(), ranges = json::array();
  for (int i = 0; i < 5; ++i) {
    const double angle = (-60 + 30 * i) * M_PI / 180;
    bool hit = false;
    for (int h : hits) hit = hit || h == i;
    points.push_back(hit ? json{2 * std::cos(angle), 2 * std::sin(angle), 0} : json{0, 0, 0});
    ranges.push_back(hit ? 2.0 : 10.0);
  }
  return {{"range_list", ranges}, {"point_list", points}, {"timestamp", 1.0}};
}

TEST(Ros2MappingTest, LaserScanMissesAreInfinityAndTheReachIsTheirRange) {
  LaserReading reading;
  const LaserScanValues v = laser_scan_values(scan({1, 3}), 10, reading);
  EXPECT_NEAR(v.angle_min, -M_PI / 3, 1e-6);
  EXPECT_NEAR(v.angle_max, M_PI / 3, 1e-6);
  EXPECT_NEAR(v.angle_increment, M_PI / 6, 1e-6);
  EXPECT_FLOAT_EQ(v.scan_time, 0.1f);
  EXPECT_EQ(v.range_min, 0.0f);
  EXPECT_EQ(v.range_max, 10.0f);
  const float inf = std::numeric_limits<float>::infinity();
  EXPECT_EQ(v.ranges, (std::vector<float>{inf, 2, inf, 2, inf}));
  // a scan that hits everything keeps the reach and the arc read before
  const LaserScanValues all = laser_scan_values(scan({0, 1, 2, 3, 4}), 0, reading);
  EXPECT_EQ(all.range_max, 10.0f);
  EXPECT_EQ(all.scan_time, 0.0f);
  EXPECT_NEAR(all.angle_min, -M_PI / 3, 1e-6);
}

TEST(Ros2MappingTest, LaserScanBeforeAnyMissReachesItsFarthestHit) {
  LaserReading reading;
  json sample = scan({0, 1, 2, 3, 4});
  sample["range_list"][2] = 3.5;
  EXPECT_EQ(laser_scan_values(sample, 10, reading).range_max, 3.5f);
  // no arc read yet (no two hits): MORSE's default, 1° apart, centred
  LaserReading fresh;
  const LaserScanValues blind = laser_scan_values(scan({}), 10, fresh);
  EXPECT_NEAR(blind.angle_min, -2 * M_PI / 180, 1e-6);
  EXPECT_NEAR(blind.angle_increment, M_PI / 180, 1e-6);
  EXPECT_THROW(laser_scan_values(json{{"range_list", {1, "far"}}}, 10, fresh),
               std::invalid_argument);
  EXPECT_THROW(laser_scan_values(json{{"point_list", json::array()}}, 10, fresh),
               std::invalid_argument);
}

TEST(Ros2TypesTest, TypesAreNamedAsRos2NamesThem) {
  EXPECT_STREQ(tf2_msgs_msg_dds__TFMessage__desc.m_typename, "tf2_msgs::msg::dds_::TFMessage_");
  EXPECT_STREQ(rosgraph_msgs_msg_dds__Clock__desc.m_typename, "rosgraph_msgs::msg::dds_::Clock_");
  EXPECT_STREQ(rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc.m_typename,
               "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_");
  // keyless, as ROS 2's messages are
  EXPECT_EQ(nav_msgs_msg_dds__Odometry__desc.m_nkeys, 0u);
  EXPECT_STREQ(sensor_msgs_msg_dds__Image__desc.m_typename, "sensor_msgs::msg::dds_::Image_");
  EXPECT_STREQ(sensor_msgs_msg_dds__CameraInfo__desc.m_typename,
               "sensor_msgs::msg::dds_::CameraInfo_");
  EXPECT_STREQ(sensor_msgs_msg_dds__LaserScan__desc.m_typename,
               "sensor_msgs::msg::dds_::LaserScan_");
  EXPECT_EQ(sizeof(rmw_dds_common_msg_dds__Gid_{}.data), 16u);
}

TEST(Ros2TypesTest, NameOnlyDropsTheTypeInformationAndKeepsTheRest) {
  const dds_topic_descriptor_t& generated = sensor_msgs_msg_dds__JointState__desc;
  ASSERT_NE(generated.m_flagset & DDS_TOPIC_XTYPES_METADATA, 0u);
  const dds_topic_descriptor_t* copy = name_only(generated);
  EXPECT_EQ(copy->m_flagset & DDS_TOPIC_XTYPES_METADATA, 0u);
  EXPECT_EQ(copy->type_information.data, nullptr);
  EXPECT_EQ(copy->type_mapping.data, nullptr);
  EXPECT_STREQ(copy->m_typename, generated.m_typename);
  EXPECT_EQ(copy->m_ops, generated.m_ops);
  EXPECT_EQ(copy->m_size, generated.m_size);
  EXPECT_EQ(name_only(generated), copy);  // one copy per type
}

}  // namespace
}  // namespace simgate::ros2
