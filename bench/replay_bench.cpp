// Replay throughput: periods per second of the whole job (look-ahead sampling, planner, path
// walk) on a long spiral NURBS, the work `ncd replay` and the service's cycle do per period.
#include <benchmark/benchmark.h>

#include <cmath>

#include "motion/job.hpp"

namespace ncd::motion {
namespace {

// An Archimedean spiral of `turns` turns from r = 100 mm inwards at 0.1 mm pitch, 16 control
// points per turn, as a cubic B-spline with integer knots (as LinuxCNC's G5.2 builds them).
toolpath::Path spiral(int turns) {
  const int per_turn = 16, n = turns * per_turn + 1, degree = 3;
  std::vector<Vec3> pts;
  for (int i = 0; i < n; ++i) {
    const double th = 2.0 * kPi * i / per_turn, r = 100.0 - 0.1 * i / per_turn;
    pts.emplace_back(r * std::cos(th), r * std::sin(th), 2.0 * std::sin(0.05 * th));
  }
  std::vector<double> knots(degree + 1, 0.0);
  const int inner = n - degree - 1;
  for (int i = 1; i <= inner; ++i) knots.push_back(i);
  knots.insert(knots.end(), degree + 1, inner + 1.0);
  toolpath::Path path;
  path.segments.push_back(
      {toolpath::NurbsCurve(degree, knots, pts), std::nullopt, std::nullopt, false, 0});
  path.source = "spiral";
  return path;
}

JobConfig machine() {
  JobConfig c;
  c.cutting.teeth = 4;
  c.cutting.spindle_rpm = 12000.0;
  return c;
}

void BM_ReplaySpiral(benchmark::State& state) {
  const toolpath::Path path = spiral(static_cast<int>(state.range(0)));
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
  const toolpath::Path path = spiral(200);
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
