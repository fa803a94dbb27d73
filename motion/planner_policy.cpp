// The planner's brake policy π and its certificate (the top of planner.cpp, 1 and 2): the exact
// check of one period, π's limits this step (tangential and axis scales), π's tracking jerk
// (dead-beat, or the period average of the time-optimal profile), the blocks π looks at, and the
// rollout that runs a first jerk then π to rest, checking every period, with the memo of a
// cruise (the top of planner.cpp, "Cruise").
#include <algorithm>
#include <cmath>
#include <limits>

#include "motion/planner.hpp"
#include "motion/planner_math.hpp"

namespace ncd::motion {

using namespace planner_math;

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

// The smallest axis scales of the window's intervals (1 for an empty window; push() refuses
// scales above 1), kept as samples are pushed and dropped.
Planner::AxisScale Planner::window_axis_scale() const {
  return {accel_scale_min_.min_or(1.0), jerk_scale_min_.min_or(1.0)};
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

// The brake policy π (the top of planner.cpp, 1): settle on the lowest demanding block, else brake
// to rest.
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
      // The intervals after this one in its run of equal limits would each merge into the
      // block (its level is theirs) and only move its end: move it to the run's last one before
      // the stop at once.
      const std::size_t j =
          q_s < stop_mm && blocks_[block_count_ - 1].v_max_mm_per_s == v ? run_last(i, stop_mm) : i;
      if (j > i) {
        i = j;
        k = ring_index(j);
        const double q_j = sample(j + 1).s_mm;
        blocks_[block_count_ - 1].end_mm = std::min(q_j, stop_mm);
        if (q_j >= stop_mm) break;
        k = k + 1 < ring_.size() ? k + 1 : 0;
        continue;
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

// The last interval m ≥ i of interval i's run of equal limits that build_blocks reaches before
// the stop (sample m at or after stop_mm ends its loop): both conditions hold from i up to
// some m and fail after it (run_ring_ grows along the window, s increases), so a bisection.
std::size_t Planner::run_last(std::size_t i, double stop_mm) const {
  const std::uint64_t run = run_ring_[ring_index(i)];
  std::size_t lo = i, hi = count_ - 1;  // lo holds; hi (no interval from the last sample) fails
  while (hi - lo > 1) {
    const std::size_t mid = lo + (hi - lo) / 2;
    const std::size_t k = ring_index(mid);
    (run_ring_[k] == run && ring_[k].s_mm < stop_mm ? lo : hi) = mid;
  }
  return lo;
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
}  // namespace ncd::motion
