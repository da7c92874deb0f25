#include "simgate/foxglove/sensors.h"

#include <cmath>
#include <cstdint>

#include "simgate/core/base64.h"
#include "simgate/foxglove/protocol.h"

#include "parts.h"

namespace simgate::foxglove {

namespace {

using parts::array_of;
using parts::numbers_schema;
using parts::pose_schema;
using parts::time_schema;
using parts::timestamp;
using parts::vector3;

json string_schema() { return json{{"type", "string"}}; }
json integer_schema() { return json{{"type", "integer"}, {"minimum", 0}}; }
json number_schema() { return json{{"type", "number"}}; }
json numbers_array(std::size_t count) {
  json a = array_of(number_schema());
  a["minItems"] = count;
  a["maxItems"] = count;
  return a;
}

// A message schema: its title, what simgate fills it from, its properties, all required
// but `optional`.
json message_schema(SensorMessage message, const char* description, json properties,
                    std::initializer_list<const char*> optional = {}) {
  json required = json::array();
  for (auto it = properties.begin(); it != properties.end(); ++it) {
    bool is_optional = false;
    for (const char* o : optional) is_optional = is_optional || it.key() == o;
    if (!is_optional) required.push_back(it.key());
  }
  return json{{"title", schema_name(message)},
              {"description", description},
              {"type", "object"},
              {"properties", std::move(properties)},
              {"required", std::move(required)}};
}

// Roll, pitch, yaw (rad, about x, then y, then z: R = Rz(yaw) Ry(pitch) Rx(roll)) as a
// quaternion.
json quaternion_of(double roll, double pitch, double yaw) {
  const double cr = std::cos(roll / 2), sr = std::sin(roll / 2);
  const double cp = std::cos(pitch / 2), sp = std::sin(pitch / 2);
  const double cy = std::cos(yaw / 2), sy = std::sin(yaw / 2);
  return parts::quaternion(cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                           cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy);
}

// The payload of a camera's sample (its pixels and their description), or null.
const StreamPayload* image_payload(const StreamSample& sample) {
  const StreamPayload* p = sample.payload();
  return p && p->content == "image" && p->description.is_object() ? p : nullptr;
}

std::string compressed_image(const StreamSample& sample, const std::string& frame) {
  const json& record = sample.data();
  if (!record.is_object()) return {};
  const auto image = record.find("image");
  if (image == record.end() || !image->is_string()) return {};
  return dump(json{{"timestamp", timestamp(sample.time())},
                   {"frame_id", frame},
                   {"data", *image},
                   {"format", "png"}});
}

std::string raw_image(const StreamSample& sample, const std::string& frame) {
  const StreamPayload* p = image_payload(sample);
  if (!p) return {};
  const json& d = p->description;
  return dump(json{{"timestamp", timestamp(sample.time())},
                   {"frame_id", frame},
                   {"width", d.value("width", 0)},
                   {"height", d.value("height", 0)},
                   {"encoding", d.value("encoding", "")},
                   {"step", d.value("step", 0)},
                   {"data", base64_encode(p->bytes)}});
}

std::string camera_calibration(const StreamSample& sample, const std::string& frame) {
  const StreamPayload* p = image_payload(sample);
  if (!p) return {};
  const json& d = p->description;
  const json k = d.value("intrinsic_matrix", json::array());
  const auto element = [&](int row, int column) {
    return k.is_array() && row < static_cast<int>(k.size()) ? parts::at(k[row], column) : 0.0;
  };
  json intrinsic = json::array(), projection = json::array();
  for (int row = 0; row < 3; ++row) {
    for (int column = 0; column < 3; ++column) {
      intrinsic.push_back(element(row, column));
      projection.push_back(element(row, column));
    }
    projection.push_back(0.0);
  }
  return dump(json{{"timestamp", timestamp(sample.time())},
                   {"frame_id", frame},
                   {"width", d.value("width", 0)},
                   {"height", d.value("height", 0)},
                   {"distortion_model", "plumb_bob"},
                   {"D", json::array({0.0, 0.0, 0.0, 0.0, 0.0})},
                   {"K", std::move(intrinsic)},
                   {"R", json::array({1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0})},
                   {"P", std::move(projection)}});
}

std::string laser_scan(const StreamSample& sample, const std::string& frame, LaserArc& arc) {
  const json& d = sample.data();
  if (!d.is_object()) return {};
  const auto ranges = d.find("range_list");
  if (ranges == d.end() || !ranges->is_array() || ranges->empty()) return {};
  for (const json& r : *ranges)
    if (!r.is_number()) return {};
  const auto points = d.find("point_list");
  if (points != d.end()) arc.read(*points, ranges->size());
  const double n = static_cast<double>(ranges->size());
  const auto [start, step] = arc.angles(ranges->size());
  return dump(json{{"timestamp", timestamp(sample.time())},
                   {"frame_id", frame},
                   {"pose", parts::identity_pose()},
                   {"start_angle", start},
                   {"end_angle", start + (n - 1) * step},
                   {"ranges", *ranges},
                   {"intensities", json::array()}});
}

std::string odometry(const StreamSample& sample, const std::string& frame) {
  static constexpr std::string_view k_keys[] = {"x",  "y",  "z",  "roll", "pitch", "yaw",
                                                "vx", "vy", "vz", "wx",   "wy",    "wz"};
  double v[std::size(k_keys)];
  try {
    sample.numbers(k_keys, v);
  } catch (const std::exception&) {
    return {};
  }
  return dump(json{
      {"timestamp", timestamp(sample.time())},
      {"frame_id", frame + "/origin"},
      {"body_frame_id", frame},
      {"pose",
       {{"position", vector3(v[0], v[1], v[2])}, {"orientation", quaternion_of(v[3], v[4], v[5])}}},
      {"linear_velocity", vector3(v[6], v[7], v[8])},
      {"angular_velocity", vector3(v[9], v[10], v[11])}});
}

std::string joint_states(const StreamSample& sample) {
  const json& d = sample.data();
  if (!d.is_object()) return {};
  json joints = json::array();
  for (auto it = d.begin(); it != d.end(); ++it)
    if (it.key() != "timestamp" && it->is_number())
      joints.push_back(json{{"name", it.key()}, {"position", it->get<double>()}});
  return dump(json{{"timestamp", timestamp(sample.time())}, {"joints", std::move(joints)}});
}

}  // namespace

std::vector<SensorChannel> sensor_channels(std::string_view kind) {
  if (kind == "image")
    return {{"", SensorMessage::compressed_image},
            {"/calibration", SensorMessage::camera_calibration}};
  if (kind == "depth_image")
    return {{"", SensorMessage::raw_image}, {"/calibration", SensorMessage::camera_calibration}};
  if (kind == "laser_scan") return {{"", SensorMessage::laser_scan}};
  if (kind == "odometry") return {{"", SensorMessage::odometry}};
  if (kind == "joint_state") return {{"", SensorMessage::joint_states}};
  return {};
}

const char* schema_name(SensorMessage message) {
  switch (message) {
    case SensorMessage::compressed_image: return "foxglove.CompressedImage";
    case SensorMessage::raw_image: return "foxglove.RawImage";
    case SensorMessage::camera_calibration: return "foxglove.CameraCalibration";
    case SensorMessage::laser_scan: return "foxglove.LaserScan";
    case SensorMessage::odometry: return "foxglove.Odometry";
    case SensorMessage::joint_states: return "foxglove.JointStates";
    case SensorMessage::log: return "foxglove.Log";
  }
  return "";
}

json sensor_schema(SensorMessage message) {
  const json base64{{"type", "string"}, {"contentEncoding", "base64"}};
  switch (message) {
    case SensorMessage::compressed_image:
      return message_schema(message, "A video_camera's image, PNG (simgate: its JSON record's)",
                            {{"timestamp", time_schema()},
                             {"frame_id", string_schema()},
                             {"data", base64},
                             {"format", string_schema()}});
    case SensorMessage::raw_image:
      return message_schema(message,
                            "A depth_camera's image: 32FC1, metres along the optical axis, 0 "
                            "where nothing is within reach (simgate: its raw pixels)",
                            {{"timestamp", time_schema()},
                             {"frame_id", string_schema()},
                             {"width", integer_schema()},
                             {"height", integer_schema()},
                             {"encoding", string_schema()},
                             {"step", integer_schema()},
                             {"data", base64}});
    case SensorMessage::camera_calibration:
      return message_schema(message, "A camera's intrinsics (a pinhole: no distortion)",
                            {{"timestamp", time_schema()},
                             {"frame_id", string_schema()},
                             {"width", integer_schema()},
                             {"height", integer_schema()},
                             {"distortion_model", string_schema()},
                             {"D", array_of(number_schema())},
                             {"K", numbers_array(9)},
                             {"R", numbers_array(9)},
                             {"P", numbers_array(12)}});
    case SensorMessage::laser_scan:
      return message_schema(message,
                            "A laser_scanner's scan: one range per ray (laser_range for a miss)",
                            {{"timestamp", time_schema()},
                             {"frame_id", string_schema()},
                             {"pose", pose_schema()},
                             {"start_angle", number_schema()},
                             {"end_angle", number_schema()},
                             {"ranges", array_of(number_schema())},
                             {"intensities", array_of(number_schema())}});
    case SensorMessage::odometry:
      return message_schema(
          message,
          "An odometry's integrated pose (in its frame at the start) and velocities (in its "
          "frame)",
          {{"timestamp", time_schema()},
           {"frame_id", string_schema()},
           {"body_frame_id", string_schema()},
           {"pose", pose_schema()},
           {"linear_velocity", numbers_schema({"x", "y", "z"})},
           {"angular_velocity", numbers_schema({"x", "y", "z"})}},
          {"linear_velocity", "angular_velocity"});
    case SensorMessage::joint_states: {
      const json joint{{"type", "object"},
                       {"properties", {{"name", string_schema()}, {"position", number_schema()}}},
                       {"required", {"name"}}};
      return message_schema(message, "An armature's joints: radians (hinge) or metres (slide)",
                            {{"timestamp", time_schema()}, {"joints", array_of(joint)}});
    }
    case SensorMessage::log:
      return message_schema(message, "simgate's log lines",
                            {{"timestamp", time_schema()},
                             {"level", {{"type", "integer"}, {"minimum", 0}, {"maximum", 5}}},
                             {"message", string_schema()},
                             {"name", string_schema()},
                             {"file", string_schema()},
                             {"line", integer_schema()}});
  }
  return json::object();
}

std::string sensor_message(SensorMessage message, const StreamSample& sample,
                           const std::string& frame, LaserArc& arc) {
  switch (message) {
    case SensorMessage::compressed_image: return compressed_image(sample, frame);
    case SensorMessage::raw_image: return raw_image(sample, frame);
    case SensorMessage::camera_calibration: return camera_calibration(sample, frame);
    case SensorMessage::laser_scan: return laser_scan(sample, frame, arc);
    case SensorMessage::odometry: return odometry(sample, frame);
    case SensorMessage::joint_states: return joint_states(sample);
    case SensorMessage::log: return {};
  }
  return {};
}

std::string log_message(double time, log::Level level, std::string_view text) {
  int foxglove_level = 0;
  switch (level) {
    case log::Level::trace:
    case log::Level::debug: foxglove_level = 1; break;
    case log::Level::info: foxglove_level = 2; break;
    case log::Level::warning: foxglove_level = 3; break;
    case log::Level::error: foxglove_level = 4; break;
    case log::Level::off: break;
  }
  return dump(json{{"timestamp", timestamp(time)},
                   {"level", foxglove_level},
                   {"message", std::string(text)},
                   {"name", "simgate"},
                   {"file", ""},
                   {"line", 0}});
}

}  // namespace simgate::foxglove
