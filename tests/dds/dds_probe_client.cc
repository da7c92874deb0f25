// dds_probe_client — a DdsClient in its own process, for tests that need the client
// elsewhere (another network namespace) or killable (client death).
//
//   dds_probe_client DOMAIN PARTITION CONFIG waypoint X Y
//       waits for the server, lists its services, calls robot.waypoint goto(X, Y, 0) and
//       robot.pose get_local_data(); prints one JSON object and exits 0 (1 on any failure).
//   dds_probe_client DOMAIN PARTITION CONFIG hang COMPONENT SERVICE PARAMS_JSON
//       starts an async call, prints "accepted" once acknowledged, then waits (at most 60 s)
//       to be killed.
//   dds_probe_client DOMAIN PARTITION CONFIG pipeline N
//       starts N calls of calc.add(i, 1) back to back, then waits for each (60 s in all at
//       most); prints {"answered": ..., "overloaded": ..., "other": ..., "lost": ...}: lost =
//       calls that got no final reply, overloaded = refused "Overloaded" (FL_BUSY).
//   dds_probe_client DOMAIN PARTITION CONFIG echo N BYTES
//       calls calc.echo(text of BYTES bytes) N times, one after the other (5 s each at most);
//       prints {"answered": ..., "failed": ..., "ms": ...} and exits 0.
//
// CONFIG is Cyclone XML text or a file:// URI. Every wait is bounded.
#include <chrono>
#include <iostream>
#include <string>
#include <thread>
#include <vector>

#include "simgate/client/dds_client.h"

using namespace std::chrono_literals;
using simgate::json;
using simgate::client::DdsClient;
using simgate::client::DdsClientOptions;

namespace {

json outcome_json(const simgate::Outcome& o) {
  json out = {{"status", simgate::to_string(o.status)}, {"message", o.message}};
  out["value"] = o.value ? *o.value : json();
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 5) {
    std::cerr << "usage: dds_probe_client DOMAIN PARTITION CONFIG (waypoint X Y | hang COMPONENT "
                 "SERVICE PARAMS | "
                 "pipeline N | echo N BYTES)\n";
    return 2;
  }
  try {
    DdsClientOptions options;
    options.domain = static_cast<std::uint32_t>(std::stoul(argv[1]));
    options.partition = argv[2];
    options.config = argv[3];
    options.discovery_timeout = 30s;
    std::string mode = argv[4];
    DdsClient client(options);
    if (!client.wait_for_server(30s)) {
      std::cerr << "dds_probe_client: no server in partition " << options.partition << "\n";
      return 1;
    }

    if (mode == "waypoint" && argc == 7) {
      json result;
      json services = client.list_services(30s);
      result["services"] = json::array();
      for (const json& s : services)
        result["services"].push_back(s["component"].get<std::string>() + "." +
                                     s["name"].get<std::string>());
      double x = std::stod(argv[5]), y = std::stod(argv[6]);
      result["goto"] = outcome_json(client.call("robot.waypoint", "goto", {x, y, 0.0}, 120s));
      result["pose"] = outcome_json(client.call("robot.pose", "get_local_data", nullptr, 30s));
      std::cout << result.dump() << std::endl;
      return 0;
    }
    if (mode == "hang" && argc == 8) {
      auto id = client.start(argv[5], argv[6], json::parse(argv[7]));
      if (!client.wait_accepted(id, 30s)) {
        std::cerr << "dds_probe_client: call not accepted\n";
        return 1;
      }
      std::cout << "accepted" << std::endl;
      std::this_thread::sleep_for(60s);  // until killed
      return 1;
    }
    if (mode == "pipeline" && argc == 6) {
      const int count = std::stoi(argv[5]);
      std::vector<DdsClient::CallId> ids;
      for (int i = 0; i < count; ++i) ids.push_back(client.start("calc", "add", {i, 1}));
      int answered = 0, overloaded = 0, other = 0, lost = 0;
      json first_other;
      const auto deadline = std::chrono::steady_clock::now() + 60s;
      for (int i = 0; i < count; ++i) {
        auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
            deadline - std::chrono::steady_clock::now());
        try {
          simgate::Outcome out = client.wait(ids[i], std::max(left, std::chrono::milliseconds(1)));
          if (out.status == simgate::Status::success && out.value == json(double(i + 1))) {
            ++answered;
          } else if (out.failure == simgate::Failure::busy &&
                     out.message.rfind("Overloaded", 0) == 0) {
            ++overloaded;
          } else if (other++ == 0) {
            first_other = outcome_json(out);
          }
        } catch (const std::exception& e) {
          ++lost;  // no final reply in time
        }
      }
      std::cout << json{{"answered", answered},
                        {"overloaded", overloaded},
                        {"other", other},
                        {"first_other", first_other},
                        {"lost", lost}}
                       .dump()
                << std::endl;
      return 0;
    }
    if (mode == "echo" && argc == 7) {
      const int count = std::stoi(argv[5]);
      const std::string text(std::stoul(argv[6]), 'x');
      int answered = 0, failed = 0;
      const auto started = std::chrono::steady_clock::now();
      for (int i = 0; i < count; ++i) {
        try {
          simgate::Outcome out = client.call("calc", "echo", {text}, 5s);
          ++(out.value == json(text) ? answered : failed);
        } catch (const std::exception& e) {
          ++failed;
        }
      }
      auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(
          std::chrono::steady_clock::now() - started);
      std::cout << json{{"answered", answered}, {"failed", failed}, {"ms", ms.count()}}.dump()
                << std::endl;
      return 0;
    }
    std::cerr << "dds_probe_client: unknown mode or wrong arguments\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "dds_probe_client: " << e.what() << "\n";
    return 1;
  }
}
