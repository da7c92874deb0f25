// compute — MORSE's asynchronous "manually registering services" example, in C++.
//
// start_computation() is registered as the async service test_component.compute; it only
// records the start value and the request's Completion (MORSE's result_setter). The main
// loop calls process() and, once per second, advances the computation by one unit; at 0
// it completes the request. Try it:
//
//   $ simgate_example_compute
//   listening on tcp://127.0.0.1:4000
//   $ telnet localhost 4000
//   req2 test_component compute (5,)
//   [about 5 seconds later]
//   req2 SUCCESS "done!"
#include <chrono>
#include <exception>
#include <iostream>
#include <mutex>

#include "example_common.h"
#include "simgate/core/plugin_loader.h"

namespace {

using simgate::Completion;
using simgate::Status;

// The computation's state. Services run under the simulation lock, on whichever thread
// runs them (the transport's I/O thread runs a request itself when the lock is free), so
// the main loop touches this state under that lock too, as a simulation loop steps under it.
struct State {
  Completion result_cb;                             // finishes the request
  bool run_computation = false;                     // a computation is under way
  long value = 0;                                   // units left
  std::chrono::steady_clock::time_point next_step;  // when the next unit is due
};
State g_state;

// The async service: arbitrary parameters, the Completion first. Must return quickly.
bool start_computation(Completion result_setter, long start_value) {
  g_state.result_cb = result_setter;
  g_state.value = start_value;
  g_state.run_computation = true;
  g_state.next_step = std::chrono::steady_clock::now();  // the first unit right away
  return true;                                           // the task was started
}

// One step of the computation, once per second.
long complex_computation(long a) {
  if (a <= 0) {
    // at the end of the computation, set the result (any JSON value)
    g_state.result_cb(Status::success, "done!");
    g_state.run_computation = false;
  }
  return a - 1;
}

}  // namespace

int main(int argc, char** argv) {
  simgate::json options;  // the socket transport's, from --host, --port, --success-word
  if (auto code = simgate::examples::parse_socket_options(
          argc, argv, "simgate_example_compute",
          "MORSE's standalone async example: test_component compute(start_value), 1 unit/s",
          options))
    return *code;  // --help, or a usage error
  try {
    auto req_manager = simgate::load_transport("socket", options);
    // the optional service name defines a custom one: test_component.compute
    req_manager->register_async_service("test_component", start_computation, "compute",
                                        {"start_value"});

    simgate::examples::install_stop_handlers();
    req_manager->start();
    std::cout << "listening on " << req_manager->endpoints().at(0) << std::endl;

    using Clock = std::chrono::steady_clock;
    simgate::SimulationGate& simulation_lock = *req_manager->gate();
    while (!simgate::examples::g_stop.load()) {
      // serve requests until the next unit is due (at most 100 ms, to notice a stop)
      Clock::duration wait = std::chrono::milliseconds(100);
      {
        std::lock_guard lock(simulation_lock);
        if (g_state.run_computation) wait = std::min(wait, g_state.next_step - Clock::now());
      }
      req_manager->process(std::max(wait, Clock::duration::zero()));  // takes the lock itself
      std::lock_guard lock(simulation_lock);
      if (g_state.run_computation && Clock::now() >= g_state.next_step) {
        g_state.next_step += std::chrono::seconds(1);
        g_state.value = complex_computation(g_state.value);
        std::cout << "Value is now " << g_state.value << std::endl;
      }
    }
    req_manager->stop();
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "simgate_example_compute: " << e.what() << std::endl;
    return 1;
  }
}
