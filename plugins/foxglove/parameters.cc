// parameters.cc — the foxglove transport's parameters: every component's properties
// (get_properties, set_property) as /<component>/<property> (foxglove_server.h).
#include <algorithm>

#include "foxglove_client.h"
#include "simgate/core/text.h"

namespace simgate::foxglove {

// ---- parameters: the components' properties

struct FoxgloveServer::ParameterQuery {
  std::weak_ptr<Client> client;  // who asked (none: the subscriptions' poll)
  std::string id;                // its request's id
  std::set<std::string> wanted;  // the names asked (empty: all)
  bool poll = false;             // the poll: subscribers get what changed
  std::size_t waiting = 0;       // get_properties calls not answered yet
  std::vector<std::pair<std::string, json>> values;
};

std::optional<std::pair<std::string, std::string>> FoxgloveServer::parameter_of(
    const std::string& name) const {
  std::optional<std::pair<std::string, std::string>> best;
  for (const ServiceDef& s : services_) {
    if (s.service != "set_property") continue;
    const std::string prefix = topic_of(s.component) + "/";
    if (name.size() > prefix.size() && name.starts_with(prefix) &&
        (!best || prefix.size() > topic_of(best->first).size() + 1))
      best = std::pair{s.component, name.substr(prefix.size())};
  }
  return best;
}

void FoxgloveServer::query_parameters(const std::shared_ptr<ParameterQuery>& query) {
  std::vector<std::pair<RequestId, Call>> calls;
  for (const ServiceDef& s : services_) {
    if (s.service != "get_properties") continue;
    const RequestId id = new_request_id();
    parameter_calls_[id] = ParameterCall{query, s.component, {}, {}};
    calls.emplace_back(id, Call{s.component, "get_properties", json::object()});
  }
  query->waiting = calls.size();
  if (calls.empty()) {
    finish_query(*query);
    return;
  }
  run_or_submit(std::move(calls));
}

void FoxgloveServer::get_parameters(Client& client, const GetParameters& request) {
  auto query = std::make_shared<ParameterQuery>();
  query->client = std::static_pointer_cast<Client>(client.shared_from_this());
  query->id = request.id;
  query->wanted.insert(request.names.begin(), request.names.end());
  query_parameters(query);
}

void FoxgloveServer::set_parameters(Client& client, const SetParameters& request) {
  std::vector<std::pair<RequestId, Call>> calls;
  auto self = std::static_pointer_cast<Client>(client.shared_from_this());
  std::vector<std::string> names;
  for (const auto& [name, value] : request.parameters) {
    const auto target = parameter_of(name);
    if (!target) {
      std::vector<std::string> components;
      for (const ServiceDef& s : services_)
        if (s.service == "set_property") components.push_back(topic_of(s.component));
      complain(client, Level::error,
               "setParameters: no parameter " + quoted_prefix(name) +
                   " (a parameter is /<component>/<property>; components with properties here: " +
                   (components.empty() ? std::string("none") : join(components)) + ")");
      continue;
    }
    const RequestId id = new_request_id();
    parameter_calls_[id] = ParameterCall{nullptr, target->first, self, name};
    calls.emplace_back(id, Call{target->first, "set_property",
                                json{{"prop_name", target->second}, {"prop_val", value}}});
    names.push_back(name);
  }
  if (!calls.empty()) run_or_submit(std::move(calls));
  // the answer: the values as they are now (set ones included: the calls ran first, or wait
  // for the same simulation turn ahead of the query's)
  if (!request.id.empty()) get_parameters(client, GetParameters{names, request.id});
  poll_parameters();  // subscribers learn of the change
}

bool FoxgloveServer::parameter_completion(RequestId id, Outcome& outcome) {
  const auto it = parameter_calls_.find(id);
  if (it == parameter_calls_.end()) return false;
  ParameterCall call = std::move(it->second);
  parameter_calls_.erase(it);
  if (!call.query) {  // set_property
    if (outcome.status != Status::success)
      if (auto client = call.setter.lock(); client && !client->closed())
        complain(*client, Level::error,
                 "setParameters: " + call.name + ": " + std::string(to_string(outcome.status)) +
                     (outcome.message.empty() ? "" : ": " + outcome.message));
    return true;
  }
  ParameterQuery& query = *call.query;
  if (outcome.status == Status::success && outcome.value && outcome.value->is_object()) {
    const auto properties = outcome.value->find("properties");
    if (properties != outcome.value->end() && properties->is_object())
      for (const auto& [property, value] : properties->items()) {
        std::string name = topic_of(call.component) + "/" + property;
        if (query.wanted.empty() || query.wanted.count(name))
          query.values.emplace_back(std::move(name), value);
      }
  }
  if (--query.waiting == 0) finish_query(query);
  return true;
}

void FoxgloveServer::finish_query(ParameterQuery& query) {
  if (!query.poll) {
    if (auto client = query.client.lock(); client && !client->closed())
      client->queue_text(parameter_values(query.values, query.id));
    return;
  }
  parameters_polling_ = false;
  std::vector<std::pair<std::string, json>> changed;
  for (auto& [name, value] : query.values) {
    auto known = parameters_known_.find(name);
    if (known != parameters_known_.end() && known->second == value) continue;
    parameters_known_[name] = value;
    changed.emplace_back(name, value);
  }
  if (changed.empty()) return;
  for_each_connection([&](kit::Connection& connection) {
    auto& client = static_cast<Client&>(connection);
    std::vector<std::pair<std::string, json>> theirs;
    for (const auto& [name, value] : changed)
      if (client.all_parameters || client.parameters.count(name)) theirs.emplace_back(name, value);
    if (!theirs.empty() && client.open()) client.queue_text(parameter_values(theirs, ""));
  });
  flush_touched();
}

void FoxgloveServer::poll_parameters() {
  if (parameters_polling_ || stopping_) return;
  bool wanted = false;
  for_each_connection([&](kit::Connection& connection) {
    const auto& client = static_cast<Client&>(connection);
    wanted = wanted || client.all_parameters || !client.parameters.empty();
  });
  if (!wanted) return;
  parameters_polling_ = true;
  auto query = std::make_shared<ParameterQuery>();
  query->poll = true;
  query_parameters(query);
}

}  // namespace simgate::foxglove
