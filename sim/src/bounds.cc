#include "simgate/sim/bounds.h"

#include <cmath>
#include <cstdio>
#include <string>

#include "simgate/core/errors.h"
#include "helpers.h"

namespace simgate::sim::bounds {

namespace {
// %g: "1e+300", "0.5", "nan", "inf" — the value as the client sent it, whatever it is
std::string with_unit(const std::string& text, std::string_view unit) {
  return unit.empty() ? text : text + " " + std::string(unit);
}

// FAILED with Failure::bad_arguments (JSON-RPC: invalid params), the parameter named in the
// structured detail as the type checks name it
[[noreturn]] void refuse(std::string_view parameter, const std::string& message,
                         const std::string& expected) {
  throw ServiceError(message, Failure::bad_arguments,
                     {{"parameter", std::string(parameter)}, {"expected", expected}});
}
}  // namespace

void require_within(std::string_view parameter, double value, double bound, std::string_view unit) {
  if (std::isfinite(value) && std::abs(value) <= bound) return;
  const std::string expected = "a finite number within ±" + with_unit(number(bound), unit);
  refuse(parameter,
         std::string(parameter) + " = " + number(value) + " is out of bounds: expected " + expected,
         expected);
}

void require_between(std::string_view parameter, double value, double low, double high,
                     std::string_view unit) {
  if (std::isfinite(value) && value >= low && value <= high) return;
  const std::string expected =
      "a finite number from " + number(low) + " to " + with_unit(number(high), unit);
  refuse(parameter,
         std::string(parameter) + " = " + number(value) + " is out of bounds: expected " + expected,
         expected);
}

void require_inside_world(std::string_view parameter, double value, std::string_view object,
                          std::string_view axis, double coordinate) {
  if (std::isfinite(coordinate) && std::abs(coordinate) <= position) return;
  const std::string bound = "±" + with_unit(number(position), "m");
  refuse(parameter,
         std::string(parameter) + " = " + number(value) + " would take " + std::string(object) +
             " to " + std::string(axis) + " = " + number(coordinate) + ", beyond the world bound " +
             bound,
         "a move that keeps every coordinate within " + bound);
}

}  // namespace simgate::sim::bounds
