// run_with_idle_spin: when the I/O thread polls and when it sleeps, with a scripted event
// loop on a simulated clock (deterministic: no real time passes).
#include <chrono>
#include <cstddef>
#include <memory>
#include <vector>

#include <gtest/gtest.h>

#include "simgate/kit/idle_spin.h"

namespace simgate::kit {
namespace {

using std::chrono::microseconds;

// A clock that moves only when the scripted loop says so.
struct FakeClock {
  using duration = std::chrono::nanoseconds;
  using rep = duration::rep;
  using period = duration::period;
  using time_point = std::chrono::time_point<FakeClock>;
  static constexpr bool is_steady = true;
  static inline time_point current{};
  static time_point now() { return current; }
};

// Events at given times (µs from the start). poll() costs 1 µs and runs the events due;
// run_one() sleeps until the next event and runs it. Out of events: stopped.
class ScriptedLoop {
 public:
  explicit ScriptedLoop(std::vector<long> event_times_us) : events_(std::move(event_times_us)) {
    FakeClock::current = FakeClock::time_point{};
  }
  std::size_t poll() {
    ++polls;
    FakeClock::current += microseconds(1);
    std::size_t ran = 0;
    for (; next_ < events_.size() && due(events_[next_]); ++next_, ++ran)
      note_lateness(events_[next_]);
    return ran;
  }
  std::size_t run_one() {
    ++sleeps;
    if (watched && *watched) ++sleeps_while_watched;
    if (next_ == events_.size()) return 0;
    if (!due(events_[next_]))
      FakeClock::current = FakeClock::time_point{microseconds(events_[next_])};
    ++next_;
    return 1;
  }
  void run() {
    ran_plainly = true;
    next_ = events_.size();
  }
  bool stopped() const { return next_ == events_.size(); }

  std::size_t polls = 0;   // poll() calls
  std::size_t sleeps = 0;  // run_one() calls
  bool ran_plainly = false;
  const bool* watched = nullptr;         // a direct reader's socket is watched (no async read)
  std::size_t sleeps_while_watched = 0;  // run_one() calls with *watched: a lost socket
  microseconds most_late{0};             // the longest an event waited for poll()

 private:
  void note_lateness(long at_us) {
    const auto late = std::chrono::duration_cast<microseconds>(
        FakeClock::now() - FakeClock::time_point{microseconds(at_us)});
    if (late > most_late) most_late = late;
  }
  static bool due(long at_us) {
    return FakeClock::now() >= FakeClock::time_point{microseconds(at_us)};
  }
  std::vector<long> events_;
  std::size_t next_ = 0;
};

// A socket read directly (idle_spin.h's `direct`): its requests arrive at given times;
// poll() costs `read_cost` and takes those due while the socket is watched. Parked, it
// waits for the event loop (not modelled: the tests give it nothing more to read).
struct ScriptedDirectReads {
  explicit ScriptedDirectReads(std::vector<long> request_times_us)
      : requests(std::move(request_times_us)) {}
  std::size_t poll() {
    if (!watched) return 0;
    ++polls;
    FakeClock::current += read_cost;
    std::size_t ran = 0;
    while (next < requests.size() &&
           FakeClock::now() >= FakeClock::time_point{microseconds(requests[next])})
      ++next, ++ran;
    return ran;
  }
  bool watching() const { return watched; }
  void park() {
    if (watched) ++parks;
    watched = false;
  }

  std::vector<long> requests;
  std::size_t next = 0;       // requests[next] is the next to arrive
  microseconds read_cost{1};  // how long one poll() takes to read and handle what it finds
  bool watched = true;        // no async read pending: only poll() reads the socket
  std::size_t polls = 0;      // poll() calls that read the socket
  std::size_t parks = 0;      // park() calls that handed the socket back
};

std::vector<long> every(long first_us, long gap_us, int count) {
  std::vector<long> t;
  for (int i = 0; i < count; ++i) t.push_back(first_us + gap_us * i);
  return t;
}

TEST(IdleSpinTest, NoSpinRunsTheLoopPlainly) {
  ScriptedLoop loop(every(0, 10, 5));
  run_with_idle_spin<ScriptedLoop, FakeClock>(loop, microseconds(0));
  EXPECT_TRUE(loop.ran_plainly);
  EXPECT_EQ(loop.polls, 0u);
}

TEST(IdleSpinTest, EventsCloseTogetherAreTakenWithoutSleeping) {
  // a client calling back to back: every event arrives within the window
  ScriptedLoop loop(every(0, 10, 1000));
  run_with_idle_spin<ScriptedLoop, FakeClock>(loop, microseconds(50));
  EXPECT_EQ(loop.sleeps, 0u);
}

TEST(IdleSpinTest, EventsFarApartAreWaitedForAsleepAfterOneWastedWindow) {
  // a client calling every millisecond: polling would never catch it
  ScriptedLoop loop(every(1000, 1000, 200));
  run_with_idle_spin<ScriptedLoop, FakeClock>(loop, microseconds(50));
  EXPECT_LE(loop.polls, 50u + 1);  // one window at the start, none after
  EXPECT_EQ(loop.sleeps, 200u);
}

TEST(IdleSpinTest, PollingResumesWhenEventsComeCloseTogetherAgain) {
  std::vector<long> t = every(1000, 1000, 20);             // slow: the thread sleeps at once
  for (long at : every(20'020, 10, 500)) t.push_back(at);  // then back to back
  ScriptedLoop loop(t);
  run_with_idle_spin<ScriptedLoop, FakeClock>(loop, microseconds(50));
  // one sleep per slow event, one that finds the fast ones starting, then polling only
  EXPECT_LE(loop.sleeps, 20u + 2);
  EXPECT_GE(loop.polls, 500u * 5);
}

TEST(IdleSpinTest, AWatchedSocketIsReadDirectlyAndTheEventLoopStillPolled) {
  // a lone client calling back to back, read directly; another connection's requests
  // (the event loop's) come every 200 µs and are served between the direct reads
  ScriptedDirectReads direct(every(0, 10, 990));  // the last at 9 890 µs
  ScriptedLoop loop(every(100, 200, 50));         // the last at 9 900 µs
  loop.watched = &direct.watched;
  run_with_idle_spin<ScriptedLoop, FakeClock>(loop, microseconds(50), direct);
  EXPECT_EQ(direct.next, 990u);  // every request taken by a direct read
  EXPECT_EQ(direct.parks, 0u);   // never slept: never handed back
  EXPECT_EQ(loop.sleeps, 0u);
  // the event loop is polled once every k_direct_polls_per_poll direct reads that find
  // nothing, and every k_direct_reads_per_poll that find something
  const std::size_t empty_reads = direct.polls - 990;
  EXPECT_GE(loop.polls, empty_reads / k_direct_polls_per_poll);
  EXPECT_LE(loop.polls, empty_reads / k_direct_polls_per_poll + 990 / k_direct_reads_per_poll + 1);
}

TEST(IdleSpinTest, AWatchedSocketThatNeverRunsDryDoesNotStarveTheEventLoop) {
  // a client flooding its connection (blank lines, junk, notifications): every direct read
  // finds something. Other connections' requests (the event loop's, every 200 µs) are
  // still served within a few reads: before, the loop was polled only when a direct read
  // found nothing, and they waited for the whole flood (issue #35, item 3)
  ScriptedDirectReads direct(every(0, 1, 20'000));  // one request per 1 µs read, for 20 ms
  ScriptedLoop loop(every(100, 200, 110));          // the last at 21 900 µs
  loop.watched = &direct.watched;
  run_with_idle_spin<ScriptedLoop, FakeClock>(loop, microseconds(50), direct);
  EXPECT_EQ(direct.next, 20'000u);
  EXPECT_GE(loop.polls, direct.polls / k_direct_reads_per_poll);
  EXPECT_LE(loop.most_late, microseconds(2 * k_direct_reads_per_poll))
      << loop.most_late.count() << " µs";
}

TEST(IdleSpinTest, AFloodReadInLargeBuffersDoesNotHoldTheEventLoopForManyReads) {
  // a flood handled in full buffers: each direct read takes 6 ms to handle (a JSON-RPC
  // client's 64 KiB of blank lines). Before, the loop waited for k_direct_reads_per_poll
  // of them (190 ms); now an event waits about one read at most (issue #35, item 3)
  ScriptedDirectReads direct(every(0, 6'000, 80));  // one full buffer waiting per read, 480 ms
  direct.read_cost = microseconds(6'000);
  ScriptedLoop loop(every(100, 1'000, 500));  // another client's call every millisecond, 500 ms
  loop.watched = &direct.watched;
  run_with_idle_spin<ScriptedLoop, FakeClock>(loop, microseconds(50), direct);
  EXPECT_EQ(direct.next, 80u);
  EXPECT_LE(loop.most_late, direct.read_cost + k_direct_reading_per_poll)
      << loop.most_late.count() << " µs";
}

TEST(IdleSpinTest, TheWatchedSocketIsHandedBackBeforeTheThreadSleeps) {
  // the client stops calling; other events come far apart: the thread sleeps for each,
  // never with the socket watched (its next request would go unread)
  ScriptedDirectReads direct(every(0, 10, 20));
  ScriptedLoop loop(every(1000, 1000, 5));
  loop.watched = &direct.watched;
  run_with_idle_spin<ScriptedLoop, FakeClock>(loop, microseconds(50), direct);
  EXPECT_EQ(direct.next, 20u);
  EXPECT_EQ(direct.parks, 1u);
  EXPECT_GE(loop.sleeps, 1u);
  EXPECT_EQ(loop.sleeps_while_watched, 0u);
}

// ---- DirectReads: the watched connection

// A connection whose reads are scripted: each read_now() takes the next answer.
struct ScriptedReadConnection {
  std::vector<bool> waiting;  // read_now() answers, in order (then: nothing waiting)
  std::size_t reads = 0;      // read_now() calls
  int async_reads = 0;        // read_async() calls
  bool is_closed = false;
  // watched again after a read, as a session is
  DirectReads<ScriptedReadConnection>* rewatch = nullptr;
  std::shared_ptr<ScriptedReadConnection> self;

  bool read_now() {
    const bool got = reads < waiting.size() && waiting[reads];
    ++reads;
    if (got && rewatch) rewatch->watch(self);
    return got;
  }
  void read_async() { ++async_reads; }
  bool closed() const { return is_closed; }
};

std::shared_ptr<ScriptedReadConnection> scripted_read_connection(std::vector<bool> waiting) {
  auto c = std::make_shared<ScriptedReadConnection>();
  c->waiting = std::move(waiting);
  c->self = c;  // the test breaks the cycle
  return c;
}

TEST(DirectReadsTest, PollsTheWatchedConnectionUntilParked) {
  DirectReads<ScriptedReadConnection> direct;
  EXPECT_EQ(direct.poll(), 0u);  // nothing watched
  auto c = scripted_read_connection({false, true, false});
  c->rewatch = &direct;
  direct.watch(c);
  EXPECT_EQ(direct.poll(), 0u);  // nothing waiting: still watched
  EXPECT_TRUE(direct.watching());
  EXPECT_EQ(direct.poll(), 1u);  // a read, handled; the connection watched itself again
  EXPECT_TRUE(direct.watching());
  direct.park();
  EXPECT_FALSE(direct.watching());
  EXPECT_EQ(c->async_reads, 1);  // waits through the event loop now
  EXPECT_EQ(direct.poll(), 0u);
  EXPECT_EQ(c->reads, 2u);
  direct.park();  // parking twice starts no second async read
  EXPECT_EQ(c->async_reads, 1);
  c->self.reset();
}

TEST(DirectReadsTest, AClosedConnectionIsDroppedAndAnotherParksThePrevious) {
  DirectReads<ScriptedReadConnection> direct;
  auto first = scripted_read_connection({});
  auto second = scripted_read_connection({});
  direct.watch(first);
  direct.watch(second);  // the first waits through the event loop again
  EXPECT_EQ(first->async_reads, 1);
  second->is_closed = true;
  EXPECT_EQ(direct.poll(), 0u);
  EXPECT_FALSE(direct.watching());  // dropped, not parked (no async read on a closed socket)
  EXPECT_EQ(second->async_reads, 0);
  direct.watch(first);
  direct.forget(*first);
  EXPECT_FALSE(direct.watching());
  // forgotten by the server (it finished), its socket may still be open for a goodbye: it
  // waits for its client's answer through the event loop (before: nobody read it)
  EXPECT_EQ(first->async_reads, 2);
  first->self.reset();
  second->self.reset();
}

}  // namespace
}  // namespace simgate::kit
