// Replay throughput: periods per second of the whole job (look-ahead sampling, planner, path
// walk) on a long spiral NURBS, the work `ncd replay` and the service's cycle do per period.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>

#include "motion/job.hpp"
#include "toolpath/spiral.hpp"

namespace ncd::motion {
namespace {

JobConfig machine() {
  JobConfig c;
  c.cutting.teeth = 4;
  c.cutting.spindle_rpm = 12000.0;
  return c;
}

// The replay of `ncd replay --path-only` on the spiral of scripts/spiral_path.py (the issue's
// figure: 100 turns, 145 000 periods; here 20 turns, the same work per period). Arg 1 = 1:
// flat intervals skipped (the default); 0: the full search on every interval, the sampling
// as it was before (the baseline, in the same run). Counters: periods per second, and the
// share of the curve intervals found flat.
void BM_ReplaySpiral(benchmark::State& state) {
  const toolpath::Path path = toolpath::spiral_path(static_cast<int>(state.range(0)));
  JobConfig cfg;  // the documented defaults, as `ncd replay` without --machine
  cfg.sampler.skip_flat_intervals = state.range(1) != 0;
  std::int64_t periods = 0;
  double flat_share = 0.0;
  for (auto _ : state) {
    Job job(path, cfg);
    for (;;) {
      job.prepare();
      const Setpoint sp = job.step();
      ++periods;
      if (sp.done) break;
    }
    flat_share = static_cast<double>(job.sampler().flat_intervals()) /
                 static_cast<double>(std::max<std::size_t>(1, job.sampler().curve_intervals()));
  }
  state.counters["periods_per_s"] =
      benchmark::Counter(static_cast<double>(periods), benchmark::Counter::kIsRate);
  state.counters["flat_share"] = flat_share;
}
BENCHMARK(BM_ReplaySpiral)
    ->ArgNames({"turns", "skip_flat"})
    ->Args({20, 0})
    ->Args({20, 1})
    ->Unit(benchmark::kMillisecond);

void BM_JobCycleStep(benchmark::State& state) {
  // The cycle's share of a period (planner step + path walk), the look-ahead sampling done
  // outside the timed region as the planner thread does it.
  const toolpath::Path path = toolpath::spiral_path(200);
  auto job = std::make_unique<Job>(path, machine());
  for (auto _ : state) {
    state.PauseTiming();
    job->prepare();
    if (job->done()) job = std::make_unique<Job>(path, machine());
    job->prepare();
    state.ResumeTiming();
    benchmark::DoNotOptimize(job->step());
  }
}
BENCHMARK(BM_JobCycleStep);

}  // namespace
}  // namespace ncd::motion
