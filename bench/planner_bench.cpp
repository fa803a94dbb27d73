// Look-ahead feed planner: one step() on a long path (cruise, braking and landing mixed), and
// whole periods per second; the counter "rollouts" is the mean work per step. The fit of dense
// polylines under G64 Q (feed/polyline_fit.cpp) on the dense CAM program, against the
// cost of building the job on the raw polyline in the same run.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdlib>
#include <optional>
#include <vector>

#include "feed/polyline_fit.hpp"
#include "motion/job.hpp"
#include "motion/planner.hpp"
#include "tests/common/dense_cam.hpp"

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
      if (p.push({next_s, pattern_limit(next_s), 1}) != PushResult::Ok) std::abort();
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
  p.reserve_for_speed(60.0);
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

// Cruise at a flat limit: the common case. Arg 1 reuses the cruise's rollout from the memo
// (docs/planner.md §6, "The cruise from the memo"), arg 0 simulates it every period: the
// baseline, in the same run.
PlannerLimits memo_limits(const benchmark::State& state) {
  PlannerLimits l = bench_limits();
  l.reuse_rollouts = state.range(0) != 0;
  return l;
}

void BM_PlannerStepCruise(benchmark::State& state) {
  Planner p(memo_limits(state), 1e9);
  p.reserve_for_speed(50.0);
  double next_s = 0.0;
  for (auto _ : state) {
    while (p.wants_samples()) {
      if (p.push({next_s, 50.0, 1}) != PushResult::Ok) std::abort();
      next_s += 0.25;
    }
    benchmark::DoNotOptimize(p.step());
  }
  state.counters["from_memo"] = benchmark::Counter(static_cast<double>(p.rollouts_from_memo()),
                                                   benchmark::Counter::kAvgIterations);
}
BENCHMARK(BM_PlannerStepCruise)->Arg(0)->Arg(1)->Repetitions(5)->ReportAggregatesOnly(true);

// A whole 2 m path with the pattern, start to rest at L (arg as above).
void BM_PlannerWholePath(benchmark::State& state) {
  std::size_t periods = 0;
  for (auto _ : state) {
    Planner p(memo_limits(state), 2000.0);
    p.reserve_for_speed(60.0);
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
BENCHMARK(BM_PlannerWholePath)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// A zig-zag of 40 legs of 5 mm with 150° turns, walked whole by the job: arg 0 keeps its
// corners sharp (G64 P0: stops, no line of setpoints), arg 10 passes them within 0.01 mm
// (docs/planner.md §3b: the line of setpoints and an overlap at each corner). The baseline is
// arg 0 in the same run; items are emitted periods, and "simulated_s" the motion's duration.
void BM_JobZigZagCorners(benchmark::State& state) {
  std::vector<Vec3> pts{Vec3::Zero()};
  for (int i = 0; i < 40; ++i) {
    const double ang = (i % 2 ? -1.0 : 1.0) * (0.5 * M_PI - 15.0 * M_PI / 180.0);
    pts.push_back(pts.back() + 5.0 * Vec3(std::cos(ang), std::sin(ang), 0.0));
  }
  toolpath::Path path;
  toolpath::PathSegment seg;
  seg.geometry = toolpath::Polyline{pts, {}};
  seg.feed_mm_per_min = 6000.0;
  seg.blend_tolerance_mm = 1e-3 * static_cast<double>(state.range(0));
  path.segments.push_back(seg);
  std::int64_t periods = 0;
  double simulated_s = 0.0;
  for (auto _ : state) {
    Job job(path, JobConfig{});
    while (!job.done()) {
      job.prepare();
      simulated_s = job.step().t_s;
      ++periods;
    }
  }
  state.SetItemsProcessed(periods);
  state.counters["simulated_s"] = simulated_s;
}
BENCHMARK(BM_JobZigZagCorners)
    ->Arg(0)
    ->Arg(10)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(5)
    ->ReportAggregatesOnly(true);

// The fit alone (runs, least squares, proof); items are polyline points.
void BM_PolylineFit(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const toolpath::Path path = test::dense_cam(n - 1, 3, 0.01);
  const feed::MachineLimits limits;
  feed::FitReport rep;
  for (auto _ : state) {
    benchmark::DoNotOptimize(feed::fit_polylines(path, limits, &rep));
  }
  state.counters["spans"] = static_cast<double>(rep.spans);
  state.counters["deviation_um"] = 1000.0 * rep.max_deviation_mm;
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_PolylineFit)
    ->Arg(1000)
    ->Arg(20000)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(5)
    ->ReportAggregatesOnly(true);

// Baseline: building the job (walker, sampler) on the raw polyline, which the fit precedes.
void BM_JobBuildRawDense(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const toolpath::Path path = test::dense_cam(n - 1, 3, std::nullopt);
  JobConfig raw;
  raw.limits.fit_dense_runs = false;  // the polyline itself, not the default fit under G64 P
  for (auto _ : state) {
    Job job(path, raw);
    benchmark::DoNotOptimize(job.walker().length_mm());
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_JobBuildRawDense)
    ->Arg(1000)
    ->Arg(20000)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(5)
    ->ReportAggregatesOnly(true);

}  // namespace
}  // namespace ncd::motion
