// Sensors' samples in Foxglove's schemas (simgate/foxglove/sensors.h): which channels each
// stream kind makes, each message made from a sample as the components make them, a
// laser's arc read from its hits, and samples of another shape refused ("") rather than
// sent wrong. (That the messages are what Foxglove's own schemas accept is checked end to
// end, by tests/foxglove/foxglove_client_test.js with @foxglove/schemas.)
#include "simgate/foxglove/sensors.h"

#include <cmath>
#include <cstring>
#include <memory>

#include <gtest/gtest.h>

#include "simgate/core/base64.h"

namespace simgate::foxglove {
namespace {

json parse(const std::string& text) { return json::parse(text); }

// A camera's sample: 2x1 pixels, their record made by to_json as the camera's is.
SamplePtr camera_sample(const std::string& encoding, std::vector<std::uint8_t> bytes) {
  auto payload = std::make_shared<StreamPayload>();
  payload->content = "image";
  const int pixel = encoding == "rgb8" ? 3 : 4;
  payload->description = {{"width", 2},
                          {"height", 1},
                          {"encoding", encoding},
                          {"step", 2 * pixel},
                          {"is_bigendian", false},
                          {"intrinsic_matrix", {{100, 0, 1}, {0, 100, 0.5}, {0, 0, 1}}}};
  payload->bytes = std::move(bytes);
  payload->to_json = [](const StreamPayload&) {
    return json{{"width", 2}, {"height", 1}, {"image", "iVBORw0KGgo="}};
  };
  return std::make_shared<StreamSample>(7, 1.5, payload);
}

TEST(FoxgloveSensors, EachKindMakesItsChannelsAndOthersNone) {
  const auto image = sensor_channels("image");
  ASSERT_EQ(image.size(), 2u);
  EXPECT_EQ(image[0].suffix, "");
  EXPECT_EQ(image[0].message, SensorMessage::compressed_image);
  EXPECT_EQ(image[1].suffix, "/calibration");
  EXPECT_EQ(image[1].message, SensorMessage::camera_calibration);
  EXPECT_EQ(sensor_channels("depth_image")[0].message, SensorMessage::raw_image);
  EXPECT_EQ(sensor_channels("laser_scan")[0].message, SensorMessage::laser_scan);
  EXPECT_EQ(sensor_channels("odometry")[0].message, SensorMessage::odometry);
  EXPECT_EQ(sensor_channels("joint_state")[0].message, SensorMessage::joint_states);
  // no Foxglove schema fits them: they go as JSON, plottable
  for (const char* kind : {"pose", "imu", "proximity", "odometry_raw", "sensors"})
    EXPECT_TRUE(sensor_channels(kind).empty()) << kind;
  EXPECT_STREQ(schema_name(SensorMessage::laser_scan), "foxglove.LaserScan");
  EXPECT_EQ(sensor_schema(SensorMessage::odometry)["title"], "foxglove.Odometry");
}

TEST(FoxgloveSensors, AVideoCamerasImageIsItsPngAndItsIntrinsicsACalibration) {
  LaserArc arc;
  const SamplePtr sample = camera_sample("rgb8", std::vector<std::uint8_t>(6, 9));
  const json image =
      parse(sensor_message(SensorMessage::compressed_image, *sample, "rover.camera", arc));
  EXPECT_EQ(image["format"], "png");
  EXPECT_EQ(image["data"], "iVBORw0KGgo=");
  EXPECT_EQ(image["frame_id"], "rover.camera");
  EXPECT_EQ(image["timestamp"], (json{{"sec", 1}, {"nsec", 500000000}}));
  const json calibration =
      parse(sensor_message(SensorMessage::camera_calibration, *sample, "rover.camera", arc));
  EXPECT_EQ(calibration["width"], 2);
  EXPECT_EQ(calibration["height"], 1);
  EXPECT_EQ(calibration["K"], (json{100, 0, 1, 0, 100, 0.5, 0, 0, 1}));
  EXPECT_EQ(calibration["P"], (json{100, 0, 1, 0, 0, 100, 0.5, 0, 0, 0, 1, 0}));
  EXPECT_EQ(calibration["R"], (json{1, 0, 0, 0, 1, 0, 0, 0, 1}));
  EXPECT_EQ(calibration["distortion_model"], "plumb_bob");
}

TEST(FoxgloveSensors, ADepthImageGoesRawInMetres) {
  LaserArc arc;
  std::vector<std::uint8_t> bytes(8);
  const float metres[2] = {1.25f, 0.0f};
  std::memcpy(bytes.data(), metres, sizeof metres);
  const SamplePtr sample = camera_sample("32FC1", bytes);
  const json image = parse(sensor_message(SensorMessage::raw_image, *sample, "rover.depth", arc));
  EXPECT_EQ(image["encoding"], "32FC1");
  EXPECT_EQ(image["step"], 8);
  EXPECT_EQ(image["width"], 2);
  EXPECT_EQ(base64_decode(image["data"].get<std::string>()), bytes);
}

TEST(FoxgloveSensors, ALaserScansArcIsReadFromItsHits) {
  // MORSE's arc: 5 rays from -60° every 30°; rays 1 and 3 hit, the others miss
  const double degree = M_PI / 180;
  json points = json::array(), ranges = json::array();
  for (int i = 0; i < 5; ++i) {
    const double angle = (-60 + 30 * i) * degree;
    const bool hit = i == 1 || i == 3;
    points.push_back(hit ? json{2 * std::cos(angle), 2 * std::sin(angle), 0} : json{0, 0, 0});
    ranges.push_back(hit ? 2.0 : 10.0);
  }
  const StreamSample sample(1, 0.25, json{{"range_list", ranges}, {"point_list", points}});
  LaserArc arc;
  const json scan = parse(sensor_message(SensorMessage::laser_scan, sample, "rover.laser", arc));
  EXPECT_NEAR(scan["start_angle"].get<double>(), -60 * degree, 1e-12);
  EXPECT_NEAR(scan["end_angle"].get<double>(), 60 * degree, 1e-12);
  EXPECT_EQ(scan["ranges"], ranges);
  EXPECT_EQ(scan["frame_id"], "rover.laser");
  EXPECT_EQ(scan["pose"]["orientation"]["w"], 1);
  // a scan that sees one thing only keeps the arc read before
  json one = points;
  one[3] = json{0, 0, 0};
  const StreamSample blind(2, 0.5, json{{"range_list", ranges}, {"point_list", one}});
  const json again = parse(sensor_message(SensorMessage::laser_scan, blind, "rover.laser", arc));
  EXPECT_NEAR(again["start_angle"].get<double>(), -60 * degree, 1e-12);
}

TEST(FoxgloveSensors, AFullTurnsBearingsWrapAndAScanWithNoArcYetIsCentred) {
  // 360° every 90°: 4 rays from -180°; atan2 says +180° for the first
  json points = json::array();
  for (int i = 0; i < 4; ++i) {
    const double angle = (-180 + 90 * i) * M_PI / 180;
    points.push_back(json{std::cos(angle), std::sin(angle), 0});
  }
  LaserArc arc;
  ASSERT_TRUE(arc.read(points, 4));
  EXPECT_NEAR(arc.step, M_PI / 2, 1e-12);
  EXPECT_NEAR(std::abs(arc.start), M_PI, 1e-12);
  // nothing hit, nothing read before: 1° apart, centred
  LaserArc fresh;
  const StreamSample misses(
      1, 0, json{{"range_list", {5, 5, 5}}, {"point_list", {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}}}});
  const json scan = parse(sensor_message(SensorMessage::laser_scan, misses, "l", fresh));
  EXPECT_NEAR(scan["start_angle"].get<double>(), -M_PI / 180, 1e-12);
  EXPECT_NEAR(scan["end_angle"].get<double>(), M_PI / 180, 1e-12);
}

TEST(FoxgloveSensors, AnOdometrysAnglesBecomeAQuaternion) {
  const StreamSample sample(1, 2,
                            json{{"x", 1},
                                 {"y", 2},
                                 {"z", 0},
                                 {"roll", 0},
                                 {"pitch", 0},
                                 {"yaw", M_PI / 2},
                                 {"vx", 0.5},
                                 {"vy", 0},
                                 {"vz", 0},
                                 {"wx", 0},
                                 {"wy", 0},
                                 {"wz", 0.1}});
  LaserArc arc;
  const json odometry =
      parse(sensor_message(SensorMessage::odometry, sample, "rover.odometry", arc));
  EXPECT_EQ(odometry["frame_id"], "rover.odometry/origin");
  EXPECT_EQ(odometry["body_frame_id"], "rover.odometry");
  EXPECT_EQ(odometry["pose"]["position"], (json{{"x", 1}, {"y", 2}, {"z", 0}}));
  const json& q = odometry["pose"]["orientation"];
  EXPECT_NEAR(q["w"].get<double>(), std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(q["z"].get<double>(), std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(q["x"].get<double>(), 0, 1e-12);
  EXPECT_EQ(odometry["linear_velocity"]["x"], 0.5);
  EXPECT_EQ(odometry["angular_velocity"]["z"], 0.1);
}

TEST(FoxgloveSensors, JointsAreNamedAndTheTimestampIsNoJoint) {
  const StreamSample sample(1, 3, json{{"shoulder", 0.5}, {"elbow", -1}, {"timestamp", 3}});
  LaserArc arc;
  const json states = parse(sensor_message(SensorMessage::joint_states, sample, "arm", arc));
  ASSERT_EQ(states["joints"].size(), 2u);
  EXPECT_EQ(states["joints"][0], (json{{"name", "elbow"}, {"position", -1}}));
  EXPECT_EQ(states["joints"][1], (json{{"name", "shoulder"}, {"position", 0.5}}));
}

TEST(FoxgloveSensors, ASampleOfAnotherShapeMakesNoMessage) {
  LaserArc arc;
  const StreamSample text(1, 0, json("not an object"));
  const StreamSample no_ranges(1, 0, json{{"point_list", json::array()}});
  const StreamSample bad_range(1, 0, json{{"range_list", {1, "far"}}});
  const StreamSample half_odometry(1, 0, json{{"x", 1}});
  const StreamSample json_image(1, 0, json{{"image", "abc"}});  // no pixels: no raw image
  for (SensorMessage m : {SensorMessage::compressed_image, SensorMessage::laser_scan,
                          SensorMessage::odometry, SensorMessage::joint_states})
    EXPECT_EQ(sensor_message(m, text, "f", arc), "") << schema_name(m);
  EXPECT_EQ(sensor_message(SensorMessage::laser_scan, no_ranges, "f", arc), "");
  EXPECT_EQ(sensor_message(SensorMessage::laser_scan, bad_range, "f", arc), "");
  EXPECT_EQ(sensor_message(SensorMessage::odometry, half_odometry, "f", arc), "");
  EXPECT_EQ(sensor_message(SensorMessage::raw_image, json_image, "f", arc), "");
  EXPECT_EQ(sensor_message(SensorMessage::camera_calibration, json_image, "f", arc), "");
}

TEST(FoxgloveSensors, ALogLineKeepsItsLevelAndText) {
  const json line = parse(log_message(4.25, log::Level::warning, "robot: a wheel slips"));
  EXPECT_EQ(line["level"], 3);
  EXPECT_EQ(line["message"], "robot: a wheel slips");
  EXPECT_EQ(line["name"], "simgate");
  EXPECT_EQ(line["timestamp"], (json{{"sec", 4}, {"nsec", 250000000}}));
  EXPECT_EQ(parse(log_message(0, log::Level::debug, ""))["level"], 1);
  EXPECT_EQ(parse(log_message(0, log::Level::error, ""))["level"], 4);
}

}  // namespace
}  // namespace simgate::foxglove
