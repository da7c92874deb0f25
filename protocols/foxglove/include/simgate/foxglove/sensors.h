// simgate/foxglove/sensors.h — sensors' stream samples in Foxglove's message schemas, so that
// Foxglove's panels show them as they show a ROS robot's: a video_camera's images as
// foxglove.CompressedImage (the PNG its JSON record holds) with foxglove.CameraCalibration, a
// depth_camera's as foxglove.RawImage (32FC1: metres, raw), a laser_scanner's scans as
// foxglove.LaserScan, an odometry's as foxglove.Odometry, an armature_pose's joints as
// foxglove.JointStates, and the log as foxglove.Log. The JSON Schemas are this project's
// writing of Foxglove's message definitions (foxglove/foxglove-sdk `schemas/`);
// tests/foxglove checks the messages against @foxglove/schemas' own. Shared by the foxglove
// transport and recorders.
//
// Frames: a sensor's frame is named after its component ("rover.laser"); an odometry's
// pose is in "<component>/origin", the sensor's frame where the odometry started.
//
// Threads: pure functions, any thread; a LaserArc (simgate/core/laser_arc.h) belongs to
// whoever converts one stream.
#ifndef SIMGATE_FOXGLOVE_SENSORS_H_
#define SIMGATE_FOXGLOVE_SENSORS_H_

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "simgate/core/laser_arc.h"
#include "simgate/core/log.h"
#include "simgate/core/status.h"
#include "simgate/core/streams.h"

namespace simgate::foxglove {

// The messages a stream can be carried as.
enum class SensorMessage {
  compressed_image,    // kind "image": the PNG of its record
  raw_image,           // kind "depth_image": the payload's pixels (32FC1)
  camera_calibration,  // kinds "image", "depth_image": the payload's intrinsics
  laser_scan,          // kind "laser_scan"
  odometry,            // kind "odometry" (the integrated level)
  joint_states,        // kind "joint_state"
  log,                 // not a stream: log lines (log_message)
};

// A channel a stream of some kind makes: its topic is the stream's with `suffix` appended.
struct SensorChannel {
  std::string_view suffix;  // "" (the stream's own topic) or "/calibration"
  SensorMessage message;
};
// The channels a stream of `kind` is carried on (empty: none of Foxglove's schemas fits it,
// it goes as the component's JSON).
std::vector<SensorChannel> sensor_channels(std::string_view kind);

// The schema's name ("foxglove.LaserScan") and its JSON Schema.
const char* schema_name(SensorMessage message);
json sensor_schema(SensorMessage message);

// `sample` (a stream of the message's kind) as that message (JSON text), its frame named
// `frame` ("rover.camera"); "" when the sample is not of that shape (logged by the caller).
// A laser scan reads and updates `arc` (simgate/core/laser_arc.h: where its rays point).
std::string sensor_message(SensorMessage message, const StreamSample& sample,
                           const std::string& frame, LaserArc& arc);

// A log line as foxglove.Log (JSON text) at simulated time `time`: level trace and debug ->
// DEBUG, info -> INFO, warning -> WARNING, error -> ERROR; name "simgate".
std::string log_message(double time, log::Level level, std::string_view text);

}  // namespace simgate::foxglove

#endif  // SIMGATE_FOXGLOVE_SENSORS_H_
