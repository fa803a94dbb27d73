// The service with the cycle on the owner's thread (ServiceOptions::cycle_thread false, the
// simulated clock: how `ncd replay` runs its job). Checked against the slow reference of the old
// replay loop, written here: a motion::Job stepped directly, reading Job::limit_here and
// Job::roughness_here_um after each step. The sink must see the same setpoints with the same
// job state; a hold, a stop and an exception behave as the state machine says.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "gcode/path_io.hpp"
#include "service/service.hpp"
#include "tests/common/test_paths.hpp"
#include "tests/service/capture_sink.hpp"

namespace {

using namespace ncd;
using service::State;

// A square of G1 moves at one feed: corners where the limit and the rest points change.
const char* kSquare = "G21 G90 G94\nG0 X0 Y0 Z0\nG1 F3000 X20\nY20\nX0\nY0\nM2\n";

std::shared_ptr<const toolpath::Path> path_of(const char* text, const char* name) {
  return std::make_shared<toolpath::Path>(toolpath::read_path_text(text, name));
}

struct Seen {
  motion::Setpoint sp;
  double limit_mm_per_s = 0.0, roughness_um = 0.0;
  std::int64_t prepare_ns = 0, step_ns = 0;
};

// Records each setpoint with what the job says right after it, as replay's recorder does.
class JobStateSink final : public service::SetpointSink {
 public:
  explicit JobStateSink(std::vector<Seen>& out, int throw_at = -1)
      : out_(out), throw_at_(throw_at) {}
  void write(const motion::Setpoint&) override {
    throw std::logic_error("write() called with the cycle on the owner's thread");
  }
  void write_period(const motion::Setpoint& sp, const motion::Job& job,
                    const motion::PeriodTimes& times) override {
    if (static_cast<int>(out_.size()) == throw_at_) throw LimitError("the sink refuses");
    out_.push_back({sp, job.limit_here().feed_mm_per_s, job.roughness_here_um(sp.v_mm_per_s),
                    times.prepare_ns, times.step_ns});
  }
  void commit() override {}

 private:
  std::vector<Seen>& out_;
  int throw_at_;
};

// The old replay loop: prepare, step, then the job's limit and roughness at the new position.
std::vector<Seen> owner_reference(const toolpath::Path& path, const motion::JobConfig& cfg) {
  motion::Job job(path, cfg);
  std::vector<Seen> out;
  for (;;) {
    job.prepare();
    const motion::Setpoint sp = job.step();
    EXPECT_EQ(sp.fault, motion::StepFault::None);
    out.push_back({sp, job.limit_here().feed_mm_per_s, job.roughness_here_um(sp.v_mm_per_s)});
    if (sp.done || out.size() > 1000000) break;
  }
  return out;
}

service::ServiceOptions owner_thread(std::int64_t periods_per_poll = 1024) {
  service::ServiceOptions o;
  o.clock = motion::ClockKind::Simulated;
  o.realtime = false;
  o.cycle_thread = false;
  o.periods_per_poll = periods_per_poll;
  o.ring_capacity = 4;
  return o;
}

service::JobSpec spec_of(std::shared_ptr<const toolpath::Path> path,
                         std::unique_ptr<service::SetpointSink> sink) {
  service::JobSpec j;
  j.name = "job";
  j.path = std::move(path);
  j.rules = service::LiveLimitRules::from(j.motion.limits);
  j.sink = std::move(sink);
  return j;
}

TEST(ServiceOwnerThread, TheSinkSeesTheReferenceSetpointsWithTheJobAsEachLeftIt) {
  for (const auto& [text, name] :
       {std::pair{ncd::test::kCubicJson, "cubic.json"}, {kSquare, "square.ngc"}}) {
    SCOPED_TRACE(name);
    const auto path = path_of(text, name);
    std::vector<Seen> got;
    service::Service s(owner_thread(7));  // 7: the batches end anywhere, even mid-corner
    s.submit(spec_of(path, std::make_unique<JobStateSink>(got)));
    s.start();
    int polls = 0;
    while (s.poll()) ++polls;
    EXPECT_EQ(s.state(), State::Done);
    const std::vector<Seen> ref = owner_reference(*path, motion::JobConfig{});
    ASSERT_EQ(got.size(), ref.size());
    EXPECT_GE(polls, static_cast<int>(ref.size() / 7) - 1);  // at most 7 periods a poll
    for (std::size_t k = 0; k < ref.size(); ++k) {
      ASSERT_EQ(got[k].sp.p, ref[k].sp.p) << "setpoint " << k;
      ASSERT_EQ(got[k].sp.t_s, ref[k].sp.t_s) << "setpoint " << k;
      ASSERT_EQ(got[k].sp.v_mm_per_s, ref[k].sp.v_mm_per_s) << "setpoint " << k;
      ASSERT_EQ(got[k].sp.limit_id, ref[k].sp.limit_id) << "setpoint " << k;
      ASSERT_EQ(got[k].limit_mm_per_s, ref[k].limit_mm_per_s) << "setpoint " << k;
      ASSERT_EQ(got[k].roughness_um, ref[k].roughness_um) << "setpoint " << k;
      ASSERT_GE(got[k].prepare_ns, 0);
      ASSERT_GT(got[k].step_ns, 0);
    }
    // The cycle counted every period as a wake-up on time, none caught up.
    const motion::CycleStats* cs = s.cycle_stats();
    ASSERT_NE(cs, nullptr);
    EXPECT_EQ(cs->periods, static_cast<std::int64_t>(ref.size()));
    EXPECT_EQ(cs->caught_up, 0);
    EXPECT_EQ(cs->lateness_ns.count(), static_cast<std::int64_t>(ref.size()));
    EXPECT_EQ(cs->lateness_ns.max(), 0.0);
    EXPECT_GT(cs->first_window_ns, 0);
    ASSERT_NE(s.job(), nullptr);
    EXPECT_EQ(s.job()->length_mm(), s.status().length_mm);
    EXPECT_EQ(s.status().setpoints, static_cast<std::int64_t>(ref.size()));
  }
}

TEST(ServiceOwnerThread, TheSameSetpointsAsWithACycleThread) {
  const auto path = path_of(kSquare, "square.ngc");
  std::vector<motion::Setpoint> threaded;
  {
    service::ServiceOptions o = owner_thread();
    o.cycle_thread = true;
    o.ring_capacity = 64;
    service::Service s(o);
    s.submit(spec_of(path, std::make_unique<test::CaptureSink>(threaded)));
    s.start();
    while (s.poll()) {
    }
    ASSERT_EQ(s.state(), State::Done);
  }
  std::vector<Seen> here;
  service::Service s(owner_thread());
  s.submit(spec_of(path, std::make_unique<JobStateSink>(here)));
  s.start();
  while (s.poll()) {
  }
  ASSERT_EQ(here.size(), threaded.size());
  for (std::size_t k = 0; k < here.size(); ++k) {
    ASSERT_EQ(here[k].sp.p, threaded[k].p) << "setpoint " << k;
    ASSERT_EQ(here[k].sp.t_s, threaded[k].t_s) << "setpoint " << k;
  }
}

TEST(ServiceOwnerThread, HoldAndStopBetweenPollsActAtTheNextPeriod) {
  const auto path = path_of(ncd::test::kCubicJson, "cubic.json");
  std::vector<Seen> got;
  service::Service s(owner_thread(10));
  s.submit(spec_of(path, std::make_unique<JobStateSink>(got)));
  s.start();
  while (got.size() < 200) s.poll();
  ASSERT_EQ(got.size(), 200u);  // 20 polls of 10 periods
  s.hold(service::HoldHolder::Operator);
  // Held: the feed comes down to rest and stays there, the position with it.
  for (int k = 0; k < 200; ++k) s.poll();
  EXPECT_EQ(s.state(), State::Holding);
  ASSERT_EQ(got.size(), 2200u);
  EXPECT_EQ(got.back().sp.v_mm_per_s, 0.0);
  EXPECT_EQ(got[got.size() - 1].sp.p, got[got.size() - 100].sp.p);
  s.stop("the operator pressed stop");
  while (s.poll()) {
  }
  EXPECT_EQ(s.state(), State::Stopped);
  EXPECT_LT(got.back().sp.s_mm, s.job()->length_mm());
}

TEST(ServiceOwnerThread, AnExceptionOfTheSinkEndsTheJobInErrorAndReachesTheOwner) {
  std::vector<Seen> got;
  service::Service s(owner_thread());
  s.submit(spec_of(path_of(ncd::test::kCubicJson, "cubic.json"),
                   std::make_unique<JobStateSink>(got, 300)));
  s.start();
  try {
    while (s.poll()) {
    }
    FAIL() << "the sink's exception was swallowed";
  } catch (const LimitError& e) {
    EXPECT_STREQ(e.what(), "the sink refuses");
  }
  EXPECT_EQ(got.size(), 300u);
  EXPECT_EQ(s.state(), State::Error);
  EXPECT_EQ(s.status().error, "the sink refuses");  // not an "internal error"
  EXPECT_FALSE(s.poll());                           // the job is over; poll has nothing to do
}

TEST(ServiceOwnerThread, OnlyTheSimulatedClockRunsWithoutACycleThread) {
  service::ServiceOptions o = owner_thread();
  o.clock = motion::ClockKind::Wall;
  try {
    service::Service s(o);
    FAIL() << "a wall clock on the owner's thread was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("simulated clock"), std::string::npos) << e.what();
  }
}

}  // namespace
