// Block encoder throughput (setpoints per second) on the experiment-3 chamfer of paper 000
// walked at 4 ms as `ncd replay out/demo/exp3.json --machine config/chamfer-exp3.toml` walks
// it, against a baseline that only copies the setpoints; with what the encoding gives at
// 19 200 baud 7E2 (blocks, characters, link use, chord error against the tolerance, lowered
// blocks, predicted underruns) as counters. Two more cases bound the cost: a straight line
// (the running bound keeps every block O(1) a setpoint up to the cap) and a circle at a
// tolerance just above the rounding error (the exact scans the bound cannot spare).
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include "cam/chamfer.hpp"
#include "geometry/nurbs.hpp"
#include "link/block_encoder.hpp"
#include "motion/job.hpp"

namespace ncd::comms {
namespace {

using motion::Setpoint;

// The chamfer path as `ncd chamfer` writes it and path_io reads it: the loop of ball centres,
// contact normals −e, closed on its first point, F300 S3000.
toolpath::Path experiment3_path() {
  toolpath::ChamferSpec s;  // R_I 18, r 13, R_B 3, W 0.7, ε 0.01, inner upper edge
  s.rod_radius_mm = 1.8;
  s.non_knife_angle_rad = deg_to_rad(93.0);
  const toolpath::ChamferPath chamfer = toolpath::generate_chamfer(s);
  toolpath::Polyline pl;
  for (const auto& p : chamfer.points) {
    pl.points.push_back(p.cl);
    pl.normals.push_back(-p.e);
  }
  pl.points.push_back(pl.points.front());
  pl.normals.push_back(pl.normals.front());
  toolpath::PathSegment seg;
  seg.geometry = std::move(pl);
  seg.feed_mm_per_min = 300.0;
  seg.spindle_rpm = 3000.0;
  toolpath::Path path;
  path.segments.push_back(std::move(seg));
  return path;
}

// config/chamfer-exp3.toml.
motion::JobConfig experiment3_machine() {
  motion::JobConfig c;  // period 4 ms, 6000 mm/min, 1000 mm/s², 20000 mm/s³, chord 1 µm
  c.cutting.ball_radius_mm = 3.0;
  c.cutting.pick_feed_mm = 0.0;
  c.cutting.teeth = 2;
  c.cutting.spindle_rpm = 3000.0;
  c.cutting.roughness_target_um = 0.05;
  return c;
}

std::vector<Setpoint> walk(const toolpath::Path& path, const motion::JobConfig& config) {
  motion::Job job(path, config);
  std::vector<Setpoint> out;
  Setpoint start;  // at rest at the start, as replay pushes it
  start.p = job.walker().position();
  out.push_back(start);
  for (;;) {
    job.prepare();
    out.push_back(job.step());
    if (out.back().done) break;
  }
  return out;
}

const std::vector<Setpoint>& experiment3_setpoints() {
  static const std::vector<Setpoint> sps = walk(experiment3_path(), experiment3_machine());
  return sps;
}

void run_encoder(benchmark::State& state, const std::vector<Setpoint>& sps,
                 const EncoderSettings& settings) {
  EncoderStats stats;
  for (auto _ : state) {
    std::int64_t chars = 0;
    BlockEncoder enc(settings, [&chars](const EncodedBlock& b) { chars += b.chars; });
    for (const Setpoint& sp : sps) enc.push(sp);
    enc.finish();
    benchmark::DoNotOptimize(chars);
    stats = enc.stats();
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(sps.size()));
  state.counters["setpoints"] = static_cast<double>(sps.size());
  state.counters["blocks"] = static_cast<double>(stats.blocks);
  state.counters["chars"] = static_cast<double>(stats.chars);
  state.counters["block_min_mm"] = stats.length_min_mm;
  state.counters["block_median_mm"] = stats.length_median_mm();
  state.counters["link_use_mean_pct"] = 100.0 * stats.link_use_mean();
  state.counters["link_use_peak_pct"] = 100.0 * stats.link_use_peak;
  state.counters["link_use_overall_pct"] = 100.0 * stats.link_use_overall();
  state.counters["chord_err_max_um"] = 1000.0 * stats.chord_error_max_mm;
  state.counters["tolerance_um"] = 1000.0 * stats.chord_tolerance_mm;
  state.counters["lowered_blocks"] = static_cast<double>(stats.lowered_blocks);
  state.counters["underruns"] = static_cast<double>(stats.queue.underruns);
}

// The encoder with the defaults: 2 µm, ±5 %, 80 % of 19 200 baud 7E2, µm, F to 0.1 mm/min.
void BM_EncodeExperiment3(benchmark::State& state) {
  run_encoder(state, experiment3_setpoints(), EncoderSettings{});
}
BENCHMARK(BM_EncodeExperiment3)->Unit(benchmark::kMicrosecond);

// The floor: each setpoint copied once into a buffer, through the same kind of sink call.
void BM_CopySetpointsBaseline(benchmark::State& state) {
  const std::vector<Setpoint>& sps = experiment3_setpoints();
  std::vector<Setpoint> out(sps.size());
  for (auto _ : state) {
    std::size_t n = 0;
    const auto sink = [&out, &n](const Setpoint& sp) { out[n++] = sp; };
    for (const Setpoint& sp : sps) sink(sp);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(sps.size()));
}
BENCHMARK(BM_CopySetpointsBaseline)->Unit(benchmark::kMicrosecond);

// 20 000 setpoints on a straight line at 20 mm/s: blocks run to the cap of 4096.
void BM_EncodeStraightLine(benchmark::State& state) {
  std::vector<Setpoint> sps;
  const Vec3 dir = Vec3(3, 4, 12).normalized();
  for (int k = 0; k <= 20000; ++k) {
    Setpoint sp;
    sp.t_s = 0.004 * k;
    sp.s_mm = 20.0 * sp.t_s;
    sp.p = Vec3(1, 2, 3) + sp.s_mm * dir;
    sp.v_mm_per_s = 20.0;
    sps.push_back(sp);
  }
  EncoderSettings s;
  s.line.baud = 115200;
  run_encoder(state, sps, s);
}
BENCHMARK(BM_EncodeStraightLine)->Unit(benchmark::kMicrosecond);

// A 50 mm circle at 3000 mm/min with the tolerance at 1.05 times the rounding error: the
// running bound rarely spares the scan.
void BM_EncodeCircleTightTolerance(benchmark::State& state) {
  const double r = 50.0, w = std::sqrt(0.5);
  std::vector<Vec3> pts = {{r, 0, 0},   {r, r, 0},  {0, r, 0},  {-r, r, 0}, {-r, 0, 0},
                           {-r, -r, 0}, {0, -r, 0}, {r, -r, 0}, {r, 0, 0}};
  toolpath::PathSegment seg;
  seg.geometry = toolpath::NurbsCurve(2, {0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1},
                                      std::move(pts), {1, w, 1, w, 1, w, 1, w, 1});
  seg.feed_mm_per_min = 3000.0;
  toolpath::Path path;
  path.segments.push_back(std::move(seg));
  motion::JobConfig c;
  c.cutting.teeth = 4;
  c.cutting.spindle_rpm = 12000.0;
  static const std::vector<Setpoint> sps = walk(path, c);
  EncoderSettings s;
  s.line.baud = 115200;
  s.chord_tolerance_mm = 1.05 * rounding_error_mm(3);
  run_encoder(state, sps, s);
}
BENCHMARK(BM_EncodeCircleTightTolerance)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace ncd::comms
