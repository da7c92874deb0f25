#include "simgate/core/component.h"
#include "simgate/core/streams.h"

#include <stdexcept>

#include "simgate/core/log.h"

namespace simgate {

Component::Component(std::string name)
    : name_(std::move(name)), slot_(std::make_shared<AsyncSlot>()) {
  slot_->component = name_;
  slot_->interrupt = [this] { interrupt(); };
}

void Component::interrupt() {
  // MORSE's default: the running request ends PREEMPTED
  if (slot_->busy()) slot_->running_completion(Status::preempted);
}

void Component::completed(Status status, json result) {
  if (!slot_->busy()) {
    log::warning(name_, ": completed(", to_string(status), ") with no async request running");
    return;
  }
  slot_->running_completion(status, std::move(result));
}

bool Component::progress(json value) {
  return slot_->busy() && slot_->running_completion.progress(std::move(value));
}

bool Component::progress_due() const {
  return slot_->busy() && slot_->running_completion.progress_due();
}

std::string Component::running_service() const {
  return slot_->busy() ? slot_->running->service : std::string();
}

const char* to_string(StreamDirection direction) {
  return direction == StreamDirection::in ? "IN" : "OUT";
}

void Component::declare_output_stream(std::string kind, std::function<json()> produce) {
  stream_ = StreamDeclaration{
      StreamDirection::out, std::move(kind), std::move(produce), {}, {}, {}, nullptr, 0};
}

json record_json(const std::vector<std::string>& fields, std::span<const double> values) {
  json out = json::object();
  for (std::size_t i = 0; i < fields.size() && i < values.size(); ++i) out[fields[i]] = values[i];
  return out;
}

void Component::declare_output_stream(std::string kind, std::vector<std::string> fields,
                                      std::function<void(std::span<double>)> produce) {
  if (fields.empty() || fields.size() > k_max_record_fields)
    throw std::invalid_argument(name_ + ": a record stream has 1 to " +
                                std::to_string(k_max_record_fields) + " numbers, not " +
                                std::to_string(fields.size()));
  auto as_json = [fields, produce] {
    double values[k_max_record_fields];
    produce(std::span<double>(values, fields.size()));
    return record_json(fields, std::span<const double>(values, fields.size()));
  };
  stream_ = StreamDeclaration{StreamDirection::out,
                              std::move(kind),
                              std::move(as_json),
                              {},
                              std::move(fields),
                              std::move(produce),
                              nullptr,
                              0};
}

void Component::declare_pushed_stream(std::string kind, double frequency) {
  if (!(frequency > 0))
    throw std::invalid_argument(name_ + ": a pushed stream's frequency must be > 0");
  stream_ = StreamDeclaration{StreamDirection::out,
                              std::move(kind),
                              {},
                              {},
                              {},
                              {},
                              std::make_shared<StreamOutlet>(name_),
                              frequency};
}

void Component::declare_event_stream(std::string kind) {
  stream_ = StreamDeclaration{StreamDirection::out,
                              std::move(kind),
                              {},
                              {},
                              {},
                              {},
                              std::make_shared<StreamOutlet>(name_),
                              0};
}

bool Component::stream_wanted() const {
  return stream_ && stream_->outlet && stream_->outlet->wanted();
}

void Component::note_skipped_sample() {
  if (stream_ && stream_->outlet) stream_->outlet->note_skipped();
}

bool Component::push_sample(double time, json data) {
  if (!stream_ || !stream_->outlet) return false;
  return stream_->outlet->push(time, std::move(data), nullptr);
}

bool Component::push_sample(double time, std::shared_ptr<const StreamPayload> payload) {
  if (!stream_ || !stream_->outlet || !payload) return false;
  return stream_->outlet->push(time, nullptr, std::move(payload));
}

void Component::declare_input_stream(std::string kind, std::vector<std::string> fields,
                                     std::function<void(const json&)> apply) {
  stream_ = StreamDeclaration{StreamDirection::in,
                              std::move(kind),
                              {},
                              std::move(apply),
                              std::move(fields),
                              {},
                              nullptr,
                              0};
}

ServiceBuilder Component::adopt(std::shared_ptr<Service> service) {
  if (service->descriptor().is_async) service->set_slot(slot_);
  for (auto& existing : services_)
    if (existing->descriptor().name == service->descriptor().name) {
      existing = std::move(service);
      return ServiceBuilder(*existing);
    }
  services_.push_back(std::move(service));
  return ServiceBuilder(*services_.back());
}

}  // namespace simgate
