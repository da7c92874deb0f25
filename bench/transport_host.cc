// transport_host.cc — a standalone simgate server for benchmarks: one transport plugin
// and one trivial service, with no simulation.
//
// Loads the transport plugin named by --transport (socket, jsonrpc, websocket, foxglove, dds) with
// load_transport_plugin(name)->create(options), registers the seed's example service
// `test_component add(a, b)` with register_service, and calls process(wait) in a loop on
// the main thread, exactly as the seed's `while True: req_manager.process()`. Whatever it
// measures is therefore transport + core: framing, parsing, hand-off to the process()
// thread, argument conversion, the call, the reply.
//
// Usage: simgate_bench_host --transport NAME [--options JSON] [--max-seconds 600]
// Prints {"transport": NAME, "endpoints": [...]} on stdout once serving; exits on
// SIGTERM/SIGINT or after --max-seconds.
#include <atomic>
#include <cstdint>
#include <csignal>
#include <iostream>
#include <string>

#include "bench_util.h"
#include "simgate/core/plugin_loader.h"
#include "simgate/core/request_manager.h"

namespace {

std::atomic<bool> g_stop{false};  // set by the signal handler

extern "C" void on_signal(int) { g_stop.store(true); }

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "A transport plugin serving `test_component add(a, b)` from a process() loop, no simulation.",
      "simgate_bench_host"};
  std::string transport, options_text = "{}";
  double max_seconds = 600;
  app.add_option("--transport", transport, "the plugin: socket, jsonrpc, dds")->required();
  app.add_option("--options", options_text, "its options (JSON object)")->capture_default_str();
  app.add_option("--max-seconds", max_seconds, "exit after this long (a bounded run)")
      ->capture_default_str();
  if (auto code = simgate::bench::parse_command_line(app, argc, argv)) return *code;
  try {
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);

    // the plugin, as the gateway would load it
    auto plugin = simgate::load_transport_plugin(transport);
    auto manager =
        plugin->create(simgate::json::parse(options_text), "transports." + transport + ".options");
    manager
        ->register_service("test_component", [](std::int64_t a, std::int64_t b) { return a + b; },
                           "add", {"a", "b"})
        .doc("a + b (the seed's example)");
    manager->start();

    std::cout << simgate::json{{"transport", transport}, {"endpoints", manager->endpoints()}}.dump()
              << std::endl;

    // the seed's loop, bounded in time
    auto deadline =
        simgate::bench::Clock::now() + std::chrono::duration_cast<simgate::bench::Clock::duration>(
                                           std::chrono::duration<double>(max_seconds));
    while (!g_stop.load() && simgate::bench::Clock::now() < deadline)
      manager->process(std::chrono::milliseconds(50));

    manager->abandon_pending("the benchmark host is stopping");
    manager->stop();
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "simgate_bench_host: " << e.what() << "\n";
    return 1;
  }
}
