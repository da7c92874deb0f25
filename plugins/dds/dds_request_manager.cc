// The DDS transport: its options, its Cyclone entities, the DDS thread (waitset loop) and
// the catalog. The requests taken from the request topic and handed to the core, and the
// replies made of outcomes and refusals: dds_requests.cc; the per-client reply writers
// (clients, replies, parking): dds_reply_writers.cc.
#include "dds_request_manager.h"

#include <algorithm>
#include <array>
#include <stdexcept>

#include "cyclone_config.h"
#include "simgate/core/config.h"
#include "simgate/core/log.h"
#include "simgate/core/plugin.h"
#include "simgate_streams.h"

namespace simgate::dds {

namespace {

// Waitset attachment tokens: which entity woke the DDS thread. A client's reply writer is
// attached with its own (positive) entity handle as token.
constexpr dds_attach_t k_token_requests = -1;
constexpr dds_attach_t k_token_guard = -2;
constexpr dds_attach_t k_token_request_matched = -3;

}  // namespace

DdsOptions DdsOptions::parse(const json& options) {
  ConfigObject config(options, "");
  DdsOptions out;
  out.domain = static_cast<uint32_t>(config.get_int("domain", 0, 0, 230));
  out.partition = config.get_string("partition", out.partition);
  if (out.partition.empty() || out.partition.find_first_of("*?[]") != std::string::npos)
    config.fail("partition", "a non-empty partition name without wildcards (* ? [ ])");
  out.config = config.get_string("config", "");
  out.max_samples =
      static_cast<int32_t>(config.get_int("max_samples", out.max_samples, 1, 1 << 20));
  out.max_in_flight = static_cast<int32_t>(config.get_int(
      "max_in_flight", std::max(1, out.max_samples / 4), 1, std::max(1, out.max_samples / 3)));
  out.park_timeout = std::chrono::milliseconds(
      config.get_int("park_timeout_ms", out.park_timeout.count(), 0, 3'600'000));
  out.max_params = static_cast<std::size_t>(
      config.get_int("max_params", static_cast<long long>(out.max_params), 2, 64ll << 20));
  out.max_depth = static_cast<std::size_t>(
      config.get_int("max_depth", static_cast<long long>(out.max_depth), 2, 10000));
  out.global_policy =
      config.get_choice("global_policy", "reject", {"reject", "preempt"}) == "preempt"
          ? GlobalPolicy::preempt
          : GlobalPolicy::reject;
  out.progress_interval = std::chrono::milliseconds(
      config.get_int("progress_interval_ms", out.progress_interval.count(), 0, 3'600'000));
  out.cancel_on_disconnect =
      config.get_choice("on_disconnect", "cancel", {"cancel", "let_run"}) == "cancel";
  out.direct_stream_writes =
      config.get_choice("stream_writes", "direct", {"direct", "thread"}) == "direct";
  config.finish();
  return out;
}

void DdsRequestManager::validate_options(const json& options) {
  DdsOptions parsed = DdsOptions::parse(options);
  check_cyclone_config(parsed.domain, parsed.config);
}

DdsRequestManager::DdsRequestManager(const json& options)
    : RequestManager("DDS service manager"), options_(DdsOptions::parse(options)) {
  set_global_policy(options_.global_policy);
  set_progress_interval(options_.progress_interval);
  create_entities();
}

DdsRequestManager::~DdsRequestManager() { stop(); }

void DdsRequestManager::create_entities() {
  participant_ =
      std::make_unique<Participant>(options_.domain, resolve_config(options_.config),
                                    "DDS transport (domain " + std::to_string(options_.domain) +
                                        ", partition '" + options_.partition + "')");
  dds_entity_t pp = participant_->handle();
  dds_guid_t guid;
  if (dds_get_guid(pp, &guid) == DDS_RETCODE_OK) server_id_ = to_hex(to_client_id(guid));

  // publisher and subscriber in our partition
  QosPtr partition_qos(dds_create_qos());
  dds_qset_partition1(partition_qos.get(), options_.partition.c_str());
  publisher_ = check_created(dds_create_publisher(pp, partition_qos.get(), nullptr), "publisher");
  subscriber_ =
      check_created(dds_create_subscriber(pp, partition_qos.get(), nullptr), "subscriber");

  dds_entity_t request_topic =
      check_created(dds_create_topic(pp, &simgate_Request_desc, k_request_topic, nullptr, nullptr),
                    "topic simgate_Request");
  dds_entity_t catalog_topic = check_created(
      dds_create_topic(pp, &simgate_CatalogEntry_desc, k_catalog_topic, nullptr, nullptr),
      "topic simgate_Catalog");

  // requests: reliable, keep-all, volatile, bounded (writers block when we fall behind)
  QosPtr request_qos = make_qos(false, 0, DDS_SECS(1));
  dds_qset_resource_limits(request_qos.get(), options_.max_samples, DDS_LENGTH_UNLIMITED,
                           DDS_LENGTH_UNLIMITED);
  request_reader_ = check_created(
      dds_create_reader(subscriber_, request_topic, request_qos.get(), nullptr), "request reader");

  // replies, one writer per client (add_client): reliable, keep-all, volatile, and never
  // blocking: a reader that stops acknowledging fills its own writer's history (up to
  // Cyclone's WHC high-water mark), after which writes to it fail at once (TIMEOUT) instead of
  // holding the DDS thread, and its replies are parked, retried, then dropped
  reply_topic_ =
      check_created(dds_create_topic(pp, &simgate_Reply_desc, k_reply_topic, nullptr, nullptr),
                    "topic simgate_Reply");
  reply_qos_ = make_qos(false, 0, 0);
  dds_qset_resource_limits(reply_qos_.get(), options_.max_samples * 4, DDS_LENGTH_UNLIMITED,
                           DDS_LENGTH_UNLIMITED);
  dds_qset_writer_data_lifecycle(reply_qos_.get(), false);
  std::string userdata = "simgate.role=server;simgate.v=2;simgate.id=" + server_id_;
  dds_qset_userdata(reply_qos_.get(), userdata.data(), userdata.size());

  // progress reports, one writer per client that asks (ensure_progress_writer): best effort,
  // the last report only: never blocking, never lingering when deleted, and a reader that
  // takes nothing loses old reports and holds up no reply
  progress_topic_ =
      check_created(dds_create_topic(pp, &simgate_Reply_desc, k_progress_topic, nullptr, nullptr),
                    "topic simgate_Progress");
  progress_qos_ = make_qos(false, 1, 0);
  dds_qset_reliability(progress_qos_.get(), DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_writer_data_lifecycle(progress_qos_.get(), false);
  dds_qset_userdata(progress_qos_.get(), userdata.data(), userdata.size());

  // replies' images, raw (send_images), one writer per client beside its reply writer:
  // reliable, keep-all, never blocking (a write the writer cannot take leaves the image's PNG
  // in the reply), in the client's partition; only a client with a reader on it gets them
  image_topic_ = check_created(
      dds_create_topic(pp, &simgate_stream_Image_desc, k_reply_image_topic, nullptr, nullptr),
      "topic simgate_ReplyImage");
  image_qos_ = make_qos(false, 0, 0);
  dds_qset_resource_limits(image_qos_.get(), options_.max_samples, DDS_LENGTH_UNLIMITED,
                           DDS_LENGTH_UNLIMITED);
  dds_qset_writer_data_lifecycle(image_qos_.get(), false);
  dds_qset_userdata(image_qos_.get(), userdata.data(), userdata.size());

  // catalog: the last sample of each component, kept for late joiners
  QosPtr catalog_qos = make_qos(true, 1, DDS_SECS(1));
  catalog_writer_ = check_created(
      dds_create_writer(publisher_, catalog_topic, catalog_qos.get(), nullptr), "catalog writer");

  // the waitset of the DDS thread
  waitset_ = check_created(dds_create_waitset(pp), "waitset");
  guard_ = check_created(dds_create_guardcondition(pp), "guard condition");
  read_condition_ =
      check_created(dds_create_readcondition(request_reader_, DDS_ANY_STATE), "read condition");
  dds_set_status_mask(request_reader_, DDS_SUBSCRIPTION_MATCHED_STATUS);
  check_created(dds_waitset_attach(waitset_, read_condition_, k_token_requests),
                "waitset attachment");
  check_created(dds_waitset_attach(waitset_, guard_, k_token_guard), "waitset attachment");
  check_created(dds_waitset_attach(waitset_, request_reader_, k_token_request_matched),
                "waitset attachment");
}

std::vector<std::string> DdsRequestManager::endpoints() const {
  return {"dds:domain=" + std::to_string(options_.domain) + ";partition=" + options_.partition};
}

void DdsRequestManager::start() {
  if (stopped_ || started_.exchange(true)) return;
  // the data streams (issue #21): also with none yet, for those of robots spawned later
  if (streams())
    streams_ = std::make_unique<DdsStreams>(
        streams(), transport_name(), participant_->handle(), publisher_, subscriber_, waitset_,
        server_id_, options_.direct_stream_writes, options_.max_params, options_.max_depth);
  thread_ = std::thread([this] { run(); });
}

void DdsRequestManager::stop() {
  if (stopped_.exchange(true)) return;
  // stop the DDS thread
  stopping_ = true;
  if (guard_ > 0) dds_set_guardcondition(guard_, true);
  if (thread_.joinable()) thread_.join();
  // answer what is still pending (FAILED, shutdown), then leave the domain. From here on
  // outcomes reach on_service_completion under the simulation lock, on the thread that
  // produces them: finished_ is guarded by that lock.
  deliver_on_any_thread();
  {
    std::lock_guard lock(*gate());
    deliver_handed_over();
  }
  if (!batch_.empty()) submit_batch(std::move(batch_));
  abandon_pending();
  if (participant_) {
    try {
      {
        std::lock_guard lock(*gate());
        draining_.swap(finished_);
      }
      write_finished(draining_, true);
    } catch (const std::exception& e) {
      log::error("DDS transport: final replies not sent: ", e.what());
    }
  }
  streams_.reset();  // unsubscribes; its entities go with the participant
  participant_.reset();
}

void DdsRequestManager::on_service_completion(RequestId id, Outcome&& outcome) {
  // the DDS thread (the core hands other threads' outcomes over), inside run_or_submit()
  // under the simulation lock or in deliver_handed_over(): kept until write_finished(),
  // which writes them outside the lock
  finished_.emplace_back(id, std::move(outcome));
}

void DdsRequestManager::on_service_progress(RequestId id, json&& value) {
  // where outcomes go (DDS thread), before the call's outcome; none once stopping (the
  // simulation thread may deliver from then on, and nobody writes them)
  if (stopping_.load(std::memory_order_relaxed)) return;
  progress_.emplace_back(id, std::move(value));
}

// ---------------------------------------------------------------------------------------
// the DDS thread

void DdsRequestManager::run() {
  // outcomes produced on other threads: the guard condition wakes this thread (once per
  // burst), which delivers and writes them
  deliver_on_this_thread([this] { dds_set_guardcondition(guard_, true); });
  try {
    publish_catalog();
    if (streams_) streams_->sync();
  } catch (const std::exception& e) {
    log::error("DDS transport: catalog not published: ", e.what());
  }
  // clients that were matched before the thread started
  sweep_clients();
  constexpr dds_return_t k_slots = 8;
  dds_attach_t triggered[k_slots];
  auto next_parked = std::chrono::steady_clock::time_point::max();
  while (!stopping_) {
    // wait for work, or until a parked reply needs attention
    dds_duration_t timeout = DDS_SECS(1);
    if (parked_count_ > 0) {
      auto left = next_parked - std::chrono::steady_clock::now();
      timeout = std::clamp<dds_duration_t>(
          std::chrono::duration_cast<std::chrono::nanoseconds>(left).count(), DDS_MSECS(1),
          DDS_SECS(1));
    }
    dds_return_t n = dds_waitset_wait(waitset_, triggered, k_slots, timeout);
    if (n < 0) {
      log::error("DDS transport: waitset failed: ", retcode_text(n));
      break;
    }
    bool requests = false, outcomes = false, writers = false, samples = n > k_slots,
         commands = n > k_slots, matched = n > k_slots;
    std::array<dds_entity_t, k_slots> readers;  // reply writers whose match changed
    std::size_t reader_count = 0;
    for (dds_return_t i = 0; i < std::min(n, k_slots); ++i) {
      requests |= triggered[i] == k_token_requests;
      outcomes |= triggered[i] == k_token_guard;
      writers |= triggered[i] == k_token_request_matched;
      samples |= triggered[i] == DdsStreams::k_token_samples;
      commands |= triggered[i] == DdsStreams::k_token_commands;
      matched |= triggered[i] == DdsStreams::k_token_matched;
      if (triggered[i] > 0) readers[reader_count++] = static_cast<dds_entity_t>(triggered[i]);
    }
    try {
      // new clients first, so that their requests find them; then the readers that matched,
      // so that replies find them
      if (writers || n > k_slots) sweep_clients();
      if (n > k_slots) {
        for (auto& [id, client] : clients_) refresh_reader_match(id, client);
      } else {
        for (std::size_t i = 0; i < reader_count; ++i)
          if (auto it = reply_writers_.find(readers[i]); it != reply_writers_.end())
            refresh_reader_match(it->second, clients_.at(it->second));
      }
      // the guard before what raised it is looked at: whatever is handed over, or changes
      // the catalog, from now on raises it again (a robot's components leave one by one, and
      // the catalog written at the first must be written anew at the last)
      if (outcomes) {
        bool ignored;
        dds_take_guardcondition(guard_, &ignored);
      }
      if (catalog_changed_.exchange(false)) {
        publish_catalog();
        if (streams_)
          streams_->sync();  // a component deleted (or spawned) may take its stream along
      }
      if (streams_ && matched) streams_->update_matches();
      if (streams_ && samples) streams_->write_samples();
      if (streams_ && commands) streams_->take_commands();
      if (requests) take_requests();
      if (outcomes) {
        deliver_handed_over();
        write_finished();
      }
      if (parked_count_ > 0) next_parked = flush_all_parked();
      if (!retiring_.empty()) retire_pending();  // at least once a second (the wait's timeout)
    } catch (const std::exception& e) {
      // keep serving everyone else
      log::error("DDS transport: ", e.what());
    }
  }
}

void DdsRequestManager::on_services_changed() {
  catalog_changed_ = true;
  // before start() the DDS thread's first publication sees the change; after stop(), nobody
  if (started_ && !stopping_ && guard_ > 0) dds_set_guardcondition(guard_, true);
}

void DdsRequestManager::publish_catalog() {
  // one entry per component, services in registration order
  std::vector<std::string> order;
  std::map<std::string, json> services;
  async_services_.clear();
  for (const ServiceDescriptor& d : descriptors()) {
    async_services_[d.qualified_name()] = d.is_async;
    auto [it, inserted] = services.try_emplace(d.component, json::array());
    if (inserted) order.push_back(d.component);
    it->second.push_back(d.to_json());
  }
  for (const std::string& component : order) {
    std::string text = dump(services[component]);
    simgate_CatalogEntry entry{};
    entry.component = const_cast<char*>(component.c_str());
    entry.server = const_cast<char*>(server_id_.c_str());
    entry.count = static_cast<uint32_t>(order.size());
    entry.revision = catalog_revision_ + 1;
    entry.services = const_cast<char*>(text.c_str());
    dds_return_t rc = dds_write(catalog_writer_, &entry);
    if (rc < 0)
      log::error("DDS transport: catalog entry '", component, "' not written: ", retcode_text(rc));
  }
  // components served no more: their entries are disposed (a reader sees them not alive)
  for (const std::string& component : published_) {
    if (services.contains(component)) continue;
    simgate_CatalogEntry key{};
    key.component = const_cast<char*>(component.c_str());
    key.server = const_cast<char*>(server_id_.c_str());
    key.services = const_cast<char*>("");
    dds_return_t rc = dds_dispose(catalog_writer_, &key);
    if (rc < 0)
      log::error("DDS transport: catalog entry '", component, "' not disposed: ", retcode_text(rc));
  }
  ++catalog_revision_;
  published_ = std::set<std::string>(order.begin(), order.end());
  log::info("DDS transport: serving ", components().size(), " component(s) on domain ",
            options_.domain, ", partition '", options_.partition, "'");
}

}  // namespace simgate::dds

// The plugin entry point: libsimgate_transport_dds.so exports simgate_transport_dds_entry.
SIMGATE_TRANSPORT_PLUGIN(dds, simgate::dds::DdsRequestManager, "0.1.0", "domain", "partition",
                         "config", "max_samples", "max_in_flight", "park_timeout_ms", "max_params",
                         "max_depth", "global_policy", "progress_interval_ms", "on_disconnect",
                         "stream_writes")
