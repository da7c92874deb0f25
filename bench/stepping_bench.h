// stepping_bench.h — simgate_bench_sim's stepping modes (stepping_bench.cc says how):
//   --mode bare      mj_step in a tight loop on --mjcf: the physics alone (--copies worlds
//                    stepped by --threads threads)
//   --mode sleep     a loop with no work sleeping until each period: the timer's jitter
//   --mode gateway   the Gateway of --config with a step probe: steps/s, real-time factor,
//                    overruns and the jitter of the step period
//   --mode humanoid  issue #18's stepping target: the gateway's loop on Debian's humanoid
//                    against bare mj_step calls, step for step
#ifndef SIMGATE_BENCH_STEPPING_BENCH_H_
#define SIMGATE_BENCH_STEPPING_BENCH_H_

#include <string>

#include "bench_util.h"

namespace simgate::bench {

// `copies` worlds of the model `mjcf`, world i stepped by thread i % `threads`, for
// `duration_s` seconds. Throws on failure.
json run_bare(const std::string& mjcf, double duration_s, int copies, int threads);

// Sleeps until each period of the MJCF's timestep, scheduled as the gateway's loop schedules
// its steps, for `duration_s` seconds. Throws on failure.
json run_sleep(const std::string& mjcf, double duration_s);

// The Gateway of the deployment file `config` at `factor` (0 = as fast as possible) for
// `duration_s` seconds, or until standard input closes with `until_stdin`; prints its
// endpoints on stdout once serving. A non-empty `record_dir` lets clients record into it.
// Throws on failure.
json run_gateway(const std::string& config, double factor, double duration_s, bool until_stdin,
                 const std::string& record_dir);

// Alternating rounds of the gateway's loop and a bare loop on the humanoid `mjcf_arg` (empty:
// Debian's), as shipped and with 40 sensor values, for `duration_s` seconds. Throws on
// failure.
json run_humanoid(const std::string& mjcf_arg, double duration_s);

}  // namespace simgate::bench

#endif  // SIMGATE_BENCH_STEPPING_BENCH_H_
