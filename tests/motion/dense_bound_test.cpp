// Dense CAM programs under plain G64 P against the time-optimal bound of the shape they sample
// (issue 34; docs/planner.md §3d, §6). Three programs, each walked by the real Job under the
// default limits (the planner tests' machine: the roughness law out of the way):
//   - issue 34's program: 20 000 G1 of 0.01 mm along y = 5 sin(x/3), 4 decimals, F3000;
//   - a CAM-style finishing raster over a surface z = f(x, y) (tests/common/shape_bound.hpp),
//     generated here (4 decimals) and as examples/surface-finish.ngc (3 decimals, read from text);
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
#include "tests/common/dense_walk.hpp"
#include "tests/common/shape_bound.hpp"
#include "tests/motion/planner_machine.hpp"
#include "tests/motion/reference.hpp"

namespace ncd::motion {
namespace {

using toolpath::NurbsCurve;
using toolpath::Path;
using toolpath::Polyline;

JobConfig dense_machine(bool fit_dense_runs = true) {
  JobConfig c = test::planner_machine();
  c.limits.fit_dense_runs = fit_dense_runs;
  return c;
}

void print_row(const char* name, const test::DenseWalk& w, double bound_s) {
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
void expect_within(const test::DenseWalk& w, double p_mm) {
  EXPECT_LE(w.setpoint_off_mm, p_mm);
  EXPECT_LE(w.vertex_off_mm, p_mm);
}

TEST(DenseBound, SineUnderG64PNearTheShapesBound) {
  const JobConfig cfg = dense_machine();
  const double bound =
      test::phase_plane_time_s(test::sine_limit(20000, cfg.limits), cfg.limits.max_accel_mm_per_s2,
                               cfg.limits.max_jerk_mm_per_s3);
  print_header();
  const test::DenseWalk off =
      test::walk_dense(test::sine_program(20000, 4, 0.01), dense_machine(false));
  print_row("sine 4 dp, P0.01, fit off", off, bound);
  for (const double p : {0.01, 0.005, 0.002}) {
    const test::DenseWalk w = test::walk_dense(test::sine_program(20000, 4, p), cfg);
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
  const test::DenseWalk tight = test::walk_dense(test::sine_program(20000, 4, 0.001), cfg);
  print_row("sine 4 dp, G64 P0.001 (no budget)", tight, bound);
  EXPECT_EQ(tight.fit.runs, 0u);
  EXPECT_GE(off.t_s, 1.3 * bound);  // what the fit gains: the raw polyline is far slower
}

TEST(DenseBound, SurfaceRasterNearTheShapesBound) {
  const JobConfig cfg = dense_machine();
  constexpr std::size_t kPasses = 9;
  const double p = 0.01;
  const double bound =
      test::phase_plane_time_s(test::surface_limit(kPasses, p, cfg.limits),
                               cfg.limits.max_accel_mm_per_s2, cfg.limits.max_jerk_mm_per_s3);
  print_header();
  const test::DenseWalk off =
      test::walk_dense(test::surface_program(kPasses, 4, p), dense_machine(false));
  print_row("surface raster 4 dp, P0.01, fit off", off, bound);
  const test::DenseWalk w = test::walk_dense(test::surface_program(kPasses, 4, p), cfg);
  print_row("surface raster 4 dp, G64 P0.01", w, bound);
  // One run per pass: the 90° corners at the step-overs are kept.
  EXPECT_EQ(w.fit.runs, kPasses);
  EXPECT_GE(w.t_s, bound);
  EXPECT_LE(w.t_s, 1.15 * bound);
  expect_within(w, p);
}

// examples/surface-finish.ngc (scripts/surface_finish.py): the same surface as above, as a CAM
// post writes it (7 passes, 0.025 mm steps, 3 decimals, only the words that change), read by
// ncd's interpreter, with its 5 mm retract: one run per pass, near the shape's bound, within P.
TEST(DenseBound, SurfaceFinishExampleNearTheShapesBound) {
  const JobConfig cfg = dense_machine();
  const double p = 0.01, bound = test::surface_finish_bound_s(cfg.limits);
  const Path path =
      toolpath::read_path_file(std::string(NCD_SOURCE_DIR) + "/examples/surface-finish.ngc");
  print_header();
  const test::DenseWalk off = test::walk_dense(path, dense_machine(false));
  print_row("surface-finish.ngc, fit off", off, bound);
  const test::DenseWalk w = test::walk_dense(path, cfg);
  print_row("surface-finish.ngc, G64 P0.01", w, bound);
  EXPECT_EQ(w.fit.runs, 7u);
  EXPECT_GE(w.t_s, bound);
  EXPECT_LE(w.t_s, 1.15 * bound);
  expect_within(w, p);
  EXPECT_GE(off.t_s, 1.15 * bound);  // the raw polyline of 3 decimals is not near the bound
}

TEST(DenseBound, LinuxCnc3dtestNearItsBound) {
  const std::string file = "/usr/share/linuxcnc/ncfiles/3dtest.ngc";
  if (!std::filesystem::exists(file)) GTEST_SKIP() << file << " is not installed";
  const JobConfig cfg = dense_machine();
  const Path path = toolpath::read_path_file(file);
  const test::ShapeLimit lim = test::program_limit(path, cfg.limits);
  const double bound =
      test::phase_plane_time_s(lim, cfg.limits.max_accel_mm_per_s2, cfg.limits.max_jerk_mm_per_s3);
  std::size_t rests = 0;
  for (const double v : lim.v_mm_per_s) rests += v == 0.0 ? 1 : 0;
  std::printf("  3dtest: %zu segments, %.3f mm, %zu rests inside\n", path.segments.size(),
              lim.s_mm.back(), rests);
  print_header();
  const test::DenseWalk w = test::walk_dense(path, cfg);
  print_row("3dtest.ngc (G64, P = 0.01)", w, bound);
  EXPECT_GE(w.t_s, bound);
  EXPECT_LE(w.t_s, 1.15 * bound);
  // Its arcs are NURBS: the vertex check covers its lines; setpoints against lines and arcs.
  expect_within(w, cfg.limits.blend_tolerance_mm);
}

}  // namespace
}  // namespace ncd::motion
