// `simgate replay FILE` (see commands.h, recorder/replay.h).
#include <atomic>
#include <filesystem>
#include <iostream>

#include "commands.h"
#include "simgate/core/errors.h"
#include "simgate/core/log.h"
#include "simgate/mcap/reader.h"
#include "simgate/recorder/replay.h"
#include "simgate/sim/registry.h"

namespace simgate::gateway {

namespace {

// The deployment the recording carries, or --config's.
Deployment replay_deployment(const ReplayArgs& args, const recorder::Recording& recording,
                             ConfigErrors& errors) {
  if (args.config) return load_deployment(*args.config, errors);
  const json& d = recording.deployment;
  if (!d.is_object() || !d.contains("document"))
    throw UsageError(args.file +
                     ": the recording carries no deployment: give the one it ran with (--config)");
  return parse_deployment(d["document"], d.value("base_dir", "."), d.value("file", ""), errors);
}

void print_report(const recorder::ReplayReport& report, const recorder::Recording& recording,
                  bool verify) {
  std::cout << recording.path << ": replayed " << report.steps << " steps, "
            << report.inputs_applied << " inputs (" << report.inputs_skipped
            << " loop controls skipped) in " << report.wall_seconds << " s; "
            << report.steps_compared << " steps compared";
  if (!report.mismatch) {
    std::cout << ": " << (verify ? "every state identical, bit for bit" : "no difference") << "\n";
  } else {
    const auto& m = *report.mismatch;
    std::cout << "\nfirst difference: step " << m.step << " (sim time " << m.sim_time << " s): ";
    for (std::size_t i = 0; i < m.quantities.size(); ++i)
      std::cout << (i ? ", " : "") << m.quantities[i];
    std::cout << " differ\n";
    if (m.inputs.empty()) {
      std::cout << "  no input was taken just before it (an input earlier, or something outside "
                   "the recording, changed the run)\n";
    } else {
      std::cout << "  inputs taken just before it:\n";
      for (const json& in : m.inputs) std::cout << "    " << in.dump() << "\n";
    }
  }
  if (report.outcomes_differing > 0)
    std::cout << report.outcomes_differing << " request(s) ended otherwise than recorded\n";
  if (!recording.complete)
    std::cout << "note: the recording is cut (" << recording.truncation
              << "): replayed up to its last complete chunk\n";
}

}  // namespace

int cmd_replay(const ReplayArgs& args) {
  apply_log_level(args.log_level);
  if (args.serve && args.verify)
    throw UsageError(
        "--serve and --verify: one or the other (a served run may be changed by its "
        "clients)");
  if (args.realtime_factor && !args.serve)
    throw UsageError("--realtime-factor: only with --serve (a replay is as fast as possible)");
  if (args.endpoints_file && !args.serve)
    throw UsageError("--endpoints-file: only with --serve (nothing listens otherwise)");
  // before any thread starts (served: the transports' threads inherit the blocked signals)
  std::optional<StopOnSignals> signals;
  if (args.serve) signals.emplace();
  recorder::Recording recording;
  try {
    recording = recorder::Recording::read(args.file);
  } catch (const mcap::ReadError& e) {
    std::cerr << "simgate: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "simgate: " << e.what() << "\n";
    return 2;
  }
  ConfigErrors errors;
  const Deployment deployment = replay_deployment(args, recording, errors);
  GatewayOptions options;
  options.check_only = !args.serve;  // nothing listens, unless served
  options.plugin_dirs = args.plugin_dirs;
  options.realtime_factor = args.serve ? parse_factor(args.realtime_factor) : 0;
  // the replayer, built on the simulation before the transports take its services
  std::optional<recorder::Replayer> replayer;
  std::string refusal;
  options.on_simulation_built = [&](sim::Simulation& simulation,
                                    sim::SupervisionServices& supervision) {
    try {
      replayer.emplace(simulation, recording);
    } catch (const std::exception& e) {
      refusal = e.what();
      return;
    }
    if (args.serve) replayer->add_services(supervision);
  };
  const sim::ComponentRegistry registry = sim::builtin_registry();
  std::unique_ptr<Gateway> gateway;
  try {
    gateway = std::make_unique<Gateway>(deployment, registry, options, std::move(errors));
  } catch (const ConfigError& e) {
    throw ConfigError(e.errors(), args.config.value_or(args.file + " (its deployment)"));
  }
  if (!replayer) {
    std::cerr << "simgate: cannot replay: " << refusal << "\n";
    return 2;
  }
  recorder::ReplayOptions replay_options;
  replay_options.stop_at_mismatch = args.verify;
  std::atomic<bool> stop{false};
  if (args.serve) {
    gateway->start();
    if (args.endpoints_file) write_endpoints_file(*args.endpoints_file, gateway->endpoints());
    print_banner(*gateway);
    replay_options.serve = true;
    replay_options.stop = &stop;
    signals->start([&stop, &gateway] {
      stop = true;
      gateway->simulation().gate()->signal();
    });
  }
  const recorder::ReplayReport report = replayer->run(replay_options);
  if (args.serve) {
    signals.reset();
    gateway->shutdown();
    if (args.endpoints_file) std::filesystem::remove(*args.endpoints_file);
  }
  if (args.json) {
    json out = report.to_json();
    out["file"] = recording.path;
    out["complete"] = recording.complete;
    std::cout << out.dump() << "\n";
  } else {
    print_report(report, recording, args.verify);
  }
  return args.verify && report.mismatch ? 1 : 0;
}

}  // namespace simgate::gateway
