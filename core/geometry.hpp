// Shared value types: points and vectors in mm, as Eigen fixed-size vectors.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <limits>

namespace ncd {

using Vec3 = Eigen::Vector3d;

constexpr double kPi = 3.14159265358979323846;
inline constexpr double kInf = std::numeric_limits<double>::infinity();

inline double deg_to_rad(double deg) {
  return deg * kPi / 180.0;
}
inline double rad_to_deg(double rad) {
  return rad * 180.0 / kPi;
}

}  // namespace ncd
