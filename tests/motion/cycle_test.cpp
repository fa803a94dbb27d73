// The cycle thread: on the simulated clock it gives exactly the setpoints of stepping the job
// directly (replay); on the wall clock no setpoint is lost or skipped; hold, resume, override
// and stop act through the planner without breaking a limit.
#include "motion/cycle.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <iostream>
#include <thread>
#include <vector>

#include "gcode/path_io.hpp"
#include "tests/common/test_paths.hpp"

namespace ncd::motion {
namespace {

JobConfig machine() {
  JobConfig c;
  c.cutting.teeth = 4;
  c.cutting.spindle_rpm = 12000.0;
  return c;
}

// Steps the job directly, as replay does: the reference sequence.
std::vector<Setpoint> direct(const toolpath::Path& path) {
  Job job(path, machine());
  std::vector<Setpoint> out;
  for (;;) {
    job.prepare();
    out.push_back(job.step());
    if (out.back().done) return out;
  }
}

// Runs a cycle to its end, popping setpoints on this thread; `during` is called once per
// popped setpoint with the cycle and the setpoint's index.
template <class F>
std::vector<Setpoint> drain(Cycle& cycle, F&& during) {
  std::vector<Setpoint> out;
  Setpoint sp;
  for (;;) {
    if (cycle.pop(sp)) {
      out.push_back(sp);
      during(cycle, out.size() - 1);
    } else if (cycle.finished()) {
      while (cycle.pop(sp)) out.push_back(sp);
      break;
    } else {
      std::this_thread::yield();
    }
  }
  cycle.join();
  return out;
}

TEST(Cycle, SimulatedClockGivesExactlyTheReplaySetpoints) {
  const toolpath::Path path = toolpath::read_path_text(ncd::test::kCubicJson, "cubic");
  const std::vector<Setpoint> want = direct(path);
  CycleOptions o;
  o.clock = ClockKind::Simulated;
  o.ring_capacity = 64;  // small: the cycle must wait for the consumer, never drop
  Cycle cycle(std::make_unique<Job>(path, machine()), o);
  (void)cycle.start();
  const std::vector<Setpoint> got = drain(cycle, [](Cycle&, std::size_t) {});
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    ASSERT_EQ(got[i].p, want[i].p) << i;
    ASSERT_EQ(got[i].t_s, want[i].t_s) << i;
    ASSERT_EQ(got[i].v_mm_per_s, want[i].v_mm_per_s) << i;
  }
  EXPECT_EQ(cycle.stats().setpoints_lost, 0);
  EXPECT_EQ(cycle.status().state, CycleState::Done);
}

TEST(Cycle, WallClockLosesAndSkipsNothing) {
  // A 0.4 s move at 4 ms: every period gives one setpoint, t_s = k T, whatever the lateness.
  const toolpath::Path path = toolpath::read_path_text(
      R"({"polyline": {"points": [[0,0,0],[10,0,0]]}, "feed_mm_per_min": 3000})", "line");
  const std::size_t want = direct(path).size();
  CycleOptions o;
  o.clock = ClockKind::Wall;
  o.realtime = false;
  Cycle cycle(std::make_unique<Job>(path, machine()), o);
  const RealtimeGrant g = cycle.start();
  EXPECT_FALSE(g.message.empty());
  const std::vector<Setpoint> got = drain(cycle, [](Cycle&, std::size_t) {});
  ASSERT_EQ(got.size(), want);
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_NEAR(got[i].t_s, 0.004 * static_cast<double>(i + 1), 1e-12) << i;
  }
  const CycleStats& st = cycle.stats();
  EXPECT_EQ(st.setpoints_lost, 0);
  EXPECT_EQ(st.periods, static_cast<std::int64_t>(want));
  EXPECT_EQ(st.lateness_ns.count() + st.caught_up, st.periods);
}

// The same accounts with every core kept busy, so that wake-ups come late and periods are
// caught up (how many depends on the machine; the identities hold for any number, 0 included).
TEST(Cycle, WallClockUnderContentionAccountsForEveryPeriod) {
  const toolpath::Path path = toolpath::read_path_text(
      R"({"polyline": {"points": [[0,0,0],[10,0,0]]}, "feed_mm_per_min": 3000})", "line");
  const std::vector<Setpoint> reference = direct(path);
  const std::size_t want = reference.size();
  std::atomic<bool> busy{true};
  std::vector<std::thread> spinners;
  const unsigned n = 2 * std::max(1u, std::thread::hardware_concurrency());
  for (unsigned i = 0; i < n; ++i) {
    spinners.emplace_back([&busy] {
      volatile std::uint64_t x = 0;
      while (busy.load(std::memory_order_relaxed)) x = x + 1;
    });
  }
  CycleOptions o;
  o.clock = ClockKind::Wall;
  o.realtime = false;
  Cycle cycle(std::make_unique<Job>(path, machine()), o);
  (void)cycle.start();
  const std::vector<Setpoint> got = drain(cycle, [](Cycle&, std::size_t) {});
  busy = false;
  for (std::thread& t : spinners) t.join();
  ASSERT_EQ(got.size(), want);
  for (std::size_t i = 0; i < got.size(); ++i) {
    ASSERT_EQ(got[i].t_s, reference[i].t_s) << i;  // the time base, exactly
  }
  const CycleStats& st = cycle.stats();
  std::cout << "late wake-ups " << st.late_wakeups << ", caught up " << st.caught_up << " of "
            << st.periods << " periods\n";
  EXPECT_EQ(st.setpoints_lost, 0);
  EXPECT_EQ(st.periods, static_cast<std::int64_t>(want));
  EXPECT_EQ(st.lateness_ns.count() + st.caught_up, st.periods);
}

// Tangential limits over a sequence of setpoints (the planner's own a and j).
void expect_within_limits(const std::vector<Setpoint>& sps) {
  const JobConfig c = machine();
  for (const Setpoint& sp : sps) {
    ASSERT_LE(std::abs(sp.a_mm_per_s2), c.limits.max_accel_mm_per_s2 * (1 + 1e-9)) << sp.t_s;
    ASSERT_LE(std::abs(sp.j_mm_per_s3), c.limits.max_jerk_mm_per_s3 * (1 + 1e-9)) << sp.t_s;
    ASSERT_LE(sp.v_mm_per_s, 2.0 * c.limits.max_feed_mm_per_min / 60.0);
  }
}

TEST(Cycle, HoldThenResumeReachesTheSameEndWithinLimits) {
  const toolpath::Path path = toolpath::read_path_text(ncd::test::kCubicJson, "cubic");
  const std::vector<Setpoint> want = direct(path);
  CycleOptions o;
  o.clock = ClockKind::Simulated;
  o.ring_capacity = 2;  // the cycle stays within two periods of the consumer's commands
  Cycle cycle(std::make_unique<Job>(path, machine()), o);
  (void)cycle.start();
  std::size_t held_from = 0, resumed_at = 0;
  const std::vector<Setpoint> got = drain(cycle, [&](Cycle& c, std::size_t i) {
    if (i == 100) c.hold();
    if (i > 100 && held_from == 0 && c.status().state == CycleState::Holding &&
        c.status().v_mm_per_s == 0.0) {
      held_from = i;
    }
    if (held_from != 0 && i == held_from + 50) {
      c.resume();
      resumed_at = i;
    }
  });
  ASSERT_GT(held_from, 0u);
  ASSERT_GT(resumed_at, 0u);
  expect_within_limits(got);
  // While held at rest the position does not move.
  for (std::size_t i = held_from + 5; i < resumed_at; ++i)
    EXPECT_EQ(got[i].p, got[held_from + 5].p);
  EXPECT_TRUE(got.back().done);
  EXPECT_NEAR((got.back().p - want.back().p).norm(), 0.0, 1e-9);
  EXPECT_GT(got.size(), want.size());  // the hold took time
}

TEST(Cycle, OverrideChangesNeverBreakTheLimits) {
  const toolpath::Path path = toolpath::read_path_text(ncd::test::kCubicJson, "cubic");
  CycleOptions o;
  o.clock = ClockKind::Simulated;
  o.ring_capacity = 2;  // the cycle stays within two periods of the consumer's commands
  Cycle cycle(std::make_unique<Job>(path, machine()), o);
  (void)cycle.start();
  const std::vector<Setpoint> got = drain(cycle, [&](Cycle& c, std::size_t i) {
    if (i == 50) c.set_override(0.3);
    if (i == 200) c.set_override(2.0);
    if (i == 260) c.set_override(0.0);
    if (i == 400) c.set_override(1.0);
  });
  expect_within_limits(got);
  EXPECT_TRUE(got.back().done);
  // At 30 % the feed settles below 30 % of the machine maximum.
  EXPECT_LE(got[190].v_mm_per_s, 0.3 * 100.0 * (1 + 1e-9));
  // At 0 % it comes to rest on the path.
  EXPECT_EQ(got[399].v_mm_per_s, 0.0);
}

TEST(Cycle, StopComesToRestOnThePathBeforeItsEnd) {
  const toolpath::Path path = toolpath::read_path_text(ncd::test::kCubicJson, "cubic");
  CycleOptions o;
  o.clock = ClockKind::Simulated;
  o.ring_capacity = 2;  // the cycle stays within two periods of the consumer's commands
  Cycle cycle(std::make_unique<Job>(path, machine()), o);
  (void)cycle.start();
  const std::vector<Setpoint> got = drain(cycle, [&](Cycle& c, std::size_t i) {
    if (i == 120) c.stop();
  });
  expect_within_limits(got);
  EXPECT_EQ(cycle.status().state, CycleState::Stopped);
  EXPECT_FALSE(got.back().done);
  EXPECT_EQ(got.back().v_mm_per_s, 0.0);
  EXPECT_LT(got.back().s_mm, cycle.length_mm());
}

}  // namespace
}  // namespace ncd::motion
