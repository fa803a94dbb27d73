// One interpolation period of the curve walker on a rational cubic NURBS with the knot vector
// of paper 004, Fig. 11 ([0 0 0 0 0.2 0.4 0.6 0.8 1 1 1 1], an up- and down-milling path):
// Taylor predictor + Newton correction on the true arc length against the paper's Taylor-only
// step (eq. 7), at Δs = 0.4 mm (100 mm/s at 4 ms). docs/feedrate.md §2 quotes 4.3 µs per cycle
// for an RK2 predictor–corrector (Erwinski 2022).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <utility>
#include <vector>

#include "feed/curve_walker.hpp"
#include "feed/feed_limits.hpp"
#include "geometry/nurbs.hpp"

namespace ncd::feed {
namespace {

toolpath::NurbsCurve fig11_path() {
  std::vector<double> knots = {0, 0, 0, 0, 0.2, 0.4, 0.6, 0.8, 1, 1, 1, 1};
  std::vector<Vec3> points = {{0, 0, 0},   {10, 0, 8},  {20, 5, 15}, {30, 5, 4},
                              {40, 0, -6}, {50, 0, 10}, {60, 5, 12}, {70, 5, 0}};
  std::vector<double> weights = {1.0, 0.8, 1.3, 1.0, 0.9, 1.2, 0.7, 1.0};
  return toolpath::NurbsCurve(3, std::move(knots), std::move(points), std::move(weights));
}

constexpr double kDeltaSmm = 0.4;

void run_walker(benchmark::State& state, const WalkerConfig& config) {
  const toolpath::NurbsCurve curve = fig11_path();
  CurveWalker walker(curve, config);
  long steps = 0;
  long iterations = 0;
  for (auto _ : state) {
    if (walker.at_end()) walker.reset(curve.u_begin());
    const StepResult r = walker.step(kDeltaSmm);
    benchmark::DoNotOptimize(r);
    iterations += r.iterations;
    ++steps;
  }
  state.counters["iterations_per_step"] =
      static_cast<double>(iterations) / static_cast<double>(std::max(1L, steps));
}

void BM_WalkerStepCorrected(benchmark::State& state) {
  run_walker(state, WalkerConfig{});
}
BENCHMARK(BM_WalkerStepCorrected);

// The paper's interpolator: eq. (7) alone, one evaluation per period.
void BM_WalkerStepTaylorOnly(benchmark::State& state) {
  WalkerConfig config;
  config.mode = StepMode::TaylorOnly;
  config.measure_arc_length = false;
  run_walker(state, config);
}
BENCHMARK(BM_WalkerStepTaylorOnly);

// Taylor-only plus the Gauss–Legendre measurement of the arc it actually travelled.
void BM_WalkerStepTaylorMeasured(benchmark::State& state) {
  WalkerConfig config;
  config.mode = StepMode::TaylorOnly;
  run_walker(state, config);
}
BENCHMARK(BM_WalkerStepTaylorMeasured);

// What one evaluation of the curve costs, the unit of the three above.
void BM_NurbsEval(benchmark::State& state) {
  const toolpath::NurbsCurve curve = fig11_path();
  double u = 0.0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(curve.eval(u));
    u += 0.0007;
    if (u > 1.0) u = 0.0;
  }
}
BENCHMARK(BM_NurbsEval);

// The feed limit at the walker's new point, the other per-period cost of the cycle.
void BM_FeedLimitAtPoint(benchmark::State& state) {
  const toolpath::NurbsCurve curve = fig11_path();
  const MachineLimits limits;
  const CuttingParams cutting;
  double u = 0.0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(feed_limit_at(limits, cutting, curve.eval(u)));
    u += 0.0007;
    if (u > 1.0) u = 0.0;
  }
}
BENCHMARK(BM_FeedLimitAtPoint);

}  // namespace
}  // namespace ncd::feed
