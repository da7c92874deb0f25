// example_common.h — what the standalone examples share: command-line options and a
// clean stop on SIGINT/SIGTERM. Not part of the library; kept tiny on purpose.
#ifndef SIMGATE_DOCS_EXAMPLES_EXAMPLE_COMMON_H_
#define SIMGATE_DOCS_EXAMPLES_EXAMPLE_COMMON_H_

#include <atomic>
#include <csignal>
#include <cstdlib>
#include <iostream>
#include <stdexcept>
#include <string>

#include "simgate/core/status.h"

namespace simgate::examples {

// Set by SIGINT/SIGTERM; the process() loop ends when it is true.
inline std::atomic<bool> g_stop{false};

inline void install_stop_handlers() {
  auto handler = [](int) { g_stop.store(true); };
  std::signal(SIGINT, handler);
  std::signal(SIGTERM, handler);
}

// --host H, --port N (0 = any free port), --success-word SUCCESS|OK -> the socket
// transport's options. Throws std::invalid_argument with a usage message.
inline json socket_options(int argc, char** argv, const char* program) {
  json options{{"port", 4000}};
  const std::string usage = std::string("usage: ") + program +
                            " [--host 127.0.0.1] [--port 4000] [--success-word SUCCESS|OK]";
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") throw std::invalid_argument(usage);
    if (i + 1 >= argc) throw std::invalid_argument(arg + ": missing value\n" + usage);
    std::string value = argv[++i];
    if (arg == "--port") {
      char* end = nullptr;
      long port = std::strtol(value.c_str(), &end, 10);
      if (value.empty() || *end != '\0' || port < 0 || port > 65535)
        throw std::invalid_argument("--port: expected 0..65535, got '" + value + "'");
      options["port"] = port;
    } else if (arg == "--host") {
      options["host"] = value;
    } else if (arg == "--success-word") {
      options["success_word"] = value;  // the transport validates it
    } else {
      throw std::invalid_argument("unknown option '" + arg + "'\n" + usage);
    }
  }
  return options;
}

}  // namespace simgate::examples

#endif  // SIMGATE_DOCS_EXAMPLES_EXAMPLE_COMMON_H_
