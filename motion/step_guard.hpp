// The step rule: the last check a setpoint passes before it leaves a job (docs/hardening.md,
// "The step rule"). Whatever the planner and the walker did, a setpoint k is emitted only if
//
//   (1) speed:        Δs_k ≤ v_max·T·(1 + m) + ε,        v_max = max feed × max(1, override)
//   (2) acceleration: |Δs_k − Δs_{k−1}| ≤ a_max·T²·(1 + m) + ε
//   (3) walk:         |p_k − p_{k−1}| ≤ Δs_k·(1 + m) + ε
//
// with Δs_k the planned arc length of period k (the planner's s(t+T) − s(t)), p_k the position,
// T the period, m = kStepMarginRel and ε = kStepSlackMm. In a period of a corner passed
// without its stop (docs/planner.md §3b) two moves run at once along straight pieces d_in and
// d_out, and Δs_k is the length of their superposed planned step, |Δs_in d_in + Δs_out d_out|
// (the job passes it): the setpoint's s sums both moves' progress, up to twice the step at a
// turn of more than 90°, and the sum refused correct overlaps (a pipeline fuzzer finding,
// 0.01136 mm against 0.01104). The overlap's own rule holds |Δp| ≤ v_max T and
// |Δ²p| ≤ a_max T² there, which give (1) and (2) for that step (| |u| − |w| | ≤ |u − w|). (2) holds
// for any motion whose tangential acceleration stays within a_max: the second difference of s over
// spacing T is a(ξ)·T² for some ξ (mean value theorem). (3) holds because a chord is never longer
// than its arc, and the walker makes the arc equal to Δs within feed_tolerance_rel ≤ 1e-2 < m. So a
// setpoint that fails any of them is a fault of the computation, never of the input: the job
// stops there, that setpoint is not emitted, and the caller reports the fault (exit 3 in
// `ncd replay`, state "error" in the service). The chord tolerance is a limit of the finish,
// not of the machine, and the feed override scales it with the limit curve: it is checked when
// a run is accepted (motion::refusal), not here. The check is a few multiplications: no
// allocation, no exception, a result code.
#pragma once

#include <cmath>
#include <cstdint>

#include "core/geometry.hpp"

namespace ncd::motion {

inline constexpr double kStepMarginRel = 0.02;  // m: 2 % above the bound
inline constexpr double kStepSlackMm = 1e-6;    // ε: 1 nm, the setpoint file's resolution

// Speed, Acceleration, Walk: the step rule above. Plan: the look-ahead could not go on (a limit
// sample the planner refused, a zero limit inside a stretch, a stretch it could not restart);
// the job's, not the guard's (motion/job.hpp), reported through the same channel.
enum class StepFault : std::uint8_t { None, Speed, Acceleration, Walk, Plan };

// "speed", "acceleration", "walk", "plan"; "none".
const char* to_string(StepFault fault);

struct StepBounds {
  double max_feed_mm_per_s = 100.0;
  double max_accel_mm_per_s2 = 1000.0;
  double period_s = 0.004;
};

// What the guard saw at the first fault.
struct StepFaultInfo {
  StepFault fault = StepFault::None;
  std::int64_t period = 0;      // 1-based index of the refused setpoint
  double t_s = 0.0;             // its time
  double s_mm = 0.0;            // planned arc length where it would have been
  Vec3 from_mm = Vec3::Zero();  // the last emitted position
  Vec3 to_mm = Vec3::Zero();    // the refused position
  double value = 0.0;           // what the rule measured (mm)
  double allowed = 0.0;         // what it allows (mm)
};

class StepGuard {
 public:
  StepGuard(const StepBounds& bounds, const Vec3& start_mm) : b_(bounds), last_p_(start_mm) {}

  void set_override(double fraction) {
    if (fraction > override_peak_) override_peak_ = fraction;
  }

  // Checks one setpoint; the first fault is kept (info()) and every later call repeats it.
  StepFault check(double t_s, double s_mm, double planned_ds_mm, const Vec3& p_mm) {
    if (info_.fault != StepFault::None) return info_.fault;
    ++period_;
    const double k = 1.0 + kStepMarginRel;
    const double step_mm = (p_mm - last_p_).norm();
    const double v_max = b_.max_feed_mm_per_s * (override_peak_ > 1.0 ? override_peak_ : 1.0);
    StepFault f = StepFault::None;
    double value = 0.0, allowed = 0.0;
    if (!(planned_ds_mm <= (allowed = v_max * b_.period_s * k + kStepSlackMm))) {
      f = StepFault::Speed, value = planned_ds_mm;
    } else if (!(std::abs(planned_ds_mm - last_ds_) <=
                 (allowed =
                      b_.max_accel_mm_per_s2 * b_.period_s * b_.period_s * k + kStepSlackMm))) {
      f = StepFault::Acceleration, value = std::abs(planned_ds_mm - last_ds_);
    } else if (!(step_mm <= (allowed = planned_ds_mm * k + kStepSlackMm))) {
      f = StepFault::Walk, value = step_mm;
    }
    if (f != StepFault::None) {
      info_ = {f, period_, t_s, s_mm, last_p_, p_mm, value, allowed};
      return f;
    }
    last_p_ = p_mm;
    last_ds_ = planned_ds_mm;
    return f;
  }

  const StepFaultInfo& info() const { return info_; }

 private:
  StepBounds b_;
  Vec3 last_p_;
  double last_ds_ = 0.0;  // the motion starts at rest
  double override_peak_ = 1.0;
  std::int64_t period_ = 0;
  StepFaultInfo info_;
};

}  // namespace ncd::motion
