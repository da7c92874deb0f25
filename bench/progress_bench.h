// progress_bench.h — simgate_bench_sim --mode progress (issue #20): the real-time factor of
// the gateway's loop while `calls` JSON-RPC calls get progress reports at 1 kHz each,
// against rounds of the same calls without progress (progress_bench.cc says how).
#ifndef SIMGATE_BENCH_PROGRESS_BENCH_H_
#define SIMGATE_BENCH_PROGRESS_BENCH_H_

#include <string>

#include "bench_util.h"

namespace simgate::bench {

// Runs alternating rounds (without / with progress) of `calls` concurrent calls, each
// lasting `round_s` simulated seconds, for `duration_s` seconds (at least one of each) on
// the scene `mjcf`. Returns the results as one JSON object. Throws on failure.
json run_progress(const std::string& mjcf, double duration_s, double round_s, int calls);

}  // namespace simgate::bench

#endif  // SIMGATE_BENCH_PROGRESS_BENCH_H_
