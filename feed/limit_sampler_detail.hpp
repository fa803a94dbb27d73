// What the limit sampler's files share (limit_sampler.cpp, limit_sampler_setup.cpp,
// limit_sampler_laws.cpp): a few constants, the corner mode that decides a rest, and small
// numeric helpers (golden section, a 10-point arc length, a vanishing parametric speed). The
// sampler itself is explained at the top of limit_sampler.cpp.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/geometry.hpp"
#include "core/quadrature.hpp"
#include "feed/feed_limits.hpp"
#include "geometry/nurbs.hpp"
#include "geometry/path.hpp"

namespace ncd::feed::sampler_detail {

// The mode that decides whether a corner is a rest. G64 P0 (or a plain G64 with
// blend_tolerance_mm 0) holds its end points exactly, as G61.1 does: its corners are rests
// (docs/planner.md §3a; passed at the corner speed they would be missed by up to ε_c).
inline toolpath::PathControl corner_mode(const toolpath::PathSegment& s, const MachineLimits& l) {
  if (s.path_control != toolpath::PathControl::blend) return s.path_control;
  const double p_mm = s.blend_tolerance_mm.value_or(l.blend_tolerance_mm);
  return std::isfinite(p_mm) && p_mm > 0.0 ? toolpath::PathControl::blend
                                           : toolpath::PathControl::exact_path;
}

// The points curve_turn samples an interval at (docs/planner.md §3c).
inline constexpr int kTurnPoints = 9;

// The knot span index of u, as NurbsCurve::find_span.
inline std::size_t knot_span_of(const toolpath::NurbsCurve& c, double u) {
  const auto& U = c.knots();
  const auto p = static_cast<std::size_t>(c.degree());
  const auto it = std::upper_bound(U.begin() + static_cast<std::ptrdiff_t>(p),
                                   U.end() - static_cast<std::ptrdiff_t>(p) - 1, u);
  return std::max(p, static_cast<std::size_t>(it - U.begin()) - 1);
}

// The argument of the minimum of a unimodal f on [a, b], by golden section, to width tol.
template <typename F>
double golden_section_min(F&& f, double a, double b, double tol) {
  constexpr double kGolden = 0.6180339887498949;
  double x1 = b - kGolden * (b - a), x2 = a + kGolden * (b - a);
  double f1 = f(x1), f2 = f(x2);
  for (int it = 0; it < 100 && b - a > tol; ++it) {
    if (f1 <= f2) {
      b = x2, x2 = x1, f2 = f1, x1 = b - kGolden * (b - a), f1 = f(x1);
    } else {
      a = x1, x1 = x2, f1 = f2, x2 = a + kGolden * (b - a), f2 = f(x2);
    }
  }
  return f1 <= f2 ? x1 : x2;
}

inline FeedLimitResult min_of(FeedLimitResult a, FeedLimitResult b) {
  return b.feed_mm_per_s < a.feed_mm_per_s ? b : a;
}

inline Vec3 unit_or_zero(const Vec3& v) {
  const double n = v.norm();
  return n > 0.0 ? Vec3(v / n) : Vec3::Zero();
}

// The arc length of c over [a, b] by the 10-point rule (the sampler's intervals hold no knot,
// so the rule is exact to rounding there), its nodes sharing one span search.
inline double gauss_arc_mm(const toolpath::NurbsCurve& c, double a, double b) {
  std::size_t span = 0;
  return GaussLegendre10::integrate([&c, &span](double w) { return c.derivative(w, span).norm(); },
                                    a, b);
}

// The parametric speed |C'| = |d1| vanishes to rounding: below 1e-9 of the curve's size (its
// largest control point, at least 1 mm) per unit of its parameter range.
inline bool speed_vanishes(const toolpath::NurbsCurve& c, const Vec3& d1) {
  double top = 0.0;
  for (const Vec3& q : c.points()) top = std::max(top, q.norm());
  return !(d1.norm() > 1e-9 * std::max(1.0, top) / std::max(c.u_end() - c.u_begin(), 1e-300));
}

}  // namespace ncd::feed::sampler_detail
