// stream_samples.cc — what a stream's samples travel in: the sample (its JSON and text made
// once, on the first thread that asks), a subscriber's queue of the latest N
// (StreamSubscription: drops counted and logged once, the transport woken when it stops being
// empty, or a direct subscriber written at once) and a pushed stream's outlet
// (StreamOutlet). The hub that makes and fans out the samples: streams.cc.
#include <algorithm>
#include <stdexcept>

#include "simgate/core/log.h"
#include "simgate/core/streams.h"

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

}  // namespace simgate
