// sim::TaskPool (worlds.h): the pool `simulation step_many` steps worlds on. Every task of a
// batch runs exactly once, spread over the helpers and the caller, and run() returns only
// when all have returned; batches follow one another on the same threads.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <set>
#include <thread>
#include <vector>

#include "simgate/sim/worlds.h"

namespace simgate::sim {
namespace {

TEST(TaskPool, RunsEveryTaskOnceAndReturnsWhenAllHaveReturned) {
  for (const std::size_t helpers : {0u, 1u, 3u}) {
    TaskPool pool(helpers);
    EXPECT_EQ(pool.threads(), helpers);
    for (const std::size_t count : {0u, 1u, 2u, 7u, 64u}) {
      std::vector<std::atomic<int>> runs(count);
      std::atomic<int> finished{0};
      pool.run(count, [&](std::size_t i) {
        std::this_thread::sleep_for(std::chrono::microseconds(50));  // others take the rest
        runs[i].fetch_add(1);
        finished.fetch_add(1);
      });
      EXPECT_EQ(finished.load(), static_cast<int>(count)) << helpers << " helpers";
      for (std::size_t i = 0; i < count; ++i) EXPECT_EQ(runs[i].load(), 1) << i;
    }
  }
}

TEST(TaskPool, SpreadsABatchOverItsThreads) {
  TaskPool pool(1);
  std::mutex mutex;
  std::set<std::thread::id> seen;
  // each task waits until two threads have taken one: only the helper and the caller together
  // can finish the batch (bounded: a pool that used one thread would end the loop at its deadline)
  std::atomic<int> started{0};
  pool.run(2, [&](std::size_t) {
    {
      std::lock_guard lock(mutex);
      seen.insert(std::this_thread::get_id());
    }
    started.fetch_add(1);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (started.load() < 2 && std::chrono::steady_clock::now() < deadline)
      std::this_thread::yield();
  });
  EXPECT_EQ(seen.size(), 2u);
  EXPECT_TRUE(seen.contains(std::this_thread::get_id()));  // the caller works too
}

}  // namespace
}  // namespace simgate::sim
