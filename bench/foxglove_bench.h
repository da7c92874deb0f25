// foxglove_bench.h — issue #38's Foxglove target for simgate_bench_sim (foxglove_bench.cc says
// how):
//   --mode foxglove_rtf  the real-time factor of a gateway serving --mjcf
//                        (bench/pendulums50.xml: 50 moving bodies and a camera) on the foxglove
//                        transport while --calls Foxglove clients (4) each receive /tf at
//                        --frequency (60 Hz) and the camera's 640x480 images at 10 Hz, against
//                        the same gateway with no client.
#ifndef SIMGATE_BENCH_FOXGLOVE_BENCH_H_
#define SIMGATE_BENCH_FOXGLOVE_BENCH_H_

#include <string>

#include "bench_util.h"

namespace simgate::bench {

// The scene `mjcf` (its body "rig" holding a video_camera of its MJCF camera "overview") on
// the foxglove transport at an ephemeral loopback port, `seconds` of wall time without
// clients, then `seconds` with `clients` Foxglove clients subscribed to /tf (the simulation's
// body poses at `frequency`) and to the camera's images, each reading every message. Throws
// on failure.
json run_foxglove_rtf(const std::string& mjcf, int clients, double frequency, double seconds);

}  // namespace simgate::bench

#endif  // SIMGATE_BENCH_FOXGLOVE_BENCH_H_
