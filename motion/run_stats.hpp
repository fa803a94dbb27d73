// What a run did, in numbers, accumulated setpoint by setpoint in fixed memory.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "core/histogram.hpp"
#include "motion/job.hpp"

namespace ncd::motion {

inline constexpr double kViolationRel = 1e-6;  // a limit is violated beyond this relative excess
// Relative feed error is taken over steps of at least 1 µm: below that (the first and last
// periods of a ramp from or to rest) the ratio measures the rounding of the path length
// (≈1e-13 mm), not the interpolator; those steps count in the absolute maximum.
inline constexpr double kFeedErrorMinStepMm = 1e-3;

// The arc-length drift a run may end with: |Σ true arc − path length| ≤ this + the walker's
// relative tolerance × length (docs/hardening.md, "Accepting a run").
inline constexpr double kDriftToleranceMm = 1e-3;

// Which jerk bound the planner enforces (docs/planner.md §3c), for the reports.
inline const char* jerk_bound_in_force(feed::JerkBound bound) {
  return bound == feed::JerkBound::vector
             ? "vector: the jerk vector |d3p/dt3| <= j_max on curves and at curvature jumps "
               "(tangential limits scaled where a curve needs it), across runs of polyline "
               "pieces shorter than one period's travel (their discrete curvature and its "
               "jumps), and the setpoints' direction change at a corner passed without a stop"
             : "tangential jerk |j_t| <= j_max and centripetal jerk v^3 kappa^2 <= j_max, each; "
               "the jerk vector (jerk_vector_max) is measured, not bounded";
}

struct RunStats {
  std::int64_t cycles = 0;
  double duration_s = 0.0;
  double path_length_mm = 0.0;
  double travelled_mm = 0.0;
  double travelled_carry_mm = 0.0;     // Neumaier compensation: Σ over 1e6 periods stays exact
  double feed_error_max_rel = 0.0;     // |true arc − planned Δs| / Δs, worst step ≥ 1 µm
  double feed_error_max_abs_mm = 0.0;  // |true arc − planned Δs|, worst step of all
  double feed_error_sum_sq = 0.0;      // for the RMS
  std::int64_t feed_error_steps = 0;
  double chord_error_max_mm = 0.0;
  double accel_max_mm_per_s2 = 0.0;  // tangential
  double jerk_max_mm_per_s3 = 0.0;   // tangential (the planner's j, bounded by j_max)
  // The jerk the axes feel: |p_k − 3 p_k−1 + 3 p_k−2 − p_k−3| / T³ from the setpoints, the
  // largest so far. Not bounded by j_max (docs/planner.md §3c): on a curve it adds v³κ² and
  // 3 v a κ to the tangential jerk. last_p_mm holds the three previous setpoints.
  double jerk_vector_max_mm_per_s3 = 0.0;
  std::array<Vec3, 3> last_p_mm{};
  // Per axis (X, Y, Z), from the setpoints' differences: the largest |Δp_i|/T, |Δ²p_i|/T² and
  // |Δ³p_i|/T³ (docs/planner.md §3f).
  std::array<double, 3> axis_feed_max_mm_per_s{}, axis_accel_max_mm_per_s2{},
      axis_jerk_max_mm_per_s3{};
  // The rotary index axis (docs/planner.md §3g): indexes made, the time spent in them, and the
  // axis's peaks from the setpoints' differences (|Δr|/T, |Δ²r|/T², |Δ³r|/T³), degrees.
  std::int64_t index_moves = 0;
  double index_time_s = 0.0;
  std::array<double, 3> last_rotary_deg{};
  double rotary_speed_max_deg_per_s = 0.0, rotary_accel_max_deg_per_s2 = 0.0,
         rotary_jerk_max_deg_per_s3 = 0.0;
  std::int64_t violations_rotary = 0;
  bool was_indexing = false;
  // Set with last_rotary_deg by a caller that knows where the axis stands before the first
  // period (the path's rotary_start_deg); else the first setpoint's position is taken.
  bool rotary_started = false;  // periods where a rotary peak exceeds its limit
  double feed_max_mm_per_s = 0.0;
  double roughness_max_um = 0.0;
  std::int64_t violations_feed = 0, violations_accel = 0, violations_jerk = 0, violations_chord = 0;
  std::int64_t not_converged = 0;
  std::array<std::int64_t, 256> cycles_by_limit{};
  LogHistogram step_time_ns;

  double feed_error_rms_rel() const;
  std::int64_t limit_violations() const;
  double drift_mm() const { return (travelled_mm - path_length_mm) + travelled_carry_mm; }
};

// One axis's peaks against its own limits (+inf where the machine file gives none), for the
// reports; ratio: the largest of peak / limit over the three (0 without limits).
struct AxisPeak {
  char axis;
  double feed_mm_per_min, accel_mm_per_s2, jerk_mm_per_s3;
  double feed_limit_mm_per_min, accel_limit_mm_per_s2, jerk_limit_mm_per_s3;
  double feed_ratio() const { return feed_mm_per_min / feed_limit_mm_per_min; }
  double accel_ratio() const { return accel_mm_per_s2 / accel_limit_mm_per_s2; }
  double jerk_ratio() const { return jerk_mm_per_s3 / jerk_limit_mm_per_s3; }
};
std::array<AxisPeak, 3> axis_peaks(const RunStats& stats, const feed::MachineLimits& limits);
// The replay report's "axis_peaks": per axis, each peak and its limit (null: none).
nlohmann::ordered_json axis_peaks_json(const RunStats& stats, const feed::MachineLimits& limits);
// The replay's text lines for them ("" without per-axis limits in the machine file).
std::string axis_peaks_text(const RunStats& stats, const feed::MachineLimits& limits);

// The rotary axis's line of the replay report ("" without one), and its JSON ("rotary_axis").
std::string rotary_text(const RunStats& stats, const feed::MachineLimits& limits);
nlohmann::ordered_json rotary_json(const RunStats& stats, const feed::MachineLimits& limits);

// Why a finished run must not reach a machine: any limit violation (feed, acceleration, jerk,
// chord) or an arc-length drift beyond kDriftToleranceMm; empty when it may. The one
// acceptance rule of replay and of its tests.
std::string refusal(const RunStats& stats, const JobConfig& config);

// Adds one period: the setpoint, the continuous feed limit and the predicted roughness at its
// position, and the wall time the step took.
void record(RunStats& stats, const JobConfig& config, const Setpoint& sp, double limit_mm_per_s,
            double roughness_um, double step_time_ns);

}  // namespace ncd::motion
