// stream_hub.h — what a StreamHub keeps of each stream (private to core/src: streams.cc,
// stream_commands.cc).
#ifndef SIMGATE_CORE_SRC_STREAM_HUB_H_
#define SIMGATE_CORE_SRC_STREAM_HUB_H_

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "simgate/core/streams.h"

namespace simgate {

struct StreamHub::Stream {
  StreamInfo info;
  std::function<json()> produce;                          // out
  std::function<void(std::span<double>)> produce_record;  // out, a record (StreamDeclaration)
  std::shared_ptr<const std::vector<std::string>>
      record_fields;                       // its numbers' names, shared by its samples
  std::function<void(const json&)> apply;  // in
  std::shared_ptr<StreamOutlet> outlet;    // out, pushed (its produce is empty)
  double period = 0;                       // out: simulated seconds between samples
  double next_due = 0;                     // out: when the next sample is due
  double last_time = 0;                    // out: time of the last sample
  std::uint64_t seq = 0;                   // out: samples produced
  std::shared_ptr<StreamSample> spare;     // out, a record: the last sample, if no queue took it
  std::vector<std::shared_ptr<StreamSubscription>> subscribers;
  // what publish_due looks at before it takes the hub mutex (written under it)
  std::atomic<std::size_t> subscriber_count{0};  // subscribers.size()
  std::atomic<bool> first_wanted{false};         // a subscriber waits for its first sample
  std::uint64_t dropped_before = 0;              // drops of subscriptions that ended
  std::uint64_t skipped = 0;    // out, pushed: samples due that never came (note_skipped)
  bool skip_logged = false;     // the first skip was logged
  std::optional<json> pending;  // in: the command waiting for the lock
  std::uint64_t commands = 0;
  std::uint64_t replaced = 0;
  std::uint64_t refused = 0;
  std::string last_refusal;
  bool refusal_logged = false;
  bool failure_logged = false;  // out: produce() threw once
};

}  // namespace simgate

#endif  // SIMGATE_CORE_SRC_STREAM_HUB_H_
