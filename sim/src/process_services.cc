// The process group of `simulation` (docs/world/entities.md): MORSE's terminate and
// set_log_level.
//
// terminate ends the process at once, without finalization (MORSE: the game engine ends
// without close_all): no reply is sent, pending requests are not answered, transports and
// components are not stopped; the operating system closes the sockets (clients see the
// connection end) and DDS peers see the participant go when its lease expires. quit is the
// clean way: the loop stops after this step and every request still pending is answered.
//
// Both act on the whole process, not the world: they are process-wide services
// (ServiceDescriptor::process_wide), served only through console transports (by default the
// socket transport on loopback: service_access.h). quit (supervision.cc) is one too.
//
// set_log_level component level: MORSE sets the level of the Python logger
// `morse.<component>`. simgate's log has one process-wide level (core/log.h; its lines
// do not carry a component), so the level is set for everything; the component must still
// be one the caller's transport serves (the mapping is a boundary, call_context.h).
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "simgate/core/call_context.h"
#include "simgate/core/errors.h"
#include "simgate/core/log.h"
#include "simgate/core/suggest.h"
#include "simgate/sim/world_services.h"

namespace simgate::sim {

void add_process_services(SupervisionServices& simulation, Simulation& sim) {
  simulation
      .offer_service(
          "terminate",
          [] {
            log::warning("simulation: terminate requested: exiting now, without finalization");
            std::fflush(nullptr);
            std::_Exit(0);
          })
      .doc("End the process at once: no finalization, no reply, pending requests left unanswered")
      .process_wide();
  simulation
      .offer_service(
          "set_log_level",
          [&sim](const std::string& component, const std::string& level) {
            std::vector<std::string> names;
            for (const auto& e : sim.components())
              if (caller_serves(e->component->name())) names.push_back(e->component->name());
            if (std::find(names.begin(), names.end(), component) == names.end())
              throw ServiceError(
                  "Component '" + component + "' not found" + did_you_mean(component, names),
                  Failure::bad_arguments,
                  {{"parameter", "component"},
                   {"expected", "a component name"},
                   {"choices", names}});
            // Python's names (DEBUG, INFO, WARNING, ERROR, CRITICAL) and simgate's, any case
            std::string lower;
            for (char c : level)
              lower += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
            if (lower == "critical" || lower == "fatal") lower = "error";
            log::Level parsed;
            if (!log::parse_level(lower, parsed))
              throw ServiceError(
                  "Unknown level: '" + level +
                      "' (expected one of DEBUG, INFO, WARNING, ERROR, CRITICAL, or trace, off)",
                  Failure::bad_arguments, {{"parameter", "level"}, {"expected", "a log level"}});
            // said before the change, as a warning: a level that hides warnings (error, off)
            // is still seen being set, and by whom
            log::warning("simulation: log level ", log::to_string(log::level()), " -> ",
                         log::to_string(parsed), " (asked by ", caller_description(), ", for '",
                         component, "')");
            log::set_level(parsed);
          },
          {"component", "level"})
      .doc(
          "Set the log level, process-wide (DEBUG, INFO, WARNING, ERROR, CRITICAL); component: one "
          "this transport "
          "serves")
      .process_wide();
}

}  // namespace simgate::sim
