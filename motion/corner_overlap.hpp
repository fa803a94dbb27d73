// Passing a sharp corner without its stop: the end of one move and the start of the next,
// superposed in time (docs/planner.md §3b). Plain data in, a period count out; no allocation.
#pragma once

#include <array>
#include <limits>

#include <cstddef>
#include <span>

#include "core/geometry.hpp"
#include "feed/corner_blend.hpp"

namespace ncd::motion {

// One setpoint of the stream the overlap works on: where it stands, and the 1-D motion along
// the path that made it (the planner's s, v, a at the end of the period, and the jerk during
// it). `raw`: the planner's own setpoint, not yet part of an overlap.
struct OverlapSample {
  Vec3 p_mm = Vec3::Zero();
  double s_mm = 0.0, v_mm_per_s = 0.0, a_mm_per_s2 = 0.0, j_mm_per_s3 = 0.0;
  double v_limit_mm_per_s = 0.0;  // the move's feed limit there (the planner's limit curve)
  bool raw = true;
  double chord_error_mm = 0.0;  // overlap_setpoints' result: the period's chord error
};

inline constexpr double kNoAxisLimit = std::numeric_limits<double>::infinity();

struct OverlapLimits {
  double period_s = 0.004;
  double max_feed_mm_per_s = 100.0;
  double max_accel_mm_per_s2 = 1000.0;     // |Δ²p|/T² of the result
  double max_jerk_vector_mm_per_s3 = 2e4;  // |Δ³p|/T³ of the result
  double chord_tolerance_mm = 0.001;       // the continuous motion against each chord
  // Per-axis limits (docs/planner.md §3f): each axis's |Δp_i|/T, |Δ²p_i|/T², |Δ³p_i|/T³ of the
  // result (+inf: none).
  std::array<double, 3> axis_feed_mm_per_s{kNoAxisLimit, kNoAxisLimit, kNoAxisLimit};
  std::array<double, 3> axis_accel_mm_per_s2{kNoAxisLimit, kNoAxisLimit, kNoAxisLimit};
  std::array<double, 3> axis_jerk_mm_per_s3{kNoAxisLimit, kNoAxisLimit, kNoAxisLimit};
};

// The most periods m ≤ m_max by which the motion that rests at the corner at w[rest] may be
// overlapped with the motion that leaves it: the m setpoints before the rest and the m after
// it become the m − 1 setpoints w[rest − m + k] + w[rest + k] − V (k = 1 … m − 1), and every
// limit holds on the result: speed, acceleration vector and jerk vector by differences of the
// setpoints (three on each side of the window included), the speed of each superposed period
// (its mean |Δp|/T and its speed at every instant) within both moves' feed limits there (the
// slower of the two), every setpoint, chord midpoint and
// point of the continuous motion within the corner's tolerance of its two pieces, and the
// continuous motion within the chord tolerance of each chord. 0 if none does. The samples
// used must be raw, on the corner's straight pieces, and inside w.
int longest_overlap(const feed::SharpCorner& corner, const OverlapLimits& limits,
                    std::span<const OverlapSample> w, std::size_t rest, int m_max);

// The m setpoints that replace w[rest − m + 1 … rest + m] under longest_overlap's rule:
// w[rest − m + k] + w[rest + k] − V for k = 1 … m (the last is w[rest + m] itself), and each
// period's chord error (out has m room). Their s is the sum of the two motions' progress (it
// grows as both do), v the speed of the superposed motion, and a and j the larger in
// magnitude of the two moves' own: each move keeps its tangential limits.
void overlap_setpoints(const feed::SharpCorner& corner, double period_s,
                       std::span<const OverlapSample> w, std::size_t rest, int m,
                       std::span<OverlapSample> out);

// The distance of p from the corner's two pieces (each as long as SharpCorner says), mm.
double corner_distance_mm(const feed::SharpCorner& corner, const Vec3& p_mm);

inline constexpr int kMaxOverlapPeriods = 16;  // the longest overlap tried, periods

// The largest overlap the acceleration limit leaves room for: the end of a stop and the start
// of a move are jerk ramps, whose accelerations add up to j_max · m T ≤ a_max (+1), in
// [1, kMaxOverlapPeriods].
int overlap_periods_max(double max_accel_mm_per_s2, double max_jerk_mm_per_s3, double period_s);

}  // namespace ncd::motion
