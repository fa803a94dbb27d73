// The curve walker against curves whose arc length is known in closed form: a helix traversed
// with an accelerating parameter (|P'| not constant, so eq. 7 alone is inexact) and an S of two
// rational quadratic quarter circles joined C¹ at u = 1, where P'' jumps (a repeated knot).
// The feed error of a step is |L(u_i, u_{i+1}) − Δs| / Δs with L from the closed form, never
// from the walker's own quadrature.
#include "feed/curve_walker.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <iostream>
#include <new>
#include <random>

#include "core/error.hpp"
#include "core/quadrature.hpp"
#include "feed/feed_limits.hpp"
#include "tests/common/count_allocations.hpp"
#include "tests/common/seed.hpp"

namespace ncd::feed {
namespace {

using toolpath::CurvePoint;
using toolpath::ParametricCurve;

// H(φ) = (a cos φ, a sin φ, b φ) with φ(u) = u + k u²: |P'| = c φ'(u), c = sqrt(a² + b²), grows
// along the curve; the arc length from 0 is c φ(u).
class AcceleratingHelix final : public ParametricCurve {
 public:
  AcceleratingHelix(double a, double b, double k, double u_end)
      : a_(a), b_(b), k_(k), end_(u_end) {}
  double u_begin() const override { return 0.0; }
  double u_end() const override { return end_; }
  CurvePoint eval(double u) const override {
    const double phi = u + k_ * u * u, dphi = 1.0 + 2.0 * k_ * u, ddphi = 2.0 * k_;
    const double c = std::cos(phi), s = std::sin(phi);
    const Vec3 h1(-a_ * s, a_ * c, b_), h2(-a_ * c, -a_ * s, 0.0);
    return {Vec3(a_ * c, a_ * s, b_ * phi), dphi * h1, ddphi * h1 + dphi * dphi * h2};
  }
  std::vector<double> breakpoints() const override { return {0.0, end_}; }
  double arc(double u) const { return std::hypot(a_, b_) * (u + k_ * u * u); }

 private:
  double a_, b_, k_, end_;
};

// Rational quadratic Bézier, weights (1, √2/2, 1): an exact quarter circle, traversed with a
// non-constant speed.
struct RationalQuarter {
  Vec3 p0, p1, p2;
  CurvePoint eval(double t) const {
    const double w1 = std::sqrt(0.5);
    const double b0 = (1 - t) * (1 - t), b1 = 2 * t * (1 - t), b2 = t * t;
    const double d0 = -2 * (1 - t), d1 = 2 - 4 * t, d2 = 2 * t;
    const Vec3 n = b0 * p0 + w1 * b1 * p1 + b2 * p2;
    const Vec3 n1 = d0 * p0 + w1 * d1 * p1 + d2 * p2;
    const Vec3 n2 = 2 * p0 - 4 * w1 * p1 + 2 * p2;
    const double w = b0 + w1 * b1 + b2, wd = d0 + w1 * d1 + d2, wdd = 2 - 4 * w1 + 2;
    const Vec3 p = n / w;
    const Vec3 v = (n1 - wd * p) / w;
    return {p, v, (n2 - 2 * wd * v - wdd * p) / w};
  }
};

// Two quarter circles of radius R bending opposite ways, u ∈ [0, 2], joined at u = 1 with
// equal P' (C¹) but P'' jumping; the joint is listed twice, as a double knot would be.
class RationalS final : public ParametricCurve {
 public:
  explicit RationalS(double radius)
      : r_(radius),
        first_{Vec3(r_, 0, 0), Vec3(r_, r_, 0), Vec3(0, r_, 0)},
        second_{Vec3(0, r_, 0), Vec3(-r_, r_, 0), Vec3(-r_, 2 * r_, 0)} {}
  double u_begin() const override { return 0.0; }
  double u_end() const override { return 2.0; }
  CurvePoint eval(double u) const override {
    return u < 1.0 ? first_.eval(u) : second_.eval(u - 1.0);
  }
  std::vector<double> breakpoints() const override { return {0.0, 1.0, 1.0, 2.0}; }
  // R times the angle swept about each centre.
  double arc(double u) const {
    if (u <= 1.0) return r_ * angle(Vec3::Zero(), first_.p0, first_.eval(u).p);
    return 0.5 * kPi * r_ + r_ * angle(Vec3(0, 2 * r_, 0), second_.p0, second_.eval(u - 1.0).p);
  }

 private:
  static double angle(const Vec3& centre, const Vec3& from, const Vec3& to) {
    const Vec3 x = from - centre, y = to - centre;
    return std::atan2(x.cross(y).norm(), x.dot(y));
  }
  double r_;
  RationalQuarter first_, second_;
};

// P(u) = (u², 0, 0): P'(0) = 0, a parametrisation that stands still at its start.
class StandingStart final : public ParametricCurve {
 public:
  double u_begin() const override { return 0.0; }
  double u_end() const override { return 1.0; }
  CurvePoint eval(double u) const override {
    return {Vec3(u * u, 0, 0), Vec3(2 * u, 0, 0), Vec3(2, 0, 0)};
  }
  std::vector<double> breakpoints() const override { return {0.0, 1.0}; }
};

struct WalkStats {
  double max_feed_error_rel = 0.0;    // over Ok steps, against the closed form
  double max_drift_mm = 0.0;          // |true s − Σ commanded| over the whole walk
  double max_measure_error_mm = 0.0;  // |reported arc − closed form|
  int steps = 0;
  int max_iterations = 0;
  long total_iterations = 0;
  bool ended = false;
  bool all_ok = true;  // no NotConverged / Stalled / InvalidStep
};

template <class Curve>
WalkStats walk(const Curve& curve, const WalkerConfig& config,
               const std::function<double(int)>& delta_s_of_step) {
  CurveWalker walker(curve, config);
  WalkStats st;
  double commanded_mm = 0.0;
  const double s0 = curve.arc(curve.u_begin());
  while (!walker.at_end() && st.steps < 1000000) {
    const double u0 = walker.u();
    const double ds = delta_s_of_step(st.steps);
    const StepResult r = walker.step(ds);
    ++st.steps;
    const double true_mm = curve.arc(r.u) - curve.arc(u0);
    st.max_measure_error_mm =
        std::max(st.max_measure_error_mm, std::abs(r.arc_length_mm - true_mm));
    st.max_iterations = std::max(st.max_iterations, r.iterations);
    st.total_iterations += r.iterations;
    if (r.status == StepStatus::Ok) {
      st.max_feed_error_rel = std::max(st.max_feed_error_rel, std::abs(true_mm - ds) / ds);
      commanded_mm += ds;
    } else if (r.status == StepStatus::ReachedEnd) {
      st.ended = (r.u == curve.u_end());
      EXPECT_LE(true_mm, ds * (1.0 + 1e-9));
      commanded_mm += r.arc_length_mm;  // the planner is told how far the last step went
    } else {
      st.all_ok = false;
    }
    st.max_drift_mm = std::max(st.max_drift_mm, std::abs(curve.arc(r.u) - s0 - commanded_mm));
  }
  return st;
}

WalkerConfig corrected() {
  return {};
}
WalkerConfig taylor_only() {
  WalkerConfig c;
  c.mode = StepMode::TaylorOnly;
  return c;
}

const auto kConstant = [](int) { return 0.4; };  // 100 mm/s at 4 ms

// --- feed error per step ----------------------------------------------------------------------

TEST(CurveWalker, CorrectedStepsTravelDeltaSWithin1e9OnTheAcceleratingHelix) {
  const AcceleratingHelix helix(10.0, 2.0, 0.2, 2.0 * kPi);
  const WalkStats st = walk(helix, corrected(), kConstant);
  std::cout << "helix corrected: steps " << st.steps << ", max feed error " << st.max_feed_error_rel
            << ", max iterations " << st.max_iterations << ", mean "
            << static_cast<double>(st.total_iterations) / st.steps << "\n";
  EXPECT_TRUE(st.all_ok);
  EXPECT_TRUE(st.ended);
  EXPECT_LE(st.max_feed_error_rel, 1e-9);
  EXPECT_LE(st.max_measure_error_mm, 1e-12);
  EXPECT_LE(st.max_iterations, 3);
  EXPECT_GT(st.steps, 300);
}

TEST(CurveWalker, TaylorOnlyShowsTheFluctuationTheCorrectionRemoves) {
  const AcceleratingHelix helix(10.0, 2.0, 0.2, 2.0 * kPi);
  const WalkStats st = walk(helix, taylor_only(), kConstant);
  std::cout << "helix Taylor only: max feed error " << st.max_feed_error_rel << ", drift "
            << st.max_drift_mm << " mm\n";
  EXPECT_GT(st.max_feed_error_rel, 1e-6);  // the check above can fail
  EXPECT_LT(st.max_feed_error_rel, 1e-2);
  EXPECT_EQ(st.max_iterations, 0);
  EXPECT_LE(st.max_measure_error_mm, 1e-12);  // the measured arc is still the true one
  EXPECT_TRUE(st.ended);
}

TEST(CurveWalker, CorrectedStepsCrossTheC1JointOfTheRationalS) {
  const RationalS s(10.0);
  const WalkStats st = walk(s, corrected(), kConstant);
  const WalkStats taylor = walk(s, taylor_only(), kConstant);
  std::cout << "rational S: corrected " << st.max_feed_error_rel << ", Taylor only "
            << taylor.max_feed_error_rel << " (drift " << taylor.max_drift_mm << " mm)\n";
  EXPECT_TRUE(st.all_ok);
  EXPECT_TRUE(st.ended);
  EXPECT_LE(st.max_feed_error_rel, 1e-9);
  EXPECT_LE(st.max_measure_error_mm, 1e-12);
  EXPECT_GT(taylor.max_feed_error_rel, 1e-6);
}

TEST(CurveWalker, ArcLengthSplitsAtTheJointWherePDoublePrimeJumps) {
  const RationalS s(10.0);
  const CurveWalker walker(s);
  const double want = s.arc(1.1) - s.arc(0.9);
  EXPECT_NEAR(walker.arc_length_mm(0.9, 1.1), want, 1e-13);
  // One panel straight across the joint is visibly worse: the split is what makes it exact.
  const double one_panel =
      GaussLegendre10::integrate([&s](double u) { return s.eval(u).d1.norm(); }, 0.9, 1.1);
  EXPECT_GT(std::abs(one_panel - want), 1e-10);
  EXPECT_NEAR(walker.arc_length_mm(1.1, 0.9), -want, 1e-13);
}

// --- accumulated drift ------------------------------------------------------------------------

TEST(CurveWalker, DriftOverWholeCurvesStaysBelowAMicrometreMillionth) {
  const AcceleratingHelix helix(10.0, 2.0, 0.2, 2.0 * kPi);
  const RationalS s(10.0);
  const WalkStats h = walk(helix, corrected(), kConstant);
  const WalkStats r = walk(s, corrected(), kConstant);
  EXPECT_LE(h.max_drift_mm, 1e-6);
  EXPECT_LE(r.max_drift_mm, 1e-6);
  const WalkStats ht = walk(helix, taylor_only(), kConstant);
  EXPECT_GT(ht.max_drift_mm, 1e-6);  // without correction the error accumulates
  std::cout << "drift: helix " << h.max_drift_mm << " mm, S " << r.max_drift_mm
            << " mm; Taylor only " << ht.max_drift_mm << " mm\n";
}

// --- ramps, tiny steps, the end ---------------------------------------------------------------

TEST(CurveWalker, RampsWithDeltaSChangingEveryStep) {
  const AcceleratingHelix helix(10.0, 2.0, 0.2, 2.0 * kPi);
  const RationalS s(10.0);
  // Smooth ramp 0 → 0.4 mm over 80 periods (an S-curve in speed), then cruise.
  const auto ramp = [](int k) {
    const double x = std::min(1.0, (k + 1) / 80.0);
    return 0.4 * x * x * (3.0 - 2.0 * x);
  };
  for (const WalkStats& st : {walk(helix, corrected(), ramp), walk(s, corrected(), ramp)}) {
    EXPECT_TRUE(st.all_ok);
    EXPECT_TRUE(st.ended);
    EXPECT_LE(st.max_feed_error_rel, 1e-9);
    EXPECT_LE(st.max_drift_mm, 1e-6);
  }
  // Random Δs in [1e-4, 0.8] mm, a feed jumping between periods.
  std::mt19937_64 rng(ncd::test::seed(20240611));
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const auto jumpy = [&](int) { return 1e-4 + 0.8 * unit(rng); };
  for (const WalkStats& st : {walk(helix, corrected(), jumpy), walk(s, corrected(), jumpy)}) {
    EXPECT_TRUE(st.all_ok);
    EXPECT_LE(st.max_feed_error_rel, 1e-9);
    EXPECT_LE(st.max_drift_mm, 1e-6);
  }
}

TEST(CurveWalker, TinyStepsConvergeToTheParameterResolution) {
  const AcceleratingHelix helix(10.0, 2.0, 0.2, 2.0 * kPi);
  CurveWalker walker(helix);
  walker.reset(5.0);
  for (int k = 0; k < 100; ++k) {
    const double u0 = walker.u();
    const StepResult r = walker.step(1e-7);
    ASSERT_EQ(r.status, StepStatus::Ok) << k;
    EXPECT_NEAR(helix.arc(r.u) - helix.arc(u0), 1e-7, 1e-12) << k;
  }
  const double u0 = walker.u();
  const StepResult zero = walker.step(0.0);
  EXPECT_EQ(zero.status, StepStatus::Ok);
  EXPECT_EQ(zero.u, u0);
  EXPECT_EQ(walker.step(-0.1).status, StepStatus::InvalidStep);
  EXPECT_EQ(walker.step(std::nan("")).status, StepStatus::InvalidStep);
  EXPECT_EQ(walker.u(), u0);
}

TEST(CurveWalker, LastStepLandsOnTheEndExactlyInBothModes) {
  const RationalS s(10.0);
  for (const WalkerConfig& config : {corrected(), taylor_only()}) {
    CurveWalker walker(s, config);
    walker.reset(1.999);
    const double rest = s.arc(2.0) - s.arc(1.999);
    const StepResult r = walker.step(0.4);
    EXPECT_EQ(r.status, StepStatus::ReachedEnd);
    EXPECT_EQ(r.u, 2.0);
    EXPECT_NEAR(r.arc_length_mm, rest, 1e-14);
    EXPECT_TRUE(walker.at_end());
    const StepResult after = walker.step(0.4);
    EXPECT_EQ(after.status, StepStatus::ReachedEnd);
    EXPECT_EQ(after.arc_length_mm, 0.0);
  }
  // A step that ends just short of u_end stays Ok; Δs equal to the rest lands on it.
  CurveWalker walker(s);
  walker.reset(1.9);
  const double rest = s.arc(2.0) - s.arc(1.9);
  EXPECT_EQ(walker.step(rest * (1 - 1e-6)).status, StepStatus::Ok);
  EXPECT_LT(walker.u(), 2.0);
  walker.reset(1.9);
  const StepResult exact = walker.step(rest);
  EXPECT_EQ(exact.u, 2.0);
  EXPECT_EQ(exact.status, StepStatus::ReachedEnd);
}

TEST(CurveWalker, StandingStartIsWalkedByTheCorrectorAndStallsTaylor) {
  const StandingStart curve;  // arc length from 0 is u²
  CurveWalker walker(curve);
  const StepResult r = walker.step(0.04);
  EXPECT_EQ(r.status, StepStatus::Ok);
  EXPECT_NEAR(r.u * r.u, 0.04, 1e-12);
  CurveWalker taylor(curve, taylor_only());
  EXPECT_EQ(taylor.step(0.04).status, StepStatus::Stalled);
  EXPECT_EQ(taylor.u(), 0.0);
}

// --- real-time contract and input errors ------------------------------------------------------

TEST(CurveWalker, StepsAndFeedLimitsDoNotAllocate) {
  const RationalS s(10.0);
  CurveWalker walker(s);
  CurveWalker taylor(s, taylor_only());
  const MachineLimits limits;
  const CuttingParams cutting;
  double sink = 0.0;
  const long before = ncd::test::g_allocations.load();
  for (int k = 0; k < 100 && !walker.at_end(); ++k) {
    const StepResult r = walker.step(0.3);
    const StepResult t = taylor.step(0.3);
    sink += r.u + t.u + feed_limit_at(limits, cutting, s.eval(r.u)).feed_mm_per_s;
  }
  EXPECT_EQ(ncd::test::g_allocations.load() - before, 0);
  EXPECT_GT(sink, 0.0);
}

TEST(CurveWalker, RejectsBadConfigAndBreakpoints) {
  const RationalS s(10.0);
  WalkerConfig c;
  c.tolerance_rel = 0.0;
  EXPECT_THROW(CurveWalker(s, c), InputError);
  c = {};
  c.max_iterations = 0;
  EXPECT_THROW(CurveWalker(s, c), InputError);

  class Unsorted final : public ParametricCurve {
   public:
    double u_begin() const override { return 0.0; }
    double u_end() const override { return 1.0; }
    CurvePoint eval(double u) const override {
      return {Vec3(u, 0, 0), Vec3::UnitX(), Vec3::Zero()};
    }
    std::vector<double> breakpoints() const override { return {0.0, 0.7, 0.3, 1.0}; }
  };
  EXPECT_THROW(CurveWalker{Unsorted{}}, InputError);
}

}  // namespace
}  // namespace ncd::feed
