// Feed limits: each limit binds where its closed form says it should, and the reported speed
// is that closed form, recomputed here from the formulas of docs/feedrate.md §§1, 3.
#include "feed/feed_limits.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <random>

#include "core/error.hpp"
#include "tests/common/seed.hpp"

namespace ncd::feed {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// A process whose roughness feed is far above the machine's: geometry decides.
CuttingParams fast_cutting() {
  CuttingParams c;
  c.ball_radius_mm = 5.0;
  c.pick_feed_mm = 0.5;
  c.teeth = 4;
  c.spindle_rpm = 40000.0;
  c.roughness_target_um = 20.0;
  return c;
}

// docs/feedrate.md §1.1 and §1.2, written out again: f_t = min(eq. 5, eq. 6), F = f_t z N.
double roughness_reference_mm_per_s(const CuttingParams& c, double alpha) {
  const double r = c.ball_radius_mm, fp = c.pick_feed_mm, R = c.roughness_target_um / 1000.0;
  const double ft_out = fp / (2.0 * kPi) + std::sqrt(8.0 * r * R - fp * fp);
  const double ft_dc = std::sqrt(std::pow(r * std::sin(alpha), 2) + 2.0 * r * R - R * R);
  return std::min(ft_out, ft_dc) * c.teeth * c.spindle_rpm / 60.0;
}

TEST(FeedLimits, NamesForReports) {
  EXPECT_STREQ(to_string(FeedLimit::Roughness), "roughness");
  EXPECT_STREQ(to_string(FeedLimit::Chord), "chord");
  EXPECT_STREQ(to_string(FeedLimit::CentripetalAccel), "centripetal_accel");
  EXPECT_STREQ(to_string(FeedLimit::CentripetalJerk), "centripetal_jerk");
  EXPECT_STREQ(to_string(FeedLimit::MaxFeed), "max_feed");
  EXPECT_STREQ(to_string(FeedLimit::Program), "program");
  EXPECT_STREQ(to_string(FeedLimit::Corner), "corner");
}

TEST(FeedLimits, RoughnessBindsOnAFlatStraightPassAtTheDeadCentre) {
  const MachineLimits m;
  CuttingParams slow;  // 2 teeth, 10 µm, 6000 rpm: f_t ≈ 0.316 mm at α = 0, ≈ 63 mm/s
  slow.spindle_rpm = 6000.0;
  const FeedLimitResult r = feed_limit(m, slow, 0.0, 0.0);
  EXPECT_EQ(r.limit, FeedLimit::Roughness);
  EXPECT_NEAR(r.feed_mm_per_s, roughness_reference_mm_per_s(slow, 0.0), 1e-12);
  // Tilting out of the dead-centre zone raises the roughness feed (eq. 5 instead of eq. 6).
  const FeedLimitResult tilted = feed_limit(m, slow, 0.0, deg_to_rad(20.0));
  EXPECT_EQ(tilted.limit, FeedLimit::Roughness);
  EXPECT_NEAR(tilted.feed_mm_per_s, roughness_reference_mm_per_s(slow, deg_to_rad(20.0)), 1e-12);
  EXPECT_GT(tilted.feed_mm_per_s, 1.4 * r.feed_mm_per_s);
}

TEST(FeedLimits, MaxFeedBindsOnAStraightLine) {
  const MachineLimits m;  // 6000 mm/min
  const FeedLimitResult r = feed_limit(m, fast_cutting(), 0.0, 0.0);
  EXPECT_EQ(r.limit, FeedLimit::MaxFeed);
  EXPECT_DOUBLE_EQ(r.feed_mm_per_s, 100.0);
}

TEST(FeedLimits, ChordBindsOnAGentleCurve) {
  const MachineLimits m;  // ε = 1 µm, T = 4 ms, a = 1000, j = 2e4
  const double rho = 5.0;
  const FeedLimitResult r = feed_limit(m, fast_cutting(), 1.0 / rho, 0.0);
  EXPECT_EQ(r.limit, FeedLimit::Chord);
  const double eps = 0.001;
  EXPECT_NEAR(r.feed_mm_per_s, 2.0 * std::sqrt(2.0 * rho * eps - eps * eps) / 0.004, 1e-12);
  // The chord of one period then deviates from the circle by exactly ε (sagitta).
  const double ds = r.feed_mm_per_s * m.period_s;
  EXPECT_NEAR(rho - std::sqrt(rho * rho - ds * ds / 4.0), eps, 1e-15);
}

TEST(FeedLimits, CentripetalAccelerationBindsWithASoftMachine) {
  MachineLimits m;
  m.max_accel_mm_per_s2 = 100.0;
  const double rho = 5.0;
  const FeedLimitResult r = feed_limit(m, fast_cutting(), 1.0 / rho, 0.0);
  EXPECT_EQ(r.limit, FeedLimit::CentripetalAccel);
  EXPECT_NEAR(r.feed_mm_per_s, std::sqrt(100.0 * rho), 1e-12);
  EXPECT_NEAR(r.feed_mm_per_s * r.feed_mm_per_s / rho, 100.0, 1e-10);  // v² κ = a_max
}

TEST(FeedLimits, CentripetalJerkBindsOnATightCorner) {
  const MachineLimits m;
  const double rho = 0.1;
  const FeedLimitResult r = feed_limit(m, fast_cutting(), 1.0 / rho, 0.0);
  EXPECT_EQ(r.limit, FeedLimit::CentripetalJerk);
  EXPECT_NEAR(r.feed_mm_per_s, std::cbrt(2e4 * rho * rho), 1e-12);
  EXPECT_NEAR(std::pow(r.feed_mm_per_s, 3) / (rho * rho), 2e4, 1e-8);  // v³ κ² = j_max
}

TEST(FeedLimits, ChordStepIsTheDiameterOnceTheToleranceExceedsTheRadius) {
  EXPECT_EQ(chord_step_mm(0.0, 0.001), kInf);
  EXPECT_DOUBLE_EQ(chord_step_mm(1.0 / 0.0005, 0.001), 0.001);
  // Continuous at ε = ρ.
  EXPECT_NEAR(chord_step_mm(1.0 / (0.001 * (1 + 1e-12)), 0.001), 0.002, 1e-14);
  EXPECT_EQ(centripetal_accel_feed_mm_per_s(0.0, 1000.0), kInf);
  EXPECT_EQ(centripetal_jerk_feed_mm_per_s(0.0, 2e4), kInf);
}

TEST(FeedLimits, TheReportedFeedIsTheMinimumOfAllFiveOverASweep) {
  const MachineLimits m;
  CuttingParams c;
  c.spindle_rpm = 6000.0;  // roughness 63–93 mm/s: every limit but accel binds somewhere
  for (int i = 0; i <= 400; ++i) {
    const double kappa = std::pow(10.0, -4.0 + 0.0125 * i);  // 1e-4 .. 1e1 per mm
    const double alpha = deg_to_rad(0.05 * i);
    const FeedLimitResult r = feed_limit(m, c, kappa, alpha);
    const double all[] = {roughness_reference_mm_per_s(c, alpha),
                          2.0 * std::sqrt(2.0 / kappa * 0.001 - 1e-6) / 0.004,
                          std::sqrt(1000.0 / kappa), std::cbrt(2e4 / (kappa * kappa)), 100.0};
    const double* least = std::min_element(std::begin(all), std::end(all));
    EXPECT_NEAR(r.feed_mm_per_s, *least, 1e-10 * *least) << i;
    EXPECT_EQ(static_cast<int>(r.limit), least - std::begin(all)) << i;
  }
}

// A helix of radius a and pitch 2πb: κ = a / (a² + b²), slope atan(b / a).
TEST(FeedLimits, AtACurvePointUsesItsCurvatureAndSlope) {
  const double a = 4.0, b = 1.5, u = 0.7;
  const toolpath::CurvePoint cp{Vec3(a * std::cos(u), a * std::sin(u), b * u),
                                Vec3(-a * std::sin(u), a * std::cos(u), b),
                                Vec3(-a * std::cos(u), -a * std::sin(u), 0.0)};
  const double kappa = a / (a * a + b * b);
  EXPECT_NEAR(curvature_per_mm(cp), kappa, 1e-15);
  MachineLimits m;
  CuttingParams c;
  const FeedLimitResult at = feed_limit_at(m, c, cp);
  const FeedLimitResult ref = feed_limit(m, c, kappa, std::atan(b / a));
  EXPECT_NEAR(at.feed_mm_per_s, ref.feed_mm_per_s, 1e-12);
  EXPECT_EQ(at.limit, ref.limit);
  // With a flat contact normal (+z) the inclination is 0 whatever the slope of the path.
  const FeedLimitResult flat = feed_limit_at(m, c, cp, Vec3::UnitZ());
  EXPECT_NEAR(flat.feed_mm_per_s, feed_limit(m, c, kappa, 0.0).feed_mm_per_s, 1e-12);
  // A cusp of the parametrisation (P' = 0) stops the feed instead of producing NaN.
  const toolpath::CurvePoint cusp{Vec3::Zero(), Vec3::Zero(), Vec3::UnitX()};
  EXPECT_EQ(feed_limit_at(m, c, cusp).feed_mm_per_s, 0.0);
}

TEST(MachineLimitsValidation, DefaultsAreValidAndBadValuesNamed) {
  EXPECT_NO_THROW(validate(MachineLimits{}));
  const double nan = std::nan("");
  for (double bad : {0.0, -1.0, nan, kInf}) {
    for (double MachineLimits::*field :
         {&MachineLimits::period_s, &MachineLimits::max_feed_mm_per_min,
          &MachineLimits::max_accel_mm_per_s2, &MachineLimits::max_jerk_mm_per_s3,
          &MachineLimits::chord_tolerance_mm, &MachineLimits::feed_tolerance_rel}) {
      MachineLimits m;
      m.*field = bad;
      EXPECT_THROW(validate(m), InputError) << bad;
    }
  }
  MachineLimits m;
  m.period_s = 2.0;
  try {
    validate(m);
    ADD_FAILURE() << "a 2 s period must be rejected";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("period_s = 2"), std::string::npos) << e.what();
  }
  m = {};
  m.feed_tolerance_rel = 1e-16;
  EXPECT_THROW(validate(m), InputError);
}

// The jerk-vector laws of docs/planner.md §3c against their definitions, on random curves and
// speeds (seed printed): the tangential scale σ is the largest in [0, 1] with
// (σJ + v³κ²)² + (3vσAκ + v³g)² ≤ (βJ)², found here by a brute-force scan of σ; the jerk-vector
// speed is where σ reaches kMinTangentialScale × β; the jump speed solves
// 2 v sin(φ/2)/T² + 0.75 v² Δκ/T = kJumpJerkShare J.
TEST(JerkVectorLaws, MatchTheirDefinitions) {
  const std::uint64_t seed = test::seed();
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  MachineLimits m;
  const double J = m.max_jerk_mm_per_s3, A = m.max_accel_mm_per_s2, T = m.period_s;
  const auto excess = [&](double sigma, double k, double g, double v, double beta) {
    const double v3 = v * v * v;
    return std::pow(sigma * J + v3 * k * k, 2) + std::pow(3.0 * v * sigma * A * k + v3 * g, 2) -
           beta * beta * J * J;
  };
  for (int i = 0; i < 2000; ++i) {
    const double k = std::pow(10.0, -3.0 + 4.0 * u01(rng));  // 0.001 to 10 /mm
    const double g = u01(rng) < 0.3 ? 0.0 : std::pow(10.0, -4.0 + 4.0 * u01(rng));
    const double v = 0.1 + 150.0 * u01(rng), beta = u01(rng) < 0.5 ? 1.0 : 0.5;
    const double sigma = tangential_scale(m, k, g, v, beta);
    ASSERT_GE(sigma, 0.0);
    ASSERT_LE(sigma, 1.0);
    // Brute force: the largest σ on a grid of 1e-4 that keeps the bound.
    double best = -1.0;
    for (int n = 0; n <= 10000; ++n) {
      if (excess(n * 1e-4, k, g, v, beta) <= 0.0) best = n * 1e-4;
    }
    if (best < 0.0) {
      EXPECT_EQ(sigma, 0.0) << "k " << k << " g " << g << " v " << v;
    } else {
      EXPECT_NEAR(sigma, best, 1.01e-4) << "k " << k << " g " << g << " v " << v;
      EXPECT_LE(excess(sigma, k, g, v, beta), 1e-9 * J * J);
    }
    const double vj = jerk_vector_feed_mm_per_s(m, k, g, beta);
    EXPECT_NEAR(tangential_scale(m, k, g, vj, beta), kMinTangentialScale * beta, 1e-6);
    const double phi = M_PI * u01(rng), dk = u01(rng) < 0.3 ? 0.0 : k;
    const double vjump = jump_feed_mm_per_s(m, phi, dk);
    const double third =
        2.0 * vjump * std::sin(0.5 * phi) / (T * T) + 0.75 * vjump * vjump * dk / T;
    EXPECT_NEAR(third, kJumpJerkShare * J, 1e-9 * J);
    EXPECT_NEAR(jump_jerk_mm_per_s3(m, phi, dk, vjump), third, 1e-9 * J);
  }
  EXPECT_EQ(tangential_scale(m, 0.0, 0.0, 100.0, 0.5), 0.5);  // a line: only the budget
  EXPECT_EQ(jerk_vector_feed_mm_per_s(m, 0.0, 0.0), kInf);
  EXPECT_EQ(jump_feed_mm_per_s(m, 0.0, 0.0), kInf);
}

}  // namespace
}  // namespace ncd::feed
