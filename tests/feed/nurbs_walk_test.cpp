// The walker on the curve it is built for: a rational cubic NURBS with the knot vector of
// paper 004, Fig. 11. No closed form here, so each step is checked against a slow reference:
// composite 10-point Gauss–Legendre with 16 panels per knot span piece.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <vector>

#include "core/quadrature.hpp"
#include "feed/curve_walker.hpp"
#include "geometry/nurbs.hpp"

namespace ncd::feed {
namespace {

toolpath::NurbsCurve fig11_path() {
  return toolpath::NurbsCurve(3, {0, 0, 0, 0, 0.2, 0.4, 0.6, 0.8, 1, 1, 1, 1},
                              {{0, 0, 0},
                               {10, 0, 8},
                               {20, 5, 15},
                               {30, 5, 4},
                               {40, 0, -6},
                               {50, 0, 10},
                               {60, 5, 12},
                               {70, 5, 0}},
                              {1.0, 0.8, 1.3, 1.0, 0.9, 1.2, 0.7, 1.0});
}

double reference_arc_mm(const toolpath::NurbsCurve& c, double u0, double u1) {
  const auto speed = [&c](double u) { return c.eval(u).d1.norm(); };
  double sum = 0.0, a = u0;
  for (double k : c.breakpoints()) {
    if (k > a && k < u1) {
      sum += GaussLegendre10::integrate(speed, a, k, 16);
      a = k;
    }
  }
  return sum + GaussLegendre10::integrate(speed, a, u1, 16);
}

struct Result {
  double max_error_rel = 0.0;
  double drift_mm = 0.0;
  bool ended = false;
};

Result walk_nurbs_case(const toolpath::NurbsCurve& curve, StepMode mode) {
  WalkerConfig config;
  config.mode = mode;
  CurveWalker walker(curve, config);
  Result res;
  double commanded = 0.0, travelled = 0.0;
  while (!walker.at_end()) {
    const double u0 = walker.u();
    const StepResult r = walker.step(0.4);
    const double true_mm = reference_arc_mm(curve, u0, r.u);
    travelled += true_mm;
    if (r.status == StepStatus::Ok) {
      res.max_error_rel = std::max(res.max_error_rel, std::abs(true_mm - 0.4) / 0.4);
      commanded += 0.4;
    } else {
      EXPECT_EQ(r.status, StepStatus::ReachedEnd);
      res.ended = r.u == curve.u_end();
      commanded += r.arc_length_mm;
    }
    res.drift_mm = std::max(res.drift_mm, std::abs(travelled - commanded));
  }
  return res;
}

TEST(CurveWalkerOnNurbs, CorrectionHoldsTheFeedOnTheFig11Path) {
  const toolpath::NurbsCurve curve = fig11_path();
  const Result corrected = walk_nurbs_case(curve, StepMode::Corrected);
  const Result taylor = walk_nurbs_case(curve, StepMode::TaylorOnly);
  std::cout << "Fig. 11 NURBS, length " << reference_arc_mm(curve, 0.0, 1.0) << " mm: corrected "
            << corrected.max_error_rel << " (drift " << corrected.drift_mm << " mm), Taylor only "
            << taylor.max_error_rel << " (drift " << taylor.drift_mm << " mm)\n";
  EXPECT_TRUE(corrected.ended);
  EXPECT_TRUE(taylor.ended);
  EXPECT_LE(corrected.max_error_rel, 1e-9);
  EXPECT_LE(corrected.drift_mm, 1e-6);
  EXPECT_GT(taylor.max_error_rel, 1e-6);
}

}  // namespace
}  // namespace ncd::feed
