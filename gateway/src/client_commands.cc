// `simgate call` and `simgate list` (see commands.h), and the params of a call (cli.h).
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdlib>
#include <iostream>
#include <map>
#include <thread>
#include <vector>

#include "commands.h"
#include "simgate/client/client.h"
#include "simgate/core/suggest.h"
#if SIMGATE_CLIENT_DDS
#include "simgate/client/dds_client.h"
#endif

namespace simgate::gateway {

namespace {

const std::vector<std::string> k_transports = {"socket", "jsonrpc", "websocket", "dds"};

// The environment variable that holds a token when --token is not given.
constexpr const char* k_token_variable = "SIMGATE_TOKEN";

}  // namespace

ClientTarget client_target(const ClientArgs& args, bool allow_partition_pattern) {
  const std::string& transport = args.transport;
  if (std::find(k_transports.begin(), k_transports.end(), transport) == k_transports.end())
    throw UsageError("--transport: expected socket, jsonrpc, websocket or dds, found '" +
                     transport + "'" + did_you_mean(transport, k_transports));
  double seconds = 0;
  try {
    seconds = std::stod(args.timeout);
  } catch (const std::exception&) {}
  if (!(seconds > 0))
    throw UsageError("--timeout: expected a positive number of seconds, found '" + args.timeout +
                     "'");
  ClientTarget target{transport, json::object(),
                      std::chrono::milliseconds(static_cast<long long>(seconds * 1000))};

  if (transport == "dds") {
    // DDS finds the simulation by domain and partition, not by address
    if (args.host || args.port)
      throw UsageError(std::string(args.host ? "--host" : "--port") +
                       " is for --transport socket, jsonrpc or websocket; dds finds the simulation "
                       "by --domain and --partition");
#if SIMGATE_CLIENT_DDS
    if (args.partition && client::is_partition_pattern(*args.partition) && !allow_partition_pattern)
      throw UsageError("--partition: '" + *args.partition +
                       "' is a pattern (* or ?): `simgate list` lists the simgates it matches and "
                       "`simgate call` calls each; this command talks to one simgate: name its "
                       "partition");
#endif
    target.options = {{"domain", args.domain ? parse_int("--domain", *args.domain, 0, 230) : 0},
                      {"partition", args.partition.value_or("simgate")}};
    if (args.dds_config) target.options["config"] = *args.dds_config;
  } else {
    if (args.domain || args.partition || args.dds_config)
      throw UsageError(std::string(args.domain      ? "--domain"
                                   : args.partition ? "--partition"
                                                    : "--dds-config") +
                       " is for --transport dds");
    target.options = {{"host", args.host.value_or("127.0.0.1")},
                      {"port", args.port ? parse_int("--port", *args.port, 1, 65535)
                                         : (transport == "jsonrpc"     ? 4001
                                            : transport == "websocket" ? 8090
                                                                       : 4000)}};
  }

  // the token of the transport's "auth": the option's, else the environment's
  const char* from_environment = std::getenv(k_token_variable);
  if (transport == "dds") {
    if (args.token) throw UsageError("--token: " + std::string(client::k_dds_has_no_token));
    if (from_environment && *from_environment)
      std::cerr << "simgate: note: " << k_token_variable
                << " is not used: " << client::k_dds_has_no_token << "\n";
  } else if (args.token || (from_environment && *from_environment)) {
    target.options["token"] = args.token ? *args.token : std::string(from_environment);
    target.options["timeout_ms"] = target.timeout.count();
  }
  return target;
}

std::unique_ptr<client::Client> connect_client(const ClientArgs& args,
                                               std::chrono::milliseconds& timeout) {
  ClientTarget target = client_target(args);
  timeout = target.timeout;
  return client::make_client(target.transport, target.options);
}

namespace {

// "name=value" with name an identifier.
bool is_identifier(const std::string& name) {
  if (name.empty() || !(std::isalpha(static_cast<unsigned char>(name[0])) || name[0] == '_'))
    return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
  });
}

// JSON, or else the text itself as a string (a bare word).
json json_or_word(const std::string& text) {
  json value = json::parse(text, nullptr, false);
  return value.is_discarded() ? json(text) : value;
}

}  // namespace

#if SIMGATE_CLIENT_DDS
namespace {

// `call --transport dds --partition PATTERN`: the call made on every simgate the pattern
// matches (by convention one per host), all at once, through a client each (a thread each:
// a host's reply never waits for another's). One JSON line per simgate, in the partitions'
// order: {"partition", "server", "status": "SUCCESS", "result"} or {..., "status": "FAILED",
// "message"}; exit 0 when every call succeeded.
int call_dds_simgates(const CallArgs& args, const ClientTarget& target, const json& params) {
  const auto simgates =
      client::list_simgates(client::DdsClientOptions::from_json(target.options), target.timeout);
  // one a partition (list_simgates sorts them by partition): a call there reaches them all
  std::vector<const client::DdsSimgate*> called;
  for (const auto& simgate : simgates) {
    if (!called.empty() && called.back()->partition == simgate.partition) {
      std::cerr << "simgate: note: partition '" << simgate.partition
                << "' has several simgates: the call there reaches each of them and one line "
                   "is printed for the partition; give each simgate a partition of its own "
                   "(docs/worlds.md, \"Across hosts\")\n";
      continue;
    }
    called.push_back(&simgate);
  }
  struct Reply {
    Status status = Status::failed;
    json said;  // the result (success), else the message
  };
  std::vector<Reply> replies(called.size());
  // the clients made one after the other (each joins the domain), then called at once
  std::vector<std::unique_ptr<client::Client>> clients(called.size());
  for (std::size_t i = 0; i < called.size(); ++i) {
    try {
      json options = target.options;
      options["partition"] = called[i]->partition;
      clients[i] = client::make_client("dds", options);
    } catch (const std::exception& e) {
      replies[i].said = e.what();
    }
  }
  std::vector<std::thread> calls;
  for (std::size_t i = 0; i < called.size(); ++i) {
    if (!clients[i]) continue;
    calls.emplace_back([&, i] {
      Reply& reply = replies[i];
      try {
        const Outcome outcome =
            clients[i]->call(args.component, args.service, params, target.timeout);
        reply.status = outcome.status;
        reply.said = outcome.status != Status::success ? json(outcome.message)
                     : outcome.value                   ? *outcome.value
                                                       : json();
      } catch (const std::exception& e) {
        reply.said = e.what();
      }
    });
  }
  for (auto& call : calls) call.join();
  std::size_t failed = 0;
  for (std::size_t i = 0; i < called.size(); ++i) {
    const Reply& reply = replies[i];
    const bool success = reply.status == Status::success;
    // its members in this order (a json object would sort them)
    std::cout << "{\"partition\":" << json(called[i]->partition).dump()
              << ",\"server\":" << json(called[i]->server).dump()
              << ",\"status\":" << json(to_string(reply.status)).dump()
              << (success ? ",\"result\":" : ",\"message\":") << reply.said.dump() << "}\n";
    if (!success) ++failed;
  }
  if (failed > 0)
    std::cerr << "simgate: " << failed << " of " << called.size() << " simgates did not succeed\n";
  return failed > 0 ? 1 : 0;
}

}  // namespace
#endif

int cmd_call(const CallArgs& args) {
  json params = call_params(args.args);
  const ClientTarget target = client_target(args.client, /*allow_partition_pattern=*/true);
#if SIMGATE_CLIENT_DDS
  if (target.transport == "dds" &&
      client::is_partition_pattern(target.options.at("partition").get<std::string>()))
    return call_dds_simgates(args, target, params);
#endif
  auto client = client::make_client(target.transport, target.options);
  Outcome outcome = client->call(args.component, args.service, params, target.timeout);
  if (outcome.status == Status::success) {
    // a service that returns nothing answers a bare SUCCESS (JSON-RPC: a null result)
    if (outcome.value && !outcome.value->is_null()) {
      std::cout << outcome.value->dump() << "\n";
    } else {
      std::cout << "SUCCESS\n";
    }
    return 0;
  }
  std::cerr << to_string(outcome.status);
  if (!outcome.message.empty()) {
    std::cerr << ": " << outcome.message;
  } else if (outcome.value) {
    std::cerr << " " << outcome.value->dump();
  }
  std::cerr << "\n";
  return 1;
}

namespace {

// The data streams this transport carries (`simulation get_stream_statistics` of each world
// `simulation list_worlds` lists, where the client may call them: a world's under "w<k>/"),
// one line each, with its port where the transport has one per stream (the socket
// transport's `simulation get_all_stream_ports`), each line after `indent`.
void print_streams(client::Client& client, std::chrono::milliseconds timeout,
                   const std::string& indent) {
  std::vector<std::string> prefixes{""};
  Outcome worlds = client.call("simulation", "list_worlds", json::array(), timeout);
  if (worlds.status == Status::success && worlds.value && worlds.value->contains("worlds"))
    for (const auto& w : (*worlds.value)["worlds"])
      if (w.value("world", 0) > 0) prefixes.push_back("w" + w["world"].dump() + "/");
  Outcome ports = client.call("simulation", "get_all_stream_ports", json::array(), timeout);
  for (const std::string& prefix : prefixes) {
    Outcome streams =
        client.call(prefix + "simulation", "get_stream_statistics", json::array(), timeout);
    if (streams.status != Status::success || !streams.value || !streams.value->is_array()) continue;
    for (const auto& s : *streams.value) {
      const std::string component = prefix + s.value("component", std::string("?"));
      std::cout << indent << component << " stream " << s.value("direction", std::string("?"))
                << " " << s.value("kind", std::string("?"));
      // an event stream (simulation.events) has no rate: frequency 0
      if (s.contains("frequency") && s["frequency"] != 0)
        std::cout << ", " << s["frequency"].dump() << " Hz";
      else if (s.contains("frequency"))
        std::cout << ", as events happen";
      if (s.contains("fields")) {
        std::string fields;
        for (const auto& f : s["fields"])
          fields += (fields.empty() ? "" : ", ") + f.get<std::string>();
        std::cout << " {" << fields << "}";
      }
      if (ports.status == Status::success && ports.value && ports.value->contains(component))
        std::cout << ", port " << (*ports.value)[component].dump();
      std::cout << "\n";
    }
  }
}

// Service descriptors, one line each after `indent`: component name(params) async — doc.
void print_services(const json& services, const std::string& indent) {
  for (const auto& s : services) {
    std::string params;
    for (const auto& p : s.value("params", json::array())) {
      params += (params.empty() ? "" : ", ") + p.value("name", std::string("?"));
      if (p.contains("default")) params += "=" + p["default"].dump();
    }
    std::cout << indent << s.value("component", std::string("?")) << " "
              << s.value("name", std::string("?")) << "(" << params << ")"
              << (s.value("async", false) ? " async" : "");
    std::string doc = s.value("doc", std::string());
    if (!doc.empty()) std::cout << " — " << doc;
    std::cout << "\n";
  }
}

#if SIMGATE_CLIENT_DDS
// `list --transport dds --partition PATTERN`: every simgate the pattern matches, by
// partition (its host), with its worlds, services and streams.
int list_dds_simgates(const ListArgs& args, const ClientTarget& target) {
  const auto simgates =
      client::list_simgates(client::DdsClientOptions::from_json(target.options), target.timeout);
  std::map<std::string, std::vector<std::string>> servers;  // by partition
  for (const auto& simgate : simgates) servers[simgate.partition].push_back(simgate.server);
  for (const auto& [partition, ids] : servers) {
    if (ids.size() < 2) continue;
    std::string listed;
    for (const auto& id : ids) listed += (listed.empty() ? "" : ", ") + id;
    std::cerr << "simgate: note: partition '" << partition << "' has several simgates (" << listed
              << "): a call there reaches each of them; give each simgate a partition of its own "
              << "(docs/worlds.md, \"Across hosts\")\n";
  }
  if (args.json) {
    json out = json::array();
    for (const auto& simgate : simgates) out.push_back(simgate.to_json());
    std::cout << out.dump(2) << "\n";
    return 0;
  }
  for (std::size_t i = 0; i < simgates.size(); ++i) {
    const client::DdsSimgate& simgate = simgates[i];
    std::string worlds;
    for (const auto& world : simgate.worlds) worlds += (worlds.empty() ? "" : ", ") + world;
    std::cout << (i ? "\n" : "") << "partition " << simgate.partition << ": worlds " << worlds
              << "; server " << simgate.server
              << (simgate.whole ? "" : " (its catalog was still arriving)") << "\n";
    print_services(simgate.services, "  ");
    // its streams: a call to that simgate alone
    json options = target.options;
    options["partition"] = simgate.partition;
    try {
      auto client = client::make_client("dds", options);
      print_streams(*client, target.timeout, "  ");
    } catch (const client::ClientError& e) {
      std::cerr << "simgate: note: the streams of partition '" << simgate.partition
                << "' were not read: " << e.what() << "\n";
    }
  }
  return 0;
}
#endif

}  // namespace

int cmd_list(const ListArgs& args) {
  const ClientTarget target = client_target(args.client, /*allow_partition_pattern=*/true);
#if SIMGATE_CLIENT_DDS
  if (target.transport == "dds" &&
      client::is_partition_pattern(target.options.at("partition").get<std::string>()))
    return list_dds_simgates(args, target);
#endif
  auto client = client::make_client(target.transport, target.options);
  json services = client->list_services(target.timeout);
  if (args.json) {
    std::cout << services.dump(2) << "\n";
    return 0;
  }
  print_services(services, "");
  print_streams(*client, target.timeout, "");
  return 0;
}

json call_params(const std::vector<std::string>& args) {
  auto first = args.begin();
  if (first != args.end() && *first == "--") ++first;
  json positional = json::array(), named = json::object();
  std::string a_positional, a_named;  // one of each, for the message
  for (auto it = first; it != args.end(); ++it) {
    const std::string& arg = *it;
    json value = json::parse(arg, nullptr, false);
    auto eq = arg.find('=');
    if (!value.is_discarded() || eq == std::string::npos) {
      positional.push_back(value.is_discarded() ? json(arg) : std::move(value));
      if (a_positional.empty()) a_positional = arg;
      continue;
    }
    std::string name = arg.substr(0, eq);
    if (!is_identifier(name))
      throw UsageError("call: '" + arg +
                       "': a named argument is name=value with name an identifier; a string "
                       "containing '=' is written JSON-quoted: '" +
                       json(arg).dump() + "'");
    if (named.contains(name)) throw UsageError("call: parameter '" + name + "' is given twice");
    named[name] = json_or_word(arg.substr(eq + 1));
    if (a_named.empty()) a_named = arg;
  }
  if (!a_named.empty() && !a_positional.empty())
    throw UsageError("call: ARGS are either all positional or all named (name=value), not both: '" +
                     a_named + "' is named, '" + a_positional +
                     "' is positional (a string containing '=' is written "
                     "JSON-quoted: '\"a=b\"')");
  return a_named.empty() ? positional : named;
}

}  // namespace simgate::gateway
