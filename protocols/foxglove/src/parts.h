// protocols/foxglove/src/parts.h — the pieces Foxglove's messages and their JSON Schemas share
// (a timestamp, a vector, a pose), for scene.cc and sensors.cc. Internal to the library.
#ifndef SIMGATE_PROTOCOLS_FOXGLOVE_PARTS_H_
#define SIMGATE_PROTOCOLS_FOXGLOVE_PARTS_H_

#include <cstddef>
#include <initializer_list>

#include "simgate/core/status.h"

namespace simgate::foxglove::parts {

// Simulated seconds as Foxglove's {sec, nsec} (0 for a time that is not positive).
json timestamp(double seconds);
// The number `v[i]`, or `fallback` when it is not one.
double at(const json& v, std::size_t i, double fallback = 0);
json vector3(double x, double y, double z);
// {x, y, z, w}
json quaternion(double w, double x, double y, double z);
// The identity pose.
json identity_pose();

// Schemas: a timestamp, an object of numbers named `keys` (all required), a pose, an array.
json time_schema();
json numbers_schema(std::initializer_list<const char*> keys);
json pose_schema();
json array_of(json items);

}  // namespace simgate::foxglove::parts

#endif  // SIMGATE_PROTOCOLS_FOXGLOVE_PARTS_H_
