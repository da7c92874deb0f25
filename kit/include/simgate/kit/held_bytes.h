// simgate/kit/held_bytes.h — what the connections of one transport hold in memory for their
// clients, together, against the transport's `max_buffered_bytes` (one cap per transport).
//
// Held: bytes read that are not yet a whole message (an unfinished line, a WebSocket
// message still arriving), replies not yet written (a client that does not read), and the
// bytes an HTTP response owns while it is written (a file the web server's cache shares is
// not counted again per response). Each connection adds what it comes to hold and takes it
// back when it no longer holds it. The rules built on it, the same on every TCP transport
// (connection.h: every connection of a transport):
//   - a connection whose unfinished message would take the total past the cap is closed;
//   - a reply that finds the total past the cap while its own connection still has replies
//     unsent closes that connection (its client does not read);
//   - a reply queued when its connection had nothing unsent is written at once when the
//     total is past the cap; a connection whose socket does not take all of it is closed (so
//     a first reply is no way around the cap);
//   - an HTTP request is answered 503 while the total is past the cap.
// A connection that reads its replies is never closed by these rules while the total is
// within the cap.
//
// Threads: the transport's I/O thread only (no atomics: nothing else reads it).
#ifndef SIMGATE_KIT_HELD_BYTES_H_
#define SIMGATE_KIT_HELD_BYTES_H_

#include <cstddef>
#include <cstdint>

namespace simgate::kit {

class HeldBytes {
 public:
  explicit HeldBytes(std::size_t max = SIZE_MAX) : max_(max) {}

  // Adds `bytes` (negative: takes them back).
  void add(std::ptrdiff_t bytes) { held_ += static_cast<std::size_t>(bytes); }
  void set_max(std::size_t max) { max_ = max; }

  std::size_t held() const { return held_; }
  std::size_t max() const { return max_; }
  // Past the cap.
  bool over() const { return held_ > max_; }
  // `more` bytes would still be within the cap.
  bool fits(std::size_t more) const { return more <= max_ && held_ <= max_ - more; }

 private:
  std::size_t held_ = 0;  // all connections together
  std::size_t max_;       // max_buffered_bytes
};

}  // namespace simgate::kit

#endif  // SIMGATE_KIT_HELD_BYTES_H_
