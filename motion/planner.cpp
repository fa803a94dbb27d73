// Look-ahead feed planner: a jerk-limited online trajectory in one dimension (arc length s).
//
// Input: a feed-limit curve v_lim(s), piecewise constant between pushed samples (the limit
// over the interval after a sample when the upstream gives it, else the minimum of the two
// ends; docs/planner.md §2); limits a_max, j_max; period T. Output: s(t) with a constant jerk
// inside each period, so s is a cubic per period; v <= v_lim(s) at every instant,
// |a| <= a_max, |j| <= j_max, v >= 0, at rest at s = 0 and at rest exactly at s = L.
//
//   v_lim ─────────┐              ┌──────────────        window: samples from s to
//                  │              │                      s + H(v, a), H = S-curve braking
//   v(s)   ╭───────╮╲             │    ╭──────────       distance from a bound on the
//         ╱         ╲╲____________│___╱                  speed reachable soon, the ramp of a
//                                                        to 0 (twice), plus margin
//        ╱           ╲ certificate: brake & settle
//   ────●──────────────●──────────●───────────────●──── s
//       s(t)   s(t+T)   block      block          s + H    (or L: land exactly there)
//
// 1. Certificate. A state X = (s, v, a) is safe if the BRAKE POLICY π, run forward in discrete
//    time (one constant jerk per period, exactly as executed), keeps every constraint and comes
//    to rest before the end of what is known (the last sample, L, or s + H). π is a fixed,
//    deterministic rule: look at the blocks ahead (runs of samples; blocks shorter than 1/48 of
//    the window are merged, keeping the minimum); a block r "demands" when the time-optimal
//    S-curve from (v, a) to (v_r, a = 0) needs at least the distance to r minus a margin of
//    2vT; then π tracks the lowest demanding v_r (settling there at a = 0, so the motion meets
//    a drop of the limit at the new level, without a dip); if nothing demands, π brakes to rest
//    as fast as the limits allow. Tracking uses the jerk averaged over the period of the
//    continuous time-optimal velocity profile (so a(t+T) is exact), and a two-period dead-beat
//    (j1, j2 solve v and a exactly) once it fits in ±j_max: that makes rest exact (v = a = 0).
//    π has a second member, tried where the first fails (a state is safe if either certifies
//    it): it settles 2.5 % below the demanding level, its final ramp onto that level at 0.95
//    j_max (onto rest both ramp at 0.9). It can brake later into a dip of the limit and pass
//    the bottom a little below it, as the time-optimal motion does (docs/planner.md §4, "The
//    undershooting member").
// 2. Exact checks. Each simulated period is checked exactly: |j| <= j_max, |a(t+T)| <= a_max (a
//    is linear inside), the quadratic v(τ) has its extremes at the ends or at τ = −a/j, and its
//    maximum must not exceed the minimum limit over [s(t), s(t+T)] (conservative: at every
//    instant, not only at samples); v >= 0; s(t+T) <= the stop point.
// 3. Follower. Each period the planner takes the largest jerk whose next state is safe:
//    j_top = min(j_max, (a_max − a)/T) first, else the dead-beat onto the local limit (this is
//    how it cruises exactly at a flat limit), else a bisection between j_top and the jerk of the
//    plan it committed to last period (its tail is still a valid certificate, since samples are
//    only appended beyond its stop point). So safety holds by induction from rest, whatever the
//    policy's quality; the policy only decides how early slowdowns start.
// 4. Landing. Near L, the committed plan (which stops at or before L) plus the minimum-norm
//    jerk correction that puts the end state exactly at (L, 0, 0), or a minimum-norm landing of
//    n periods from the current state, is checked as above and then executed as it stands.
//    The shortest are tried first: when cruising at the limit, the time-optimal stop itself
//    (ramps at 0.99 j_max) after the cruise that fills the distance, its deceleration lowered by
//    bisection so that it rests on L after whole periods (the correction then only takes up the
//    period averaging, and leaves the cruise alone); below the limit (a short move), a rise to a
//    peak, a cruise and the time-optimal stop in the fewest whole periods, its correction
//    weighted away from the ramps (reach_base); then zero-jerk bases from the time-optimal
//    stop time up, then the plan cut short by 3, 2, 1 periods (its creep onto L folded into the
//    correction), then the plan itself. A zero-jerk landing longer than cruising at v and then
//    stopping time-optimally is not taken while v ≥ a_max T: committed early, it brakes softly all
//    the way (docs/planner.md §4).
// Override scales the limits; lowering it runs π towards the new limits while checking
// against the old ones until the new ones hold. Hold makes π's target 0 from now on; a hold
// during a landing cuts it short where π's stop rests sooner (docs/planner.md §4, step 5).
// Jerk vector (docs/planner.md §3c): a sample may carry a curve span (κ, g, budget), and then
// the exact checks hold the jerk vector bound at each period's highest speed and |a|, π plans
// with the tangential scale σ (a_max and j_max times σ) that keeps it for the whole window at
// the highest speed π may reach, and the look-ahead is sized for braking at the lowest σ
// allowed (min_tangential_scale). Without spans the arithmetic is unchanged.
//
// Cruise (docs/planner.md §6, "The cruise from the memo"). After the dead-beat onto a flat
// limit w, a state within rounding of (w, a = 0) is put exactly on it (as rest is put on exact
// zeros), so a cruise repeats bit for bit. A rollout whose every period stays at or below the
// lowest block of the window never settles on a block nor meets the limit curve: its jerks
// depend only on (v, a, the first jerk, π's limits and member), and from s + Δ it is the same
// rollout shifted by Δ. The last such rollout is kept (the memo) and reused while it still rests
// before the stop point; a cruise's certificate then costs a copy, not a simulation.
//
// Work per step: at most 2 + kBisection rollouts of at most rollout_cap_ periods, each period
// O(1) plus the blocks within its braking distance. Memory: the six plan buffers are sized once,
// by reserve_for_speed at the job's start, for three stops from twice the machine's top feed
// (rollout_cap_ periods); every write into them is bounded by rollout_cap_ (a rollout longer
// than that fails its certificate; a landing longer than that is not tried, and a slow move
// lands once it is within reach), and push() refuses a limit above the reserved speed. No step
// allocates or throws: push() answers with a PushResult, restart() and set_override() with a
// bool.
#include "motion/planner.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "core/error.hpp"

namespace ncd::motion {
namespace {

constexpr int kBisection = 10;       // bisection steps for the largest safe jerk
constexpr double kRelSlack = 1e-12;  // rounding slack on v and a checks (relative)
constexpr double kBlocksPerWindow = 48.0;

double clampj(double j, double j_max) {
  return std::clamp(j, -j_max, j_max);
}

constexpr double kFinalJerk = 0.9;  // final ramp at 0.9 j_max: the slack absorbs sampling
// π's second member (see the top, 1): it settles this fraction below a demanding block's level,
// its final ramp at kUnderFinalJerk j_max (docs/planner.md §4, "The undershooting member").
constexpr double kUndershoot = 0.025;
constexpr double kUnderFinalJerk = 0.95;
constexpr double kLandJerk = 0.99;  // a landing's ramps: room for its minimum-norm correction

// Time-optimal velocity change from (v0, a0) to (w, a = 0) in the decreasing direction: a ramp
// at −j1 to a_p, a hold at a_p (>= −a_max), a final ramp at +j3 to a = 0.
struct Profile {
  double t1, t2, t3, ap;
};
Profile decrease_profile(double v0, double a0, double w, double a_max, double j1, double j3) {
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
bool decreasing(double v0, double a0, double w, double j1, double j3) {
  return (a0 > 0.0 ? v0 + 0.5 * a0 * a0 / j1 : v0 - 0.5 * a0 * a0 / j3) > w;
}

// Distance of the decreasing profile from (v0, a0) down to (w, 0), ramps at j1 and j3; 0 if none
// is needed.
double profile_distance(double v0, double a0, double w, double a_max, double j1, double j3) {
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
double decrease_jerk(double v0, double a0, double w, double T, double a_max, double j_max,
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
void change_phases(double v0, double a0, double w, double a_max, double jl, Phase* out) {
  const double sg = decreasing(v0, a0, w, jl, jl) ? 1.0 : -1.0;
  const Profile p = decrease_profile(sg * v0, sg * a0, sg * w, a_max, jl, jl);
  out[0] = Phase{p.t1, -sg * jl};
  out[1] = Phase{p.t2, 0.0};
  out[2] = Phase{p.t3, sg * jl};
}

// Runs phases from (v, a) (s from 0); returns the distance, adds the time to *t_s.
double run_phases(const Phase* ph, int n, double v, double a, double* t_s) {
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
void average_phases(const Phase* ph, int count, std::size_t n, double T, double* out) {
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

}  // namespace

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
  blocks_.resize(limits.window_capacity);
  last_.done = false;
}

bool Planner::restart(double length_mm) {
  if (!std::isfinite(length_mm) || length_mm < 0.0 || !done_) return false;
  length_mm_ = length_mm;
  head_ = count_ = 0;
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

std::size_t Planner::ring_index(std::size_t i) const {
  const std::size_t k = head_ + i;  // < 2 x the ring's size: a subtraction, not a division
  return k < ring_.size() ? k : k - ring_.size();
}

const LimitSample& Planner::sample(std::size_t i) const {
  return ring_[ring_index(i)];
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
  if (count_ > 0) interval_ring_[ring_index(count_ - 1)] = interval_between(sample(count_ - 1), in);
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
    head_ = (head_ + 1) % ring_.size();
    --count_;
  }
}

// One period of constant jerk j from x (exact cubic); rest is snapped to exact zeros.
Planner::Kin Planner::cubic_step(const Kin& x, double j) const {
  const double T = period_s_;
  return Kin{x.s_mm + x.v_mm_per_s * T + 0.5 * x.a_mm_per_s2 * T * T + j * T * T * T / 6.0,
             x.v_mm_per_s + x.a_mm_per_s2 * T + 0.5 * j * T * T, x.a_mm_per_s2 + j * T};
}

Planner::Kin Planner::advance(const Kin& x, double j) const {
  Kin y = cubic_step(x, j);
  if (std::abs(y.v_mm_per_s) <= v_eps_ && std::abs(y.a_mm_per_s2) <= a_eps_) {
    y.v_mm_per_s = 0.0;
    y.a_mm_per_s2 = 0.0;
  }
  y.s_mm = std::max(y.s_mm, x.s_mm);
  return y;
}

// The lowest and highest speed of one period at jerk j from x: the quadratic v(τ) has its
// extremes at the ends or at τ = −a/j.
Planner::SpeedRange Planner::period_speeds(const Kin& x, double j) const {
  const double T = period_s_;
  const double v1 = x.v_mm_per_s + x.a_mm_per_s2 * T + 0.5 * j * T * T;
  SpeedRange r{std::min(x.v_mm_per_s, v1), std::max(x.v_mm_per_s, v1)};
  if (j != 0.0) {
    const double tau = -x.a_mm_per_s2 / j;
    if (tau > 0.0 && tau < T) {
      const double vt = x.v_mm_per_s + x.a_mm_per_s2 * tau + 0.5 * j * tau * tau;
      r.lo = std::min(r.lo, vt);
      r.hi = std::max(r.hi, vt);
    }
  }
  return r;
}

// Exact check of one period: jerk, acceleration, v(τ) within [0, min limit over the span].
bool Planner::check_period(const Kin& x, double j, Cursor& c, double scale, double stop_mm,
                           double* v_hi_out) const {
  const double T = period_s_;
  if (!(std::abs(j) <= j_max_)) return false;
  const double a1 = x.a_mm_per_s2 + j * T;
  if (std::abs(a1) > a_max_ * (1.0 + kRelSlack)) return false;
  const auto [v_lo, v_hi] = period_speeds(x, j);
  if (v_hi_out) *v_hi_out = v_hi;
  if (v_lo < -v_eps_) return false;
  const double s1 = x.s_mm + x.v_mm_per_s * T + 0.5 * x.a_mm_per_s2 * T * T + j * T * T * T / 6.0;
  if (s1 > stop_mm + 1e-12 * std::max(1.0, length_mm_)) return false;
  if (v_hi <= 0.0) return true;
  if (count_ < 2) return false;
  while (c.segment + 2 < count_ && sample(c.segment + 1).s_mm <= x.s_mm) ++c.segment;
  JerkVectorSpan span;  // the curve over the period's span: largest κ and g, smallest budget
  const double a_hi_abs = std::max(std::abs(x.a_mm_per_s2), std::abs(a1));
  for (std::size_t k = c.segment; k + 1 < count_; ++k) {
    const double lim = interval_limit(k) * scale;
    if (v_hi > lim * (1.0 + kRelSlack)) return false;
    if (any_axis_) {  // per-axis limits: the tangential a and j the interval's axes allow
      const LimitSample& q = sample(k);
      if (std::abs(j) > j_max_ * q.jerk_scale * (1.0 + kRelSlack) ||
          a_hi_abs > a_max_ * q.accel_scale * (1.0 + kRelSlack)) {
        return false;
      }
    }
    if (any_scaled_) {  // the curve of the interval that starts at sample k
      const JerkVectorSpan q = sample(k).jerk_span;
      span.curvature_per_mm = std::max(span.curvature_per_mm, q.curvature_per_mm);
      span.turn_per_mm2 = std::max(span.turn_per_mm2, q.turn_per_mm2);
      span.budget = std::min(span.budget, q.budget);
    }
    if (sample(k + 1).s_mm >= s1) {
      if (!any_scaled_) return true;
      // The jerk vector (docs/planner.md §3c) at the period's highest speed and |a| (a is
      // linear in the period, so its ends bound it).
      return jerk_vector_within(span, v_hi, a_hi_abs, j, j_max_, kRelSlack);
    }
  }
  return false;  // beyond the last sample
}

// The tangential scale the interval starting at sample i allows at speeds up to v (never above
// the sample's v_max, which the checks hold there: the sampler made the scale at the interval's
// limit at least min_tangential_scale).
double Planner::sample_scale(std::size_t i, double v) const {
  const LimitSample& q = sample(i);
  return tangential_scale(q.jerk_span, std::min(v, interval_limit(i) * override_applied_), a_max_,
                          j_max_);
}

// The tangential scale of the interval that holds s at v.
double Planner::scale_at(double s_mm, double v) const {
  if (count_ == 0) return 1.0;
  std::size_t i = 0;
  while (i + 1 < count_ && sample(i + 1).s_mm <= s_mm) ++i;
  return sample_scale(i, v);
}

// π's scale: the smallest σ in the window at the highest speed π may reach from here (the
// horizon's bound on the speed soon reachable, and the settling above it). π only brakes or
// settles below that speed, so every period it simulates keeps the bound there; at lower
// speeds the scale is larger (the cross term 3 v a κ and v³κ² shrink), which the exact checks
// use. (The largest σ that every sample within reach of a stop at σ allows was tried: the cubic
// took 1.876 s against 1.816 s, since π then brakes for the near samples harder than the
// checks of the farther ones allow, and more rollouts fail.)
void Planner::set_policy_limits() {
  double sigma = 1.0;
  if (any_scaled_) {
    const double T = period_s_, a = std::max(x_.a_mm_per_s2, 0.0);
    const double a_next = std::min(a + j_max_ * T, a_max_);  // after one more period
    const double v_top =
        x_.v_mm_per_s + (a + a_max_) * 2.0 * T + a_next * a_next / (2.0 * j_max_ * scale_floor_);
    for (std::size_t i = 0; i < count_; ++i) sigma = std::min(sigma, sample_scale(i, v_top));
  }
  pol_a_ = a_max_ * sigma;
  pol_j_ = j_max_ * sigma;
  if (any_axis_) {  // per-axis limits: π keeps the smallest of the window (docs/planner.md §3f)
    // Rounded down to 1/64 (and by 1e-9, for π's rounding): its limits then change only where
    // the window's axis limits change by a step, and the memo's key holds them.
    const AxisScale w = window_axis_scale();
    const auto step_down = [](double x) {
      const double q = std::floor(x * 64.0) / 64.0;
      return (q > 0.0 ? q : x) * (1.0 - 1e-9);
    };
    pol_a_ = std::min(pol_a_, a_max_ * step_down(w.accel));
    pol_j_ = std::min(pol_j_, j_max_ * step_down(w.jerk));
  }
}

// The smallest axis scales of the window's intervals.
Planner::AxisScale Planner::window_axis_scale() const {
  AxisScale w{1.0, 1.0};
  for (std::size_t i = 0; i < count_; ++i) {
    w.accel = std::min(w.accel, sample(i).accel_scale);
    w.jerk = std::min(w.jerk, sample(i).jerk_scale);
  }
  return w;
}

// The axis scales of the interval that holds s.
Planner::AxisScale Planner::axis_scale_at(double s_mm) const {
  if (count_ == 0) return {1.0, 1.0};
  std::size_t i = 0;
  while (i + 1 < count_ && sample(i + 1).s_mm <= s_mm) ++i;
  return {sample(i).accel_scale, sample(i).jerk_scale};
}

double Planner::v_settle(const Kin& x) const {
  return x.v_mm_per_s + x.a_mm_per_s2 * std::abs(x.a_mm_per_s2) / (2.0 * pol_j_);
}

// π's final ramp towards speed w: the member's onto a block's level, kFinalJerk onto rest
// (the undershooting member changes only how π meets a dip, not how it stops).
double Planner::final_jerk(double w) const {
  return w > 0.0 ? pol_final_ : kFinalJerk;
}

double Planner::need_mm(const Kin& x, double w) const {
  return profile_distance(x.v_mm_per_s, x.a_mm_per_s2, w, pol_a_, pol_j_, final_jerk(w) * pol_j_);
}

// Two-period dead-beat onto (w, a = 0): the first jerk; ok if both fit and v stays >= 0.
double Planner::deadbeat_jerk(const Kin& x, double w, bool* ok) const {
  const double T = period_s_;
  const double dv = x.v_mm_per_s - w;
  const double j1 = -dv / (T * T) - 1.5 * x.a_mm_per_s2 / T;
  const double j2 = dv / (T * T) + 0.5 * x.a_mm_per_s2 / T;
  *ok = std::abs(j1) <= pol_j_ && std::abs(j2) <= pol_j_ &&
        std::abs(x.a_mm_per_s2 + j1 * T) <= pol_a_;
  if (*ok) {  // v stays >= 0 over both periods (ends and interior extremes)
    Kin y = x;
    for (double j : {j1, j2}) {
      const double v1 = y.v_mm_per_s + y.a_mm_per_s2 * T + 0.5 * j * T * T;
      double lo = std::min(y.v_mm_per_s, v1);
      if (j != 0.0) {
        const double tau = -y.a_mm_per_s2 / j;
        if (tau > 0.0 && tau < T) lo = std::min(lo, y.v_mm_per_s + 0.5 * y.a_mm_per_s2 * tau);
      }
      if (lo < -v_eps_) *ok = false;
      y = Kin{0.0, v1, y.a_mm_per_s2 + j * T};
    }
  }
  return j1;
}

// Jerk of one period towards speed w at a = 0: dead-beat if it fits, else the decreasing (or
// mirrored increasing) profile.
double Planner::track(const Kin& x, double w) const {
  bool ok = false;
  const double j1 = deadbeat_jerk(x, w, &ok);
  if (ok) return j1;
  const double f = final_jerk(w);
  const double v = x.v_mm_per_s, a = x.a_mm_per_s2, j3 = f * pol_j_;
  const bool down = decreasing(v, a, w, pol_j_, j3);
  const bool up = decreasing(-v, -a, -w, pol_j_, j3);
  // Neither: on a final-ramp parabola (to rounding); the ramp's landing jerk follows it.
  if (down || (!up && a < 0.0)) {
    return decrease_jerk(v, a, w, period_s_, pol_a_, pol_j_, f);
  }
  if (up || a > 0.0) return -decrease_jerk(-v, -a, -w, period_s_, pol_a_, pol_j_, f);
  return 0.0;
}

// The brake policy π (see top): settle on the lowest demanding block, else brake to rest.
double Planner::policy(const Kin& x, Cursor& c, std::uint8_t* binding_id) const {
  if (policy_hold_) return track(x, 0.0);
  while (c.block + 1 < block_count_ && blocks_[c.block].end_mm <= x.s_mm) ++c.block;
  const double vs = v_settle(x);
  // A block demands only below max(vs, v): where no block ahead is, π brakes to rest.
  const std::size_t b_end =
      c.block < block_count_ && blocks_[c.block].min_on_mm_per_s < std::max(vs, x.v_mm_per_s)
          ? block_count_
          : c.block;
  const double margin = 2.0 * x.v_mm_per_s * period_s_ + pol_j_ * period_s_ * period_s_ * period_s_;
  const double reach = b_end > c.block ? need_mm(x, 0.0) + margin : 0.0;
  double w = std::numeric_limits<double>::infinity();
  for (std::size_t b = c.block; b < b_end; ++b) {
    const Block& bl = blocks_[b];
    const double dist = bl.begin_mm - x.s_mm;
    if (dist > reach) break;
    // Demands: above its level, and either in it, committed to go below it, or due to brake.
    const double lim = bl.v_max_mm_per_s;
    if (lim < std::max(vs, x.v_mm_per_s) && lim < w &&
        (dist <= 0.0 ||
         !decreasing(x.v_mm_per_s, x.a_mm_per_s2, lim, pol_j_, final_jerk(lim) * pol_j_) ||
         need_mm(x, lim) + margin >= dist)) {
      w = lim;
      if (binding_id) *binding_id = bl.limit_id;
    }
  }
  return track(x, std::isfinite(w) ? w * (1.0 - pol_under_) : 0.0);
}

// Blocks of the window from s to stop_mm, limits scaled; short blocks merged (minimum kept).
void Planner::build_blocks(double scale, double stop_mm) {
  block_count_ = 0;
  blocks_period_ = periods_;
  blocks_scale_ = scale;
  blocks_stop_mm_ = stop_mm;
  if (count_ < 2) return;
  const double len_min = (stop_mm - x_.s_mm) / kBlocksPerWindow;
  std::size_t k = ring_index(0);  // ring index of sample i
  for (std::size_t i = 0; i + 1 < count_; ++i) {
    const std::size_t k_next = k + 1 < ring_.size() ? k + 1 : 0;
    const double q_s = ring_[k_next].s_mm;
    const double b0 = std::max(ring_[k].s_mm, x_.s_mm);
    const double b1 = std::min(q_s, stop_mm);
    if (b1 > b0) {
      const IntervalLimit& lim = interval_ring_[k];
      const double v = lim.v_mm_per_s * scale;
      Block* last = block_count_ > 0 ? &blocks_[block_count_ - 1] : nullptr;
      if (last && (last->v_max_mm_per_s == v || last->end_mm - last->begin_mm < len_min)) {
        last->end_mm = b1;
        if (v < last->v_max_mm_per_s) {
          last->v_max_mm_per_s = v;
          last->limit_id = lim.limit_id;
        }
      } else {
        blocks_[block_count_++] = Block{b0, b1, v, lim.limit_id, 0.0};
      }
    }
    if (q_s >= stop_mm) break;
    k = k_next;
  }
  double lowest = std::numeric_limits<double>::infinity();  // each block's min_on
  for (std::size_t b = block_count_; b-- > 0;) {
    lowest = std::min(lowest, blocks_[b].v_max_mm_per_s);
    blocks_[b].min_on_mm_per_s = lowest;
  }
}

// The lowest level of the blocks built this step (−inf without blocks).
double Planner::window_min() const {
  return block_count_ > 0 ? blocks_[0].min_on_mm_per_s : -std::numeric_limits<double>::infinity();
}

// Simulates j0 then π until rest, checking every period; the jerks go to out[0, out_n). Where
// π's first member fails, its second (the undershooting one) is tried: either certifies.
bool Planner::rollout(double j0, double scale_check, double stop_mm, std::vector<double>& out,
                      std::size_t& out_n) {
  if (rollout_member(j0, scale_check, stop_mm, out, out_n)) return true;
  if (policy_hold_) return false;  // braking to rest: both members are the same
  pol_final_ = kUnderFinalJerk;
  pol_under_ = kUndershoot;
  const bool ok = rollout_member(j0, scale_check, stop_mm, out, out_n);
  pol_final_ = kFinalJerk;
  pol_under_ = 0.0;
  return ok;
}

bool Planner::rollout_member(double j0, double scale_check, double stop_mm,
                             std::vector<double>& out, std::size_t& out_n) {
  ++last_rollouts_;
  const RolloutKey key{x_.v_mm_per_s, x_.a_mm_per_s2, j0,         scale_check, pol_a_,
                       pol_j_,        pol_final_,     pol_under_, policy_hold_};
  // In a window flat enough for it, the memo's rollout shifted to s (see RolloutKey), if it
  // still rests before the stop point with room for the rounding of s.
  // (With per-axis limits, a rollout keeps the window's smallest axis limits only if its first
  // period does: π's own periods keep pol_a_ and pol_j_, which are below them.)
  const double a1 = x_.a_mm_per_s2 + j0 * period_s_;
  const bool axes_ok = !any_axis_ || (std::abs(j0) <= pol_j_ &&
                                      std::abs(x_.a_mm_per_s2) <= pol_a_ && std::abs(a1) <= pol_a_);
  const bool flat_window = reuse_rollouts_ && !any_scaled_ && axes_ok &&
                           blocks_period_ == periods_ && scale_check == blocks_scale_;
  if (flat_window && memo_n_ > 0 && key == memo_key_ && window_min() >= memo_v_need_ &&
      x_.s_mm + memo_span_mm_ + 1e-9 * std::max(1.0, length_mm_) <=
          std::min(stop_mm, blocks_stop_mm_)) {
    std::copy_n(memo_.begin(), memo_n_, out.begin());
    out_n = memo_n_;
    ++memo_hits_;
    return true;
  }
  Cursor c;
  Kin x = x_;
  double j = j0;
  double v_need = 0.0;  // the highest speed of any period, and of any state π looks from
  for (std::size_t n = 0; n < rollout_cap_; ++n) {
    double v_hi = 0.0;
    if (!check_period(x, j, c, scale_check, stop_mm, &v_hi)) return false;
    out[n] = j;
    v_need = std::max(v_need, v_hi);
    x = advance(x, j);
    if (x.v_mm_per_s == 0.0 && x.a_mm_per_s2 == 0.0) {
      out_n = n + 1;
      if (flat_window && window_min() >= v_need && x.s_mm <= blocks_stop_mm_) {
        std::copy_n(out.begin(), out_n, memo_.begin());
        memo_n_ = out_n;
        memo_key_ = key;
        memo_v_need_ = v_need;
        memo_span_mm_ = x.s_mm - x_.s_mm;
      }
      return true;
    }
    v_need = std::max({v_need, x.v_mm_per_s, v_settle(x)});
    j = policy(x, c, nullptr);
  }
  return false;
}

// Landing on (L, 0, 0) in n periods: base jerks (the plan's tail, 0, or the S-curve of
// scurve_base) plus the minimum-norm correction; checked exactly; on success it becomes the
// plan (landing_ set).
bool Planner::land_with(std::size_t n, LandBase base) {
  if (n < 3 || n > rollout_cap_) return false;
  // The correction acts on the periods from `first` on: the S-curve base's cruise stays exact
  // (at the cap any added jerk would cross the limit).
  const std::size_t first = base == LandBase::scurve ? land_first_ : 0;
  // The reach base's ramps are at the jerk limit already: its correction is weighted by each
  // period's headroom 1 − |j| / j_max, so that it falls on the periods between the ramps.
  const auto weight = [&](std::size_t i) {
    return base == LandBase::reach ? std::max(0.0, 1.0 - std::abs(land_base_[i]) / land_j_max_)
                                   : 1.0;
  };
  if (first + 3 > n) return false;
  const double T = period_s_;
  for (std::size_t i = 0; i < n; ++i) {
    land_j_[i] = base == LandBase::plan   ? plan_[plan_pos_ + i]
                 : base != LandBase::zero ? land_base_[i]
                                          : 0.0;
  }
  const auto end_state = [&](Kin& y) {  // forward without snapping, from x_
    y = x_;
    for (std::size_t i = 0; i < n; ++i) y = cubic_step(y, land_j_[i]);
  };
  // Gram system in the basis 1, u, u² with u = (k − (m−1)/2)/m, k = periods after this one,
  // m = n − first corrected periods; rows scaled by T, T², T³ (a, v, s).
  Eigen::Matrix3d g = Eigen::Matrix3d::Zero();
  const double half = 0.5 * static_cast<double>(n - first - 1);
  const double nn = static_cast<double>(n - first);
  for (std::size_t i = first; i < n; ++i) {
    const double k = static_cast<double>(n - 1 - i);
    const double u = (k - half) / nn;
    const double rows[3] = {1.0, 0.5 * (2.0 * k + 1.0), (3.0 * k * k + 3.0 * k + 1.0) / 6.0};
    const double wi = weight(i);
    const double basis[3] = {wi, wi * u, wi * u * u};
    for (int r = 0; r < 3; ++r)
      for (int p = 0; p < 3; ++p) g(r, p) += rows[r] * basis[p];
  }
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(g);
  if (!lu.isInvertible()) return false;
  for (int pass = 0; pass < 2; ++pass) {
    Kin y{};
    end_state(y);
    // (Aimed a hair short of L: rounding must not carry the last period past the last limit
    // sample, which the exact checks refuse; the end snaps onto L, and snap_fits() holds the
    // jerk the snap adds. The hair was 1e-12 L: 5.7e-10 mm at L = 567 mm, a third difference
    // 0.04 mm/s³ above j_max at T = 2.2 ms, a finding of the pipeline fuzzer; 256 ε L is
    // above the rounding of the periods' sums and 4000 times smaller. Not when already that
    // close: a landing from there must still move forward.)
    const double hair = 256.0 * std::numeric_limits<double>::epsilon() * std::max(1.0, length_mm_);
    const double aim_mm = length_mm_ - x_.s_mm > 4.0 * hair ? length_mm_ - hair : length_mm_;
    const Eigen::Vector3d r(-y.a_mm_per_s2 / T, -y.v_mm_per_s / (T * T),
                            (aim_mm - y.s_mm) / (T * T * T));
    const Eigen::Vector3d c = lu.solve(r);
    for (std::size_t i = first; i < n; ++i) {
      const double u = (static_cast<double>(n - 1 - i) - half) / nn;
      land_j_[i] += weight(i) * (c(0) + c(1) * u + c(2) * u * u);
    }
  }
  Cursor cur;
  Kin y = x_, end = x_;
  for (std::size_t i = 0; i < n; ++i) {
    if (!check_period(y, land_j_[i], cur, override_applied_, length_mm_)) return false;
    end = cubic_step(y, land_j_[i]);
    y = advance(y, land_j_[i]);
  }
  const double tol_s = 1e-9 * std::max(1.0, length_mm_);
  if (std::abs(y.s_mm - length_mm_) > tol_s || std::abs(y.v_mm_per_s) > 1e3 * v_eps_ ||
      std::abs(y.a_mm_per_s2) > 1e3 * a_eps_) {
    return false;
  }
  return snap_fits(n, end) && take_landing(n);
}

// The landing's end (s, v, a) snaps onto (L, 0, 0), and the next stretch starts from there at
// rest. The third differences of s over the three periods around the snap are the B-spline
// means of the jerks (weights 1/6, 2/3, 1/6), the next stretch's included (at most j_max), plus
// δs/T³, −2δs/T³ − δv/T² − δa/2T and δs/T³ + δv/T² − δa/2T for the snap δ = (L − s, v, a)
// (worked out symbolically). So with P = 2|δs|/T³ + |δv|/T² + |δa|/2T, the last jerk within
// j_max − 6P and the two before it within j_max − 1.2P keep every third difference within
// j_max: the last weighs 1/6 in the mean the snap's third term joins, the other two 5/6 in the
// second's.
bool Planner::snap_fits(std::size_t n, const Kin& end) const {
  const double T = period_s_;
  const double snap = 2.0 * std::abs(length_mm_ - end.s_mm) / (T * T * T) +
                      std::abs(end.v_mm_per_s) / (T * T) + std::abs(end.a_mm_per_s2) / (2.0 * T);
  if (std::abs(land_j_[n - 1]) > j_max_ - 6.0 * snap) return false;
  for (std::size_t i = n - 3; i + 1 < n; ++i) {
    if (std::abs(land_j_[i]) > j_max_ - 1.2 * snap) return false;
  }
  return true;
}

bool Planner::take_landing(std::size_t n) {
  std::swap(plan_, land_j_);
  plan_n_ = n;
  plan_pos_ = 0;
  landing_ = true;
  return true;
}

// A landing base: the time-optimal stop from here with both ramps at kLandJerk j_max, delayed
// (the acceleration held) so that it ends after n periods, as the period averages of its jerk,
// with its deceleration lowered (bisection) until it rests on L: the correction then only
// takes up the averaging. False if no deceleration up to a_max rests on L after n periods.
bool Planner::scurve_base(std::size_t n) {
  if (n > rollout_cap_) return false;
  const double T = period_s_, jl = kLandJerk * land_j_max_;
  const auto end_mm = [&](double a_cap) {  // fills land_base_; where it rests (NaN: too long)
    const Profile p = decrease_profile(x_.v_mm_per_s, x_.a_mm_per_s2, 0.0, a_cap, jl, jl);
    const double t0 = static_cast<double>(n) * T - (p.t1 + p.t2 + p.t3);
    if (t0 < 0.0) return std::numeric_limits<double>::quiet_NaN();
    const double brake_end = t0 + p.t1, ramp_begin = brake_end + p.t2;
    const double ramp_end = ramp_begin + p.t3;
    const auto overlap = [](double lo, double hi, double a, double b) {
      return std::max(0.0, std::min(hi, b) - std::max(lo, a));
    };
    land_first_ = static_cast<std::size_t>(t0 / T);
    Kin y = x_;
    for (std::size_t i = 0; i < n; ++i) {
      const double lo = static_cast<double>(i) * T, hi = lo + T;
      const double j =
          jl * (overlap(lo, hi, ramp_begin, ramp_end) - overlap(lo, hi, t0, brake_end)) / T;
      land_base_[i] = j;
      y = cubic_step(y, j);
    }
    return y.s_mm;
  };
  double hi = land_a_max_, lo = 0.05 * land_a_max_;
  const double s_hi = end_mm(hi), s_lo = end_mm(lo);
  if (!(s_hi >= length_mm_) || s_lo > length_mm_) return false;  // (NaN at lo: too long, fine)
  for (int k = 0; k < 40; ++k) {
    const double mid = 0.5 * (lo + hi);
    const double s_mid = end_mm(mid);
    (std::isnan(s_mid) || s_mid < length_mm_ ? lo : hi) = mid;
  }
  return !std::isnan(end_mm(hi));
}

// A landing base for a motion that has not reached its limit (a short move): rise to a peak
// speed w (the time-optimal change from (v, a) to (w, 0)), cruise at w, then the time-optimal
// stop, all ramps at kLandJerk j_max. The fastest such motion takes the highest w whose rise and
// stop fit the distance; to end after exactly n periods, w is lowered (bisection) until the
// cruise that fills the distance makes up the time. Its jerk is averaged over the periods; the
// minimum-norm correction takes up that averaging. (The zero base's correction alone is the
// minimum-L2 jerk, a quadratic that needs 60 d / t³ where the bang-bang move needs 32 d / t³:
// 23 % longer on a short line.) Returns the fastest time from here, +inf if none; for n > 0,
// fills land_base_ with the base of exactly n periods, and returns +inf if there is none.
double Planner::reach_base(std::size_t n, double v_cap, double jerk_fraction) {
  const double T = period_s_, jl = jerk_fraction * land_j_max_;
  const double v0 = x_.v_mm_per_s, a0 = x_.a_mm_per_s2, d = length_mm_ - x_.s_mm;
  Phase ph[7];
  // Rise (or fall) to w, cruise, stop: distance and time without the cruise.
  const auto shape = [&](double w, double* t_s) {
    change_phases(v0, a0, w, land_a_max_, jl, ph);
    change_phases(w, 0.0, 0.0, land_a_max_, jl, ph + 4);
    ph[3] = Phase{0.0, 0.0};
    *t_s = 0.0;
    return run_phases(ph, 7, v0, a0, t_s);
  };
  // The lowest peak: a ramped to 0 at once. Below it the rise would turn into a dip.
  const double w_min = std::max(v0 + (a0 > 0.0 ? 0.5 : -0.5) * a0 * a0 / jl, 1e-9 * v_cap);
  double t = 0.0;
  if (!(w_min < v_cap) || shape(w_min, &t) > d) return std::numeric_limits<double>::infinity();
  double lo = w_min, hi = v_cap;
  if (shape(hi, &t) > d) {  // the peak stays below the cap: the highest w that fits
    for (int k = 0; k < 60; ++k) {
      const double mid = 0.5 * (lo + hi);
      (shape(mid, &t) <= d ? lo : hi) = mid;
    }
    hi = lo;
  }
  const double w_fast = hi;
  const double fill = d - shape(w_fast, &t);
  if (fill < -1e-9 * std::max(1.0, d)) return std::numeric_limits<double>::infinity();
  const double t_fast = t + std::max(fill, 0.0) / w_fast;
  const double t_n = static_cast<double>(n) * T;
  if (n == 0) return t_fast;
  // The base fills land_base_[0, n): no landing is longer than the buffers (land_with refuses
  // it too); a slow move lands once it is within rollout_cap_ periods of L.
  if (t_n < t_fast || n > rollout_cap_) return std::numeric_limits<double>::infinity();
  // The time of the motion through w: falls as w rises towards w_fast.
  const auto time_through = [&](double w) {
    double tw = 0.0;
    const double left = d - shape(w, &tw);
    return left < 0.0 ? -1.0 : tw + left / w;
  };
  lo = 1e-9 * v_cap;  // below w_min the rise turns into a dip: slower still
  hi = w_fast;
  if (!(time_through(lo) > t_n)) return std::numeric_limits<double>::infinity();
  for (int k = 0; k < 60; ++k) {
    const double mid = 0.5 * (lo + hi);
    (time_through(mid) > t_n ? lo : hi) = mid;
  }
  const double w = hi;
  double tw = 0.0;
  const double left = d - shape(w, &tw);
  ph[3] = Phase{std::max(left, 0.0) / w, 0.0};  // the cruise
  average_phases(ph, 7, n, T, land_base_.data());
  land_first_ = 0;
  return t_fast;
}

// Tries to land on L from here: the committed plan corrected, then minimum-norm landings. The
// blocks were built this step up to L (step() calls it only then).
bool Planner::try_landing() {
  const double T = period_s_;
  const double slack = 4.0 * x_.v_mm_per_s * T + 64.0 * j_max_ * T * T * T;
  land_a_max_ = a_max_, land_j_max_ = j_max_;
  if (any_axis_) {  // the landing runs to L inside the window: its axes' smallest scales
    const AxisScale w = window_axis_scale();
    land_a_max_ *= w.accel;
    land_j_max_ *= w.jerk;
  }
  if (length_mm_ - x_.s_mm > need_mm(x_, 0.0) + slack) return false;
  const std::size_t tail = plan_n_ - plan_pos_;
  // Shorter landings than the plan's first: the earliest rest on L from here. None is shorter
  // than the time-optimal stop from (v, a), whatever the distance; at most kShortLandings tries
  // (bounded work per period).
  constexpr std::size_t kShortLandings = 16;
  const Profile stop =
      decrease_profile(x_.v_mm_per_s, x_.a_mm_per_s2, 0.0, land_a_max_, land_j_max_, land_j_max_);
  const double t_stop = stop.t1 + stop.t2 + stop.t3;
  const std::size_t n0 =
      std::max<std::size_t>(3, t_stop > 0.0 ? static_cast<std::size_t>(t_stop / T) : 0);
  // Nor is one taken that ends later than cruising at v and then stopping time-optimally
  // would: committed early, a minimum-norm landing brakes softly all the way to L.
  // (Not below a_max T, where cruising is no estimate: near rest any landing is taken; but a
  // cruise at the limit is one, however slow.)
  const double v = x_.v_mm_per_s;
  const bool at_limit = v > 0.0 && v >= limit_at(x_.s_mm) * override_applied_ * (1.0 - 1e-9);
  double n_cruise = std::numeric_limits<double>::infinity();
  if (v >= land_a_max_ * T || at_limit) {
    const double t_cruise = t_stop + std::max(length_mm_ - x_.s_mm - need_mm(x_, 0.0), 0.0) / v;
    n_cruise = std::max(std::ceil(t_cruise / T) + 1.0, static_cast<double>(n0 + 2));
  }
  // The time-optimal stop itself, after cruising over the distance it leaves: the earliest the
  // motion can rest on L, to within the periods (the policy's final ramp is at kFinalJerk).
  // Only when cruising at the limit: below it the follower may still gain before braking.
  if (at_limit) {
    const double jl = kLandJerk * land_j_max_;
    const Profile q = decrease_profile(v, x_.a_mm_per_s2, 0.0, land_a_max_, jl, jl);
    const double d_left =
        length_mm_ - x_.s_mm - profile_distance(v, x_.a_mm_per_s2, 0.0, land_a_max_, jl, jl);
    const double t_land = q.t1 + q.t2 + q.t3 + std::max(d_left, 0.0) / v;
    const auto n_land = static_cast<std::size_t>(std::ceil(t_land / T));
    for (std::size_t n = n_land; n < n_land + 2; ++n) {
      if (scurve_base(n) && land_with(n, LandBase::scurve)) return true;
    }
  }
  // Below the limit: rise, cruise and stop in the fewest whole periods (a short move).
  if (!at_limit) {
    double v_cap = std::numeric_limits<double>::infinity();  // the lowest block up to L
    for (std::size_t k = 0; k < block_count_; ++k)
      v_cap = std::min(v_cap, blocks_[k].v_max_mm_per_s);
    const double t_fast = std::isfinite(v_cap) ? reach_base(0, v_cap, kLandJerk) : v_cap;
    if (std::isfinite(t_fast)) {
      const auto n_fast = static_cast<std::size_t>(std::ceil(t_fast / T - 1e-9));
      for (std::size_t n = std::max<std::size_t>(n_fast, 3); n < n_fast + 2; ++n) {
        for (const double f : {kLandJerk, 0.97, 0.94}) {
          if (std::isfinite(reach_base(n, v_cap, f)) && land_with(n, LandBase::reach)) return true;
        }
      }
    }
  }
  for (std::size_t n = n0; n < tail && n < n0 + kShortLandings; ++n) {
    if (static_cast<double>(n) > n_cruise) break;
    if (land_with(n, LandBase::zero)) return true;
  }
  // The plan cut short: its last periods are often a creep onto L (the policy settles with
  // margin), which the correction can fold into the earlier ones.
  for (std::size_t cut = 3; cut > 0; --cut) {
    if (tail >= 3 + cut && land_with(tail - cut, LandBase::plan)) return true;
  }
  if (tail >= 3 && land_with(tail, LandBase::plan)) return true;
  if (tail >= 2 && static_cast<double>(tail + 1) <= n_cruise &&
      land_with(tail + 1, LandBase::zero)) {
    return true;
  }
  std::size_t n = std::max<std::size_t>(3, tail);
  for (int k = 0; k < 12 && n <= rollout_cap_ && static_cast<double>(n) <= n_cruise; ++k) {
    if (land_with(n, LandBase::zero)) return true;
    n = n + std::max<std::size_t>(1, n / 4);
  }
  return false;
}

// A hold while a landing runs: the landing ends at rest too, but it may cruise a few periods
// first, and it rests on L. π's stop from here (checked like every rollout) is taken instead
// when it rests in fewer periods; else the landing goes on, since nothing stops sooner.
bool Planner::cut_landing_for_hold() {
  if (x_.v_mm_per_s == 0.0 && x_.a_mm_per_s2 == 0.0) return false;
  const double last_s = count_ > 0 ? sample(count_ - 1).s_mm : x_.s_mm;
  policy_hold_ = true;
  Cursor c;
  const double j = policy(x_, c, nullptr);
  const bool sooner = rollout(j, override_applied_, std::min(length_mm_, last_s), best_, best_n_) &&
                      best_n_ < plan_n_ - plan_pos_;
  policy_hold_ = false;
  if (!sooner) return false;
  landing_ = false;
  take_best(j, kLimitIdHold);
  return true;
}

// Makes the rollout in best_ (its first jerk j) the committed plan and executes j.
void Planner::take_best(double j, std::uint8_t limit_id) {
  std::swap(plan_, best_);
  plan_n_ = best_n_;
  plan_pos_ = 1;
  commit(j, limit_id);
}

// After a dead-beat onto a flat limit w: a state within rounding of (w, a = 0) is put on it
// exactly, as advance() puts rest on exact zeros, so that the cruise repeats bit for bit (its
// next jerk is 0, and its rollout the memo's: see RolloutKey). It moves v by at most v_eps and
// a by at most a_eps, and only where no block of the window is below w, so v = w holds every
// limit the next periods meet (the window reaches far beyond them).
void Planner::settle_on(double w) {
  if (std::abs(x_.v_mm_per_s - w) > v_eps_ || std::abs(x_.a_mm_per_s2) > a_eps_) return;
  if (!(window_min() >= w)) return;
  x_.v_mm_per_s = last_.v_mm_per_s = w;
  x_.a_mm_per_s2 = last_.a_mm_per_s2 = 0.0;
}

// Executes jerk j for one period and records the output sample.
void Planner::commit(double j, std::uint8_t limit_id) {
  x_ = advance(x_, j);
  ++periods_;
  t_s_ = static_cast<double>(periods_) * period_s_;
  last_ = MotionSample{t_s_, x_.s_mm,  x_.v_mm_per_s, x_.a_mm_per_s2,
                       j,    limit_id, false,         limit_at(x_.s_mm)};
}

// The limit curve at s (see MotionSample::v_limit_mm_per_s). The samples behind s were dropped
// at the start of the step, so this passes at most the few samples one period crosses.
double Planner::limit_at(double s_mm) const {
  if (count_ == 0) return 0.0;
  std::size_t i = 0;
  while (i + 1 < count_ && sample(i + 1).s_mm <= s_mm) ++i;
  return interval_limit(i);
}

// The limit over the interval from p to the next sample q, and its law (see LimitSample).
Planner::IntervalLimit Planner::interval_between(const LimitSample& p, const LimitSample& q) {
  if (std::isfinite(p.v_after_mm_per_s)) return {p.v_after_mm_per_s, p.after_limit_id};
  return {std::min(p.v_max_mm_per_s, q.v_max_mm_per_s),
          p.v_max_mm_per_s <= q.v_max_mm_per_s ? p.limit_id : q.limit_id};
}

double Planner::interval_limit(std::size_t i) const {
  return i + 1 < count_ ? interval_ring_[ring_index(i)].v_mm_per_s : sample(i).v_max_mm_per_s;
}

MotionSample Planner::step() {
  if (done_) return last_;
  last_rollouts_ = 0;
  if (length_mm_ == 0.0) {
    done_ = true;
    last_ = MotionSample{t_s_, 0.0, 0.0, 0.0, 0.0, kLimitIdPathEnd, true, limit_at(0.0)};
    return last_;
  }
  drop_passed_samples();
  set_policy_limits();
  if (landing_ && (hold_ || override_target_ == 0.0) && cut_landing_for_hold()) return last_;
  if (landing_) {
    const double j = plan_[plan_pos_++];
    commit(j, kLimitIdPathEnd);
    if (plan_pos_ == plan_n_) {
      x_ = Kin{length_mm_, 0.0, 0.0};
      last_.s_mm = length_mm_;
      last_.v_mm_per_s = 0.0;
      last_.a_mm_per_s2 = 0.0;
      last_.done = true;
      done_ = true;
    }
    return last_;
  }
  if (override_target_ >= override_applied_) override_applied_ = override_target_;
  const double last_s = count_ > 0 ? sample(count_ - 1).s_mm : x_.s_mm;
  const double real_stop = std::min(length_mm_, last_s);
  const double stop = std::min(real_stop, x_.s_mm + horizon_mm(x_.v_mm_per_s, x_.a_mm_per_s2));
  const bool at_rest = x_.v_mm_per_s == 0.0 && x_.a_mm_per_s2 == 0.0;
  const double j_fallback = plan_pos_ < plan_n_ ? plan_[plan_pos_] : 0.0;
  const auto use_fallback = [&](std::uint8_t id) {
    if (plan_pos_ < plan_n_) ++plan_pos_;
    commit(j_fallback, id);
  };
  std::size_t n = 0;

  // Feed hold (or override 0 %): π brakes to rest; stays there until resume().
  if (hold_ || override_target_ == 0.0) {
    policy_hold_ = true;
    Cursor c;
    const double j = at_rest ? 0.0 : policy(x_, c, nullptr);
    if (rollout(j, override_applied_, real_stop, best_, best_n_)) {
      take_best(j, kLimitIdHold);
    } else {
      use_fallback(kLimitIdHold);
    }
    policy_hold_ = false;
    if (x_.v_mm_per_s == 0.0 && x_.a_mm_per_s2 == 0.0) override_applied_ = override_target_;
    return last_;
  }

  // Override lowered: brake towards the new limits, checked against the old ones until the
  // new ones hold.
  if (override_target_ < override_applied_) {
    build_blocks(override_target_, stop);
    Cursor c;
    std::uint8_t id = kLimitIdLookahead;
    const double j = at_rest ? 0.0 : policy(x_, c, &id);
    if (rollout(j, override_target_, real_stop, best_, best_n_)) {
      override_applied_ = override_target_;
      take_best(j, id);
    } else if (rollout(j, override_applied_, real_stop, best_, best_n_)) {
      take_best(j, id);
    } else {
      use_fallback(id);
    }
    return last_;
  }

  build_blocks(override_applied_, stop);
  const double T = period_s_;
  const double sigma =
      any_scaled_ ? scale_at(x_.s_mm, x_.v_mm_per_s + std::abs(x_.a_mm_per_s2) * period_s_ +
                                          j_max_ * period_s_ * period_s_)
                  : 1.0;
  double j_here = sigma * j_max_, a_here = sigma * a_max_;
  if (any_axis_) {
    const AxisScale here = axis_scale_at(x_.s_mm);
    j_here = std::min(j_here, here.jerk * j_max_);
    a_here = std::min(a_here, here.accel * a_max_);
  }
  const double j_top = clampj(std::min(j_here, (a_here - x_.a_mm_per_s2) / T), j_here);
  if (rollout(j_top, override_applied_, real_stop, best_, best_n_)) {
    const double a1 = x_.a_mm_per_s2 + j_top * T;
    take_best(j_top, a1 >= a_here * (1.0 - 1e-9) ? kLimitIdAcceleration : kLimitIdJerk);
    return last_;
  }
  if (stop == length_mm_ && try_landing()) {
    const double j = plan_[plan_pos_++];
    commit(j, kLimitIdPathEnd);
    return last_;
  }
  // The binding limit: the current block if we sit on it, else what π brakes for.
  const auto binding = [&]() {
    const double cur = block_count_ > 0 ? blocks_[0].v_max_mm_per_s : 0.0;
    if (block_count_ > 0 && x_.v_mm_per_s >= cur * (1.0 - 1e-9)) return blocks_[0].limit_id;
    std::uint8_t id = stop == length_mm_ ? kLimitIdPathEnd : kLimitIdLookahead;
    Cursor c;
    (void)policy(x_, c, &id);
    return id;
  };
  double lo = j_fallback;
  bool have = false;
  if (block_count_ > 0) {
    bool ok = false;
    const double jd = deadbeat_jerk(x_, blocks_[0].v_max_mm_per_s, &ok);
    // Else the policy's own discrete approach onto the local limit (parabola, dead-beat).
    const double jt = ok ? jd : track(x_, blocks_[0].v_max_mm_per_s);
    if (jt > lo && jt < j_top && rollout(jt, override_applied_, real_stop, trial_, n)) {
      std::swap(trial_, best_);
      best_n_ = n;
      take_best(jt, binding());
      if (ok) settle_on(blocks_[0].v_max_mm_per_s);
      return last_;
    }
  }
  double hi = j_top;
  double j_best = lo;
  for (int k = 0; k < kBisection; ++k) {
    const double mid = 0.5 * (lo + hi);
    if (rollout(mid, override_applied_, real_stop, trial_, n)) {
      std::swap(trial_, best_);
      best_n_ = n;
      lo = j_best = mid;
      have = true;
    } else {
      hi = mid;
    }
  }
  if (have) {
    take_best(j_best, 0);
  } else {
    use_fallback(0);
  }
  last_.limit_id = binding();
  return last_;
}

bool Planner::set_override(double fraction) {
  if (!(fraction >= 0.0 && fraction <= 2.0)) return false;
  override_target_ = fraction;
  return true;
}

void Planner::hold() {
  hold_ = true;
}

void Planner::resume() {
  hold_ = false;
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
