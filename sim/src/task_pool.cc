#include "simgate/sim/task_pool.h"

#include <algorithm>

namespace simgate::sim {

TaskPool::TaskPool(std::size_t threads) {
  for (std::size_t i = 0; i < std::max<std::size_t>(threads, 1); ++i)
    threads_.emplace_back([this] { work(); });
}

TaskPool::~TaskPool() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  work_.notify_all();
  for (auto& t : threads_) t.join();
}

void TaskPool::submit(std::size_t count, std::function<void(std::size_t)> task,
                      std::function<void()> then) {
  if (count == 0) {
    if (then) then();
    return;
  }
  auto batch = std::make_shared<Batch>();
  batch->task = std::move(task);
  batch->then = std::move(then);
  batch->count = batch->unfinished = count;
  {
    std::lock_guard lock(mutex_);
    queue_.push_back(std::move(batch));
    ++batches_;
  }
  if (count == 1)
    work_.notify_one();
  else
    work_.notify_all();
}

void TaskPool::wait_idle() {
  std::unique_lock lock(mutex_);
  idle_.wait(lock, [&] { return batches_ == 0; });
}

void TaskPool::work() {
  std::unique_lock lock(mutex_);
  for (;;) {
    work_.wait(lock, [&] { return stop_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stopping, and nothing is left to take
    std::shared_ptr<Batch> batch = queue_.front();
    const std::size_t i = batch->next++;
    if (batch->next == batch->count) queue_.pop_front();
    lock.unlock();
    batch->task(i);
    lock.lock();
    if (--batch->unfinished != 0) continue;
    lock.unlock();
    if (batch->then) batch->then();
    batch.reset();  // what the batch's functions hold goes before the batch is said to end
    lock.lock();
    if (--batches_ == 0) idle_.notify_all();
  }
}

}  // namespace simgate::sim
