// The service library without a socket (service/service.hpp): the state machine, the holder of
// a hold, the commands refused in the wrong state, the event feed and its drop count, and the
// setpoints a job emits against a motion::Job stepped directly here (the slow reference: the
// same job walked period by period with no cycle thread, no ring and no service).
#include "service/service.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <iostream>
#include <string>
#include <thread>
#include <vector>

#include "core/error.hpp"
#include "core/histogram.hpp"
#include "feed/feed_limits.hpp"
#include "gcode/path_io.hpp"
#include "tests/common/test_paths.hpp"
#include "tests/service/capture_sink.hpp"

namespace {

using namespace ncd;
using service::EventKind;
using service::HoldHolder;
using service::State;

std::shared_ptr<const toolpath::Path> cubic() {
  return std::make_shared<toolpath::Path>(
      toolpath::read_path_text(ncd::test::kCubicJson, "cubic.json"));
}

service::JobSpec service_job_of(std::shared_ptr<const toolpath::Path> path,
                                std::vector<motion::Setpoint>& out, bool& committed) {
  service::JobSpec j;
  j.name = "cubic";
  j.path = std::move(path);
  j.rules = service::LiveLimitRules::from(j.motion.limits);
  j.sink = std::make_unique<test::CaptureSink>(out, &committed);
  return j;
}

service::ServiceOptions simulated(std::size_t ring = 8192) {
  service::ServiceOptions o;
  o.clock = motion::ClockKind::Simulated;
  o.realtime = false;
  o.ring_capacity = ring;
  return o;
}

// The reference: the job stepped here, every setpoint up to the end.
std::vector<motion::Setpoint> service_reference(const toolpath::Path& path,
                                                const motion::JobConfig& c) {
  motion::Job job(path, c);
  std::vector<motion::Setpoint> out;
  for (;;) {
    job.prepare();
    const motion::Setpoint sp = job.step();
    EXPECT_EQ(sp.fault, motion::StepFault::None);
    out.push_back(sp);
    if (sp.done || out.size() > 1000000) break;
  }
  return out;
}

// Polls until the service is no longer busy (at most `polls` times).
void run_out(service::Service& s, int polls = 10000000) {
  while (s.poll() && --polls > 0) {
  }
  ASSERT_GT(polls, 0) << "the job never ended";
}

std::vector<service::Event> drain(service::Subscription& sub) {
  std::vector<service::Event> out;
  service::Event e;
  while (sub.pop(e)) out.push_back(e);
  return out;
}

TEST(ServiceStates, AJobRunsFromIdleToDoneAndEmitsTheReferenceSetpoints) {
  service::Service s(simulated());
  auto feed = s.subscribe(256);
  EXPECT_EQ(s.state(), State::Idle);
  std::vector<motion::Setpoint> got;
  bool committed = false;
  auto path = cubic();
  s.submit(service_job_of(path, got, committed));
  EXPECT_EQ(s.state(), State::Ready);
  s.start();
  EXPECT_EQ(s.state(), State::Running);
  run_out(s);
  EXPECT_EQ(s.state(), State::Done);
  EXPECT_TRUE(committed);
  const std::vector<motion::Setpoint> ref = service_reference(*path, motion::JobConfig{});
  ASSERT_EQ(got.size(), ref.size());
  for (std::size_t k = 0; k < ref.size(); ++k) {
    ASSERT_EQ(got[k].p, ref[k].p) << "setpoint " << k;
    ASSERT_EQ(got[k].t_s, ref[k].t_s) << "setpoint " << k;
  }
  EXPECT_NEAR(got.back().p.x(), 100.0, 1e-9);  // the last control point of the clamped cubic
  const service::Status st = s.status();
  EXPECT_EQ(st.setpoints, static_cast<std::int64_t>(ref.size()));
  EXPECT_DOUBLE_EQ(st.progress, 1.0);
  EXPECT_EQ(st.violations.total(), 0);
  // The events, in order, numbered without a gap.
  const auto ev = drain(*feed);
  std::vector<std::pair<EventKind, State>> seen;
  for (std::size_t k = 0; k < ev.size(); ++k) {
    EXPECT_EQ(ev[k].seq, k + 1);
    if (ev[k].kind == EventKind::State || ev[k].kind == EventKind::Job) {
      seen.emplace_back(ev[k].kind, ev[k].state);
    }
  }
  const std::vector<std::pair<EventKind, State>> want = {
      {EventKind::State, State::Ready},   {EventKind::Job, State::Ready},
      {EventKind::State, State::Running}, {EventKind::Job, State::Running},
      {EventKind::State, State::Done},    {EventKind::Job, State::Done}};
  EXPECT_EQ(seen, want);
  EXPECT_EQ(feed->dropped(), 0u);
}

// A sink slower than the cycle (1 ms a setpoint against a cycle thread on the simulated clock,
// which refills the ring as fast as it is drained): each poll still drains at most a ring's
// worth and comes back to its owner (the last one also flushes the ring the motion's end left),
// and the job ends with all the reference's setpoints.
TEST(ServiceStates, APollDrainsAtMostARingsWorthWhateverTheSinksSpeed) {
  constexpr std::size_t kRing = 16;
  service::Service s(simulated(kRing));
  std::vector<motion::Setpoint> got;
  bool committed = false;
  auto path = cubic();
  service::JobSpec j = service_job_of(path, got, committed);
  struct SlowSink : test::CaptureSink {
    using test::CaptureSink::CaptureSink;
    void write(const motion::Setpoint& sp) override {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
      test::CaptureSink::write(sp);
    }
  };
  j.sink = std::make_unique<SlowSink>(got, &committed);
  s.submit(std::move(j));
  s.start();
  std::size_t before = 0, full = 0;
  for (int polls = 0; polls < 10000000 && s.poll(); ++polls) {
    ASSERT_LE(got.size() - before, kRing) << "poll " << polls;
    full += got.size() - before == kRing ? 1 : 0;
    before = got.size();
  }
  EXPECT_LE(got.size() - before, 2 * kRing);  // the last: a ring, then the ring the end left
  EXPECT_EQ(s.state(), State::Done);
  // The sink was the slower: most polls stopped at the bound, with the ring refilled behind.
  EXPECT_GT(full, got.size() / kRing / 2) << got.size() << " setpoints";
  EXPECT_EQ(got.size(), service_reference(*path, motion::JobConfig{}).size());
}

TEST(ServiceStates, CommandsInTheWrongStateAreRefusedNamingIt) {
  service::Service s(simulated(64));
  const auto refused = [](auto&& f, const std::string& part) {
    try {
      f();
      ADD_FAILURE() << "accepted; expected an error with \"" << part << "\"";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };
  refused([&] { s.start(); }, "state idle");
  refused([&] { s.hold(HoldHolder::Operator); }, "state idle");
  refused([&] { s.resume(HoldHolder::Operator); }, "state idle");
  refused([&] { s.stop("x"); }, "state idle");
  refused([&] { s.set_override(250); }, "outside 0..200");  // a preset is checked too
  std::vector<motion::Setpoint> got;
  bool committed = false;
  s.submit(service_job_of(cubic(), got, committed));
  s.start();
  refused([&] { s.submit(service_job_of(cubic(), got, committed)); }, "a job is running");
  refused([&] { s.set_override(250); }, "outside 0..200");
  refused([&] { s.set_override(-1); }, "outside 0..200");
  s.hold(HoldHolder::Operator);
  EXPECT_EQ(s.status().holder, HoldHolder::Operator);
  // Only the holder releases a hold.
  refused([&] { s.resume(HoldHolder::Link); }, "held by the operator");
  s.resume(HoldHolder::Operator);
  EXPECT_EQ(s.state(), State::Running);
  EXPECT_EQ(s.status().holder, HoldHolder::None);
  run_out(s);
  EXPECT_EQ(s.state(), State::Done);
  refused([&] { s.start(); }, "state done");
}

TEST(ServiceStates, AnOperatorHoldComesToRestOnThePathAndResumesWithinTheLimits) {
  // A ring of 64 setpoints: the cycle (simulated clock) runs only as far ahead as poll() drains.
  service::Service s(simulated(64));
  std::vector<motion::Setpoint> got;
  bool committed = false;
  s.submit(service_job_of(cubic(), got, committed));
  s.start();
  while (got.size() < 100) s.poll();
  s.hold(HoldHolder::Operator);
  // Bounded by setpoints, not polls: how many setpoints a poll drains depends on the scheduler
  // (on one core about 14 000 polls went by before the hold's few dozen periods were made).
  const std::size_t held_at = got.size();
  while (got.size() < held_at + 1000 &&
         !(s.status().feed_mm_per_min == 0.0 && got.back().v_mm_per_s == 0.0)) {
    ASSERT_TRUE(s.poll()) << "the job ended while held";
  }
  ASSERT_EQ(got.back().v_mm_per_s, 0.0) << "not at rest 1000 periods after the hold";
  const Vec3 rest = got.back().p;
  const std::size_t n = got.size();
  for (int k = 0; k < 200; ++k) s.poll();
  // At rest, held: the walker may repay its sub-tolerance arc-length residual (PathWalker's
  // debt, here about 1e-14 mm) in the first held period; after that nothing moves at all.
  for (std::size_t k = n; k < got.size(); ++k) EXPECT_LT((got[k].p - rest).norm(), 1e-12);
  for (std::size_t k = n + 1; k < got.size(); ++k) EXPECT_EQ(got[k].p, got[n].p);
  EXPECT_EQ(s.state(), State::Holding);
  EXPECT_TRUE(s.status().time_left_s.has_value());
  s.resume(HoldHolder::Operator);
  run_out(s);
  EXPECT_EQ(s.state(), State::Done);
  const motion::JobConfig c;
  for (const auto& sp : got) {
    ASSERT_LE(std::abs(sp.a_mm_per_s2), c.limits.max_accel_mm_per_s2 * (1 + 1e-9));
    ASSERT_LE(std::abs(sp.j_mm_per_s3), c.limits.max_jerk_mm_per_s3 * (1 + 1e-9));
  }
  EXPECT_NEAR(got.back().p.x(), 100.0, 1e-9);
}

TEST(ServiceStates, StopEndsAsStoppedWithWhyAndWhereAndCommitsTheSetpoints) {
  service::Service s(simulated(64));
  std::vector<motion::Setpoint> got;
  bool committed = false;
  s.submit(service_job_of(cubic(), got, committed));
  s.start();
  while (got.size() < 50) s.poll();
  s.stop("the operator pressed stop");
  run_out(s);
  EXPECT_EQ(s.state(), State::Stopped);
  EXPECT_TRUE(committed);
  const service::Status st = s.status();
  ASSERT_TRUE(st.stopped.has_value());
  EXPECT_EQ(st.stopped->why, "the operator pressed stop");
  EXPECT_EQ(st.stopped->position_mm, got.back().p);
  EXPECT_EQ(got.back().v_mm_per_s, 0.0);
  EXPECT_LT(st.stopped->s_mm, st.stopped->length_mm);
  // A new job may follow.
  std::vector<motion::Setpoint> again;
  s.submit(service_job_of(cubic(), again, committed));
  EXPECT_EQ(s.state(), State::Ready);
}

// The status's program line and binding limit, poll by poll, against what the drained setpoint's
// position says independently: three sides of a square walked by G1 moves on source lines 3, 4
// and 5 (y = 0 on line 3, x = 20 on line 4, y = 20 on line 5). Each has its own feed, so each
// is its own segment (moves in a row at one feed make one polyline segment, whose line is the
// first's). Cruising in the middle of the first side at F600 (10 mm/s, far below the machine's
// limits) the program's F binds; held at rest, the hold.
TEST(ServiceStatus, TheProgramLineAndTheBindingLimitFollowTheSetpoints) {
  const char* kSquareProgram =
      "G21 G90 G17\nG0 X0 Y0 Z0\nG1 X20 F600\nG1 Y20 F480\nG1 X0 F600\nM2\n";
  auto path =
      std::make_shared<toolpath::Path>(toolpath::read_path_text(kSquareProgram, "square.ngc"));
  // The cycle on this thread, one period per poll: the status is read after every setpoint. (On
  // the cycle thread a poll drains whatever the thread has made, so how many setpoints a side
  // gets checked at depends on the scheduler: CI once saw 64 polls on a side of 500 periods.)
  service::ServiceOptions o = simulated(64);
  o.cycle_thread = false;
  o.periods_per_poll = 1;
  service::Service s(o);
  std::vector<motion::Setpoint> got;
  bool committed = false;
  s.submit(service_job_of(path, got, committed));
  EXPECT_EQ(s.status().line, 0);  // no setpoint yet
  EXPECT_EQ(s.status().binding_limit, "");
  s.start();
  int checked[6] = {};
  bool saw_program = false;
  const auto expected_line = [](const Vec3& p) {
    const double eps = 1e-6;  // the corners belong to either side: not checked
    if (std::abs(p.y()) < eps && p.x() > eps && p.x() < 20 - eps) return 3;
    if (std::abs(p.x() - 20) < eps && p.y() > eps && p.y() < 20 - eps) return 4;
    if (std::abs(p.y() - 20) < eps && p.x() > eps && p.x() < 20 - eps) return 5;
    return 0;
  };
  while (s.poll()) {
    if (got.empty()) continue;
    const service::Status st = s.status();
    const Vec3 p = got.back().p;
    if (const int want = expected_line(p); want > 0) {
      ASSERT_EQ(st.line, want) << "at " << p.transpose();
      ++checked[want];
    }
    // Mid-side, cruising: the F word binds.
    if (std::abs(got.back().v_mm_per_s - 10.0) < 1e-9 && std::abs(p.y()) < 1e-9 &&
        std::abs(p.x() - 10.0) < 2.0) {
      EXPECT_EQ(st.binding_limit, "program") << "at " << p.transpose();
      saw_program = true;
    }
    if (checked[4] == 10) {  // on the second side: hold, come to rest, resume
      s.hold(HoldHolder::Operator);
      while (s.poll() && !(got.back().v_mm_per_s == 0.0)) {
      }
      EXPECT_EQ(s.status().binding_limit, "hold");
      EXPECT_EQ(s.status().line, 4);
      s.resume(HoldHolder::Operator);
      ++checked[4];
    }
  }
  EXPECT_EQ(s.state(), State::Done);
  EXPECT_GT(checked[3], 100);
  EXPECT_GT(checked[4], 100);
  EXPECT_GT(checked[5], 100);
  EXPECT_TRUE(saw_program);
  EXPECT_EQ(s.status().line, 5);  // the end of the last move
}

// The feed limit the status carries (Status::feed_limit_mm_per_min, the last setpoint's
// motion::Setpoint::feed_limit_mm_per_s) against an evaluation written here: a line at F3000,
// a semicircle of radius 2 mm, a line back. On the lines the limit is the F word (the machine's
// 6000 mm/min and the roughness law at α = 0 are above it); on the arc the smallest of the F
// word, the chord law 2 √(2ρε − ε²) / T (Yeh and Hsu), √(a ρ), (j ρ²)^(1/3) and the roughness
// law at α = 0 (feed::feed_limit). Tolerance: at every setpoint the reported limit is
// at most that value (1e-9 relative: the sampler's nodes are interval minima) and the feed at
// most the reported limit (1e-9); more than 1 mm of path from a joint it equals the value to
// 1e-6 (the planner's curve is the smaller of two nodes, each the minimum over the two 0.2 mm
// intervals it bounds, so within 0.6 mm of a joint it may take the other side's value).
TEST(ServiceStatus, TheFeedLimitIsTheLawsValueAtThePositionAndTheFeedNeverExceedsIt) {
  const char* kLoopProgram = "G21 G90 G17\nG0 X0 Y0 Z0\nG1 X10 F3000\nG3 X10 Y4 I0 J2\nG1 X0\nM2\n";
  auto path = std::make_shared<toolpath::Path>(toolpath::read_path_text(kLoopProgram, "loop.ngc"));
  service::Service s(simulated(64));
  std::vector<motion::Setpoint> got;
  bool committed = false;
  s.submit(service_job_of(path, got, committed));
  EXPECT_EQ(s.status().feed_limit_mm_per_min, 0.0);  // no setpoint yet
  const motion::JobConfig c;                         // the job's limits (job_of's defaults)
  const feed::MachineLimits& m = c.limits;
  const double f_mm_per_s = 3000.0 / 60.0, rho_mm = 2.0, eps = m.chord_tolerance_mm;
  const double laws_line = feed::feed_limit(m, c.cutting, 0.0, 0.0).feed_mm_per_s;
  ASSERT_GT(laws_line, f_mm_per_s);  // the F word binds on the lines
  const double line_mm_per_s = f_mm_per_s;
  const double arc_mm_per_s = std::min(
      {f_mm_per_s, 2.0 * std::sqrt(2.0 * rho_mm * eps - eps * eps) / m.period_s,
       std::sqrt(m.max_accel_mm_per_s2 * rho_mm), std::cbrt(m.max_jerk_mm_per_s3 * rho_mm * rho_mm),
       feed::feed_limit(m, c.cutting, 1.0 / rho_mm, 0.0).feed_mm_per_s});
  ASSERT_LT(arc_mm_per_s, 0.9 * line_mm_per_s);  // the arc's laws bind there
  s.start();
  int middle_line = 0, middle_arc = 0;
  std::size_t seen = 0;
  while (s.poll()) {
    if (got.empty()) continue;
    EXPECT_EQ(s.status().feed_limit_mm_per_min, got.back().feed_limit_mm_per_s * 60.0);
    for (; seen < got.size(); ++seen) {
      const motion::Setpoint& sp = got[seen];
      const Vec3 p = sp.p;
      const bool on_arc = p.x() > 10.0 + 1e-9;
      double want = line_mm_per_s, from_joint_mm = std::abs(p.x() - 10.0);
      if (on_arc) {
        const double theta = std::atan2(p.y() - 2.0, p.x() - 10.0) + M_PI / 2;  // 0 … π
        want = arc_mm_per_s;
        from_joint_mm = rho_mm * std::min(theta, M_PI - theta);
      } else if (from_joint_mm < 1e-9) {
        want = arc_mm_per_s;  // on the joint: either side's
      }
      ASSERT_LE(sp.feed_limit_mm_per_s, want * (1 + 1e-9))
          << "t = " << sp.t_s << " s at " << p.transpose();
      ASSERT_LE(sp.v_mm_per_s, sp.feed_limit_mm_per_s * (1 + 1e-9))
          << "t = " << sp.t_s << " s at " << p.transpose();
      if (from_joint_mm > 1.0) {
        ASSERT_NEAR(sp.feed_limit_mm_per_s, want, 1e-6 * want)
            << "t = " << sp.t_s << " s at " << p.transpose();
        ++(on_arc ? middle_arc : middle_line);
      }
    }
  }
  EXPECT_EQ(s.state(), State::Done);
  EXPECT_GT(middle_line, 40);
  EXPECT_GT(middle_arc, 20);
  std::cout << "[ measured ] limit on the lines " << line_mm_per_s * 60 << " mm/min, on the arc "
            << arc_mm_per_s * 60 << " mm/min; " << middle_line << " + " << middle_arc
            << " setpoints away from the joints checked\n";
}

TEST(ServiceEvents, ALaggingSubscriberLosesEventsCountedNeverBlocksTheLoop) {
  service::Service s(simulated());
  auto slow = s.subscribe(2);  // never read until the end
  auto fast = s.subscribe(1024);
  std::vector<motion::Setpoint> got;
  bool committed = false;
  s.submit(service_job_of(cubic(), got, committed));
  s.start();
  run_out(s);
  const auto all = drain(*fast);
  const auto kept = drain(*slow);
  ASSERT_GE(all.size(), 6u);
  ASSERT_EQ(kept.size(), 2u);
  EXPECT_EQ(slow->dropped(), all.size() - 2);
  EXPECT_EQ(kept[0].seq, 1u);  // the first two were kept, the rest dropped
  EXPECT_EQ(kept[1].seq, 2u);
  EXPECT_EQ(s.status().events_dropped, all.size() - 2);
  // A closed subscriber is forgotten.
  fast->close();
  slow->close();
  s.submit(service_job_of(cubic(), got, committed));
  EXPECT_EQ(s.status().events_dropped, 0u);
}

}  // namespace

namespace {

// The fine histogram regrouped by hand to the coarse buckets: the slow reference of the live bins.
motion::Cycle::LatenessBins regrouped(const LogHistogram& h) {
  motion::Cycle::LatenessBins out{};
  for (int i = 0; i < LogHistogram::kBuckets; ++i) {
    const int g = i == 0 ? 0 : 1 + (i - 1) / (LogHistogram::kPerDecade / 8);
    out[static_cast<std::size_t>(g)] += h.buckets()[static_cast<std::size_t>(i)];
  }
  return out;
}

std::int64_t total(const motion::Cycle::LatenessBins& b) {
  std::int64_t n = 0;
  for (const std::int64_t c : b) n += c;
  return n;
}

}  // namespace

TEST(ServiceStatus, TheLiveLatenessHistogramGrowsAndEndsAsTheCyclesOwn) {
  // The wall clock (lateness > 0 happens): while the job runs every bin only grows and never
  // holds more wake-ups than periods run; at the end the bins are the cycle's full histogram
  // regrouped, and hold every wake-up (periods = wake-ups + periods caught up).
  service::ServiceOptions o;
  o.clock = motion::ClockKind::Wall;
  o.realtime = false;
  service::Service s(o);
  EXPECT_EQ(total(s.status().lateness_bins_ns), 0);
  EXPECT_EQ(s.cycle_stats(), nullptr);
  std::vector<motion::Setpoint> out;
  bool committed = false;
  s.submit(service_job_of(cubic(), out, committed));
  s.start();
  EXPECT_EQ(s.cycle_stats(), nullptr);  // the cycle runs
  motion::Cycle::LatenessBins last{};
  int looks = 0;
  while (s.poll()) {
    if (++looks % 50 == 0) {
      const service::Status st = s.status();
      for (std::size_t g = 0; g < last.size(); ++g) {
        ASSERT_GE(st.lateness_bins_ns[g], last[g]) << "bin " << g;
      }
      last = st.lateness_bins_ns;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ASSERT_EQ(s.state(), State::Done);
  const motion::CycleStats* stats = s.cycle_stats();
  ASSERT_NE(stats, nullptr);
  const service::Status st = s.status();
  EXPECT_EQ(st.lateness_bins_ns, regrouped(stats->lateness_ns));
  EXPECT_EQ(total(st.lateness_bins_ns), stats->periods - stats->caught_up);
  EXPECT_GT(stats->periods, 100);
}

TEST(ServiceStatus, OnTheSimulatedClockEveryWakeUpIsOnTime) {
  // No sleeping: every lateness is exactly 0, so all wake-ups fall in the first bin (< 1 ns).
  service::Service s(simulated());
  std::vector<motion::Setpoint> out;
  bool committed = false;
  s.submit(service_job_of(cubic(), out, committed));
  s.start();
  run_out(s);
  const service::Status st = s.status();
  EXPECT_EQ(st.lateness_bins_ns[0], static_cast<std::int64_t>(out.size()));
  EXPECT_EQ(total(st.lateness_bins_ns), st.lateness_bins_ns[0]);
}

// Issue 33: an override set before cycle start (idle, or with a job ready) is shown at once and
// applies from the job's first period: the setpoints equal a motion::Job stepped here with the
// same override set before its first step (and differ from the job at 100 %). It is used once:
// the next job starts at 100 %.
TEST(ServiceStates, AnOverridePresetBeforeStartAppliesFromTheFirstPeriod) {
  service::Service s(simulated());
  auto feed = s.subscribe(64);
  s.set_override(40);  // idle, no job
  EXPECT_EQ(s.state(), State::Idle);
  EXPECT_EQ(s.status().override_percent, 40.0);
  std::vector<motion::Setpoint> got;
  bool committed = false;
  s.submit(service_job_of(cubic(), got, committed));
  s.set_override(50);  // ready: replaces the preset
  EXPECT_EQ(s.status().override_percent, 50.0);
  const std::vector<service::Event> events = drain(*feed);
  std::vector<double> presets;
  for (const service::Event& e : events) {
    if (e.kind == EventKind::Override) presets.push_back(e.value);
  }
  EXPECT_EQ(presets, (std::vector<double>{40.0, 50.0}));
  s.start();
  EXPECT_EQ(s.status().override_percent, 50.0);
  run_out(s);
  ASSERT_EQ(s.state(), State::Done);
  EXPECT_EQ(s.status().override_percent, 100.0);  // the next start's: the preset was used
  motion::Job half(*cubic(), motion::JobConfig{});
  ASSERT_TRUE(half.set_override(0.5));
  std::vector<motion::Setpoint> want;
  for (;;) {
    half.prepare();
    want.push_back(half.step());
    if (want.back().done || want.size() > 1000000) break;
  }
  const std::vector<motion::Setpoint> full = service_reference(*cubic(), motion::JobConfig{});
  ASSERT_EQ(got.size(), want.size());
  EXPECT_GT(want.size(), full.size() + full.size() / 2);  // half the feed: far longer
  for (std::size_t k = 0; k < got.size(); ++k) {
    ASSERT_EQ(got[k].p, want[k].p) << k;
    ASSERT_EQ(got[k].v_mm_per_s, want[k].v_mm_per_s) << k;
  }
  // The next job, with no preset, runs at 100 %: the reference's setpoints.
  std::vector<motion::Setpoint> again;
  s.submit(service_job_of(cubic(), again, committed));
  s.start();
  run_out(s);
  ASSERT_EQ(again.size(), full.size());
  for (std::size_t k = 0; k < again.size(); ++k) ASSERT_EQ(again[k].p, full[k].p) << k;
}
