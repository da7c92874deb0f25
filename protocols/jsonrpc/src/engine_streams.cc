// engine_streams.cc — the JSON-RPC engine's data streams (core/streams.h): the reserved
// methods rpc.streams, rpc.subscribe, rpc.unsubscribe and rpc.publish, and the rpc.sample
// notifications a subscription brings. Wire: docs/transports/jsonrpc.md#data-streams.
//
// A subscription belongs to its connection: it ends with rpc.unsubscribe, when the client
// leaves, or when its component is deleted (rpc.unsubscribed {subscription, reason} tells
// the client). Samples are notifications the client may miss: each subscription keeps the
// latest `stream_queue` samples in the core, and a connection that lets more than the
// session's droppable budget (kit::Connection::k_droppable_unsent_bytes, both transports)
// pile up unread loses samples rather than its replies; both losses are counted (simulation
// get_stream_statistics) and logged once.
//
// Threads: the I/O thread, except wake_streams() (the thread that holds the simulation
// lock, when a subscription's queue stops being empty: one post per burst).
#include <algorithm>

#include <boost/asio/post.hpp>

#include "simgate/jsonrpc/engine.h"
#include "simgate/core/log.h"

namespace simgate::jsonrpc {

namespace streams_detail {

json stream_json(const StreamInfo& info) {
  json out{{"component", info.component},
           {"direction", to_string(info.direction)},
           {"kind", info.kind},
           {"type", info.type}};
  if (info.direction == StreamDirection::out)
    out["frequency"] = info.frequency;
  else
    out["fields"] = info.fields;
  return out;
}

// The one argument `name` of `params`: {"<name>": X} or [X]; null when absent.
const json* single_param(const json& params, const char* name) {
  if (params.is_object() && params.size() == 1 && params.contains(name)) return &params[name];
  if (params.is_array() && params.size() == 1) return &params[0];
  return nullptr;
}

}  // namespace streams_detail

json JsonRpcEngine::stream_list() const {
  json out = json::array();
  if (streams())
    for (const auto& info : streams()->streams(transport_name()))
      out.push_back(streams_detail::stream_json(info));
  return out;
}

bool JsonRpcEngine::handle_stream_method(Session& session, const std::string& method,
                                         const json& params, ReplyTo& to) {
  if (method == "rpc.streams") {
    reply(to, result_response(to.id, stream_list()));
  } else if (method == "rpc.subscribe") {
    subscribe(session, params, to);
  } else if (method == "rpc.unsubscribe") {
    const json* id = streams_detail::single_param(params, "subscription");
    if (!id || !id->is_number_unsigned()) {
      reply(
          to,
          error_response(
              to.id, code::invalid_params,
              "Invalid params: rpc.unsubscribe takes {\"subscription\": <the number rpc.subscribe "
              "answered>}",
              json{{"method", method}, {"parameter", "subscription"}}));
      return true;
    }
    reply(to, result_response(to.id, unsubscribe(session, id->get<std::uint64_t>())));
  } else if (method == "rpc.publish") {
    publish(params, to);
  } else {
    return false;
  }
  return true;
}

void JsonRpcEngine::subscribe(Session& session, const json& params, ReplyTo& to) {
  const json* component = streams_detail::single_param(params, "component");
  if (!component || !component->is_string()) {
    reply(to,
          error_response(
              to.id, code::invalid_params,
              "Invalid params: rpc.subscribe takes {\"component\": \"<a component with an output "
              "stream>\"} (rpc.streams lists them)",
              json{{"method", "rpc.subscribe"}, {"parameter", "component"}}));
    return;
  }
  const std::string& name = component->get_ref<const std::string&>();
  auto info = streams() ? streams()->find(name, transport_name()) : std::nullopt;
  if (!info || info->direction != StreamDirection::out) {
    std::vector<std::string> outputs;
    if (streams())
      for (const auto& s : streams()->streams(transport_name()))
        if (s.direction == StreamDirection::out) outputs.push_back(s.component);
    std::string list;
    for (const auto& o : outputs) list += (list.empty() ? "" : ", ") + o;
    reply(to,
          error_response(
              to.id, code::invalid_params,
              "Invalid params: no output stream '" + name + "' on this transport (" +
                  (list.empty() ? std::string("it carries none") : "output streams: " + list) + ")",
              json{{"method", "rpc.subscribe"}, {"parameter", "component"}, {"streams", outputs}}));
    return;
  }
  // a second subscribe of the same stream on a connection is the first one
  for (const auto& s : stream_subs_)
    if (s.session.lock().get() == &session && s.subscription->component() == name) {
      reply(to, result_response(to.id, json{{"subscription", s.id},
                                            {"stream", streams_detail::stream_json(*info)}}));
      return;
    }
  StreamSub sub;
  sub.id = next_subscription_++;
  sub.session = session.shared();
  sub.subscription =
      streams()->subscribe(name, transport_name(),
                           SubscriberOptions{options_.stream_queue, tag_ + " " + session.label(),
                                             [this] { wake_streams(); }});
  if (!sub.subscription) {  // deleted meanwhile
    reply(to, error_response(to.id, code::invalid_params,
                             "Invalid params: no output stream '" + name + "'",
                             json{{"method", "rpc.subscribe"}, {"parameter", "component"}}));
    return;
  }
  // the answer goes before the first sample (which the next simulation turn brings)
  reply(to, result_response(to.id, json{{"subscription", sub.id},
                                        {"stream", streams_detail::stream_json(*info)}}));
  stream_subs_.push_back(std::move(sub));
}

bool JsonRpcEngine::unsubscribe(Session& session, std::uint64_t id) {
  auto it = std::find_if(stream_subs_.begin(), stream_subs_.end(), [&](const StreamSub& s) {
    return s.id == id && s.session.lock().get() == &session;
  });
  if (it == stream_subs_.end()) return false;
  streams()->unsubscribe(it->subscription);
  stream_subs_.erase(it);
  return true;
}

void JsonRpcEngine::publish(const json& params, ReplyTo& to) {
  // {"component": "robot.motion", "data": {...}} or ["robot.motion", {...}]
  const json* component = nullptr;
  const json* data = nullptr;
  if (params.is_object() && params.size() == 2 && params.contains("component") &&
      params.contains("data")) {
    component = &params["component"];
    data = &params["data"];
  } else if (params.is_array() && params.size() == 2) {
    component = &params[0];
    data = &params[1];
  }
  if (!component || !component->is_string() || !data) {
    reply(to, error_response(
                  to.id, code::invalid_params,
                  "Invalid params: rpc.publish takes {\"component\": \"<a component with an input "
                  "stream>\", \"data\": {<the command>}}",
                  json{{"method", "rpc.publish"}}));
    return;
  }
  PublishResult result;
  if (streams())
    result = streams()->publish(component->get_ref<const std::string&>(), transport_name(), *data);
  else
    result.error = "no input stream '" + component->get_ref<const std::string&>() + "' here";
  if (!result.ok) {
    reply(to, error_response(to.id, code::invalid_params, "Invalid params: " + result.error,
                             json{{"method", "rpc.publish"}, {"component", *component}}));
    return;
  }
  // applied: the component took it; false: it waits for the simulation's next turn (latest wins)
  reply(to, result_response(to.id, json{{"applied", result.applied}}));
}

void JsonRpcEngine::wake_streams() {
  if (streams_woken_.exchange(true, std::memory_order_acq_rel)) return;
  boost::asio::post(io_, [this] { drain_streams(); });
}

void JsonRpcEngine::drain_streams() {
  streams_woken_.store(false, std::memory_order_release);
  for (auto it = stream_subs_.begin(); it != stream_subs_.end();) {
    StreamSub& s = *it;
    auto session = s.session.lock();
    if (!session || session->closed()) {
      streams()->unsubscribe(s.subscription);
      it = stream_subs_.erase(it);
      continue;
    }
    samples_.clear();
    s.subscription->take(samples_);
    std::uint64_t lost = 0;
    for (const SamplePtr& sample : samples_) {
      const bool queued = session->queue_droppable_message([&](std::string& out) {
        out += R"({"jsonrpc":"2.0","method":"rpc.sample","params":{"subscription":)";
        out += std::to_string(s.id);
        out += R"(,"component":)";
        out += dump(json(s.subscription->component()));
        out += R"(,"seq":)";
        out += std::to_string(sample->seq());
        out += R"(,"time":)";
        out += dump(json(sample->time()));
        out += R"(,"data":)";
        out += sample->text();
        out += "}}";
      });
      if (!queued) ++lost;
    }
    s.subscription->note_dropped(lost);
    if (s.subscription->closed()) {
      // its component was deleted: the client learns why its samples stop
      session->queue_message(dump(json{
          {"jsonrpc", "2.0"},
          {"method", "rpc.unsubscribed"},
          {"params",
           {{"subscription", s.id},
            {"component", s.subscription->component()},
            {"reason", "the component left the simulation (removed, or its world deleted)"}}}}));
      it = stream_subs_.erase(it);
      continue;
    }
    ++it;
  }
  samples_.clear();
  flush_replies();
}

void JsonRpcEngine::end_subscriptions(const Session* session) {
  for (auto it = stream_subs_.begin(); it != stream_subs_.end();) {
    auto owner = it->session.lock();
    if (session && owner && owner.get() != session) {
      ++it;
      continue;
    }
    streams()->unsubscribe(it->subscription);
    it = stream_subs_.erase(it);
  }
}

}  // namespace simgate::jsonrpc
