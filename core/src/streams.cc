// streams.cc — StreamHub: the streams of one simulation (added, removed, listed, their
// statistics), each output stream's samples read when due after a step (publish_due) or
// pushed by its component, and fanned out to its subscribers. Input streams' commands:
// stream_commands.cc; samples, subscriptions and outlets: stream_samples.cc.
#include "simgate/core/streams.h"

#include <algorithm>
#include <stdexcept>

#include "simgate/core/log.h"
#include "stream_hub.h"

namespace simgate {

// ---------------------------------------------------------------------------------------
// StreamHub

struct StreamHub::Due {
  Stream* stream;
  bool due;                              // by its frequency (else only its new subscribers get it)
  std::shared_ptr<StreamSample> sample;  // once produced
  bool queued = false;                   // a subscriber's queue took the sample
};

StreamHub::StreamHub(std::shared_ptr<SimulationGate> gate) : gate_(std::move(gate)) {}
StreamHub::~StreamHub() {
  for (auto& s : streams_)
    if (s->outlet) {
      s->outlet->hub_ = nullptr;
      s->outlet->wanted_.store(false, std::memory_order_release);
    }
}

StreamHub::Stream* StreamHub::find_locked(std::string_view component) {
  for (auto& s : streams_)
    if (s->info.component == component) return s.get();
  return nullptr;
}

const StreamHub::Stream* StreamHub::find_locked(std::string_view component) const {
  for (const auto& s : streams_)
    if (s->info.component == component) return s.get();
  return nullptr;
}

namespace {
bool carries(const StreamInfo& info, std::string_view transport) {
  return transport == StreamHub::k_every_transport ||
         std::find(info.transports.begin(), info.transports.end(), transport) !=
             info.transports.end();
}
}  // namespace

StreamHub::Stream* StreamHub::find_input_locked(std::string_view component,
                                                std::string_view transport) {
  Stream* s = find_locked(component);
  return s && s->info.direction == StreamDirection::in && carries(s->info, transport) ? s : nullptr;
}

std::optional<json> StreamHub::sample_now(std::string_view component) const {
  const Stream* s = find_locked(component);
  if (!s || s->info.direction != StreamDirection::out || !s->produce) return std::nullopt;
  try {
    if (s->produce_record) {
      double values[k_max_record_fields];
      const std::size_t n = s->record_fields->size();
      s->produce_record(std::span<double>(values, n));
      return record_json(*s->record_fields, std::span<const double>(values, n));
    }
    return s->produce();
  } catch (const std::exception& e) {
    log::warning("stream ", component, ": reading a sample failed: ", e.what());
    return std::nullopt;
  }
}

void StreamHub::add(const Component& component, std::string type,
                    std::vector<std::string> transports, double frequency) {
  const StreamDeclaration* declaration = component.stream();
  if (!declaration) throw std::invalid_argument(component.name() + " has no stream");
  if (declaration->direction == StreamDirection::out && !(frequency > 0))
    throw std::invalid_argument(component.name() + ": a stream's frequency must be > 0");
  auto stream = std::make_unique<Stream>();
  stream->info.component = component.name();
  stream->info.direction = declaration->direction;
  stream->info.kind = declaration->kind;
  stream->info.type = std::move(type);
  stream->info.fields = declaration->fields;
  stream->info.transports = std::move(transports);
  if (declaration->direction == StreamDirection::out) {
    stream->info.frequency = frequency;
    stream->period = 1.0 / frequency;
    stream->produce = declaration->produce;
    if (declaration->outlet) {
      // pushed: the component's rate is the stream's (0: an event stream, no rate); the hub
      // only fans out
      if (declaration->outlet->hub_ && declaration->outlet->hub_ != this)
        throw std::invalid_argument(component.name() +
                                    ": its pushed stream is run by another hub already");
      stream->outlet = declaration->outlet;
      stream->info.pushed = true;
      stream->info.frequency = declaration->pushed_frequency;
      stream->produce = nullptr;
    }
    if (declaration->produce_record) {
      stream->produce_record = declaration->produce_record;
      stream->record_fields = std::make_shared<const std::vector<std::string>>(declaration->fields);
    }
  } else {
    stream->apply = declaration->apply;
  }
  std::lock_guard lock(mutex_);
  if (find_locked(component.name()))
    throw std::invalid_argument(component.name() + " has a stream already");
  if (stream->outlet) stream->outlet->hub_ = this;
  streams_.push_back(std::move(stream));
}

bool StreamHub::remove(const std::string& component) {
  std::vector<std::shared_ptr<StreamSubscription>> closed;
  {
    std::lock_guard lock(mutex_);
    auto it = std::find_if(streams_.begin(), streams_.end(),
                           [&](const auto& s) { return s->info.component == component; });
    if (it == streams_.end()) return false;
    closed = std::move((*it)->subscribers);
    subscribers_.fetch_sub(closed.size(), std::memory_order_release);
    for (const auto& s : closed) dropped_by_removed_ += s->dropped();
    dropped_by_removed_ += (*it)->dropped_before + (*it)->skipped;
    if (const auto& outlet = (*it)->outlet) {
      outlet->wanted_.store(false, std::memory_order_release);
      outlet->hub_ = nullptr;
    }
    streams_.erase(it);
  }
  for (const auto& s : closed) {
    s->close();
    s->wake();
  }
  return true;
}

void StreamHub::remove_all() {
  std::vector<std::string> components;
  {
    std::lock_guard lock(mutex_);
    for (const auto& s : streams_) components.push_back(s->info.component);
  }
  for (const std::string& component : components) remove(component);
}

void StreamHub::publish_due(double time) {
  time_.store(time, std::memory_order_relaxed);
  if (subscribers_.load(std::memory_order_acquire) == 0) return;
  // which streams give a sample now, without the hub mutex: streams_ and the schedules
  // change only under the simulation lock, which the caller holds; what the transports
  // change (subscribers, first samples wanted) is read from atomics
  due_.clear();
  for (auto& stream_ptr : streams_) {
    Stream& s = *stream_ptr;
    if (!s.produce || s.subscriber_count.load(std::memory_order_acquire) == 0) continue;
    if (time < s.last_time) s.next_due = time;  // the clock went back (reset): start again from now
    const bool due = time + 1e-9 >= s.next_due;
    if (due || s.first_wanted.load(std::memory_order_acquire)) due_.push_back({&s, due, nullptr});
  }
  if (due_.empty()) return;
  // the samples, without the hub mutex (the simulation lock keeps the streams): a transport
  // that subscribes or publishes meanwhile never waits for a component
  for (Due& d : due_) {
    Stream& s = *d.stream;
    try {
      if (s.produce_record) {
        std::shared_ptr<StreamSample> sample = std::move(s.spare);
        if (sample)
          sample->reuse(time);
        else
          sample = std::make_shared<StreamSample>(0, time, s.record_fields);
        s.produce_record(sample->record_values());
        d.sample = std::move(sample);
      } else {
        d.sample = std::make_shared<StreamSample>(0, time, s.produce());
      }
    } catch (const std::exception& e) {
      // no sample this time; the next try is at the next due time
      if (!s.failure_logged) {
        s.failure_logged = true;
        log::warning(s.info.component,
                     " stream: reading a sample failed (logged once): ", e.what());
      }
    }
  }
  {
    std::lock_guard lock(mutex_);
    for (Due& d : due_) {
      Stream& s = *d.stream;
      s.first_wanted.store(false, std::memory_order_relaxed);
      if (!d.sample) {
        s.next_due = time + s.period;
        continue;
      }
      d.sample->seq_ = ++s.seq;
      s.last_time = time;
      d.queued = fan_out(s, d.sample, d.due);
      if (d.due) {
        s.next_due += s.period;
        if (s.next_due <= time) s.next_due = time + s.period;
      }
    }
  }
  after_fan_out();
  // a record sample that never left this thread (only direct subscribers had it, and they
  // wrote it at once) is the stream's next one; the others go when nobody holds them
  for (Due& d : due_)
    if (d.sample && !d.queued && d.stream->produce_record) d.stream->spare = std::move(d.sample);
  due_.clear();
}

bool StreamHub::fan_out(Stream& stream, const SamplePtr& sample, bool due) {
  bool queued = false;
  for (auto& sub : stream.subscribers) switch (sub->push(sample, due)) {
      case StreamSubscription::Pushed::wake:
        to_wake_.push_back(sub);
        queued = true;
        break;
      case StreamSubscription::Pushed::queued: queued = true; break;
      case StreamSubscription::Pushed::deliver: sub->deliver(*sample, due); break;
      case StreamSubscription::Pushed::no: break;
    }
  return queued;
}

void StreamHub::after_fan_out() {
  for (const auto& sub : to_wake_) sub->wake();
  to_wake_.clear();
}

bool StreamHub::push(const std::string& component, double time, json data,
                     std::shared_ptr<const StreamPayload> payload) {
  // made before the hub mutex is taken (a transport subscribing never waits on an allocation)
  auto sample = payload ? std::make_shared<StreamSample>(0, time, std::move(payload))
                        : std::make_shared<StreamSample>(0, time, std::move(data));
  {
    std::lock_guard lock(mutex_);
    Stream* s = find_locked(component);
    if (!s || !s->outlet || s->subscribers.empty()) return false;
    sample->seq_ = ++s->seq;
    s->last_time = time;
    s->first_wanted.store(false, std::memory_order_relaxed);
    fan_out(*s, sample, true);
  }
  after_fan_out();
  return true;
}

void StreamHub::note_skipped(const std::string& component) {
  bool first = false;
  {
    std::lock_guard lock(mutex_);
    Stream* s = find_locked(component);
    if (!s) return;
    ++s->skipped;
    first = !s->skip_logged;
    s->skip_logged = true;
  }
  if (first)
    log::warning(
        component,
        " stream: a sample due was skipped (its component could not make it in time: a camera's "
        "render thread behind); this is logged once; simulation get_stream_statistics counts them");
}

std::vector<StreamInfo> StreamHub::streams(std::string_view transport) const {
  std::lock_guard lock(mutex_);
  std::vector<StreamInfo> out;
  for (const auto& s : streams_)
    if (carries(s->info, transport)) out.push_back(s->info);
  return out;
}

std::optional<StreamInfo> StreamHub::find(std::string_view component,
                                          std::string_view transport) const {
  std::lock_guard lock(mutex_);
  const Stream* s = find_locked(component);
  if (!s || !carries(s->info, transport)) return std::nullopt;
  return s->info;
}

std::shared_ptr<StreamSubscription> StreamHub::subscribe(std::string_view component,
                                                         std::string_view transport,
                                                         SubscriberOptions options) {
  std::shared_ptr<StreamSubscription> subscription;
  {
    std::lock_guard lock(mutex_);
    Stream* s = find_locked(component);
    if (!s || s->info.direction != StreamDirection::out || !carries(s->info, transport))
      return nullptr;
    subscription = std::make_shared<StreamSubscription>(std::string(component), std::move(options));
    s->subscribers.push_back(subscription);
    s->subscriber_count.store(s->subscribers.size(), std::memory_order_release);
    s->first_wanted.store(true, std::memory_order_release);
    if (s->outlet) s->outlet->wanted_.store(true, std::memory_order_release);
    subscribers_.fetch_add(1, std::memory_order_release);
    turn_wanted_.store(true, std::memory_order_release);
  }
  gate_->signal();  // the simulation's next turn gives it its first sample
  return subscription;
}

void StreamHub::unsubscribe(const std::shared_ptr<StreamSubscription>& subscription) {
  if (!subscription) return;
  {
    std::lock_guard lock(mutex_);
    if (Stream* s = find_locked(subscription->stream_)) {
      auto it = std::find(s->subscribers.begin(), s->subscribers.end(), subscription);
      if (it != s->subscribers.end()) {
        s->dropped_before += subscription->dropped();
        s->subscribers.erase(it);
        s->subscriber_count.store(s->subscribers.size(), std::memory_order_release);
        subscribers_.fetch_sub(1, std::memory_order_release);
        if (s->outlet && s->subscribers.empty())
          s->outlet->wanted_.store(false, std::memory_order_release);
      }
    }
  }
  subscription->close();
}

std::vector<StreamStatistics> StreamHub::statistics(std::string_view transport) const {
  std::lock_guard lock(mutex_);
  std::vector<StreamStatistics> out;
  for (const auto& s : streams_) {
    if (!transport.empty() && !carries(s->info, transport)) continue;
    StreamStatistics st;
    st.info = s->info;
    st.samples = s->seq;
    st.subscribers = s->subscribers.size();
    st.skipped = s->skipped;
    st.dropped = s->dropped_before + s->skipped;
    for (const auto& sub : s->subscribers) st.dropped += sub->dropped();
    st.commands = s->commands;
    st.replaced = s->replaced;
    st.refused = s->refused;
    st.last_refusal = s->last_refusal;
    out.push_back(std::move(st));
  }
  return out;
}

std::uint64_t StreamHub::total_samples() const {
  std::lock_guard lock(mutex_);
  std::uint64_t n = 0;
  for (const auto& s : streams_) n += s->seq;
  return n;
}

std::uint64_t StreamHub::total_dropped() const {
  std::lock_guard lock(mutex_);
  std::uint64_t n = dropped_by_removed_;
  for (const auto& s : streams_) {
    n += s->dropped_before + s->skipped;
    for (const auto& sub : s->subscribers) n += sub->dropped();
  }
  return n;
}

}  // namespace simgate
