// Gauss–Legendre quadrature on [a, b]: the arc-length integrals of paper 000 eq. (28)–(31), the
// per-period arc length of the curve walker, and the reference arc lengths of the tests. The
// 10-point rule (exact for polynomials of degree 19) and the 5-point rule (degree 9), from the
// roots of P10 and P5.
#pragma once

#include <array>
#include <cmath>

namespace ncd {

struct GaussLegendre10 {
  static constexpr std::array<double, 5> kNode = {
      0.1488743389816312108848260, 0.4333953941292471907992659, 0.6794095682990244062343274,
      0.8650633666889845107320967, 0.9739065285171717200779640};
  static constexpr std::array<double, 5> kWeight = {
      0.2955242247147528701738930, 0.2692667193099963550912269, 0.2190863625159820439955349,
      0.1494513491505805931457763, 0.0666713443086881375935688};

  // Integral of f over [a, b] with one 10-point panel.
  template <class F>
  static double integrate(F&& f, double a, double b) {
    const double half = 0.5 * (b - a);
    const double mid = 0.5 * (a + b);
    double sum = 0.0;
    for (std::size_t i = 0; i < kNode.size(); ++i) {
      sum += kWeight[i] * (f(mid - half * kNode[i]) + f(mid + half * kNode[i]));
    }
    return sum * half;
  }

  // Integral of f over [a, b] given its one-panel value `whole`: the panel against its two
  // halves, halved again until they agree to 1e-12 (relative), at most 8 halvings deep. Tighter
  // is noise: a span of Δu = 3e-4 near u = 0.05 resolves u only to 2e-14 of its width, so an
  // arc-length integrand |C'| itself carries ~1e-14 relative rounding.
  template <class F>
  static double adaptive(F&& f, double a, double b, double whole, int depth = 0) {
    const double m = 0.5 * (a + b);
    const double left = integrate(f, a, m);
    const double right = integrate(f, m, b);
    if (depth >= 8 || std::abs(left + right - whole) <= 1e-12 * std::abs(left + right)) {
      return left + right;
    }
    return adaptive(f, a, m, left, depth + 1) + adaptive(f, m, b, right, depth + 1);
  }

  // Integral of f over [a, b] with `panels` equal 10-point panels (composite rule).
  template <class F>
  static double integrate(F&& f, double a, double b, int panels) {
    const double h = (b - a) / panels;
    double sum = 0.0;
    for (int k = 0; k < panels; ++k) sum += integrate(f, a + k * h, a + (k + 1) * h);
    return sum;
  }
};

struct GaussLegendre5 {
  static constexpr std::array<double, 2> kNode = {0.5384693101056830910363144,
                                                  0.9061798459386639927976269};
  static constexpr std::array<double, 2> kWeight = {0.4786286704993664680412915,
                                                    0.2369268850561890875142640};
  static constexpr double kCentreWeight = 0.5688888888888888888888889;

  // Integral of f over [a, b] with one 5-point panel.
  template <class F>
  static double integrate(F&& f, double a, double b) {
    const double half = 0.5 * (b - a);
    const double mid = 0.5 * (a + b);
    double sum = kCentreWeight * f(mid);
    for (std::size_t i = 0; i < kNode.size(); ++i) {
      sum += kWeight[i] * (f(mid - half * kNode[i]) + f(mid + half * kNode[i]));
    }
    return sum * half;
  }
};

}  // namespace ncd
