// The feed limit at one point of a path: the smallest of the roughness law (paper 004), the
// chord error, the centripetal acceleration and jerk, and the machine's maximum feed
// (docs/feedrate.md §3), with the name of the limit that binds. Explained in feed_limits.cpp.
// Pure functions, no allocation: the planner samples them along the path.
#pragma once

#include <algorithm>
#include <array>
#include <limits>
#include <string>

#include "core/geometry.hpp"
#include "feed/roughness.hpp"
#include "geometry/curve.hpp"
#include "geometry/path.hpp"

namespace ncd::feed {

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
  Corner,
  JerkVector
};
inline constexpr int kFeedLimitCount = 8;

// "roughness", "chord", "centripetal_accel", "centripetal_jerk", "max_feed", "program",
// "corner", "jerk_vector".
const char* to_string(FeedLimit limit);

// Which jerk the limits bound (docs/planner.md §3c). tangential: |d³s/dt³| ≤ j_max and
// v³κ² ≤ j_max, each on its own. vector: the jerk vector |d³p/dt³| ≤ j_max on curves and at
// curvature jumps, and the direction change of the setpoints at a corner passed without a stop.
enum class JerkBound { tangential, vector };
const char* to_string(JerkBound bound);  // "tangential", "vector"

// One axis's own limits (the machine file's [axis.x], [axis.y], [axis.z]; docs/planner.md §3f).
// +inf: not given, the axis is bounded by the path limits only.
struct AxisLimits {
  double max_feed_mm_per_min = std::numeric_limits<double>::infinity();
  double max_accel_mm_per_s2 = std::numeric_limits<double>::infinity();
  double max_jerk_mm_per_s3 = std::numeric_limits<double>::infinity();
  bool any() const;
};

// The rotary index axis (the machine file's [axis.a] or [axis.b]; docs/planner.md §3g): which it
// is ('a': about X, RS-274's A; 'b': about Y, B; 0: the machine has none) and its own limits in
// degrees. It only indexes: the part is turned between cuts, rest to rest, while X, Y and Z stand
// still (motion/rotary_index.hpp); the path limits above do not apply to it.
struct RotaryLimits {
  char axis = 0;
  double max_feed_deg_per_min = 3600.0;  // 10 rev/min, a common rotary table's rapid
  double max_accel_deg_per_s2 = 1800.0;
  double max_jerk_deg_per_s3 = 36000.0;
  bool present() const { return axis != 0; }
};

// The share of an axis's acceleration (and jerk) that the curve laws leave to the tangential
// motion where a curve moves that axis normally (docs/planner.md §3f): the centripetal part is
// held to (1 − share) of the axis's limit, so the planner keeps at least share of it.
inline constexpr double kAxisTangentialShare = 0.5;
// Per-axis jerk limits on a curve (docs/planner.md §3f): the lowest fraction of its acceleration
// scale an interval may ask of the planner so that the cross term 3 v a k_i of an axis's jerk
// stays within its budget, before its speed is lowered instead.
inline constexpr double kMinAxisAccelFactor = 0.3;

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
  // Dense runs of short G1 moves under G64 P (no Q) fitted by a curve within P − ε_c
  // (feed/polyline_fit.cpp, docs/planner.md §3d); false: only a program's G64 Q fits.
  bool fit_dense_runs = true;
  JerkBound jerk_bound = JerkBound::tangential;
  std::array<AxisLimits, 3> axes{};  // X, Y, Z; the path limits above stay a further cap
  RotaryLimits rotary;               // the rotary index axis, if the machine has one
  bool has_axis_limits() const;
  bool has_axis_jerk() const;  // some [axis.*] max_jerk_mm_per_s3 is given
};

// Under JerkBound::vector (docs/planner.md §3c): the share of j_max a curvature jump or a
// corner's direction change may take of the third difference of the setpoints (the rest is
// left to the motion around it), and the lowest tangential scale a curve may ask of the planner
// (times its budget, 1 − the share of a jump nearby) before its speed is lowered instead.
inline constexpr double kJumpJerkShare = 0.5;
inline constexpr double kMinTangentialScale = 0.3;
// The lowest tangential scale the sampler ever gives: what the planner sizes its look-ahead for.
inline constexpr double kTangentialScaleFloor = kMinTangentialScale * (1.0 - kJumpJerkShare);

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

// Per-axis limits (docs/planner.md §3f) at a point with unit tangent t and curvature vector k
// (κ N): the axis speed min_i vmax_i / |t_i| (reported as MaxFeed), and where the curve bends,
// the centripetal acceleration v² |k_i| ≤ (1 − kAxisTangentialShare) a_i and the centripetal
// jerk v³ κ |k_i| ... see feed_limits.cpp; +inf (MaxFeed) without axis limits.
FeedLimitResult axis_feed_limit(const MachineLimits& limits, const Vec3& unit_tangent,
                                const Vec3& curvature_vector_per_mm);
// Whether every law of axis_feed_limit is above v with |t_i|, |k_i| and κ given separately
// (each law falls as they grow: at bounds of them over a stretch, whether axis_feed_limit is
// above v all over it; the flat-interval test). Compared as v, v² and v³: no root is taken.
bool axis_laws_above(const MachineLimits& limits, const Vec3& tangent_abs,
                     const Vec3& curvature_abs_per_mm, double curvature_per_mm, double v);
// The tangential acceleration and jerk the axes allow on a stretch whose unit tangent has
// components at most tangent_max[i] and which bends an axis where bends[i] (then that axis keeps
// kAxisTangentialShare of its limit for the tangential motion): as fractions of the path's
// a_max and j_max, each in (0, 1].
struct AxisScales {
  double accel = 1.0, jerk = 1.0;
};
// jerk_budget[i] (≤ 1): the fraction of axis i's jerk left to the motion near a jump that takes
// the rest (axis_jump_shares()).
AxisScales axis_scales(const MachineLimits& limits, const Vec3& tangent_max,
                       const std::array<bool, 3>& bends, const Vec3& jerk_budget = Vec3::Ones());
// An axis's acceleration and jerk as the planner is given them: the machine file's, lowered by
// what the walker's arc-length tolerance may add to the setpoints' differences (+inf: none).
double axis_accel_for_planner(const MachineLimits& limits, std::size_t axis);
double axis_jerk_for_planner(const MachineLimits& limits, std::size_t axis);
// The lowest scales axis_scales() can give (tangent components of 1, every axis bent): what the
// planner sizes its look-ahead for.
AxisScales axis_scale_floor(const MachineLimits& limits);
// The limits a job is planned under when an axis has a jerk limit (docs/planner.md §3f): the
// jerk vector bounded (jerk_bound = vector) by min(j_max, min_i j_i). Each axis's jerk is a
// component of that vector, so it stays within its own limit wherever the vector bound holds,
// curvature jumps included; the price is that every direction gets the slowest axis's jerk.
// Without axis jerk limits the limits are returned as they are.
MachineLimits with_axis_jerk(const MachineLimits& limits);

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

// Jerk vector bound (docs/planner.md §3c). On a curve of curvature κ whose curvature vector
// turns at |κ' N + κ τ B| = g (1/mm²), a motion with v ≤ v_max, |a_t| ≤ σ a_max and
// |j_t| ≤ σ j_max has |jerk| ≤ sqrt((σ J + v³κ²)² + (3 v σ A κ + v³ g)²). The largest σ in
// [0, 1] that keeps it ≤ budget × j_max at v_max; 0 if none does.
double tangential_scale(const MachineLimits& limits, double curvature_per_mm,
                        double curvature_turn_per_mm2, double v_max_mm_per_s,
                        double budget_fraction = 1.0);
// The speed at which tangential_scale() reaches kMinTangentialScale × budget (+inf on a line).
double jerk_vector_feed_mm_per_s(const MachineLimits& limits, double curvature_per_mm,
                                 double curvature_turn_per_mm2, double budget_fraction = 1.0);
// A corner passed at speed v without a stop: the velocity turns by φ (a jump of 2 v sin(φ/2))
// and the acceleration jumps by v² Δκ where the curvature vector jumps by Δκ. The third
// difference of the setpoints sees at most 2 v sin(φ/2) / T² + 0.75 v² Δκ / T; the largest v
// that keeps it ≤ kJumpJerkShare j_max (+inf where neither turns).
double jump_feed_mm_per_s(const MachineLimits& limits, double phi_rad,
                          double curvature_jump_per_mm);
// That third difference at speed v: 2 v sin(φ/2) / T² + 0.75 v² Δκ / T, mm/s³.
double jump_jerk_mm_per_s3(const MachineLimits& limits, double phi_rad,
                           double curvature_jump_per_mm, double v_mm_per_s);

// Per-axis jerk at jumps (docs/planner.md §3f), where an axis has a jerk limit: a corner passed
// at speed v without a stop changes the unit direction by Δd (velocity jump v Δd) and the
// curvature vector by Δk (acceleration jump v² Δk). Axis i's third difference of the setpoints
// sees at most v |Δd_i| / T² + 0.75 v² |Δk_i| / T (the vector law of jump_jerk_mm_per_s3 per
// component). The largest v that keeps it ≤ kJumpJerkShare of every axis's jerk (as the planner
// is given it, axis_jerk_for_planner); +inf where no axis with a jerk limit jumps.
double axis_jump_feed_mm_per_s(const MachineLimits& limits, const Vec3& direction_jump,
                               const Vec3& curvature_jump_per_mm);
// The share of each axis's jerk those jumps take at speed v (≤ kJumpJerkShare; 0 on an axis
// without a jerk limit): the motion within two periods' travel keeps the rest.
Vec3 axis_jump_shares(const MachineLimits& limits, const Vec3& direction_jump,
                      const Vec3& curvature_jump_per_mm, double v_mm_per_s);

// Curvature |P' × P''| / |P'|³ of a curve point, 1/mm; +inf where P' = 0 (a cusp: stop).
double curvature_per_mm(const toolpath::CurvePoint& point);
// Curvature vector κ N = (P' × P'') × P' / |P'|⁴ (zero where P' = 0).
Vec3 curvature_vector_per_mm(const toolpath::CurvePoint& point);
// feed_limit for a tool the roughness law does not model (geometry/tool.hpp: a flat or bull-nose
// end mill, a drill, a tool of no stated kind): the curve laws and the machine's maximum.
FeedLimitResult curve_feed_limit(const MachineLimits& limits, double curvature_per_mm);

// feed_limit with κ from the point and α = asin(t_z) of its tangent (3-axis ball end).
FeedLimitResult feed_limit_at(const MachineLimits& limits, const CuttingParams& cutting,
                              const toolpath::CurvePoint& point);
// feed_limit with κ from the point and α from a contact normal (see roughness.hpp).
FeedLimitResult feed_limit_at(const MachineLimits& limits, const CuttingParams& cutting,
                              const toolpath::CurvePoint& point, const Vec3& contact_normal,
                              const Vec3& tool_axis = Vec3::UnitZ());

// Below this turn a joint of two pieces is straight, not a corner (the sampler and the blends).
inline constexpr double kMinTurnRad = 1e-9;

// The speed a segment may not exceed, mm/s: the machine's maximum feed, and the programmed feed
// of a move that is not a rapid.
inline double segment_cap_mm_per_s(const toolpath::PathSegment& s, const MachineLimits& l) {
  double c = l.max_feed_mm_per_min / 60.0;
  if (!s.rapid && s.feed_mm_per_min) c = std::min(c, *s.feed_mm_per_min / 60.0);
  return c;
}

}  // namespace ncd::feed
