// engine.cc — the JSON-RPC engine's member definitions (simgate/jsonrpc/engine.h): parsing a
// message, batches, dispatch to the core, rpc.login, rpc.cancel, rpc.discover, replies
// (engine_streams.cc: the data streams). Compiled once, for every framing.
#include <algorithm>
#include <cstring>
#include <exception>
#include <iterator>
#include <stdexcept>

#include <boost/asio/post.hpp>

#include "simgate/jsonrpc/engine.h"
#include "simgate/jsonrpc/protocol.h"
#include "simgate/core/errors.h"
#include "simgate/core/log.h"
#include "simgate/core/text.h"

namespace simgate::jsonrpc {

namespace engine_detail {
constexpr std::string_view k_version = "0.1.0";
// a reply buffer larger than this is not kept for the next reply
constexpr std::size_t k_kept_line_bytes = 256 * 1024;
}  // namespace engine_detail

JsonRpcEngine::JsonRpcEngine(std::string who, std::string tag, Options options)
    : RequestManager(std::move(who)), options_(std::move(options)), tag_(std::move(tag)) {
  set_global_policy(options_.tcp.global_policy);
  set_progress_interval(options_.tcp.progress_interval);
  for (const auto& message : options_.tcp.warnings) log::warning(message);
}

void JsonRpcEngine::deliver_here() {
  // outcomes produced on the simulation thread come here: one drain per burst, then one
  // write per connection
  deliver_on_this_thread([this] { boost::asio::post(io_, [this] { drain_completions(); }); });
}

void JsonRpcEngine::input_ended(Session& session) {
  // the client will send nothing more: under "cancel" it has left, and its calls end
  if (options_.tcp.cancel_on_disconnect)
    for (RequestId id : session.pending_calls()) cancel(id);
}

void JsonRpcEngine::session_closed(Session& session) {
  client_left(session.number());
  end_subscriptions(&session);
  if (stopping_ || !options_.tcp.cancel_on_disconnect) return;
  // the client is gone: its pending calls end (their replies are dropped)
  for (RequestId id : session.pending_calls()) cancel(id);
}

void JsonRpcEngine::stop_io() {
  stopping_ = true;
  end_subscriptions(nullptr);
}

void JsonRpcEngine::finish_stop() {
  deliver_on_any_thread();  // the connections are gone: outcomes from now on go nowhere
  // finish what the core still holds (replies can no longer be sent)
  abandon_pending();
}

// A batch: the responses collected in entry order, sent as one array when all are in. Its
// reply is bounded: once the responses stored reach max_unsent_bytes, each later entry
// answers a short -32006 instead of its result (issue #17: a batch of rpc.discover built a
// 222 MB reply).
struct JsonRpcEngine::Batch {
  Batch(std::size_t n, std::size_t max_bytes) : responses(n), remaining(n), max_bytes(max_bytes) {}
  std::vector<std::string> responses;  // serialised; empty = no response (notification)
  std::size_t remaining;               // entries not yet finished
  std::size_t bytes = 0;               // of the responses stored so far
  std::size_t max_bytes;               // the connection's max_unsent_bytes
  bool full() const { return bytes >= max_bytes; }
};

void JsonRpcEngine::handle_message(Session& session, std::string_view line) {
  // framing: optional "\r" before the "\n"; blank lines are keep-alives
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  if (line.find_first_not_of(" \t\r") == std::string_view::npos) return;

  // (a line over max_message_bytes never comes here: on_oversized_line)
  ReplyTo single{session.ref(), nullptr, false, nullptr, 0, {}};
  // the common shape (one plain request object) without a DOM; anything else, errors
  // included, takes the full path below
  if (parse_request_fast(line, options_.max_depth, request_)) {
    dispatch(session, request_, std::move(single));
    return;
  }
  if (json_nests_deeper_than(line, options_.max_depth)) {
    reply(single, error_response(nullptr, code::invalid_request,
                                 "Invalid Request: message nests deeper than max_depth (" +
                                     std::to_string(options_.max_depth) + ")",
                                 json{{"reason", "nesting too deep"}}));
    return;
  }
  // nlohmann's parser ends the text at a NUL byte: `<request>\0<anything>` would run the
  // request and ignore the rest (issue #17, item 9). JSON has no raw NUL, not even in strings.
  if (const std::size_t nul = line.find('\0'); nul != std::string_view::npos) {
    reply(single,
          error_response(nullptr, code::parse_error, "Parse error",
                         json{{"reason", "a NUL byte at column " + std::to_string(nul + 1) +
                                             " (JSON text has none; write \\u0000 in a string)"}}));
    return;
  }
  json message;
  try {
    message = json::parse(line.begin(), line.end());
  } catch (const json::exception& e) {
    // parse_error, and out_of_range for numbers beyond a double ("1e400")
    reply(single,
          error_response(nullptr, code::parse_error, "Parse error", json{{"reason", e.what()}}));
    return;
  }

  // a number id json::parse read as a double is echoed as sent, not rounded (two such ids
  // would otherwise collide): its exact text, read again from the line (issue #17, item 9)
  auto float_id = [](const json& m) {
    auto it = m.is_object() ? m.find("id") : m.end();
    return it != m.end() && it->is_number_float();
  };
  std::vector<std::pair<std::size_t, std::string>> id_texts;
  if (message.is_array() ? std::any_of(message.begin(), message.end(), float_id)
                         : float_id(message))
    id_texts = float_id_texts(line);
  auto id_text = [&id_texts](std::size_t index) {
    for (auto& [i, text] : id_texts)
      if (i == index) return std::move(text);
    return std::string();
  };

  if (message.is_array()) {
    if (message.empty()) {
      reply(single, error_response(nullptr, code::invalid_request, "Invalid Request: empty batch",
                                   json{{"reason", "a batch must contain at least one request"}}));
      return;
    }
    // every entry counts against max_in_flight, whatever it is (rpc.*, invalid entries):
    // a batch larger than the room left is refused whole, with one error (issue #17: a
    // 2 MB batch of `1`s built a million error objects on the I/O thread)
    const std::size_t room =
        options_.tcp.max_in_flight - std::min(session.in_flight(), options_.tcp.max_in_flight);
    if (message.size() > room) {
      const json refusal = error_response(
          nullptr, code::overloaded,
          "Overloaded: a batch of " + std::to_string(message.size()) + " entries, " +
              std::to_string(room) +
              " more calls allowed in flight on this connection (max_in_flight " +
              std::to_string(options_.tcp.max_in_flight) + ")",
          json{{"batch_entries", message.size()}, {"max_in_flight", options_.tcp.max_in_flight}});
      // a batch of a size clients send: each request answered with its own id, so that its
      // client knows which calls failed; a huge one (or one of no requests): the one error
      const auto has_id = [](const json& entry) {
        auto it = entry.is_object() ? entry.find("id") : entry.end();
        return it != entry.end() && (it->is_string() || it->is_number());
      };
      if (message.size() > k_refused_batch_answered_by_entry ||
          std::none_of(message.begin(), message.end(), has_id)) {
        reply(single, json(refusal));
        return;
      }
      auto batch = std::make_shared<Batch>(message.size(), options_.tcp.max_unsent_bytes);
      for (std::size_t i = 0; i < message.size(); ++i) {
        const bool answered = has_id(message[i]);
        ReplyTo to{session.ref(), answered ? message[i]["id"] : json(nullptr), !answered, batch, i,
                   id_text(i)};
        json response = refusal;
        response["id"] = to.id;
        reply(to, std::move(response));
      }
      return;
    }
    // every entry answers into the batch; the array goes out when the last one is in
    auto batch = std::make_shared<Batch>(message.size(), options_.tcp.max_unsent_bytes);
    for (std::size_t i = 0; i < message.size(); ++i)
      handle_request(session, message[i],
                     ReplyTo{session.ref(), nullptr, false, batch, i, id_text(i)});
    return;
  }
  single.id_text = id_text(0);
  handle_request(session, message, single);
}

void JsonRpcEngine::flush_submissions() {
  // one hand-over per read: a batch's calls always travel together, so they run in the
  // same process(); when the simulation lock is free they run here, on this thread, and
  // their replies are queued on their connections before run_or_submit returns
  if (to_submit_count_ == 0) return;
  // the call objects stay for the next read's requests (their arrays circulate with
  // request_'s params: no allocation per request), at most k_kept_calls of them
  run_or_submit(std::span(to_submit_.data(), to_submit_count_), /*refilled=*/true);
  to_submit_count_ = 0;
  if (to_submit_.size() > k_kept_calls)
    to_submit_.erase(to_submit_.begin() + k_kept_calls, to_submit_.end());
}

void JsonRpcEngine::handle_request(Session& session, json& message, ReplyTo to) {
  // validate; invalid requests are answered even without an id
  Request request;
  if (auto error = parse_request(message, request)) {
    to.id = (*error)["id"];
    reply(to, std::move(*error));
    return;
  }
  request.id_text = to.id_text;  // its key among the connection's ids: exact, as echoed
  dispatch(session, request, std::move(to));
}

void JsonRpcEngine::dispatch(Session& session, Request& request, ReplyTo&& to) {
  to.id = request.id;
  to.notification = !request.has_id;

  // reserved methods run here, on the I/O thread
  const std::string& method = request.method;
  // one look at the prefix, so that a service call pays no comparison with each reserved name
  const bool reserved = method.starts_with("rpc.") || method.starts_with("$/");
  if (reserved && method == "rpc.login") {
    handle_login(session, request.params, std::move(to));
    return;
  }
  if (!session.authenticated()) [[unlikely]] {
    reply(to,
          error_response(
              to.id, code::unauthorized,
              "Unauthorized: call rpc.login with the token first (the transport's \"auth\" option; "
              "docs/transports/jsonrpc.md#authentication)",
              json{{"method", method}}));
    return;
  }
  if (reserved && (method == "rpc.cancel" || method == "$/cancelRequest")) {
    handle_cancel(session, method, request.params, std::move(to));
    return;
  }
  if (reserved && method == "rpc.discover") {
    if (to.batch && to.batch->full()) {
      reply(to, std::nullopt);  // answered -32006 by reply(): the document is not even built
      return;
    }
    json document =
        openrpc_document(descriptors(), engine_detail::k_version,
                         global_policy() == GlobalPolicy::preempt ? "preempt" : "reject");
    // the data streams of this transport (rpc.subscribe, rpc.publish): an OpenRPC extension
    document["x-simgate-streams"] = stream_list();
    reply(to, result_response(to.id, std::move(document)));
    return;
  }
  if (reserved && method.starts_with("rpc.") &&
      handle_stream_method(session, method, request.params, to))
    return;
  std::string_view component, service;  // views of method
  if ((reserved && method.starts_with("rpc.")) || !split_method(method, component, service)) {
    const std::string reason =
        method.rfind("rpc.", 0) == 0
            ? "'" + method + "' is not a method of this server (rpc.* is reserved)"
            : "'" + method + "' is not of the form 'component.service'";
    reply(to, error_response(to.id, code::method_not_found, "Method not found: " + reason,
                             json{{"method", method}, {"reason", reason}}));
    return;
  }

  // limits: calls in flight on this connection, ids unique among them
  if (session.in_flight() >= options_.tcp.max_in_flight) {
    if (to.notification)
      log::debug(name(), ": ", session.label(), ": notification ", method, " dropped: overloaded");
    reply(to,
          error_response(to.id, code::overloaded,
                         "Overloaded: " + std::to_string(session.in_flight()) +
                             " calls in flight on this connection (max_in_flight " +
                             std::to_string(options_.tcp.max_in_flight) + ")",
                         json{{"method", method}, {"max_in_flight", options_.tcp.max_in_flight}}));
    return;
  }
  // the session's key for the id: its text as echoed ("" for a null id or none: untracked);
  // taken at once (one probe of the table), given back if the call is refused below
  std::string_view key;
  std::size_t key_hash = 0;
  const RequestId id = add_pending();  // filled below once the call is accepted
  if (request.has_id && !request.id.is_null()) {
    if (request.id_text.empty()) request.id_text = dump(request.id);
    key = request.id_text;
    const auto hash = session.track(key, id);
    if (!hash) {
      drop_pending(id);
      reply(to, error_response(to.id, code::invalid_request,
                               "Invalid Request: id " + request.id_text +
                                   " is already used by a pending call on this connection",
                               json{{"method", method}, {"reason", "duplicate id"}}));
      return;
    }
    key_hash = *hash;
  }

  // call options: "_meta" in named params (MCP's convention), never an argument
  // (positional params have no place for them: an array's elements are all arguments)
  CallOptions call_options;
  if (request.params.is_object()) {
    if (auto meta = request.params.find("_meta"); meta != request.params.end()) {
      std::string why;
      call_options = read_meta(*meta, why);
      if (!why.empty()) {
        if (!key.empty()) session.forget_call(key_hash, id);
        drop_pending(id);
        reply(to, error_response(to.id, code::invalid_params, "Invalid params: _meta: " + why,
                                 json{{"method", method}, {"parameter", "_meta"}}));
        return;
      }
      request.params.erase(meta);
    }
  }
  // progress goes to the call's id: a notification (no id) or a null id has none
  const bool wants_progress = call_options.progress && !key.empty() && !to.notification;

  // gathered; flush_submissions() hands the calls of this read to the core together
  session.add_in_flight();
  if (to_submit_count_ == to_submit_.size()) to_submit_.emplace_back();
  auto& [call_id, call] = to_submit_[to_submit_count_++];
  call_id = id;
  // a kept call object names the same service more often than not: no copy then
  if (!same_text(call.component, component)) call.component.assign(component);
  if (!same_text(call.service, service)) call.service.assign(service);
  call.params.swap(request.params);  // request_ takes the call's old array, for the next parse
  call.progress = wants_progress;
  call.client = session.number();
  call.timeout = call_options.timeout;  // a notification's too: its service stops in time
  Pending& pending = **pending_.find(id);
  pending.to = std::move(to);
  assign_text(pending.method, method);
  assign_text(pending.id_key, key);
  pending.id_hash = key_hash;
  pending.cancel = false;
}

RequestId JsonRpcEngine::add_pending() {
  std::unique_ptr<Pending> entry;
  if (spare_pending_.empty()) {
    entry = std::make_unique<Pending>();
  } else {
    entry = std::move(spare_pending_.back());
    spare_pending_.pop_back();
  }
  return pending_.insert(std::move(entry));
}

void JsonRpcEngine::drop_pending(RequestId id) {
  if (auto* slot = pending_.find(id)) {
    if (spare_pending_.size() < k_spare_pending) {
      (*slot)->recycle();
      spare_pending_.push_back(std::move(*slot));
    }
    pending_.erase(id);
  }
}

void JsonRpcEngine::handle_login(Session& session, const json& params, ReplyTo to) {
  // {"token": "..."} or ["..."]
  const json* token = nullptr;
  if (params.is_object() && params.size() == 1 && params.contains("token"))
    token = &params["token"];
  if (params.is_array() && params.size() == 1) token = &params[0];
  if (!token || !token->is_string()) {
    reply(to, error_response(
                  to.id, code::invalid_params,
                  "Invalid params: rpc.login takes the token, as {\"token\": \"...\"} or [\"...\"]",
                  json{{"method", "rpc.login"}}));
    return;
  }
  // no authentication configured: any login succeeds (a client may always log in)
  if (!options_.tcp.auth.enabled ||
      options_.tcp.auth.accepts(token->get_ref<const std::string&>())) {
    if (options_.tcp.auth.enabled) log::info(name(), ": ", session.label(), " authenticated");
    session.set_authenticated();
    reply(to, result_response(to.id, true));
    return;
  }
  // one guess per connection: the error goes out with this read's replies, then it closes
  log::warning(name(), ": ", session.label(), " presented a wrong token; connection closed");
  reply(to,
        error_response(to.id, code::unauthorized, "Unauthorized: wrong token; connection closed",
                       json{{"method", "rpc.login"}}));
  boost::asio::post(io_, [session = session.shared()] {
    session->flush_writes();
    session->end("wrong token", kit::Ending::refused);
  });
}

void JsonRpcEngine::handle_cancel(Session& session, const std::string& method, const json& params,
                                  ReplyTo to) {
  // {"id": X} or [X]
  const json* target = nullptr;
  if (params.is_object() && params.contains("id")) target = &params["id"];
  if (params.is_array() && params.size() == 1) target = &params[0];
  if (!target || !(target->is_string() || target->is_number())) {
    reply(to, error_response(to.id, code::invalid_params,
                             "Invalid params: " + method +
                                 " takes {\"id\": <id of one of your pending calls>}",
                             json{{"method", method}, {"parameter", "id"}}));
    return;
  }
  // calls read before this cancel reach the simulation thread first (inside a batch the
  // batch's calls stay together: a cancel there sees the calls of earlier messages only)
  if (!to.batch) flush_submissions();
  const auto id = session.find(dump(*target));
  if (!id) {
    reply(to, result_response(to.id, false));
    return;
  }
  // the answer comes once the cancel ran, through the same list as outcomes, so it keeps
  // its place among the replies (before the cancelled call's -32002)
  const RequestId cancel_id = add_pending();
  session.add_in_flight();
  Pending& pending = **pending_.find(cancel_id);
  pending.to = std::move(to);
  pending.method.assign(method);
  pending.id_key.clear();
  pending.cancel = true;
  cancel(*id, [this, cancel_id](bool found) {
    complete_request(cancel_id, Outcome::success(json(found)));
  });
}

void JsonRpcEngine::on_service_completion(RequestId id, Outcome&& outcome) {
  // the I/O thread (deliver_on_this_thread): inside run_or_submit, or drain_completions()
  finish_call(id, std::move(outcome));
}

void JsonRpcEngine::on_service_progress(RequestId id, json&& value) {
  // the I/O thread, before the call's response
  auto* slot = pending_.find(id);
  if (!slot) return;
  Pending* pending = slot->get();
  Session* session = pending->to.session.get();
  if (!session) return;  // its client left
  const std::string& id_key = pending->id_key;
  session->queue_droppable_message([&](std::string& out) {
    out += R"({"jsonrpc":"2.0","method":"rpc.progress","params":{"id":)";
    out += id_key;
    out += R"(,"status":"RUNNING","data":)";
    out += dump(value);
    out += "}}";
  });
}

void JsonRpcEngine::drain_completions() {
  // replies of the whole burst go out with one write per connection
  deliver_handed_over();
  flush_replies();
}

void JsonRpcEngine::finish_call(RequestId id, Outcome&& outcome) {
  auto* slot = pending_.find(id);
  if (!slot) return;
  // taken out of the table while it is answered (the reply may close its connection); kept
  // for a later call afterwards
  struct GiveBack {
    std::vector<std::unique_ptr<Pending>>& spare;
    std::unique_ptr<Pending> entry;
    ~GiveBack() {
      if (spare.size() >= k_spare_pending) return;
      entry->recycle();
      spare.push_back(std::move(entry));
    }
  } taken{spare_pending_, std::move(*slot)};
  pending_.erase(id);
  Pending& pending = *taken.entry;
  // no atomic operation here (kit::ConnectionRef): null when the client left, and then
  // nobody to answer: skip serialising (results can be large)
  Session* session = pending.to.session.get();
  if (!session) return;
  try {
    if (pending.cancel) {
      // rpc.cancel's own answer: true if the call was still running
      reply(pending.to, result_response(pending.to.id,
                                        outcome.value ? std::move(*outcome.value) : json(false)));
    } else if (outcome.status == Status::success) {
      static const json k_no_result;  // null
      if (pending.to.batch)
        reply(pending.to, result_response(pending.to.id, outcome.value ? std::move(*outcome.value)
                                                                       : json(nullptr)));
      else if (!pending.to.notification) {
        // the envelope by hand around the result; id_key is dump(id) ("" for a null id)
        line_.clear();
        append_result_line(line_,
                           pending.id_key.empty() ? std::string_view("null") : pending.id_key,
                           outcome.value ? *outcome.value : k_no_result);
        session->queue_message(line_);
        if (line_.capacity() > engine_detail::k_kept_line_bytes)
          std::string().swap(line_);  // keep no large buffer
      }
    } else {
      reply(pending.to, outcome_response(pending.to.id, outcome, pending.method));
    }
  } catch (const std::exception& e) {
    log::error(tag_, ": reply to ", pending.method, ": ", e.what());
  }
  if (!pending.id_key.empty()) session->forget_call(pending.id_hash, id);
  session->done();
}

void JsonRpcEngine::reply(ReplyTo& to, std::optional<json> response) {
  if (to.batch) {
    auto& batch = *to.batch;
    if (!to.notification) {
      std::string text;
      if (response && !batch.full())
        text = to.id_text.empty() ? dump(*response) : response_with_id_text(*response, to.id_text);
      if (!response || batch.bytes + text.size() > batch.max_bytes) {
        // past the batch's byte budget: a short error instead (counted, so the reply stays
        // within max_unsent_bytes plus one such line per entry)
        batch.bytes = std::max(batch.bytes, batch.max_bytes);
        text = dump(error_response(to.id, code::overloaded,
                                   "Overloaded: the batch's reply exceeds max_unsent_bytes (" +
                                       std::to_string(batch.max_bytes) +
                                       "); this entry's response was dropped",
                                   json{{"max_unsent_bytes", batch.max_bytes}}));
      }
      batch.bytes += text.size();
      batch.responses[to.index] = std::move(text);
    }
    if (--batch.remaining > 0) return;
    // the last entry: send what the batch answers, nothing if it held only notifications
    std::string array;
    for (auto& r : batch.responses) {
      if (r.empty()) continue;
      array += array.empty() ? '[' : ',';
      array += r;
    }
    Session* session = to.session.get();
    if (session && !array.empty()) session->queue_message(array + "]");
    return;
  }
  if (to.notification || !response) return;
  if (Session* session = to.session.get())
    session->queue_message(to.id_text.empty() ? dump(*response)
                                              : response_with_id_text(*response, to.id_text));
}

}  // namespace simgate::jsonrpc
