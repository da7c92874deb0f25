#include "simgate/gateway/cli.h"

#include <signal.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "simgate/client/client.h"
#include "simgate/core/errors.h"
#include "simgate/core/log.h"
#include "simgate/core/suggest.h"
#include "simgate/gateway/gateway.h"

namespace simgate::gateway {

namespace {

constexpr const char* k_description = "simgate: a MuJoCo simulation whose components serve MORSE-style services";

constexpr const char* k_footer = R"(Synopsis:
  simgate run CONFIG [--status [SECONDS]] [--log-level L] [--realtime-factor F|max]
                     [--endpoints-file PATH] [--plugin-path DIR]...
  simgate check CONFIG [--log-level L] [--plugin-path DIR]...
  simgate call [CLIENT OPTIONS] COMPONENT SERVICE [ARGS...]
  simgate list [CLIENT OPTIONS] [--json]
  simgate help [COMMAND]
  CLIENT OPTIONS: --transport socket|jsonrpc|dds, --timeout S, then --host H --port P
                  (socket, jsonrpc) or --domain N --partition P --dds-config XML (dds)

`simgate COMMAND --help` shows a command's options (docs/cli.md: the reference).)";

constexpr const char* k_exit_codes =
    "Exit codes: 0 success, 1 failed call or runtime error, 2 bad usage or invalid configuration.";

constexpr const char* k_run_footer = R"(--status prints one line every SECONDS (5 without a value), measured over that time:
  status: sim 12.345 s, real-time factor 1.00 (target 1.00), 3 clients, 812 requests/s
Ctrl-C (SIGINT) or SIGTERM stops the simulation cleanly; a second one exits at once.)";

constexpr const char* k_call_footer = R"(ARGS: each is JSON (5, -1, "text", [1,2], {"a":1}) or a bare word (a string), sent as
positional params [..]; or all of them name=value (name an identifier, value JSON or a bare
word), sent as named params {..}: `simgate call robot.motion set_speed v=0.5 w=0.2`.
Named and positional ARGS cannot be mixed; a string containing '=' is written JSON-quoted:
'"a=b"'. Options come before COMPONENT: everything after it is an ARG, even -1 or --x
(a "--" right after SERVICE is skipped).
Prints the result as JSON, or SUCCESS for a service that returns nothing (exit 0); a
FAILED or PREEMPTED call prints its reason on stderr (exit 1).)";

constexpr double k_default_status_interval = 5.0;  // seconds, `--status` without a value

std::string version_text() { return std::string("simgate ") + SIMGATE_VERSION + " (MuJoCo " + mj_versionString() + ")"; }

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

// A number of seconds within [min, max]; `hint` is appended to the error.
double parse_seconds(const std::string& option, const std::string& text, double min, double max,
                     const std::string& hint = "") {
  try {
    std::size_t used = 0;
    double seconds = std::stod(text, &used);
    if (used == text.size() && seconds >= min && seconds <= max) return seconds;
  } catch (const std::exception&) {
  }
  std::ostringstream range;
  range << min << " to " << max;
  throw UsageError(option + ": expected a number of seconds from " + range.str() + ", found '" + text + "'" + hint);
}

// An integer within [min, max].
int parse_int(const std::string& option, const std::string& text, int min, int max) {
  try {
    std::size_t used = 0;
    int value = std::stoi(text, &used);
    if (used == text.size() && value >= min && value <= max) return value;
  } catch (const std::exception&) {
  }
  throw UsageError(option + ": expected an integer from " + std::to_string(min) + " to " + std::to_string(max) +
                   ", found '" + text + "'");
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

// "2 robot(s), 8 component(s)": a component is anything a transport serves (robots, their
// actuators and sensors, simulation, time), counted the same everywhere
std::string counts(const Deployment& d) {
  return std::to_string(d.robots.size()) + " robot(s), " + std::to_string(d.component_names().size()) +
         " component(s)";
}

void print_banner(Gateway& g) {
  const Deployment& d = g.deployment();
  auto& sim = g.simulation();
  // the scene as the user would type it: relative to the current directory when inside it
  std::string scene = d.mjcf;
  std::error_code ec;
  auto relative = std::filesystem::relative(d.mjcf, std::filesystem::current_path(), ec);
  if (!ec && !relative.empty() && relative.begin()->string() != "..") scene = relative.string();
  std::cout << "simgate " << SIMGATE_VERSION << ": scene " << scene << ", " << counts(d) << ", timestep "
            << sim.timestep() << " s, "
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

// ---- run and check ---------------------------------------------------------------------

// What `run` and `check` were given.
struct RunArgs {
  std::string config;                          // CONFIG
  std::optional<std::string> log_level;        // --log-level
  std::optional<std::string> realtime_factor;  // --realtime-factor
  std::optional<std::string> endpoints_file;   // --endpoints-file
  std::vector<std::string> plugin_dirs;        // --plugin-path, in order
  std::optional<double> status_interval;       // --status [SECONDS], in seconds
};

// One reading of the counters a status line is made of.
struct StatusSample {
  std::chrono::steady_clock::time_point wall;  // when it was taken
  std::uint64_t steps = 0;                     // physics steps since start
  double sim_time = 0;                         // simulated seconds
  double timestep = 0;                         // seconds per step
  double target_factor = 0;                    // configured real-time factor (0 = max)
  std::uint64_t requests = 0;                  // requests handled by every transport
  std::size_t clients = 0;                     // clients connected to every transport
};

// "status: sim 12.345 s, real-time factor 1.00 (target 1.00), 3 clients, 812 requests/s":
// the factor and the rate are measured between two samples (steps, not sim time, so a
// reset of the simulation clock does not count as going backwards).
std::string status_line(const StatusSample& before, const StatusSample& now) {
  double wall = std::chrono::duration<double>(now.wall - before.wall).count();
  double factor = wall > 0 ? static_cast<double>(now.steps - before.steps) * now.timestep / wall : 0.0;
  double rate = wall > 0 ? static_cast<double>(now.requests - before.requests) / wall : 0.0;
  std::ostringstream line;
  line << std::fixed << "status: sim " << std::setprecision(3) << now.sim_time << " s, real-time factor "
       << std::setprecision(2) << factor << " (target ";
  if (now.target_factor == 0) {
    line << "max";
  } else {
    line << now.target_factor;
  }
  line << "), " << now.clients << (now.clients == 1 ? " client, " : " clients, ") << std::setprecision(0) << rate
       << " requests/s\n";
  return line.str();
}

// Prints a status line on stdout every `interval` from a thread of its own, from start()
// until stop() (or destruction). The simulation must outlive it and keep its transports
// meanwhile (stop it before Gateway::shutdown()).
class StatusReporter {
 public:
  StatusReporter(sim::Simulation& simulation, double interval_seconds)
      : simulation_(simulation),
        interval_(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
            std::chrono::duration<double>(interval_seconds))) {}
  ~StatusReporter() { stop(); }
  StatusReporter(const StatusReporter&) = delete;
  StatusReporter& operator=(const StatusReporter&) = delete;

  void start() {
    thread_ = std::thread([this] { run(); });
  }
  // Any thread but its own; returns once the thread has ended.
  void stop() {
    {
      std::lock_guard lock(mutex_);
      stopping_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable()) thread_.join();
  }

 private:
  void run() {
    StatusSample previous = sample();
    auto next = previous.wall + interval_;
    std::unique_lock lock(mutex_);
    while (!wake_.wait_until(lock, next, [&] { return stopping_; })) {
      lock.unlock();
      StatusSample now = sample();
      std::string line = status_line(previous, now);
      std::cout << line << std::flush;
      previous = now;
      // the next line on the interval's grid, skipping beats missed (a suspended process)
      next += interval_;
      if (next <= now.wall) next = now.wall + interval_;
      lock.lock();
    }
  }

  StatusSample sample() {
    StatusSample s;
    s.wall = std::chrono::steady_clock::now();
    s.steps = simulation_.steps();
    {
      // MuJoCo's clock and the pacing are the simulation thread's: read them under its lock,
      // briefly
      std::lock_guard lock(*simulation_.gate());
      s.sim_time = simulation_.sim_time();
      s.timestep = simulation_.timestep();
      s.target_factor = simulation_.realtime_factor();
    }
    for (const auto& manager : simulation_.request_managers()) {
      s.requests += manager->requests_handled();
      s.clients += manager->client_count();
    }
    return s;
  }

  sim::Simulation& simulation_;                    // read, never changed
  std::chrono::steady_clock::duration interval_;   // between two lines
  std::mutex mutex_;                               // guards stopping_
  std::condition_variable wake_;                   // stop() was called
  bool stopping_ = false;                          // the thread must end
  std::thread thread_;                             // prints the lines
};

int cmd_run(const RunArgs& args, bool check_only) {
  GatewayOptions options;
  options.check_only = check_only;
  options.realtime_factor = parse_factor(args.realtime_factor);
  options.plugin_dirs = args.plugin_dirs;
  apply_log_level(args.log_level);

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

  Deployment deployment = load(args.config, args.log_level);
  auto registry = sim::builtin_registry();
  std::unique_ptr<Gateway> built;
  try {
    built = std::make_unique<Gateway>(deployment, registry, options);
  } catch (const ConfigError& e) {
    throw ConfigError(e.errors(), args.config);
  }
  Gateway& gateway = *built;
  if (check_only) {
    for (const auto& w : gateway.warnings()) std::cout << "warning: " << w << "\n";
    std::cout << args.config << ": OK (" << counts(deployment) << ", " << deployment.transports.size()
              << " transport(s)" << (gateway.warnings().empty() ? "" : ", " + std::to_string(gateway.warnings().size()) + " warning(s)") << ")\n";
    return 0;
  }
  for (const auto& w : gateway.warnings()) log::warning("config '", args.config, "': ", w);

  gateway.start();
  if (args.endpoints_file) write_endpoints_file(*args.endpoints_file, gateway.endpoints());
  print_banner(gateway);
  std::optional<StatusReporter> status;
  if (args.status_interval) {
    status.emplace(gateway.simulation(), *args.status_interval);
    status->start();
  }

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
  // the status and signal threads go first: they must not touch a gateway being torn down
  if (status) status->stop();
  finished = true;
  signal_thread.join();
  gateway.shutdown();
  if (args.endpoints_file) std::filesystem::remove(*args.endpoints_file);
  log::info("simgate: stopped");
  return code;
}

// ---- call and list ---------------------------------------------------------------------

// The client options of `call` and `list`, as written.
struct ClientArgs {
  std::string transport = "socket";     // --transport
  std::optional<std::string> host;      // --host
  std::optional<std::string> port;      // --port
  std::optional<std::string> domain;    // --domain
  std::optional<std::string> partition; // --partition
  std::optional<std::string> dds_config;  // --dds-config
  std::string timeout = "30";           // --timeout, seconds
};

const std::vector<std::string> k_transports = {"socket", "jsonrpc", "dds"};

std::unique_ptr<client::Client> connect(const ClientArgs& args, std::chrono::milliseconds& timeout) {
  const std::string& transport = args.transport;
  if (std::find(k_transports.begin(), k_transports.end(), transport) == k_transports.end())
    throw UsageError("--transport: expected socket, jsonrpc or dds, found '" + transport + "'" +
                     did_you_mean(transport, k_transports));
  double seconds = 0;
  try {
    seconds = std::stod(args.timeout);
  } catch (const std::exception&) {
  }
  if (!(seconds > 0)) throw UsageError("--timeout: expected a positive number of seconds, found '" + args.timeout + "'");
  timeout = std::chrono::milliseconds(static_cast<long long>(seconds * 1000));

  json options;
  if (transport == "dds") {
    // DDS finds the simulation by domain and partition, not by address
    if (args.host || args.port)
      throw UsageError(std::string(args.host ? "--host" : "--port") +
                       " is for --transport socket or jsonrpc; dds finds the simulation by --domain and --partition");
    options = {{"domain", args.domain ? parse_int("--domain", *args.domain, 0, 230) : 0},
               {"partition", args.partition.value_or("simgate")}};
    if (args.dds_config) options["config"] = *args.dds_config;
  } else {
    if (args.domain || args.partition || args.dds_config)
      throw UsageError(std::string(args.domain ? "--domain" : args.partition ? "--partition" : "--dds-config") +
                       " is for --transport dds");
    options = {{"host", args.host.value_or("127.0.0.1")},
               {"port", args.port ? parse_int("--port", *args.port, 1, 65535) : (transport == "jsonrpc" ? 4001 : 4000)}};
  }
  return client::make_client(transport, options);
}

// What `call` was given.
struct CallArgs {
  ClientArgs client;              // how to reach the simulation
  std::string component;          // COMPONENT
  std::string service;            // SERVICE
  std::vector<std::string> args;  // ARGS, as written
};

int cmd_call(const CallArgs& args) {
  json params = call_params(args.args);
  std::chrono::milliseconds timeout{};
  auto client = connect(args.client, timeout);
  Outcome outcome = client->call(args.component, args.service, params, timeout);
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

// What `list` was given.
struct ListArgs {
  ClientArgs client;  // how to reach the simulation
  bool json = false;  // --json: the descriptors as one JSON document
};

int cmd_list(const ListArgs& args) {
  std::chrono::milliseconds timeout{};
  auto client = connect(args.client, timeout);
  json services = client->list_services(timeout);
  if (args.json) {
    std::cout << services.dump(2) << "\n";
    return 0;
  }
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

// "name=value" with name an identifier.
bool is_identifier(const std::string& name) {
  if (name.empty() || !(std::isalpha(static_cast<unsigned char>(name[0])) || name[0] == '_')) return false;
  return std::all_of(name.begin(), name.end(),
                     [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; });
}

// JSON, or else the text itself as a string (a bare word).
json json_or_word(const std::string& text) {
  json value = json::parse(text, nullptr, false);
  return value.is_discarded() ? json(text) : value;
}

// ---- the command line ------------------------------------------------------------------

// CLI11's help, with "commands" for its "subcommands".
class HelpFormatter : public CLI::Formatter {
 public:
  HelpFormatter() {
    label("SUBCOMMAND", "COMMAND");
    label("SUBCOMMANDS", "COMMANDS");
    column_width(32);
  }
  std::string make_option_opts(const CLI::Option* option) const override {
    // positionals are in the usage line; no "TEXT REQUIRED" after their names
    return option->get_positional() ? "" : CLI::Formatter::make_option_opts(option);
  }
};

// Every command of `simgate`, their options and where the parsed values go.
class CommandLine {
 public:
  CommandLine() : app_(k_description, "simgate") {
    auto formatter = std::make_shared<HelpFormatter>();
    app_.formatter(formatter);
    app_.footer(std::string(k_footer) + "\n" + k_exit_codes);
    app_.require_subcommand(0, 1);
    app_.set_version_flag("--version", version_text());

    run_ = add_command("run", "start the simulation described by CONFIG (JSON)");
    add_config_options(run_, run_args_);
    run_->add_option("--realtime-factor", run_args_.realtime_factor,
                     "1 = real time, 2 = twice as fast, max = as fast as possible")
        ->type_name("F|max");
    run_->add_option("--endpoints-file", run_args_.endpoints_file,
                     "write {\"transport\": [\"tcp://host:port\", ...]} there once listening")
        ->type_name("PATH");
    status_ = run_->add_option("--status", status_text_,
                               "print sim time, real-time factor, clients, requests/s every SECONDS (default 5)")
                  ->expected(0, 1)
                  ->multi_option_policy(CLI::MultiOptionPolicy::TakeLast)
                  ->option_text("[SECONDS]");
    run_->footer(std::string(k_run_footer) + "\n" + k_exit_codes);

    check_ = add_command("check", "validate CONFIG (scene, components, transport plugins and options) and exit");
    add_config_options(check_, check_args_);
    check_->footer(k_exit_codes);

    call_ = add_command("call", "call a service of a running simulation and print its result");
    add_client_options(call_, call_args_.client);
    call_->add_option("COMPONENT", call_args_.component, "the component: robot.motion, simulation, ...")
        ->required();
    call_->add_option("SERVICE", call_args_.service, "its service: set_speed, list_robots, ...")->required();
    call_->add_option("ARGS", call_args_.args, "the parameters: JSON values or bare words, or all name=value (below)");
    // options only before COMPONENT: ARGS may look like options (-1, --x)
    call_->positionals_at_end();
    call_->footer(std::string(k_call_footer) + "\n" + k_exit_codes);

    list_ = add_command("list", "list the services a running simulation offers, with their parameters");
    add_client_options(list_, list_args_.client);
    list_->add_flag("--json", list_args_.json, "print the service descriptors as one JSON array");
    list_->footer(k_exit_codes);
  }

  // The top-level help, or one command's.
  std::string help(const std::string& command = "") const {
    if (command.empty()) return app_.help();
    return app_.get_subcommand(command)->help("simgate");
  }
  const std::vector<std::string>& commands() const { return names_; }

  // Parses argv and runs the command; CLI11's errors propagate.
  int run(int argc, char** argv) {
    app_.parse(argc, argv);
    if (run_->parsed()) return cmd_run(finish_run(run_args_), false);
    if (check_->parsed()) return cmd_run(check_args_, true);
    if (call_->parsed()) return cmd_call(call_args_);
    if (list_->parsed()) return cmd_list(list_args_);
    // `simgate` alone
    std::cerr << app_.help();
    return 2;
  }
  // The command being parsed or run ("" for none yet).
  std::string command() const {
    for (const auto* sub : app_.get_subcommands()) return sub->get_name();
    return "";
  }
  // Prints help or version as CLI11 was asked to; returns its exit code.
  int exit(const CLI::ParseError& e) { return app_.exit(e, std::cout, std::cerr); }

 private:
  CLI::App* add_command(const std::string& name, const std::string& description) {
    names_.push_back(name);
    CLI::App* sub = app_.add_subcommand(name, description);
    sub->set_version_flag("--version", version_text());
    sub->group("Commands");
    return sub;
  }

  static void add_config_options(CLI::App* command, RunArgs& args) {
    command->add_option("CONFIG", args.config, "the deployment file (JSON, docs/configuration.md)")
        ->required();
    command->add_option("--log-level", args.log_level, "trace, debug, info, warning, error or off (overrides the config)")
        ->type_name("L");
    command->add_option("--plugin-path", args.plugin_dirs, "search transport plugins in DIR (after SIMGATE_PLUGIN_PATH; repeatable)")
        ->allow_extra_args(false)
        ->option_text("DIR");
  }

  static void add_client_options(CLI::App* command, ClientArgs& args) {
    command->add_option("--transport", args.transport, "socket (default), jsonrpc or dds")->type_name("T");
    command->add_option("--host", args.host, "socket/jsonrpc: the server's address (default 127.0.0.1)")
        ->type_name("H");
    command->add_option("--port", args.port, "socket/jsonrpc: its port (default 4000 socket, 4001 jsonrpc)")
        ->type_name("P");
    command->add_option("--domain", args.domain, "dds: the simulation's DDS domain (default 0)")->type_name("N");
    command->add_option("--partition", args.partition, "dds: its partition (default simgate)")->type_name("P");
    command->add_option("--dds-config", args.dds_config,
                        "dds: Cyclone XML or file:// URI (default: loopback only; env = CYCLONEDDS_URI)")
        ->type_name("XML");
    command->add_option("--timeout", args.timeout, "seconds to wait for the simulation and its answer (default 30)")
        ->type_name("S");
  }

  // --status: no value = every k_default_status_interval seconds
  RunArgs& finish_run(RunArgs& args) {
    if (status_->count() == 0) return args;
    if (status_text_.empty()) {
      args.status_interval = k_default_status_interval;
      return args;
    }
    // a word that is no number was probably meant as a file (CLI11 gives the required
    // CONFIG its value first, so only a second file can end up here)
    const std::string& text = status_text_.back();
    bool number = !json::parse(text, nullptr, false).is_discarded();
    args.status_interval =
        parse_seconds("--status", text, 0.1, 86400, number ? "" : " (write CONFIG before a --status without SECONDS)");
    return args;
  }

  CLI::App app_;                          // `simgate`
  std::vector<std::string> names_;        // the commands, in order
  CLI::App *run_, *check_, *call_, *list_;  // its commands
  CLI::Option* status_;                   // run --status
  std::vector<std::string> status_text_;  // its value, if any
  RunArgs run_args_, check_args_;         // parsed values of each command
  CallArgs call_args_;
  ListArgs list_args_;
};

}  // namespace

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
      throw UsageError("call: '" + arg + "': a named argument is name=value with name an identifier; a string "
                       "containing '=' is written JSON-quoted: '" + json(arg).dump() + "'");
    if (named.contains(name)) throw UsageError("call: parameter '" + name + "' is given twice");
    named[name] = json_or_word(arg.substr(eq + 1));
    if (a_named.empty()) a_named = arg;
  }
  if (!a_named.empty() && !a_positional.empty())
    throw UsageError("call: ARGS are either all positional or all named (name=value), not both: '" + a_named +
                     "' is named, '" + a_positional + "' is positional (a string containing '=' is written "
                     "JSON-quoted: '\"a=b\"')");
  return a_named.empty() ? positional : named;
}

int run_cli(int argc, char** argv) {
  CommandLine cli;
  try {
    // `simgate help [COMMAND]`, `simgate version` (kept from before CLI11), and a misspelt
    // command named as such
    if (argc >= 2 && argv[1][0] != '-') {
      std::string command = argv[1];
      const auto& commands = cli.commands();
      if (command == "help") {
        std::string topic = argc >= 3 ? argv[2] : "";
        if (!topic.empty() && std::find(commands.begin(), commands.end(), topic) == commands.end())
          throw UsageError("help: unknown command '" + topic + "'" + did_you_mean(topic, commands));
        std::cout << cli.help(topic);
        return 0;
      }
      if (command == "version") {
        std::cout << version_text() << "\n";
        return 0;
      }
      if (std::find(commands.begin(), commands.end(), command) == commands.end())
        throw UsageError("unknown command '" + command + "'" + did_you_mean(command, commands));
    }
    return cli.run(argc, argv);
  } catch (const CLI::Success& e) {
    return cli.exit(e);  // --help, --version
  } catch (const CLI::ParseError& e) {
    std::string command = cli.command();
    std::string who = command.empty() ? "simgate" : "simgate " + command;
    std::cerr << who << ": " << e.what() << "\n(" << who << " --help shows the usage)\n";
    return 2;
  } catch (const UsageError& e) {
    std::string command = cli.command();
    std::string who = command.empty() ? "simgate" : "simgate " + command;
    std::cerr << "simgate: " << e.what() << "\n(" << who << " --help shows the usage)\n";
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
