// simgate/sim/communication.h — the `communication` pseudo-component (MORSE's
// communication services).
//
// distance_and_view robot1 robot2 -> [distance, can_see]: the distance in metres between
// the two robots' root bodies (their origins, world frame), and whether the segment
// between those origins is clear of every geom other than the two robots' own (their
// subtrees: a robot does not hide itself). Unknown robot (or one the caller's transport
// does not serve): FAILED "<name> does not exist in the simulation " (MORSE's text).
//
// Threads: simulation thread only, as every service.
#ifndef SIMGATE_SIM_COMMUNICATION_H_
#define SIMGATE_SIM_COMMUNICATION_H_

#include <string>

#include "simgate/core/component.h"
#include "simgate/sim/simulation.h"

namespace simgate::sim {

class CommunicationServices : public Component {
 public:
  explicit CommunicationServices(Simulation& sim);

  json distance_and_view(const std::string& robot1, const std::string& robot2) const;

 private:
  // The root body of robot `name`, or FAILED naming `parameter`.
  int robot_body(const std::string& name, const std::string& parameter) const;
  // Whether no geom but those of the subtrees of `body1` and `body2` crosses the segment
  // between their origins.
  bool line_of_sight(int body1, int body2) const;

  Simulation& sim_;  // whose robots
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_COMMUNICATION_H_
