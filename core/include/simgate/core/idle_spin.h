// simgate/core/idle_spin.h — how a transport's I/O thread waits for its next event.
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
#ifndef SIMGATE_CORE_IDLE_SPIN_H_
#define SIMGATE_CORE_IDLE_SPIN_H_

#include <chrono>
#include <thread>

namespace simgate {

// While it polls, the thread yields the CPU every this many empty polls (about every
// 5 µs): often enough that a thread waking on this CPU waits microseconds, not a
// scheduler time slice; rarely enough to cost a polled request next to nothing.
inline constexpr unsigned k_polls_per_yield = 8;

template <class EventLoop, class Clock = std::chrono::steady_clock>
void run_with_idle_spin(EventLoop& loop, std::chrono::microseconds spin) {
  if (spin.count() <= 0) {
    loop.run();
    return;
  }
  bool polling = true;  // waiting has been short lately: poll before sleeping
  auto poll_until = Clock::now() + spin;
  unsigned idle_polls = 0;
  while (!loop.stopped()) {
    if (polling) {
      if (loop.poll() > 0) {
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
    const auto slept_at = Clock::now();
    if (loop.run_one() == 0) return;
    const auto woke_at = Clock::now();
    polling = woke_at - slept_at < spin;
    poll_until = woke_at + spin;
  }
}

}  // namespace simgate

#endif  // SIMGATE_CORE_IDLE_SPIN_H_
