// commands.h — the `simgate` commands behind the command line (cli.cc parses, these run).
//
// run_command.cc: `run` and `check` (the banner, the status line); client_commands.cc:
// `call` and `list` (a client of any transport); stream_commands.cc: `watch` and `publish`
// (data streams); snapshot_command.cc: `snapshot` (a client, or the scene of a config
// rendered in-process). Each returns the process exit code and throws UsageError,
// ConfigError, client::ClientError or a runtime error, which run_cli() turns into messages
// and exit codes. Private to the gateway.
#ifndef SIMGATE_GATEWAY_SRC_COMMANDS_H_
#define SIMGATE_GATEWAY_SRC_COMMANDS_H_

#include <signal.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "simgate/client/client.h"
#include "simgate/gateway/cli.h"
#include "simgate/gateway/deployment.h"
#include "simgate/gateway/gateway.h"

namespace simgate::gateway {

// What `run` and `check` were given.
struct RunArgs {
  std::string config;                          // CONFIG ("" when --model alone)
  std::optional<std::string> model;            // --model FILE.xml
  std::optional<std::string> port;             // --port BASE (--model without CONFIG)
  std::optional<std::string> log_level;        // --log-level
  std::optional<std::string> realtime_factor;  // --realtime-factor
  std::optional<std::string> endpoints_file;   // --endpoints-file
  std::vector<std::string> plugin_dirs;        // --plugin-path, in order
  std::optional<double> status_interval;       // --status [SECONDS], in seconds
  std::optional<std::string> record;           // --record FILE (run)
  std::optional<std::string> record_dir;       // --record-dir DIR (run)
  bool mcp_only = false;  // `mcp --model` without CONFIG: an mcp transport, not socket and jsonrpc
};

// The client options of `call`, `list`, `watch`, `publish` and `snapshot`, as written.
struct ClientArgs {
  std::string transport = "socket";       // --transport
  std::optional<std::string> host;        // --host
  std::optional<std::string> port;        // --port
  std::optional<std::string> domain;      // --domain
  std::optional<std::string> partition;   // --partition
  std::optional<std::string> dds_config;  // --dds-config
  std::optional<std::string> token;       // --token (else the SIMGATE_TOKEN environment variable)
  std::string timeout = "30";             // --timeout, seconds
};

// What `call` was given.
struct CallArgs {
  ClientArgs client;              // how to reach the simulation
  std::string component;          // COMPONENT
  std::string service;            // SERVICE
  std::vector<std::string> args;  // ARGS, as written
};

// What `list` was given.
struct ListArgs {
  ClientArgs client;  // how to reach the simulation
  bool json = false;  // --json: the descriptors as one JSON document
};

// What `watch` was given.
struct WatchArgs {
  ClientArgs client;                    // how to reach the simulation
  std::string component;                // COMPONENT, an output stream
  std::optional<std::string> count;     // --count N: stop after N samples
  std::optional<std::string> duration;  // --duration SECONDS: stop after that (wall clock)
};

// What `publish` was given.
struct PublishArgs {
  ClientArgs client;                 // how to reach the simulation
  std::string component;             // COMPONENT, an input stream
  std::string data;                  // JSON_OBJECT, as written
  std::optional<std::string> count;  // --count N commands (default 1)
  std::optional<std::string> rate;   // --rate HZ between them (default 10)
};

// What `snapshot` was given.
struct SnapshotArgs {
  ClientArgs client;                  // how to reach a running simulation
  RunArgs scene;                      // --config / --model: render it here, no gateway
  std::optional<std::string> camera;  // --camera NAME (an MJCF camera; none: the free view)
  std::string size = "640x480";       // --size WxH
  std::string out;                    // OUT.png
};

// What `mcp` was given.
struct McpArgs {
  RunArgs run;                       // CONFIG / --model: run the simulation here
  std::optional<std::string> url;    // --url: a running simulation's mcp endpoint
  std::optional<std::string> token;  // --token (else SIMGATE_TOKEN)
};

// What `replay` was given.
struct ReplayArgs {
  std::string file;                            // FILE, a recording
  bool verify = false;                         // --verify: exit 1 at the first step that differs
  bool json = false;                           // --json: the report as one JSON document
  std::optional<std::string> config;           // --config CONFIG instead of the recorded deployment
  std::vector<std::string> plugin_dirs;        // --plugin-path, in order
  std::optional<std::string> log_level;        // --log-level
  bool serve = false;                          // --serve: through the deployment's transports
  std::optional<std::string> realtime_factor;  // --realtime-factor (with --serve)
  std::optional<std::string> endpoints_file;   // --endpoints-file (with --serve)
};

// `run CONFIG` (check_only false) or `check CONFIG`.
int cmd_run(const RunArgs& args, bool check_only);
// `call COMPONENT SERVICE ARGS...`: prints the result, SUCCESS, or the failure on stderr.
int cmd_call(const CallArgs& args);
// `list`: every service a running simulation offers.
int cmd_list(const ListArgs& args);
// `watch COMPONENT`: its stream's samples, one JSON line each (stream_commands.cc).
int cmd_watch(const WatchArgs& args);
// `publish COMPONENT JSON_OBJECT`: commands to its input stream (stream_commands.cc).
int cmd_publish(const PublishArgs& args);
// `snapshot OUT.png`: a picture of the scene (simulation get_snapshot), written as a PNG.
int cmd_snapshot(const SnapshotArgs& args);
// `mcp`: an MCP server on standard input and output, bridged to an mcp transport's HTTP
// endpoint (a running simulation's, or this process's: mcp_command.cc).
int cmd_mcp(const McpArgs& args);
// `replay FILE`: re-runs a recording (replay_command.cc); with --verify, exit 1 at a
// difference, 2 for a file that is not a recording or cannot be replayed here.
int cmd_replay(const ReplayArgs& args);

// Where the client options point: the transport, make_client()'s options ({host, port} or
// {domain, partition, config}; and the token of --token or SIMGATE_TOKEN, which
// make_client() presents) and --timeout. UsageError when they are wrong, and for a dds
// --partition pattern unless `allow_partition_pattern` (`list`, `call`: every simgate it
// matches).
struct ClientTarget {
  std::string transport;              // socket, jsonrpc, websocket or dds
  json options;                       // for client::make_client()
  std::chrono::milliseconds timeout;  // --timeout
};
ClientTarget client_target(const ClientArgs& args, bool allow_partition_pattern = false);
// A client of the transport the options name (UsageError when they are wrong); `timeout`
// gets --timeout.
std::unique_ptr<client::Client> connect_client(const ClientArgs& args,
                                               std::chrono::milliseconds& timeout);
// The deployment of `run` / `check` (CONFIG, or --model's), its log level applied unless
// the command line set one; the errors of its structure are recorded in `errors`, what is
// valid returned (parse_deployment), for build_gateway to report them with its own.
Deployment load_deployment_args(const RunArgs& args, ConfigErrors& errors);
// The gateway of that deployment (Gateway, given the structure's errors): throws one
// ConfigError naming CONFIG (or the model) with every error of every section.
std::unique_ptr<Gateway> build_gateway(const RunArgs& args, const Deployment& deployment,
                                       const sim::ComponentRegistry& registry,
                                       GatewayOptions options, ConfigErrors errors);

// --endpoints-file: `endpoints` as {"transport": ["tcp://host:port", ...]} at `path`, written
// whole, then renamed (a reader never sees half a file).
void write_endpoints_file(const std::string& path,
                          const std::map<std::string, std::vector<std::string>>& endpoints);

// What a serving command (run, replay --serve) prints once its transports listen: the scene,
// the robots, each transport's endpoints and how to try it.
void print_banner(Gateway& gateway);

// SIGINT and SIGTERM for a command that serves until stopped (run, replay --serve): blocked
// from construction on (construct it before any thread starts: they inherit the mask), SIGPIPE
// ignored (a closed client must not kill the server); after start(stop), a thread of its own
// runs `stop` on the first signal, and a second one exits at once. Destruction ends the thread.
class StopOnSignals {
 public:
  StopOnSignals();
  ~StopOnSignals();
  StopOnSignals(const StopOnSignals&) = delete;
  StopOnSignals& operator=(const StopOnSignals&) = delete;
  void start(std::function<void()> stop);

 private:
  sigset_t signals_;
  std::atomic<bool> finished_{false};
  std::thread thread_;
};

// ---- parsing helpers shared by the commands (cli.cc); each throws UsageError

// Applies --log-level if given.
void apply_log_level(const std::optional<std::string>& level);
// --realtime-factor: a number >= 0 or "max" (0).
std::optional<double> parse_factor(const std::optional<std::string>& text);
// A number of seconds within [min, max]; `hint` is appended to the error.
double parse_seconds(const std::string& option, const std::string& text, double min, double max,
                     const std::string& hint = "");
// An integer within [min, max].
int parse_int(const std::string& option, const std::string& text, int min, int max);

}  // namespace simgate::gateway

#endif  // SIMGATE_GATEWAY_SRC_COMMANDS_H_
