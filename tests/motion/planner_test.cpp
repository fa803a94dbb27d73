// Look-ahead feed planner: every motion is checked against an independent, slow reference of
// the constraints (exact crossing times of every sample inside every period), random limit
// curves in bulk (seed printed; NCD_TEST_SEED overrides), closed-form S-curve durations, the
// memory bound over an hour of periods, override and hold.
#include "motion/planner.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "tests/common/sanitized.hpp"
#include "tests/common/seed.hpp"

namespace ncd::motion {
namespace {

constexpr double kTol = 1e-9;  // relative tolerance of the checks (rounding only)

// The limit over the interval from curve[k] to curve[k + 1]: its own value where given
// (LimitSample::v_after_mm_per_s), else the smaller of its two ends.
double interval_value(const std::vector<LimitSample>& curve, std::size_t k) {
  if (std::isfinite(curve[k].v_after_mm_per_s)) return curve[k].v_after_mm_per_s;
  return std::min(curve[k].v_max_mm_per_s, curve[k + 1].v_max_mm_per_s);
}

// The limit the curve sets at s: the value of the interval holding s (of both adjacent
// intervals at a sample point); 0 outside the curve.
double limit_at(const std::vector<LimitSample>& curve, double s) {
  auto it = std::upper_bound(curve.begin(), curve.end(), s,
                             [](double x, const LimitSample& p) { return x < p.s_mm; });
  if (it == curve.begin() || it == curve.end()) {
    if (it == curve.end() && curve.size() >= 2 && curve.back().s_mm == s) {
      return interval_value(curve, curve.size() - 2);
    }
    return 0.0;
  }
  const auto i = static_cast<std::size_t>(it - curve.begin());  // curve[i-1].s <= s < curve[i].s
  double v = interval_value(curve, i - 1);
  if (curve[i - 1].s_mm == s && i >= 2) v = std::min(v, interval_value(curve, i - 2));
  return v;
}

struct Cubic {
  double s, v, a, j;
  double pos(double t) const { return s + v * t + 0.5 * a * t * t + j * t * t * t / 6.0; }
  double vel(double t) const { return v + a * t + 0.5 * j * t * t; }
  // Max of v over [t0, t1]: ends and the stationary point.
  double vmax(double t0, double t1) const {
    double m = std::max(vel(t0), vel(t1));
    if (j != 0.0) {
      const double ts = -a / j;
      if (ts > t0 && ts < t1) m = std::max(m, vel(ts));
    }
    return m;
  }
  double vmin(double t0, double t1) const {
    double m = std::min(vel(t0), vel(t1));
    if (j != 0.0) {
      const double ts = -a / j;
      if (ts > t0 && ts < t1) m = std::min(m, vel(ts));
    }
    return m;
  }
};

struct Report {
  double duration_s = 0.0;
  double v_peak = 0.0;
  int failures = 0;
};

// Checks a whole motion against the limits and the curve (scaled by limit_scale); returns the
// number of violations (each reported once with its period).
Report check_motion(const std::vector<MotionSample>& m, const std::vector<LimitSample>& curve,
                    const PlannerLimits& lim, double length_mm, double limit_scale = 1.0,
                    bool expect_done = true) {
  Report r;
  const double T = lim.period_s;
  auto fail = [&](const std::string& what, std::size_t i) {
    if (r.failures++ < 5) ADD_FAILURE() << what << " at period " << i << " t=" << m[i].t_s;
  };
  if (m.empty()) {
    fail("empty motion", 0);
    return r;
  }
  if (m[0].s_mm != 0.0 || m[0].v_mm_per_s != 0.0 || m[0].a_mm_per_s2 != 0.0)
    fail("not at rest at 0", 0);
  const double v_scale = lim.a_max_mm_per_s2 * T + lim.j_max_mm_per_s3 * T * T;
  for (std::size_t i = 1; i < m.size(); ++i) {
    const MotionSample& p = m[i - 1];
    const MotionSample& q = m[i];
    const Cubic c{p.s_mm, p.v_mm_per_s, p.a_mm_per_s2, q.j_mm_per_s3};
    if (std::abs(q.t_s - p.t_s - T) > 1e-9 * T) fail("period not T", i);
    if (std::abs(q.j_mm_per_s3) > lim.j_max_mm_per_s3 * (1 + kTol)) fail("jerk over j_max", i);
    if (std::abs(q.a_mm_per_s2) > lim.a_max_mm_per_s2 * (1 + kTol)) fail("accel over a_max", i);
    // The samples are the cubic's values at the period end (rest snapped to exact zeros).
    if (std::abs(c.pos(T) - q.s_mm) > 1e-9 * std::max(1.0, length_mm)) fail("s off cubic", i);
    if (std::abs(c.vel(T) - q.v_mm_per_s) > 1e-9 * v_scale) fail("v off cubic", i);
    if (std::abs(p.a_mm_per_s2 + q.j_mm_per_s3 * T - q.a_mm_per_s2) > 1e-9 * v_scale / T)
      fail("a off cubic", i);
    if (q.s_mm < p.s_mm) fail("s decreased", i);
    if (q.s_mm > length_mm) fail("overshoot of L", i);
    if (c.vmin(0, T) < -1e-9 * v_scale) fail("negative speed", i);
    r.v_peak = std::max(r.v_peak, c.vmax(0, T));
    // Exact: split the period where s crosses a sample, then v max on each piece.
    double t0 = 0.0;
    double s_end = c.pos(T);
    auto it = std::upper_bound(curve.begin(), curve.end(), c.pos(0),
                               [](double x, const LimitSample& e) { return x < e.s_mm; });
    while (true) {
      double t1 = T;
      const bool crosses = it != curve.end() && it->s_mm < s_end;
      if (crosses) {  // bisection on the monotone cubic, to the last bit
        double lo = t0, hi = T;
        for (int k = 0; k < 200 && lo < hi; ++k) {
          const double mid = 0.5 * (lo + hi);
          if (mid <= lo || mid >= hi) break;
          (c.pos(mid) < it->s_mm ? lo : hi) = mid;
        }
        t1 = hi;
      }
      const double s_mid = c.pos(0.5 * (t0 + t1));
      const double lim_v = limit_at(curve, std::clamp(s_mid, c.pos(t0), c.pos(t1))) * limit_scale;
      const double v_hi = c.vmax(t0, t1);
      if (v_hi > lim_v * (1 + kTol) + 1e-12) {
        fail("speed " + std::to_string(v_hi) + " over limit " + std::to_string(lim_v) +
                 " at s=" + std::to_string(s_mid),
             i);
        break;
      }
      if (!crosses) break;
      t0 = t1;
      ++it;
    }
  }
  const MotionSample& e = m.back();
  if (expect_done) {
    if (!e.done) fail("not done", m.size() - 1);
    if (e.s_mm != length_mm || e.v_mm_per_s != 0.0 || e.a_mm_per_s2 != 0.0)
      fail("does not end at rest exactly at L: s=" + std::to_string(e.s_mm), m.size() - 1);
  }
  r.duration_s = e.t_s;
  return r;
}

// The highest limit of a curve: what its planner's buffers are reserved for.
double top_speed(const std::vector<LimitSample>& c) {
  double v = 0.0;
  for (const LimitSample& q : c) {
    v = std::max(v, q.v_max_mm_per_s);
    if (std::isfinite(q.v_after_mm_per_s)) v = std::max(v, q.v_after_mm_per_s);
  }
  return v;
}

PlannerLimits limits(double a, double j, double T) {
  PlannerLimits l;
  l.a_max_mm_per_s2 = a;
  l.j_max_mm_per_s3 = j;
  l.period_s = T;
  return l;
}

std::vector<LimitSample> flat(double length_mm, double v, double spacing_mm) {
  std::vector<LimitSample> c;
  for (double s = 0.0;; s += spacing_mm) {
    c.push_back({std::min(s, length_mm), v, 1});
    if (s >= length_mm) break;
  }
  return c;
}

// Time-optimal rest-to-rest duration on a flat limit (7- or 5-phase S-curve); a bisection on
// the peak speed when the path is too short to reach v.
double scurve_duration(double length_mm, double v, double a, double j) {
  const auto t_acc = [&](double vp) {
    return vp >= a * a / j ? vp / a + a / j : 2.0 * std::sqrt(vp / j);
  };
  if (v * t_acc(v) <= length_mm) return 2.0 * t_acc(v) + (length_mm - v * t_acc(v)) / v;
  double lo = 0.0, hi = v;
  for (int k = 0; k < 200; ++k) {
    const double mid = 0.5 * (lo + hi);
    (mid * t_acc(mid) < length_mm ? lo : hi) = mid;
  }
  return 2.0 * t_acc(lo);
}

TEST(PlannerLimits, RejectsDegenerateLimitsNamingTheValue) {
  const auto msg = [](PlannerLimits l) {
    try {
      Planner p(l, 10.0);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(msg(limits(0.0, 2e4, 0.004)).find("a_max_mm_per_s2"), std::string::npos);
  EXPECT_NE(msg(limits(-5.0, 2e4, 0.004)).find("a_max_mm_per_s2"), std::string::npos);
  EXPECT_NE(msg(limits(1e3, 0.0, 0.004)).find("j_max_mm_per_s3"), std::string::npos);
  EXPECT_NE(msg(limits(1e3, 2e4, 0.0)).find("period_s"), std::string::npos);
  EXPECT_NE(msg(limits(1e3, std::nan(""), 0.004)).find("j_max_mm_per_s3"), std::string::npos);
  EXPECT_THROW(Planner(limits(1e3, 2e4, 0.004), -1.0), InputError);
  EXPECT_EQ(msg(limits(1e3, 2e4, 0.004)), "");
}

// push() refuses a bad sample with a result code, never an exception, and leaves the planner as
// it was (the sample after a refused one is judged against the last one taken).
TEST(Planner, RejectsBadSamplesWithResultCodes) {
  Planner p(limits(1e3, 2e4, 0.004), 10.0);
  p.reserve_for_speed(20.0);
  EXPECT_EQ(p.push({1.0, 10.0, 1}), PushResult::FirstNotAtZero);
  EXPECT_EQ(p.push({0.0, 10.0, 1}), PushResult::Ok);
  EXPECT_EQ(p.push({0.0, 10.0, 1}), PushResult::NotIncreasing);
  EXPECT_EQ(p.push({std::nan(""), 10.0, 1}), PushResult::NotIncreasing);
  EXPECT_EQ(p.push({1.0, -1.0, 1}), PushResult::SpeedInvalid);
  EXPECT_EQ(p.push({1.0, std::nan(""), 1}), PushResult::SpeedInvalid);
  EXPECT_EQ(p.push({1.0, 10.0, kLimitIdJerk}), PushResult::IdReserved);
  EXPECT_EQ(p.push({1.0, 10.0, 1, {}, 5.0, 1}), PushResult::AfterInvalid);
  EXPECT_EQ(p.push({1.0, 10.0, 1, {}, std::nan(""), 1}), PushResult::AfterInvalid);
  EXPECT_EQ(p.push({1.0, 10.0, 1, {}, 20.0, kLimitIdJerk}), PushResult::IdReserved);
  EXPECT_EQ(p.push({1.0, 10.0, 1, {-1.0, 0.0, 1.0}}), PushResult::SpanInvalid);
  EXPECT_EQ(p.push({1.0, 10.0, 1, {0.0, 0.0, 0.0}}), PushResult::SpanInvalid);
  EXPECT_EQ(p.push({1.0, 20.5, 1}), PushResult::AboveReserve);  // buffers are sized for 20
  EXPECT_EQ(p.push({1.0, 10.0, 1, {}, 21.0, 1}), PushResult::AboveReserve);
  EXPECT_EQ(p.push({2.0, 0.0, 1}), PushResult::SpeedInvalid);  // a stop must end the path
  EXPECT_NE(describe(PushResult::SpeedInvalid, {2.0, 0.0, 1}, 20.0).find("end the path there"),
            std::string::npos);
  EXPECT_NE(describe(PushResult::AboveReserve, {1.0, 20.5, 1}, 20.0).find("20.000000 mm/s"),
            std::string::npos);
  EXPECT_EQ(p.window_samples(), 1u);  // only the good one was taken
  EXPECT_EQ(p.push({1.0, 10.0, 1}), PushResult::Ok);
  Planner q(limits(1e3, 2e4, 0.004), 10.0);
  EXPECT_FALSE(q.set_override(2.5));
  EXPECT_FALSE(q.set_override(-0.1));
  EXPECT_FALSE(q.set_override(std::nan("")));
  EXPECT_EQ(q.override_fraction(), 1.0);
  EXPECT_TRUE(q.set_override(1.5));
  EXPECT_FALSE(q.restart(5.0));  // not at rest at its end yet
}

// The buffers are sized once, by reserve_for_speed, and nothing grows them afterwards: a slow
// move (F10) after a fast one lands without writing past them (LinuxCNC's flowsnake.ngc found
// the landing of such a move writing past its buffers; docs/planner.md §4).
TEST(Planner, ASlowMoveLandsWithinTheBuffersSizedForTheTopSpeed) {
  const PlannerLimits l = limits(3000.0, 60000.0, 0.004);
  for (const double length_mm : {0.05, 0.3, 1.0, 3.0}) {
    const std::vector<LimitSample> c{{0.0, 10.0 / 60.0, 1}, {length_mm, 10.0 / 60.0, 1}};
    Planner p(l, length_mm);
    p.reserve_for_speed(250.0);
    std::size_t next = 0;
    MotionSample m;
    std::size_t n = 0;
    for (; n < 1'000'000 && !m.done; ++n) {
      ASSERT_EQ(push_available(p, c, next), PushResult::Ok);
      m = p.step();
    }
    ASSERT_TRUE(m.done) << length_mm;
    EXPECT_DOUBLE_EQ(m.s_mm, length_mm);
    // At least the time of the move at F10, and not much more.
    EXPECT_GE(static_cast<double>(n) * l.period_s, length_mm / (10.0 / 60.0) - 1e-9) << length_mm;
  }
}

// An interval's own limit (LimitSample::v_after_mm_per_s) is held instead of the smaller of
// its two samples: a 30 mm interval whose ends are at 20 mm/s but whose own limit is 80 mm/s
// is crossed above 20 and never above 80, the interval after it (no own limit) at 20 at most.
TEST(Planner, HoldsAnIntervalsOwnLimitWhereGiven) {
  const PlannerLimits l = limits(1e3, 2e4, 0.004);
  std::vector<LimitSample> c{{0.0, 20.0, 1, {}, 80.0, 2}, {30.0, 20.0, 1}, {60.0, 20.0, 1}};
  const auto m = plan_all(l, 60.0, c);
  EXPECT_EQ(check_motion(m, c, l, 60.0).failures, 0);
  double v_first = 0.0, v_second = 0.0;
  for (const MotionSample& s : m) {
    double& v_peak = s.s_mm < 30.0 ? v_first : v_second;
    v_peak = std::max(v_peak, s.v_mm_per_s);
  }
  EXPECT_GT(v_first, 75.0);
  EXPECT_LE(v_first, 80.0 * (1.0 + kTol));
  EXPECT_LE(v_second, 20.0 * (1.0 + kTol));
  // The same curve without the interval's own limit: 20 mm/s all along.
  c[0].v_after_mm_per_s = std::numeric_limits<double>::infinity();
  double v_node_rule = 0.0;
  for (const MotionSample& s : plan_all(l, 60.0, c))
    v_node_rule = std::max(v_node_rule, s.v_mm_per_s);
  EXPECT_LE(v_node_rule, 20.0 * (1.0 + kTol));
}

TEST(Planner, ZeroLengthIsDoneAtOnce) {
  const std::vector<LimitSample> c = {{0.0, 10.0, 1}, {1.0, 10.0, 1}};
  const auto m = plan_all(limits(1e3, 2e4, 0.004), 0.0, c);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_TRUE(m[1].done);
  EXPECT_EQ(m[1].t_s, 0.0);
  EXPECT_EQ(m[1].s_mm, 0.0);
}

TEST(Planner, CruisesExactlyAtAFlatLimit) {
  const PlannerLimits l = limits(1000.0, 20000.0, 0.004);
  const auto c = flat(300.0, 50.0, 0.5);
  const auto m = plan_all(l, 300.0, c);
  const Report r = check_motion(m, c, l, 300.0);
  EXPECT_EQ(r.failures, 0);
  std::size_t at_limit = 0;
  for (const auto& s : m) at_limit += std::abs(s.v_mm_per_s - 50.0) <= 1e-9;
  // 300 mm at 50 mm/s is 6 s; braking and accelerating take 0.1 s each.
  EXPECT_GT(static_cast<double>(at_limit) * l.period_s, 5.6) << at_limit;
  EXPECT_LE(r.v_peak, 50.0 * (1 + kTol));
}

TEST(Planner, RestToRestMatchesClosedFormSCurveWithinOnePeriod) {
  struct Case {
    double L, v, a, j, T;
  };
  const Case cases[] = {
      {100.0, 50.0, 1000.0, 20000.0, 0.004},  // 7 phases
      {100.0, 10.0, 1000.0, 20000.0, 0.004},  // 5 phases (v < a²/j: a_max not reached)
      {40.0, 120.0, 3000.0, 60000.0, 0.002},  // 7 phases
      {2.0, 100.0, 1000.0, 20000.0, 0.004},   // v not reached: peak found by bisection
      {0.3, 100.0, 500.0, 5000.0, 0.001},     // short, soft
  };
  for (const Case& k : cases) {
    const PlannerLimits l = limits(k.a, k.j, k.T);
    const auto c = flat(k.L, k.v, k.L / 7.0);
    const auto m = plan_all(l, k.L, c);
    const Report r = check_motion(m, c, l, k.L);
    EXPECT_EQ(r.failures, 0);
    const double want = scurve_duration(k.L, k.v, k.a, k.j);
    EXPECT_GE(r.duration_s, want - 1e-9) << "faster than time-optimal?";
    // 1–9 periods more before the landings of docs/planner.md §6 (the short-move base among
    // them); 0.2–1.8 now.
    EXPECT_LE(r.duration_s, want + 2.0 * k.T) << "L=" << k.L << " v=" << k.v << " want " << want;
    std::printf("S-curve L=%g v=%g: %.4f s vs closed form %.4f s (+%.1f periods)\n", k.L, k.v,
                r.duration_s, want, (r.duration_s - want) / k.T);
  }
}

// Random rest-to-rest moves on a flat limit (lengths from 10 µm to 60 mm, limits and periods
// spread over two decades; the seed printed) against the closed-form time-optimal S-curve: every
// constraint kept, never faster, and near it. Measured on seeds 1–3 (1500 moves each): 0.83–0.86
// periods beyond it on average, 5–5.3 % of the moves more than two periods, the worst 4.5–6.8
// periods (long moves at T = 1 ms and a low jerk that peak below their cap). Before the
// short-move landing (docs/planner.md §6): 1.41–1.47 on average, 21–22 % beyond two periods,
// the worst 6.8–12.8. Over seeds 2000–2060: mean at most 0.87, at most 99 beyond two, the worst
// 10.0 periods (13.2 before a slow cruise at its limit, below a_max T, kept its landing to the
// time-optimal stop: seed 2008, 1.65 mm at 6.4 mm/s, a_max 2457 mm/s², T 4 ms). The same 1500
// moves run in Debug, so the thresholds mean the same.
TEST(Planner, RandomRestToRestNearTheClosedForm) {
  const std::uint64_t seed = ncd::test::seed();
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double periods[] = {0.001, 0.002, 0.004};
  constexpr int kCases = 1500;
  double worst = 0.0, sum = 0.0;
  int beyond_two = 0;
  for (int i = 0; i < kCases; ++i) {
    const PlannerLimits l = limits(200.0 + 2800.0 * u(rng), 2000.0 + 58000.0 * u(rng),
                                   periods[static_cast<std::size_t>(u(rng) * 2.999)]);
    const double length_mm = 0.01 * std::pow(6000.0, u(rng));
    const double v = 5.0 + 195.0 * u(rng);
    const auto c = flat(length_mm, v, std::max(0.05, length_mm * u(rng)));
    const auto m = plan_all(l, length_mm, c);
    const Report r = check_motion(m, c, l, length_mm);
    const double want = scurve_duration(length_mm, v, l.a_max_mm_per_s2, l.j_max_mm_per_s3);
    const double extra = (r.duration_s - want) / l.period_s;
    ASSERT_EQ(r.failures, 0) << "case " << i;
    ASSERT_GE(extra, -1e-6) << "case " << i << ": faster than time-optimal?";
    EXPECT_LE(extra, 20.0) << "case " << i << " L=" << length_mm << " v=" << v
                           << " a=" << l.a_max_mm_per_s2 << " j=" << l.j_max_mm_per_s3
                           << " T=" << l.period_s;
    worst = std::max(worst, extra);
    sum += extra;
    beyond_two += extra > 2.0 ? 1 : 0;
  }
  std::printf(
      "%d random rest-to-rest moves: periods beyond the closed form: mean %.2f, worst %.2f, "
      "%d beyond two\n",
      kCases, sum / kCases, worst, beyond_two);
  EXPECT_LE(sum / kCases, 1.0);
  EXPECT_LE(beyond_two, kCases / 10);
}

TEST(Planner, SuddenDropIsMetAtTheNewLevelWithoutDip) {
  const PlannerLimits l = limits(1000.0, 20000.0, 0.004);
  std::vector<LimitSample> c;
  for (int i = 0; i <= 600; ++i) c.push_back({0.1 * i, i < 300 ? 80.0 : 10.0, 2});
  const auto m = plan_all(l, 60.0, c);
  EXPECT_EQ(check_motion(m, c, l, 60.0).failures, 0);
  // The slowdown started early enough (checked above) and not needlessly early: the speed at
  // the drop is the new level, reached settled (a ≈ 0), with no dip below it after.
  double v_at_drop = -1.0, v_min_after = 1e9;
  for (const auto& s : m) {
    if (s.s_mm <= 30.0) v_at_drop = s.v_mm_per_s;
    if (s.s_mm > 30.0 && s.s_mm < 55.0) v_min_after = std::min(v_min_after, s.v_mm_per_s);
  }
  EXPECT_GT(v_at_drop, 9.0);
  EXPECT_GT(v_min_after, 9.0);
}

TEST(Planner, PathShorterThanBrakingDistance) {
  const PlannerLimits l = limits(1000.0, 20000.0, 0.004);
  // Braking from 200 mm/s needs 20 mm; the path has 0.05 mm.
  const std::vector<LimitSample> c = {{0.0, 200.0, 1}, {0.05, 200.0, 1}};
  const auto m = plan_all(l, 0.05, c);
  EXPECT_EQ(check_motion(m, c, l, 0.05).failures, 0);
  EXPECT_LE(m.back().t_s, scurve_duration(0.05, 200.0, 1000.0, 20000.0) + 10.0 * l.period_s);
}

// A random limit curve: flat runs, steps, dense smooth stretches, occasionally very low.
std::vector<LimitSample> random_curve(std::mt19937_64& rng, double length_mm) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<LimitSample> c;
  double s = 0.0;
  while (true) {
    const double kind = u(rng);
    const double run = length_mm * (0.02 + 0.3 * u(rng));
    const double level = 2.0 + 150.0 * u(rng) * u(rng);
    const double spacing = kind < 0.4 ? run : (0.02 + 0.5 * u(rng)) * std::min(run, 5.0);
    const double amp = kind < 0.7 ? 0.0 : 0.6 * level * u(rng);
    const double wave = 0.5 + 10.0 * u(rng);
    const auto id = static_cast<std::uint8_t>(kind * 4.0);
    const double end = s + run;
    for (; s < end && s < length_mm; s += spacing) {
      c.push_back({s, std::max(0.5, level + amp * std::sin(s / wave)), id});
    }
    if (s >= length_mm) break;
  }
  c.push_back({std::max(length_mm, c.back().s_mm + 1e-3), 5.0 + 100.0 * u(rng), 9});
  // Half the curves give some intervals their own limit (an upstream that knows the minimum
  // over each interval, as the job's sampler does): up to 3x the sample's own.
  if (u(rng) < 0.5) {
    for (std::size_t k = 0; k + 1 < c.size(); ++k) {
      if (u(rng) < 0.5) {
        c[k].v_after_mm_per_s = c[k].v_max_mm_per_s * (1.0 + 2.0 * u(rng));
        c[k].after_limit_id = 7;
      }
    }
  }
  return c;
}

TEST(Planner, RandomLimitCurvesKeepEveryConstraint) {
  const std::uint64_t seed = ncd::test::seed();
  std::printf("Planner random curves: NCD_TEST_SEED=%llu\n", static_cast<unsigned long long>(seed));
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double periods[] = {0.001, 0.002, 0.004};
  int cases = 0, total_failures = 0;
#ifdef NDEBUG
  constexpr int kCases = 400;
#else
  constexpr int kCases = 150;  // Debug + sanitizers: about 20 s
#endif
  for (; cases < kCases; ++cases) {
    const PlannerLimits l = limits(200.0 + 2800.0 * u(rng), 2000.0 + 58000.0 * u(rng),
                                   periods[static_cast<std::size_t>(u(rng) * 2.999)]);
    const double length_mm = u(rng) < 0.1 ? 0.01 + u(rng) : 1.0 + 60.0 * u(rng);
    const auto c = random_curve(rng, length_mm);
    std::vector<MotionSample> m;
    ASSERT_NO_THROW(m = plan_all(l, length_mm, c, 2'000'000)) << "case " << cases;
    const Report r = check_motion(m, c, l, length_mm);
    total_failures += r.failures;
    if (r.failures > 0) {
      ADD_FAILURE() << "case " << cases << " seed " << seed << " L=" << length_mm
                    << " a=" << l.a_max_mm_per_s2 << " j=" << l.j_max_mm_per_s3
                    << " T=" << l.period_s;
      break;
    }
  }
  EXPECT_EQ(total_failures, 0);
}

TEST(Planner, WindowStaysBoundedOverAnHourOfPeriods) {
  const PlannerLimits l = limits(1000.0, 20000.0, 0.004);
  const double length_mm = 1e6;
  const double spacing = 0.25;
  // Repetitive 20 mm pattern: 60 mm/s, a drop to 15, a stretch at 40 with a ripple.
  const auto limit = [](double s) {
    const double x = std::fmod(s, 20.0);
    if (x < 12.0) return 60.0;
    if (x < 14.0) return 15.0;
    return 40.0 + 5.0 * std::sin(x);
  };
  Planner p(l, length_mm);
  p.reserve_for_speed(60.0);
  double next_s = 0.0;
  std::size_t hw_at_10pct = 0;
  double prev_s = 0.0;
  const std::size_t periods = 900'000;
  for (std::size_t i = 0; i < periods; ++i) {
    while (p.wants_samples()) {
      ASSERT_EQ(p.push({next_s, limit(next_s), 3}), PushResult::Ok);
      next_s += spacing;
    }
    const MotionSample m = p.step();
    ASSERT_GE(m.s_mm, prev_s);
    ASSERT_LE(std::abs(m.a_mm_per_s2), l.a_max_mm_per_s2 * (1 + kTol));
    const double k = std::floor(m.s_mm / spacing);  // the sampled curve: min of the two ends
    const double sampled = std::min(limit(k * spacing), limit((k + 1.0) * spacing));
    ASSERT_LE(m.v_mm_per_s, sampled * (1 + kTol) + 1e-9) << m.s_mm;
    prev_s = m.s_mm;
    if (i == periods / 10) hw_at_10pct = p.window_samples_high_water();
  }
  const double bound_mm = p.lookahead_bound_mm();
  EXPECT_GT(prev_s, 100'000.0);  // it moved: ~36 mm/s on average for an hour
  EXPECT_LE(p.window_ahead_mm_high_water(), bound_mm + spacing);
  EXPECT_LE(p.window_samples_high_water(),
            static_cast<std::size_t>(std::ceil(bound_mm / spacing)) + 3);
  EXPECT_EQ(p.window_samples_high_water(), hw_at_10pct);  // no growth with path length
  std::printf("window high water: %zu samples, %.3f mm ahead (bound %.3f mm)\n",
              p.window_samples_high_water(), p.window_ahead_mm_high_water(), bound_mm);
}

TEST(Planner, FullWindowCapacityOnlySlowsDown) {
  PlannerLimits l = limits(1000.0, 20000.0, 0.004);
  l.window_capacity = 8;  // far fewer samples than the braking distance needs
  const auto c = flat(30.0, 80.0, 0.1);
  const auto m = plan_all(l, 30.0, c);
  EXPECT_EQ(check_motion(m, c, l, 30.0).failures, 0);
}

// Streaming with override changes or a hold in the middle; returns the motion.
std::vector<MotionSample> run_with(const PlannerLimits& l, double length_mm,
                                   const std::vector<LimitSample>& c,
                                   const std::function<void(Planner&, std::size_t)>& event) {
  Planner p(l, length_mm);
  p.reserve_for_speed(top_speed(c));
  std::vector<MotionSample> out{MotionSample{}};
  std::size_t next = 0;
  for (std::size_t i = 0; i < 1'000'000 && !out.back().done; ++i) {
    event(p, i);
    EXPECT_EQ(push_available(p, c, next), PushResult::Ok);
    out.push_back(p.step());
  }
  return out;
}

TEST(Planner, OverrideRaisesAndLowersTheFeedWithinAccelerationAndJerk) {
  const PlannerLimits l = limits(1000.0, 20000.0, 0.004);
  const auto c = flat(400.0, 50.0, 0.5);
  const auto m = run_with(l, 400.0, c, [](Planner& p, std::size_t i) {
    if (i == 250) p.set_override(1.5);  // 1 s in: 75 mm/s
    if (i == 750) p.set_override(0.4);  // 3 s in: 20 mm/s
  });
  // Everything holds against the highest scale; a and j always.
  EXPECT_EQ(check_motion(m, c, l, 400.0, 1.5).failures, 0);
  double v_high = 0.0, v_late = 0.0;
  for (const auto& s : m) {
    if (s.t_s > 2.0 && s.t_s < 3.0) v_high = std::max(v_high, s.v_mm_per_s);
    if (s.t_s > 3.2 && !s.done && s.s_mm < 390.0) v_late = std::max(v_late, s.v_mm_per_s);
  }
  EXPECT_NEAR(v_high, 75.0, 1e-9);
  EXPECT_LE(v_late, 20.0 * (1 + kTol));  // braked to the new limit within 0.2 s
  EXPECT_GE(v_late, 20.0 - 1e-9);
}

TEST(Planner, HoldStopsOnThePathAndResumes) {
  const PlannerLimits l = limits(1000.0, 20000.0, 0.004);
  const auto c = flat(100.0, 50.0, 0.5);
  double s_held = -1.0;
  const auto m = run_with(l, 100.0, c, [&](Planner& p, std::size_t i) {
    if (i == 200) p.hold();
    if (i == 400) s_held = p.done() ? -1.0 : 0.0, p.resume();
  });
  EXPECT_EQ(check_motion(m, c, l, 100.0).failures, 0);
  // Stopped within the S-curve stop time from 50 mm/s (0.1 s) plus two periods, then still.
  const double t_stop = 50.0 / 1000.0 + 1000.0 / 20000.0 + 2 * l.period_s;
  bool stopped = false;
  for (const auto& s : m) {
    if (s.t_s > 0.8 + t_stop && s.t_s <= 1.6) {
      EXPECT_EQ(s.v_mm_per_s, 0.0) << s.t_s;
      EXPECT_EQ(s.limit_id, kLimitIdHold);
      stopped = true;
    }
  }
  EXPECT_TRUE(stopped);
  EXPECT_EQ(s_held, 0.0);
  EXPECT_TRUE(m.back().done);
}

// A hold given while the planner lands on L (its landing committed, issue 13): the landing is
// cut short where a stop is faster, and never delays the hold. For a hold at every period of
// the landings of lines of several lengths (their landings begin with whole periods of cruise
// before the time-optimal stop), the motion brakes from the next period on when it was
// cruising, is at rest by the time the jerk-limited stop from the state at the hold allows (two
// periods more for the whole periods), stays on [0, L], keeps every limit, and after the resume
// ends at rest exactly at L.
TEST(Planner, AHoldDuringTheLandingCutsItShort) {
  const PlannerLimits l = limits(1000.0, 20000.0, 0.004);
  std::size_t cruising_holds = 0;
  // Periods from a hold in the landing's cruise to the first braking period (j < −J/2): the
  // landing's own (what a hold waited before) and the held motion's, the largest over them.
  std::size_t worst_landing = 0, worst_held = 0;
  const auto until_braking = [](const std::vector<MotionSample>& m, std::size_t at, double J) {
    std::size_t k = at + 1;
    while (k < m.size() && m[k].j_mm_per_s3 >= -0.5 * J && m[k].v_mm_per_s > 0.0) ++k;
    return k - at - 1;
  };
  for (const double length_mm : {20.0, 33.3, 50.0, 71.7}) {
    const auto c = flat(length_mm, 100.0, 0.5);
    const auto free = run_with(l, length_mm, c, [](Planner&, std::size_t) {});
    std::size_t first = 0;
    while (first < free.size() && free[first].limit_id != kLimitIdPathEnd) ++first;
    ASSERT_LT(first, free.size());
    for (std::size_t at = first; at + 1 < free.size(); ++at) {
      SCOPED_TRACE("L = " + std::to_string(length_mm) + " mm, hold at period " +
                   std::to_string(at));
      const auto m = run_with(l, length_mm, c, [&](Planner& p, std::size_t i) {
        if (i == at) p.hold();
        if (i == at + 100) p.resume();
      });
      EXPECT_EQ(check_motion(m, c, l, length_mm).failures, 0);
      ASSERT_TRUE(m.back().done);
      EXPECT_EQ(m.back().s_mm, length_mm);
      const MotionSample& h = m[at];  // the state the hold finds (m[0] is the start)
      const double v = h.v_mm_per_s, a = h.a_mm_per_s2;
      // The stop from (v, a): a ramp to −a_max and back, at most (v + a²/2J)/A + 2A/J.
      const double A = l.a_max_mm_per_s2, J = l.j_max_mm_per_s3;
      const double t_stop = (v + a * a / (2.0 * J)) / A + 2.0 * A / J + 2.0 * l.period_s;
      for (std::size_t k = at + 1; k < m.size() && k < at + 100; ++k) {
        if (m[k].t_s >= h.t_s + t_stop) {
          EXPECT_EQ(m[k].v_mm_per_s, 0.0) << m[k].t_s;
        }
      }
      // The landing's cruise (jerk and acceleration zero but for the rounding of its
      // correction): the held motion brakes at once instead.
      if (std::abs(free[at + 1].j_mm_per_s3) < 1e-6 && std::abs(free[at + 1].a_mm_per_s2) < 1e-9 &&
          v > 0.0) {
        ++cruising_holds;
        worst_landing = std::max(worst_landing, until_braking(free, at, J));
        worst_held = std::max(worst_held, until_braking(m, at, J));
        EXPECT_LT(m[at + 1].j_mm_per_s3, -0.5 * J) << "the landing cruised on through the hold";
      }
    }
  }
  EXPECT_GT(cruising_holds, 0U);  // the case the test is about occurs
  std::printf(
      "a hold during a landing: braking after at most %zu periods (the landing's own: %zu)\n",
      worst_held, worst_landing);
}

TEST(Planner, ReplayIsDeterministic) {
  std::mt19937_64 rng(7);
  const auto c = random_curve(rng, 40.0);
  const PlannerLimits l = limits(1500.0, 30000.0, 0.002);
  const auto a = plan_all(l, 40.0, c);
  const auto b = plan_all(l, 40.0, c);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a[i].s_mm, b[i].s_mm);
    ASSERT_EQ(a[i].j_mm_per_s3, b[i].j_mm_per_s3);
  }
}

// The memo (docs/planner.md §6, "The cruise from the memo") claims that a rollout reused from it
// is the one the planner would simulate: random limit curves with flat stretches, long cruises
// at one limit, and a feed hold and override changes at random periods, planned with and without
// reuse_rollouts, give the same motion bit for bit (every s, v, a, j and binding limit). The
// memo must actually be used (its hits counted), or the comparison proves nothing.
TEST(Planner, RolloutsFromTheMemoAreTheSimulatedOnesBitForBit) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::size_t hits = 0, periods = 0;
  const int cases = ncd::test::sweep_cases(60);
  for (int k = 0; k < cases; ++k) {
    PlannerLimits on =
        limits(200.0 + 2800.0 * u(rng), 2000.0 + 58000.0 * u(rng), k % 2 == 0 ? 0.004 : 0.001);
    PlannerLimits off = on;
    off.reuse_rollouts = false;
    const double length_mm = 5.0 + 200.0 * u(rng);
    std::vector<LimitSample> c;
    if (k % 3 == 0) {  // one long cruise at a single limit
      const double level = 20.0 + 180.0 * u(rng);
      for (double s = 0.0; s < length_mm; s += 0.25) c.push_back({s, level, 1});
      c.push_back({length_mm, level, 1});
    } else {
      c = random_curve(rng, length_mm);
    }
    const auto hold_at = static_cast<std::size_t>(2000.0 * u(rng));
    const auto override_at = static_cast<std::size_t>(2000.0 * u(rng));
    const double fraction = 0.3 + 1.5 * u(rng);
    Planner a(on, length_mm), b(off, length_mm);
    a.reserve_for_speed(top_speed(c));
    b.reserve_for_speed(top_speed(c));
    std::size_t next_a = 0, next_b = 0;
    for (std::size_t n = 0; n < 2'000'000 && !a.done(); ++n) {
      if (n == hold_at) a.hold(), b.hold();
      if (n == hold_at + 150) a.resume(), b.resume();
      if (n == override_at) a.set_override(fraction), b.set_override(fraction);
      ASSERT_EQ(push_available(a, c, next_a), PushResult::Ok);
      ASSERT_EQ(push_available(b, c, next_b), PushResult::Ok);
      const MotionSample x = a.step(), y = b.step();
      ASSERT_EQ(x.s_mm, y.s_mm) << "case " << k << " period " << n;
      ASSERT_EQ(x.v_mm_per_s, y.v_mm_per_s) << "case " << k << " period " << n;
      ASSERT_EQ(x.a_mm_per_s2, y.a_mm_per_s2) << "case " << k << " period " << n;
      ASSERT_EQ(x.j_mm_per_s3, y.j_mm_per_s3) << "case " << k << " period " << n;
      ASSERT_EQ(x.limit_id, y.limit_id) << "case " << k << " period " << n;
      ASSERT_EQ(x.done, y.done) << "case " << k << " period " << n;
      ++periods;
    }
    ASSERT_TRUE(a.done()) << "case " << k;
    EXPECT_EQ(b.rollouts_from_memo(), 0U);
    hits += a.rollouts_from_memo();
  }
  std::printf("%d limit curves, %zu periods, %zu rollouts from the memo\n", cases, periods, hits);
  EXPECT_GT(hits, periods / 4);
}

}  // namespace
}  // namespace ncd::motion
