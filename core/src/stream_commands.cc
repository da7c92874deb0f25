// stream_commands.cc — StreamHub's input streams: a command a transport publishes, checked
// for keys the stream does not take, applied at once when the simulation lock is free or kept
// (latest wins) for the simulation's next turn (apply_commands); refusals counted and logged
// once. The streams, their samples and subscriptions: streams.cc.
#include <algorithm>

#include "simgate/core/input_tap.h"
#include "simgate/core/log.h"
#include "simgate/core/streams.h"
#include "simgate/core/suggest.h"
#include "stream_hub.h"

namespace simgate {

std::string StreamHub::unknown_key(const StreamInfo& info, const json& command) {
  for (auto it = command.begin(); it != command.end(); ++it) {
    // a sample written back keeps its timestamp (an armature_pose's to an armature)
    if (it.key() == "timestamp" ||
        std::find(info.fields.begin(), info.fields.end(), it.key()) != info.fields.end())
      continue;
    std::string expected;
    for (const auto& k : info.fields) expected += (expected.empty() ? "" : ", ") + k;
    return "the command has an unknown key '" + it.key() + "' (expected " + expected + ")" +
           did_you_mean(it.key(), info.fields);
  }
  return "";
}

std::string StreamHub::apply(Stream& stream, const json& command) {
  // the component, without the hub mutex (the caller holds the simulation lock, which keeps
  // the stream); then the counters, with it
  std::string refusal;
  try {
    stream.apply(command);
  } catch (const std::exception& e) {
    refusal = e.what();
  }
  if (InputTap* tap = gate_->input_tap()) [[unlikely]]
    tap->command_applied(stream.info.component, command, refusal);
  std::lock_guard lock(mutex_);
  if (refusal.empty())
    ++stream.commands;
  else
    count_refusal_locked(stream, refusal, /*log=*/true);
  return refusal;
}

void StreamHub::count_refusal_locked(Stream& stream, std::string reason, bool log) {
  ++stream.refused;
  stream.last_refusal = std::move(reason);
  if (!log || stream.refusal_logged) return;
  stream.refusal_logged = true;
  log::warning(stream.info.component,
               " stream: a command was refused (logged once; simulation "
               "get_stream_statistics counts them): ",
               stream.last_refusal);
}

bool StreamHub::note_refused(std::string_view component, std::string_view transport,
                             std::string reason) {
  std::lock_guard lock(mutex_);
  Stream* s = find_input_locked(component, transport);
  if (s) count_refusal_locked(*s, std::move(reason), /*log=*/false);
  return s != nullptr;
}

std::size_t StreamHub::apply_commands() {
  std::vector<std::pair<Stream*, json>> waiting;
  {
    std::lock_guard lock(mutex_);
    turn_wanted_.store(false, std::memory_order_relaxed);
    for (auto& s : streams_) {
      if (!s->pending) continue;
      waiting.emplace_back(s.get(), std::move(*s->pending));
      s->pending.reset();
    }
  }
  for (auto& [stream, command] : waiting) apply(*stream, command);
  return waiting.size();
}

PublishResult StreamHub::publish(std::string_view component, std::string_view transport,
                                 json command) {
  PublishResult result;
  if (!command.is_object()) {
    // refused before any component sees it, but a refusal of the stream all the same (a
    // client whose commands all go nowhere shows in get_stream_statistics)
    result.error = "a command of " + std::string(component) + " is a JSON object, found " +
                   std::string(command.type_name());
    std::lock_guard lock(mutex_);
    if (Stream* s = find_input_locked(component, transport))
      count_refusal_locked(*s, result.error, /*log=*/true);
    return result;
  }
  std::unique_lock gate(*gate_, std::try_to_lock);
  Stream* s = nullptr;
  std::optional<json> older;  // a command that waited, applied first
  {
    std::lock_guard lock(mutex_);
    s = find_input_locked(component, transport);
    if (!s) {
      result.error = "no input stream '" + std::string(component) + "' here";
      return result;
    }
    // a key the stream does not take is refused now, not after waiting for the lock: the
    // client is never told "queued" of a command that will be refused (issue #35, item 10)
    result.error = unknown_key(s->info, command);
    if (!result.error.empty()) {
      count_refusal_locked(*s, result.error, /*log=*/true);
      return result;
    }
    if (!gate.owns_lock()) {
      if (s->pending) ++s->replaced;
      s->pending = std::move(command);
      turn_wanted_.store(true, std::memory_order_release);
      result.ok = true;
      gate_->signal();
      return result;
    }
    older.swap(s->pending);
  }
  // the simulation lock is ours: what waited goes first, then this one, and the component
  // says at once
  if (older) apply(*s, *older);
  result.error = apply(*s, command);
  result.ok = result.error.empty();
  result.applied = result.ok;
  return result;
}

}  // namespace simgate
