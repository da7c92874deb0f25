// jsonrpc_test_host — serves the JSON-RPC test services (test_services.h) through the
// jsonrpc plugin, for clients written in other languages (the jayson end-to-end test).
//
//   jsonrpc_test_host ['{"port": 0, ...}']
// Prints "listening on tcp://127.0.0.1:<port>" once ready, then serves until its standard
// input reaches end of file (the driving script closes it, or dies).
#include <cstdio>
#include <iostream>
#include <string>

#include "simgate/core/log.h"
#include "test_services.h"

int main(int argc, char** argv) {
  try {
    simgate::json options = argc > 1 ? simgate::json::parse(argv[1]) : simgate::json::object();
    simgate::jsonrpc_test::TestHost host(options);
    std::cout << "listening on " << host.manager().endpoints().at(0) << std::endl;
    // serve until stdin closes
    std::string ignored;
    while (std::getline(std::cin, ignored)) {}
    host.stop();
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "jsonrpc_test_host: %s\n", e.what());
    return 1;
  }
}
