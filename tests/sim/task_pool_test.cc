// sim::TaskPool (task_pool.h): the pool `simulation step_many` steps worlds on. Every task of
// a batch runs exactly once on the pool's threads, then the batch's `then` once; submit()
// does not wait; batches are taken in the order they came.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <set>
#include <thread>
#include <vector>

#include "simgate/sim/task_pool.h"

namespace simgate::sim {
namespace {

TEST(TaskPool, RunsEveryTaskOnceThenItsThenOnce) {
  for (const std::size_t threads : {1u, 2u, 4u}) {
    TaskPool pool(threads);
    EXPECT_EQ(pool.threads(), threads);
    for (const std::size_t count : {0u, 1u, 2u, 7u, 64u}) {
      std::vector<std::atomic<int>> runs(count);
      std::atomic<int> finished{0}, thens{0}, finished_at_then{-1};
      pool.submit(
          count,
          [&](std::size_t i) {
            std::this_thread::sleep_for(std::chrono::microseconds(50));  // others take the rest
            runs[i].fetch_add(1);
            finished.fetch_add(1);
          },
          [&] {
            finished_at_then = finished.load();
            thens.fetch_add(1);
          });
      pool.wait_idle();
      EXPECT_EQ(finished.load(), static_cast<int>(count)) << threads << " threads";
      EXPECT_EQ(thens.load(), 1);
      EXPECT_EQ(finished_at_then.load(), static_cast<int>(count));  // after every task
      for (std::size_t i = 0; i < count; ++i) EXPECT_EQ(runs[i].load(), 1) << i;
    }
  }
}

TEST(TaskPool, SubmitReturnsBeforeTheTasksRunAndSpreadsThemOverItsThreads) {
  TaskPool pool(2);
  std::mutex mutex;
  std::set<std::thread::id> seen;
  std::atomic<bool> release{false};
  std::atomic<int> started{0}, ended{0};
  // each task waits until both have started: only two threads together can finish the batch
  // (bounded: a pool that used one thread would end the wait at its deadline)
  pool.submit(2, [&](std::size_t) {
    {
      std::lock_guard lock(mutex);
      seen.insert(std::this_thread::get_id());
    }
    started.fetch_add(1);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while ((started.load() < 2 || !release.load()) && std::chrono::steady_clock::now() < deadline)
      std::this_thread::yield();
    ended.fetch_add(1);
  });
  EXPECT_EQ(ended.load(), 0);  // submit() returned while the tasks wait for `release`
  release = true;
  pool.wait_idle();
  EXPECT_EQ(seen.size(), 2u);
  EXPECT_FALSE(seen.contains(std::this_thread::get_id()));  // the caller does not step
}

TEST(TaskPool, BatchesAreTakenInTheOrderTheyCame) {
  TaskPool pool(1);
  std::vector<int> order;  // one thread: no lock needed
  for (int batch = 0; batch < 5; ++batch)
    pool.submit(
        3, [&order, batch](std::size_t i) { order.push_back(batch * 10 + static_cast<int>(i)); });
  pool.wait_idle();
  EXPECT_EQ(order, (std::vector<int>{0, 1, 2, 10, 11, 12, 20, 21, 22, 30, 31, 32, 40, 41, 42}));
}

TEST(TaskPool, ItsDestructorRunsWhatIsQueued) {
  std::atomic<int> runs{0};
  {
    TaskPool pool(1);
    for (int batch = 0; batch < 4; ++batch) pool.submit(8, [&](std::size_t) { runs.fetch_add(1); });
  }
  EXPECT_EQ(runs.load(), 32);
}

}  // namespace
}  // namespace simgate::sim
