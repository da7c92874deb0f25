// simgate/kit/read_split.h — when a transport answers half a read before parsing the rest.
//
// A client that pipelines (keeps many requests in flight on one connection) sends them in
// large reads. A transport that parses a whole read, runs it and only then writes the
// replies makes the client wait for the last of them before it sends more: client and
// server take turns, and on a machine with two cores one of them is always idle. Running
// the first half of a large read and writing its replies before parsing the second half
// lets the client read them and send more while the server works: the two overlap.
//
// With several connections active that overlap is already there (the server has their
// reads to work on), and the extra write would only cost. ReadSplit tells the two cases
// apart: a connection is alone when every read for at least k_alone_after came from it.
// The same test decides whether, after a large read, a transport reads that connection
// on while bytes are waiting (one write for the reads in a row) before going back to the
// event loop, which only pays when no other connection is waiting for its turn.
//
//   ReadSplit split;  // one per transport, I/O thread only
//   on each read of connection c:   bytes >= ReadSplit::k_min_bytes: at the first line
//                                   boundary past the middle, if split.alone(c): run what
//                                   was parsed so far and write the replies
//                                   at the end: split.alone(c); run the rest; write
//
// Not thread-safe (a transport's single I/O thread).
#ifndef SIMGATE_KIT_READ_SPLIT_H_
#define SIMGATE_KIT_READ_SPLIT_H_

#include <chrono>
#include <cstddef>

namespace simgate::kit {

class ReadSplit {
 public:
  using Clock = std::chrono::steady_clock;
  // Reads shorter than this (about 16 short requests) are never split.
  static constexpr std::size_t k_min_bytes = 512;
  // A connection is alone after this long with no read from another one.
  static constexpr std::chrono::milliseconds k_alone_after{2};

  // Notes a read (or half a read) from `connection`; true when it is the only connection
  // that has been sending for at least k_alone_after.
  bool alone(const void* connection, Clock::time_point now = Clock::now()) {
    if (connection != last_) {
      last_ = connection;
      since_ = now;
    }
    return now - since_ >= k_alone_after;
  }

 private:
  const void* last_ = nullptr;  // the connection of the previous read (compared, never used)
  Clock::time_point since_{};   // when reads began to come from last_ only
};

}  // namespace simgate::kit

#endif  // SIMGATE_KIT_READ_SPLIT_H_
