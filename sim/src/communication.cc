#include "simgate/sim/communication.h"

#include <cmath>

#include "simgate/core/call_context.h"
#include "simgate/core/errors.h"
#include "simgate/sim/sim_component.h"

namespace simgate::sim {

CommunicationServices::CommunicationServices(Simulation& sim)
    : Component("communication"), sim_(sim) {
  add_service("distance_and_view", &CommunicationServices::distance_and_view, {"robot1", "robot2"})
      .doc(
          "[distance, can_see] between two robots' roots: metres, and whether nothing else lies "
          "between them");
}

int CommunicationServices::robot_body(const std::string& name, const std::string& parameter) const {
  // a robot the caller's transport does not serve does not exist for it (call_context.h)
  const ComponentEntry* e = sim_.find(name);
  const auto* robot = e && e->is_robot && caller_serves(name)
                          ? dynamic_cast<const Robot*>(e->component.get())
                          : nullptr;
  if (!robot) {
    std::vector<std::string> robots;
    for (const auto& r : sim_.components())
      if (r->is_robot && caller_serves(r->component->name()))
        robots.push_back(r->component->name());
    // MORSE's text, trailing space included; the choices go in the detail
    throw ServiceError(
        name + " does not exist in the simulation ", Failure::bad_arguments,
        {{"parameter", parameter}, {"expected", "a robot name"}, {"choices", robots}});
  }
  return robot->body();
}

json CommunicationServices::distance_and_view(const std::string& robot1,
                                              const std::string& robot2) const {
  const int body1 = robot_body(robot1, "robot1");
  const int body2 = robot_body(robot2, "robot2");
  const double distance = (body_position(sim_, body2) - body_position(sim_, body1)).norm();
  return json::array({distance, line_of_sight(body1, body2)});
}

bool CommunicationServices::line_of_sight(int body1, int body2) const {
  const mjModel* m = sim_.m();
  const mjData* d = sim_.d();
  const Eigen::Vector3d from = body_position(sim_, body1);
  const Eigen::Vector3d segment = body_position(sim_, body2) - from;
  const double length = segment.norm();
  if (length == 0) return true;
  // mj_ray excludes one body; the robots' other bodies are passed by casting again from
  // just beyond each of their hits (a convex geom is hit at most twice: entering, leaving)
  const double step_past = 1e-6 / length;  // a micrometre, as a fraction of the segment
  double t = 0;                            // fraction of the segment cleared so far
  for (int cast = 0; cast < 2 * m->ngeom + 2; ++cast) {
    const Eigen::Vector3d start = from + t * segment;
    int geom = -1;
    // x: the hit as a multiple of `segment`, or -1 (mj_ray skips fully transparent geoms)
    const mjtNum x = mj_ray(m, d, start.data(), segment.data(), nullptr, 1, body1, &geom, nullptr);
    if (x < 0 || t + x >= 1) return true;
    const int body = m->geom_bodyid[geom];
    if (!in_subtree(m, body, body1) && !in_subtree(m, body, body2)) return false;
    t += x + step_past;
  }
  // not reached for convex geoms; a robot made of more hits than that is not seen through
  return false;
}

}  // namespace simgate::sim
