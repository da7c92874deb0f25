#include "simgate/client/dds_client.h"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <thread>
#include <unordered_map>
#include <vector>

#include "dds_catalog.h"
#include "dds_support.h"
#include "simgate/core/config.h"
#include "simgate/core/request_manager.h"
#include "simgate/core/streams.h"
#include "simgate_streams.h"

namespace simgate::client {

using dds::ClientId;
using dds::retcode_text;
using dds_catalog::check;

namespace {

constexpr dds_attach_t k_token_guard = 2;
constexpr dds_attach_t k_token_status = 3;

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
// our partition) never reach our reader.
bool is_ours(const void* sample, void* arg) {
  return std::memcmp(static_cast<const simgate_Reply*>(sample)->client, arg, 16) == 0;
}

json parse_or_string(const char* text) {
  json value = json::parse(text, nullptr, false);
  return value.is_discarded() ? json(text) : value;
}

// Why a simulation may be invisible: the network settings both sides must share.
std::string network_hint(const std::string& config) {
  std::string mine;
  if (config.empty()) {
    mine = "simgate's loopback-only settings (the default)";
  } else if (config == "env") {
    const char* uri = std::getenv("CYCLONEDDS_URI");
    mine = uri && *uri ? "CYCLONEDDS_URI=" + std::string(uri)
                       : "Cyclone's default network settings (CYCLONEDDS_URI is not set)";
  } else if (config.find('<') == std::string::npos) {
    mine = "the settings of " + config;
  } else {
    mine = "the Cyclone XML it was given";
  }
  return "The simulation and this client must share the domain, the partition and the Cyclone "
         "network settings: "
         "this client uses " +
         mine +
         "; a simulation's dds transport uses loopback only unless its \"config\" "
         "option says otherwise (simgate call --dds-config: XML, a file:// URI, or env for "
         "CYCLONEDDS_URI).";
}

// A participant of the options' domain, with their network settings (ClientError when Cyclone
// refuses them).
std::unique_ptr<dds::Participant> join_domain(const DdsClientOptions& options) {
  try {
    return std::make_unique<dds::Participant>(
        options.domain, dds::resolve_config(options.config),
        "DDS client (domain " + std::to_string(options.domain) + ")");
  } catch (const std::runtime_error& e) {
    throw ClientError(e.what());
  }
}

}  // namespace

DdsClientOptions DdsClientOptions::from_json(const json& options) {
  try {
    ConfigObject config(options.is_null() ? json::object() : options, "dds client");
    DdsClientOptions out;
    out.domain = static_cast<std::uint32_t>(config.get_int("domain", 0, 0, 230));
    out.partition = config.get_string("partition", out.partition);
    out.config = config.get_string("config", "");
    out.discovery_timeout = std::chrono::milliseconds(
        config.get_int("discovery_timeout_ms", out.discovery_timeout.count(), 0, 3'600'000));
    out.raw_images = config.get_bool("raw_images", out.raw_images);
    config.finish();
    return out;
  } catch (const ConfigError& e) {
    throw ClientError(e.what());
  }
}

class DdsClient::Impl {
 public:
  // The state of one call (or cancel) until its final reply is consumed.
  struct Slot {
    bool accepted = false;           // ST_ACCEPTED seen (or final reply)
    std::optional<Outcome> outcome;  // the final reply
    std::size_t raw = 0;             // how many of its records say "format": "raw"
    std::vector<std::shared_ptr<const StreamPayload>> images;  // simgate_ReplyImage of its
                                                               // seq, in arrival (= record) order
    std::string error;                                         // the server went away

    // The final reply and every image it announces are here.
    bool complete() const { return outcome && images.size() >= raw; }
  };

  explicit Impl(DdsClientOptions options);
  ~Impl();

  bool wait_for_server(std::chrono::milliseconds timeout);
  // Waits up to `discovery` for a server, then writes the request; returns its seq.
  CallId send(simgate_Op op, const std::string& component, const std::string& service,
              const json& params, CallId target, std::chrono::milliseconds discovery);
  bool wait_accepted(CallId id, std::chrono::milliseconds timeout);
  // `whole`: the caller's whole timeout when part of it went into finding a server (for
  // the message); 0 = `timeout`.
  Outcome wait(CallId id, std::chrono::milliseconds timeout, std::chrono::milliseconds whole = {});
  json list_services(std::chrono::milliseconds timeout);

  // Caller's thread, with `lock` (on mutex_) held: returns true once done() holds, false at
  // the deadline. The first waiter without a reader becomes the reader: it waits on the
  // reply reader itself and takes every reply (its own and the other callers'); the others
  // wait on changed_ until their reply is in their slot or the reader role is free.
  template <class Done>
  bool await(std::unique_lock<std::mutex>& lock, std::chrono::steady_clock::time_point deadline,
             Done done);

  DdsClientOptions options_;                       // as given
  std::unique_ptr<dds::Participant> participant_;  // owns every entity
  ClientId client_id_{};                           // our request writer's GUID
  std::string id_hex_;                             // the same, hex
  dds_entity_t publisher_ = 0;                     // in the partition
  dds_entity_t reply_subscriber_ = 0;              // in "<partition>/<id_hex_>"
  dds_entity_t request_writer_ = 0;                // simgate_Request
  dds_entity_t reply_reader_ = 0;                  // simgate_Reply, filtered on client_id_
  dds_entity_t image_reader_ = 0;                  // simgate_ReplyImage (raw_images only)
  dds_entity_t waitset_ = 0, guard_ = 0;           // the status thread's waitset and its stop guard
  dds_entity_t reader_waitset_ = 0;                // the reading caller's waitset
  dds_entity_t read_condition_ = 0;                // replies available (on reader_waitset_)
  dds_entity_t image_condition_ = 0;               // images available (on reader_waitset_)
  dds_entity_t reader_guard_ = 0;                  // wakes the reading caller (match change, stop)
  std::atomic<CallId> next_seq_{1};                // call numbering

  std::mutex take_images_mutex_;            // one take_images() at a time (taken before
                                            // mutex_): a call's images stay in order
  std::mutex mutex_;                        // guards everything below
  std::condition_variable changed_;         // a reply, a match, or stop
  std::unordered_map<CallId, Slot> slots_;  // calls not yet consumed
  int server_readers_ = 0;                  // matched request readers
  int server_writers_ = 0;                  // matched reply writers
  bool reading_ = false;                    // a caller is the reader (see await)
  bool stopping_ = false;                   // the status thread must leave
  std::mutex catalog_mutex_;                // one list_services at a time
  std::unique_ptr<dds_catalog::CatalogReader> catalog_;  // created by the first list_services

  std::thread thread_;  // the status thread

 private:
  void run();
  void take_replies();
  void take_images();
  void update_matches();
};

DdsClient::Impl::Impl(DdsClientOptions options) : options_(std::move(options)) {
  if (is_partition_pattern(options_.partition))
    throw ClientError("DDS client: partition '" + options_.partition +
                      "' is a pattern: a client calls one simgate, in the partition it names "
                      "(list_simgates, `simgate list --partition PATTERN`, lists those a "
                      "pattern matches)");
  participant_ = join_domain(options_);
  dds_entity_t pp = participant_->handle();
  dds::QosPtr partition_qos(dds_create_qos());
  dds_qset_partition1(partition_qos.get(), options_.partition.c_str());
  publisher_ = check(dds_create_publisher(pp, partition_qos.get(), nullptr), "publisher");

  // the request writer; its GUID is our id
  dds_entity_t request_topic =
      check(dds_create_topic(pp, &simgate_Request_desc, dds::k_request_topic, nullptr, nullptr),
            "topic simgate_Request");
  dds::QosPtr request_qos = dds::make_qos(false, 0, DDS_SECS(1));
  request_writer_ = check(dds_create_writer(publisher_, request_topic, request_qos.get(), nullptr),
                          "request writer");
  dds_guid_t guid;
  check(dds_get_guid(request_writer_, &guid), "client id");
  client_id_ = dds::to_client_id(guid);
  id_hex_ = dds::to_hex(client_id_);

  // the reply reader: in our own partition, where the server writes our replies with a writer
  // of ours alone; only our instance; announced so the server knows when it matched
  dds::QosPtr reply_partition_qos(dds_create_qos());
  const std::string reply_partition = options_.partition + "/" + id_hex_;
  dds_qset_partition1(reply_partition_qos.get(), reply_partition.c_str());
  reply_subscriber_ =
      check(dds_create_subscriber(pp, reply_partition_qos.get(), nullptr), "reply subscriber");
  dds_entity_t reply_topic =
      check(dds_create_topic(pp, &simgate_Reply_desc, dds::k_reply_topic, nullptr, nullptr),
            "topic simgate_Reply");
  dds_topic_filter filter{};
  filter.mode = DDS_TOPIC_FILTER_SAMPLE_ARG;
  filter.f.sample_arg = &is_ours;
  filter.arg = client_id_.data();
  check(dds_set_topic_filter_extended(reply_topic, &filter), "reply filter");
  dds::QosPtr reply_qos = dds::make_qos(false, 0, DDS_SECS(1));
  std::string userdata = "simgate.role=client;simgate.v=2;simgate.id=" + id_hex_;
  dds_qset_userdata(reply_qos.get(), userdata.data(), userdata.size());
  // raw images: their reader first, announced as the reply reader is (the server discovers a
  // participant's endpoints in the order they were created: when it has matched our reply
  // reader, it knows this one, and the images of our first call already come raw)
  if (options_.raw_images) {
    dds_entity_t image_topic = check(dds_create_topic(pp, &simgate_stream_Image_desc,
                                                      dds::k_reply_image_topic, nullptr, nullptr),
                                     "topic simgate_ReplyImage");
    image_reader_ =
        check(dds_create_reader(reply_subscriber_, image_topic, reply_qos.get(), nullptr),
              "image reader");
  }
  reply_reader_ = check(dds_create_reader(reply_subscriber_, reply_topic, reply_qos.get(), nullptr),
                        "reply reader");

  // callers wait for replies themselves (one at a time is the reader: see await)
  reader_waitset_ = check(dds_create_waitset(pp), "reply waitset");
  read_condition_ = check(dds_create_readcondition(reply_reader_, DDS_ANY_STATE), "read condition");
  reader_guard_ = check(dds_create_guardcondition(pp), "reply guard condition");
  check(dds_waitset_attach(reader_waitset_, read_condition_, 0), "waitset attachment");
  check(dds_waitset_attach(reader_waitset_, reader_guard_, 0), "waitset attachment");
  if (image_reader_ > 0) {
    image_condition_ =
        check(dds_create_readcondition(image_reader_, DDS_ANY_STATE), "image read condition");
    check(dds_waitset_attach(reader_waitset_, image_condition_, 0), "waitset attachment");
  }

  // the status thread waits for match changes and stop
  waitset_ = check(dds_create_waitset(pp), "waitset");
  guard_ = check(dds_create_guardcondition(pp), "guard condition");
  dds_set_status_mask(reply_reader_, DDS_SUBSCRIPTION_MATCHED_STATUS);
  dds_set_status_mask(request_writer_, DDS_PUBLICATION_MATCHED_STATUS);
  check(dds_waitset_attach(waitset_, guard_, k_token_guard), "waitset attachment");
  check(dds_waitset_attach(waitset_, reply_reader_, k_token_status), "waitset attachment");
  check(dds_waitset_attach(waitset_, request_writer_, k_token_status), "waitset attachment");
  thread_ = std::thread([this] { run(); });
}

DdsClient::Impl::~Impl() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  if (guard_ > 0) dds_set_guardcondition(guard_, true);
  if (thread_.joinable()) thread_.join();
  catalog_.reset();
  participant_.reset();
}

void DdsClient::Impl::run() {
  update_matches();
  dds_attach_t triggered[8];
  for (;;) {
    {
      std::lock_guard lock(mutex_);
      if (stopping_) return;
    }
    dds_return_t n = dds_waitset_wait(waitset_, triggered, 8, DDS_SECS(1));
    if (n < 0) return;
    bool status = false;
    for (dds_return_t i = 0; i < std::min<dds_return_t>(n, 8); ++i)
      status |= triggered[i] == k_token_status;
    if (status) update_matches();
  }
}

void DdsClient::Impl::update_matches() {
  // reading the statuses resets them
  dds_publication_matched_status_t pub{};
  dds_subscription_matched_status_t sub{};
  dds_get_publication_matched_status(request_writer_, &pub);
  dds_get_subscription_matched_status(reply_reader_, &sub);
  // replies (and images) already received are outcomes, not losses
  take_images();
  take_replies();
  std::lock_guard lock(mutex_);
  server_readers_ = static_cast<int>(pub.current_count);
  server_writers_ = static_cast<int>(sub.current_count);
  // no server left: nobody will answer the calls in flight
  if (server_writers_ == 0 || server_readers_ == 0) {
    for (auto& [id, slot] : slots_)
      if (!slot.complete() && slot.error.empty())
        slot.error =
            "DDS client: the server of partition '" + options_.partition + "' (domain " +
            std::to_string(options_.domain) + ") went away before answering call " +
            std::to_string(id) +
            (slot.outcome ? " (its reply came, " + std::to_string(slot.images.size()) + " of its " +
                                std::to_string(slot.raw) + " raw images did not)"
                          : std::string());
  }
  changed_.notify_all();
  // the reading caller waits on DDS, not on changed_
  if (reading_) dds_set_guardcondition(reader_guard_, true);
}

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

bool DdsClient::Impl::wait_for_server(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  return changed_.wait_for(lock, timeout,
                           [&] { return server_readers_ > 0 && server_writers_ > 0; });
}

DdsClient::CallId DdsClient::Impl::send(simgate_Op op, const std::string& component,
                                        const std::string& service, const json& params,
                                        CallId target, std::chrono::milliseconds discovery) {
  if (!wait_for_server(discovery)) {
    std::string found;
    {
      std::lock_guard lock(mutex_);
      found = server_readers_ > 0   ? "found its request reader only"
              : server_writers_ > 0 ? "found its reply writer only"
                                    : "found neither";
    }
    throw ClientError(
        "DDS client: no simgate simulation in domain " + std::to_string(options_.domain) +
        ", partition '" + options_.partition + "' within " + std::to_string(discovery.count()) +
        " ms: waited for a simulation's request reader and reply writer to match this client (" +
        found + "). " + network_hint(options_.config));
  }
  CallId seq = next_seq_++;
  {
    std::lock_guard lock(mutex_);
    slots_.emplace(seq, Slot{});
  }
  std::string params_text = params.is_null()
                                ? std::string()
                                : params.dump(-1, ' ', false, json::error_handler_t::replace);
  simgate_Request request{};
  std::memcpy(request.id.client, client_id_.data(), client_id_.size());
  request.id.seq = seq;
  request.op = op;
  request.component = const_cast<char*>(component.c_str());
  request.service = const_cast<char*>(service.c_str());
  request.params = const_cast<char*>(params_text.c_str());
  request.target = target;
  dds_return_t rc = dds_write(request_writer_, &request);
  if (rc < 0) {
    std::lock_guard lock(mutex_);
    slots_.erase(seq);
    throw ClientError("DDS client: request " + component + "." + service +
                      " not sent: " + retcode_text(rc));
  }
  return seq;
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

json DdsClient::Impl::list_services(std::chrono::milliseconds timeout) {
  std::lock_guard lock(catalog_mutex_);
  // created once: transient-local, so it receives what was published before
  if (!catalog_)
    catalog_ =
        std::make_unique<dds_catalog::CatalogReader>(participant_->handle(), options_.partition);
  const auto catalogs =
      catalog_->read(std::chrono::steady_clock::now() + timeout, std::chrono::milliseconds(0));
  if (catalogs.empty())
    throw ClientError(
        "DDS client: no simgate simulation in domain " + std::to_string(options_.domain) +
        ", partition '" + options_.partition + "' within " + std::to_string(timeout.count()) +
        " ms: waited for a simulation's catalog of services. " + network_hint(options_.config));
  // one server per partition is the rule; were there more, a component listed once
  std::map<std::string, json> by_component;
  for (const auto& catalog : catalogs)
    for (const auto& [component, services] : catalog.services) by_component[component] = services;
  json out = json::array();
  for (auto& [component, services] : by_component)
    for (auto& service : services) out.push_back(std::move(service));
  return out;
}

// ---------------------------------------------------------------------------------------

DdsClient::DdsClient(DdsClientOptions options)
    : impl_(std::make_unique<Impl>(std::move(options))) {}
DdsClient::~DdsClient() = default;

bool DdsClient::wait_for_server(std::chrono::milliseconds timeout) {
  return impl_->wait_for_server(timeout);
}

DdsClient::CallId DdsClient::start(const std::string& component, const std::string& service,
                                   const json& params) {
  return impl_->send(simgate_OP_CALL, component, service, params, 0,
                     impl_->options_.discovery_timeout);
}

bool DdsClient::wait_accepted(CallId id, std::chrono::milliseconds timeout) {
  return impl_->wait_accepted(id, timeout);
}

Outcome DdsClient::wait(CallId id, std::chrono::milliseconds timeout) {
  return impl_->wait(id, timeout);
}

namespace {

// What is left of `timeout` since `started` (zero at least).
std::chrono::milliseconds left_of(std::chrono::milliseconds timeout,
                                  std::chrono::steady_clock::time_point started) {
  auto spent = std::chrono::duration_cast<std::chrono::milliseconds>(
      std::chrono::steady_clock::now() - started);
  return std::max(timeout - spent, std::chrono::milliseconds(0));
}

}  // namespace

bool DdsClient::cancel(CallId id, std::chrono::milliseconds timeout) {
  // the timeout bounds the whole cancel, finding the server included
  auto started = std::chrono::steady_clock::now();
  CallId seq = impl_->send(simgate_OP_CANCEL, "", "", nullptr, id, timeout);
  Outcome answer = impl_->wait(seq, left_of(timeout, started), timeout);
  return answer.value && answer.value->is_boolean() && answer.value->get<bool>();
}

Outcome DdsClient::call(const std::string& component, const std::string& service,
                        const json& params, std::chrono::milliseconds timeout) {
  // the timeout bounds the whole call, finding the server included (not discovery_timeout)
  auto started = std::chrono::steady_clock::now();
  CallId seq = impl_->send(simgate_OP_CALL, component, service, params, 0, timeout);
  return impl_->wait(seq, left_of(timeout, started), timeout);
}

json DdsClient::list_services(std::chrono::milliseconds timeout) {
  return impl_->list_services(timeout);
}

void DdsClient::login(const std::string&, std::chrono::milliseconds) {
  throw ClientError("dds client: " + std::string(k_dds_has_no_token));
}

const std::string& DdsClient::id() const { return impl_->id_hex_; }

bool is_partition_pattern(std::string_view partition) {
  return partition.find_first_of("*?") != std::string_view::npos;
}

json DdsSimgate::to_json() const {
  json out = {
      {"partition", partition}, {"server", server}, {"worlds", worlds}, {"services", services}};
  if (!whole) out["whole"] = false;
  return out;
}

std::vector<DdsSimgate> list_simgates(const DdsClientOptions& options,
                                      std::chrono::milliseconds timeout,
                                      std::chrono::milliseconds settle) {
  const std::unique_ptr<dds::Participant> participant = join_domain(options);
  std::vector<dds_catalog::ServerCatalog> catalogs;
  {
    dds_catalog::CatalogReader reader(participant->handle(), options.partition);
    catalogs = reader.read(std::chrono::steady_clock::now() + timeout, settle);
  }
  if (catalogs.empty())
    throw ClientError("DDS client: no simgate in domain " + std::to_string(options.domain) +
                      " whose partition matches '" + options.partition + "' within " +
                      std::to_string(timeout.count()) +
                      " ms: waited for catalogs (simgate_Catalog) in the partitions it "
                      "matches. " +
                      network_hint(options.config));
  std::vector<DdsSimgate> out;
  for (auto& catalog : catalogs) {
    DdsSimgate simgate{catalog.partition, catalog.server, {}, json::array(), catalog.whole};
    std::set<unsigned> worlds;
    for (auto& [component, services] : catalog.services) {
      auto address = RequestManager::world_address(component);
      worlds.insert(address ? address->first : 0);
      for (auto& service : services) simgate.services.push_back(std::move(service));
    }
    for (unsigned world : worlds) simgate.worlds.push_back("w" + std::to_string(world));
    out.push_back(std::move(simgate));
  }
  return out;
}

std::unique_ptr<Client> make_dds_client(const json& options) {
  return std::make_unique<DdsClient>(DdsClientOptions::from_json(options));
}

}  // namespace simgate::client
