// The DDS transport's requests (DDS thread): taken from the request topic in batches, each
// checked (its client by its writer, its seq not pending, the client's requests in flight, its
// names, params and timeout) and handed to the core with run_or_submit(); cancels answered in
// order with the completions; the replies made of outcomes and refusals. Options, entities,
// the DDS thread and the catalog: dds_request_manager.cc; writing the replies:
// dds_reply_writers.cc.
#include <algorithm>
#include <cstring>

#include "dds_request_manager.h"
#include "simgate/core/config.h"
#include "simgate/core/log.h"

namespace simgate::dds {

namespace {

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

}  // namespace

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
