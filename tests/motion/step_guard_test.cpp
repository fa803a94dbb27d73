// The step rule (motion/step_guard.hpp) on motions whose steps are known in closed form, the
// acceptance rule of a finished run (motion::refusal), and the rule inside a real Job.
#include "motion/step_guard.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "motion/job.hpp"
#include "motion/run_stats.hpp"

namespace ncd::motion {
namespace {

constexpr double kGuardT = 0.004;
constexpr double kPi = 3.14159265358979323846;

StepBounds bounds() {
  StepBounds b;
  b.max_feed_mm_per_s = 100.0;
  b.max_accel_mm_per_s2 = 1000.0;
  b.period_s = kGuardT;
  return b;
}

// s(t) = a t²/2 on the x axis: the second difference of s is exactly a T² (the rule's
// acceleration bound is a_max T² (1 + m) + ε). Returns the first fault and its period.
std::pair<StepFault, std::int64_t> accelerate(double a_mm_per_s2, int periods) {
  StepGuard g(bounds(), Vec3::Zero());
  double s_prev = 0.0;
  for (int k = 1; k <= periods; ++k) {
    const double t = k * kGuardT, s = 0.5 * a_mm_per_s2 * t * t;
    const StepFault f = g.check(t, s, s - s_prev, Vec3(s, 0, 0));
    if (f != StepFault::None) return {f, g.info().period};
    s_prev = s;
  }
  return {StepFault::None, 0};
}

TEST(StepGuard, AccelerationAtTheLimitPassesAndAboveTheMarginFaults) {
  // 1000 mm/s² for 20 periods reaches 80 mm/s, under the 100 mm/s of the speed bound.
  EXPECT_EQ(accelerate(1000.0, 20).first, StepFault::None);
  EXPECT_EQ(accelerate(1000.0 * (1 + 0.9 * kStepMarginRel), 20).first, StepFault::None);
  // 3 % above: the first step is a T²/2 (within the bound), the second a full a T².
  const auto [fault, period] = accelerate(1030.0, 20);
  EXPECT_EQ(fault, StepFault::Acceleration);
  EXPECT_EQ(period, 2);
}

TEST(StepGuard, SpeedBoundIsTheMaximumFeedTimesTheOverride) {
  const auto cruise = [](double v_mm_per_s, double override_fraction) {
    StepBounds b = bounds();
    b.max_accel_mm_per_s2 = 1e12;  // speed alone
    StepGuard g(b, Vec3::Zero());
    g.set_override(override_fraction);
    StepFault f = StepFault::None;
    for (int k = 1; k <= 10 && f == StepFault::None; ++k) {
      f = g.check(k * kGuardT, v_mm_per_s * k * kGuardT, v_mm_per_s * kGuardT,
                  Vec3(v_mm_per_s * k * kGuardT, 0, 0));
    }
    return f;
  };
  EXPECT_EQ(cruise(100.0, 1.0), StepFault::None);
  EXPECT_EQ(cruise(101.0, 1.0), StepFault::None);  // within the 2 % margin
  EXPECT_EQ(cruise(103.0, 1.0), StepFault::Speed);
  EXPECT_EQ(cruise(150.0, 2.0), StepFault::None);   // 200 % override allows 200 mm/s
  EXPECT_EQ(cruise(150.0, 0.5), StepFault::Speed);  // a lower override never lowers the bound
}

TEST(StepGuard, ChordsOfACircleWalkAndAJumpIsRefusedWhereItHappens) {
  // On a circle of radius R at arc step Δs, the chord is 2R sin(Δs/2R) < Δs: never refused.
  const double r_mm = 20.0, ds_mm = 0.0085;  // 127 mm/min, as in issue 11
  StepGuard g(bounds(), Vec3(r_mm, 0, 0));
  double last_ds = 0.0, s_total = 0.0;
  int k = 1;
  for (; k <= 1000; ++k) {
    // Ramp to Δs within the acceleration bound, then cruise.
    const double step = std::min(ds_mm, last_ds + 0.5 * 1000.0 * kGuardT * kGuardT);
    s_total += step;
    const double phi = s_total / r_mm;
    ASSERT_EQ(
        g.check(k * kGuardT, s_total, step, Vec3(r_mm * std::cos(phi), r_mm * std::sin(phi), 0)),
        StepFault::None)
        << k;
    last_ds = step;
  }
  // The jump of issue 11: 28.1 mm in one period at a planned 0.0085 mm.
  const Vec3 to(-0.1305, -19.8713, 0.0);
  EXPECT_EQ(g.check(k * kGuardT, 9.0, ds_mm, to), StepFault::Walk);
  const StepFaultInfo& info = g.info();
  EXPECT_EQ(info.period, k);
  EXPECT_NEAR(info.allowed, ds_mm * (1 + kStepMarginRel) + kStepSlackMm, 1e-15);
  EXPECT_NEAR(info.value, (to - info.from_mm).norm(), 1e-12);
  EXPECT_GT(info.value, 20.0);
  // Once refused, every later setpoint is refused too, even a harmless one.
  EXPECT_EQ(g.check((k + 1) * kGuardT, 9.0, 0.0, info.from_mm), StepFault::Walk);
}

TEST(StepGuard, NotANumberIsRefused) {
  {
    StepGuard g(bounds(), Vec3::Zero());
    EXPECT_EQ(g.check(kGuardT, 0.001, 0.001, Vec3(std::nan(""), 0, 0)), StepFault::Walk);
  }
  {
    StepGuard g(bounds(), Vec3::Zero());
    EXPECT_EQ(g.check(kGuardT, 0.001, std::nan(""), Vec3(0.001, 0, 0)), StepFault::Speed);
  }
}

TEST(RunRefusal, ViolationsAndDriftAreNamedAndACleanRunIsAccepted) {
  JobConfig config;
  RunStats st;
  st.path_length_mm = 100.0;
  st.travelled_mm = 100.0 + 0.5 * kDriftToleranceMm;
  EXPECT_EQ(refusal(st, config), "");
  st.violations_chord = 397;
  EXPECT_NE(refusal(st, config).find("397 limit violation(s)"), std::string::npos);
  EXPECT_NE(refusal(st, config).find("chord 397"), std::string::npos);
  st.violations_chord = 0;
  st.travelled_mm = 100.0 - 28.09;  // the drift of issue 11
  EXPECT_NE(refusal(st, config).find("arc-length drift -28.09 mm"), std::string::npos)
      << refusal(st, config);
}

TEST(StepGuardInAJob, AClosedFormCircleWalksWithoutAFault) {
  // A quarter circle as a rational quadratic NURBS: the step rule must never fire on it.
  toolpath::Path path;
  toolpath::PathSegment seg;
  const double w = std::sqrt(0.5);
  seg.geometry = toolpath::NurbsCurve(2, {0, 0, 0, 1, 1, 1},
                                      {Vec3(20, 0, 0), Vec3(20, 20, 0), Vec3(0, 20, 0)}, {1, w, 1});
  seg.feed_mm_per_min = 3000.0;
  path.segments.push_back(seg);
  JobConfig config;
  Job job(path, config);
  Setpoint sp;
  int periods = 0;
  do {
    job.prepare();
    sp = job.step();
    ASSERT_EQ(sp.fault, StepFault::None) << job.fault_message();
  } while (!sp.done && ++periods < 100000);
  EXPECT_TRUE(sp.done);
  EXPECT_NEAR(sp.s_mm, 0.5 * kPi * 20.0, 1e-6);
  EXPECT_EQ(job.fault().fault, StepFault::None);
}

}  // namespace
}  // namespace ncd::motion
