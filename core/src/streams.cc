#include "simgate/core/streams.h"

#include <algorithm>
#include <stdexcept>

#include "simgate/core/errors.h"
#include "simgate/core/input_tap.h"
#include "simgate/core/log.h"
#include "simgate/core/suggest.h"

namespace simgate {

// ---------------------------------------------------------------------------------------
// StreamSample

const json& StreamSample::data() const {
  if ((!fields_ && !payload_) || data_made_.load(std::memory_order_acquire)) return data_;
  std::lock_guard lock(made_mutex_);
  if (!data_made_.load(std::memory_order_relaxed)) {
    if (fields_) {
      data_ = record_json(*fields_, {values_.data(), fields_->size()});
    } else {
      data_ = payload_->to_json ? payload_->to_json(*payload_)
                                : json{{"content", payload_->content},
                                       {"description", payload_->description},
                                       {"bytes", payload_->bytes.size()}};
    }
    data_made_.store(true, std::memory_order_release);
  }
  return data_;
}

const std::string& StreamSample::text() const {
  if (text_made_.load(std::memory_order_acquire)) return text_;
  const json& data = this->data();  // (before the mutex: data() takes it too)
  std::lock_guard lock(made_mutex_);
  if (!text_made_.load(std::memory_order_relaxed)) {
    text_ = data.dump(-1, ' ', false, json::error_handler_t::replace);
    text_made_.store(true, std::memory_order_release);
  }
  return text_;
}

void StreamSample::reuse(double time) {
  // it never left the simulation thread (the hub's condition): nobody else reads it
  time_ = time;
  if (data_made_.load(std::memory_order_relaxed)) {
    data_ = json();
    data_made_.store(false, std::memory_order_relaxed);
  }
  if (text_made_.load(std::memory_order_relaxed)) {
    text_.clear();
    text_made_.store(false, std::memory_order_relaxed);
  }
}

double StreamSample::number(std::string_view key) const {
  if (fields_) {
    for (std::size_t i = 0; i < fields_->size(); ++i)
      if ((*fields_)[i] == key) return values_[i];
  } else if (auto it = data().find(key); it != data().end() && it->is_number()) {
    return it->get<double>();
  }
  throw std::out_of_range("the sample has no number '" + std::string(key) + "'");
}

void StreamSample::numbers(std::span<const std::string_view> keys, std::span<double> out) const {
  if (!fields_) {
    for (std::size_t k = 0; k < keys.size() && k < out.size(); ++k) out[k] = number(keys[k]);
    return;
  }
  const std::vector<std::string>& fields = *fields_;
  std::size_t at = 0;  // where the next key is looked for first
  for (std::size_t k = 0; k < keys.size() && k < out.size(); ++k) {
    std::size_t tried = 0;
    while (tried < fields.size() && fields[at] != keys[k]) {
      at = at + 1 == fields.size() ? 0 : at + 1;
      ++tried;
    }
    if (tried == fields.size())
      throw std::out_of_range("the sample has no number '" + std::string(keys[k]) + "'");
    out[k] = values_[at];
    at = at + 1 == fields.size() ? 0 : at + 1;
  }
}

// ---------------------------------------------------------------------------------------
// StreamSubscription

std::size_t StreamSubscription::take(std::vector<SamplePtr>& out) {
  std::lock_guard lock(mutex_);
  const std::size_t n = queue_.size();
  for (auto& sample : queue_) out.push_back(std::move(sample));
  queue_.clear();
  wake_armed_ = true;
  return n;
}

void StreamSubscription::note_dropped(std::uint64_t n) {
  if (n == 0) return;
  dropped_.fetch_add(n, std::memory_order_relaxed);
  log_first_drop();
}

std::uint64_t StreamSubscription::dropped() const {
  return dropped_.load(std::memory_order_relaxed);
}

std::uint64_t StreamSubscription::delivered() const {
  return delivered_.load(std::memory_order_relaxed);
}

bool StreamSubscription::closed() const {
  std::lock_guard lock(mutex_);
  return closed_;
}

StreamSubscription::Pushed StreamSubscription::push(const SamplePtr& sample, bool due) {
  // a direct subscriber's flags are read by deliver(), under the hub mutex as this is
  if (options_.deliver) return Pushed::deliver;
  bool dropped_one = false;
  bool wake = false;
  {
    std::lock_guard lock(mutex_);
    if (closed_) return Pushed::no;
    const bool first = wants_first_;
    wants_first_ = false;
    if (!due && !first) return Pushed::no;
    if (queue_.size() >= std::max<std::size_t>(1, options_.capacity)) {
      queue_.pop_front();
      dropped_.fetch_add(1, std::memory_order_relaxed);
      dropped_one = true;
    }
    queue_.push_back(sample);
    delivered_.fetch_add(1, std::memory_order_relaxed);
    wake = wake_armed_;
    wake_armed_ = false;
  }
  if (dropped_one) log_first_drop();
  return wake ? Pushed::wake : Pushed::queued;
}

void StreamSubscription::deliver(const StreamSample& sample, bool due) {
  // under the hub mutex, which unsubscribe() and the stream's removal take to take this
  // subscription off its stream: once they have returned, nothing is being delivered
  const bool first = wants_first_;
  wants_first_ = false;
  if (!due && !first) return;
  bool sent = false;
  std::string failure;  // the first time the transport threw (logged once)
  try {
    sent = options_.deliver(sample);
  } catch (const std::exception& e) {
    if (!failure_logged_) failure = e.what();
    failure_logged_ = true;
  }
  delivered_.fetch_add(1, std::memory_order_relaxed);
  if (!sent) dropped_.fetch_add(1, std::memory_order_relaxed);
  if (!failure.empty())
    log::warning(
        component_,
        " stream: ", options_.label.empty() ? std::string("a subscriber") : options_.label,
        " could not send a sample (logged once; simulation get_stream_statistics counts them as "
        "dropped): ",
        failure);
  else if (!sent)
    log_first_drop();
}

void StreamSubscription::close() {
  std::lock_guard lock(mutex_);
  closed_ = true;
  wake_armed_ = false;
}

void StreamSubscription::log_first_drop() {
  {
    std::lock_guard lock(mutex_);
    if (drop_logged_) return;
    drop_logged_ = true;
  }
  log::warning(
      component_,
      " stream: ", options_.label.empty() ? std::string("a subscriber") : options_.label,
      " reads slower than samples come; its oldest samples are dropped (this is logged once; "
      "simulation get_stream_statistics counts them)");
}

// ---------------------------------------------------------------------------------------
// StreamOutlet

bool StreamOutlet::push(double time, json data, std::shared_ptr<const StreamPayload> payload) {
  if (!hub_ || !wanted()) return false;
  return hub_->push(component_, time, std::move(data), std::move(payload));
}

void StreamOutlet::note_skipped() {
  if (hub_) hub_->note_skipped(component_);
}

// ---------------------------------------------------------------------------------------
// StreamHub

struct StreamHub::Due {
  Stream* stream;
  bool due;                              // by its frequency (else only its new subscribers get it)
  std::shared_ptr<StreamSample> sample;  // once produced
  bool queued = false;                   // a subscriber's queue took the sample
};

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
