// websocket_test_host — serves the JSON-RPC test services (tests/jsonrpc/test_services.h)
// through the websocket plugin, for clients written in other languages (ws_client_test.js).
//
//   websocket_test_host ['{"port": 0, ...}']
// Prints "listening on ws://127.0.0.1:<port>/" once ready, then serves until its standard
// input reaches end of file (the driving script closes it, or dies).
#include <cstdio>
#include <iostream>
#include <string>

#include "test_services.h"

int main(int argc, char** argv) {
  try {
    simgate::json options = argc > 1 ? simgate::json::parse(argv[1]) : simgate::json::object();
    simgate::jsonrpc_test::TestHost host(
        options, std::string(SIMGATE_TEST_PLUGIN_DIR) + "/libsimgate_transport_websocket.so");
    std::cout << "listening on " << host.manager().endpoints().at(0) << std::endl;
    // serve until stdin closes
    std::string ignored;
    while (std::getline(std::cin, ignored)) {}
    host.stop();
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "websocket_test_host: %s\n", e.what());
    return 1;
  }
}
