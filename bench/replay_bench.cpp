// Replay throughput: periods per second of the whole job (look-ahead sampling, planner, path
// walk) on a long spiral NURBS, the work `ncd replay` and the service's cycle do per period.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>

#include "geometry/spiral.hpp"
#include "motion/job.hpp"
#include "motion/run_stats.hpp"
#include "service/service.hpp"

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

// The same replay with per-axis limits (docs/planner.md §3f, §6): Arg 0, none (the baseline,
// in the same run); 1, examples/machine-slow-z.toml's Z (1500 mm/min, 250 mm/s², 4000 mm/s³);
// 2, that Z and X and Y at 10 000 mm/s³. The work per period the 300 000 periods per
// CPU second asks of a machine with axis limits.
void BM_ReplaySpiralAxes(benchmark::State& state) {
  const toolpath::Path path = toolpath::spiral_path(20);
  JobConfig cfg;
  if (state.range(0) >= 1) {
    cfg.limits.axes[2].max_feed_mm_per_min = 1500.0;
    cfg.limits.axes[2].max_accel_mm_per_s2 = 250.0;
    cfg.limits.axes[2].max_jerk_mm_per_s3 = 4000.0;
  }
  if (state.range(0) >= 2) {
    cfg.limits.axes[0].max_jerk_mm_per_s3 = 10000.0;
    cfg.limits.axes[1].max_jerk_mm_per_s3 = 10000.0;
  }
  std::int64_t periods = 0;
  for (auto _ : state) {
    Job job(path, cfg);
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
BENCHMARK(BM_ReplaySpiralAxes)
    ->ArgName("axes")
    ->Arg(0)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond);

// `ncd replay`'s loop with its per-setpoint statistics (the feed limit and the roughness at the
// new position, motion::record), two ways on the 20-turn spiral: Arg 0, the job stepped
// directly as replay did before it ran on the service library (the baseline); Arg 1, the same
// work through service::Service on the simulated clock without a cycle thread, the statistics
// in a SetpointSink (app/replay_cmd.cpp's ReplayRecorder without its files).
class RecordSink final : public service::SetpointSink {
 public:
  RecordSink(RunStats& st, const JobConfig& cfg) : st_(st), cfg_(cfg) {}
  void write(const Setpoint&) override {}
  void write_period(const Setpoint& sp, const Job& job, const PeriodTimes& times) override {
    record(st_, cfg_, sp, job.limit_here().feed_mm_per_s, job.roughness_here_um(sp.v_mm_per_s),
           static_cast<double>(times.step_ns));
  }
  void commit() override {}

 private:
  RunStats& st_;
  const JobConfig& cfg_;
};

void BM_ReplayLoop(benchmark::State& state) {
  const auto path = std::make_shared<const toolpath::Path>(toolpath::spiral_path(20));
  const JobConfig cfg;
  const bool through_service = state.range(0) != 0;
  std::int64_t periods = 0;
  for (auto _ : state) {
    RunStats st;
    if (through_service) {
      service::ServiceOptions o;
      o.clock = ClockKind::Simulated;
      o.realtime = false;
      o.cycle_thread = false;
      o.ring_capacity = 16;
      service::Service svc(o);
      service::JobSpec spec;
      spec.path = path;
      spec.motion = cfg;
      spec.rules = service::LiveLimitRules::from(cfg.limits);
      spec.rules.feed = spec.rules.accel = spec.rules.jerk = spec.rules.chord =
          service::RuleAction::Report;
      spec.sink = std::make_unique<RecordSink>(st, cfg);
      svc.submit(std::move(spec));
      svc.start();
      while (svc.poll()) {
      }
    } else {
      Job job(*path, cfg);
      for (;;) {
        const auto t0 = std::chrono::steady_clock::now();
        job.prepare();
        const auto t1 = std::chrono::steady_clock::now();
        const Setpoint sp = job.step();
        const auto t2 = std::chrono::steady_clock::now();
        benchmark::DoNotOptimize(t1 - t0);
        record(st, cfg, sp, job.limit_here().feed_mm_per_s, job.roughness_here_um(sp.v_mm_per_s),
               static_cast<double>(std::chrono::nanoseconds(t2 - t1).count()));
        if (sp.done) break;
      }
    }
    periods += st.cycles;
  }
  state.counters["periods_per_s"] =
      benchmark::Counter(static_cast<double>(periods), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ReplayLoop)->ArgName("service")->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

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
