// Independent references for the planner tests, written here from first principles (not from
// motion/ or interpolator/): the time-optimal jerk-limited rest-to-rest move along a line in
// closed form, a NURBS point by Cox–de Boor, and the programmed geometry of a Path as a dense table
// of (s, point) for nearest-point and chord checks.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "core/geometry.hpp"
#include "toolpath/path.hpp"

namespace ncd::test {

// The B-spline basis function N_{i,p}(u) by the Cox–de Boor recursion (The NURBS Book, eq. 2.5),
// written here without the library's algorithm A2.3; the last span is closed at its end.
inline double nurbs_basis(const std::vector<double>& U, std::size_t i, int p, double u) {
  if (p == 0) {
    const bool last = U[i + 1] == U.back() && u == U.back() && U[i] < U[i + 1];
    return (U[i] <= u && u < U[i + 1]) || last ? 1.0 : 0.0;
  }
  const auto pz = static_cast<std::size_t>(p);
  double b = 0.0;
  if (U[i + pz] > U[i]) b += (u - U[i]) / (U[i + pz] - U[i]) * nurbs_basis(U, i, p - 1, u);
  if (U[i + pz + 1] > U[i + 1]) {
    b += (U[i + pz + 1] - u) / (U[i + pz + 1] - U[i + 1]) * nurbs_basis(U, i + 1, p - 1, u);
  }
  return b;
}

// A NURBS point from the basis functions: Σ N_i w_i P_i / Σ N_i w_i.
inline Vec3 nurbs_point(const toolpath::NurbsCurve& c, double u) {
  Vec3 a = Vec3::Zero();
  double w = 0.0;
  for (std::size_t i = 0; i < c.points().size(); ++i) {
    const double b = nurbs_basis(c.knots(), i, c.degree(), u) * c.weights()[i];
    a += b * c.points()[i];
    w += b;
  }
  return a / w;
}

// Shortest time of a rest-to-rest move of length d under |v| <= v, |a| <= a, |j| <= j (the
// symmetric seven-phase S-curve; phases vanish when the distance is short).
inline double scurve_time_s(double d, double v, double a, double j) {
  if (d <= 0.0) return 0.0;
  // Time and distance to reach speed w from rest and come back to a = 0.
  const auto ramp_t = [&](double w) {
    return w >= a * a / j ? w / a + a / j : 2.0 * std::sqrt(w / j);
  };
  const double t_full = ramp_t(v);
  const double d_full = v * t_full;  // accelerate to v and brake from it: 2 × (v t / 2)
  if (d_full <= d) return 2.0 * t_full + (d - d_full) / v;
  // Peak speed w < v with w · ramp_t(w) = d: increasing in w, bisect.
  double lo = 0.0, hi = v;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (mid * ramp_t(mid) < d ? lo : hi) = mid;
  }
  return 2.0 * ramp_t(0.5 * (lo + hi));
}

// The programmed geometry: points along the path with their arc length. Polyline vertices
// exactly; NURBS sampled about every `step_mm` of arc.
struct GeometryTable {
  std::vector<double> s_mm;
  std::vector<Vec3> p;
};

inline GeometryTable tabulate(const toolpath::Path& path, double step_mm = 0.0025) {
  GeometryTable t;
  const auto add = [&](const Vec3& q) {
    t.s_mm.push_back(t.p.empty() ? 0.0 : t.s_mm.back() + (q - t.p.back()).norm());
    t.p.push_back(q);
  };
  for (const auto& seg : path.segments) {
    if (const auto* line = std::get_if<toolpath::Polyline>(&seg.geometry)) {
      for (const auto& q : line->points) add(q);
      continue;
    }
    const auto& c = std::get<toolpath::NurbsCurve>(seg.geometry);
    const auto bp = c.breakpoints();
    for (std::size_t i = 0; i + 1 < bp.size(); ++i) {
      const double u0 = bp[i], u1 = bp[i + 1];
      if (!(u1 > u0)) continue;
      double rough = 0.0;
      for (int k = 0; k < 32; ++k) {
        rough += (c.eval(u0 + (u1 - u0) * (k + 1) / 32.0).p - c.eval(u0 + (u1 - u0) * k / 32.0).p)
                     .norm();
      }
      const int n = std::clamp(static_cast<int>(rough / step_mm), 64, 1000000);
      // Arc length between samples by 3-point Gauss–Legendre on |P'| (not the chord, whose
      // shortfall would add up along the path and shift the table against the setpoints' s).
      const auto speed = [&c](double u) { return c.eval(u).d1.norm(); };
      double u_prev = u0;
      for (int k = 0; k <= n; ++k) {
        const double u = k == n ? u1 : u0 + (u1 - u0) * k / n;
        const Vec3 q = c.eval(u).p;
        if (t.p.empty()) {
          t.s_mm.push_back(0.0);
        } else {
          const double h = 0.5 * (u - u_prev), m = 0.5 * (u + u_prev), g = std::sqrt(0.6);
          const double arc =
              h * (5.0 * speed(m - g * h) + 8.0 * speed(m) + 5.0 * speed(m + g * h)) / 9.0;
          t.s_mm.push_back(t.s_mm.back() + arc);
        }
        t.p.push_back(q);
        u_prev = u;
      }
    }
  }
  return t;
}

// Distance from q to the segment [a, b].
inline double distance_to_segment(const Vec3& q, const Vec3& a, const Vec3& b) {
  const Vec3 d = b - a;
  const double len2 = d.squaredNorm();
  const double f = len2 > 0.0 ? std::clamp((q - a).dot(d) / len2, 0.0, 1.0) : 0.0;
  return (q - (a + f * d)).norm();
}

// Distance from q to the programmed geometry near arc length s (searched within ±window).
inline double distance_to_path(const GeometryTable& t, const Vec3& q, double s_mm,
                               double window_mm) {
  const auto lo = std::lower_bound(t.s_mm.begin(), t.s_mm.end(), s_mm - window_mm);
  const auto hi = std::upper_bound(t.s_mm.begin(), t.s_mm.end(), s_mm + window_mm);
  std::size_t i0 = static_cast<std::size_t>(lo - t.s_mm.begin());
  std::size_t i1 = static_cast<std::size_t>(hi - t.s_mm.begin());
  if (i0 > 0) --i0;
  i1 = std::min(i1, t.p.size() - 1);
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = i0; i < i1; ++i)
    best = std::min(best, distance_to_segment(q, t.p[i], t.p[i + 1]));
  if (i0 == i1) best = (q - t.p[i0]).norm();
  return best;
}

}  // namespace ncd::test
