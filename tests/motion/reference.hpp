// Independent references for the planner tests, written here from first principles (not from
// motion/ or interpolator/): the time-optimal jerk-limited rest-to-rest move along a line in
// closed form, a NURBS point by Cox–de Boor, and the programmed geometry of a Path as a dense table
// of (s, point) for nearest-point and chord checks.
#pragma once

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <vector>

#include "core/geometry.hpp"
#include "geometry/path.hpp"

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

// A lower bound on the duration of any motion along a velocity-limit profile with |a| ≤ A and
// |jerk| ≤ J, from rest at s[0] to rest at s.back(): the profile V(s) must already hold the
// acceleration (the phase plane's forward and backward passes), V[0] = V.back() = 0.
//
// The phase plane alone lets the acceleration jump from −A to +A at the bottom of every dip
// of V, from 0 to A at the rest ends, and from A to 0 onto a top; here the jerk is counted
// there. Pick pivots: the rest ends, where (v, a) = (0, 0), and the bottoms of the dips of V,
// where the motion's state is some (v0 ≤ V, a0 ∈ [−A, A]). Split the path between consecutive
// pivots. From a pivot, any motion's acceleration τ later is at most min(A, a0 + J τ), and τ
// earlier its deceleration is at most min(A, −a0 + J τ) (|jerk| ≤ J), and either is at most
// √(2J (U − v)) (U below); the fastest such motion that keeps v ≤ V(s) (accelerating at that
// cap, or along V where V binds: in one dimension under an upper bound v ≤ V(s) and a cap that
// grows with time and falls with speed, it is ahead at every instant) reaches the split points in a
// time that no motion beats. So the duration is at least the sum, over pivots, of the fastest
// backward and forward times to the neighbouring splits, minimised over the unknown a0 at interior
// pivots (the forward time falls and the backward time rises with a0, so a grid of a0 bounds the
// minimum from below: forward at the upper and backward at the lower end of each cell; 200
// cells by default). Every choice of pivots and splits gives a valid bound, so the splits are those
// that make it largest: the arrival times of the fastest motions are recorded at about 500
// candidate splits per stretch, and a coordinate ascent from the tops of V moves each split to
// where the two pivots around it add up most (a split at the top lets the motion from one side
// arrive there at the top speed while the other is still climbing; on a line whose top lies below
// the cap the best split is where the two meet, and the bound reaches the all-jerk ratio 0.909 of
// the optimum, where a split at the top gave 0.77). A dip is a pivot where V rises by at least
// 5 % on both sides. The integration in time (step dt_s) is numerical, like the phase plane's.
// One stretch of the bound: from one split to the next (the path's ends for the first and the
// last); any motion spends at least time_s between them.
struct BoundStretch {
  double begin_mm, end_mm, time_s;
};

inline double jerk_pivot_bound_s(const std::vector<double>& s, const std::vector<double>& V,
                                 double A, double J, double dt_s = 5e-6,
                                 std::vector<BoundStretch>* stretches = nullptr, int cells = 200) {
  const std::size_t n = s.size();
  // The top within reach: U[k] = max V over s[k] ± V_top A / J. Whatever the motion's
  // acceleration a, |jerk| ≤ J keeps its sign for |a|/J ≤ A/J more: for a > 0 the speed still
  // rises by a²/2J, for a < 0 it was a²/2J higher |a|/J ago, within V_top A / J of travel; so
  // v + a²/2J ≤ U(s), a cap |a| ≤ √(2J (U − v)) (the S-curve's own ramp onto its top).
  const double v_top = *std::max_element(V.begin(), V.end());
  const double reach_mm = v_top * A / J;
  std::vector<double> U(n);
  {
    std::deque<std::size_t> window;  // indices of a falling run of V: the front is the maximum
    std::size_t hi = 0;
    for (std::size_t k = 0, lo = 0; k < n; ++k) {
      for (; hi < n && s[hi] <= s[k] + reach_mm; ++hi) {
        while (!window.empty() && V[window.back()] <= V[hi]) window.pop_back();
        window.push_back(hi);
      }
      for (; s[lo] < s[k] - reach_mm; ++lo) {
        if (window.front() == lo) window.pop_front();
      }
      U[k] = V[window.front()];
    }
  }
  // The fastest motion from pivot i towards index `to`, with v0 = V[i] and the acceleration cap
  // min(A, a_start + J τ) in its own direction of travel: the time at which it reaches each
  // index of `at` (ordered away from i, the last one `to`) goes to out (where it parks for
  // good, V = 0 over a cell, the time it ran: a lower bound too).
  const auto fastest_s = [&](std::size_t i, std::size_t to, double a_start,
                             const std::vector<std::size_t>& at, std::vector<double>& out) {
    out.assign(at.size(), 0.0);
    const int dir = to > i ? 1 : -1;
    std::size_t k = i;     // cell index: position between s[k] and s[k + dir]
    std::size_t next = 0;  // the next index of `at` to reach
    double x = 0.0, v = V[i], t = 0.0;
    const auto limit_at = [&](double dist) {
      while (k != to && std::abs(s[k + static_cast<std::size_t>(dir)] - s[i]) < dist) {
        k = dir > 0 ? k + 1 : k - 1;
      }
      // The larger end of the cell: V between samples is not below both (a concave V near
      // rest, √(2 A d), would be cut by a chord).
      return k == to ? V[to] : std::max(V[k], V[dir > 0 ? k + 1 : k - 1]);
    };
    while (next < at.size() && t < 1e4) {  // (V = 0 over a cell never ends)
      const double top = std::max(U[k], U[k == to ? k : dir > 0 ? k + 1 : k - 1]);
      const double cap =
          std::min({A, a_start + J * (t + dt_s), std::sqrt(2.0 * J * std::max(0.0, top - v))});
      double v1 = std::max(0.0, v + cap * dt_s);
      const double step = 0.5 * (v + v1) * dt_s;
      v1 = std::min(v1, limit_at(x + step));
      const double step1 = 0.5 * (v + v1) * dt_s;
      // Every index of `at` this step reaches: the time within the step at the mean speed.
      while (next < at.size() && x + step1 >= std::abs(s[at[next]] - s[i])) {
        const double v_mid = 0.5 * (v + v1), gap = std::abs(s[at[next]] - s[i]) - x;
        out[next++] = t + (v_mid > 0.0 ? gap / v_mid : dt_s);
      }
      if (step1 <= 0.0 && cap <= 0.0 && v <= 0.0) {  // parked: wait for the cap to turn
        t += dt_s;
        continue;
      }
      x += step1;
      v = v1;
      t += dt_s;
    }
    for (; next < at.size(); ++next) out[next] = t;  // never reached: the time so far bounds it
  };
  // Pivots: the ends and the prominent dips.
  std::vector<std::size_t> pivots{0};
  for (std::size_t i = 1; i + 1 < n; ++i) {
    if (!(V[i] < V[i - 1] && V[i] <= V[i + 1])) continue;
    const double rise = 1.05 * V[i];
    bool left = false, right = false;
    for (std::size_t k = i; k-- > pivots.back() && V[k] >= V[i] && !left;) left = V[k] >= rise;
    for (std::size_t k = i + 1; k < n && V[k] >= V[i] && !right; ++k) right = V[k] >= rise;
    if (left && right) pivots.push_back(i);
  }
  pivots.push_back(n - 1);
  // Candidate splits between consecutive pivots (about 500 each), and the arrival times of the
  // fastest motions from both pivots there: fwd[p][c][m] from pivot p (its a0 cell c) forward
  // to candidate m of stretch p, bwd[p][c][m] from pivot p + 1 backward to it. The ends have
  // a0 = 0 only (cell 0). Interior pivots take the a0 grid: the forward time falls and the
  // backward time rises with a0, so a grid bounds the minimum over a0 from below (forward at
  // the upper and backward at the lower end of each cell).
  const int kCells = cells;
  const std::size_t stretches_n = pivots.size() - 1;
  std::vector<std::vector<std::size_t>> cand(stretches_n);
  for (std::size_t p = 0; p < stretches_n; ++p) {
    const std::size_t lo = pivots[p] + 1, hi = pivots[p + 1];
    const std::size_t stride = std::max<std::size_t>(1, (hi - lo) / 500);
    for (std::size_t k = lo; k < hi; k += stride) cand[p].push_back(k);
    if (cand[p].empty()) cand[p].push_back(std::min(lo, hi));
  }
  using Table = std::vector<std::vector<std::vector<double>>>;  // [stretch][cell][candidate]
  Table fwd(stretches_n), bwd(stretches_n);
  for (std::size_t p = 0; p < stretches_n; ++p) {
    const bool end_before = p == 0, end_after = p + 1 == stretches_n;
    std::vector<std::size_t> back(cand[p].rbegin(), cand[p].rend());
    fwd[p].resize(end_before ? 1 : kCells + 1);
    bwd[p].resize(end_after ? 1 : kCells + 1);
    for (std::size_t c = 0; c < fwd[p].size(); ++c) {
      const double a0 = end_before ? 0.0 : -A + 2.0 * A * static_cast<double>(c) / kCells;
      fastest_s(pivots[p], cand[p].back(), a0, cand[p], fwd[p][c]);
    }
    for (std::size_t c = 0; c < bwd[p].size(); ++c) {
      const double a0 = end_after ? 0.0 : -A + 2.0 * A * static_cast<double>(c) / kCells;
      fastest_s(pivots[p + 1], cand[p].front(), -a0, back, bwd[p][c]);
      std::reverse(bwd[p][c].begin(), bwd[p][c].end());
    }
  }
  // The bound at pivot q (its time from the split before it, index mb of stretch q − 1, to the
  // split after it, index mf of stretch q), minimised over its a0.
  const auto pivot_s = [&](std::size_t q, std::size_t mb, std::size_t mf) {
    if (q == 0) return fwd[0][0][mf];
    if (q == stretches_n) return bwd[q - 1][0][mb];
    double least = std::numeric_limits<double>::infinity();
    for (int c = 0; c < kCells; ++c) least = std::min(least, fwd[q][c + 1][mf] + bwd[q - 1][c][mb]);
    return least;
  };
  // Every choice of splits gives a valid bound: take the one that maximises it (coordinate
  // ascent from the tops of V; each split moves the pivots on its two sides).
  std::vector<std::size_t> split(stretches_n);
  for (std::size_t p = 0; p < stretches_n; ++p) {
    std::size_t best = 0;
    for (std::size_t m = 0; m < cand[p].size(); ++m)
      if (V[cand[p][m]] > V[cand[p][best]]) best = m;
    split[p] = best;
  }
  const auto around = [&](std::size_t p, std::size_t m) {  // the two pivots split p touches
    return pivot_s(p, p == 0 ? 0 : split[p - 1], m) +
           pivot_s(p + 1, m, p + 1 < stretches_n ? split[p + 1] : 0);
  };
  for (int sweep = 0; sweep < 4; ++sweep) {
    for (std::size_t p = 0; p < stretches_n; ++p) {
      for (std::size_t m = 0; m < cand[p].size(); ++m)
        if (around(p, m) > around(p, split[p])) split[p] = m;
    }
  }
  double total = 0.0;
  if (stretches) stretches->clear();
  for (std::size_t q = 0; q <= stretches_n; ++q) {
    const std::size_t mb = q == 0 ? 0 : split[q - 1], mf = q < stretches_n ? split[q] : 0;
    const double t_q = pivot_s(q, mb, mf);
    total += t_q;
    if (stretches) {
      const double b = q == 0 ? s.front() : s[cand[q - 1][mb]];
      const double e = q == stretches_n ? s.back() : s[cand[q][mf]];
      stretches->push_back({b, e, t_q});
    }
  }
  return total;
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
