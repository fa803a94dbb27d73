// Dense CAM programs under plain G64 P against the time-optimal bound of the shape they sample
// (issue 34; docs/planner.md §3d, §6). Three programs, each walked by the real Job under the
// default limits (the planner tests' machine: the roughness law out of the way):
//   - issue 34's program: 20 000 G1 of 0.01 mm along y = 5 sin(x/3), 4 decimals, F3000;
//   - a CAM-style finishing raster over a surface z = f(x, y) (tests/common/shape_bound.hpp);
//   - LinuxCNC's 3dtest.ngc (where installed), read by ncd's interpreter.
// The bound (tests/common/shape_bound.hpp) comes from the shape's own analytic curvature for the
// first two, and from a fine sampling of the programmed geometry (lines and arcs as read, before
// any fit or blend) for 3dtest. Asserted: the walk's duration within 1.15 of the bound (and never
// below it), every setpoint within P of the programmed points (distance to the polyline) and
// every programmed point within P of a chord between two setpoints. Durations are simulated
// time, never wall-clock.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "feed/limit_sampler_detail.hpp"
#include "gcode/path_io.hpp"
#include "motion/job.hpp"
#include "tests/common/shape_bound.hpp"
#include "tests/motion/planner_machine.hpp"
#include "tests/motion/reference.hpp"

namespace ncd::motion {
namespace {

using toolpath::NurbsCurve;
using toolpath::Path;
using toolpath::Polyline;

// A curve's length by the midpoint rule on |C'| (4096 steps).
double curve_length_mm(const NurbsCurve& c) {
  const int n = 4096;
  const double du = (c.u_end() - c.u_begin()) / n;
  double len = 0.0;
  for (int k = 0; k < n; ++k) len += du * c.eval(c.u_begin() + du * (k + 0.5)).d1.norm();
  return len;
}

struct DenseWalk {
  double t_s = 0.0;
  double setpoint_off_mm = 0.0;  // largest distance of a setpoint from the programmed path
  double vertex_off_mm = 0.0;    // largest distance of a programmed vertex from the chords
  feed::FitReport fit;
};

// Walks the path with cfg; measures the two distances against the programmed path.
DenseWalk walk_dense(const Path& path, const JobConfig& cfg) {
  Job job(path, cfg);
  const test::GeometryTable program = test::tabulate(path);
  DenseWalk w;
  w.fit = job.fit_report();
  std::vector<Vec3> sp_p;
  std::vector<double> sp_s;
  while (!job.done()) {
    job.prepare();
    const Setpoint sp = job.step();
    w.t_s = sp.t_s;
    w.setpoint_off_mm =
        std::max(w.setpoint_off_mm, test::distance_to_path(program, sp.p, sp.s_mm, 1.0));
    sp_p.push_back(sp.p);
    sp_s.push_back(sp.s_mm);
  }
  // Every polyline vertex against the chords between setpoints within 1 mm of its arc length.
  double s0 = 0.0;
  for (const auto& seg : path.segments) {
    const auto* line = std::get_if<Polyline>(&seg.geometry);
    if (!line) {
      const auto& c = std::get<NurbsCurve>(seg.geometry);
      s0 += curve_length_mm(c);
      continue;
    }
    double s = s0;
    for (std::size_t i = 0; i < line->points.size(); ++i) {
      if (i > 0) s += (line->points[i] - line->points[i - 1]).norm();
      const auto lo = std::lower_bound(sp_s.begin(), sp_s.end(), s - 1.0) - sp_s.begin();
      const auto hi = std::upper_bound(sp_s.begin(), sp_s.end(), s + 1.0) - sp_s.begin();
      double best = std::numeric_limits<double>::infinity();
      for (auto j = std::max<std::ptrdiff_t>(lo, 1); j < hi; ++j) {
        best = std::min(best, test::distance_to_segment(line->points[i], sp_p[j - 1], sp_p[j]));
      }
      w.vertex_off_mm = std::max(w.vertex_off_mm, best);
    }
    s0 = s;
  }
  return w;
}

JobConfig machine(bool fit_dense_runs = true) {
  JobConfig c = test::planner_machine();
  c.limits.fit_dense_runs = fit_dense_runs;
  return c;
}

void print_row(const char* name, const DenseWalk& w, double bound_s) {
  std::printf(
      "| %-34s | %7.3f s | %7.3f s | %5.3f | %3zu runs %4zu spans | %7.5f mm | %7.5f mm |\n", name,
      w.t_s, bound_s, w.t_s / bound_s, w.fit.runs, w.fit.spans, w.setpoint_off_mm, w.vertex_off_mm);
}

void print_header() {
  std::printf(
      "| program                            | ncd       | bound     | ratio | fitted             "
      "| setpoints | vertices  |\n");
}

// Within P: setpoints and vertices (the rounding of 4 decimals is in the program itself).
void expect_within(const DenseWalk& w, double p_mm) {
  EXPECT_LE(w.setpoint_off_mm, p_mm);
  EXPECT_LE(w.vertex_off_mm, p_mm);
}

TEST(DenseBound, SineUnderG64PNearTheShapesBound) {
  const JobConfig cfg = machine();
  const double bound =
      test::phase_plane_time_s(test::sine_limit(20000, cfg.limits), cfg.limits.max_accel_mm_per_s2,
                               cfg.limits.max_jerk_mm_per_s3);
  print_header();
  const DenseWalk off = walk_dense(test::sine_program(20000, 4, 0.01), machine(false));
  print_row("sine 4 dp, P0.01, fit off", off, bound);
  for (const double p : {0.01, 0.005, 0.002}) {
    const DenseWalk w = walk_dense(test::sine_program(20000, 4, p), cfg);
    char name[64];
    std::snprintf(name, sizeof name, "sine 4 dp, G64 P%g", p);
    print_row(name, w, bound);
    EXPECT_GE(w.t_s, bound);
    EXPECT_LE(w.t_s, 1.15 * bound) << name;
    EXPECT_GE(w.fit.runs, 1u);
    EXPECT_LE(w.fit.max_deviation_mm, p - cfg.limits.chord_tolerance_mm);
    expect_within(w, p);
  }
  // P ≤ ε_c leaves the fit no budget: the run stays a polyline, within P all the same.
  const DenseWalk tight = walk_dense(test::sine_program(20000, 4, 0.001), cfg);
  print_row("sine 4 dp, G64 P0.001 (no budget)", tight, bound);
  EXPECT_EQ(tight.fit.runs, 0u);
  EXPECT_GE(off.t_s, 1.3 * bound);  // what the fit gains: the raw polyline is far slower
}

TEST(DenseBound, SurfaceRasterNearTheShapesBound) {
  const JobConfig cfg = machine();
  constexpr std::size_t kPasses = 9;
  const double p = 0.01;
  const double bound =
      test::phase_plane_time_s(test::surface_limit(kPasses, p, cfg.limits),
                               cfg.limits.max_accel_mm_per_s2, cfg.limits.max_jerk_mm_per_s3);
  print_header();
  const DenseWalk off = walk_dense(test::surface_program(kPasses, 4, p), machine(false));
  print_row("surface raster 4 dp, P0.01, fit off", off, bound);
  const DenseWalk w = walk_dense(test::surface_program(kPasses, 4, p), cfg);
  print_row("surface raster 4 dp, G64 P0.01", w, bound);
  // One run per pass: the 90° corners at the step-overs are kept.
  EXPECT_EQ(w.fit.runs, kPasses);
  EXPECT_GE(w.t_s, bound);
  EXPECT_LE(w.t_s, 1.15 * bound);
  expect_within(w, p);
}

// The programmed geometry's limit (3dtest): polyline pieces at their cap, arcs (NURBS) sampled
// every ~2 µm with the curve laws at their curvature, each joint at the corner limit within P
// (0 under G61/G61.1/P0 and at a stop).
test::ShapeLimit program_limit(const Path& path, const feed::MachineLimits& l) {
  test::ShapeLimit lim;
  Vec3 prev_dir = Vec3::Zero();
  for (const auto& seg : path.segments) {
    const double cap =
        std::min(l.max_feed_mm_per_min,
                 seg.rapid || !seg.feed_mm_per_min ? l.max_feed_mm_per_min : *seg.feed_mm_per_min) /
        60.0;
    const bool blend = feed::sampler_detail::corner_mode(seg, l) == toolpath::PathControl::blend;
    const double p_mm = blend ? seg.blend_tolerance_mm.value_or(l.blend_tolerance_mm) : 0.0;
    const auto joint = [&](const Vec3& dir) {  // the corner into a piece of direction dir
      if (lim.s_mm.empty()) return;
      const double turn =
          prev_dir.norm() > 0.0 && dir.norm() > 0.0
              ? std::acos(std::clamp(prev_dir.normalized().dot(dir.normalized()), -1.0, 1.0))
              : 0.0;
      lim.v_mm_per_s.back() =
          std::min({lim.v_mm_per_s.back(), cap, test::corner_limit_mm_per_s(turn, p_mm, l)});
    };
    if (seg.stop_before && !lim.s_mm.empty()) lim.v_mm_per_s.back() = 0.0;
    if (const auto* line = std::get_if<Polyline>(&seg.geometry)) {
      for (std::size_t i = 0; i + 1 < line->points.size(); ++i) {
        const Vec3 d = line->points[i + 1] - line->points[i];
        if (!(d.norm() > 0.0)) continue;
        joint(d);
        if (lim.s_mm.empty()) lim.add(0.0, cap);
        lim.add_line(d.norm(), cap);
        prev_dir = d;
      }
      continue;
    }
    const auto& c = std::get<NurbsCurve>(seg.geometry);
    joint(c.eval(c.u_begin()).d1);
    if (lim.s_mm.empty()) lim.add(0.0, cap);
    const double len = curve_length_mm(c);
    const int n = std::max(64, static_cast<int>(len / 0.002));
    const double du = (c.u_end() - c.u_begin()) / n;
    for (int k = 1; k <= n; ++k) {
      const auto at = c.eval(c.u_begin() + du * k);
      const auto mid = c.eval(c.u_begin() + du * (k - 0.5));
      const double kappa = at.d1.cross(at.d2).norm() / std::pow(at.d1.norm(), 3);
      lim.add(du * mid.d1.norm(), test::curve_limit_mm_per_s(kappa, cap, l));
    }
    prev_dir = c.eval(c.u_end()).d1;
  }
  return lim;
}

TEST(DenseBound, LinuxCnc3dtestNearItsBound) {
  const std::string file = "/usr/share/linuxcnc/ncfiles/3dtest.ngc";
  if (!std::filesystem::exists(file)) GTEST_SKIP() << file << " is not installed";
  const JobConfig cfg = machine();
  const Path path = toolpath::read_path_file(file);
  const test::ShapeLimit lim = program_limit(path, cfg.limits);
  const double bound =
      test::phase_plane_time_s(lim, cfg.limits.max_accel_mm_per_s2, cfg.limits.max_jerk_mm_per_s3);
  std::size_t rests = 0;
  for (const double v : lim.v_mm_per_s) rests += v == 0.0 ? 1 : 0;
  std::printf("  3dtest: %zu segments, %.3f mm, %zu rests inside\n", path.segments.size(),
              lim.s_mm.back(), rests);
  print_header();
  const DenseWalk w = walk_dense(path, cfg);
  print_row("3dtest.ngc (G64, P = 0.01)", w, bound);
  EXPECT_GE(w.t_s, bound);
  EXPECT_LE(w.t_s, 1.15 * bound);
  // Its arcs are NURBS: the vertex check covers its lines; setpoints against lines and arcs.
  expect_within(w, cfg.limits.blend_tolerance_mm);
}

}  // namespace
}  // namespace ncd::motion
