#include "simgate/gateway/cli.h"

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "simgate/client/client.h"
#include "simgate/core/errors.h"
#include "simgate/core/log.h"
#include "simgate/gateway/gateway.h"

namespace simgate::gateway {

namespace {

constexpr const char* k_usage = R"(simgate — MuJoCo simulation whose components serve MORSE-style services

usage:
  simgate run CONFIG [options]     start the simulation described by CONFIG (JSON)
      --log-level LEVEL            trace, debug, info, warning, error, off (overrides the config)
      --realtime-factor F          1 = real time, 2 = twice as fast, max = as fast as possible
      --endpoints-file PATH        write {"transport": ["tcp://host:port", ...]} once listening
      --plugin-path DIR            search transport plugins in DIR first
  simgate check CONFIG [--plugin-path DIR]
                                   validate CONFIG (scene, components, plugins) and exit
  simgate call [options] COMPONENT SERVICE [ARGS...]
                                   call a service; each ARG is JSON (5, "text", [1,2]) or a bare word
      --transport T                socket (default), jsonrpc or dds
      --host H --port P            socket/jsonrpc server address (default 127.0.0.1, 4000 or 4001)
      --domain N --partition P     dds: the simulation's domain and partition (default 0, simgate)
      --dds-config XML             dds: Cyclone XML or file:// URI (default: loopback only)
      --timeout S                  seconds to wait for the answer (default 30)
  simgate list [options]           list the services a server offers (same options as call)
  simgate --help | --version

exit codes: 0 success, 1 failed call or runtime error, 2 bad usage or invalid configuration
)";

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Takes "--name VALUE" options out of args; positional arguments stay in order.
class Args {
 public:
  Args(int argc, char** argv, int first) {
    for (int i = first; i < argc; ++i) items_.emplace_back(argv[i]);
  }
  // Options must come before the positional arguments of `call` (its ARGS may look like options).
  std::optional<std::string> option(const std::string& name) {
    for (std::size_t i = 0; i < items_.size(); ++i) {
      if (items_[i] == "--") break;
      if (items_[i] == name) {
        if (i + 1 >= items_.size()) throw UsageError(name + " needs a value");
        std::string value = items_[i + 1];
        items_.erase(items_.begin() + static_cast<long>(i), items_.begin() + static_cast<long>(i) + 2);
        return value;
      }
      if (items_[i].rfind(name + "=", 0) == 0) {
        std::string value = items_[i].substr(name.size() + 1);
        items_.erase(items_.begin() + static_cast<long>(i));
        return value;
      }
    }
    return std::nullopt;
  }
  // Remaining arguments; unknown "--options" before them are errors.
  std::vector<std::string> positional(bool allow_dashes_after_first = false) {
    std::vector<std::string> out;
    for (const auto& a : items_) {
      if (a == "--") continue;
      if (a.rfind("--", 0) == 0 && !(allow_dashes_after_first && !out.empty()))
        throw UsageError("unknown option " + a);
      out.push_back(a);
    }
    return out;
  }

 private:
  std::vector<std::string> items_;  // not yet consumed
};

void apply_log_level(const std::optional<std::string>& level) {
  if (!level) return;
  log::Level l;
  if (!log::parse_level(*level, l))
    throw UsageError("--log-level: expected trace, debug, info, warning, error or off, found '" + *level + "'");
  log::set_level(l);
}

std::optional<double> parse_factor(const std::optional<std::string>& text) {
  if (!text) return std::nullopt;
  if (*text == "max") return 0.0;
  try {
    std::size_t used = 0;
    double f = std::stod(*text, &used);
    if (used == text->size() && f >= 0) return f;
  } catch (const std::exception&) {
  }
  throw UsageError("--realtime-factor: expected a number >= 0 or 'max', found '" + *text + "'");
}

// Loads the deployment and applies its log level unless the command line set one.
Deployment load(const std::string& file, const std::optional<std::string>& cli_level) {
  Deployment d = load_deployment(file);
  if (cli_level) {
    apply_log_level(cli_level);
  } else if (d.log_level) {
    apply_log_level(d.log_level);
  }
  return d;
}

void write_endpoints_file(const std::string& path, const std::map<std::string, std::vector<std::string>>& endpoints) {
  // written whole, then renamed: a reader never sees half a file
  std::string tmp = path + ".tmp" + std::to_string(getpid());
  {
    std::ofstream out(tmp);
    out << json(endpoints).dump() << "\n";
    if (!out) throw std::runtime_error("--endpoints-file: cannot write '" + tmp + "'");
  }
  std::filesystem::rename(tmp, path);
}

// "tcp://127.0.0.1:4000" -> ("127.0.0.1", "4000")
std::optional<std::pair<std::string, std::string>> tcp_host_port(const std::string& endpoint) {
  const std::string prefix = "tcp://";
  if (endpoint.rfind(prefix, 0) != 0) return std::nullopt;
  std::string rest = endpoint.substr(prefix.size());
  auto colon = rest.rfind(':');
  if (colon == std::string::npos) return std::nullopt;
  std::string host = rest.substr(0, colon);
  if (host.size() > 2 && host.front() == '[') host = host.substr(1, host.size() - 2);
  return std::make_pair(host, rest.substr(colon + 1));
}

void print_banner(Gateway& g) {
  const Deployment& d = g.deployment();
  auto& sim = g.simulation();
  std::size_t robots = d.robots.size(), components = 0;
  for (const auto& r : d.robots) components += r.components.size();
  // the scene as the user would type it: relative to the current directory when inside it
  std::string scene = d.mjcf;
  std::error_code ec;
  auto relative = std::filesystem::relative(d.mjcf, std::filesystem::current_path(), ec);
  if (!ec && !relative.empty() && relative.begin()->string() != "..") scene = relative.string();
  std::cout << "simgate " << SIMGATE_VERSION << ": scene " << scene << ", " << robots << " robot(s), " << components
            << " component(s), timestep " << sim.timestep() << " s, "
            << (sim.realtime_factor() == 0 ? std::string("as fast as possible")
                                           : "real time x" + std::to_string(sim.realtime_factor()).substr(0, 4))
            << "\n";
  std::optional<std::pair<std::string, std::string>> socket_address;
  for (const auto& [name, endpoints] : g.endpoints()) {
    for (const auto& e : endpoints) {
      std::cout << name << ": " << e << "\n";
      auto t = std::find_if(d.transports.begin(), d.transports.end(), [&](const auto& c) { return c.name == name; });
      if (!socket_address && t != d.transports.end() && t->plugin == "socket") socket_address = tcp_host_port(e);
    }
    const auto& served = g.served().at(name);
    std::string list;
    for (const auto& c : served) list += (list.empty() ? "" : ", ") + c;
    std::cout << "  serves: " << (list.empty() ? "(nothing)" : list) << "\n";
  }
  if (socket_address) {
    // a first command: drive the robot if a motion_vw is reachable, else ask for the robots
    std::string first = "1 simulation list_robots";
    for (const auto& r : d.robots)
      for (const auto& c : r.components) {
        auto& served = g.served();
        bool on_socket = false;
        for (const auto& [name, list] : served)
          if (std::find(list.begin(), list.end(), c.name) != list.end()) on_socket = true;
        if (c.type == "motion_vw" && on_socket && first.rfind("1 simulation", 0) == 0)
          first = "1 " + c.name + " set_speed [0.5, 0.2]";
      }
    std::cout << "try: telnet " << socket_address->first << " " << socket_address->second << "   then type: " << first
              << "\n";
  }
  std::cout << "Ctrl-C (or `simulation quit`) stops the simulation.\n" << std::flush;
}

int cmd_run(Args& args, bool check_only) {
  auto level = args.option("--log-level");
  auto factor = parse_factor(args.option("--realtime-factor"));
  auto endpoints_file = args.option("--endpoints-file");
  GatewayOptions options;
  options.check_only = check_only;
  options.realtime_factor = factor;
  while (auto dir = args.option("--plugin-path")) options.plugin_dirs.push_back(*dir);
  auto positional = args.positional();
  if (positional.size() != 1) throw UsageError(std::string(check_only ? "check" : "run") + " takes one CONFIG file");
  apply_log_level(level);

  // SIGINT/SIGTERM are handled by a thread (blocked everywhere else, inherited by the
  // transports' threads); SIGPIPE is ignored: a closed client must not kill the server
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  if (!check_only) {
    pthread_sigmask(SIG_BLOCK, &signals, nullptr);
    signal(SIGPIPE, SIG_IGN);
  }

  Deployment deployment = load(positional[0], level);
  auto registry = sim::builtin_registry();
  std::unique_ptr<Gateway> built;
  try {
    built = std::make_unique<Gateway>(deployment, registry, options);
  } catch (const ConfigError& e) {
    throw ConfigError("config '" + positional[0] + "': " + e.what());
  }
  Gateway& gateway = *built;
  if (check_only) {
    std::size_t components = 0;
    for (const auto& r : deployment.robots) components += 1 + r.components.size();
    std::cout << positional[0] << ": OK (" << deployment.robots.size() << " robot(s), " << components
              << " component(s), " << deployment.transports.size() << " transport(s))\n";
    return 0;
  }

  gateway.start();
  if (endpoints_file) write_endpoints_file(*endpoints_file, gateway.endpoints());
  print_banner(gateway);

  std::atomic<bool> finished{false};
  std::thread signal_thread([&] {
    int received = 0;
    timespec poll{0, 100'000'000};
    while (!finished.load()) {
      siginfo_t info;
      int sig = sigtimedwait(&signals, &info, &poll);
      if (sig <= 0) continue;
      if (++received == 1) {
        log::info("simgate: ", sig == SIGINT ? "SIGINT" : "SIGTERM", ", shutting down");
        gateway.stop();
      } else {
        static const char msg[] = "simgate: second signal, exiting now\n";
        (void)!write(2, msg, sizeof msg - 1);
        _exit(128 + sig);
      }
    }
  });
  int code = 0;
  try {
    gateway.run();
  } catch (const std::exception& e) {
    log::error("simgate: the simulation stopped: ", e.what());
    code = 1;
  }
  // the signal thread goes first: it must not call stop() on a gateway being torn down
  finished = true;
  signal_thread.join();
  gateway.shutdown();
  if (endpoints_file) std::filesystem::remove(*endpoints_file);
  log::info("simgate: stopped");
  return code;
}

json parse_call_argument(const std::string& text) {
  try {
    return json::parse(text);
  } catch (const json::parse_error&) {
    return text;  // a bare word is a string
  }
}

// a positive integer option within [min, max], or the fallback
int int_option(Args& args, const std::string& name, int fallback, int min, int max) {
  auto text = args.option(name);
  if (!text) return fallback;
  try {
    std::size_t used = 0;
    int value = std::stoi(*text, &used);
    if (used == text->size() && value >= min && value <= max) return value;
  } catch (const std::exception&) {
  }
  throw UsageError(name + ": expected an integer from " + std::to_string(min) + " to " + std::to_string(max) +
                   ", found '" + *text + "'");
}

std::unique_ptr<client::Client> connect(Args& args, std::chrono::milliseconds& timeout) {
  std::string transport = args.option("--transport").value_or("socket");
  std::string timeout_text = args.option("--timeout").value_or("30");
  double seconds = 0;
  try {
    seconds = std::stod(timeout_text);
  } catch (const std::exception&) {
  }
  if (!(seconds > 0)) throw UsageError("--timeout: expected a positive number of seconds, found '" + timeout_text + "'");
  timeout = std::chrono::milliseconds(static_cast<long long>(seconds * 1000));

  json options;
  if (transport == "dds") {
    // DDS finds the simulation by domain and partition, not by address
    options = {{"domain", int_option(args, "--domain", 0, 0, 232)},
               {"partition", args.option("--partition").value_or("simgate")}};
    if (auto xml = args.option("--dds-config")) options["config"] = *xml;
  } else {
    options = {{"host", args.option("--host").value_or("127.0.0.1")},
               {"port", int_option(args, "--port", transport == "jsonrpc" ? 4001 : 4000, 1, 65535)}};
  }
  return client::make_client(transport, options);
}

int cmd_call(Args& args) {
  std::chrono::milliseconds timeout{};
  auto client = connect(args, timeout);
  auto positional = args.positional(true);
  if (positional.size() < 2) throw UsageError("call takes COMPONENT SERVICE [ARGS...]");
  json params = json::array();
  for (std::size_t i = 2; i < positional.size(); ++i) params.push_back(parse_call_argument(positional[i]));
  Outcome outcome = client->call(positional[0], positional[1], params, timeout);
  if (outcome.status == Status::success) {
    if (outcome.value) std::cout << outcome.value->dump() << "\n";
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

int cmd_list(Args& args) {
  std::chrono::milliseconds timeout{};
  auto client = connect(args, timeout);
  if (!args.positional().empty()) throw UsageError("list takes no positional arguments");
  json services = client->list_services(timeout);
  for (const auto& s : services) {
    std::string params;
    for (const auto& p : s.value("params", json::array())) {
      params += (params.empty() ? "" : ", ") + p.value("name", std::string("?"));
      if (p.contains("default")) params += "=" + p["default"].dump();
    }
    std::cout << s.value("component", std::string("?")) << " " << s.value("name", std::string("?")) << "(" << params
              << ")" << (s.value("async", false) ? " async" : "");
    std::string doc = s.value("doc", std::string());
    if (!doc.empty()) std::cout << " — " << doc;
    std::cout << "\n";
  }
  return 0;
}

}  // namespace

int run_cli(int argc, char** argv) {
  if (argc < 2) {
    std::cerr << k_usage;
    return 2;
  }
  std::string command = argv[1];
  try {
    Args args(argc, argv, 2);
    if (command == "--help" || command == "-h" || command == "help") {
      std::cout << k_usage;
      return 0;
    }
    if (command == "--version" || command == "version") {
      std::cout << "simgate " << SIMGATE_VERSION << " (MuJoCo " << mj_versionString() << ")\n";
      return 0;
    }
    if (command == "run") return cmd_run(args, false);
    if (command == "check") return cmd_run(args, true);
    if (command == "call") return cmd_call(args);
    if (command == "list") return cmd_list(args);
    throw UsageError("unknown command '" + command + "'");
  } catch (const UsageError& e) {
    std::cerr << "simgate: " << e.what() << "\n(simgate --help shows the usage)\n";
    return 2;
  } catch (const ConfigError& e) {
    std::cerr << "simgate: invalid configuration: " << e.what() << "\n";
    return 2;
  } catch (const client::ClientError& e) {
    std::cerr << "simgate: " << e.what() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "simgate: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace simgate::gateway
