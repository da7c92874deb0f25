// The hand-off of outcomes to a transport's own thread (RequestManager::
// deliver_on_this_thread): outcomes reach on_service_completion on that thread only, in the
// order they were produced, with one wake per burst; answers a transport makes itself
// (answer_in_order, complete_request) keep their place among them.
#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <future>
#include <mutex>
#include <thread>
#include <vector>

#include "simgate/core/component.h"
#include "simgate/core/request_manager.h"

namespace simgate {
namespace {

// A transport with an I/O thread: a task queue standing in for an io_context.
class ThreadedManager : public RequestManager {
 public:
  ThreadedManager() : RequestManager("Threaded service manager") {
    register_service("c", [](int x) { return x; }, "echo", {"x"});
    register_async_service("c", [this](Completion done) { started_ = std::move(done); }, "start");
    thread_ = std::thread([this] {
      deliver_on_this_thread([this] {
        wakes_.fetch_add(1);
        post_io([this] { deliver_handed_over(); });
      });
      io_thread_ = std::this_thread::get_id();
      std::unique_lock lock(mutex_);
      ready_ = true;
      cv_.notify_all();
      for (;;) {
        cv_.wait(lock, [this] { return stop_ || !tasks_.empty(); });
        if (tasks_.empty()) return;  // stopping, nothing left
        auto task = std::move(tasks_.front());
        tasks_.pop_front();
        lock.unlock();
        task();
        lock.lock();
      }
    });
    std::unique_lock lock(mutex_);
    cv_.wait(lock, [this] { return ready_; });
  }
  ~ThreadedManager() override { stop_io(); }

  void stop_io() {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    cv_.notify_all();
    if (thread_.joinable()) thread_.join();
  }
  // Runs `task` on the I/O thread and waits for it.
  void on_io(std::function<void()> task) {
    std::mutex m;
    std::condition_variable cv;
    bool done = false;
    post_io([&] {
      task();
      std::lock_guard lock(m);
      done = true;
      cv.notify_all();
    });
    std::unique_lock lock(m);
    cv.wait(lock, [&] { return done; });
  }
  // Keeps the I/O thread busy until `released` is ready (nothing is delivered meanwhile).
  void hold_io(std::shared_future<void> released) {
    post_io([released] { released.wait_for(std::chrono::seconds(10)); });
  }
  // Waits (bounded) until `n` outcomes have been delivered.
  bool wait_for_deliveries(std::size_t n) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, std::chrono::seconds(10), [&] { return delivered_.size() >= n; });
  }

  struct Delivery {
    RequestId id;
    Outcome outcome;
    bool on_io_thread;
    bool progress = false;  // a progress report (its value in outcome.value)
  };
  std::vector<Delivery> delivered() {
    std::lock_guard lock(mutex_);
    return delivered_;
  }
  Call echo(int x) { return Call{"c", "echo", json::array({x})}; }
  // the call `c start` started last (the simulation thread's, as a component's)
  Completion started_;
  using RequestManager::answer_in_order;
  using RequestManager::complete_request;
  using RequestManager::deliver_handed_over;
  using RequestManager::deliver_on_any_thread;

  std::atomic<int> wakes_{0};

 protected:
  void on_service_completion(RequestId id, Outcome&& outcome) override {
    std::lock_guard lock(mutex_);
    delivered_.push_back({id, std::move(outcome), std::this_thread::get_id() == io_thread_});
    cv_.notify_all();
  }
  void on_service_progress(RequestId id, json&& value) override {
    std::lock_guard lock(mutex_);
    delivered_.push_back(
        {id, Outcome::success(std::move(value)), std::this_thread::get_id() == io_thread_, true});
    cv_.notify_all();
  }

 private:
  void post_io(std::function<void()> task) {
    {
      std::lock_guard lock(mutex_);
      tasks_.push_back(std::move(task));
    }
    cv_.notify_all();
  }

  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<std::function<void()>> tasks_;
  bool ready_ = false;
  bool stop_ = false;
  std::thread::id io_thread_;
  std::vector<Delivery> delivered_;
  std::thread thread_;
};

std::vector<RequestId> ids_of(const std::vector<ThreadedManager::Delivery>& deliveries) {
  std::vector<RequestId> ids;
  for (const auto& d : deliveries) ids.push_back(d.id);
  return ids;
}

TEST(HandoffTest, OutcomesOfTheSimulationThreadAreDeliveredOnTheTransportsThreadInOrder) {
  ThreadedManager rm;
  std::vector<RequestId> ids;
  for (int i = 0; i < 3; ++i) {
    ids.push_back(rm.new_request_id());
    rm.submit(ids.back(), rm.echo(i));
  }
  // the I/O thread is busy while this thread, playing the simulation thread, produces one
  // burst of three outcomes: however the threads are scheduled, the burst is one wake
  std::promise<void> burst_done;
  rm.hold_io(burst_done.get_future().share());
  rm.process();
  burst_done.set_value();
  ASSERT_TRUE(rm.wait_for_deliveries(3));
  const auto delivered = rm.delivered();
  EXPECT_EQ(ids_of(delivered), ids);
  for (const auto& d : delivered) EXPECT_TRUE(d.on_io_thread);
  EXPECT_EQ(delivered[2].outcome.value, json(2));
  EXPECT_EQ(rm.wakes_.load(), 1);  // one wake for the burst
}

TEST(HandoffTest, ProgressReportsTravelLikeOutcomesAndArriveBeforeTheirCallsOutcome) {
  ThreadedManager rm;
  const RequestId id = rm.new_request_id();
  Call call{"c", "start", nullptr};
  call.progress = true;
  rm.submit(id, std::move(call));
  rm.set_progress_interval(std::chrono::nanoseconds(0));
  rm.process();  // this thread plays the simulation's: it starts the call, then reports
  ASSERT_TRUE(rm.started_.progress(1));
  ASSERT_TRUE(rm.started_.progress(2));
  rm.started_(Status::success, 3);
  rm.process();
  ASSERT_TRUE(rm.wait_for_deliveries(3));
  const auto delivered = rm.delivered();
  ASSERT_EQ(delivered.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(delivered[i].id, id);
    EXPECT_TRUE(delivered[i].on_io_thread);
    EXPECT_EQ(delivered[i].progress, i < 2);
    EXPECT_EQ(delivered[i].outcome.value, json(static_cast<int>(i) + 1));
  }
}

TEST(HandoffTest, AnOutcomeProducedOnTheTransportsThreadFollowsThoseHandedOverBefore) {
  ThreadedManager rm;
  const RequestId first = rm.new_request_id();
  const RequestId second = rm.new_request_id();
  rm.on_io([&] {
    // handed over from the simulation thread while the I/O thread is busy here
    std::thread sim([&] {
      rm.submit(first, rm.echo(1));
      rm.process();
    });
    sim.join();
    // the I/O thread runs a request itself: delivered at once, after `first`
    rm.run_or_submit(second, rm.echo(2));
  });
  ASSERT_TRUE(rm.wait_for_deliveries(2));
  const auto delivered = rm.delivered();
  EXPECT_EQ(ids_of(delivered), (std::vector<RequestId>{first, second}));
  for (const auto& d : delivered) EXPECT_TRUE(d.on_io_thread);
}

TEST(HandoffTest, AnAnswerInOrderFollowsTheRequestsSubmittedBeforeIt) {
  ThreadedManager rm;
  const RequestId call = rm.new_request_id();
  const RequestId answer = rm.new_request_id();
  rm.submit(call, rm.echo(7));
  rm.answer_in_order(answer, Outcome::failed(Failure::bad_arguments, "refused by the transport"));
  rm.process();
  ASSERT_TRUE(rm.wait_for_deliveries(2));
  const auto delivered = rm.delivered();
  EXPECT_EQ(ids_of(delivered), (std::vector<RequestId>{call, answer}));
  EXPECT_EQ(delivered[1].outcome.message, "refused by the transport");
  EXPECT_TRUE(delivered[1].on_io_thread);
}

TEST(HandoffTest, ACancelsAnswerTravelsLikeAnOutcome) {
  ThreadedManager rm;
  const RequestId answer = rm.new_request_id();
  rm.cancel(rm.new_request_id(),
            [&](bool found) { rm.complete_request(answer, Outcome::success(json(found))); });
  rm.process();
  ASSERT_TRUE(rm.wait_for_deliveries(1));
  const auto delivered = rm.delivered();
  EXPECT_EQ(delivered[0].id, answer);
  EXPECT_EQ(delivered[0].outcome.value, json(false));  // nothing of that id was running
  EXPECT_TRUE(delivered[0].on_io_thread);
}

TEST(HandoffTest, AfterTheThreadEndsOutcomesAreDeliveredWhereProduced) {
  ThreadedManager rm;
  rm.stop_io();
  rm.deliver_on_any_thread();
  const RequestId id = rm.new_request_id();
  rm.submit(id, rm.echo(3));
  rm.process();
  const auto delivered = rm.delivered();
  ASSERT_EQ(delivered.size(), 1u);
  EXPECT_FALSE(delivered[0].on_io_thread);
  EXPECT_EQ(rm.wakes_.load(), 0);
}

TEST(HandoffTest, OutcomesHandedOverAfterTheThreadEndedCanStillBeTaken) {
  ThreadedManager rm;
  rm.stop_io();
  const RequestId id = rm.new_request_id();
  rm.submit(id, rm.echo(4));
  rm.process();  // handed over: the thread that would take it is gone
  EXPECT_TRUE(rm.delivered().empty());
  EXPECT_EQ(rm.wakes_.load(), 1);
  rm.deliver_on_any_thread();
  EXPECT_EQ(rm.deliver_handed_over(), 1u);  // e.g. a transport's final replies at stop()
  ASSERT_EQ(rm.delivered().size(), 1u);
  EXPECT_EQ(rm.delivered()[0].id, id);
}

}  // namespace
}  // namespace simgate
