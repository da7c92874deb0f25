// example_common.h — what the standalone examples share: command-line options (CLI11) and a
// clean stop on SIGINT/SIGTERM. Not part of the library; kept tiny on purpose.
#ifndef SIMGATE_DOCS_EXAMPLES_EXAMPLE_COMMON_H_
#define SIMGATE_DOCS_EXAMPLES_EXAMPLE_COMMON_H_

#include <atomic>
#include <csignal>
#include <iostream>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "simgate/core/status.h"

namespace simgate::examples {

// Set by SIGINT/SIGTERM; the process() loop ends when it is true.
inline std::atomic<bool> g_stop{false};

inline void install_stop_handlers() {
  auto handler = [](int) { g_stop.store(true); };
  std::signal(SIGINT, handler);
  std::signal(SIGTERM, handler);
}

// Parses --host H, --port N (0 = any free port) and --success-word SUCCESS|OK into the
// socket transport's options (`options`). Returns nullopt to go on, or the exit code main
// returns: 0 after --help, 2 after a usage error (printed on stderr).
inline std::optional<int> parse_socket_options(int argc, char** argv, const std::string& program,
                                               const std::string& description, json& options) {
  CLI::App app{description, program};
  std::string host = "127.0.0.1";
  int port = 4000;
  std::string success_word = "SUCCESS";
  app.add_option("--host", host, "address to listen on")->capture_default_str();
  app.add_option("--port", port, "port to listen on (0 = any free port)")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
  app.add_option("--success-word", success_word,
                 "the status word of a success: SUCCESS or OK (MORSE's docs)")
      ->capture_default_str();  // the transport validates it
  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << program << ": " << e.what() << " (" << program << " --help shows the options)\n";
    return 2;
  }
  options = {{"host", host}, {"port", port}, {"success_word", success_word}};
  return std::nullopt;
}

}  // namespace simgate::examples

#endif  // SIMGATE_DOCS_EXAMPLES_EXAMPLE_COMMON_H_
