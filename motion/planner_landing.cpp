// The planner's landing on L (the top of planner.cpp, 4): the bases a landing starts from (the
// time-optimal stop delayed to whole periods, the rise-cruise-stop of a short move, zero, the
// committed plan), the minimum-norm jerk correction that puts the end exactly on (L, 0, 0), its
// exact check and end snap, the order landings are tried in, and a hold during a landing.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "motion/planner.hpp"
#include "motion/planner_math.hpp"

namespace ncd::motion {

using namespace planner_math;

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

}  // namespace ncd::motion
