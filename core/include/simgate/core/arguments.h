// simgate/core/arguments.h — converting JSON arguments to C++ parameter types, and back.
//
// ArgTraits<T> says how a JSON value becomes a T (from_json, throwing TypeMismatch with
// what was expected), how a T becomes JSON (to_json) and what JSON schema describes T
// (schema, for introspection). Built in: bool, integers (range-checked), floating point,
// std::string, json (anything), std::vector, std::array, std::optional, std::map<string,T>.
// Eigen vectors: include simgate/core/eigen.h. Other types: specialise ArgTraits, or give
// them nlohmann::json from_json/to_json (the fallback below uses those).
#ifndef SIMGATE_CORE_ARGUMENTS_H_
#define SIMGATE_CORE_ARGUMENTS_H_

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "simgate/core/status.h"

namespace simgate {

// A JSON value did not fit the parameter type. `expected` reads as "number",
// "array of 3 numbers"; `where` locates the element inside the value ("[2]", ".x").
struct TypeMismatch {
  std::string expected;
  std::string where;
  std::string found;  // describe_json() of the offending element
};

// describe_json is defined in config.cc; declared here to keep this header standalone.
std::string describe_json(const json& value);

template <class T, class Enable = void>
struct ArgTraits {
  // fallback: any type nlohmann::json can convert
  static T from_json(const json& j) {
    try {
      return j.get<T>();
    } catch (const json::exception&) {
      throw TypeMismatch{"a value convertible to the parameter type", "", describe_json(j)};
    }
  }
  static json to_json(const T& v) { return json(v); }
  static json schema() { return json::object(); }
  static std::string expected() { return "value"; }
};

template <>
struct ArgTraits<bool> {
  static bool from_json(const json& j) {
    if (!j.is_boolean()) throw TypeMismatch{"boolean", "", describe_json(j)};
    return j.get<bool>();
  }
  static json to_json(bool v) { return v; }
  static json schema() { return {{"type", "boolean"}}; }
  static std::string expected() { return "boolean"; }
};

template <class T>
struct ArgTraits<T, std::enable_if_t<std::is_integral_v<T> && !std::is_same_v<T, bool>>> {
  static T from_json(const json& j) {
    // integers, or numbers with an integral value (5.0 from JavaScript clients); read
    // through get_ptr (one type check) rather than get<> (a conversion switch). Unsigned
    // first: nlohmann's get_ptr<number_integer_t*> also answers for unsigned values.
    if (const auto* v = j.get_ptr<const json::number_unsigned_t*>()) {
      if (std::in_range<T>(*v)) return static_cast<T>(*v);
      throw TypeMismatch{expected() + " in range", "", describe_json(j)};
    }
    if (const auto* v = j.get_ptr<const json::number_integer_t*>()) {
      if (std::in_range<T>(*v)) return static_cast<T>(*v);
      throw TypeMismatch{expected() + " in range", "", describe_json(j)};
    }
    if (j.is_number_float()) {
      // in range: min <= d < 2^digits. Both bounds are exact doubles; max itself is not for
      // 64-bit types (double(UINT64_MAX) rounds up to 2^64, which does not fit: converting
      // it is undefined behaviour)
      constexpr double upper =
          double(std::uint64_t{1} << (std::numeric_limits<T>::digits - 1)) * 2.0;
      double d = j.get<double>();
      if (std::isfinite(d) && std::trunc(d) == d && d >= double(std::numeric_limits<T>::min()) &&
          d < upper)
        return static_cast<T>(d);
    }
    throw TypeMismatch{expected(), "", describe_json(j)};
  }
  static json to_json(T v) { return v; }
  static json schema() {
    json s{{"type", "integer"}};
    if constexpr (std::is_unsigned_v<T>) s["minimum"] = 0;
    return s;
  }
  static std::string expected() {
    return std::is_unsigned_v<T> ? "non-negative integer" : "integer";
  }
};

template <class T>
struct ArgTraits<T, std::enable_if_t<std::is_floating_point_v<T>>> {
  static T from_json(const json& j) {
    if (const auto* v = j.get_ptr<const json::number_float_t*>()) return static_cast<T>(*v);
    if (const auto* v = j.get_ptr<const json::number_unsigned_t*>()) return static_cast<T>(*v);
    if (const auto* v = j.get_ptr<const json::number_integer_t*>()) return static_cast<T>(*v);
    throw TypeMismatch{"number", "", describe_json(j)};
  }
  static json to_json(T v) { return v; }
  static json schema() { return {{"type", "number"}}; }
  static std::string expected() { return "number"; }
};

template <>
struct ArgTraits<std::string> {
  static std::string from_json(const json& j) {
    if (!j.is_string()) throw TypeMismatch{"string", "", describe_json(j)};
    return j.get<std::string>();
  }
  static json to_json(const std::string& v) { return v; }
  static json schema() { return {{"type", "string"}}; }
  static std::string expected() { return "string"; }
};

template <>
struct ArgTraits<json> {
  static json from_json(const json& j) { return j; }
  static json to_json(const json& v) { return v; }
  static json schema() { return json::object(); }
  static std::string expected() { return "any JSON value"; }
};

namespace detail {
// Converts element `i` of an array, prefixing its index to the location of any mismatch.
template <class T>
T convert_element(const json& j, const std::string& where) {
  try {
    return ArgTraits<T>::from_json(j);
  } catch (TypeMismatch& m) {
    m.where = where + m.where;
    throw;
  }
}
}  // namespace detail

template <class T>
struct ArgTraits<std::vector<T>> {
  static std::vector<T> from_json(const json& j) {
    if (!j.is_array()) throw TypeMismatch{expected(), "", describe_json(j)};
    std::vector<T> out;
    out.reserve(j.size());
    for (std::size_t i = 0; i < j.size(); ++i)
      out.push_back(detail::convert_element<T>(j[i], "[" + std::to_string(i) + "]"));
    return out;
  }
  static json to_json(const std::vector<T>& v) {
    json out = json::array();
    for (const auto& e : v) out.push_back(ArgTraits<T>::to_json(e));
    return out;
  }
  static json schema() { return {{"type", "array"}, {"items", ArgTraits<T>::schema()}}; }
  static std::string expected() { return "array of " + ArgTraits<T>::expected() + "s"; }
};

template <class T, std::size_t N>
struct ArgTraits<std::array<T, N>> {
  static std::array<T, N> from_json(const json& j) {
    if (!j.is_array() || j.size() != N) throw TypeMismatch{expected(), "", describe_json(j)};
    std::array<T, N> out;
    for (std::size_t i = 0; i < N; ++i)
      out[i] = detail::convert_element<T>(j[i], "[" + std::to_string(i) + "]");
    return out;
  }
  static json to_json(const std::array<T, N>& v) {
    json out = json::array();
    for (const auto& e : v) out.push_back(ArgTraits<T>::to_json(e));
    return out;
  }
  static json schema() {
    return {{"type", "array"}, {"items", ArgTraits<T>::schema()}, {"minItems", N}, {"maxItems", N}};
  }
  static std::string expected() {
    return "array of " + std::to_string(N) + " " + ArgTraits<T>::expected() + "s";
  }
};

template <class T>
struct ArgTraits<std::optional<T>> {
  static std::optional<T> from_json(const json& j) {
    if (j.is_null()) return std::nullopt;
    return ArgTraits<T>::from_json(j);
  }
  static json to_json(const std::optional<T>& v) { return v ? ArgTraits<T>::to_json(*v) : json(); }
  static json schema() {
    json s = ArgTraits<T>::schema();
    if (s.contains("type")) s["type"] = json::array({s["type"], "null"});
    return s;
  }
  static std::string expected() { return ArgTraits<T>::expected() + " or null"; }
};

template <class T>
struct ArgTraits<std::map<std::string, T>> {
  static std::map<std::string, T> from_json(const json& j) {
    if (!j.is_object()) throw TypeMismatch{expected(), "", describe_json(j)};
    std::map<std::string, T> out;
    for (auto it = j.begin(); it != j.end(); ++it)
      out.emplace(it.key(), detail::convert_element<T>(it.value(), "." + it.key()));
    return out;
  }
  static json to_json(const std::map<std::string, T>& v) {
    json out = json::object();
    for (const auto& [k, e] : v) out[k] = ArgTraits<T>::to_json(e);
    return out;
  }
  static json schema() {
    return {{"type", "object"}, {"additionalProperties", ArgTraits<T>::schema()}};
  }
  static std::string expected() { return "object of " + ArgTraits<T>::expected() + "s"; }
};

}  // namespace simgate

#endif  // SIMGATE_CORE_ARGUMENTS_H_
