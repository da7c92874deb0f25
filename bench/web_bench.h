// web_bench.h — issue #23's browser target for simgate_bench_sim (web_bench.cc says how):
//   --mode web_poses  the real-time factor of a gateway (config/demo.json, the web app's
//                     deployment) while --calls WebSocket clients (20), as many browser
//                     pages, each receive the simulation's body poses at --frequency (60 Hz),
//                     against the same gateway with no client.
#ifndef SIMGATE_BENCH_WEB_BENCH_H_
#define SIMGATE_BENCH_WEB_BENCH_H_

#include <string>

#include "bench_util.h"

namespace simgate::bench {

// The deployment `config` (its transports moved to ephemeral loopback ports; its `simulation`
// stream on the websocket transport at `frequency`), `seconds` of wall time without clients,
// then `seconds` with `clients` WebSocket clients subscribed to the `simulation` stream, each
// reading every sample. Throws on failure.
json run_web_poses(const std::string& config, int clients, double frequency, double seconds);

}  // namespace simgate::bench

#endif  // SIMGATE_BENCH_WEB_BENCH_H_
