// The jerk-vector bound of a motion along a curve (docs/planner.md §3c), shared by the limit
// sampler (interpolator/) and the planner (motion/). Along a path with curvature κ whose
// curvature vector turns at g = |κ' N + κ τ B| (1/mm²), a motion at speed v with tangential
// acceleration a and jerk j has
//
//     jerk = (j − v³κ²) T + (3 v a κ + v³ κ') N + v³ κ τ B,
//     |jerk|² ≤ (|j| + v³κ²)² + (3 v |a| κ + v³ g)².
#pragma once

#include <algorithm>
#include <cmath>

namespace ncd {

// The curve data one interval of the limit curve carries for the bound.
struct JerkVectorSpan {
  double curvature_per_mm = 0.0;  // largest κ
  double turn_per_mm2 = 0.0;      // largest g
  double budget = 1.0;            // fraction of j_max the smooth motion may use (a curvature
                                  // jump nearby takes the rest)
};

// True when |j| and |a| at speeds up to v keep the bound within budget × j_max.
inline bool jerk_vector_within(const JerkVectorSpan& c, double v, double a, double j, double j_max,
                               double rel_slack = 0.0) {
  const double v3 = v * v * v, k = c.curvature_per_mm;
  const double t = std::abs(j) + v3 * k * k;
  const double n = 3.0 * v * std::abs(a) * k + v3 * c.turn_per_mm2;
  const double lim = c.budget * j_max * (1.0 + rel_slack);
  return t * t + n * n <= lim * lim;
}

// The largest σ in [0, 1] such that |a| ≤ σ a_max and |j| ≤ σ j_max keep the bound at every
// speed up to v: (σ J + c1)² + (σ b + c2)² = (budget J)², c1 = v³κ², b = 3 v A κ, c2 = v³ g,
// the larger root; 0 if none.
inline double tangential_scale(const JerkVectorSpan& c, double v, double a_max, double j_max) {
  const double k = c.curvature_per_mm, g = c.turn_per_mm2;
  if (!(k > 0.0) && !(g > 0.0)) return std::clamp(c.budget, 0.0, 1.0);
  if (!std::isfinite(v)) return 0.0;
  const double v3 = v * v * v;
  const double c1 = v3 * k * k, b = 3.0 * v * a_max * k, c2 = v3 * g;
  const double r2 = c.budget * c.budget * j_max * j_max;
  const double qa = j_max * j_max + b * b, qb = j_max * c1 + b * c2, qc = c1 * c1 + c2 * c2 - r2;
  if (qc >= 0.0) return 0.0;
  return std::clamp((-qb + std::sqrt(qb * qb - qa * qc)) / qa, 0.0, 1.0);
}

}  // namespace ncd
