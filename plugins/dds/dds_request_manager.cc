#include "dds_request_manager.h"

#include <algorithm>
#include <cstring>
#include <set>
#include <stdexcept>

#include "cyclone_config.h"
#include "simgate/core/config.h"
#include "simgate/core/log.h"

namespace simgate::dds {

namespace {

// Waitset attachment tokens: which entity woke the DDS thread.
constexpr dds_attach_t k_token_requests = 1;
constexpr dds_attach_t k_token_guard = 2;
constexpr dds_attach_t k_token_reply_matched = 3;
constexpr dds_attach_t k_token_request_matched = 4;

// How many requests one dds_take returns at most.
constexpr int k_take_batch = 32;

std::string dump(const json& value) { return value.dump(-1, ' ', false, json::error_handler_t::replace); }

// Throws std::runtime_error when a Cyclone call returned an error.
dds_entity_t check(dds_entity_t rc, const std::string& what) {
  if (rc < 0) throw std::runtime_error("DDS transport: cannot create " + what + ": " + retcode_text(rc));
  return rc;
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
  out.max_samples = static_cast<int32_t>(config.get_int("max_samples", out.max_samples, 1, 1 << 20));
  out.park_timeout = std::chrono::milliseconds(
      config.get_int("park_timeout_ms", out.park_timeout.count(), 0, 3'600'000));
  out.max_params = static_cast<std::size_t>(
      config.get_int("max_params", static_cast<long long>(out.max_params), 2, 64ll << 20));
  out.max_depth = static_cast<std::size_t>(
      config.get_int("max_depth", static_cast<long long>(out.max_depth), 2, 10000));
  out.global_policy = config.get_choice("global_policy", "reject", {"reject", "preempt"}) == "preempt"
                          ? GlobalPolicy::preempt
                          : GlobalPolicy::reject;
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
  create_entities();
}

DdsRequestManager::~DdsRequestManager() { stop(); }

void DdsRequestManager::create_entities() {
  participant_ = std::make_unique<Participant>(options_.domain, resolve_config(options_.config),
                                               "DDS transport (domain " + std::to_string(options_.domain) +
                                                   ", partition '" + options_.partition + "')");
  dds_entity_t pp = participant_->handle();
  dds_guid_t guid;
  if (dds_get_guid(pp, &guid) == DDS_RETCODE_OK) server_id_ = to_hex(to_client_id(guid));

  // publisher and subscriber in our partition
  QosPtr partition_qos(dds_create_qos());
  dds_qset_partition1(partition_qos.get(), options_.partition.c_str());
  publisher_ = check(dds_create_publisher(pp, partition_qos.get(), nullptr), "publisher");
  subscriber_ = check(dds_create_subscriber(pp, partition_qos.get(), nullptr), "subscriber");

  dds_entity_t request_topic =
      check(dds_create_topic(pp, &simgate_Request_desc, k_request_topic, nullptr, nullptr), "topic simgate_Request");
  dds_entity_t reply_topic =
      check(dds_create_topic(pp, &simgate_Reply_desc, k_reply_topic, nullptr, nullptr), "topic simgate_Reply");
  dds_entity_t catalog_topic = check(
      dds_create_topic(pp, &simgate_CatalogEntry_desc, k_catalog_topic, nullptr, nullptr), "topic simgate_Catalog");

  // requests: reliable, keep-all, volatile, bounded (writers block when we fall behind)
  QosPtr request_qos = make_qos(false, 0, DDS_SECS(1));
  dds_qset_resource_limits(request_qos.get(), options_.max_samples, DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED);
  request_reader_ = check(dds_create_reader(subscriber_, request_topic, request_qos.get(), nullptr), "request reader");

  // replies: reliable, keep-all, volatile; a slow reader may hold the DDS thread 200 ms at most
  QosPtr reply_qos = make_qos(false, 0, DDS_MSECS(200));
  dds_qset_resource_limits(reply_qos.get(), options_.max_samples * 4, DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED);
  dds_qset_writer_data_lifecycle(reply_qos.get(), false);
  std::string userdata = "simgate.role=server;simgate.v=1;simgate.id=" + server_id_;
  dds_qset_userdata(reply_qos.get(), userdata.data(), userdata.size());
  reply_writer_ = check(dds_create_writer(publisher_, reply_topic, reply_qos.get(), nullptr), "reply writer");

  // catalog: the last sample of each component, kept for late joiners
  QosPtr catalog_qos = make_qos(true, 1, DDS_SECS(1));
  catalog_writer_ = check(dds_create_writer(publisher_, catalog_topic, catalog_qos.get(), nullptr), "catalog writer");

  // the waitset of the DDS thread
  waitset_ = check(dds_create_waitset(pp), "waitset");
  guard_ = check(dds_create_guardcondition(pp), "guard condition");
  read_condition_ = check(dds_create_readcondition(request_reader_, DDS_ANY_STATE), "read condition");
  dds_set_status_mask(reply_writer_, DDS_PUBLICATION_MATCHED_STATUS);
  dds_set_status_mask(request_reader_, DDS_SUBSCRIPTION_MATCHED_STATUS);
  check(dds_waitset_attach(waitset_, read_condition_, k_token_requests), "waitset attachment");
  check(dds_waitset_attach(waitset_, guard_, k_token_guard), "waitset attachment");
  check(dds_waitset_attach(waitset_, reply_writer_, k_token_reply_matched), "waitset attachment");
  check(dds_waitset_attach(waitset_, request_reader_, k_token_request_matched), "waitset attachment");
}

std::vector<std::string> DdsRequestManager::endpoints() const {
  return {"dds:domain=" + std::to_string(options_.domain) + ";partition=" + options_.partition};
}

void DdsRequestManager::start() {
  if (stopped_ || started_.exchange(true)) return;
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
  participant_.reset();
}

void DdsRequestManager::on_service_completion(RequestId id, Outcome&& outcome) {
  // the DDS thread (the core hands other threads' outcomes over), inside run_or_submit()
  // under the simulation lock or in deliver_handed_over(): kept until write_finished(),
  // which writes them outside the lock
  finished_.emplace_back(id, std::move(outcome));
}

// ---------------------------------------------------------------------------------------
// the DDS thread

void DdsRequestManager::run() {
  // outcomes produced on other threads: the guard condition wakes this thread (once per
  // burst), which delivers and writes them
  deliver_on_this_thread([this] { dds_set_guardcondition(guard_, true); });
  try {
    publish_catalog();
  } catch (const std::exception& e) {
    log::error("DDS transport: catalog not published: ", e.what());
  }
  dds_attach_t triggered[8];
  while (!stopping_) {
    // wait for work; wake now and then while replies are parked
    dds_duration_t timeout = parked_count_ > 0 ? DDS_MSECS(50) : DDS_SECS(1);
    dds_return_t n = dds_waitset_wait(waitset_, triggered, 8, timeout);
    if (n < 0) {
      log::error("DDS transport: waitset failed: ", retcode_text(n));
      break;
    }
    bool requests = false, outcomes = false, readers = false, writers = false;
    for (dds_return_t i = 0; i < std::min<dds_return_t>(n, 8); ++i) {
      requests |= triggered[i] == k_token_requests;
      outcomes |= triggered[i] == k_token_guard;
      readers |= triggered[i] == k_token_reply_matched;
      writers |= triggered[i] == k_token_request_matched;
    }
    try {
      // matches first, so that replies find their readers
      if (readers) {
        dds_publication_matched_status_t status;
        dds_get_publication_matched_status(reply_writer_, &status);
        refresh_reply_readers();
      }
      if (requests) take_requests();
      if (outcomes) {
        bool ignored;
        dds_take_guardcondition(guard_, &ignored);
        deliver_handed_over();
        write_finished();
      }
      if (writers) {
        dds_subscription_matched_status_t status;
        dds_get_subscription_matched_status(request_reader_, &status);
        client_count_.store(status.current_count, std::memory_order_relaxed);
        sweep_clients();
      }
      if (parked_count_ > 0) expire_parked();
    } catch (const std::exception& e) {
      // keep serving everyone else
      log::error("DDS transport: ", e.what());
    }
  }
}

void DdsRequestManager::publish_catalog() {
  // one entry per component, services in registration order
  std::vector<std::string> order;
  std::map<std::string, json> services;
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
    entry.services = const_cast<char*>(text.c_str());
    dds_return_t rc = dds_write(catalog_writer_, &entry);
    if (rc < 0) log::error("DDS transport: catalog entry '", component, "' not written: ", retcode_text(rc));
  }
  log::info("DDS transport: serving ", components().size(), " component(s) on domain ", options_.domain,
            ", partition '", options_.partition, "'");
}

bool DdsRequestManager::lookup_async(const std::string& component, const std::string& service) {
  std::string& key = lookup_key_;  // reused: no allocation per call
  key.assign(component).append(".").append(service);
  auto it = async_services_.find(key);
  if (it != async_services_.end()) return it->second;
  // registered after start(), or unknown: look again (unknown names are remembered as sync)
  for (const ServiceDescriptor& d : descriptors()) async_services_[d.qualified_name()] = d.is_async;
  auto [again, inserted] = async_services_.try_emplace(key, false);
  if (inserted && async_services_.size() > 100'000) async_services_.erase(again);  // bounded
  return inserted ? false : again->second;
}

void DdsRequestManager::take_requests() {
  void* samples[k_take_batch];
  dds_sample_info_t infos[k_take_batch];
  for (;;) {
    samples[0] = nullptr;
    dds_return_t n = dds_take(request_reader_, samples, infos, k_take_batch, k_take_batch);
    if (n <= 0) {
      if (n < 0) log::error("DDS transport: taking requests failed: ", retcode_text(n));
      return;
    }
    for (dds_return_t i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      try {
        handle_request(*static_cast<const simgate_Request*>(samples[i]), infos[i].publication_handle);
      } catch (const std::exception& e) {
        log::error("DDS transport: request dropped: ", e.what());
      }
    }
    dds_return_loan(request_reader_, samples, n);
    // the calls of this take, run here when the simulation lock is free
    run_batch();
    if (n < k_take_batch) return;
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

void DdsRequestManager::handle_request(const simgate_Request& request, dds_instance_handle_t writer) {
  ClientId client_id;
  std::memcpy(client_id.data(), request.id.client, client_id.size());
  const std::uint64_t seq = request.id.seq;

  // one client id belongs to one request writer
  auto [it, inserted] = clients_.try_emplace(client_id);
  ClientState& client = it->second;
  if (inserted) {
    // a writer that already left (its samples outlive it) would never be swept
    dds_builtintopic_endpoint_t* ep = dds_get_matched_publication_data(request_reader_, writer);
    if (!ep) {
      clients_.erase(it);
      log::debug("DDS transport: request ", seq, " of client ", to_hex(client_id), " ignored: its writer left");
      return;
    }
    dds_builtintopic_free_endpoint(ep);
    client.writer = writer;
  } else if (client.writer != writer) {
    log::warning("DDS transport: request ", seq, " ignored: client id ", to_hex(client_id),
                 " already belongs to another request writer");
    return;
  }
  if (client.gone) return;

  switch (request.op) {
    case simgate_OP_CALL: {
      if (client.calls.count(seq)) {
        run_batch();
        send_reply(client_id, failure_reply(seq, simgate_FL_BAD_REQUEST,
                                            "DDS transport: call " + std::to_string(seq) + " of client " +
                                                to_hex(client_id) + " is already pending (duplicate seq)"));
        return;
      }
      Call call;
      call.component = request.component ? request.component : "";
      call.service = request.service ? request.service : "";
      std::string_view params_text = request.params ? request.params : "";
      if (params_text.size() > options_.max_params) {
        run_batch();
        send_reply(client_id, failure_reply(seq, simgate_FL_BAD_ARGUMENTS,
                                            call.component + "." + call.service + ": params are " +
                                                std::to_string(params_text.size()) + " bytes, more than max_params (" +
                                                std::to_string(options_.max_params) + ")"));
        return;
      }
      // before parsing: a deeper value would recurse once per level in dump(), copies and
      // comparisons (issue #17: 80 000 levels overflowed the stack)
      if (json_nests_deeper_than(params_text, options_.max_depth)) {
        run_batch();
        send_reply(client_id, failure_reply(seq, simgate_FL_BAD_ARGUMENTS,
                                            call.component + "." + call.service +
                                                ": params nest deeper than max_depth (" +
                                                std::to_string(options_.max_depth) + ")"));
        return;
      }
      if (!params_text.empty()) {
        call.params = json::parse(params_text, nullptr, false);
        if (call.params.is_discarded() || !(call.params.is_array() || call.params.is_object() || call.params.is_null())) {
          run_batch();
          send_reply(client_id, failure_reply(seq, simgate_FL_BAD_ARGUMENTS,
                                              call.component + "." + call.service +
                                                  ": params must be a JSON array, object or \"\", not '" +
                                                  std::string(params_text.substr(0, 60)) + "'"));
          return;
        }
      }
      // into the batch for the core; async calls are acknowledged at once, after the
      // replies of the calls before them
      bool is_async = lookup_async(call.component, call.service);
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
      return;
    }
    case simgate_OP_CANCEL: {
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
      // the answer goes out like a completion, in order with them
      const RequestId answer_id = new_request_id();
      pending_.emplace(answer_id, Pending{client_id, seq, false, true});
      cancel(target->second, [this, answer_id](bool found) { complete_request(answer_id, Outcome::success(json(found))); });
      run_pending_ = true;  // the next run_batch() executes it here if it can
      return;
    }
  }
  run_batch();
  send_reply(client_id, failure_reply(seq, simgate_FL_BAD_REQUEST,
                                      "DDS transport: unknown op " + std::to_string(int(request.op)) +
                                          " (expected OP_CALL or OP_CANCEL)"));
}

void DdsRequestManager::write_finished() {
  if (finished_.empty()) return;
  // swapped, not moved: both vectors keep their capacity
  draining_.swap(finished_);
  write_finished(draining_, false);
}

void DdsRequestManager::write_finished(std::vector<std::pair<RequestId, Outcome>>& batch, bool final_flush) {
  for (auto& [id, outcome] : batch) {
    auto p = pending_.find(id);
    if (p == pending_.end()) continue;
    Pending pending = p->second;
    pending_.erase(p);
    if (pending.cancel_answer) {
      // the answer to a cancel: whether the call was still running
      const bool found = outcome.value && outcome.value->is_boolean() && outcome.value->get<bool>();
      ReplyData answer;
      answer.seq = pending.seq;
      answer.result = found ? "true" : "false";
      if (!found) answer.message = "the call had already finished";
      send_reply(pending.client, std::move(answer), final_flush);
      continue;
    }
    // a completed call
    auto c = clients_.find(pending.client);
    if (c != clients_.end()) {
      c->second.calls.erase(pending.seq);
      if (c->second.gone) {
        if (c->second.calls.empty()) forget_client(pending.client);
        continue;
      }
    }
    send_reply(pending.client, to_reply(pending.seq, outcome), final_flush);
  }
  batch.clear();
}

void DdsRequestManager::send_reply(const ClientId& client_id, ReplyData reply, bool final_flush) {
  // written at once when the client's reply reader is matched
  auto c = clients_.find(client_id);
  if (final_flush || matched_ids_.count(client_id) || c == clients_.end()) {
    write_reply(client_id, reply);
    return;
  }
  ClientState& client = c->second;
  if (client.gone) return;
  // otherwise parked until it matches (bounded in count and time)
  if (client.parked.size() >= static_cast<std::size_t>(options_.max_samples)) {
    log::warning("DDS transport: client ", to_hex(client_id), " has ", client.parked.size(),
                 " replies waiting for its reader; writing reply ", reply.seq, " unmatched");
    write_reply(client_id, reply);
    return;
  }
  log::debug("DDS transport: reply ", reply.seq, " to client ", to_hex(client_id),
             " parked until its reply reader matches");
  reply.deadline = std::chrono::steady_clock::now() + options_.park_timeout;
  client.parked.push_back(std::move(reply));
  ++parked_count_;
}

void DdsRequestManager::write_reply(const ClientId& client_id, const ReplyData& reply) {
  simgate_Reply sample{};
  std::memcpy(sample.client, client_id.data(), client_id.size());
  sample.seq = reply.seq;
  sample.status = reply.status;
  sample.failure = reply.failure;
  sample.last = reply.last;
  sample.result = const_cast<char*>(reply.result.c_str());
  sample.message = const_cast<char*>(reply.message.c_str());
  sample.data = const_cast<char*>(reply.data.c_str());
  dds_return_t rc = dds_write(reply_writer_, &sample);
  if (rc < 0)
    log::warning("DDS transport: reply ", reply.seq, " to client ", to_hex(client_id),
                 " not written: ", retcode_text(rc));
}

void DdsRequestManager::refresh_reply_readers() {
  // the matched reply readers, and the client ids their USER_DATA announce
  std::vector<dds_instance_handle_t> handles(reply_readers_.size() + 16);
  dds_return_t n;
  while ((n = dds_get_matched_subscriptions(reply_writer_, handles.data(), handles.size())) >
         static_cast<dds_return_t>(handles.size()))
    handles.resize(static_cast<std::size_t>(n) + 16);
  if (n < 0) {
    log::error("DDS transport: matched reply readers unknown: ", retcode_text(n));
    return;
  }
  std::map<dds_instance_handle_t, std::optional<ClientId>> readers;
  for (dds_return_t i = 0; i < n; ++i) {
    auto old = reply_readers_.find(handles[i]);
    if (old != reply_readers_.end()) {
      readers.emplace(*old);
      continue;
    }
    std::optional<ClientId> id;
    if (dds_builtintopic_endpoint_t* ep = dds_get_matched_subscription_data(reply_writer_, handles[i])) {
      id = client_id_from_userdata(ep->qos);
      dds_builtintopic_free_endpoint(ep);
    }
    readers.emplace(handles[i], id);
  }
  reply_readers_ = std::move(readers);
  matched_ids_.clear();
  for (const auto& [handle, id] : reply_readers_)
    if (id) ++matched_ids_[*id];

  // flush what was parked for readers that just matched
  for (auto& [id, client] : clients_) {
    if (client.parked.empty() || !matched_ids_.count(id)) continue;
    for (const ReplyData& reply : client.parked) write_reply(id, reply);
    parked_count_ -= client.parked.size();
    client.parked.clear();
  }
}

void DdsRequestManager::sweep_clients() {
  // the request writers still matched
  std::vector<dds_instance_handle_t> handles(clients_.size() + 16);
  dds_return_t n;
  while ((n = dds_get_matched_publications(request_reader_, handles.data(), handles.size())) >
         static_cast<dds_return_t>(handles.size()))
    handles.resize(static_cast<std::size_t>(n) + 16);
  if (n < 0) {
    log::error("DDS transport: matched request writers unknown: ", retcode_text(n));
    return;
  }
  std::set<dds_instance_handle_t> live(handles.begin(), handles.begin() + n);
  // every client whose writer left is gone
  std::vector<ClientId> gone;
  for (const auto& [id, client] : clients_)
    if (!client.gone && !live.count(client.writer)) gone.push_back(id);
  for (const ClientId& id : gone) client_gone(id, clients_.at(id));
  // their cancels, here if the simulation lock is free
  run_batch();
}

void DdsRequestManager::client_gone(const ClientId& id, ClientState& client) {
  client.gone = true;
  parked_count_ -= client.parked.size();
  client.parked.clear();
  // its async calls are cancelled; sync ones finish and their replies are dropped
  std::size_t cancelled = 0;
  for (const auto& [seq, request] : client.calls) {
    auto p = pending_.find(request);
    if (p != pending_.end() && p->second.is_async) {
      cancel(request);
      ++cancelled;
    }
  }
  if (cancelled > 0) run_pending_ = true;
  log::info("DDS transport: client ", to_hex(id), " disappeared; ", cancelled, " async call(s) cancelled");
  if (client.calls.empty()) forget_client(id);
}

void DdsRequestManager::forget_client(const ClientId& id) {
  simgate_Reply key{};
  std::memcpy(key.client, id.data(), id.size());
  dds_unregister_instance(reply_writer_, &key);  // fails harmlessly if never written
  clients_.erase(id);
}

void DdsRequestManager::expire_parked() {
  // replies whose reader never matched are written anyway (a reader without simgate.id
  // USER_DATA still gets them), oldest first
  auto now = std::chrono::steady_clock::now();
  for (auto& [id, client] : clients_) {
    auto end = std::find_if(client.parked.begin(), client.parked.end(),
                            [&](const ReplyData& r) { return r.deadline > now; });
    if (end == client.parked.begin()) continue;
    log::warning("DDS transport: no reply reader of client ", to_hex(id), " matched within ",
                 options_.park_timeout.count(), " ms; writing ", end - client.parked.begin(), " reply(ies) anyway");
    for (auto r = client.parked.begin(); r != end; ++r) write_reply(id, *r);
    parked_count_ -= static_cast<std::size_t>(end - client.parked.begin());
    client.parked.erase(client.parked.begin(), end);
  }
}

DdsRequestManager::ReplyData DdsRequestManager::to_reply(std::uint64_t seq, const Outcome& outcome) {
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

DdsRequestManager::ReplyData DdsRequestManager::failure_reply(std::uint64_t seq, simgate_Failure failure,
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
