// simgate/kit/idle_spin.h — how a transport's I/O thread waits for its next event.
//
// A thread that sleeps in epoll between requests pays a scheduler wake-up when the next one
// arrives: on a virtual machine that is often more than the request itself, and a client
// that calls services one after the other (a control loop, a script) pays it on every call.
// After handling something, the I/O thread can instead keep polling for a short while
// (`spin`) before it sleeps: a request that arrives within that window is taken at once.
//
// Spinning only pays when the next event comes soon, so the rule adapts, as KVM's halt
// polling does: the thread polls after an event only while waiting has recently been short.
// When it had to sleep and the sleep lasted `spin` or longer (a client calling every
// millisecond, say), it stops polling and sleeps at once after each event, until a sleep
// shorter than `spin` shows that events come close together again. A quiet server never
// spins; a client with long pauses costs at most one wasted window per change of pace; a
// client calling back to back keeps one core polling while it does.
//
//   run_with_idle_spin(io_context, std::chrono::microseconds(50));
//
// `EventLoop` is anything with run(), poll() and run_one() (the last two returning how
// many handlers ran) and stopped(): boost::asio::io_context. Returns when the loop is
// stopped or out of work, as run() does; exceptions from handlers propagate, as with run().
//
// Reading one connection directly. Through the event loop, a request that arrives while
// the thread polls costs two system calls: epoll_wait reports the socket ready, then recv
// reads it. A transport whose one busy client waits for each answer before it sends the
// next can let the polling thread read that client's socket itself instead: one recv per
// poll, the request taken by the recv that finds it. While it does, the socket has no read
// waiting in the event loop (two readers of one socket would race), so before the thread
// sleeps it hands the socket back. The third argument, `direct`, is anything with
//   std::size_t poll()   reads the socket it watches, if any, without blocking, and handles
//                        what it read; returns how many reads it handled (0: nothing
//                        watched, or nothing waiting)
//   bool watching() const
//   void park()          before the thread sleeps: the watched socket (if any) waits
//                        through the event loop again (an async read)
// While a socket is watched, the event loop is still polled, every k_direct_polls_per_poll
// direct reads that found nothing, and every k_direct_reads_per_poll that found something
// or k_direct_reading_per_poll of them, whichever comes first, so that other connections
// and posted work wait microseconds, at most about one direct read, even while the
// watched client floods its socket (blank lines, junk, notifications: every direct read
// finds something, and a read of a full buffer can take milliseconds to handle).
// DirectReads<Connection> below is such an argument, for a transport's connection class.
//
// Direct reads run outside the event loop's run()/poll(): code that asks "am I on the I/O
// thread?" must ask by thread (Asio's running_in_this_thread() is false there).
#ifndef SIMGATE_KIT_IDLE_SPIN_H_
#define SIMGATE_KIT_IDLE_SPIN_H_

#include <chrono>
#include <cstddef>
#include <memory>
#include <thread>
#include <utility>

namespace simgate::kit {

// While it polls, the thread yields the CPU every this many empty polls (about every
// 5 µs): often enough that a thread waking on this CPU waits microseconds, not a
// scheduler time slice; rarely enough to cost a polled request next to nothing.
inline constexpr unsigned k_polls_per_yield = 8;

// While a socket is read directly, the event loop is polled once every this many direct
// reads that find nothing (each poll of either is a system call of about the same cost)...
inline constexpr unsigned k_direct_polls_per_poll = 4;
// ...and once every this many that find something: a client that never runs dry (a
// pipelining one, or one flooding its socket) does not keep the others waiting for more
// than this many reads, and pays one event-loop poll per this many of its reads.
inline constexpr unsigned k_direct_reads_per_poll = 32;
// ...or sooner, once direct reads have held the thread this long since the event loop was
// last polled: a client that sends full buffers (a flood) is handled in large reads, and
// 32 of them kept the others waiting up to 190 ms (issue #35, item 3). A pipelining
// client's small reads never take this long, so it still pays one poll per 32 reads.
inline constexpr std::chrono::microseconds k_direct_reading_per_poll{500};

// The `direct` argument of a transport that reads nothing itself.
struct NoDirectReads {
  std::size_t poll() { return 0; }
  bool watching() const { return false; }
  void park() {}
};

// The one connection a transport's polling thread reads itself: run_with_idle_spin's
// `direct` argument. `Connection` has
//   bool read_now()     reads what is waiting, without waiting, and handles it as its async
//                       read's completion would (and may be watched again); false when
//                       nothing was waiting
//   void read_async()   waits for its next bytes through the event loop (an async read)
//   bool closed() const
// A connection about to start an async read is watch()ed instead when the transport
// decides it should be (a client sending alone, ReadSplit::alone, while the thread polls:
// never with a spin of 0, where nothing would poll it). One thread (the I/O thread).
template <class Connection>
class DirectReads {
 public:
  // Watches `connection` instead of an async read; a connection watched before is parked.
  void watch(std::shared_ptr<Connection> connection) {
    if (connection_ && connection_ != connection) park();
    connection_ = std::move(connection);
  }
  // Lets `connection` go if watched (the server forgets it: it finished). Its socket may
  // stay open for a goodbye (a WebSocket close handshake): it waits for the client's answer
  // through the event loop (read_async does nothing once the socket is shut), or nobody would
  // read it until its close timer gave up (WebSocketAuthTest.AWrongTokenIsAnsweredThenClosed
  // WithAReason, under load).
  void forget(const Connection& connection) {
    if (connection_.get() != &connection) return;
    auto finished = std::move(connection_);
    finished->read_async();
  }

  std::size_t poll() {
    if (!connection_) return 0;
    // handling the read may watch it again (its next read)
    auto connection = std::move(connection_);
    if (connection->read_now()) return 1;
    if (!connection->closed()) connection_ = std::move(connection);
    return 0;
  }
  bool watching() const { return connection_ != nullptr; }
  void park() {
    if (auto connection = std::move(connection_)) connection->read_async();
  }

 private:
  std::shared_ptr<Connection> connection_;  // watched: no async read pending on it
};

template <class EventLoop, class Clock = std::chrono::steady_clock, class Direct = NoDirectReads>
void run_with_idle_spin(EventLoop& loop, std::chrono::microseconds spin, Direct&& direct = {}) {
  if (spin.count() <= 0) {
    loop.run();
    return;
  }
  bool polling = true;  // waiting has been short lately: poll before sleeping
  auto poll_until = Clock::now() + spin;
  unsigned idle_polls = 0;
  unsigned direct_polls = 0;  // direct reads that found nothing
  unsigned direct_reads = 0;  // direct reads that found something
  auto loop_polled_at = Clock::now();
  while (!loop.stopped()) {
    if (polling) {
      // the event loop is polled every few direct reads, whatever they found: a watched
      // socket that never runs dry (a flooding client) must not keep the others unserved
      std::size_t handled = direct.poll();
      const bool loop_due = !direct.watching() ? handled == 0
                            : handled == 0
                                ? ++direct_polls % k_direct_polls_per_poll == 0
                                : ++direct_reads % k_direct_reads_per_poll == 0 ||
                                      Clock::now() - loop_polled_at >= k_direct_reading_per_poll;
      if (loop_due) {
        handled += loop.poll();
        loop_polled_at = Clock::now();
      }
      if (handled > 0) {
        poll_until = Clock::now() + spin;  // something happened: keep watching
        continue;
      }
      if (Clock::now() < poll_until) {
        // every few polls, a thread that needs this CPU (the simulation's) goes first
        if (++idle_polls % k_polls_per_yield == 0) std::this_thread::yield();
        continue;
      }
    }
    // sleep until the next event; how long it took decides whether to poll after it
    direct.park();
    const auto slept_at = Clock::now();
    if (loop.run_one() == 0) return;
    const auto woke_at = Clock::now();
    polling = woke_at - slept_at < spin;
    poll_until = woke_at + spin;
    loop_polled_at = woke_at;
  }
}

}  // namespace simgate::kit

#endif  // SIMGATE_KIT_IDLE_SPIN_H_
