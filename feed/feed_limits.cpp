// Feed limits along a path (docs/feedrate.md §§1–3). The commanded feed at a point is the
// smallest of five speeds, each a closed form in the local curvature κ = 1/ρ and the contact
// inclination α:
//
//   roughness  f_t(R, α) z N / 60                 Choi's inverse law (paper 004, eqs. 5, 6)
//   chord      Δs_max / T,  Δs_max = 2 sqrt(2ρε − ε²)     sagitta of a chord of the osculating
//              circle ≤ ε (Yeh and Hsu, CAD 2002); for ε ≥ ρ every chord up to the diameter 2ρ
//              is within ε, so Δs_max = 2ρ there (the formula's value at ε = ρ)
//   accel      sqrt(a_max / κ)                    centripetal acceleration v² κ ≤ a_max
//   jerk       (j_max / κ²)^(1/3)                 centripetal jerk v³ κ² ≤ j_max (constant κ)
//   max feed   F_max / 60
//
//          chord Δs
//      ●━━━━━━━━━━━━━━━━●      ε = ρ − sqrt(ρ² − (Δs/2)²)
//       ╲ ε  ....      ╱
//         ╲.       . ╱   arc of radius ρ
//
// Under JerkBound::vector (docs/planner.md §3c) also the jerk-vector law: the speed at which the
// tangential scale σ that keeps |jerk| ≤ j_max falls to kMinTangentialScale, and the jump law
// 2 v sin(φ/2) / T² + 0.75 v² Δκ / T ≤ kJumpJerkShare j_max at corners and curvature jumps.
// Per-axis limits (docs/planner.md §3f), where the machine file gives [axis.x|y|z]: the axis
// speed min_i vmax_i / |t_i|, and on a curve the centripetal acceleration v² |k_i| and the
// centripetal jerk v³ κ² |t_i| of each axis held to (1 − kAxisTangentialShare) of its limit;
// the tangential acceleration and jerk of an interval are held to the axes' share by the
// planner (axis_scales()).
// On a straight line (κ = 0) only roughness and the maximum feed remain. The binding limit is
// reported with the speed; ties go to the first in enum order, so the report is deterministic.
#include "feed/feed_limits.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <utility>

#include "core/error.hpp"
#include "core/jerk_vector.hpp"
#include "core/number_text.hpp"

namespace ncd::feed {
namespace {

FeedLimitResult with_curvature(const MachineLimits& limits, double roughness_mm_per_s,
                               double curvature_per_mm) {
  FeedLimitResult best{roughness_mm_per_s, FeedLimit::Roughness};
  const auto consider = [&best](double feed_mm_per_s, FeedLimit limit) {
    if (feed_mm_per_s < best.feed_mm_per_s) best = {feed_mm_per_s, limit};
  };
  consider(chord_feed_mm_per_s(curvature_per_mm, limits.chord_tolerance_mm, limits.period_s),
           FeedLimit::Chord);
  consider(centripetal_accel_feed_mm_per_s(curvature_per_mm, limits.max_accel_mm_per_s2),
           FeedLimit::CentripetalAccel);
  consider(centripetal_jerk_feed_mm_per_s(curvature_per_mm, limits.max_jerk_mm_per_s3),
           FeedLimit::CentripetalJerk);
  consider(limits.max_feed_mm_per_min / 60.0, FeedLimit::MaxFeed);
  return best;
}

}  // namespace

bool AxisLimits::any() const {
  return std::isfinite(max_feed_mm_per_min) || std::isfinite(max_accel_mm_per_s2) ||
         std::isfinite(max_jerk_mm_per_s3);
}

bool MachineLimits::has_axis_limits() const {
  return axes[0].any() || axes[1].any() || axes[2].any();
}

bool MachineLimits::has_axis_jerk() const {
  return std::isfinite(axes[0].max_jerk_mm_per_s3) || std::isfinite(axes[1].max_jerk_mm_per_s3) ||
         std::isfinite(axes[2].max_jerk_mm_per_s3);
}

FeedLimitResult axis_feed_limit(const MachineLimits& limits, const Vec3& t, const Vec3& k) {
  FeedLimitResult r{kInf, FeedLimit::MaxFeed};
  const double kappa = k.norm(), keep = 1.0 - kAxisTangentialShare;
  for (int i = 0; i < 3; ++i) {
    const AxisLimits& ax = limits.axes[static_cast<std::size_t>(i)];
    const double ti = std::abs(t[i]), ki = std::abs(k[i]);
    if (ti > 0.0 && ax.max_feed_mm_per_min / 60.0 / ti < r.feed_mm_per_s) {
      r = {ax.max_feed_mm_per_min / 60.0 / ti, FeedLimit::MaxFeed};
    }
    if (ki > 0.0) {
      const double v = std::sqrt(keep * ax.max_accel_mm_per_s2 / ki);
      if (v < r.feed_mm_per_s) r = {v, FeedLimit::CentripetalAccel};
    }
    if (ti > 0.0 && kappa > 0.0) {
      const double v = std::cbrt(keep * ax.max_jerk_mm_per_s3 / (kappa * kappa * ti));
      if (v < r.feed_mm_per_s) r = {v, FeedLimit::CentripetalJerk};
    }
  }
  return r;
}

bool axis_laws_above(const MachineLimits& limits, const Vec3& t_abs, const Vec3& k_abs,
                     double kappa_per_mm, double v) {
  const double keep = 1.0 - kAxisTangentialShare;
  for (std::size_t i = 0; i < 3; ++i) {
    const AxisLimits& ax = limits.axes[i];
    const double ti = t_abs[static_cast<int>(i)], ki = k_abs[static_cast<int>(i)];
    if (ti > 0.0 && !(ax.max_feed_mm_per_min / 60.0 > v * ti)) return false;
    if (ki > 0.0 && !(keep * ax.max_accel_mm_per_s2 > v * v * ki)) return false;
    if (ti > 0.0 && kappa_per_mm > 0.0 &&
        !(keep * ax.max_jerk_mm_per_s3 > v * v * v * kappa_per_mm * kappa_per_mm * ti)) {
      return false;
    }
  }
  return true;
}

// The walker puts each setpoint on the planned arc length to feed_tolerance_rel of the
// period's step (docs/feedrate.md), so a second difference of the setpoints may differ from
// the planned motion's by 2 tol v T / T², a third by 4 tol v T / T³ (v up to the maximum
// feed): the axis limits the planner is given are lowered by that much (at most by half).
double axis_accel_for_planner(const MachineLimits& limits, std::size_t axis) {
  const double a = limits.axes[axis].max_accel_mm_per_s2;
  const double err =
      2.0 * limits.feed_tolerance_rel * limits.max_feed_mm_per_min / 60.0 / limits.period_s;
  return std::max(a - err, 0.5 * a);
}

double axis_jerk_for_planner(const MachineLimits& limits, std::size_t axis) {
  const double j = limits.axes[axis].max_jerk_mm_per_s3;
  const double err = 4.0 * limits.feed_tolerance_rel * limits.max_feed_mm_per_min / 60.0 /
                     (limits.period_s * limits.period_s);
  return std::max(j - err, 0.5 * j);
}

AxisScales axis_scales(const MachineLimits& limits, const Vec3& tangent_max,
                       const std::array<bool, 3>& bends, const Vec3& jerk_budget) {
  double a = limits.max_accel_mm_per_s2, j = limits.max_jerk_mm_per_s3;
  for (std::size_t i = 0; i < 3; ++i) {
    const auto I = static_cast<int>(i);
    const double ti = std::min(std::abs(tangent_max[I]), 1.0);
    if (!(ti > 0.0)) continue;
    const double share = bends[i] ? kAxisTangentialShare : 1.0;
    a = std::min(a, share * axis_accel_for_planner(limits, i) / ti);
    j = std::min(j, share * jerk_budget[I] * axis_jerk_for_planner(limits, i) / ti);
  }
  return {a / limits.max_accel_mm_per_s2, j / limits.max_jerk_mm_per_s3};
}

MachineLimits with_axis_jerk(const MachineLimits& limits) {
  bool any = false;
  double j = limits.max_jerk_mm_per_s3;
  for (const AxisLimits& ax : limits.axes) {
    if (!std::isfinite(ax.max_jerk_mm_per_s3)) continue;
    any = true;
    j = std::min(j, ax.max_jerk_mm_per_s3);
  }
  if (!any) return limits;
  MachineLimits out = limits;
  out.max_jerk_mm_per_s3 = j;
  out.jerk_bound = JerkBound::vector;
  return out;
}

AxisScales axis_scale_floor(const MachineLimits& limits) {
  return axis_scales(limits, Vec3(1.0, 1.0, 1.0), {true, true, true});
}

const char* to_string(FeedLimit limit) {
  switch (limit) {
    case FeedLimit::Roughness:
      return "roughness";
    case FeedLimit::Chord:
      return "chord";
    case FeedLimit::CentripetalAccel:
      return "centripetal_accel";
    case FeedLimit::CentripetalJerk:
      return "centripetal_jerk";
    case FeedLimit::MaxFeed:
      return "max_feed";
    case FeedLimit::Program:
      return "program";
    case FeedLimit::Corner:
      return "corner";
    case FeedLimit::JerkVector:
      return "jerk_vector";
  }
  return "unknown";
}

const char* to_string(JerkBound bound) {
  return bound == JerkBound::vector ? "vector" : "tangential";
}

void validate(const MachineLimits& limits) {
  using R = MachineLimitRanges;
  require_positive("period_s", limits.period_s);
  if (limits.period_s < R::kMinPeriodS || limits.period_s > R::kMaxPeriodS) {
    throw InputError("period_s = " + text::sig(limits.period_s) + " is outside [" +
                     text::sig(R::kMinPeriodS) + ", " + text::sig(R::kMaxPeriodS) +
                     "] s; interpolation periods are typically 0.001 to 0.01 s");
  }
  require_positive("max_feed_mm_per_min", limits.max_feed_mm_per_min);
  require_positive("max_accel_mm_per_s2", limits.max_accel_mm_per_s2);
  require_positive("max_jerk_mm_per_s3", limits.max_jerk_mm_per_s3);
  require_positive("chord_tolerance_mm", limits.chord_tolerance_mm);
  require_positive("feed_tolerance_rel", limits.feed_tolerance_rel);
  if (!(limits.blend_tolerance_mm >= 0.0 && limits.blend_tolerance_mm <= 10.0)) {
    throw InputError("blend_tolerance_mm = " + text::sig(limits.blend_tolerance_mm) +
                     " is outside [0, 10] mm: it is the corner deviation a plain G64 allows "
                     "(0: sharp corners); 0.01 is the default");
  }
  require_positive("stall_timeout_s", limits.stall_timeout_s);
  const char* axis_names[3] = {"x", "y", "z"};
  for (std::size_t i = 0; i < 3; ++i) {
    const AxisLimits& ax = limits.axes[i];
    const std::string at = std::string("axis.") + axis_names[i] + ".";
    for (const auto& [key, value] : {std::pair{"max_feed_mm_per_min", ax.max_feed_mm_per_min},
                                     std::pair{"max_accel_mm_per_s2", ax.max_accel_mm_per_s2},
                                     std::pair{"max_jerk_mm_per_s3", ax.max_jerk_mm_per_s3}}) {
      if (!(value > 0.0) || std::isnan(value)) {
        throw InputError(at + key + " = " + text::sig(value) +
                         " must be greater than 0; leave the key out for no limit of the axis's "
                         "own (the path limit then bounds it)");
      }
    }
  }
  if (limits.rotary.present()) {
    const RotaryLimits& r = limits.rotary;
    const std::string at = std::string("axis.") + r.axis + ".";
    for (const auto& [key, value] : {std::pair{"max_feed_deg_per_min", r.max_feed_deg_per_min},
                                     std::pair{"max_accel_deg_per_s2", r.max_accel_deg_per_s2},
                                     std::pair{"max_jerk_deg_per_s3", r.max_jerk_deg_per_s3}}) {
      if (!(value > 0.0) || !std::isfinite(value)) {
        throw InputError(at + key + " = " + text::sig(value) +
                         " must be a finite number greater than 0; leave the key out for its "
                         "default (config/machine.example.toml)");
      }
    }
  }
  if (limits.stall_timeout_s < 10.0 * limits.period_s) {
    throw InputError("stall_timeout_s = " + text::sig(limits.stall_timeout_s) +
                     " is shorter than 10 periods (" + text::sig(10.0 * limits.period_s) +
                     " s): the watchdog would fire at every stop; 2 s is the default");
  }
  if (limits.feed_tolerance_rel < R::kMinFeedToleranceRel ||
      limits.feed_tolerance_rel > R::kMaxFeedToleranceRel) {
    throw InputError("feed_tolerance_rel = " + text::sig(limits.feed_tolerance_rel) +
                     " is outside [" + text::sig(R::kMinFeedToleranceRel) + ", " +
                     text::sig(R::kMaxFeedToleranceRel) +
                     "]: below it double rounding cannot be corrected, above it the feed is "
                     "not controlled; 1e-10 is the default");
  }
}

double chord_step_mm(double curvature_per_mm, double chord_tolerance_mm) {
  if (!(curvature_per_mm > 0.0)) return kInf;
  const double rho = 1.0 / curvature_per_mm;
  const double eps = chord_tolerance_mm;
  if (eps >= rho) return 2.0 * rho;
  return 2.0 * std::sqrt(2.0 * rho * eps - eps * eps);
}

double chord_feed_mm_per_s(double curvature_per_mm, double chord_tolerance_mm, double period_s) {
  return chord_step_mm(curvature_per_mm, chord_tolerance_mm) / period_s;
}

double centripetal_accel_feed_mm_per_s(double curvature_per_mm, double max_accel_mm_per_s2) {
  if (!(curvature_per_mm > 0.0)) return kInf;
  return std::sqrt(max_accel_mm_per_s2 / curvature_per_mm);
}

double centripetal_jerk_feed_mm_per_s(double curvature_per_mm, double max_jerk_mm_per_s3) {
  if (!(curvature_per_mm > 0.0)) return kInf;
  return std::cbrt(max_jerk_mm_per_s3 / (curvature_per_mm * curvature_per_mm));
}

FeedLimitResult feed_limit(const MachineLimits& limits, const CuttingParams& cutting,
                           double curvature_per_mm, double inclination_rad) {
  return with_curvature(limits, roughness_feed_mm_per_s(cutting, inclination_rad),
                        curvature_per_mm);
}

FeedLimitResult curve_feed_limit(const MachineLimits& limits, double curvature_per_mm) {
  return with_curvature(limits, kInf, curvature_per_mm);  // MaxFeed is finite: never Roughness
}

double tangential_scale(const MachineLimits& limits, double kappa, double g, double v,
                        double budget) {
  return ncd::tangential_scale(JerkVectorSpan{kappa, g, budget}, v, limits.max_accel_mm_per_s2,
                               limits.max_jerk_mm_per_s3);
}

double jerk_vector_feed_mm_per_s(const MachineLimits& limits, double kappa, double g,
                                 double budget) {
  if (!(kappa > 0.0) && !(g > 0.0)) return kInf;
  // tangential_scale decreases in v: bisection on [0, hi] with hi past the crossing.
  const double target = kMinTangentialScale * budget;
  double lo = 0.0, hi = 1.0;
  while (tangential_scale(limits, kappa, g, hi, budget) >= target && hi < 1e9) {
    lo = hi;
    hi *= 2.0;
  }
  for (int it = 0; it < 80 && hi - lo > 1e-12 * hi; ++it) {
    const double mid = 0.5 * (lo + hi);
    (tangential_scale(limits, kappa, g, mid, budget) >= target ? lo : hi) = mid;
  }
  return lo;
}

// 2 v sin(φ/2) / T² + 0.75 v² Δκ / T = q J: the positive root in v.
double jump_feed_mm_per_s(const MachineLimits& limits, double phi, double dkappa) {
  const double T = limits.period_s;
  const double lin = 2.0 * std::sin(0.5 * std::max(phi, 0.0)) / (T * T);
  const double quad = 0.75 * std::max(dkappa, 0.0) / T;
  const double rhs = kJumpJerkShare * limits.max_jerk_mm_per_s3;
  if (!(lin > 0.0) && !(quad > 0.0)) return kInf;
  if (!(quad > 0.0)) return rhs / lin;
  return 2.0 * rhs / (lin + std::sqrt(lin * lin + 4.0 * quad * rhs));
}

double jump_jerk_mm_per_s3(const MachineLimits& limits, double phi, double dkappa, double v) {
  const double T = limits.period_s;
  return 2.0 * v * std::sin(0.5 * std::max(phi, 0.0)) / (T * T) +
         0.75 * v * v * std::max(dkappa, 0.0) / T;
}

// Per axis: |Δd_i| v / T² + 0.75 |Δk_i| v² / T = kJumpJerkShare j_i, the positive root in v.
double axis_jump_feed_mm_per_s(const MachineLimits& limits, const Vec3& dd, const Vec3& dk) {
  const double T = limits.period_s;
  double v = kInf;
  for (std::size_t i = 0; i < 3; ++i) {
    if (!std::isfinite(limits.axes[i].max_jerk_mm_per_s3)) continue;
    const auto I = static_cast<int>(i);
    const double lin = std::abs(dd[I]) / (T * T), quad = 0.75 * std::abs(dk[I]) / T;
    const double rhs = kJumpJerkShare * axis_jerk_for_planner(limits, i);
    if (!(lin > 0.0) && !(quad > 0.0)) continue;
    const double vi =
        quad > 0.0 ? 2.0 * rhs / (lin + std::sqrt(lin * lin + 4.0 * quad * rhs)) : rhs / lin;
    v = std::min(v, vi);
  }
  return v;
}

Vec3 axis_jump_shares(const MachineLimits& limits, const Vec3& dd, const Vec3& dk, double v) {
  const double T = limits.period_s;
  Vec3 share = Vec3::Zero();
  if (!(v > 0.0) || !std::isfinite(v)) return share;
  for (std::size_t i = 0; i < 3; ++i) {
    if (!std::isfinite(limits.axes[i].max_jerk_mm_per_s3)) continue;
    const auto I = static_cast<int>(i);
    const double j = std::abs(dd[I]) * v / (T * T) + 0.75 * std::abs(dk[I]) * v * v / T;
    share[I] = std::min(kJumpJerkShare, j / axis_jerk_for_planner(limits, i));
  }
  return share;
}

Vec3 curvature_vector_per_mm(const toolpath::CurvePoint& point) {
  const double speed2 = point.d1.squaredNorm();
  if (!(speed2 > 0.0)) return Vec3::Zero();
  return point.d1.cross(point.d2).cross(point.d1) / (speed2 * speed2);
}

double curvature_per_mm(const toolpath::CurvePoint& point) {
  const double speed = point.d1.norm();
  if (!(speed > 0.0)) return kInf;
  return point.d1.cross(point.d2).norm() / (speed * speed * speed);
}

FeedLimitResult feed_limit_at(const MachineLimits& limits, const CuttingParams& cutting,
                              const toolpath::CurvePoint& point) {
  return feed_limit(limits, cutting, curvature_per_mm(point),
                    inclination_from_tangent_rad(point.d1));
}

FeedLimitResult feed_limit_at(const MachineLimits& limits, const CuttingParams& cutting,
                              const toolpath::CurvePoint& point, const Vec3& contact_normal,
                              const Vec3& tool_axis) {
  return feed_limit(limits, cutting, curvature_per_mm(point),
                    inclination_from_normal_rad(contact_normal, point.d1, tool_axis));
}

}  // namespace ncd::feed
