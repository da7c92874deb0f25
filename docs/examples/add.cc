// add — MORSE's first "manually registering services" example, in C++.
//
// A socket request manager with no simulation at all, one synchronous service registered
// by hand, and a loop calling process(). Try it:
//
//   $ simgate_example_add                       # or --port 0 for any free port
//   listening on tcp://127.0.0.1:4000
//   $ telnet localhost 4000
//   req1 test_component add (1,2)
//   req1 SUCCESS 3
//
// With --success-word OK it answers `req1 OK 3`, as MORSE's documentation shows.
#include <exception>
#include <iostream>

#include "example_common.h"
#include "simgate/core/errors.h"
#include "simgate/core/plugin_loader.h"

namespace {

using simgate::json;

// Python's a + b for what a client can send: numbers, strings, lists.
json add(json a, json b) {
  if (a.is_number_integer() && b.is_number_integer())
    return a.get<std::int64_t>() + b.get<std::int64_t>();
  if (a.is_number() && b.is_number()) return a.get<double>() + b.get<double>();
  if (a.is_string() && b.is_string()) return a.get<std::string>() + b.get<std::string>();
  if (a.is_array() && b.is_array()) {
    for (const auto& e : b) a.push_back(e);
    return a;
  }
  throw simgate::ServiceError("unsupported operand types for +: " + simgate::describe_json(a) +
                              " and " + simgate::describe_json(b));
}

}  // namespace

int main(int argc, char** argv) {
  simgate::json options;  // the socket transport's, from --host, --port, --success-word
  if (auto code = simgate::examples::parse_socket_options(
          argc, argv, "simgate_example_add",
          "MORSE's standalone example: test_component add(a, b), served over the socket transport",
          options))
    return *code;  // --help, or a usage error
  try {
    auto req_manager = simgate::load_transport("socket", options);
    req_manager->register_service("test_component", add, "add", {"a", "b"});
    // pymorse asks for `simulation details` when it connects: an empty scene will do
    req_manager->register_service(
        "simulation", [] { return json{{"robots", json::array()}, {"environment", "standalone"}}; },
        "details");

    simgate::examples::install_stop_handlers();
    req_manager->start();
    std::cout << "listening on " << req_manager->endpoints().at(0) << std::endl;

    while (!simgate::examples::g_stop.load()) {
      // executes incoming requests and writes back results; wakes at once on a request
      req_manager->process(std::chrono::milliseconds(100));
    }
    req_manager->stop();
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "simgate_example_add: " << e.what() << std::endl;
    return 1;
  }
}
