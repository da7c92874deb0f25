// laser_bench.h — issue #18's laser_scanner target for simgate_bench_sim (laser_bench.cc says
// how):
//   --mode laser  a 360-ray scan in a furnished room, the component's update against a bare
//                 loop of the same mj_ray calls
#ifndef SIMGATE_BENCH_LASER_BENCH_H_
#define SIMGATE_BENCH_LASER_BENCH_H_

#include "bench_util.h"

namespace simgate::bench {

// Alternating batches of the laser_scanner's scan, the bare mj_ray loop and get_local_data
// for `duration_s` seconds (at least 5 of each) on a scene built in. Throws on failure (also
// when the two loops read different ranges).
json run_laser(double duration_s);

}  // namespace simgate::bench

#endif  // SIMGATE_BENCH_LASER_BENCH_H_
