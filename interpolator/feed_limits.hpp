// The feed limit at one point of a path: the smallest of the roughness law (paper 004), the
// chord error, the centripetal acceleration and jerk, and the machine's maximum feed
// (docs/feedrate.md §3), with the name of the limit that binds. Explained in feed_limits.cpp.
// Pure functions, no allocation: the planner samples them along the path.
#pragma once

#include <string>

#include "core/geometry.hpp"
#include "interpolator/roughness.hpp"
#include "toolpath/curve.hpp"

namespace ncd::interpolator {

// Which limit binds; on a tie the first in this order is reported. Program (the F word of the
// program) and Corner (a polyline vertex or a joint between segments) are applied by the
// limit sampler along a path (limit_sampler.hpp), not by feed_limit().
enum class FeedLimit {
  Roughness,
  Chord,
  CentripetalAccel,
  CentripetalJerk,
  MaxFeed,
  Program,
  Corner
};
inline constexpr int kFeedLimitCount = 7;

// "roughness", "chord", "centripetal_accel", "centripetal_jerk", "max_feed", "program",
// "corner".
const char* to_string(FeedLimit limit);

// Machine and interpolation limits. Defaults are literature values (docs/feedrate.md §3): a_max in
// 500–3000 mm/s², j_max in 2e4–6e4 mm/s³, a 1 µm chord tolerance, a 4 ms period.
struct MachineLimits {
  double period_s = 0.004;              // T, the interpolation period
  double max_feed_mm_per_min = 6000.0;  // machine maximum feed (100 mm/s)
  double max_accel_mm_per_s2 = 1000.0;  // a_max, here for the centripetal part
  double max_jerk_mm_per_s3 = 2e4;      // j_max, here for the centripetal part
  double chord_tolerance_mm = 0.001;    // ε_c between the chord of a period and the curve
  double feed_tolerance_rel = 1e-10;    // |arc travelled − Δs| / Δs the walker corrects to
  double blend_tolerance_mm = 0.01;     // corner deviation allowed without G64 P
  double stall_timeout_s = 2.0;         // the cycle's no-progress watchdog (motion/cycle.cpp)
};

// Ranges that make MachineLimits valid, shared by validation and its messages.
struct MachineLimitRanges {
  static constexpr double kMinPeriodS = 1e-5;
  static constexpr double kMaxPeriodS = 1.0;
  static constexpr double kMinFeedToleranceRel = 1e-14;  // below it double rounding dominates
  static constexpr double kMaxFeedToleranceRel = 1e-2;
};

// Throws InputError naming the value, the limit and a way out.
void validate(const MachineLimits& limits);

struct FeedLimitResult {
  double feed_mm_per_s = 0.0;
  FeedLimit limit = FeedLimit::MaxFeed;
};

// Largest step Δs whose chord stays within ε of a circle of curvature κ (Yeh and Hsu), mm;
// +inf on a straight line, the diameter 2ρ once ε ≥ ρ.
double chord_step_mm(double curvature_per_mm, double chord_tolerance_mm);
// Δs_max / T, mm/s.
double chord_feed_mm_per_s(double curvature_per_mm, double chord_tolerance_mm, double period_s);
// sqrt(a_max / κ), mm/s; +inf at κ = 0.
double centripetal_accel_feed_mm_per_s(double curvature_per_mm, double max_accel_mm_per_s2);
// (j_max / κ²)^(1/3), mm/s; +inf at κ = 0.
double centripetal_jerk_feed_mm_per_s(double curvature_per_mm, double max_jerk_mm_per_s3);

// The minimum of every limit at a point of curvature κ and contact inclination α. Both structs
// must have passed validate().
FeedLimitResult feed_limit(const MachineLimits& limits, const CuttingParams& cutting,
                           double curvature_per_mm, double inclination_rad);

// Curvature |P' × P''| / |P'|³ of a curve point, 1/mm; +inf where P' = 0 (a cusp: stop).
double curvature_per_mm(const toolpath::CurvePoint& point);
// feed_limit with κ from the point and α = asin(t_z) of its tangent (3-axis ball end).
FeedLimitResult feed_limit_at(const MachineLimits& limits, const CuttingParams& cutting,
                              const toolpath::CurvePoint& point);
// feed_limit with κ from the point and α from a contact normal (see roughness.hpp).
FeedLimitResult feed_limit_at(const MachineLimits& limits, const CuttingParams& cutting,
                              const toolpath::CurvePoint& point, const Vec3& contact_normal,
                              const Vec3& tool_axis = Vec3::UnitZ());

}  // namespace ncd::interpolator
