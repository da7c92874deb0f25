// `simgate run` and `simgate check` (see commands.h).
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <mutex>
#include <sstream>
#include <thread>

#include "commands.h"
#include "simgate/core/errors.h"
#include "simgate/core/log.h"
#include "simgate/gateway/gateway.h"
#include "simgate/sim/model_robots.h"

namespace simgate::gateway {

namespace {

// The transports of `--model` without CONFIG: MORSE's socket protocol and JSON-RPC on
// loopback, at `base` and base + 1 (their usual ports 4000 and 4001 by default; 0: both
// ports the kernel picks); for `simgate mcp` (`mcp_only`), the mcp transport on a port the
// kernel picks.
json default_model_document(int base, bool mcp_only) {
  if (mcp_only)  // its streams too: they are its resources
    return {{"transports",
             {{"mcp", {{"plugin", "mcp"}, {"options", {{"host", "127.0.0.1"}, {"port", 0}}}}}}},
            {"streams", {{"default", {"mcp"}}}}};
  return {
      {"transports",
       {{"socket", {{"plugin", "socket"}, {"options", {{"host", "127.0.0.1"}, {"port", base}}}}},
        {"jsonrpc",
         {{"plugin", "jsonrpc"},
          {"options", {{"host", "127.0.0.1"}, {"port", base == 0 ? 0 : base + 1}}}}}}}};
}

// The deployment of `--model FILE.xml [CONFIG]`: the model's robots (model_robots.h), each
// of type mjcf; the scene is the model (CONFIG's timestep and realtime_factor kept); the
// rest (transports, access lists, component libraries, log level) is CONFIG's, whose own
// robots and mapping are replaced (every transport serves every component).
Deployment model_deployment(const RunArgs& args, ConfigErrors& errors) {
  const std::string model_file = std::filesystem::absolute(*args.model).lexically_normal().string();
  std::vector<sim::ModelRobot> robots;
  try {
    robots = sim::find_model_robots(sim::Model::load_file(model_file));
  } catch (const std::exception& e) {
    throw ConfigError("--model: expected a loadable MJCF model, found an error: " +
                      std::string(e.what()));
  }
  if (args.port && !args.config.empty())
    throw UsageError(
        "--port: only for --model without CONFIG (CONFIG's transports name their own ports)");
  const int port_base = args.port ? parse_int("--port", *args.port, 0, 65534) : 4000;
  json document = args.config.empty() ? default_model_document(port_base, args.mcp_only)
                                      : load_config_document(args.config);
  if (!document.is_object())
    return parse_deployment(document, ".", args.config, errors);  // its own error
  json scene = document.contains("scene") && document["scene"].is_object() ? document["scene"]
                                                                           : json::object();
  scene["mjcf"] = model_file;
  document["scene"] = scene;
  document["robots"] = json::array();
  for (const auto& r : robots)
    document["robots"].push_back({{"name", r.name}, {"type", "mjcf"}, {"body", r.body}});
  document.erase("services");
  const std::string base = args.config.empty()
                               ? std::filesystem::current_path().string()
                               : std::filesystem::absolute(args.config).parent_path().string();
  return parse_deployment(document, base, args.config, errors);
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
  return std::to_string(d.robots.size()) + " robot(s), " +
         std::to_string(d.component_names().size()) + " component(s)";
}

}  // namespace

void write_endpoints_file(const std::string& path,
                          const std::map<std::string, std::vector<std::string>>& endpoints) {
  // written whole, then renamed: a reader never sees half a file
  std::string tmp = path + ".tmp" + std::to_string(getpid());
  {
    std::ofstream out(tmp);
    out << json(endpoints).dump() << "\n";
    if (!out) throw std::runtime_error("--endpoints-file: cannot write '" + tmp + "'");
  }
  std::filesystem::rename(tmp, path);
}

void print_banner(Gateway& g) {
  const Deployment& d = g.deployment();
  auto& sim = g.simulation();
  // the scene as the user would type it: relative to the current directory when inside it
  std::string scene = d.mjcf;
  std::error_code ec;
  auto relative = std::filesystem::relative(d.mjcf, std::filesystem::current_path(), ec);
  if (!ec && !relative.empty() && relative.begin()->string() != "..") scene = relative.string();
  std::cout << "simgate " << SIMGATE_VERSION << ": scene " << scene << ", " << counts(d)
            << ", timestep " << sim.timestep() << " s, "
            << (sim.realtime_factor() == 0
                    ? std::string("as fast as possible")
                    : "real time x" + std::to_string(sim.realtime_factor()).substr(0, 4))
            << "\n";
  // what each robot is made of (a robot of type mjcf: what the model gave it)
  for (const auto& r : d.robots) {
    std::string parts;
    for (const auto& c : r.components)
      parts += (parts.empty() ? "" : ", ") + c.name.substr(r.robot.name.size() + 1);
    std::cout << "robot " << r.robot.name << " (" << r.robot.type << ", body " << r.robot.body
              << "): " << (parts.empty() ? "no components" : parts) << "\n";
  }
  std::optional<std::pair<std::string, std::string>> socket_address;
  std::string socket_name;  // the transport socket_address belongs to
  for (const auto& [name, endpoints] : g.endpoints()) {
    for (const auto& e : endpoints) {
      std::cout << name << ": " << e << "\n";
      auto t = std::find_if(d.transports.begin(), d.transports.end(),
                            [&](const auto& c) { return c.name == name; });
      if (!socket_address && t != d.transports.end() && t->plugin == "socket") {
        socket_address = tcp_host_port(e);
        socket_name = name;
      }
    }
    const auto& served = g.served().at(name);
    std::string list;
    for (const auto& c : served) list += (list.empty() ? "" : ", ") + c;
    std::cout << "  serves: " << (list.empty() ? "(nothing)" : list) << "\n";
    // its allow and deny lists, when it has any: what its clients may call is narrower
    auto t = std::find_if(d.transports.begin(), d.transports.end(),
                          [&](const auto& c) { return c.name == name; });
    if (t != d.transports.end() && !t->access.allows_everything())
      std::cout << "  services: " << t->access.describe() << "\n";
    // the web app a websocket transport serves on its port (docs/web.md), unless turned off
    if (t != d.transports.end() && t->plugin == "websocket" && !endpoints.empty() &&
        endpoints.front().starts_with("ws://") &&
        !(t->options.is_object() && t->options.value("web", true) == false))
      std::cout << "  web app: http" << endpoints.front().substr(2) << "\n";
  }
  if (socket_address) {
    // a first command: drive the robot if a motion_vw is reachable through that socket
    // transport (another transport's component is not), else ask for the robots
    std::string first = "1 simulation list_robots";
    const auto& served = g.served().at(socket_name);
    const auto socket_config = std::find_if(d.transports.begin(), d.transports.end(),
                                            [&](const auto& c) { return c.name == socket_name; });
    for (const auto& r : d.robots)
      for (const auto& c : r.components) {
        bool on_socket = std::find(served.begin(), served.end(), c.name) != served.end() &&
                         socket_config->access.allows(c.name, "set_speed");
        if (c.type == "motion_vw" && on_socket && first.rfind("1 simulation", 0) == 0)
          first = "1 " + c.name + " set_speed [0.5, 0.2]";
      }
    std::cout << "try: telnet " << socket_address->first << " " << socket_address->second
              << "   then type: " << first << "\n";
  }
  std::cout << "Ctrl-C (or `simulation quit`) stops the simulation.\n" << std::flush;
}

namespace {

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
  double factor =
      wall > 0 ? static_cast<double>(now.steps - before.steps) * now.timestep / wall : 0.0;
  double rate = wall > 0 ? static_cast<double>(now.requests - before.requests) / wall : 0.0;
  std::ostringstream line;
  line << std::fixed << "status: sim " << std::setprecision(3) << now.sim_time
       << " s, real-time factor " << std::setprecision(2) << factor << " (target ";
  if (now.target_factor == 0) {
    line << "max";
  } else {
    line << now.target_factor;
  }
  line << "), " << now.clients << (now.clients == 1 ? " client, " : " clients, ")
       << std::setprecision(0) << rate << " requests/s\n";
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

  sim::Simulation& simulation_;                   // read, never changed
  std::chrono::steady_clock::duration interval_;  // between two lines
  std::mutex mutex_;                              // guards stopping_
  std::condition_variable wake_;                  // stop() was called
  bool stopping_ = false;                         // the thread must end
  std::thread thread_;                            // prints the lines
};

}  // namespace

StopOnSignals::StopOnSignals() {
  sigemptyset(&signals_);
  sigaddset(&signals_, SIGINT);
  sigaddset(&signals_, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals_, nullptr);
  signal(SIGPIPE, SIG_IGN);
}

StopOnSignals::~StopOnSignals() {
  finished_ = true;
  if (thread_.joinable()) thread_.join();
}

void StopOnSignals::start(std::function<void()> stop) {
  thread_ = std::thread([this, stop = std::move(stop)] {
    int received = 0;
    timespec poll{0, 100'000'000};
    while (!finished_.load()) {
      siginfo_t info;
      const int sig = sigtimedwait(&signals_, &info, &poll);
      if (sig <= 0) continue;
      if (++received == 1) {
        log::info("simgate: ", sig == SIGINT ? "SIGINT" : "SIGTERM", ", shutting down");
        stop();
      } else {
        static const char msg[] = "simgate: second signal, exiting now\n";
        (void)!write(2, msg, sizeof msg - 1);
        _exit(128 + sig);
      }
    }
  });
}

Deployment load_deployment_args(const RunArgs& args, ConfigErrors& errors) {
  if (args.port && !args.model)
    throw UsageError("--port: only with --model (a config names its transports' ports)");
  Deployment d = args.model ? model_deployment(args, errors) : load_deployment(args.config, errors);
  const std::optional<std::string>& cli_level = args.log_level;
  if (cli_level) {
    apply_log_level(cli_level);
  } else if (d.log_level) {
    apply_log_level(d.log_level);
  }
  return d;
}

std::unique_ptr<Gateway> build_gateway(const RunArgs& args, const Deployment& deployment,
                                       const sim::ComponentRegistry& registry,
                                       GatewayOptions options, ConfigErrors errors) {
  try {
    return std::make_unique<Gateway>(deployment, registry, std::move(options), std::move(errors));
  } catch (const ConfigError& e) {
    throw ConfigError(e.errors(), args.config.empty() ? *args.model : args.config);
  }
}

int cmd_run(const RunArgs& args, bool check_only) {
  GatewayOptions options;
  options.check_only = check_only;
  options.realtime_factor = parse_factor(args.realtime_factor);
  options.plugin_dirs = args.plugin_dirs;
  apply_log_level(args.log_level);
  if (args.record_dir) {
    if (!std::filesystem::is_directory(*args.record_dir))
      throw UsageError("--record-dir: '" + *args.record_dir + "' is not a directory");
    options.record_dir = std::filesystem::canonical(*args.record_dir).string();
  }

  // before any thread starts: the transports' threads inherit the blocked signals
  std::optional<StopOnSignals> signals;
  if (!check_only) signals.emplace();

  // the errors of the file's structure are reported with those the gateway finds
  ConfigErrors errors;
  Deployment deployment = load_deployment_args(args, errors);
  auto registry = sim::builtin_registry();
  std::unique_ptr<Gateway> built =
      build_gateway(args, deployment, registry, options, std::move(errors));
  Gateway& gateway = *built;
  const std::string source =
      args.config.empty() ? *args.model : args.config;  // names it in messages
  if (check_only) {
    for (const auto& w : gateway.warnings()) std::cout << "warning: " << w << "\n";
    std::cout << source << ": OK (" << counts(gateway.deployment()) << ", "
              << deployment.transports.size() << " transport(s)"
              << (gateway.warnings().empty()
                      ? ""
                      : ", " + std::to_string(gateway.warnings().size()) + " warning(s)")
              << ")\n";
    return 0;
  }
  for (const auto& w : gateway.warnings()) log::warning("config '", source, "': ", w);

  // from the first step: before the transports open
  if (args.record) gateway.start_recording(std::filesystem::absolute(*args.record).string());
  gateway.start();
  if (args.endpoints_file) write_endpoints_file(*args.endpoints_file, gateway.endpoints());
  print_banner(gateway);
  std::optional<StatusReporter> status;
  if (args.status_interval) {
    status.emplace(gateway.simulation(), *args.status_interval);
    status->start();
  }

  signals->start([&gateway] { gateway.stop(); });
  int code = 0;
  try {
    gateway.run();
  } catch (const std::exception& e) {
    log::error("simgate: the simulation stopped: ", e.what());
    code = 1;
  }
  // the status and signal threads go first: they must not touch a gateway being torn down
  if (status) status->stop();
  signals.reset();
  gateway.shutdown();
  if (args.endpoints_file) std::filesystem::remove(*args.endpoints_file);
  log::info("simgate: stopped");
  return code;
}

}  // namespace simgate::gateway
