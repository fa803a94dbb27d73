// The planner's window of limit samples and its life (the planner is explained at the top of
// planner.cpp): construction and restart, the look-ahead horizon and whether the window wants
// samples, push() and its checks (with the words of each refusal), the buffers sized once by
// reserve_for_speed, the samples the motion has passed, and plan_all for a whole curve at once.
#include <algorithm>
#include <cmath>
#include <string>

#include "core/error.hpp"
#include "motion/planner.hpp"
#include "motion/planner_math.hpp"

namespace ncd::motion {

using namespace planner_math;

double braking_distance_mm(double v, double v_t, double a_max, double j_max) {
  const double dv = std::max(v - v_t, 0.0);
  const double t =
      dv >= a_max * a_max / j_max ? dv / a_max + a_max / j_max : 2.0 * std::sqrt(dv / j_max);
  return 0.5 * (v + v_t) * t;
}

const char* to_string(PushResult r) {
  switch (r) {
    case PushResult::Ok:
      return "ok";
    case PushResult::SpeedInvalid:
      return "speed_invalid";
    case PushResult::AfterInvalid:
      return "after_invalid";
    case PushResult::IdReserved:
      return "id_reserved";
    case PushResult::SpanInvalid:
      return "span_invalid";
    case PushResult::FirstNotAtZero:
      return "first_not_at_zero";
    case PushResult::NotIncreasing:
      return "not_increasing";
    case PushResult::WindowFull:
      return "window_full";
    case PushResult::AboveReserve:
      return "above_reserve";
  }
  return "unknown";
}

std::string describe(PushResult r, const LimitSample& in, double reserved) {
  const std::string at = " at s_mm = " + std::to_string(in.s_mm);
  switch (r) {
    case PushResult::Ok:
      return "ok";
    case PushResult::SpeedInvalid:
      return "v_max_mm_per_s = " + std::to_string(in.v_max_mm_per_s) + at +
             " is invalid: a feed limit must be finite and > 0; where the machine must stop, end "
             "the path there and start a new one";
    case PushResult::AfterInvalid:
      return "v_after_mm_per_s = " + std::to_string(in.v_after_mm_per_s) + at +
             " is invalid: the limit over the interval after a sample is at least the sample's "
             "v_max_mm_per_s (" +
             std::to_string(in.v_max_mm_per_s) + "); use +inf where it is not known";
    case PushResult::IdReserved:
      return "limit_id = " + std::to_string(in.limit_id) +
             " or after_limit_id = " + std::to_string(in.after_limit_id) + at +
             " is reserved (>= " + std::to_string(kLimitIdReserved) + "); use a smaller id";
    case PushResult::SpanInvalid:
      return "the jerk-vector span" + at + " (curvature " +
             std::to_string(in.jerk_span.curvature_per_mm) + " /mm, turn " +
             std::to_string(in.jerk_span.turn_per_mm2) + " /mm^2, budget " +
             std::to_string(in.jerk_span.budget) +
             ") is invalid: curvature and turn must be finite and >= 0, the budget in (0, 1]";
    case PushResult::FirstNotAtZero:
      return "s_mm = " + std::to_string(in.s_mm) +
             " is invalid for the first limit sample: the curve must start at s = 0";
    case PushResult::NotIncreasing:
      return "s_mm = " + std::to_string(in.s_mm) +
             " is invalid: samples must have finite, strictly increasing s";
    case PushResult::WindowFull:
      return "the look-ahead window is full" + at +
             ": push only while wants_samples(), or raise window_capacity";
    case PushResult::AboveReserve:
      return "v_max_mm_per_s = " + std::to_string(in.v_max_mm_per_s) + " (interval " +
             std::to_string(in.v_after_mm_per_s) + ")" + at +
             " is above the speed the planner's buffers were sized for at the job's start (" +
             std::to_string(reserved) +
             " mm/s): every feed limit must be capped by the machine's maximum feed";
  }
  return "unknown";
}

void validate(const PlannerLimits& limits) {
  require_positive("a_max_mm_per_s2", limits.a_max_mm_per_s2);
  require_positive("j_max_mm_per_s3", limits.j_max_mm_per_s3);
  require_positive("period_s", limits.period_s);
  if (!(limits.min_tangential_scale > 0.0 && limits.min_tangential_scale <= 1.0)) {
    throw InputError("min_tangential_scale = " + std::to_string(limits.min_tangential_scale) +
                     " is invalid: it is a fraction of the limits, in (0, 1]");
  }
  if (limits.window_capacity < 2) {
    throw InputError("window_capacity = " + std::to_string(limits.window_capacity) +
                     " is invalid: the look-ahead needs at least 2 samples");
  }
}

Planner::Planner(const PlannerLimits& limits, double length_mm)
    : a_max_(limits.a_max_mm_per_s2),
      j_max_(limits.j_max_mm_per_s3),
      period_s_(limits.period_s),
      length_mm_(length_mm),
      scale_floor_(limits.min_tangential_scale),
      pol_a_(limits.a_max_mm_per_s2),
      pol_j_(limits.j_max_mm_per_s3) {
  validate(limits);
  require_finite("length_mm", length_mm);
  if (length_mm < 0.0) {
    throw InputError("length_mm = " + std::to_string(length_mm) +
                     " is invalid: a path length must be >= 0");
  }
  pol_final_ = kFinalJerk;
  reuse_rollouts_ = limits.reuse_rollouts;
  v_eps_ = 1e-9 * j_max_ * period_s_ * period_s_;
  a_eps_ = 1e-9 * j_max_ * period_s_;
  ring_.resize(limits.window_capacity);
  interval_ring_.resize(limits.window_capacity);
  run_ring_.resize(limits.window_capacity);
  accel_scale_min_.reserve(limits.window_capacity);
  jerk_scale_min_.reserve(limits.window_capacity);
  blocks_.resize(limits.window_capacity);
  last_.done = false;
}

bool Planner::restart(double length_mm) {
  if (!std::isfinite(length_mm) || length_mm < 0.0 || !done_) return false;
  length_mm_ = length_mm;
  head_ = count_ = 0;
  accel_scale_min_.clear();
  jerk_scale_min_.clear();
  saw_end_ = false;
  block_count_ = 0;
  x_ = Kin{0.0, 0.0, 0.0};
  done_ = false;
  plan_n_ = plan_pos_ = best_n_ = 0;
  landing_ = false;
  override_applied_ = override_target_;  // at rest: a new override holds at once
  last_.s_mm = 0.0;
  last_.done = false;
  return true;
}

// Look-ahead distance wanted at (v, a): braking from a bound on the speed soon reachable, plus
// twice the travel while the acceleration reached by then ramps down to 0 (the end of the
// window is a stop for the certificate; counting the ramp once gave the cubic 1.648 s, 1.5 or
// more times 1.628 s, none 1.664 s: docs/planner.md §4). (Braking at the lowest tangential
// scale a sample may carry.)
double Planner::horizon_mm(double v, double a) const {
  const double T = period_s_;
  const double v_hi = v + (std::max(a, 0.0) + a_max_) * 2.0 * T + a_max_ * a_max_ / (2.0 * j_max_);
  const double a_hi = std::min(std::max(a, 0.0) + 2.0 * j_max_ * T, a_max_);
  const double a_brake = a_max_ * scale_floor_, j_brake = j_max_ * scale_floor_;
  return braking_distance_mm(v_hi, 0.0, a_brake, j_brake) + 2.0 * v_hi * a_hi / j_brake +
         4.0 * v_hi * T + 8.0 * j_max_ * T * T * T;
}

double Planner::lookahead_bound_mm() const {
  return horizon_mm(2.0 * v_top_pushed_, a_max_);
}

bool Planner::wants_samples() const {
  if (saw_end_ || count_ >= ring_.size()) return false;
  if (count_ < 2) return true;
  return sample(count_ - 1).s_mm < x_.s_mm + horizon_mm(x_.v_mm_per_s, x_.a_mm_per_s2);
}

PushResult Planner::push(const LimitSample& in) {
  if (saw_end_) return PushResult::Ok;  // past L: nothing more is needed
  const PushResult r = classify(in);
  if (r != PushResult::Ok) return r;
  ring_[ring_index(count_)] = in;
  if (count_ > 0) {
    const std::size_t k = ring_index(count_ - 1);
    interval_ring_[k] = interval_between(sample(count_ - 1), in);
    const std::size_t k_prev = count_ >= 2 ? ring_index(count_ - 2) : k;
    run_ring_[k] = count_ >= 2 && interval_ring_[k_prev].v_mm_per_s == interval_ring_[k].v_mm_per_s
                       ? run_ring_[k_prev]
                       : front_seq_ + count_ - 1;
  }
  accel_scale_min_.push(front_seq_ + count_, in.accel_scale);
  jerk_scale_min_.push(front_seq_ + count_, in.jerk_scale);
  const JerkVectorSpan span = in.jerk_span;
  if (span.curvature_per_mm != 0.0 || span.turn_per_mm2 != 0.0 || span.budget != 1.0) {
    any_scaled_ = true;
  }
  if (in.accel_scale != 1.0 || in.jerk_scale != 1.0) any_axis_ = true;
  ++count_;
  count_high_water_ = std::max(count_high_water_, count_);
  ahead_high_water_mm_ = std::max(ahead_high_water_mm_, in.s_mm - x_.s_mm);
  if (in.s_mm >= length_mm_) saw_end_ = true;
  v_top_pushed_ = std::max(v_top_pushed_, in.v_max_mm_per_s);
  return PushResult::Ok;
}

// Whether push() can take the sample: the checks in the order describe() words them.
PushResult Planner::classify(const LimitSample& in) const {
  if (!std::isfinite(in.s_mm)) return PushResult::NotIncreasing;
  if (!std::isfinite(in.v_max_mm_per_s) || in.v_max_mm_per_s <= 0.0) {
    return PushResult::SpeedInvalid;
  }
  if (!(in.v_after_mm_per_s >= in.v_max_mm_per_s)) return PushResult::AfterInvalid;
  if (in.limit_id >= kLimitIdReserved || in.after_limit_id >= kLimitIdReserved) {
    return PushResult::IdReserved;
  }
  const JerkVectorSpan span = in.jerk_span;
  const bool constrained =
      span.curvature_per_mm != 0.0 || span.turn_per_mm2 != 0.0 || span.budget != 1.0;
  // (A span whose scale at v_max falls below min_tangential_scale is kept: the look-ahead is
  // then shorter than a stop at that scale needs, and the motion slows for it, never faster.)
  if (constrained && !(span.curvature_per_mm >= 0.0 && std::isfinite(span.curvature_per_mm) &&
                       span.turn_per_mm2 >= 0.0 && std::isfinite(span.turn_per_mm2) &&
                       span.budget > 0.0 && span.budget <= 1.0)) {
    return PushResult::SpanInvalid;
  }
  if (!(in.accel_scale > 0.0 && in.accel_scale <= 1.0 && in.jerk_scale > 0.0 &&
        in.jerk_scale <= 1.0)) {
    return PushResult::SpanInvalid;
  }
  if (count_ == 0 && periods_ == 0 && in.s_mm != 0.0) return PushResult::FirstNotAtZero;
  if (count_ > 0 && !(in.s_mm > sample(count_ - 1).s_mm)) return PushResult::NotIncreasing;
  if (count_ >= ring_.size()) return PushResult::WindowFull;
  // The buffers hold every rollout from speeds up to 2 v_reserved (override 200 %): no limit
  // the motion may follow, at a sample or over an interval, may be above v_reserved.
  if (in.v_max_mm_per_s > v_reserved_ ||
      (std::isfinite(in.v_after_mm_per_s) && in.v_after_mm_per_s > v_reserved_)) {
    return PushResult::AboveReserve;
  }
  return PushResult::Ok;
}

void Planner::reserve_for_speed(double v_mm_per_s) {
  // Longest rollout: a stop from 2 v (override 200 %) with settling phases, tripled. Bounded:
  // a stop longer than kMaxRolloutPeriods is refused here, with the numbers, instead of sizing
  // buffers from them (1e300 mm/s would overflow the cast; 1e12 would exhaust memory).
  require_finite("v_mm_per_s", v_mm_per_s);
  const double v_cap = 2.0 * v_mm_per_s + a_max_ * a_max_ / j_max_;
  const double a_brake = a_max_ * scale_floor_, j_brake = j_max_ * scale_floor_;
  const double t_stop = v_cap / a_brake + 2.0 * a_brake / j_brake;
  const double periods = std::ceil(3.0 * t_stop / period_s_) + 64.0;
  if (!(periods <= static_cast<double>(kMaxRolloutPeriods))) {
    throw InputError("a stop from " + std::to_string(v_mm_per_s) +
                     " mm/s at a_max = " + std::to_string(a_max_) +
                     " mm/s^2 and j_max = " + std::to_string(j_max_) + " mm/s^3 takes " +
                     std::to_string(t_stop) + " s, more than the planner's bound of " +
                     std::to_string(static_cast<double>(kMaxRolloutPeriods) * period_s_ / 3.0) +
                     " s; lower the maximum feed or raise the acceleration and jerk limits");
  }
  v_reserved_ = std::max(v_reserved_, v_mm_per_s);
  const auto cap = static_cast<std::size_t>(periods);
  if (cap > rollout_cap_) {
    rollout_cap_ = cap;
    plan_.resize(cap);
    trial_.resize(cap);
    best_.resize(cap);
    memo_.resize(cap);
    land_j_.resize(cap);
    land_base_.resize(cap);
  }
}

void Planner::drop_passed_samples() {
  while (count_ >= 3 && sample(1).s_mm <= x_.s_mm) {
    accel_scale_min_.drop(front_seq_);
    jerk_scale_min_.drop(front_seq_);
    ++front_seq_;
    head_ = (head_ + 1) % ring_.size();
    --count_;
  }
}

// The limit over the interval from p to the next sample q, and its law (see LimitSample).
Planner::IntervalLimit Planner::interval_between(const LimitSample& p, const LimitSample& q) {
  if (std::isfinite(p.v_after_mm_per_s)) return {p.v_after_mm_per_s, p.after_limit_id};
  return {std::min(p.v_max_mm_per_s, q.v_max_mm_per_s),
          p.v_max_mm_per_s <= q.v_max_mm_per_s ? p.limit_id : q.limit_id};
}

PushResult push_available(Planner& planner, std::span<const LimitSample> curve, std::size_t& next) {
  while (next < curve.size() && planner.wants_samples()) {
    const PushResult r = planner.push(curve[next]);
    if (r != PushResult::Ok) return r;
    ++next;
  }
  return PushResult::Ok;
}

std::vector<MotionSample> plan_all(const PlannerLimits& limits, double length_mm,
                                   std::span<const LimitSample> curve, std::size_t max_periods) {
  Planner planner(limits, length_mm);
  double v_top = 0.0;
  for (const LimitSample& q : curve) {
    if (std::isfinite(q.v_max_mm_per_s)) v_top = std::max(v_top, q.v_max_mm_per_s);
    if (std::isfinite(q.v_after_mm_per_s)) v_top = std::max(v_top, q.v_after_mm_per_s);
  }
  planner.reserve_for_speed(v_top);
  std::vector<MotionSample> out;
  out.push_back(MotionSample{});
  std::size_t next = 0;
  while (out.size() <= max_periods) {
    const PushResult r = push_available(planner, curve, next);
    if (r != PushResult::Ok) {
      throw InputError(describe(r, curve[next], planner.reserved_speed_mm_per_s()));
    }
    out.push_back(planner.step());
    if (out.back().done) return out;
  }
  throw InputError("the motion did not finish within " + std::to_string(max_periods) +
                   " periods: check that the limit curve reaches L = " + std::to_string(length_mm) +
                   " mm");
}

}  // namespace ncd::motion
