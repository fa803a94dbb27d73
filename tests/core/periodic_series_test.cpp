// The trigonometric interpolant and its antiderivative (core/periodic_series.hpp), against
// closed forms: a trigonometric polynomial (exact), 1/(a − b cos θ) (analytic, with a known
// antiderivative), and functions it must refuse (a near-real pole, a kink).
#include "core/periodic_series.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "tests/common/seed.hpp"

namespace ncd {
namespace {

constexpr double kPi = std::numbers::pi;

TEST(PeriodicSeries, TrigonometricPolynomialIsExact) {
  const auto f = [](double t) {
    return 3.0 + std::cos(t) - 2.0 * std::sin(3.0 * t) + 0.5 * std::cos(7.0 * t);
  };
  const auto big_f = [](double t) {
    return 3.0 * t + std::sin(t) + 2.0 / 3.0 * (std::cos(3.0 * t) - 1.0) +
           0.5 / 7.0 * std::sin(7.0 * t);
  };
  const auto slope = [](double t) {
    return -std::sin(t) - 6.0 * std::cos(3.0 * t) - 3.5 * std::sin(7.0 * t);
  };
  const auto s = PeriodicSeries::fit(f, 1e-14, 64, 4096);
  ASSERT_TRUE(s.has_value());
  EXPECT_EQ(s->samples(), 64);  // accepted at the first grid: harmonics 8… are rounding only
  EXPECT_NEAR(s->period_integral(), 6.0 * kPi, 1e-13);
  std::mt19937_64 rng(test::seed());
  std::uniform_real_distribution<double> u(0.0, 2.0 * kPi);
  for (int i = 0; i < 200; ++i) {
    const double t = u(rng);
    const PeriodicSeries::Sample at = s->at(t);
    EXPECT_NEAR(at.value, f(t), 1e-13) << t;
    EXPECT_NEAR(at.integral, big_f(t), 1e-13) << t;
    EXPECT_NEAR(at.slope, slope(t), 1e-12) << t;
  }
}

TEST(PeriodicSeries, AnalyticFunctionMatchesItsClosedFormAntiderivative) {
  // f = 1/(a − b cos θ): ∫₀^θ f = 2/√(a²−b²) atan(√((a+b)/(a−b)) tan(θ/2)) on (−π, π), period
  // integral 2π/√(a²−b²). The pole is at Im θ = acosh(a/b): a = 1.25 puts it at 0.69.
  for (const double a : {3.0, 1.25}) {
    const double b = 1.0, root = std::sqrt(a * a - b * b);
    const auto f = [&](double t) { return 1.0 / (a - b * std::cos(t)); };
    const auto s = PeriodicSeries::fit(f, 1e-14, 64, 4096);
    ASSERT_TRUE(s.has_value()) << a;
    EXPECT_NEAR(s->period_integral(), 2.0 * kPi / root, 1e-14) << a;
    for (int i = -99; i <= 99; ++i) {
      const double t = kPi * i / 100.0;
      const double want = 2.0 / root * std::atan(std::sqrt((a + b) / (a - b)) * std::tan(0.5 * t));
      const PeriodicSeries::Sample at = s->at(t);
      EXPECT_NEAR(at.integral, want, 1e-13) << "a " << a << " θ " << t;
      EXPECT_NEAR(at.value, f(t), 1e-13 * f(t)) << "a " << a << " θ " << t;
      EXPECT_NEAR(at.slope, -b * std::sin(t) * f(t) * f(t), 1e-11) << "a " << a << " θ " << t;
    }
  }
}

TEST(PeriodicSeries, OnlyEveryFourthHarmonicStillConvergesToTheFunction) {
  // exp(cos 4θ) has harmonics 0, 4, 8, …: the band checked must not mistake the zero ones for
  // convergence. Its period integral is 2π I₀(1).
  const auto f = [](double t) { return std::exp(std::cos(4.0 * t)); };
  const auto s = PeriodicSeries::fit(f, 1e-14, 64, 4096);
  ASSERT_TRUE(s.has_value());
  EXPECT_NEAR(s->period_integral(), 2.0 * kPi * std::cyl_bessel_i(0.0, 1.0), 1e-13);
  for (int i = 0; i < 100; ++i) {
    const double t = 0.0628 * i;
    EXPECT_NEAR(s->value(t), f(t), 1e-13) << t;
  }
}

TEST(PeriodicSeries, NearRealPoleOrKinkIsRefused) {
  // A pole at Im θ = acosh(1 + 1e-6) ≈ 1.4e-3 needs far more than 4096 samples; |sin θ| has
  // coefficients falling like 1/k² only.
  EXPECT_FALSE(PeriodicSeries::fit([](double t) { return 1.0 / (1.000001 - std::cos(t)); }, 1e-14,
                                   64, 4096));
  EXPECT_FALSE(
      PeriodicSeries::fit([](double t) { return std::abs(std::sin(t)); }, 1e-14, 64, 4096));
}

}  // namespace
}  // namespace ncd
