// The whole experiment-3 path of paper 000 (segmentation, δ, Algorithm 1), against which the
// paper reports 46–62 ms on an i7-4770; and its parts, to see where the time goes.
#include <benchmark/benchmark.h>

#include "toolpath/chamfer.hpp"

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
