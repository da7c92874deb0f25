// plugin_probe PLUGIN_PATH OUTPUT: loads a transport plugin by path, serves
// test_component.add through it, and prints what the plugin wrote to OUTPUT.
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "simgate/core/plugin_loader.h"

int main(int argc, char** argv) {
  if (argc != 3) {
    std::cerr << "usage: plugin_probe PLUGIN_PATH OUTPUT\n";
    return 2;
  }
  try {
    auto plugin = simgate::load_transport_plugin(argv[1]);
    auto rm =
        plugin->create({{"call", {"test_component", "add", {1, 2}}}, {"output", argv[2]}}, "probe");
    rm->register_service("test_component", [](int a, int b) { return a + b; }, "add", {"a", "b"});
    auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (!std::filesystem::exists(argv[2]) && std::chrono::steady_clock::now() < deadline)
      rm->process(std::chrono::milliseconds(10));
    std::ifstream in(argv[2]);
    std::stringstream text;
    text << in.rdbuf();
    std::cout << text.str() << "\n";
    return text.str().empty() ? 1 : 0;
  } catch (const std::exception& e) {
    std::cerr << "plugin_probe: " << e.what() << "\n";
    return 1;
  }
}
