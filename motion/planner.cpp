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

#include <algorithm>
#include <cmath>
#include <utility>

#include "motion/planner_math.hpp"

namespace ncd::motion {

using namespace planner_math;

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
  if (landing_) return step_landing();
  if (override_target_ >= override_applied_) override_applied_ = override_target_;
  const double last_s = count_ > 0 ? sample(count_ - 1).s_mm : x_.s_mm;
  StepFrame f{};
  f.real_stop = std::min(length_mm_, last_s);
  f.stop = std::min(f.real_stop, x_.s_mm + horizon_mm(x_.v_mm_per_s, x_.a_mm_per_s2));
  f.at_rest = x_.v_mm_per_s == 0.0 && x_.a_mm_per_s2 == 0.0;
  f.j_fallback = plan_pos_ < plan_n_ ? plan_[plan_pos_] : 0.0;
  if (hold_ || override_target_ == 0.0) return step_hold(f);
  if (override_target_ < override_applied_) return step_override_lowered(f);
  return step_follow(f);
}

// The next period of a landing: its planned jerk; at its end the motion rests exactly on L.
MotionSample Planner::step_landing() {
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

// Feed hold (or override 0 %): π brakes to rest; stays there until resume().
MotionSample Planner::step_hold(const StepFrame& f) {
  policy_hold_ = true;
  Cursor c;
  const double j = f.at_rest ? 0.0 : policy(x_, c, nullptr);
  if (rollout(j, override_applied_, f.real_stop, best_, best_n_)) {
    take_best(j, kLimitIdHold);
  } else {
    commit_fallback(f, kLimitIdHold);
  }
  policy_hold_ = false;
  if (x_.v_mm_per_s == 0.0 && x_.a_mm_per_s2 == 0.0) override_applied_ = override_target_;
  return last_;
}

// Override lowered: brake towards the new limits, checked against the old ones until the new
// ones hold.
MotionSample Planner::step_override_lowered(const StepFrame& f) {
  build_blocks(override_target_, f.stop);
  Cursor c;
  std::uint8_t id = kLimitIdLookahead;
  const double j = f.at_rest ? 0.0 : policy(x_, c, &id);
  if (rollout(j, override_target_, f.real_stop, best_, best_n_)) {
    override_applied_ = override_target_;
    take_best(j, id);
  } else if (rollout(j, override_applied_, f.real_stop, best_, best_n_)) {
    take_best(j, id);
  } else {
    commit_fallback(f, id);
  }
  return last_;
}

// The follower (the top, 3): the largest jerk whose next state is safe: j_top, else a landing
// on L, else the dead-beat (or π's own approach) onto the local limit, else a bisection between
// the committed plan's jerk and j_top.
MotionSample Planner::step_follow(const StepFrame& f) {
  build_blocks(override_applied_, f.stop);
  const TopJerk top = top_jerk();
  if (rollout(top.j, override_applied_, f.real_stop, best_, best_n_)) {
    const double a1 = x_.a_mm_per_s2 + top.j * period_s_;
    take_best(top.j, a1 >= top.a_here * (1.0 - 1e-9) ? kLimitIdAcceleration : kLimitIdJerk);
    return last_;
  }
  if (f.stop == length_mm_ && try_landing()) {
    const double j = plan_[plan_pos_++];
    commit(j, kLimitIdPathEnd);
    return last_;
  }
  if (block_count_ > 0 && follow_local_limit(f, top.j)) return last_;
  bisect_jerk(f, top.j);
  return last_;
}

// j_top = min(j_max, (a_max − a)/T) at the tangential scale σ of the interval here (jerk
// vector) and its axis scales (per-axis limits); a_here the acceleration limit there.
Planner::TopJerk Planner::top_jerk() const {
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
  return {clampj(std::min(j_here, (a_here - x_.a_mm_per_s2) / T), j_here), a_here};
}

// The dead-beat onto the current block's level, else the policy's own discrete approach onto
// it (parabola, dead-beat), taken if it lies between the fallback and j_top and is safe.
bool Planner::follow_local_limit(const StepFrame& f, double j_top) {
  bool ok = false;
  const double jd = deadbeat_jerk(x_, blocks_[0].v_max_mm_per_s, &ok);
  const double jt = ok ? jd : track(x_, blocks_[0].v_max_mm_per_s);
  std::size_t n = 0;
  if (!(jt > f.j_fallback && jt < j_top &&
        rollout(jt, override_applied_, f.real_stop, trial_, n))) {
    return false;
  }
  std::swap(trial_, best_);
  best_n_ = n;
  take_best(jt, binding_limit(f.stop));
  if (ok) settle_on(blocks_[0].v_max_mm_per_s);
  return true;
}

// kBisection steps between the committed plan's jerk (safe: its tail is a certificate) and
// j_top; the plan's jerk where none is safe.
void Planner::bisect_jerk(const StepFrame& f, double j_top) {
  double lo = f.j_fallback;
  bool have = false;
  double hi = j_top;
  double j_best = lo;
  std::size_t n = 0;
  for (int k = 0; k < kBisection; ++k) {
    const double mid = 0.5 * (lo + hi);
    if (rollout(mid, override_applied_, f.real_stop, trial_, n)) {
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
    commit_fallback(f, 0);
  }
  last_.limit_id = binding_limit(f.stop);
}

// The committed plan's next jerk (0 past its end), when no rollout certified a new one.
void Planner::commit_fallback(const StepFrame& f, std::uint8_t limit_id) {
  if (plan_pos_ < plan_n_) ++plan_pos_;
  commit(f.j_fallback, limit_id);
}

// The binding limit: the current block if the motion sits on it, else what π brakes for.
std::uint8_t Planner::binding_limit(double stop_mm) const {
  const double cur = block_count_ > 0 ? blocks_[0].v_max_mm_per_s : 0.0;
  if (block_count_ > 0 && x_.v_mm_per_s >= cur * (1.0 - 1e-9)) return blocks_[0].limit_id;
  std::uint8_t id = stop_mm == length_mm_ ? kLimitIdPathEnd : kLimitIdLookahead;
  Cursor c;
  (void)policy(x_, c, &id);
  return id;
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

}  // namespace ncd::motion
