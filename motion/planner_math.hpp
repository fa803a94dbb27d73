// The planner's pure math, apart from its state (as LinuxCNC keeps blendmath.c beside tp.c):
// time-optimal velocity changes under a_max and j_max (a ramp, a hold, a ramp), their distance,
// one period's jerk towards them, and runs of constant-jerk phases; and the tuning constants
// the planner's files share. The planner is explained at the top of planner.cpp.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace ncd::motion::planner_math {

inline constexpr int kBisection = 10;       // bisection steps for the largest safe jerk
inline constexpr double kRelSlack = 1e-12;  // rounding slack on v and a checks (relative)
inline constexpr double kBlocksPerWindow = 48.0;

inline double clampj(double j, double j_max) {
  return std::clamp(j, -j_max, j_max);
}

inline constexpr double kFinalJerk = 0.9;  // final ramp at 0.9 j_max: the slack absorbs sampling
// π's second member (the top of planner.cpp, 1): it settles this fraction below a demanding block's
// level, its final ramp at kUnderFinalJerk j_max (docs/planner.md §4, "The undershooting member").
inline constexpr double kUndershoot = 0.025;
inline constexpr double kUnderFinalJerk = 0.95;
inline constexpr double kLandJerk =
    0.99;  // a landing's ramps: room for its minimum-norm correction

// Time-optimal velocity change from (v0, a0) to (w, a = 0) in the decreasing direction: a ramp
// at −j1 to a_p, a hold at a_p (>= −a_max), a final ramp at +j3 to a = 0.
struct Profile {
  double t1, t2, t3, ap;
};
inline Profile decrease_profile(double v0, double a0, double w, double a_max, double j1,
                                double j3) {
  const double k = 0.5 / j1 + 0.5 / j3;
  const double excess = v0 - w + 0.5 * a0 * a0 / j1;
  double ap = -std::sqrt(std::max(excess / k, 0.0));
  double t2 = 0.0;
  if (ap < -a_max) {
    ap = -a_max;
    t2 = std::max((excess - a_max * a_max * k) / a_max, 0.0);
  }
  if (ap > a0) {  // already braking harder than needed: hold a0, then the final ramp
    return Profile{0.0, std::max((v0 - w - 0.5 * a0 * a0 / j3) / -a0, 0.0), -a0 / j3, a0};
  }
  return Profile{(a0 - ap) / j1, t2, -ap / j3, ap};
}

// True when (v0, a0) must decrease its speed to settle on w.
inline bool decreasing(double v0, double a0, double w, double j1, double j3) {
  return (a0 > 0.0 ? v0 + 0.5 * a0 * a0 / j1 : v0 - 0.5 * a0 * a0 / j3) > w;
}

// Distance of the decreasing profile from (v0, a0) down to (w, 0), ramps at j1 and j3; 0 if none
// is needed.
inline double profile_distance(double v0, double a0, double w, double a_max, double j1, double j3) {
  if (!decreasing(v0, a0, w, j1, j3)) return 0.0;
  const Profile p = decrease_profile(v0, a0, w, a_max, j1, j3);
  const double t1 = p.t1, t2 = p.t2, t3 = p.t3, ap = p.ap;
  const double d1 = v0 * t1 + 0.5 * a0 * t1 * t1 - j1 * t1 * t1 * t1 / 6.0;
  const double v1 = v0 + a0 * t1 - 0.5 * j1 * t1 * t1;
  const double d2 = v1 * t2 + 0.5 * ap * t2 * t2;
  const double v2 = v1 + ap * t2;
  const double d3 = v2 * t3 + 0.5 * ap * t3 * t3 + j3 * t3 * t3 * t3 / 6.0;
  return d1 + d2 + d3;
}

// One period's jerk towards (w, 0) in the decreasing direction: the period average of the
// profile, or, once its final ramp starts within the period, the jerk that lands exactly on
// the final-ramp parabola v − w = a² / (2 j3) at the period end.
inline double decrease_jerk(double v0, double a0, double w, double T, double a_max, double j_max,
                            double final_jerk) {
  const double j3 = final_jerk * j_max;
  const Profile p = decrease_profile(v0, a0, w, a_max, j_max, j3);
  if (p.t1 + p.t2 < T) {
    const double disc = j3 * j3 * T * T + 4.0 * j3 * a0 * T + 8.0 * j3 * (v0 - w);
    if (disc >= j3 * j3 * T * T) {
      const double a1 = 0.5 * (j3 * T - std::sqrt(disc));
      return std::clamp((a1 - a0) / T, -j_max, j_max);
    }
    return j_max;
  }
  double a1 = p.ap;
  if (T < p.t1) a1 = a0 - j_max * T;
  return std::clamp((a1 - a0) / T, -j_max, j_max);
}

// A piece of constant jerk.
struct Phase {
  double t_s, j;
};

// The time-optimal change from (v0, a0) to (w, 0), both ramps at jl, as three phases (a ramp, a
// hold, a ramp), in whichever direction it goes.
inline void change_phases(double v0, double a0, double w, double a_max, double jl, Phase* out) {
  const double sg = decreasing(v0, a0, w, jl, jl) ? 1.0 : -1.0;
  const Profile p = decrease_profile(sg * v0, sg * a0, sg * w, a_max, jl, jl);
  out[0] = Phase{p.t1, -sg * jl};
  out[1] = Phase{p.t2, 0.0};
  out[2] = Phase{p.t3, sg * jl};
}

// Runs phases from (v, a) (s from 0); returns the distance, adds the time to *t_s.
inline double run_phases(const Phase* ph, int n, double v, double a, double* t_s) {
  double s = 0.0;
  for (int i = 0; i < n; ++i) {
    const double t = ph[i].t_s, j = ph[i].j;
    s += t * (v + t * (0.5 * a + t * j / 6.0));
    v += t * (a + 0.5 * j * t);
    a += j * t;
    *t_s += t;
  }
  return s;
}

// The period averages of piecewise-constant jerk phases (from t = 0, cut at n T) into out[0, n):
// a landing base whose acceleration is the profile's own at every period end.
inline void average_phases(const Phase* ph, int count, std::size_t n, double T, double* out) {
  std::fill(out, out + n, 0.0);
  double begin = 0.0;
  for (int k = 0; k < count; ++k) {
    const double end = begin + ph[k].t_s;
    for (auto i = static_cast<std::size_t>(begin / T); i < n && static_cast<double>(i) * T < end;
         ++i) {
      const double lo = std::max(begin, static_cast<double>(i) * T);
      const double hi = std::min(end, static_cast<double>(i + 1) * T);
      if (hi > lo) out[i] += ph[k].j * (hi - lo) / T;
    }
    begin = end;
  }
}

}  // namespace ncd::motion::planner_math
