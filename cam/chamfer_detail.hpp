// What chamfer.cpp and chamfer_spec.cpp share: the pipe surface along a drill generator (a
// quadratic in z, its stable root polished by Newton: "Edge curve by numerical intersection" at
// the top of chamfer.cpp), and angles as text.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>

#include "cam/chamfer.hpp"
#include "core/number_text.hpp"

namespace ncd::toolpath::chamfer_detail {

inline std::string fmt_deg(double rad) {
  return text::sig(rad_to_deg(rad)) + "°";
}

// g(z) = qa z² + qb z + qc: the pipe surface's implicit f along the drill generator at θ.
struct Quadratic {
  double qa = 0.0, qb = 0.0, qc = 0.0;
  double discriminant() const { return qb * qb - 4.0 * qa * qc; }
};

inline Quadratic generator_quadratic(const PipeSurface& s, double r, double cos_t, double sin_t) {
  const Vec3& a = s.axis_direction;
  const Vec3 w0 = Vec3(r * cos_t, r * sin_t, 0.0) - s.axis_point;
  const double aw = a.dot(w0), rho0 = s.radius_mm + s.slope * aw;
  const double k2 = s.slope * s.slope;
  return {1.0 - (1.0 + k2) * a.z() * a.z(), 2.0 * (w0.z() - a.z() * aw - s.slope * a.z() * rho0),
          w0.squaredNorm() - aw * aw - rho0 * rho0};
}

inline Quadratic generator_quadratic(const PipeSurface& s, double r, double theta) {
  return generator_quadratic(s, r, std::cos(theta), std::sin(theta));
}

// The upper (larger) or lower root of g, from the stable quadratic formula; nullopt where the
// generator misses the surface. Requires qa > 0 (checked by validate).
inline std::optional<double> quadratic_root(const Quadratic& q, bool upper) {
  const double disc = q.discriminant();
  if (!(disc >= 0.0) || !(q.qa > 0.0)) return std::nullopt;
  const double sq = std::sqrt(disc);
  const double m = -0.5 * (q.qb + std::copysign(sq, q.qb));
  const double r1 = m / q.qa, r2 = m != 0.0 ? q.qc / m : r1;
  return upper ? std::max(r1, r2) : std::min(r1, r2);
}

// That root at θ (given by its cosine and sine), polished by Newton on the distance-like
// |w⊥| − ρ to machine precision: the start is within rounding of the cancellation in g's
// constant term, so one or two steps suffice.
inline std::optional<double> generator_root(const PipeSurface& s, double r, double cos_t,
                                            double sin_t, bool upper) {
  const auto start = quadratic_root(generator_quadratic(s, r, cos_t, sin_t), upper);
  if (!start) return std::nullopt;
  double z = *start;
  const Vec3& a = s.axis_direction;
  const Vec3 x0(r * cos_t, r * sin_t, 0.0);
  for (int i = 0; i < 4; ++i) {
    const Vec3 w = x0 + Vec3(0.0, 0.0, z) - s.axis_point;
    const double aw = a.dot(w);
    const Vec3 w_perp = w - aw * a;
    const double dist = w_perp.norm();
    const double slope = w_perp.z() / dist - s.slope * a.z();
    if (!(dist > 0.0) || slope == 0.0) break;
    const double step = (dist - (s.radius_mm + s.slope * aw)) / slope;
    z -= step;
    if (std::abs(step) <= 4.0 * std::numeric_limits<double>::epsilon() * (std::abs(z) + r)) break;
  }
  return z;
}

}  // namespace ncd::toolpath::chamfer_detail
