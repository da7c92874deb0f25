// The DDS transport: its options, its Cyclone entities, the DDS thread (waitset loop), the
// catalog, and the requests taken from the request topic and handed to the core. The
// per-client reply writers (clients, replies, parking): dds_reply_writers.cc.
#include "dds_request_manager.h"

#include <algorithm>
#include <array>
#include <cstring>
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

// How many requests one dds_take returns at most.
constexpr int k_request_take_batch = 32;

// Unknown "component.service" names remembered (as sync) before the cache is trimmed.
constexpr std::size_t k_max_cached_names = 4096;

// The longest prefix of `text` of at most `max` bytes that does not cut a UTF-8 character.
std::string_view utf8_prefix(std::string_view text, std::size_t max) {
  if (text.size() <= max) return text;
  std::size_t end = max;
  // back off the continuation bytes (10xxxxxx) of a character that straddles the cut
  while (end > 0 && (static_cast<unsigned char>(text[end]) & 0xc0) == 0x80) --end;
  return text.substr(0, end);
}

bool is_zero(const ClientId& id) {
  return std::all_of(id.begin(), id.end(), [](std::uint8_t b) { return b == 0; });
}

std::string dump(const json& value) {
  return value.dump(-1, ' ', false, json::error_handler_t::replace);
}

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

bool DdsRequestManager::lookup_async(const std::string& component, const std::string& service) {
  std::string& key = lookup_key_;  // reused: no allocation per call
  key.assign(component).append(".").append(service);
  auto it = async_services_.find(key);
  if (it != async_services_.end()) return it->second;
  // registered after start(), or unknown: look again (unknown names are remembered as sync)
  for (const ServiceDescriptor& d : descriptors()) async_services_[d.qualified_name()] = d.is_async;
  auto [again, inserted] = async_services_.try_emplace(key, false);
  if (inserted && async_services_.size() > k_max_cached_names)
    async_services_.erase(again);  // bounded
  return inserted ? false : again->second;
}

void DdsRequestManager::take_requests() {
  void* samples[k_request_take_batch];
  dds_sample_info_t infos[k_request_take_batch];
  for (;;) {
    samples[0] = nullptr;
    dds_return_t n =
        dds_take(request_reader_, samples, infos, k_request_take_batch, k_request_take_batch);
    if (n <= 0) {
      if (n < 0) log::error("DDS transport: taking requests failed: ", retcode_text(n));
      return;
    }
    for (dds_return_t i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      try {
        handle_request(*static_cast<const simgate_Request*>(samples[i]),
                       infos[i].publication_handle);
      } catch (const std::exception& e) {
        log::error("DDS transport: request dropped: ", e.what());
      }
    }
    dds_return_loan(request_reader_, samples, n);
    // the calls of this take, run here when the simulation lock is free
    run_batch();
    if (n < k_request_take_batch) return;
  }
}

void DdsRequestManager::run_batch() {
  if (batch_.empty() && !run_pending_) return;
  run_pending_ = false;
  std::vector<std::pair<RequestId, Call>> calls;
  calls.swap(batch_);
  // outcomes produced here come back to on_service_completion on this thread, kept behind
  // the earlier ones; written now, without the simulation lock
  run_or_submit(std::move(calls));
  write_finished();
}

void DdsRequestManager::handle_request(const simgate_Request& request,
                                       dds_instance_handle_t writer) {
  const std::uint64_t seq = request.id.seq;
  // the client is its request writer, known since that writer matched
  auto w = writers_.find(writer);
  if (w == writers_.end()) {
    sweep_clients();  // the match status may not have been read yet
    w = writers_.find(writer);
  }
  if (w == writers_.end()) {
    // a writer that already left (its samples outlive it)
    log::debug("DDS transport: request ", seq, " ignored: its writer left");
    return;
  }
  const ClientId client_id = w->second;
  ClientState& client = clients_.at(client_id);
  if (client.gone) return;

  // its id is its writer's GUID: another one would act for someone else (issue #17: an id
  // was bound to whichever writer used it first). Refused to the writer's true id.
  ClientId claimed;
  std::memcpy(claimed.data(), request.id.client, claimed.size());
  if (claimed != client_id) {
    std::string why = is_zero(claimed) ? "the client id is zero"
                                       : "the client id " + to_hex(claimed) +
                                             " is not the GUID of the writer that sent it";
    refuse(client_id, seq, simgate_FL_BAD_REQUEST,
           "DDS transport: request " + std::to_string(seq) + " refused: " + why +
               "; a client's id is the GUID of its request writer, here " + to_hex(client_id));
    return;
  }

  // One id (client, seq), one final reply: a request under the seq of a request still
  // pending (a call, or a cancel not answered yet) would be answered under the same id as
  // it. Refused, ST_REFUSED and not last, so that nobody takes it for the pending one's
  // end (issues #17, #35); the pending request goes on and ends with its own final reply.
  // The one exception is a cancel of the pending call under that call's own seq: it is done,
  // and the call's final reply (PREEMPTED, cancelled; or its result, had it ended first) is
  // the one final reply of the id, the cancel having no answer of its own.
  if (auto pending = client.calls.find(seq); pending != client.calls.end()) {
    run_batch();
    const bool is_call =
        pending_.count(pending->second) && !pending_.at(pending->second).cancel_answer;
    if (request.op == simgate_OP_CANCEL && request.target == seq && is_call) {
      cancel(pending->second);
      run_pending_ = true;  // the next run_batch() executes it here if it can
      return;
    }
    ReplyData refused = failure_reply(
        seq, simgate_FL_BAD_REQUEST,
        "DDS transport: " + std::string(request.op == simgate_OP_CANCEL ? "cancel " : "call ") +
            std::to_string(seq) + " of client " + to_hex(client_id) +
            " refused: " + (is_call ? "call " : "cancel ") + std::to_string(seq) +
            " is still pending (duplicate seq: a seq is used again only once its request's final "
            "reply is out); "
            "the pending one goes on");
    refused.status = simgate_ST_REFUSED;
    refused.last = false;
    send_reply(client_id, std::move(refused));
    return;
  }

  // A client that writes requests faster than it takes its replies: each request taken is
  // in flight until its final reply has gone to its reply writer, and past max_in_flight a
  // request is refused Overloaded without running (issue #35: its replies piled up behind
  // its full writer and those past max_samples were dropped, unknown to it). The refusal is
  // a reply too, parked behind the others; consecutive ones share one parked entry.
  if (in_flight(client) >= static_cast<std::size_t>(options_.max_in_flight)) {
    run_batch();
    send_reply(client_id, overloaded_reply(seq));
    return;
  }

  switch (request.op) {
    case simgate_OP_CALL: handle_call(request, client_id, client); return;
    case simgate_OP_CANCEL: handle_cancel(request, client_id, client); return;
  }
  refuse(client_id, seq, simgate_FL_BAD_REQUEST,
         "DDS transport: unknown op " + std::to_string(int(request.op)) +
             " (expected OP_CALL or OP_CANCEL)");
}

void DdsRequestManager::refuse(const ClientId& client_id, std::uint64_t seq,
                               simgate_Failure failure, std::string message) {
  run_batch();  // after the replies of the requests before it
  send_reply(client_id, failure_reply(seq, failure, std::move(message)));
}

std::optional<std::pair<simgate_Failure, std::string>> DdsRequestManager::call_refusal(
    const simgate_Request& request, Call& call) const {
  // names are bounded before they are looked up, remembered or quoted (issue #17: 10 MB
  // names were all three)
  for (auto [what, name] :
       {std::pair{"component", request.component}, std::pair{"service", request.service}}) {
    const std::size_t size = name ? std::strlen(name) : 0;
    if (size > k_max_name_bytes)
      return std::pair{simgate_FL_BAD_REQUEST,
                       "DDS transport: request " + std::to_string(request.id.seq) +
                           " refused: its " + what + " name is " + std::to_string(size) +
                           " bytes, more than " + std::to_string(k_max_name_bytes)};
  }
  call.component = request.component ? request.component : "";
  call.service = request.service ? request.service : "";
  const std::string method = call.component + "." + call.service;
  std::string_view params_text = request.params ? request.params : "";
  if (params_text.size() > options_.max_params)
    return std::pair{simgate_FL_BAD_ARGUMENTS, method + ": params are " +
                                                   std::to_string(params_text.size()) +
                                                   " bytes, more than max_params (" +
                                                   std::to_string(options_.max_params) + ")"};
  // before parsing: a deeper value would recurse once per level in dump(), copies and
  // comparisons (issue #17: 80 000 levels overflowed the stack)
  if (json_nests_deeper_than(params_text, options_.max_depth))
    return std::pair{simgate_FL_BAD_ARGUMENTS, method + ": params nest deeper than max_depth (" +
                                                   std::to_string(options_.max_depth) + ")"};
  if (!params_text.empty()) {
    call.params = json::parse(params_text, nullptr, false);
    if (call.params.is_discarded() ||
        !(call.params.is_array() || call.params.is_object() || call.params.is_null()))
      return std::pair{simgate_FL_BAD_ARGUMENTS,
                       method + ": params must be a JSON array, object or \"\", not '" +
                           std::string(utf8_prefix(params_text, 60)) + "'"};
  }
  // its deadline: 0 = none; beyond a signed 32-bit count of ms (about 24.8 days) it is
  // more likely garbage than a wait anyone means
  if (request.timeout_ms > k_max_timeout_ms)
    return std::pair{simgate_FL_BAD_ARGUMENTS,
                     method + ": timeout_ms " + std::to_string(request.timeout_ms) +
                         " is more than " + std::to_string(k_max_timeout_ms) + " (0 = no timeout)"};
  call.timeout = std::chrono::milliseconds(request.timeout_ms);
  return std::nullopt;
}

void DdsRequestManager::handle_call(const simgate_Request& request, const ClientId& client_id,
                                    ClientState& client) {
  const std::uint64_t seq = request.id.seq;
  Call call;
  if (auto refusal = call_refusal(request, call)) {
    refuse(client_id, seq, refusal->first, std::move(refusal->second));
    return;
  }
  // into the batch for the core; async calls are acknowledged at once, after the replies of
  // the calls before them
  const bool is_async = lookup_async(call.component, call.service);
  // progress asked of an async service: the client's progress writer exists from now on
  call.progress = request.progress && is_async && ensure_progress_writer(client_id, client);
  // a client that reads its images raw: the service need not encode them (no PNG made)
  call.raw_attachments = takes_images_raw(client_id, client);
  call.client = client_number(client_id);
  RequestId id = new_request_id();
  pending_.emplace(id, Pending{client_id, seq, is_async});
  client.calls.emplace(seq, id);
  if (is_async) {
    run_batch();
    ReplyData accepted;
    accepted.seq = seq;
    accepted.status = simgate_ST_ACCEPTED;
    accepted.last = false;
    send_reply(client_id, std::move(accepted));
  }
  batch_.emplace_back(id, std::move(call));
}

void DdsRequestManager::handle_cancel(const simgate_Request& request, const ClientId& client_id,
                                      ClientState& client) {
  const std::uint64_t seq = request.id.seq;
  // after the calls before it (its target may be one of them)
  run_batch();
  auto target = client.calls.find(request.target);
  if (target == client.calls.end()) {
    ReplyData answer;
    answer.seq = seq;
    answer.result = "false";
    answer.message = "no pending call " + std::to_string(request.target) + " of this client";
    send_reply(client_id, std::move(answer));
    return;
  }
  // the answer goes out like a completion, in order with them; its seq is pending till then
  const RequestId answer_id = new_request_id();
  pending_.emplace(answer_id, Pending{client_id, seq, false, true});
  client.calls.emplace(seq, answer_id);
  cancel(target->second, [this, answer_id](bool found) {
    complete_request(answer_id, Outcome::success(json(found)));
  });
  run_pending_ = true;  // the next run_batch() executes it here if it can
}

DdsRequestManager::ReplyData DdsRequestManager::to_reply(std::uint64_t seq,
                                                         const Outcome& outcome) {
  ReplyData reply;
  reply.seq = seq;
  switch (outcome.status) {
    case Status::success: reply.status = simgate_ST_SUCCESS; break;
    case Status::failed: reply.status = simgate_ST_FAILED; break;
    case Status::preempted: reply.status = simgate_ST_PREEMPTED; break;
  }
  reply.failure = to_wire(outcome.failure);
  if (outcome.value) reply.result = dump(*outcome.value);
  reply.message = outcome.message;
  if (!outcome.data.is_null() && !outcome.data.empty()) reply.data = dump(outcome.data);
  return reply;
}

DdsRequestManager::ReplyData DdsRequestManager::overloaded_reply(std::uint64_t seq) const {
  const std::string limit = std::to_string(options_.max_in_flight);
  ReplyData reply = failure_reply(
      seq, simgate_FL_BUSY,
      "Overloaded: " + limit + " requests of this client are not answered yet (max_in_flight " +
          limit + "); refused without running: send it again once replies come");
  reply.seq_end = seq;
  reply.data = dump(json{{"reason", "overloaded"}, {"max_in_flight", options_.max_in_flight}});
  return reply;
}

DdsRequestManager::ReplyData DdsRequestManager::failure_reply(std::uint64_t seq,
                                                              simgate_Failure failure,
                                                              std::string message) {
  ReplyData reply;
  reply.seq = seq;
  reply.status = simgate_ST_FAILED;
  reply.failure = failure;
  reply.result = dump(json(message));
  reply.message = std::move(message);
  return reply;
}

}  // namespace simgate::dds

// The plugin entry point: libsimgate_transport_dds.so exports simgate_transport_dds_entry.
SIMGATE_TRANSPORT_PLUGIN(dds, simgate::dds::DdsRequestManager, "0.1.0", "domain", "partition",
                         "config", "max_samples", "max_in_flight", "park_timeout_ms", "max_params",
                         "max_depth", "global_policy", "progress_interval_ms", "on_disconnect",
                         "stream_writes")
