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

// Above this ratio of the largest to the smallest |C'| at the 10 nodes, the one-panel rule is
// checked against halves (GaussLegendre10::adaptive, as the walker's arc_length_mm). |C'|² is a
// polynomial on a span; where |C'| varies by less than this, its complex zeros lie far enough from
// [a, b] for the 10-point rule to be exact to rounding. Near a near-cusp it is not: an interval of
// 0.16 mm over a dip of |C'| to a fifth of its value came out 2.4e-4 mm long, and every node after
// it stood that far from its point of the curve (docs/planner.md §2, "Arc length of an interval").
inline constexpr double kArcSmoothRatio = 1.1;

// The arc length of c over [a, b] (the sampler's intervals hold no knot): the 10-point rule,
// its nodes sharing one span search, checked adaptively where |C'| varies (kArcSmoothRatio).
inline double gauss_arc_mm(const toolpath::NurbsCurve& c, double a, double b) {
  std::size_t span = 0;
  double lo = std::numeric_limits<double>::infinity(), hi = 0.0;
  const double whole = GaussLegendre10::integrate(
      [&c, &span, &lo, &hi](double w) {
        const double v = c.derivative(w, span).norm();
        lo = std::min(lo, v), hi = std::max(hi, v);
        return v;
      },
      a, b);
  if (hi <= kArcSmoothRatio * lo) return whole;
  const auto speed = [&c, &span](double w) { return c.derivative(w, span).norm(); };
  return GaussLegendre10::adaptive(speed, a, b, whole);
}

// The parametric speed |C'| = |d1| vanishes to rounding: below 1e-9 of the curve's size (its
// largest control point, at least 1 mm) per unit of its parameter range.
inline bool speed_vanishes(const toolpath::NurbsCurve& c, const Vec3& d1) {
  double top = 0.0;
  for (const Vec3& q : c.points()) top = std::max(top, q.norm());
  return !(d1.norm() > 1e-9 * std::max(1.0, top) / std::max(c.u_end() - c.u_begin(), 1e-300));
}

}  // namespace ncd::feed::sampler_detail
