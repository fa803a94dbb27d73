// Dense CAM programs against the time-optimal bound of the shape they sample (issue 34;
// docs/planner.md §3d). Each benchmark walks one program with the real Job under the planner
// tests' machine (defaults, the roughness law out of the way) and reports, besides the CPU time
// of building and walking the job:
//   ncd_s       the walk's duration (simulated time: periods × 4 ms);
//   bound_s     the shape's phase-plane bound (tests/common/shape_bound.hpp: the program feed and
//               the curve laws at the shape's analytic curvature, never anything ncd computes;
//               for 3dtest.ngc the programmed geometry as read);
//   ratio       ncd_s / bound_s (issue 34 asks ≤ 1.15);
//   setpoint_um the largest distance of a setpoint from the programmed path, vertex_um of a
//               programmed vertex from the chords between setpoints, P_um the program's P
//               (both must be ≤ P);
//   runs, spans what the fit made of the dense runs.
// Programs: issue 34's sine (20 000 G1 of 0.01 mm along y = 5 sin(x/3), 4 decimals, F3000) under
// G64 P0.01, P0.005, P0.002; the finishing raster of tests/motion/dense_bound_test.cpp
// (9 passes, 0.01 mm steps, 4 decimals); examples/surface-finish.ngc (7 passes, 0.025 mm steps,
// 3 decimals, read by ncd's interpreter); LinuxCNC's 3dtest.ngc where installed. The /off
// variants walk the same program with fit_dense_runs = false (the raw polyline).
#include <benchmark/benchmark.h>

#include <filesystem>
#include <string>

#include "gcode/path_io.hpp"
#include "motion/job.hpp"
#include "tests/common/dense_walk.hpp"
#include "tests/common/shape_bound.hpp"
#include "tests/motion/planner_machine.hpp"

namespace ncd::motion {
namespace {

JobConfig machine(bool fit) {
  JobConfig c = test::planner_machine();
  c.limits.fit_dense_runs = fit;
  return c;
}

// Walks `path` once for the figures, then builds and walks it in the timed loop.
void measure(benchmark::State& state, const toolpath::Path& path, const JobConfig& cfg,
             double bound_s, double p_mm) {
  const test::DenseWalk w = test::walk_dense(path, cfg);
  for (auto _ : state) {
    Job job(path, cfg);
    while (!job.done()) {
      job.prepare();
      benchmark::DoNotOptimize(job.step());
    }
  }
  state.counters["ncd_s"] = w.t_s;
  state.counters["bound_s"] = bound_s;
  state.counters["ratio"] = w.t_s / bound_s;
  state.counters["setpoint_um"] = 1000.0 * w.setpoint_off_mm;
  state.counters["vertex_um"] = 1000.0 * w.vertex_off_mm;
  state.counters["P_um"] = 1000.0 * p_mm;
  state.counters["runs"] = static_cast<double>(w.fit.runs);
  state.counters["spans"] = static_cast<double>(w.fit.spans);
}

// Arg 0: P in µm; arg 1: the default fit on (1) or off (0).
void BM_DenseSineVsShapeBound(benchmark::State& state) {
  const double p_mm = static_cast<double>(state.range(0)) / 1000.0;
  const JobConfig cfg = machine(state.range(1) != 0);
  const double bound =
      test::phase_plane_time_s(test::sine_limit(20000, cfg.limits), cfg.limits.max_accel_mm_per_s2,
                               cfg.limits.max_jerk_mm_per_s3);
  measure(state, test::sine_program(20000, 4, p_mm), cfg, bound, p_mm);
}
BENCHMARK(BM_DenseSineVsShapeBound)
    ->ArgNames({"P_um", "fit"})
    ->Args({10, 1})
    ->Args({5, 1})
    ->Args({2, 1})
    ->Args({10, 0})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(2);

void BM_DenseSurfaceRasterVsShapeBound(benchmark::State& state) {
  constexpr std::size_t kPasses = 9;
  const double p_mm = 0.01;
  const JobConfig cfg = machine(state.range(0) != 0);
  const double bound =
      test::phase_plane_time_s(test::surface_limit(kPasses, p_mm, cfg.limits),
                               cfg.limits.max_accel_mm_per_s2, cfg.limits.max_jerk_mm_per_s3);
  measure(state, test::surface_program(kPasses, 4, p_mm), cfg, bound, p_mm);
}
BENCHMARK(BM_DenseSurfaceRasterVsShapeBound)
    ->ArgName("fit")
    ->Arg(1)
    ->Arg(0)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(2);

void BM_SurfaceFinishNgcVsShapeBound(benchmark::State& state) {
  const std::string file = std::string(NCD_SOURCE_DIR) + "/examples/surface-finish.ngc";
  const JobConfig cfg = machine(state.range(0) != 0);
  const double p_mm = 0.01;
  measure(state, toolpath::read_path_file(file), cfg, test::surface_finish_bound_s(cfg.limits),
          p_mm);
}
BENCHMARK(BM_SurfaceFinishNgcVsShapeBound)
    ->ArgName("fit")
    ->Arg(1)
    ->Arg(0)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(2);

void BM_Linuxcnc3dtestVsBound(benchmark::State& state) {
  const std::string file = "/usr/share/linuxcnc/ncfiles/3dtest.ngc";
  if (!std::filesystem::exists(file)) {
    state.SkipWithError((file + " is not installed").c_str());
    return;
  }
  const JobConfig cfg = machine(state.range(0) != 0);
  const toolpath::Path path = toolpath::read_path_file(file);
  const double bound =
      test::phase_plane_time_s(test::program_limit(path, cfg.limits),
                               cfg.limits.max_accel_mm_per_s2, cfg.limits.max_jerk_mm_per_s3);
  measure(state, path, cfg, bound, cfg.limits.blend_tolerance_mm);
}
BENCHMARK(BM_Linuxcnc3dtestVsBound)
    ->ArgName("fit")
    ->Arg(1)
    ->Arg(0)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(2);

}  // namespace
}  // namespace ncd::motion
