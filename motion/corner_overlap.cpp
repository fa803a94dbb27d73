// Corner overlap (docs/planner.md §3b).
//
// At a sharp corner V that the planner passes with a full stop, the motion along the piece in
// (direction d_in) ends as r(t), the distance still to go, and the motion along the piece out
// starts as q(t), the distance gone. With a stop they follow each other. Overlapping them by
// τ = m T, the tool moves along
//
//     p(t) = V − r(t) d_in + q(t − (t_rest − τ)) d_out,
//
// LinuxCNC's old parabolic blend and the superposition of two axes' own motions. Near rest
// both are jerk ramps, r = J (τ − t)³/6 and q = J t³/6, so the path is a cubic Bézier with
// control points V − L d_in, V, V, V + L d_out (L = J τ³/6): curvature 0 at both ends, and its
// distance from the pieces, min(r, q) sin φ, is largest at t = τ/2 (J τ³ sin φ / 48). The time
// saved is τ. Its jerk vector during the overlap is J (d_in + d_out), of length 2 J cos(φ/2):
// within J for turns of 120° and more (0.52 J at 150°), √2 J at 90°.
//
// The rule here does not rely on those closed forms. It works on the setpoints the planner
// made, which are exact samples of r and q, and takes the longest overlap whose result keeps,
// measured on the setpoints themselves:
//   - every setpoint and chord midpoint, and the continuous motion at the quarter points of
//     each period, within the move's G64 P of the two pieces;
//   - the vertex (the programmed end point) within P of a chord of the result: the superposed
//     path's apex lies farther from the vertex than from the pieces, by 1 / cos(φ/2);
//   - the continuous motion within the chord tolerance of each period's chord;
//   - |Δp|/T ≤ the maximum feed, |Δ²p|/T² ≤ a_max, |Δ³p|/T³ ≤ the jerk-vector limit, over the
//     window and three setpoints on each side of it;
//   - in each superposed period |Δp|/T, and the superposed speed |v_in d_in + v_out d_out| at
//     every instant of it, within the feed limit of both moves there: the sum of two motions is
//     never faster than the slower move allows (a cut's F word holds while the rapid after it
//     starts). The instant's speed is bounded by the corners of the box of both moves' speed
//     ranges in the period (its square is convex in them); the mean alone let the setpoint's
//     speed pass the limit by 6e-6 (16.6667651 mm/s against the F word's 16.6666667:
//     pipeline fuzzer finding overlap_speed_above_limit).
// The jerk-vector limit is j_max under jerk_bound = "vector" and √2 j_max under "tangential"
// (two components each within j_max, as the property tests bound the acceleration vector by
// √2 a_max there); the Job passes it. The candidates are tried from the longest down.
#include "motion/corner_overlap.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace ncd::motion {
namespace {

using feed::SharpCorner;

double segment_distance_mm(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (p - a - t * ab).norm();
}

// The 1-D motion h seconds into the period that ends at w[k]: the cubic from w[k − 1]'s state
// and w[k]'s jerk.
double s_within(std::span<const OverlapSample> w, std::size_t k, double h) {
  const OverlapSample& x = w[k - 1];
  return x.s_mm + h * (x.v_mm_per_s + h * (0.5 * x.a_mm_per_s2 + h * w[k].j_mm_per_s3 / 6.0));
}

Vec3 superposed(const SharpCorner& c, double s_rest, double s_in, double s_out) {
  return c.vertex_mm - (s_rest - s_in) * c.d_in + (s_out - s_rest) * c.d_out;
}

// The highest speed of the 1-D motion during the period that ends at w[k]: v(h) is a quadratic
// in h, largest at an end or at h = −a/j.
double period_top_speed(std::span<const OverlapSample> w, std::size_t k, double T) {
  const OverlapSample& x = w[k - 1];
  const double j = w[k].j_mm_per_s3;
  const auto v = [&](double h) { return x.v_mm_per_s + h * (x.a_mm_per_s2 + 0.5 * h * j); };
  double top = std::max(v(0.0), v(T));
  if (j != 0.0) {
    const double h = -x.a_mm_per_s2 / j;
    if (h > 0.0 && h < T) top = std::max(top, v(h));
  }
  return top;
}

// A bound on the superposed speed |v_in d_in + v_out d_out| at every instant of a period in
// which the two speeds lie in [0, x] and [0, y]: its square v_in² + v_out² + 2 v_in v_out c
// (c = d_in · d_out) is convex in (v_in, v_out) for |c| ≤ 1, so its largest value on that box
// is at a corner of it: x², y² or x² + y² + 2xyc.
double superposed_top_speed(double x, double y, double c) {
  x = std::max(x, 0.0), y = std::max(y, 0.0);
  return std::sqrt(std::max({x * x, y * y, x * x + y * y + 2.0 * x * y * c}));
}

bool feasible(const SharpCorner& c, const OverlapLimits& l, std::span<const OverlapSample> w,
              std::size_t rest, int m) {
  const auto mu = static_cast<std::size_t>(m);
  if (rest < mu + 3 || rest + mu + 3 >= w.size()) return false;
  const double s_rest = w[rest].s_mm;
  for (std::size_t k = 0; k <= mu; ++k) {
    if (!w[rest - k].raw || !w[rest + k].raw) return false;
  }
  if (s_rest - w[rest - mu].s_mm > c.in_mm || w[rest + mu].s_mm - s_rest > c.out_mm) return false;
  // The result over the window and three setpoints on each side.
  std::array<Vec3, 2 * kMaxOverlapPeriods + 8> q;
  const std::size_t n = mu + 7;
  for (std::size_t i = 0; i < 3; ++i) q[i] = w[rest - mu - 3 + i].p_mm;
  for (std::size_t k = 0; k <= mu; ++k)
    q[3 + k] = w[rest - mu + k].p_mm + w[rest + k].p_mm - c.vertex_mm;
  for (std::size_t i = 1; i <= 3; ++i) q[3 + mu + i] = w[rest + mu + i].p_mm;
  const double T = l.period_s;
  const double tol = c.tolerance_mm;
  for (std::size_t i = 1; i < n; ++i) {
    if (!((q[i] - q[i - 1]).norm() <= l.max_feed_mm_per_s * T)) return false;
    if (i >= 2 && !((q[i] - 2.0 * q[i - 1] + q[i - 2]).norm() <= l.max_accel_mm_per_s2 * T * T)) {
      return false;
    }
    if (i >= 3 && !((q[i] - 3.0 * q[i - 1] + 3.0 * q[i - 2] - q[i - 3]).norm() <=
                    l.max_jerk_vector_mm_per_s3 * T * T * T)) {
      return false;
    }
    for (int a = 0; a < 3; ++a) {  // per-axis limits
      const auto ai = static_cast<std::size_t>(a);
      if (!(std::abs(q[i][a] - q[i - 1][a]) <= l.axis_feed_mm_per_s[ai] * T)) return false;
      if (i >= 2 && !(std::abs(q[i][a] - 2.0 * q[i - 1][a] + q[i - 2][a]) <=
                      l.axis_accel_mm_per_s2[ai] * T * T)) {
        return false;
      }
      if (i >= 3 && !(std::abs(q[i][a] - 3.0 * q[i - 1][a] + 3.0 * q[i - 2][a] - q[i - 3][a]) <=
                      l.axis_jerk_mm_per_s3[ai] * T * T * T)) {
        return false;
      }
    }
  }
  // The periods that end at the superposed setpoints k = 1 … m.
  for (std::size_t k = 1; k <= mu; ++k) {
    const Vec3 &a = q[3 + k - 1], &b = q[3 + k];
    const double v_limit =
        std::min({w[rest - mu + k - 1].v_limit_mm_per_s, w[rest - mu + k].v_limit_mm_per_s,
                  w[rest + k - 1].v_limit_mm_per_s, w[rest + k].v_limit_mm_per_s});
    if (!((b - a).norm() <= v_limit * T)) return false;
    // The speed itself, not only the period's mean: at every instant of the period (a cut's
    // F word and the limit curve bound the speed, as the planner holds them on a raw motion).
    const double top = superposed_top_speed(period_top_speed(w, rest - mu + k, T),
                                            period_top_speed(w, rest + k, T), c.d_in.dot(c.d_out));
    if (!(top <= v_limit)) return false;
    if (!(corner_distance_mm(c, b) <= tol) || !(corner_distance_mm(c, 0.5 * (a + b)) <= tol)) {
      return false;
    }
    for (const double f : {0.25, 0.5, 0.75}) {
      const Vec3 x =
          superposed(c, s_rest, s_within(w, rest - mu + k, f * T), s_within(w, rest + k, f * T));
      if (!(corner_distance_mm(c, x) <= tol)) return false;
      if (!(segment_distance_mm(x, a, b) <= l.chord_tolerance_mm)) return false;
    }
  }
  // The programmed end point, the vertex, is passed within P: by a chord of the setpoints, the
  // line the machine interpolates between them.
  double to_vertex = std::numeric_limits<double>::infinity();
  for (std::size_t i = 1; i < n; ++i) {
    to_vertex = std::min(to_vertex, segment_distance_mm(c.vertex_mm, q[i - 1], q[i]));
  }
  return to_vertex <= tol;
}

}  // namespace

double corner_distance_mm(const SharpCorner& c, const Vec3& p_mm) {
  return std::min(segment_distance_mm(p_mm, c.vertex_mm - c.in_mm * c.d_in, c.vertex_mm),
                  segment_distance_mm(p_mm, c.vertex_mm, c.vertex_mm + c.out_mm * c.d_out));
}

int overlap_periods_max(double max_accel_mm_per_s2, double max_jerk_mm_per_s3, double period_s) {
  const double m = std::ceil(max_accel_mm_per_s2 / (max_jerk_mm_per_s3 * period_s)) + 1.0;
  return static_cast<int>(std::clamp(std::isfinite(m) ? m : 1.0, 1.0, double{kMaxOverlapPeriods}));
}

int longest_overlap(const SharpCorner& corner, const OverlapLimits& limits,
                    std::span<const OverlapSample> w, std::size_t rest, int m_max) {
  for (int m = std::min(m_max, kMaxOverlapPeriods); m >= 1; --m) {
    if (feasible(corner, limits, w, rest, m)) return m;
  }
  return 0;
}

void overlap_setpoints(const SharpCorner& corner, double period_s, std::span<const OverlapSample> w,
                       std::size_t rest, int m, std::span<OverlapSample> out) {
  const double s_rest = w[rest].s_mm;
  const auto mu = static_cast<std::size_t>(m);
  Vec3 before = w[rest - mu].p_mm;
  for (std::size_t k = 1; k <= mu; ++k) {
    const OverlapSample &in = w[rest - mu + k], &go = w[rest + k];
    OverlapSample& o = out[k - 1];
    o.p_mm = in.p_mm + go.p_mm - corner.vertex_mm;
    o.chord_error_mm = 0.0;
    for (const double f : {0.25, 0.5, 0.75}) {
      const double h = f * period_s;
      const Vec3 x =
          superposed(corner, s_rest, s_within(w, rest - mu + k, h), s_within(w, rest + k, h));
      o.chord_error_mm = std::max(o.chord_error_mm, segment_distance_mm(x, before, o.p_mm));
    }
    before = o.p_mm;
    o.s_mm = in.s_mm + go.s_mm - s_rest;
    o.v_mm_per_s = (in.v_mm_per_s * corner.d_in + go.v_mm_per_s * corner.d_out).norm();
    const auto larger = [](double x, double y) { return std::abs(x) >= std::abs(y) ? x : y; };
    o.a_mm_per_s2 = larger(in.a_mm_per_s2, go.a_mm_per_s2);
    o.j_mm_per_s3 = larger(in.j_mm_per_s3, go.j_mm_per_s3);
    o.raw = false;
  }
}

}  // namespace ncd::motion
