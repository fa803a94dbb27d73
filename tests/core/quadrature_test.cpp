// Gauss–Legendre: exact on polynomials up to degree 19, spectrally accurate on smooth integrands.
#include "core/quadrature.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace ncd {
namespace {

TEST(GaussLegendre10, IntegratesMonomialsUpToDegree19Exactly) {
  for (int d = 0; d <= 19; ++d) {
    const double got =
        GaussLegendre10::integrate([d](double x) { return std::pow(x, d); }, -1.0, 2.0);
    const double want = (std::pow(2.0, d + 1) - std::pow(-1.0, d + 1)) / (d + 1);
    EXPECT_NEAR(got, want, 1e-13 * std::max(1.0, std::abs(want))) << "degree " << d;
  }
}

TEST(GaussLegendre5, IntegratesMonomialsUpToDegree9ExactlyButNot10) {
  for (int d = 0; d <= 10; ++d) {
    const double got =
        GaussLegendre5::integrate([d](double x) { return std::pow(x, d); }, -1.0, 2.0);
    const double want = (std::pow(2.0, d + 1) - std::pow(-1.0, d + 1)) / (d + 1);
    if (d <= 9) {
      EXPECT_NEAR(got, want, 1e-13 * std::max(1.0, std::abs(want))) << "degree " << d;
    } else {
      EXPECT_GT(std::abs(got - want), 1e-6) << "degree " << d;
    }
  }
}

TEST(GaussLegendre10, DegreeTwentyIsNotExact) {
  // The rule has 10 nodes: x^20 is the first monomial it cannot integrate exactly.
  const double got =
      GaussLegendre10::integrate([](double x) { return std::pow(x, 20); }, -1.0, 1.0);
  EXPECT_GT(std::abs(got - 2.0 / 21.0), 1e-8);
}

TEST(GaussLegendre10, CompositeRuleOnSmoothPeriodicIntegrand) {
  const double got = GaussLegendre10::integrate([](double x) { return std::exp(std::sin(x)); }, 0.0,
                                                2.0 * 3.14159265358979323846, 8);
  EXPECT_NEAR(got, 7.95492652101284527, 1e-13);  // 2π I0(1)
}

}  // namespace
}  // namespace ncd
