// Nothing allocates in the cycle's period once the job is built: every operator new in this
// test binary is counted, and periods of a job with curves, polylines and joints must not move
// the count.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <iostream>
#include <new>

#include "motion/job.hpp"
#include "tests/common/count_allocations.hpp"
#include "toolpath/path_io.hpp"
#include "toolpath/spiral.hpp"

namespace ncd::motion {
namespace {

TEST(NoAllocation, PeriodsOfAMixedPathAllocateNothing) {
  // A G-code program: lines, a G5.2 NURBS block, more lines: segment changes and joints, and a
  // slow start, so that higher limits reach the planner only after the first window; square
  // corners and a plunge and retract, where the job restarts its planner from rest; a second
  // G5.2 whose first and last points repeat (rest refinement at both ends, docs/planner.md §3).
  const toolpath::Path path = toolpath::read_path_text(
      "G21 G90\nG0 X0 Y0 Z0\nG1 X20 Y0 F300\nG1 X20 Y10 F3000\n"
      "G5.2 X30 Y20 P1 L4\nX40 Y0 P2\nX50 Y15 P1\nX60 Y5 P1\nG5.3\n"
      "G1 X70 Y5\nG5.2 X70 Y5 P1 L4\nX80 Y20 P1\nX90 Y0 P1\nX95 Y5 P1\nX95 Y5 P1\nG5.3\n"
      "G1 X70 Y-20 F1200\nG1 Z-2 F300\nG1 Z0\nM2\n",
      "mixed.ngc");
  ASSERT_GE(path.segments.size(), 3u);
  // Under both jerk bounds (the vector bound's curve spans and scales, docs/planner.md §3c).
  for (const auto bound : {interpolator::JerkBound::tangential, interpolator::JerkBound::vector}) {
    JobConfig cfg;
    cfg.cutting.teeth = 4;
    cfg.cutting.spindle_rpm = 12000.0;
    cfg.limits.jerk_bound = bound;
    Job job(path, cfg);
    job.prepare();  // the first look-ahead window is filled before the cycle starts
    const long before = ncd::test::g_allocations.load();
    int periods = 0;
    for (;;) {
      job.prepare();
      const Setpoint sp = job.step();
      ++periods;
      if (sp.done) break;
    }
    EXPECT_GT(periods, 100);
    EXPECT_GE(job.stops_mm().size(), 3u);
    // The corner at (20, 0) is passed without its stop under "tangential" (docs/planner.md
    // §3d): the line of setpoints and its overlaps allocate nothing either.
    EXPECT_GT(job.delay_periods(), 0U);
    if (bound == interpolator::JerkBound::tangential) {
      EXPECT_GE(job.overlap_report().corners, 1U);
    }
    EXPECT_EQ(ncd::test::g_allocations.load() - before, 0)
        << "allocations during " << periods << " periods, jerk bound "
        << interpolator::to_string(bound);
  }
}

// Memory does not grow with the run, and grows with the path only by its own data: the spiral
// of `ncd replay` at 10 and 40 turns (16 control points per turn). Every period of both runs
// allocates nothing; the look-ahead window reaches the same size; what the job allocates when
// it is built grows by a bounded amount per control point (the blended copy of the path, the
// walker's and the sampler's per-knot tables).
TEST(NoAllocation, ReplayMemoryIsFlatInPathLength) {
  struct Run {
    long build_bytes = 0, run_allocations = 0;
    std::size_t window = 0;
    int periods = 0;
  };
  const auto run = [](int turns) {
    const toolpath::Path path = toolpath::spiral_path(turns);
    Run r;
    const long b0 = ncd::test::g_allocated_bytes.load();
    Job job(path, JobConfig{});
    r.build_bytes = ncd::test::g_allocated_bytes.load() - b0;
    const long a0 = ncd::test::g_allocations.load();
    for (;;) {
      job.prepare();
      ++r.periods;
      if (job.step().done) break;
    }
    r.run_allocations = ncd::test::g_allocations.load() - a0;
    r.window = job.planner().window_samples_high_water();
    return r;
  };
  const Run short_run = run(10), long_run = run(40);
  EXPECT_GT(long_run.periods, 3 * short_run.periods);
  EXPECT_EQ(short_run.run_allocations, 0) << short_run.periods << " periods";
  EXPECT_EQ(long_run.run_allocations, 0) << long_run.periods << " periods";
  EXPECT_EQ(long_run.window, short_run.window);
  const long per_point = (long_run.build_bytes - short_run.build_bytes) / (30 * 16);
  std::cout << "[ memory   ] job built: " << short_run.build_bytes << " B (10 turns), "
            << long_run.build_bytes << " B (40 turns), " << per_point << " B per control point\n";
  EXPECT_LE(per_point, 512);
}

}  // namespace
}  // namespace ncd::motion
