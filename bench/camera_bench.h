// camera_bench.h — issue #22's camera targets for simgate_bench_sim (camera_bench.cc says how):
//   --mode camera_fps  frames/s of simgate's camera path (the Renderer) against a bare
//                      mjv_updateScene + mjr_render + mjr_readPixels loop on the same kind
//                      of EGL context (GlContext), per image size, RGB and depth;
//   --mode camera_rtf  the real-time factor of a gateway (config/rover.json) while a JSON-RPC
//                      client subscribes to its 10 Hz camera stream, against the same gateway
//                      with no subscriber.
// Both print {"skipped": why} instead of figures when no EGL context can be made.
#ifndef SIMGATE_BENCH_CAMERA_BENCH_H_
#define SIMGATE_BENCH_CAMERA_BENCH_H_

#include <string>
#include <vector>

#include "bench_util.h"

namespace simgate::bench {

struct CameraFpsOptions {
  std::string mjcf;            // the scene
  std::string site = "laser";  // the camera's frame (config/rover.json's)
  std::vector<std::pair<int, int>> sizes = {{320, 240}, {640, 480}};
  int frames = 200;    // per side, per size and kind, at most
  double seconds = 5;  // per side, per size and kind, at most
  int batch = 10;      // frames of one side in a row
  bool depth = true;   // the depth rows too
};

// The frame-rate comparison. Throws on failure (not on a missing GL: then {"skipped": ...}).
json run_camera_fps(const CameraFpsOptions& options);

// The real-time-factor comparison: the deployment `config` (its transports moved to
// ephemeral loopback ports), `seconds` of wall time without and then with a JSON-RPC
// subscriber to `camera`'s stream.
json run_camera_rtf(const std::string& config, const std::string& camera, double seconds);

}  // namespace simgate::bench

#endif  // SIMGATE_BENCH_CAMERA_BENCH_H_
