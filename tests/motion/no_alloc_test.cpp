// Nothing allocates in the cycle's period once the job is built: every operator new in this
// test binary is counted, and periods of a job with curves, polylines and joints must not move
// the count.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <new>
#include <optional>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "gcode/path_io.hpp"
#include "geometry/spiral.hpp"
#include "motion/job.hpp"
#include "tests/common/count_allocations.hpp"

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
  for (const auto bound : {feed::JerkBound::tangential, feed::JerkBound::vector}) {
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
    // §3b): the line of setpoints and its overlaps allocate nothing either.
    EXPECT_GT(job.delay_periods(), 0U);
    if (bound == feed::JerkBound::tangential) {
      EXPECT_GE(job.overlap_report().corners, 1U);
    }
    EXPECT_EQ(ncd::test::g_allocations.load() - before, 0)
        << "allocations during " << periods << " periods, jerk bound " << feed::to_string(bound);
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

// Every program we have (tests/ngc and, where installed, LinuxCNC's samples) that reads, on the
// machine under which flowsnake.ngc's landing once wrote past the planner's buffers (F15000,
// 3000 mm/s², 60 000 mm/s³): the job sizes its buffers when it is made, from the machine's top
// feed, and no period of the whole walk allocates (a buffer grown in a period would be an
// allocation here; one written past is ASan's, in the debug tree). Each walks to its end.
TEST(NoAllocation, EveryProgramWeHaveWalksWithoutAllocating) {
  namespace fs = std::filesystem;
  const fs::path table =
      fs::temp_directory_path() / ("ncd_noalloc_" + std::to_string(getpid()) + ".tbl");
  std::ofstream(table) << "T1 P1 Z75.5 D0.25\nT2 P2 Z-0.25 D0.5\nT3 P3 Z28.575 D0.125\n"
                          "T4 P4 Z19.05 D0.375\nT5 P5 Z50 D0.1\nT7 P7 Z60 D0.2\nT10 P10 Z100 D0.3\n"
                          "T20 P20 Z50.8 D1\n";
  std::vector<fs::path> programs;
  for (const fs::path& dir :
       {fs::path(NCD_SOURCE_DIR) / "tests" / "ngc", fs::path("/usr/share/linuxcnc/ncfiles")}) {
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
      if (e.path().extension() == ".ngc") programs.push_back(e.path());
    }
  }
  std::sort(programs.begin(), programs.end());
  JobConfig cfg;
  cfg.limits.max_feed_mm_per_min = 15000.0;
  cfg.limits.max_accel_mm_per_s2 = 3000.0;
  cfg.limits.max_jerk_mm_per_s3 = 60000.0;
  cfg.cutting.pick_feed_mm = 0.0;
  cfg.cutting.roughness_target_um = 1000.0;
  int walked = 0;
  for (const fs::path& file : programs) {
    toolpath::InterpretOptions o;
    o.tool_table = table.string();
    o.subroutine_path = {file.parent_path().string()};
    std::optional<toolpath::Path> path;
    try {
      path = toolpath::read_path_file(file.string(), o);
    } catch (const InputError&) {
      continue;  // refused by the reader (tests/app/walk_programs_test.cpp checks the words)
    }
    Job job(*path, cfg);
    ASSERT_TRUE(job.prepare()) << file << ": " << job.fault_message();
    const long before = ncd::test::g_allocations.load();
    Setpoint sp;
    std::int64_t periods = 0;
    while (!sp.done && periods < 50'000'000) {
      job.prepare();
      sp = job.step();
      ++periods;
      ASSERT_EQ(sp.fault, StepFault::None) << file << ": " << job.fault_message();
    }
    EXPECT_TRUE(sp.done) << file;
    EXPECT_EQ(ncd::test::g_allocations.load() - before, 0)
        << file << ": allocations during " << periods << " periods";
    ++walked;
  }
  fs::remove(table);
  std::printf("%d of %zu programs walked without allocating\n", walked, programs.size());
  EXPECT_GE(walked, 40);
}

}  // namespace
}  // namespace ncd::motion
