#include "parts.h"

#include <cmath>
#include <cstdint>

namespace simgate::foxglove::parts {

json timestamp(double seconds) {
  if (!(seconds > 0)) return json{{"sec", 0}, {"nsec", 0}};
  const double whole = std::floor(seconds);
  auto nsec = static_cast<std::int64_t>(std::llround((seconds - whole) * 1e9));
  auto sec = static_cast<std::int64_t>(whole);
  if (nsec >= 1'000'000'000) {
    ++sec;
    nsec -= 1'000'000'000;
  }
  return json{{"sec", sec}, {"nsec", nsec}};
}

double at(const json& v, std::size_t i, double fallback) {
  return v.is_array() && i < v.size() && v[i].is_number() ? v[i].get<double>() : fallback;
}

json vector3(double x, double y, double z) { return json{{"x", x}, {"y", y}, {"z", z}}; }

json quaternion(double w, double x, double y, double z) {
  return json{{"x", x}, {"y", y}, {"z", z}, {"w", w}};
}

json identity_pose() {
  return json{{"position", vector3(0, 0, 0)}, {"orientation", quaternion(1, 0, 0, 0)}};
}

json time_schema() {
  return json{{"type", "object"},
              {"properties",
               {{"sec", {{"type", "integer"}, {"minimum", 0}}},
                {"nsec", {{"type", "integer"}, {"minimum", 0}, {"maximum", 999999999}}}}},
              {"required", {"sec", "nsec"}}};
}

json numbers_schema(std::initializer_list<const char*> keys) {
  json properties = json::object();
  json required = json::array();
  for (const char* k : keys) {
    properties[k] = json{{"type", "number"}};
    required.push_back(k);
  }
  return json{{"type", "object"}, {"properties", properties}, {"required", required}};
}

json pose_schema() {
  return json{{"type", "object"},
              {"properties",
               {{"position", numbers_schema({"x", "y", "z"})},
                {"orientation", numbers_schema({"x", "y", "z", "w"})}}},
              {"required", {"position", "orientation"}}};
}

json array_of(json items) { return json{{"type", "array"}, {"items", std::move(items)}}; }

}  // namespace simgate::foxglove::parts
