// snapshot_bench.h — issue #19's targets for simgate_bench_sim (snapshot_bench.cc says how):
//   --mode snapshot  `simulation save_state` and `restore_state` against mj_copyData
//   --mode spawn     `simulation spawn_entity` and `delete_entity` of one free body against
//                    the edit alone (with_entity) and a bare mj_loadXML of the scene
#ifndef SIMGATE_BENCH_SNAPSHOT_BENCH_H_
#define SIMGATE_BENCH_SNAPSHOT_BENCH_H_

#include <string>

#include "bench_util.h"

namespace simgate::bench {

// Alternating batches of save_state, restore_state and mj_copyData on the scene `mjcf` for
// `duration_s` seconds (at least one of each). Throws on failure.
json run_snapshot(const std::string& mjcf, double duration_s);

// Rounds of spawn_entity, delete_entity, with_entity and mj_loadXML on the scene `mjcf` for
// `duration` seconds (at least 20). Throws on failure.
json run_spawn(const std::string& mjcf, double duration);

}  // namespace simgate::bench

#endif  // SIMGATE_BENCH_SNAPSHOT_BENCH_H_
