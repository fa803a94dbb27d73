// Replay throughput: periods per second of the whole job (look-ahead sampling, planner, path
// walk) on a long spiral NURBS, the work `ncd replay` and the service's cycle do per period.
#include <benchmark/benchmark.h>

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

void BM_ReplaySpiral(benchmark::State& state) {
  const toolpath::Path path = toolpath::spiral_path(static_cast<int>(state.range(0)));
  std::int64_t periods = 0;
  for (auto _ : state) {
    Job job(path, machine());
    for (;;) {
      job.prepare();
      const Setpoint sp = job.step();
      ++periods;
      if (sp.done) break;
    }
  }
  state.counters["periods_per_s"] =
      benchmark::Counter(static_cast<double>(periods), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ReplaySpiral)->Arg(20)->Unit(benchmark::kMillisecond);

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
