// Dense CAM programs and the time-optimal bound of the shape they sample (issue 34), shared by
// tests/motion/dense_bound_test.cpp and bench/dense_bound_bench.cpp.
//
// The bound is a phase-plane profile computed from the shape itself, never from what ncd walks:
// samples (s, v_max(s)) of the shape's own speed limit (the program feed, and where it bends the
// curve laws of docs/planner.md §1 at its analytic curvature: chord, centripetal acceleration
// and jerk), v = 0 at rests, then forward and backward integration under the tangential
// acceleration limit, and the jerk only near rests (no motion with |jerk| ≤ J is faster at
// distance d from rest than (4.5 J d²)^(1/3)). Jerk is ignored elsewhere, so no jerk-limited
// motion along the shape under the same limits is faster: a strict lower bound.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <vector>

#include "feed/feed_limits.hpp"
#include "geometry/path.hpp"

namespace ncd::test {

// A shape's speed limit along its arc length.
struct ShapeLimit {
  std::vector<double> s_mm, v_mm_per_s;
  void add(double ds_mm, double v) {
    s_mm.push_back(s_mm.empty() ? 0.0 : s_mm.back() + ds_mm);
    v_mm_per_s.push_back(v);
  }
  // A stretch at a constant limit, in steps of at most 2 µm (the integration below is exact
  // for uniform acceleration between samples, so a long step must not hide a cruise).
  void add_line(double length_mm, double v) {
    const double n = std::max(1.0, std::ceil(length_mm / 0.002));
    for (double k = 0.0; k < n; k += 1.0) add(length_mm / n, v);
  }
};

// The curve laws at curvature κ under the cap (mm/s).
inline double curve_limit_mm_per_s(double kappa_per_mm, double cap_mm_per_s,
                                   const feed::MachineLimits& l) {
  return std::min({cap_mm_per_s,
                   feed::chord_feed_mm_per_s(kappa_per_mm, l.chord_tolerance_mm, l.period_s),
                   feed::centripetal_accel_feed_mm_per_s(kappa_per_mm, l.max_accel_mm_per_s2),
                   feed::centripetal_jerk_feed_mm_per_s(kappa_per_mm, l.max_jerk_mm_per_s3)});
}

// The highest speed at a corner turning by φ passed within P of its vertex: the circular arc
// tangent to both pieces whose midpoint is P from the vertex (R = P cos(φ/2) / (1 − cos(φ/2)),
// the curve of least curvature through the corner, §3a) under the centripetal acceleration law
// alone (its jerk and chord laws are left out: a generous corner, so the bound stays a lower
// one). 0 when P is 0 (the corner is a rest), +inf when the pieces do not turn.
inline double corner_limit_mm_per_s(double turn_rad, double p_mm, const feed::MachineLimits& l) {
  if (!(turn_rad > 1e-9)) return std::numeric_limits<double>::infinity();
  if (!(p_mm > 0.0)) return 0.0;
  // A reversal can loop within P: R is taken at least P (generous again).
  const double c = std::cos(0.5 * std::min(turn_rad, 3.14159265358979));
  return std::sqrt(l.max_accel_mm_per_s2 * std::max(p_mm * c / (1.0 - c), p_mm));
}

// The phase-plane time of the limit from rest to rest (first and last samples are rests, and
// every sample with v = 0).
inline double phase_plane_time_s(ShapeLimit lim, double a_max, double j_max) {
  std::vector<double>&s = lim.s_mm, &v = lim.v_mm_per_s;
  const std::size_t n = s.size();
  if (n < 2) return 0.0;
  v.front() = v.back() = 0.0;
  // Distance to the nearest rest, both ways, and the jerk cap from it.
  std::vector<double> d(n, std::numeric_limits<double>::infinity());
  double last = -std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < n; ++i) {
    if (v[i] == 0.0) last = s[i];
    d[i] = s[i] - last;
  }
  last = std::numeric_limits<double>::infinity();
  for (std::size_t i = n; i-- > 0;) {
    if (v[i] == 0.0) last = s[i];
    d[i] = std::min(d[i], last - s[i]);
  }
  for (std::size_t i = 0; i < n; ++i) v[i] = std::min(v[i], std::cbrt(4.5 * j_max * d[i] * d[i]));
  for (std::size_t i = 1; i < n; ++i)
    v[i] = std::min(v[i], std::sqrt(v[i - 1] * v[i - 1] + 2.0 * a_max * (s[i] - s[i - 1])));
  for (std::size_t i = n - 1; i-- > 0;)
    v[i] = std::min(v[i], std::sqrt(v[i + 1] * v[i + 1] + 2.0 * a_max * (s[i + 1] - s[i])));
  double t = 0.0;
  for (std::size_t i = 0; i + 1 < n; ++i) {
    const double ds = s[i + 1] - s[i];
    if (ds > 0.0) t += 2.0 * ds / (v[i] + v[i + 1]);
  }
  return t;
}

inline double round_to(double x, int decimals) {
  const double k = std::pow(10.0, decimals);
  return std::round(x * k) / k;
}

inline toolpath::PathSegment dense_segment(std::vector<Vec3> pts, double f_mm_per_min,
                                           double p_mm) {
  toolpath::PathSegment s;
  s.geometry = toolpath::Polyline{std::move(pts), {}};
  s.feed_mm_per_min = f_mm_per_min;
  s.blend_tolerance_mm = p_mm;  // G64 P, no Q
  return s;
}

// Issue 34's program: `moves` G1 moves of 0.01 mm in x along y = 5 sin(x/3) at F3000 under
// G64 P (no Q), coordinates written to `decimals` decimals.
inline toolpath::Path sine_program(std::size_t moves, int decimals, double p_mm) {
  std::vector<Vec3> pts;
  for (std::size_t i = 0; i <= moves; ++i) {
    const double x = 0.01 * static_cast<double>(i);
    pts.emplace_back(round_to(x, decimals), round_to(5.0 * std::sin(x / 3.0), decimals), 0.0);
  }
  toolpath::Path p;
  p.segments.push_back(dense_segment(std::move(pts), 3000.0, p_mm));
  return p;
}

// The shape's limit: y = 5 sin(x/3), x ∈ [0, 0.01 moves], κ = |y''| / (1 + y'²)^(3/2), sampled
// every 2 µm of x (arc length by the midpoint rule on √(1 + y'²)).
inline ShapeLimit sine_limit(std::size_t moves, const feed::MachineLimits& l) {
  const double x_end = 0.01 * static_cast<double>(moves), dx = 0.002;
  const auto n = static_cast<std::size_t>(std::llround(x_end / dx));
  const auto speed = [](double x) {
    const double y1 = 5.0 / 3.0 * std::cos(x / 3.0);
    return std::sqrt(1.0 + y1 * y1);
  };
  ShapeLimit lim;
  for (std::size_t i = 0; i <= n; ++i) {
    const double x = dx * static_cast<double>(i);
    const double y1 = 5.0 / 3.0 * std::cos(x / 3.0), y2 = -5.0 / 9.0 * std::sin(x / 3.0);
    const double kappa = std::abs(y2) / std::pow(1.0 + y1 * y1, 1.5);
    lim.add(i == 0 ? 0.0 : dx * speed(x - 0.5 * dx), curve_limit_mm_per_s(kappa, 50.0, l));
  }
  return lim;
}

// A CAM-style finishing raster over z = f(x, y) = 2 sin(x/5) cos(y/4) + 0.5 sin((x + y)/7):
// passes along ±x over x ∈ [0, 30] at y = 0, 0.5, …, 0.5 (passes − 1), points every 0.01 mm of
// x (a fine finishing step), each pass joined to the next by a step-over of 0.5 mm in y (one G1),
// F2000, G64 P, coordinates to `decimals` decimals: one polyline segment, as the reader merges the
// G1 moves.
struct Surface {
  static double f(double x, double y) {
    return 2.0 * std::sin(x / 5.0) * std::cos(y / 4.0) + 0.5 * std::sin((x + y) / 7.0);
  }
  static double fx(double x, double y) {
    return 0.4 * std::cos(x / 5.0) * std::cos(y / 4.0) + 0.5 / 7.0 * std::cos((x + y) / 7.0);
  }
  static double fxx(double x, double y) {
    return -0.08 * std::sin(x / 5.0) * std::cos(y / 4.0) - 0.5 / 49.0 * std::sin((x + y) / 7.0);
  }
  static constexpr double kLengthMm = 30.0, kStepMm = 0.01, kStepOverMm = 0.5, kFeed = 2000.0;
  static constexpr std::size_t kPointsPerPass = 3000;  // kLengthMm / kStepMm
};

inline double surface_x(std::size_t pass, std::size_t i) {
  const double x = Surface::kStepMm * static_cast<double>(i);
  return pass % 2 == 0 ? x : Surface::kLengthMm - x;
}

inline toolpath::Path surface_program(std::size_t passes, int decimals, double p_mm) {
  std::vector<Vec3> pts;
  for (std::size_t k = 0; k < passes; ++k) {
    const double y = Surface::kStepOverMm * static_cast<double>(k);
    for (std::size_t i = 0; i <= Surface::kPointsPerPass; ++i) {
      const double x = surface_x(k, i);
      pts.emplace_back(round_to(x, decimals), round_to(y, decimals),
                       round_to(Surface::f(x, y), decimals));
    }
  }
  toolpath::Path p;
  p.segments.push_back(dense_segment(std::move(pts), Surface::kFeed, p_mm));
  return p;
}

// The raster's limit: each pass the curve (x, y_k, f(x, y_k)), κ = |f_xx| / (1 + f_x²)^(3/2),
// sampled every 2 µm of x; each step-over a line at the feed; at each of the two corners
// between a pass and a step-over the corner limit within P (corner_limit_mm_per_s).
inline ShapeLimit surface_limit(std::size_t passes, double p_mm, const feed::MachineLimits& l) {
  const double cap = Surface::kFeed / 60.0, dx = 0.002;
  const auto n = static_cast<std::size_t>(std::llround(Surface::kLengthMm / dx));
  ShapeLimit lim;
  const auto turn = [](const Vec3& a, const Vec3& b) {
    return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0));
  };
  for (std::size_t k = 0; k < passes; ++k) {
    const double y = Surface::kStepOverMm * static_cast<double>(k), dir = k % 2 == 0 ? 1.0 : -1.0;
    const double x0 = k % 2 == 0 ? 0.0 : Surface::kLengthMm;
    for (std::size_t i = 0; i <= n; ++i) {
      const double x = x0 + dir * dx * static_cast<double>(i);
      const double f1 = Surface::fx(x, y);
      const double kappa = std::abs(Surface::fxx(x, y)) / std::pow(1.0 + f1 * f1, 1.5);
      const double xm = x - 0.5 * dir * dx, fm = Surface::fx(xm, y);
      double v = curve_limit_mm_per_s(kappa, cap, l);
      if (i == 0 && k > 0) {  // the corner from the step-over into this pass
        const Vec3 over(0.0, Surface::kStepOverMm, Surface::f(x0, y) - Surface::f(x0, y - 0.5));
        v = std::min(v, corner_limit_mm_per_s(turn(over, Vec3(dir, 0.0, dir * f1)), p_mm, l));
      }
      lim.add(lim.s_mm.empty() ? 0.0 : (i == 0 ? 0.0 : dx * std::sqrt(1.0 + fm * fm)), v);
    }
    if (k + 1 == passes) break;
    const double x1 = x0 + dir * Surface::kLengthMm;
    const Vec3 over(0.0, Surface::kStepOverMm, Surface::f(x1, y + 0.5) - Surface::f(x1, y));
    const Vec3 tangent(dir, 0.0, dir * Surface::fx(x1, y));
    lim.v_mm_per_s.back() =
        std::min(lim.v_mm_per_s.back(), corner_limit_mm_per_s(turn(tangent, over), p_mm, l));
    lim.add_line(over.norm(), cap);  // the step-over (the next pass's corner lowers its end)
  }
  return lim;
}

// examples/surface-finish.ngc (scripts/surface_finish.py): the same surface finished by 7 passes
// (0.025 mm steps, 3 decimals: the bound does not depend on the step) under G64 P0.01: a 5 mm
// plunge at the feed from rest (the spindle start) onto the surface at the origin, the passes,
// then a 5 mm rapid up in Z at the machine's maximum feed to rest; the plunge and the rapid
// joined to the passes by the corner limit within P.
inline double surface_finish_bound_s(const feed::MachineLimits& l) {
  constexpr std::size_t kPasses = 7;
  const double p_mm = 0.01, y_last = Surface::kStepOverMm * static_cast<double>(kPasses - 1);
  const double cap = Surface::kFeed / 60.0;
  const auto turn_from_z = [](const Vec3& t) {  // the angle between t and +z
    return std::acos(std::clamp(t.normalized().z(), -1.0, 1.0));
  };
  ShapeLimit lim;
  lim.add(0.0, 0.0);
  lim.add_line(5.0, cap);  // the plunge, along −z
  const double into = kPi - turn_from_z(Vec3(1.0, 0.0, Surface::fx(0.0, 0.0)));
  lim.v_mm_per_s.back() = std::min(lim.v_mm_per_s.back(), corner_limit_mm_per_s(into, p_mm, l));
  const ShapeLimit passes = surface_limit(kPasses, p_mm, l);
  for (std::size_t i = 0; i < passes.s_mm.size(); ++i) {
    const double ds = i == 0 ? 0.0 : passes.s_mm[i] - passes.s_mm[i - 1];
    lim.add(ds,
            i == 0 ? std::min(lim.v_mm_per_s.back(), passes.v_mm_per_s[i]) : passes.v_mm_per_s[i]);
  }
  const double out = turn_from_z(Vec3(1.0, 0.0, Surface::fx(Surface::kLengthMm, y_last)));
  lim.v_mm_per_s.back() = std::min(lim.v_mm_per_s.back(), corner_limit_mm_per_s(out, p_mm, l));
  lim.add_line(5.0, l.max_feed_mm_per_min / 60.0);  // the retract
  return phase_plane_time_s(lim, l.max_accel_mm_per_s2, l.max_jerk_mm_per_s3);
}

}  // namespace ncd::test
