// The live limit rules of a service job (service/live_limits.hpp): each bound on synthetic
// setpoints, with the override's scaling (feed by o, chord by o²); a job whose rule is
// tightened below what the planner keeps to ends in error at the first setpoint that breaks it,
// which is not emitted, against the reference walk of the same job (motion::Job stepped here);
// with the rule on "report" the same job ends done and counts exactly the reference's
// violations.
#include "service/live_limits.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "gcode/path_io.hpp"
#include "service/service.hpp"
#include "tests/common/test_paths.hpp"
#include "tests/service/capture_sink.hpp"

namespace {

using namespace ncd;
using service::LimitKind;

motion::Setpoint sp_with(double v, double a, double j, double chord) {
  motion::Setpoint sp;
  sp.v_mm_per_s = v;
  sp.a_mm_per_s2 = a;
  sp.j_mm_per_s3 = j;
  sp.chord_error_mm = chord;
  return sp;
}

TEST(LiveLimits, EachBoundAndTheOverridesScaling) {
  service::LiveLimitRules r;
  r.max_feed_mm_per_s = 10.0;
  r.max_accel_mm_per_s2 = 100.0;
  r.max_jerk_mm_per_s3 = 1000.0;
  r.chord_tolerance_mm = 0.001;
  const double k = 1.0 + motion::kViolationRel;
  service::LiveLimitCheck c(r);
  EXPECT_EQ(c.check(sp_with(10.0 * k * 0.999999, 100.0, -1000.0, 0.001)), LimitKind::None);
  EXPECT_EQ(c.check(sp_with(10.0 * k * 1.000001, 0, 0, 0)), LimitKind::Feed);
  EXPECT_EQ(c.check(sp_with(0, -100.0 * k * 1.000001, 0, 0)), LimitKind::Accel);
  EXPECT_EQ(c.check(sp_with(0, 0, 1000.0 * k * 1.000001, 0)), LimitKind::Jerk);
  EXPECT_EQ(c.check(sp_with(0, 0, 0, 0.001 * k * 1.000001)), LimitKind::Chord);
  EXPECT_EQ(c.violations().total(), 4);
  // The first fatal one is kept, in the unit shown (feed in mm/min).
  EXPECT_EQ(c.violations().fatal, LimitKind::Feed);
  EXPECT_NEAR(c.violations().fatal_limit, 600.0 * k, 1e-9);
  // Override 150 %: the feed bound × 1.5, the chord bound × 2.25, acceleration and jerk as before.
  c.set_override(1.5);
  EXPECT_EQ(c.check(sp_with(14.9, 0, 0, 0.00224)), LimitKind::None);
  EXPECT_EQ(c.check(sp_with(15.1, 0, 0, 0)), LimitKind::Feed);
  EXPECT_EQ(c.check(sp_with(0, 0, 0, 0.00226)), LimitKind::Chord);
  EXPECT_EQ(c.check(sp_with(0, 101.0, 0, 0)), LimitKind::Accel);
  // An override back below 100 % does not tighten the bounds (the peak counts).
  c.set_override(0.5);
  EXPECT_EQ(c.check(sp_with(14.9, 0, 0, 0)), LimitKind::None);
  // Report only: counted, never fatal.
  service::LiveLimitRules rep = r;
  rep.feed = rep.accel = rep.jerk = rep.chord = service::RuleAction::Report;
  service::LiveLimitCheck q(rep);
  EXPECT_EQ(q.check(sp_with(1e3, 1e5, 1e7, 1.0)), LimitKind::None);
  EXPECT_EQ(q.violations().total(), 4);
  EXPECT_EQ(q.violations().fatal, LimitKind::None);
  // A NaN is never within a bound.
  service::LiveLimitCheck n(r);
  EXPECT_EQ(n.check(sp_with(std::nan(""), 0, 0, 0)), LimitKind::Feed);
}

struct Outcome {
  service::State state;
  service::Status status;
  std::vector<motion::Setpoint> emitted;
  bool committed = false;
  std::vector<service::Event> violations;
};

// The cubic as a service job whose acceleration rule allows accel_mm_per_s2 (the planner keeps
// to 1000 mm/s²).
Outcome run_with_accel_rule(double accel_mm_per_s2, service::RuleAction action) {
  service::ServiceOptions o;
  o.clock = motion::ClockKind::Simulated;
  o.realtime = false;
  service::Service s(o);
  auto feed = s.subscribe(1024);
  Outcome out;
  service::JobSpec j;
  j.name = "cubic";
  j.path = std::make_shared<toolpath::Path>(
      toolpath::read_path_text(ncd::test::kCubicJson, "cubic.json"));
  j.rules = service::LiveLimitRules::from(j.motion.limits);
  j.rules.max_accel_mm_per_s2 = accel_mm_per_s2;
  j.rules.accel = action;
  j.sink = std::make_unique<test::CaptureSink>(out.emitted, &out.committed);
  s.submit(std::move(j));
  s.start();
  for (long k = 0; s.poll() && k < 100000000; ++k) {
  }
  out.state = s.state();
  out.status = s.status();
  service::Event e;
  while (feed->pop(e)) {
    if (e.kind == service::EventKind::Violation) out.violations.push_back(e);
  }
  return out;
}

// The reference walk: every setpoint of the cubic, stepped here.
std::vector<motion::Setpoint> reference() {
  const toolpath::Path path = toolpath::read_path_text(ncd::test::kCubicJson, "cubic.json");
  motion::Job job(path, motion::JobConfig{});
  std::vector<motion::Setpoint> out;
  do {
    job.prepare();
    out.push_back(job.step());
  } while (!out.back().done && out.size() < 1000000);
  return out;
}

TEST(LiveLimits, AJobBreakingAnErrorRuleEndsInErrorAndTheSetpointIsNotEmitted) {
  const double rule = 600.0;  // below the 1000 mm/s² the planner plans with
  const std::vector<motion::Setpoint> ref = reference();
  const double allowed = rule * (1.0 + motion::kViolationRel);
  std::size_t first = ref.size();
  std::int64_t breaking = 0;
  for (std::size_t k = 0; k < ref.size(); ++k) {
    if (std::abs(ref[k].a_mm_per_s2) > allowed) {
      if (first == ref.size()) first = k;
      ++breaking;
    }
  }
  ASSERT_LT(first, ref.size()) << "the reference never exceeds " << rule << " mm/s2";
  ASSERT_GT(breaking, 1);

  const Outcome e = run_with_accel_rule(rule, service::RuleAction::Error);
  EXPECT_EQ(e.state, service::State::Error);
  EXPECT_FALSE(e.committed);           // a job in error keeps no setpoints file
  EXPECT_EQ(e.emitted.size(), first);  // everything before the first breaking setpoint, not it
  for (const auto& sp : e.emitted) ASSERT_LE(std::abs(sp.a_mm_per_s2), allowed);
  EXPECT_NE(e.status.error.find("accel"), std::string::npos) << e.status.error;
  EXPECT_NE(e.status.error.find("not emitted"), std::string::npos) << e.status.error;
  EXPECT_EQ(e.status.violations.accel, 1);
  EXPECT_EQ(e.status.violations.fatal, LimitKind::Accel);
  EXPECT_DOUBLE_EQ(e.status.violations.fatal_value, std::abs(ref[first].a_mm_per_s2));
  EXPECT_DOUBLE_EQ(e.status.violations.fatal_limit, allowed);
  EXPECT_DOUBLE_EQ(e.status.violations.fatal_t_s, ref[first].t_s);
  ASSERT_EQ(e.violations.size(), 1u);
  EXPECT_DOUBLE_EQ(e.violations[0].value, std::abs(ref[first].a_mm_per_s2));

  const Outcome r = run_with_accel_rule(rule, service::RuleAction::Report);
  EXPECT_EQ(r.state, service::State::Done);
  EXPECT_TRUE(r.committed);
  EXPECT_EQ(r.emitted.size(), ref.size());
  EXPECT_EQ(r.status.violations.accel, breaking);
  EXPECT_EQ(r.status.violations.fatal, LimitKind::None);

  // The machine's own limit: nothing to report.
  const Outcome ok = run_with_accel_rule(1000.0, service::RuleAction::Error);
  EXPECT_EQ(ok.state, service::State::Done);
  EXPECT_EQ(ok.status.violations.total(), 0);
}

}  // namespace
