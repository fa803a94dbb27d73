// Nothing allocates in the cycle's period once the job is built: every operator new in this
// test binary is counted, and periods of a job with curves, polylines and joints must not move
// the count.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

#include "motion/job.hpp"
#include "tests/common/count_allocations.hpp"
#include "toolpath/path_io.hpp"

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
  JobConfig cfg;
  cfg.cutting.teeth = 4;
  cfg.cutting.spindle_rpm = 12000.0;
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
  EXPECT_EQ(ncd::test::g_allocations.load() - before, 0)
      << "allocations during " << periods << " periods";
}

}  // namespace
}  // namespace ncd::motion
