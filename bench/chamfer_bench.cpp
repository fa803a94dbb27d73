// The whole experiment-3 path of paper 000 (segmentation, δ, Algorithm 1), against which the
// paper reports 46–62 ms on an i7-4770; and its parts, to see where the time goes. Then the
// README's holes beyond the paper (docs/chamfer.md, scripts/snapshot.py HOLES): a 45° lateral
// with 2 mm eccentricity in a 5° cone, an eccentric and a cone hole with the rod check, whose
// edge curves are intersected numerically, measured in the same run as the paper's case (also
// with the paper's closed-form edge, the baseline of the numerical intersection).
#include <benchmark/benchmark.h>

#include "cam/chamfer.hpp"

namespace ncd::toolpath {
namespace {

ChamferSpec experiment3() {
  ChamferSpec s;
  s.pipe_radius_mm = 18.0;
  s.drill_radius_mm = 13.0;
  s.ball_radius_mm = 3.0;
  s.width_mm = 0.7;
  s.tolerance_mm = 0.01;
  s.rod_radius_mm = 1.8;
  s.non_knife_angle_rad = deg_to_rad(93.0);
  return s;
}

void BM_Experiment3WholePath(benchmark::State& state) {
  const ChamferSpec spec = experiment3();
  std::size_t points = 0;
  for (auto _ : state) {
    const ChamferPath path = generate_chamfer(spec);
    points = path.points.size();
    benchmark::DoNotOptimize(path.points.data());
  }
  state.counters["points"] = static_cast<double>(points);
}
BENCHMARK(BM_Experiment3WholePath)->Unit(benchmark::kMicrosecond);

void BM_Experiment3ClosedFormEdge(benchmark::State& state) {
  ChamferSpec spec = experiment3();
  spec.edge_curve = EdgeCurve::ClosedForm;
  for (auto _ : state) benchmark::DoNotOptimize(generate_chamfer(spec).points.data());
}
BENCHMARK(BM_Experiment3ClosedFormEdge)->Unit(benchmark::kMicrosecond);

// The lateral: inner edge of R_I = 18 mm at the reference point, 3 mm wall, r = 13 mm drill
// tilted 45° along the pipe, 2 mm off its axis, cone half-angle 5°, the paper's ball and width.
// No rod limit: on the acute side of this edge no α keeps a vertical rod clear (refused).
ChamferSpec lateral() {
  ChamferSpec s = experiment3();
  s.drill_tilt_rad = deg_to_rad(45.0);
  s.eccentricity_mm = 2.0;
  s.pipe_half_angle_rad = deg_to_rad(5.0);
  s.pipe_thickness_mm = 3.0;
  s.rod_radius_mm.reset();
  s.non_knife_angle_rad.reset();
  return s;
}

void whole_path(benchmark::State& state, const ChamferSpec& spec) {
  std::size_t points = 0;
  int adjusted = 0;
  for (auto _ : state) {
    const ChamferPath path = generate_chamfer(spec);
    points = path.points.size();
    adjusted = path.checks.adjusted_points;
    benchmark::DoNotOptimize(path.points.data());
  }
  state.counters["points"] = static_cast<double>(points);
  state.counters["adjusted"] = adjusted;
}

void BM_Lateral45Eccentric2Cone5WholePath(benchmark::State& state) {
  whole_path(state, lateral());
}
BENCHMARK(BM_Lateral45Eccentric2Cone5WholePath)->Unit(benchmark::kMicrosecond);

// The README's eccentric hole (scripts/snapshot.py HOLES): experiment 3's inner upper edge
// with the rod check, the drill 3 mm off the pipe axis, a 3 mm wall (both surfaces checked).
void BM_Eccentric3WholePath(benchmark::State& state) {
  ChamferSpec s = experiment3();
  s.eccentricity_mm = 3.0;
  s.pipe_thickness_mm = 3.0;
  whole_path(state, s);
}
BENCHMARK(BM_Eccentric3WholePath)->Unit(benchmark::kMicrosecond);

// The README's cone hole: the same in a 5° cone.
void BM_Cone5WholePath(benchmark::State& state) {
  ChamferSpec s = experiment3();
  s.pipe_half_angle_rad = deg_to_rad(5.0);
  s.pipe_thickness_mm = 3.0;
  whole_path(state, s);
}
BENCHMARK(BM_Cone5WholePath)->Unit(benchmark::kMicrosecond);

void BM_Experiment3Segmentation(benchmark::State& state) {
  const ChamferModel model(experiment3());
  for (auto _ : state) benchmark::DoNotOptimize(model.segment());
}
BENCHMARK(BM_Experiment3Segmentation)->Unit(benchmark::kMicrosecond);

void BM_FeedDeltaNewton(benchmark::State& state) {
  const ChamferModel model(experiment3());
  const EdgeFrame f = model.frame(1.1);
  for (auto _ : state) benchmark::DoNotOptimize(model.solve_delta(f, 1.0));
}
BENCHMARK(BM_FeedDeltaNewton);

void BM_Algorithm1AtPiOver2(benchmark::State& state) {
  const ChamferModel model(experiment3());
  const EdgeFrame f = model.frame(1.5707963267948966);
  for (auto _ : state) benchmark::DoNotOptimize(model.avoid_rod(f));
}
BENCHMARK(BM_Algorithm1AtPiOver2);

}  // namespace
}  // namespace ncd::toolpath
