// sim/src/helpers.h — small helpers several sources of libsimgate_sim share (private).
//
// Each was a file-local copy in up to four sources before; one definition here, inline.
// Pure functions; any thread.
#ifndef SIMGATE_SIM_SRC_HELPERS_H_
#define SIMGATE_SIM_SRC_HELPERS_H_

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "simgate/core/suggest.h"
#include "simgate/core/text.h"

namespace simgate::sim {

// A number as an error message shows it ("%g": 0.5, 1e-06).
inline std::string number(double x) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", x);
  return text;
}

// "; did you mean 'x'?" when `word` looks like a misspelt candidate, else "".
inline std::string suggestion(const std::string& word, const std::vector<std::string>& candidates) {
  auto match = closest_match(word, candidates);
  return match ? "; did you mean '" + *match + "'?" : "";
}

// a and b equal but for rounding (relative 1e-9): the values MuJoCo's compiler derived from
// one attribute of an actuator.
inline bool same(double a, double b) {
  return std::abs(a - b) <= 1e-9 * std::max(std::abs(a), std::abs(b));
}

// An angle brought into [-pi, pi].
inline double wrap_angle(double a) { return std::remainder(a, 2 * M_PI); }

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_SRC_HELPERS_H_
