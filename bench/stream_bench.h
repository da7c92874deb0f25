// stream_bench.h — simgate_bench_sim --mode streams (issue #21): the real-time factor and CPU
// of the gateway while `components` components stream at 100 Hz on every transport, the
// latency from a step's end to a socket subscriber's read, and the sync round trip of the
// same run (stream_bench.cc says how).
#ifndef SIMGATE_BENCH_STREAM_BENCH_H_
#define SIMGATE_BENCH_STREAM_BENCH_H_

#include <string>

#include "bench_util.h"

namespace simgate::bench {

// A baseline phase (no streams) then a streams phase, `duration_s` seconds each, on the
// scene `mjcf`; `calls` sync calls timed at the end; `dds`: the DDS transport streams too
// (its plugin is built). Returns the results as one JSON object. Throws on failure.
json run_streams(const std::string& mjcf, double duration_s, int components, int calls, bool dds);

}  // namespace simgate::bench

#endif  // SIMGATE_BENCH_STREAM_BENCH_H_
