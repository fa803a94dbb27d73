// Look-ahead feed planner: a feed-limit curve along the path in, a jerk-limited motion s(t)
// sampled every period out. Plain data in, plain data out; the algorithm is explained once at
// the top of planner.cpp.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "core/jerk_vector.hpp"
#include "motion/sliding_min.hpp"

namespace ncd::motion {

// One point of the feed-limit curve. Between two samples the limit is the MINIMUM of the two
// (conservative, piecewise constant), so an upstream that samples densely is respected; an
// upstream that knows the limit's minimum over the interval after a sample gives it in
// v_after_mm_per_s, and the planner holds that instead (docs/planner.md §2).
struct LimitSample {
  double s_mm = 0.0;            // arc length along the path, strictly increasing, first at 0
  double v_max_mm_per_s = 0.0;  // > 0; a point where the machine must stop ends the path
  std::uint8_t limit_id = 0;    // which feed law set it (< kLimitIdReserved)
  // Where the jerk vector is bounded (docs/planner.md §3c): the curve of the interval that
  // starts at this sample (its largest κ and g, and its budget; unlike v_max, not shared with
  // the interval before). The default (0, 0, 1): no constraint.
  JerkVectorSpan jerk_span{};
  // The limit over the interval from this sample to the next (its minimum there; at least
  // v_max_mm_per_s), and the law that sets it; +inf: the smaller of the two samples.
  double v_after_mm_per_s = std::numeric_limits<double>::infinity();
  std::uint8_t after_limit_id = 0;
  // Per-axis limits (docs/planner.md §3f): the tangential acceleration and jerk allowed over
  // the interval from this sample to the next, as fractions of a_max and j_max, in (0, 1].
  double accel_scale = 1.0;
  double jerk_scale = 1.0;
};

// limit_id values the planner reports itself; upstream ids must be below kLimitIdReserved.
inline constexpr std::uint8_t kLimitIdReserved = 0xF0;
inline constexpr std::uint8_t kLimitIdOverlap = 0xF9;       // a corner passed without its stop
inline constexpr std::uint8_t kLimitIdHold = 0xFA;          // feed hold or override 0 %
inline constexpr std::uint8_t kLimitIdLookahead = 0xFB;     // no samples far enough ahead
inline constexpr std::uint8_t kLimitIdPathEnd = 0xFC;       // braking to land on L
inline constexpr std::uint8_t kLimitIdJerk = 0xFD;          // |j| = j_max binds
inline constexpr std::uint8_t kLimitIdAcceleration = 0xFE;  // |a| = a_max binds

// What push() made of a sample: Ok, or why it was refused (the sample is then not taken and the
// planner is unchanged). The cycle's result code: push() never throws (planner.cpp's top).
enum class PushResult : std::uint8_t {
  Ok,
  SpeedInvalid,    // v_max not finite or not > 0
  AfterInvalid,    // v_after below v_max (or NaN)
  IdReserved,      // limit_id or after_limit_id >= kLimitIdReserved
  SpanInvalid,     // jerk_span with a negative or non-finite term, or a budget outside (0, 1],
                   // or an accel_scale or jerk_scale outside (0, 1]
  FirstNotAtZero,  // the first sample's s is not 0
  NotIncreasing,   // s not above the previous sample's
  WindowFull,      // pushed while !wants_samples() said the window was full
  AboveReserve,    // v_max above the speed the buffers were sized for (reserve_for_speed)
};
const char* to_string(PushResult result);
// The refusal in words, naming the value, the limit and a way out (allocates: for the edges).
std::string describe(PushResult result, const LimitSample& sample, double reserved_mm_per_s);

// The longest rollout the planner sizes its buffers for (periods; 3x the longest stop): six
// buffers of 2 MB, and a stop of up to 350 s at 4 ms.
inline constexpr std::size_t kMaxRolloutPeriods = std::size_t{1} << 18;

struct PlannerLimits {
  double a_max_mm_per_s2 = 1000.0;     // tangential acceleration limit
  double j_max_mm_per_s3 = 20000.0;    // tangential jerk limit
  double period_s = 0.004;             // interpolation period T
  std::size_t window_capacity = 4096;  // samples the look-ahead ring can hold (fixed memory)
  // The lowest tangential scale a sample's jerk_span may ask at its v_max (the look-ahead and
  // the buffers are sized for braking at it); 1 when every sample allows the full limits.
  double min_tangential_scale = 1.0;
  // Reuse the last rollout of a flat window, shifted (see Planner::RolloutKey); false simulates
  // every rollout (the reference the memo is tested against: the same motion bit for bit).
  bool reuse_rollouts = true;
};

// Throws InputError naming the value unless every limit is finite and > 0 (capacity >= 2).
void validate(const PlannerLimits& limits);

// The motion at the end of one period. The jerk is the constant jerk applied during the period
// that ends here, so (s, v, a) of the previous sample and j of this one give the cubic between.
struct MotionSample {
  double t_s = 0.0;
  double s_mm = 0.0;
  double v_mm_per_s = 0.0;
  double a_mm_per_s2 = 0.0;
  double j_mm_per_s3 = 0.0;
  std::uint8_t limit_id = 0;  // binding feed limit, or kLimitId* when the planner's own binds
  bool done = false;          // at rest exactly at L; further steps repeat this sample
  // The limit curve at s, at 100 % override (the limit of the interval holding s, see
  // LimitSample; at a sample, the interval after it): what the feed laws allow here whichever
  // limit binds, mm/s.
  // 0 before any sample.
  double v_limit_mm_per_s = 0.0;
};

class Planner {
 public:
  // Starts at rest at s = 0; ends at rest at s = length_mm. Throws InputError on bad input.
  Planner(const PlannerLimits& limits, double length_mm);

  // True while the look-ahead window wants more samples (not full, not past L, and not yet
  // covering the braking horizon from the current speed); push while it says so.
  bool wants_samples() const;
  // Appends one limit sample (s strictly increasing, first at 0, 0 < v finite, v at most the
  // reserved speed). Never allocates, never throws: a sample it cannot take is refused with its
  // result code and leaves the planner as it was.
  PushResult push(const LimitSample& sample);
  // Sizes the plan buffers for samples up to v (the machine's maximum feed; the override's 200 %
  // is included), once, before the planner is handed to the cycle: push() refuses faster
  // samples, and nothing allocates afterwards. Throws InputError, naming the numbers, when the
  // stop from that speed is longer than the planner's bound (kMaxRolloutPeriods).
  void reserve_for_speed(double v_mm_per_s);
  double reserved_speed_mm_per_s() const { return v_reserved_; }
  // Advances one period; no allocation, bounded work.
  MotionSample step();

  // Feed override as a fraction (0..2, 1 = 100 %): scales the limit curve; lowering it brakes
  // under the acceleration and jerk limits, so v may exceed the new curve while it does.
  // False (and nothing changes) outside 0..2: the caller checks the value at its edge.
  bool set_override(double fraction);
  double override_fraction() const { return override_applied_; }  // in force now
  // Feed hold: a jerk-limited stop on the path; resume() goes on from there.
  void hold();
  void resume();

  bool done() const { return done_; }
  // After done(): plans the next stretch, of length_mm, from rest at its s = 0, keeping the
  // buffers (no allocation), the clock, the override and the hold. False (and nothing
  // changes) on a length that is not finite and >= 0, or before done().
  bool restart(double length_mm);
  double length_mm() const { return length_mm_; }
  // Look-ahead window, now and at its high-water mark, in samples and in mm past s.
  std::size_t window_samples() const { return count_; }
  std::size_t window_samples_high_water() const { return count_high_water_; }
  double window_ahead_mm_high_water() const { return ahead_high_water_mm_; }
  // The bound the window respects: it asks for samples only up to this far past s (a sample
  // spacing more at most), where v_cap = 2 x the highest limit pushed (200 % override).
  double lookahead_bound_mm() const;
  // Rollouts evaluated in the last step (work per step, for benchmarks).
  std::size_t last_step_rollouts() const { return last_rollouts_; }
  // Rollouts taken from the memo instead of simulated, since construction.
  std::size_t rollouts_from_memo() const { return memo_hits_; }

  struct Kin {
    double s_mm, v_mm_per_s, a_mm_per_s2;
  };

 private:
  struct Block {
    double begin_mm, end_mm, v_max_mm_per_s;
    std::uint8_t limit_id;
    double min_on_mm_per_s;  // the lowest level of this block and every block after it
  };
  struct Cursor {
    std::size_t segment = 0;  // index into the ring (segment between sample i and i+1)
    std::size_t block = 0;
  };

  struct SpeedRange {
    double lo, hi;
  };
  // What a rollout's jerks depend on in a window no lower than the speeds it reaches (the
  // memo: planner.cpp's top, "Cruise").
  struct RolloutKey {
    double v, a, j0, scale, pol_a, pol_j, pol_final, pol_under;
    bool hold;
    bool operator==(const RolloutKey&) const = default;
  };

  struct IntervalLimit {
    double v_mm_per_s;  // interval_limit: the limit from a sample to the next
    std::uint8_t limit_id;
  };
  static IntervalLimit interval_between(const LimitSample& p, const LimitSample& q);
  PushResult classify(const LimitSample& sample) const;
  // (ring_index, sample, interval_limit, cubic_step and advance are inline below the class:
  // the exact checks and rollouts of planner_policy.cpp call them every simulated period.)
  std::size_t ring_index(std::size_t i) const;  // of the i-th sample of the window
  const LimitSample& sample(std::size_t i) const;
  SpeedRange period_speeds(const Kin& x, double j) const;
  void settle_on(double w_mm_per_s);
  double horizon_mm(double v_mm_per_s, double a_mm_per_s2) const;
  void drop_passed_samples();
  void build_blocks(double scale, double stop_mm);
  // v_hi_out: the period's highest speed (set whenever it returns true)
  bool check_period(const Kin& x, double j, Cursor& c, double scale, double stop_mm,
                    double* v_hi_out = nullptr) const;
  double window_min() const;
  double policy(const Kin& x, Cursor& c, std::uint8_t* binding_id) const;
  bool rollout(double j0, double scale_check, double stop_mm, std::vector<double>& out,
               std::size_t& out_n);
  bool rollout_member(double j0, double scale_check, double stop_mm, std::vector<double>& out,
                      std::size_t& out_n);  // rollout() with π's member in force
  // step()'s cases (planner.cpp): a landing's next period, a hold, a lowered override, and the
  // follower, with what they share.
  struct StepFrame {
    double real_stop, stop;  // the last sample or L; and that within the horizon
    bool at_rest;
    double j_fallback;  // the committed plan's next jerk (0 past its end)
  };
  struct TopJerk {
    double j, a_here;  // j_top, and the acceleration limit it is taken at
  };
  MotionSample step_landing();
  MotionSample step_hold(const StepFrame& f);
  MotionSample step_override_lowered(const StepFrame& f);
  MotionSample step_follow(const StepFrame& f);
  TopJerk top_jerk() const;
  bool follow_local_limit(const StepFrame& f, double j_top);
  void bisect_jerk(const StepFrame& f, double j_top);
  void commit_fallback(const StepFrame& f, std::uint8_t limit_id);
  std::uint8_t binding_limit(double stop_mm) const;
  bool try_landing();
  bool cut_landing_for_hold();
  void take_best(double j, std::uint8_t limit_id);
  enum class LandBase { zero, plan, scurve, reach };  // what a landing's correction starts from
  bool land_with(std::size_t n, LandBase base);
  bool snap_fits(std::size_t n, const Kin& end) const;  // the end snap within the jerk limit
  bool take_landing(std::size_t n);                     // land_with's jerks become the plan
  bool scurve_base(std::size_t n);
  double reach_base(std::size_t n, double v_cap, double jerk_fraction);
  double v_settle(const Kin& x) const;
  double deadbeat_jerk(const Kin& x, double w, bool* ok) const;
  double track(const Kin& x, double w) const;
  double need_mm(const Kin& x, double w) const;
  double final_jerk(double w_mm_per_s) const;
  Kin advance(const Kin& x, double j) const;
  Kin cubic_step(const Kin& x, double j) const;  // one period at jerk j, exactly, no snapping
  void commit(double j, std::uint8_t limit_id);
  double limit_at(double s_mm) const;
  double interval_limit(std::size_t i) const;  // between samples i and i + 1 (see LimitSample)

  // limits
  double a_max_, j_max_, period_s_, length_mm_;
  double scale_floor_ = 1.0;  // min_tangential_scale
  // The brake policy's limits this step: a_max and j_max times the smallest tangential scale
  // in the window (so that every period π simulates keeps the local limits).
  double pol_a_ = 0.0, pol_j_ = 0.0;
  bool any_scaled_ = false;  // a sample with a jerk_span constraint was pushed
  bool any_axis_ = false;    // a sample with an accel_scale or jerk_scale below 1 was pushed
  // The smallest accel_scale and jerk_scale of the samples from i on over [s, s1] (per-axis
  // limits; 1 without them), and of the whole window.
  struct AxisScale {
    double accel, jerk;
  };
  AxisScale window_axis_scale() const;
  // The window's smallest accel_scale and jerk_scale, kept as samples come and go (a scan of
  // the window every period was 12 % of the slow-Z spiral replay: docs/planner.md §4).
  SlidingMin accel_scale_min_, jerk_scale_min_;
  AxisScale axis_scale_at(double s_mm) const;
  // A landing's limits: a_max and j_max times the window's axis scales (the landing runs to L
  // inside the window).
  double land_a_max_ = 0.0, land_j_max_ = 0.0;
  void set_policy_limits();
  double scale_at(double s_mm, double v_mm_per_s) const;
  double sample_scale(std::size_t i, double v_mm_per_s) const;
  double v_eps_, a_eps_;
  // ring of samples
  std::vector<LimitSample> ring_;
  std::vector<IntervalLimit> interval_ring_;  // [k]: from ring_[k] to the sample after it
  // [k]: the sequence number of the first interval of the run of equal limits (v_mm_per_s)
  // that holds interval k; build_blocks merges a run in one step (run_last).
  std::vector<std::uint64_t> run_ring_;
  std::uint64_t front_seq_ = 0;  // the sequence number of sample(0) (one per sample pushed)
  std::size_t run_last(std::size_t i, double stop_mm) const;
  std::size_t head_ = 0, count_ = 0, count_high_water_ = 0;
  double ahead_high_water_mm_ = 0.0;
  double v_top_pushed_ = 0.0;
  double v_reserved_ = 0.0;  // the speed the plan buffers are sized for (reserve_for_speed)
  bool saw_end_ = false;
  // blocks (policy targets) of the current step
  std::vector<Block> blocks_;
  std::size_t block_count_ = 0;
  // when they were built (periods_), for which scale and stop
  std::int64_t blocks_period_ = -1;
  double blocks_scale_ = 0.0, blocks_stop_mm_ = 0.0;
  // the last rollout that rested within a flat window (see RolloutKey): its jerks, its key,
  // the highest speed it reached or looked from, and its length
  std::vector<double> memo_;
  bool reuse_rollouts_ = true;
  std::size_t memo_n_ = 0, memo_hits_ = 0;
  RolloutKey memo_key_{};
  double memo_v_need_ = 0.0, memo_span_mm_ = 0.0;
  // state
  Kin x_{0.0, 0.0, 0.0};
  double t_s_ = 0.0;
  std::int64_t periods_ = 0;
  bool done_ = false;
  MotionSample last_{};
  // plans: the committed plan (a validated rollout, tail from plan_pos_), and scratch
  std::vector<double> plan_, trial_, best_;
  std::size_t plan_n_ = 0, plan_pos_ = 0, best_n_ = 0;
  std::size_t rollout_cap_ = 0;
  bool landing_ = false;
  // landing scratch
  std::vector<double> land_j_, land_base_;
  std::size_t land_first_ = 0;  // the S-curve base's first braking period
  // override and hold
  double override_applied_ = 1.0, override_target_ = 1.0;
  bool hold_ = false;
  bool policy_hold_ = false;
  // π's member in force (see rollout): its final ramp (fraction of j_max) and how far below a
  // demanding block's level it settles (fraction).
  double pol_final_ = 0.0, pol_under_ = 0.0;
  std::size_t last_rollouts_ = 0;
};

inline std::size_t Planner::ring_index(std::size_t i) const {
  const std::size_t k = head_ + i;  // < 2 x the ring's size: a subtraction, not a division
  return k < ring_.size() ? k : k - ring_.size();
}

inline const LimitSample& Planner::sample(std::size_t i) const {
  return ring_[ring_index(i)];
}

inline double Planner::interval_limit(std::size_t i) const {
  return i + 1 < count_ ? interval_ring_[ring_index(i)].v_mm_per_s : sample(i).v_max_mm_per_s;
}

// One period of constant jerk j from x (exact cubic).
inline Planner::Kin Planner::cubic_step(const Kin& x, double j) const {
  const double T = period_s_;
  return Kin{x.s_mm + x.v_mm_per_s * T + 0.5 * x.a_mm_per_s2 * T * T + j * T * T * T / 6.0,
             x.v_mm_per_s + x.a_mm_per_s2 * T + 0.5 * j * T * T, x.a_mm_per_s2 + j * T};
}

// cubic_step, with rest snapped to exact zeros.
inline Planner::Kin Planner::advance(const Kin& x, double j) const {
  Kin y = cubic_step(x, j);
  if (std::abs(y.v_mm_per_s) <= v_eps_ && std::abs(y.a_mm_per_s2) <= a_eps_) {
    y.v_mm_per_s = 0.0;
    y.a_mm_per_s2 = 0.0;
  }
  y.s_mm = std::max(y.s_mm, x.s_mm);
  return y;
}

// Pushes samples from curve[next...] while the planner wants them; advances next past each one
// taken. Stops at the first refusal and returns it.
PushResult push_available(Planner& planner, std::span<const LimitSample> curve, std::size_t& next);

// The whole motion for a limit curve given at once (tests, replay): reserves for the curve's
// highest speed, then step() until done. Throws InputError on a sample the planner refuses or
// if the motion does not finish within max_periods.
std::vector<MotionSample> plan_all(const PlannerLimits& limits, double length_mm,
                                   std::span<const LimitSample> curve,
                                   std::size_t max_periods = 50'000'000);

// S-curve braking distance from v to v_t (v >= v_t), starting and ending at a = 0.
double braking_distance_mm(double v_mm_per_s, double v_target_mm_per_s, double a_max, double j_max);

}  // namespace ncd::motion
