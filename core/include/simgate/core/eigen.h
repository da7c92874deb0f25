// simgate/core/eigen.h — Eigen vectors as service parameters and results (JSON arrays).
// Include it where a service takes or returns Eigen::Vector3d and friends.
#ifndef SIMGATE_CORE_EIGEN_H_
#define SIMGATE_CORE_EIGEN_H_

#include <string>

#include <Eigen/Core>

#include "simgate/core/arguments.h"

namespace simgate {

template <class Scalar, int Rows, int Options, int MaxRows>
struct ArgTraits<Eigen::Matrix<Scalar, Rows, 1, Options, MaxRows, 1>> {
  using Vector = Eigen::Matrix<Scalar, Rows, 1, Options, MaxRows, 1>;
  static Vector from_json(const json& j) {
    if (!j.is_array() || (Rows != Eigen::Dynamic && j.size() != std::size_t(Rows)))
      throw TypeMismatch{expected(), "", describe_json(j)};
    Vector v(static_cast<Eigen::Index>(j.size()));
    for (std::size_t i = 0; i < j.size(); ++i)
      v[Eigen::Index(i)] = detail::convert_element<Scalar>(j[i], "[" + std::to_string(i) + "]");
    return v;
  }
  static json to_json(const Vector& v) {
    json out = json::array();
    for (Eigen::Index i = 0; i < v.size(); ++i) out.push_back(v[i]);
    return out;
  }
  static json schema() {
    json s{{"type", "array"}, {"items", ArgTraits<Scalar>::schema()}};
    if constexpr (Rows != Eigen::Dynamic) s["minItems"] = s["maxItems"] = Rows;
    return s;
  }
  static std::string expected() {
    return Rows == Eigen::Dynamic ? "array of numbers"
                                  : "array of " + std::to_string(Rows) + " numbers";
  }
};

}  // namespace simgate

#endif  // SIMGATE_CORE_EIGEN_H_
