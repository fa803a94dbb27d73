// Look-ahead feed planner: one step() on a long path (cruise, braking and landing mixed), and
// whole periods per second; the counter "rollouts" is the mean work per step.
#include <benchmark/benchmark.h>

#include <cmath>

#include "motion/planner.hpp"

namespace ncd::motion {
namespace {

// A repetitive 20 mm pattern sampled every 0.25 mm: flat, a drop, a rippled stretch.
double pattern_limit(double s) {
  const double x = std::fmod(s, 20.0);
  if (x < 12.0) return 60.0;
  if (x < 14.0) return 15.0;
  return 40.0 + 5.0 * std::sin(x);
}

struct Feeder {
  double next_s = 0.0;
  void feed(Planner& p) {
    while (p.wants_samples()) {
      p.push({next_s, pattern_limit(next_s), 1});
      next_s += 0.25;
    }
  }
};

PlannerLimits bench_limits() {
  PlannerLimits l;
  l.a_max_mm_per_s2 = 1000.0;
  l.j_max_mm_per_s3 = 20000.0;
  l.period_s = 0.004;
  return l;
}

// One period (push of the samples it wants, then step) on an effectively endless path.
void BM_PlannerStep(benchmark::State& state) {
  Planner p(bench_limits(), 1e9);
  Feeder f;
  for (int i = 0; i < 1000; ++i) {  // warm up: past the first acceleration
    f.feed(p);
    p.step();
  }
  double rollouts = 0.0;
  for (auto _ : state) {
    f.feed(p);
    benchmark::DoNotOptimize(p.step());
    rollouts += static_cast<double>(p.last_step_rollouts());
  }
  state.counters["rollouts"] = benchmark::Counter(rollouts, benchmark::Counter::kAvgIterations);
  state.counters["periods_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_PlannerStep)->Repetitions(5)->ReportAggregatesOnly(true);

// Cruise at a flat limit: the common case.
void BM_PlannerStepCruise(benchmark::State& state) {
  Planner p(bench_limits(), 1e9);
  double next_s = 0.0;
  for (auto _ : state) {
    while (p.wants_samples()) {
      p.push({next_s, 50.0, 1});
      next_s += 0.25;
    }
    benchmark::DoNotOptimize(p.step());
  }
}
BENCHMARK(BM_PlannerStepCruise)->Repetitions(5)->ReportAggregatesOnly(true);

// A whole 2 m path with the pattern, start to rest at L.
void BM_PlannerWholePath(benchmark::State& state) {
  std::size_t periods = 0;
  for (auto _ : state) {
    Planner p(bench_limits(), 2000.0);
    Feeder f;
    periods = 0;
    while (!p.done()) {
      f.feed(p);
      p.step();
      ++periods;
    }
  }
  state.counters["periods"] = static_cast<double>(periods);
  state.counters["periods_per_s"] = benchmark::Counter(
      static_cast<double>(periods * state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_PlannerWholePath)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace ncd::motion
