// The `simgate` command line: CLI11 parses it, commands.h runs it (see cli.h).
#include "simgate/gateway/cli.h"

#include <CLI/CLI.hpp>
#include <mujoco/mujoco.h>
#include <algorithm>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "commands.h"
#include "simgate/client/client.h"
#include "simgate/core/errors.h"
#include "simgate/core/log.h"
#include "simgate/core/suggest.h"

namespace simgate::gateway {

namespace {

constexpr const char* k_description =
    "simgate: a MuJoCo simulation whose components serve MORSE-style services";

constexpr const char* k_footer = R"(Synopsis:
  simgate run CONFIG [--status [SECONDS]] [--log-level L] [--realtime-factor F|max]
                     [--endpoints-file PATH] [--plugin-path DIR]...
  simgate run --model FILE.xml [CONFIG] [options as above] [--record FILE] [--record-dir DIR]
  simgate replay FILE [--verify | --serve [--realtime-factor F|max] [--endpoints-file PATH]]
                [--json] [--config CONFIG] [--plugin-path DIR]...
  simgate check CONFIG | --model FILE.xml [CONFIG] [--log-level L] [--plugin-path DIR]...
  simgate call [CLIENT OPTIONS] COMPONENT SERVICE [ARGS...]
  simgate list [CLIENT OPTIONS] [--json]    (dds: --partition 'PATTERN' lists several simgates)
  simgate watch [CLIENT OPTIONS] COMPONENT [--count N] [--duration SECONDS]
  simgate publish [CLIENT OPTIONS] COMPONENT JSON_OBJECT [--count N] [--rate HZ]
  simgate snapshot [CLIENT OPTIONS] [--camera NAME] [--size WxH] OUT.png
  simgate snapshot --config CONFIG | --model FILE.xml [--camera NAME] [--size WxH] OUT.png
  simgate mcp --url http://HOST:PORT/mcp [--token TOKEN]
  simgate mcp CONFIG | --model FILE.xml [CONFIG] [--log-level L] [--plugin-path DIR]...
  simgate help [COMMAND]
  CLIENT OPTIONS: --transport socket|jsonrpc|websocket|dds, --timeout S, then --host H --port P
                  [--token TOKEN] (socket, jsonrpc, websocket) or --domain N --partition P
                  --dds-config XML (dds); without --token, the SIMGATE_TOKEN environment variable

`simgate COMMAND --help` shows a command's options (docs/cli.md: the reference).)";

constexpr const char* k_exit_codes =
    "Exit codes: 0 success, 1 failed call or runtime error, 2 bad usage or invalid configuration.";

constexpr const char* k_run_footer =
    R"(--status prints one line every SECONDS (5 without a value), measured over that time:
  status: sim 12.345 s, real-time factor 1.00 (target 1.00), 3 clients, 812 requests/s
Ctrl-C (SIGINT) or SIGTERM stops the simulation cleanly; a second one exits at once.)";

constexpr const char* k_call_footer =
    R"(ARGS: each is JSON (5, -1, "text", [1,2], {"a":1}) or a bare word (a string), sent as
positional params [..]; or all of them name=value (name an identifier, value JSON or a bare
word), sent as named params {..}: `simgate call robot.motion set_speed v=0.5 w=0.2`.
Named and positional ARGS cannot be mixed; a string containing '=' is written JSON-quoted:
'"a=b"'. Options come before COMPONENT: everything after it is an ARG, even -1 or --x
(a "--" right after SERVICE is skipped).
Prints the result as JSON, or SUCCESS for a service that returns nothing (exit 0); a
FAILED or PREEMPTED call prints its reason on stderr (exit 1).
dds: a --partition pattern ('*', 'host*') makes the call on every simgate it matches (by
convention one per host), all at once, and prints a JSON line each: {"partition", "server",
"status": "SUCCESS", "result"} or {..., "status", "message"}; exit 0 when all succeeded:
  simgate call --transport dds --partition 'host*' simulation step_many n=10)";

constexpr const char* k_list_footer =
    R"(dds: a --partition pattern (* any characters, ? one: '*', 'lab-*') lists every simgate of
the domain it matches (by convention one per host, each in a partition of its own):
  partition hostA: worlds w0, w1; server 0110d23c9f2e4c8a5b3e7d1f000001c1
    robot.motion set_speed(v, w) — ...
then its components' services and streams, indented; --json: [{"partition", "server",
"worlds", "services"}, ...]. It reads the DDS catalog, then waits 1 s for more simgates.)";

constexpr const char* k_watch_footer =
    R"(Prints each sample of COMPONENT's output stream (a sensor: robot.pose) as one JSON line,
flushed at once (`| head -3`, `| jq` work), until --count samples, --duration seconds, Ctrl-C
or a closed stdout; exit 0. socket: reads the stream port `simulation get_stream_port`
names, on --host; jsonrpc, websocket: rpc.subscribe. --timeout bounds connecting and the
answers, not the wait for samples (a paused simulation sends its first sample only).
`simgate list` shows the streams of a transport; dds: not here (its streams are topics).)";

constexpr const char* k_publish_footer =
    R"(Sends JSON_OBJECT as a command to COMPONENT's input stream (an actuator): once, or --count
times at --rate (default 10 per second). `simgate publish robot.motion '{"v": 0.5, "w": 0}'`
jsonrpc, websocket: rpc.publish, a refused command is an error (exit 1); socket: lines on
the stream port, MORSE's way: nothing is answered, a refusal is only counted by the server
(`simgate call simulation get_stream_statistics`: refused, last_refusal).)";

constexpr const char* k_replay_footer =
    R"(Builds the recorded deployment here (nothing listens), puts back the state the recording
began from, then takes the recorded requests, cancels and commands at their steps, as fast as
possible, comparing every step's state with the recording's. Prints the steps and inputs
replayed; at the first step that differs, its number, the quantities that differ (qpos,
qvel, ctrl...) and the inputs taken just before it. Exit 0: the same run (with --verify: bit
for bit); 1: a step differs (--verify); 2: not a recording, cut before its initial state, or
not replayable here (another MuJoCo, another model: both named).
--serve plays it through the deployment's transports instead, paced (a live run's clients
watch it: Foxglove, the web app, pymorse), then serves its last state until Ctrl-C.)";

constexpr const char* k_mcp_footer =
    R"(Each line of standard input is one JSON-RPC message (MCP's stdio transport), posted to the
mcp transport; each answer, and each progress notification of a long call, is one line of
standard output. The log goes to standard error. With CONFIG (it needs an mcp transport) or
--model (served by an mcp transport on a port the kernel picks) the simulation runs in this
process and stops when standard input ends. docs/transports/mcp.md has an agent's config.)";

constexpr const char* k_snapshot_footer =
    R"(Without --config or --model it asks the running simulation the client options reach
(`simulation get_snapshot`); with either, it builds that deployment here (nothing listens)
and pictures its initial state. Without --camera the view frames the whole scene.
Prints what it wrote: `out.png: 640x480 PNG, 123456 bytes, camera free, sim time 0 s`.)";

constexpr double k_default_status_interval = 5.0;  // seconds, `--status` without a value

std::string version_text() {
  return std::string("simgate ") + SIMGATE_VERSION + " (MuJoCo " + mj_versionString() + ")";
}

}  // namespace

void apply_log_level(const std::optional<std::string>& level) {
  if (!level) return;
  log::Level l;
  if (!log::parse_level(*level, l))
    throw UsageError("--log-level: expected trace, debug, info, warning, error or off, found '" +
                     *level + "'");
  log::set_level(l);
}

std::optional<double> parse_factor(const std::optional<std::string>& text) {
  if (!text) return std::nullopt;
  if (*text == "max") return 0.0;
  try {
    std::size_t used = 0;
    double f = std::stod(*text, &used);
    if (used == text->size() && f >= 0) return f;
  } catch (const std::exception&) {}
  throw UsageError("--realtime-factor: expected a number >= 0 or 'max', found '" + *text + "'");
}

double parse_seconds(const std::string& option, const std::string& text, double min, double max,
                     const std::string& hint) {
  try {
    std::size_t used = 0;
    double seconds = std::stod(text, &used);
    if (used == text.size() && seconds >= min && seconds <= max) return seconds;
  } catch (const std::exception&) {}
  std::ostringstream range;
  range << min << " to " << max;
  throw UsageError(option + ": expected a number of seconds from " + range.str() + ", found '" +
                   text + "'" + hint);
}

int parse_int(const std::string& option, const std::string& text, int min, int max) {
  try {
    std::size_t used = 0;
    int value = std::stoi(text, &used);
    if (used == text.size() && value >= min && value <= max) return value;
  } catch (const std::exception&) {}
  throw UsageError(option + ": expected an integer from " + std::to_string(min) + " to " +
                   std::to_string(max) + ", found '" + text + "'");
}

namespace {

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
    status_ =
        run_->add_option(
                "--status", status_text_,
                "print sim time, real-time factor, clients, requests/s every SECONDS (default 5)")
            ->expected(0, 1)
            ->multi_option_policy(CLI::MultiOptionPolicy::TakeLast)
            ->option_text("[SECONDS]");
    run_->add_option("--record", run_args_.record,
                     "record the run from its first step to FILE (MCAP; docs/recording.md)")
        ->type_name("FILE");
    run_->add_option("--record-dir", run_args_.record_dir,
                     "let clients record (simulation start_recording NAME) into DIR")
        ->type_name("DIR");
    run_->footer(std::string(k_run_footer) + "\n" + k_exit_codes);

    replay_ = add_command(
        "replay", "re-run a recording (simgate run --record) and compare every step's state");
    replay_->add_option("FILE", replay_args_.file, "the recording (.mcap)")->required();
    replay_->add_flag("--verify", replay_args_.verify,
                      "exit 1 at the first step whose state differs from the recording's");
    replay_->add_flag("--json", replay_args_.json, "print the report as one JSON document");
    replay_
        ->add_option("--config", replay_args_.config,
                     "build this deployment instead of the one the recording carries")
        ->type_name("CONFIG");
    replay_
        ->add_option("--plugin-path", replay_args_.plugin_dirs,
                     "search component libraries in DIR too (repeatable)")
        ->allow_extra_args(false)
        ->option_text("DIR");
    replay_->add_flag("--serve", replay_args_.serve,
                      "play it through the deployment's transports, paced, until Ctrl-C");
    replay_
        ->add_option("--realtime-factor", replay_args_.realtime_factor,
                     "with --serve: 1 = real time (the deployment's by default), max = no pacing")
        ->type_name("F|max");
    replay_
        ->add_option(
            "--endpoints-file", replay_args_.endpoints_file,
            "with --serve: write {\"transport\": [\"tcp://host:port\", ...]} there once listening")
        ->type_name("PATH");
    replay_
        ->add_option("--log-level", replay_args_.log_level,
                     "trace, debug, info, warning, error, off")
        ->type_name("L");
    replay_->footer(std::string(k_replay_footer) + "\n" + k_exit_codes);

    check_ = add_command(
        "check", "validate CONFIG (scene, components, transport plugins and options) and exit");
    add_config_options(check_, check_args_);
    check_->footer(k_exit_codes);

    call_ = add_command("call", "call a service of a running simulation and print its result");
    add_client_options(call_, call_args_.client);
    call_
        ->add_option("COMPONENT", call_args_.component,
                     "the component: robot.motion, simulation, ...")
        ->required();
    call_->add_option("SERVICE", call_args_.service, "its service: set_speed, list_robots, ...")
        ->required();
    call_->add_option("ARGS", call_args_.args,
                      "the parameters: JSON values or bare words, or all name=value (below)");
    // options only before COMPONENT: ARGS may look like options (-1, --x)
    call_->positionals_at_end();
    call_->footer(std::string(k_call_footer) + "\n" + k_exit_codes);

    list_ =
        add_command("list", "list the services a running simulation offers, with their parameters");
    add_client_options(list_, list_args_.client);
    list_->add_flag("--json", list_args_.json, "print the service descriptors as one JSON array");
    list_->footer(std::string(k_list_footer) + "\n" + k_exit_codes);

    watch_ =
        add_command("watch", "print a component's stream samples (a sensor), one JSON line each");
    add_client_options(watch_, watch_args_.client);
    watch_
        ->add_option("COMPONENT", watch_args_.component,
                     "the component with an output stream: robot.pose, ...")
        ->required();
    watch_->add_option("--count", watch_args_.count, "stop after N samples")->type_name("N");
    watch_->add_option("--duration", watch_args_.duration, "stop after SECONDS (wall clock)")
        ->type_name("SECONDS");
    watch_->footer(std::string(k_watch_footer) + "\n" + k_exit_codes);

    publish_ = add_command(
        "publish", "send a command (a JSON object) to a component's input stream (an actuator)");
    add_client_options(publish_, publish_args_.client);
    publish_
        ->add_option("COMPONENT", publish_args_.component,
                     "the component with an input stream: robot.motion, ...")
        ->required();
    publish_->add_option("JSON_OBJECT", publish_args_.data, "the command: {\"v\": 0.5, \"w\": 0}")
        ->required();
    publish_->add_option("--count", publish_args_.count, "send it N times (default 1)")
        ->type_name("N");
    publish_
        ->add_option("--rate", publish_args_.rate, "commands per second with --count (default 10)")
        ->type_name("HZ");
    publish_->footer(std::string(k_publish_footer) + "\n" + k_exit_codes);

    snapshot_ = add_command(
        "snapshot", "write a picture of the scene (PNG), from a running simulation or a config");
    add_client_options(snapshot_, snapshot_args_.client);
    snapshot_
        ->add_option("--camera", snapshot_args_.camera,
                     "an MJCF camera of the scene (default: a free view of it all)")
        ->type_name("NAME");
    snapshot_->add_option("--size", snapshot_args_.size, "image size in pixels (default 640x480)")
        ->type_name("WxH");
    snapshot_
        ->add_option(
            "--config", snapshot_args_.scene.config,
            "no running simulation: build this deployment here and picture its initial state")
        ->type_name("CONFIG");
    snapshot_
        ->add_option("--model", snapshot_args_.scene.model,
                     "no running simulation: picture this MJCF model")
        ->type_name("FILE.xml");
    snapshot_
        ->add_option("--plugin-path", snapshot_args_.scene.plugin_dirs,
                     "with --config: search transport plugins in DIR too (repeatable)")
        ->allow_extra_args(false)
        ->option_text("DIR");
    snapshot_->add_option("OUT", snapshot_args_.out, "the PNG file to write")->required();
    snapshot_->footer(std::string(k_snapshot_footer) + "\n" + k_exit_codes);

    mcp_ = add_command("mcp",
                       "an MCP server on standard input and output, for AI agents that launch "
                       "one (bridged to an mcp transport)");
    mcp_->add_option("--url", mcp_args_.url,
                     "a running simulation's mcp endpoint (http://127.0.0.1:8808/mcp)")
        ->type_name("URL");
    mcp_->add_option("--token", mcp_args_.token,
                     "the token its auth wants (else the SIMGATE_TOKEN environment variable)")
        ->type_name("TOKEN");
    add_config_options(mcp_, mcp_args_.run);
    mcp_->footer(std::string(k_mcp_footer) + "\n" + k_exit_codes);
  }

  // The top-level help, or one command's.
  std::string help(const std::string& command = "") const {
    if (command.empty()) return app_.help();
    return app_.get_subcommand(command)->help("simgate");
  }
  const std::vector<std::string>& commands() const { return names_; }

  // Parses argv and runs the command; CLI11's errors propagate.
  int run(int argc, char** argv) {
    const int parsed =
        argc >= 2 && std::string_view(argv[1]) == "call" ? call_args_end(argc, argv) : argc;
    app_.parse(parsed, argv);
    if (call_->parsed()) call_args_.args.assign(argv + parsed, argv + argc);
    if (run_->parsed()) return cmd_run(with_scene(finish_run(run_args_)), false);
    if (check_->parsed()) return cmd_run(with_scene(check_args_), true);
    if (call_->parsed()) return cmd_call(call_args_);
    if (list_->parsed()) return cmd_list(list_args_);
    if (watch_->parsed()) return cmd_watch(watch_args_);
    if (publish_->parsed()) return cmd_publish(publish_args_);
    if (snapshot_->parsed()) return cmd_snapshot(snapshot_args_);
    if (replay_->parsed()) return cmd_replay(replay_args_);
    if (mcp_->parsed()) return cmd_mcp(mcp_args_);
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
  // Where `simgate call`'s ARGS begin: after its options and COMPONENT SERVICE. They are
  // taken as typed, past CLI11: it reads an option value written [a,b] as the two values a
  // and b, which would turn the JSON array ARG [1,2] into the two ARGS 1 and 2. Returns argc
  // when SERVICE is missing: CLI11 then parses it all, and reports what is wrong.
  int call_args_end(int argc, char** argv) const {
    int i = 2;
    while (i < argc && argv[i][0] == '-' && argv[i][1] != '\0') {
      const std::string token = argv[i];
      if (token == "--") {
        ++i;
        break;
      }
      const CLI::Option* option = call_->get_option_no_throw(token.substr(0, token.find('=')));
      const bool takes_value =
          option && option->get_expected_min() > 0 && token.find('=') == std::string::npos;
      i += takes_value ? 2 : 1;
    }
    return i + 2 <= argc ? i + 2 : argc;  // COMPONENT SERVICE
  }

  CLI::App* add_command(const std::string& name, const std::string& description) {
    names_.push_back(name);
    CLI::App* sub = app_.add_subcommand(name, description);
    sub->set_version_flag("--version", version_text());
    sub->group("Commands");
    return sub;
  }

  static void add_config_options(CLI::App* command, RunArgs& args) {
    command->add_option("CONFIG", args.config,
                        "the deployment file (JSON, docs/configuration.md); with --model: its "
                        "transports and options");
    command
        ->add_option("--model", args.model,
                     "serve every robot of this MJCF model with its generic components (armature, "
                     "armature_pose, "
                     "actuators, sensors); the transports are CONFIG's, or socket 4000 and jsonrpc "
                     "4001 on 127.0.0.1")
        ->type_name("FILE.xml");
    command
        ->add_option(
            "--port", args.port,
            "with --model and no CONFIG: the socket transport listens on BASE, jsonrpc on BASE+1 "
            "(default 4000; 0: ports the kernel picks)")
        ->type_name("BASE");
    command
        ->add_option("--log-level", args.log_level,
                     "trace, debug, info, warning, error or off (overrides the config)")
        ->type_name("L");
    command
        ->add_option("--plugin-path", args.plugin_dirs,
                     "search transport plugins in DIR (after SIMGATE_PLUGIN_PATH; repeatable)")
        ->allow_extra_args(false)
        ->option_text("DIR");
  }

  static void add_client_options(CLI::App* command, ClientArgs& args) {
    command
        ->add_option("--transport", args.transport, "socket (default), jsonrpc, websocket or dds")
        ->type_name("T");
    command
        ->add_option("--host", args.host,
                     "socket/jsonrpc/websocket: the server's address (default 127.0.0.1)")
        ->type_name("H");
    command
        ->add_option("--port", args.port,
                     "socket/jsonrpc/websocket: its port (default 4000 socket, 4001 jsonrpc, 8090 "
                     "websocket)")
        ->type_name("P");
    command->add_option("--domain", args.domain, "dds: the simulation's DDS domain (default 0)")
        ->type_name("N");
    command
        ->add_option(
            "--partition", args.partition,
            "dds: its partition (default simgate); list, call: or a pattern (* ?) of several")
        ->type_name("P");
    command
        ->add_option(
            "--dds-config", args.dds_config,
            "dds: Cyclone XML or file:// URI (default: loopback only; env = CYCLONEDDS_URI)")
        ->type_name("XML");
    command
        ->add_option("--token", args.token,
                     "socket/jsonrpc/websocket: the token the transport's \"auth\" option requires "
                     "(default: "
                     "the SIMGATE_TOKEN environment variable, which `ps` does not show)")
        ->type_name("TOKEN");
    command
        ->add_option("--timeout", args.timeout,
                     "seconds to wait for the simulation and its answer (default 30)")
        ->type_name("S");
  }

  // CONFIG or --model (or both): something to simulate
  static RunArgs& with_scene(RunArgs& args) {
    if (args.config.empty() && !args.model)
      throw UsageError("expected CONFIG (a deployment file), or --model FILE.xml (any MJCF model)");
    return args;
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
        parse_seconds("--status", text, 0.1, 86400,
                      number ? "" : " (write CONFIG before a --status without SECONDS)");
    return args;
  }

  CLI::App app_;                    // `simgate`
  std::vector<std::string> names_;  // the commands, in order
  CLI::App *run_, *check_, *call_, *list_, *watch_, *publish_, *snapshot_, *replay_,
      *mcp_;                              // commands
  CLI::Option* status_;                   // run --status
  std::vector<std::string> status_text_;  // its value, if any
  RunArgs run_args_, check_args_;         // parsed values of each command
  CallArgs call_args_;
  ListArgs list_args_;
  WatchArgs watch_args_;
  PublishArgs publish_args_;
  SnapshotArgs snapshot_args_;
  McpArgs mcp_args_;
  ReplayArgs replay_args_;
};

}  // namespace

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
  } catch (const client::AuthError& e) {
    std::cerr << "simgate: " << e.what()
              << "\n(a transport whose \"auth\" option requires a token takes it from "
                 "--token TOKEN or the SIMGATE_TOKEN environment variable; docs/cli.md)\n";
    return 1;
  } catch (const client::ClientError& e) {
    std::cerr << "simgate: " << e.what() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "simgate: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace simgate::gateway
