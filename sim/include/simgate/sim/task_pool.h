// simgate/sim/task_pool.h — a fixed set of threads that runs batches of tasks
// (simulation step_many's worlds, worlds.h).
//
// A batch is `count` tasks, task(0) ... task(count - 1), each run once on one of the pool's
// threads, and an optional `then` run once after all of them have returned, on the thread
// that ran the last. submit() queues it and returns at once: the caller does not wait, so a
// transport's thread that submits a batch goes on reading and answering while the pool
// works. Batches are taken in the order they came (a batch's tasks are all taken before the
// next batch's first), several may run at once when one's last tasks leave threads free.
//
//   TaskPool pool(2);
//   pool.submit(worlds.size(), [&](std::size_t i) { step(worlds[i]); }, [&] { reply(); });
//
// Tasks and `then` must not throw. A task that waits for another task must wait only for one
// of an earlier batch (those are taken first: no deadlock).
#ifndef SIMGATE_SIM_TASK_POOL_H_
#define SIMGATE_SIM_TASK_POOL_H_

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace simgate::sim {

class TaskPool {
 public:
  // `threads` threads (at least one).
  explicit TaskPool(std::size_t threads);
  // Runs what is queued to its end, then joins the threads.
  ~TaskPool();
  TaskPool(const TaskPool&) = delete;
  TaskPool& operator=(const TaskPool&) = delete;

  // Queues a batch (see above); returns at once. A batch of no task runs `then` at once, on
  // the caller's thread.
  void submit(std::size_t count, std::function<void(std::size_t)> task,
              std::function<void()> then = {});
  // Returns when every batch submitted so far has ended (its `then` returned).
  void wait_idle();
  std::size_t threads() const { return threads_.size(); }

 private:
  struct Batch {
    std::function<void(std::size_t)> task;
    std::function<void()> then;
    std::size_t count = 0;
    std::size_t next = 0;        // the next task to take
    std::size_t unfinished = 0;  // tasks not yet returned
  };

  void work();

  std::mutex mutex_;
  std::condition_variable work_;              // a batch came, or stop
  std::condition_variable idle_;              // the last batch under way ended
  std::deque<std::shared_ptr<Batch>> queue_;  // batches with tasks left to take, in order
  std::size_t batches_ = 0;                   // batches submitted and not yet ended
  bool stop_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_TASK_POOL_H_
