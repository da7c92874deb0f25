// DdsClient::Impl's replies: taken from the reply reader (and raw images from the image
// reader) by the status thread or by the caller that waits on DDS (await: one reader at a
// time, the others wait for their slot), filed in their call's slot, and a call waited for
// until its final reply and every image it announces are there (wait_accepted, wait). The
// entities and calls sent: dds_client_impl.cc.
#include <mutex>
#include <optional>
#include <utility>
#include <vector>

#include "dds_client_impl.h"
#include "dds_support.h"
#include "simgate_streams.h"

namespace simgate::client {

namespace {

// The records of a result that images may belong to: the result, or the items of its list.
std::vector<const json*> image_records(const std::optional<json>& value) {
  std::vector<const json*> records;
  if (!value) return records;
  if (value->is_object()) {
    records.push_back(&*value);
  } else if (value->is_array()) {
    for (const json& record : *value) records.push_back(&record);
  }
  return records;
}

bool is_raw(const json& record) {
  auto format = record.find("format");
  return record.is_object() && format != record.end() && *format == "raw";
}

// How many of a final result's records say their pixels come raw on simgate_ReplyImage.
std::size_t raw_count(const std::optional<json>& value) {
  std::size_t n = 0;
  for (const json* record : image_records(value)) n += is_raw(*record) ? 1 : 0;
  return n;
}

// An image of simgate_ReplyImage as a payload: the bytes copied, described as the camera
// describes its own (sim/src/cameras.cc), `timestamp` being Image.time.
std::shared_ptr<const StreamPayload> to_payload(const simgate_stream_Image& image) {
  auto payload = std::make_shared<StreamPayload>();
  payload->content = "image";
  json k = json::array();
  for (int row = 0; row < 3; ++row)
    k.push_back({image.K[row * 3], image.K[row * 3 + 1], image.K[row * 3 + 2]});
  payload->description = {{"component", image.component ? image.component : ""},
                          {"width", image.width},
                          {"height", image.height},
                          {"encoding", image.encoding ? image.encoding : ""},
                          {"step", image.step},
                          {"is_bigendian", image.is_bigendian},
                          {"intrinsic_matrix", std::move(k)},
                          {"timestamp", image.time}};
  if (image.data._length > 0)
    payload->bytes.assign(image.data._buffer, image.data._buffer + image.data._length);
  return payload;
}

// Replies for another client's id (only a writer that is not the server's would put one in
json parse_or_string(const char* text) {
  json value = json::parse(text, nullptr, false);
  return value.is_discarded() ? json(text) : value;
}

}  // namespace

void DdsClient::Impl::take_replies() {
  constexpr int batch = 16;
  void* samples[batch];
  dds_sample_info_t infos[batch];
  for (;;) {
    samples[0] = nullptr;
    dds_return_t n = dds_take(reply_reader_, samples, infos, batch, batch);
    if (n <= 0) return;
    {
      std::lock_guard lock(mutex_);
      for (dds_return_t i = 0; i < n; ++i) {
        if (!infos[i].valid_data) continue;
        const auto& reply = *static_cast<const simgate_Reply*>(samples[i]);
        // a refused duplicate of a seq: not about our call of that seq (we never send one)
        if (reply.status == simgate_ST_REFUSED) continue;
        auto it = slots_.find(reply.seq);
        if (it == slots_.end()) continue;  // nobody waits any more
        Slot& slot = it->second;
        slot.accepted = true;
        if (reply.status == simgate_ST_ACCEPTED && !reply.last) continue;
        Outcome outcome;
        switch (reply.status) {
          case simgate_ST_FAILED: outcome.status = Status::failed; break;
          case simgate_ST_PREEMPTED: outcome.status = Status::preempted; break;
          default: outcome.status = Status::success; break;
        }
        outcome.failure = dds::from_wire(reply.failure);
        if (reply.result && *reply.result) outcome.value = parse_or_string(reply.result);
        if (reply.message) outcome.message = reply.message;
        if (reply.data && *reply.data) outcome.data = parse_or_string(reply.data);
        // its images, written before it, may still be on their way (another topic)
        if (image_reader_ > 0 && outcome.status == Status::success)
          slot.raw = raw_count(outcome.value);
        slot.outcome = std::move(outcome);
      }
      changed_.notify_all();
    }
    dds_return_loan(reply_reader_, samples, n);
    if (n < batch) return;
  }
}

void DdsClient::Impl::take_images() {
  if (image_reader_ <= 0) return;
  // the status thread and the reading caller both take: one at a time, or a later batch could
  // be filed before an earlier one
  std::lock_guard take_lock(take_images_mutex_);
  constexpr int batch = 4;
  void* samples[batch];
  dds_sample_info_t infos[batch];
  for (;;) {
    samples[0] = nullptr;
    dds_return_t n = dds_take(image_reader_, samples, infos, batch, batch);
    if (n <= 0) return;
    // copied out of Cyclone's samples before taking the lock
    std::vector<std::pair<CallId, std::shared_ptr<const StreamPayload>>> images;
    for (dds_return_t i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      const auto& image = *static_cast<const simgate_stream_Image*>(samples[i]);
      images.emplace_back(image.seq, to_payload(image));
    }
    dds_return_loan(image_reader_, samples, n);
    {
      std::lock_guard lock(mutex_);
      for (auto& [seq, payload] : images) {
        auto it = slots_.find(seq);
        if (it == slots_.end()) continue;  // nobody waits any more
        it->second.images.push_back(std::move(payload));
      }
      changed_.notify_all();
    }
    if (n < batch) return;
  }
}

template <class Done>
bool DdsClient::Impl::await(std::unique_lock<std::mutex>& lock,
                            std::chrono::steady_clock::time_point deadline, Done done) {
  for (;;) {
    if (done()) return true;
    auto now = std::chrono::steady_clock::now();
    if (now >= deadline) return false;
    if (reading_) {
      // another caller reads: it hands us our reply, or the role when it leaves
      changed_.wait_until(lock, deadline);
      continue;
    }
    // be the reader: wait on the reply reader (or the guard), take every reply there is
    reading_ = true;
    lock.unlock();
    auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(deadline - now).count();
    dds_waitset_wait(reader_waitset_, nullptr, 0, static_cast<dds_duration_t>(left));
    bool ignored;
    dds_take_guardcondition(reader_guard_, &ignored);
    take_images();
    take_replies();
    lock.lock();
    reading_ = false;
    // a waiting caller takes over the role (or finds its reply)
    changed_.notify_all();
  }
}

bool DdsClient::Impl::wait_accepted(CallId id, std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  // looked up each time: another thread may wait() for the same call and consume it
  auto accepted = [&] {
    auto it = slots_.find(id);
    return it == slots_.end() || it->second.accepted || !it->second.error.empty();
  };
  await(lock, std::chrono::steady_clock::now() + timeout, accepted);
  auto it = slots_.find(id);
  return it != slots_.end() && it->second.accepted;
}

Outcome DdsClient::Impl::wait(CallId id, std::chrono::milliseconds timeout,
                              std::chrono::milliseconds whole) {
  std::unique_lock lock(mutex_);
  // the final reply and the images it announces (both topics: either may come first)
  auto finished = [&] {
    auto it = slots_.find(id);
    return it == slots_.end() || it->second.complete() || !it->second.error.empty();
  };
  if (slots_.find(id) == slots_.end())
    throw ClientError("DDS client: no call " + std::to_string(id) + " to wait for");
  await(lock, std::chrono::steady_clock::now() + timeout, finished);
  auto it = slots_.find(id);
  if (it == slots_.end())
    throw ClientError("DDS client: call " + std::to_string(id) + " was consumed by another wait()");
  Slot slot = std::move(it->second);
  slots_.erase(it);
  lock.unlock();
  if (slot.complete()) {
    // the images, one per record, beside the records that say "format": "raw"
    Outcome outcome = std::move(*slot.outcome);
    if (slot.raw > 0) {
      const std::vector<const json*> records = image_records(outcome.value);
      outcome.attachments.resize(records.size());
      std::size_t next = 0;
      for (std::size_t i = 0; i < records.size(); ++i)
        if (is_raw(*records[i])) outcome.attachments[i] = std::move(slot.images[next++]);
    }
    return outcome;
  }
  const std::string within = std::to_string((whole.count() > 0 ? whole : timeout).count()) + " ms";
  if (!slot.error.empty()) throw ClientError(slot.error);
  if (slot.outcome)
    throw ClientError("DDS client: call " + std::to_string(id) + " replied, but only " +
                      std::to_string(slot.images.size()) + " of the " + std::to_string(slot.raw) +
                      " raw images its reply announces came within " + within);
  throw ClientError("DDS client: no reply to call " + std::to_string(id) + " within " + within);
}

}  // namespace simgate::client
