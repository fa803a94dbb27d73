// A service job streamed live to the simulated controller, in process. The controller runs on a
// ManualClock that the test moves on (tests/common/paced_controller.hpp: never behind the wall
// clock, on which the sender paces its writes), and the service's cycle on the simulated clock
// with a 64-setpoint ring, so that the motion runs only as far as poll() drains it; the test
// drains it only once the sender has taken every block queued so far. The controller's
// reception, execution and injected hold are in its time. The controller raises DC3 at 192
// characters of a 4096-byte buffer: 3904 characters, 0.34 s of the sender's output, instead of
// the 64 characters (5.6 ms) of a 256-byte one, so its thread may be kept from running that long
// before a batch of characters overflows it.
// The sender times the controller's holds on the controller's clock (SenderSettings::hold_clock),
// so that a hold lasts as long for both ends however long the test's thread is kept waiting.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "core/error.hpp"
#include "gcode/path_io.hpp"
#include "link/block_encoder.hpp"
#include "link/sha256.hpp"
#include "service/service.hpp"
#include "sim/sim_controller.hpp"
#include "tests/common/paced_controller.hpp"
#include "tests/service/capture_sink.hpp"

namespace {

using namespace ncd;
using namespace std::chrono_literals;
namespace fs = std::filesystem;

const char* kCubic = R"({"nurbs": {"degree": 3, "knots": [0,0,0,0,0.25,0.5,0.75,1,1,1,1],
  "points": [[0,0,0],[10,25,0],[30,-10,2],[45,30,4],[60,0,3],[80,20,0],[100,0,0]]},
  "feed_mm_per_min": 1500})";

// How long a controller's DC3 lasts, on its clock, before the sender reports it and holds the
// motion: longer than any hold of the controller's flow control in these tests.
constexpr double kXoffTimeoutS = 1.0;

comms::LineSettings line_at(const std::string& device) {
  comms::LineSettings l;
  l.device = device;
  l.baud = 115200;
  l.data_bits = 8;
  l.parity = comms::Parity::None;
  l.stop_bits = 1;
  l.flow = comms::Flow::XonXoff;
  return l;
}

class LiveLink : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("ncd_service_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    ctl_.stop();
    fs::remove_all(dir_);
  }

  void start_controller(const comms::SimFaults& faults) {
    comms::SimControllerConfig c;
    c.line = line_at((dir_ / "cnc").string());
    c.exit_at_end = true;
    c.seed = 1;
    c.faults = faults;
    c.buffer_bytes = 4096;
    c.xoff_at = 192;
    c.xon_at = 96;
    ctl_.start(c);
  }

  void step(double dt_s) { ctl_.step(dt_s); }
  // The sender reads the line until the job's link is done.
  void follow(service::Service& s) {
    ctl_.while_sender_reads([&s] {
      const service::Status st = s.status();
      return !st.link || !st.link->done;
    });
  }

  service::JobSpec job(std::vector<motion::Setpoint>& out) {
    service::JobSpec j;
    j.name = "cubic";
    j.path = std::make_shared<toolpath::Path>(toolpath::read_path_text(kCubic, "cubic.json"));
    j.rules = service::LiveLimitRules::from(j.motion.limits);
    j.sink = std::make_unique<test::CaptureSink>(out);
    service::LinkSpec link;
    link.sender.line = line_at((dir_ / "cnc").string());
    link.sender.xoff_timeout_s = kXoffTimeoutS;
    link.sender.hold_clock = ctl_.clock();
    link.encoder.max_block_s = 0.5;
    j.link = link;
    return j;
  }

  // One turn of the loop paced by the controller: the service drains the cycle only once the
  // sender has taken every block queued so far, so the motion runs at most a ring (64 periods)
  // and a block ahead of what the controller accepts, in the controller's time.
  static void paced_poll(service::Service& s) {
    const service::Status st = s.status();
    if (!st.link || st.link->blocks_waiting == 0) s.poll();
  }

  // What the controller complained of, for a failure's message.
  static std::string alarms_and_errors(const comms::SimLog& log) {
    const nlohmann::json j = comms::to_json(log);
    return "alarms " + j["alarms"].dump() + ", errors " + j["errors"].dump() + ", end executed " +
           (log.program_end_executed ? "yes" : "no");
  }

  static service::ServiceOptions options() {
    service::ServiceOptions o;
    o.clock = motion::ClockKind::Simulated;
    o.realtime = false;
    o.ring_capacity = 64;
    return o;
  }

  // The blocks a fresh encoder makes of the emitted setpoints (what `ncd replay --blocks`
  // writes for them), each with its end of block: the program the controller must receive.
  static std::string expected_program(const std::vector<motion::Setpoint>& sps,
                                      const Vec3& start_mm) {
    comms::EncoderSettings enc;
    enc.max_block_s = 0.5;
    enc.line = line_at("");
    std::string text;
    comms::BlockEncoder e(enc, [&](const comms::EncodedBlock& b) { text += b.text + "\n"; });
    motion::Setpoint start;
    start.p = start_mm;
    e.push(start);
    for (const auto& sp : sps) e.push(sp);
    e.finish();
    return text;
  }

  fs::path dir_;
  ncd::test::PacedController ctl_;
};

TEST_F(LiveLink, JobStreamsLiveToTheControllerAsReplayEncodesIt) {
  start_controller({});
  service::Service s(options());
  follow(s);
  std::vector<motion::Setpoint> emitted;
  s.submit(job(emitted));
  s.start();
  for (int k = 0; k < 200000 && (s.busy() || !ctl_.done()); ++k) {
    paced_poll(s);
    step(0.005);
  }
  ctl_.stop();
  ASSERT_EQ(s.state(), service::State::Done)
      << s.status().error << "; controller: " << alarms_and_errors(ctl_.log());
  const service::Status st = s.status();
  ASSERT_TRUE(st.link && st.link->done);
  EXPECT_TRUE(st.link->report.completed) << st.link->report.failure;
  // The controller's flow control (DC3 at 192 characters, DC1 at 96) held the line, each time
  // for less than the hold test's xoff_timeout_s, on the controller's clock.
  EXPECT_GT(st.link->report.xoff_count, 0);
  EXPECT_EQ(st.link->report.xoff_timeouts, 0)
      << "longest hold " << st.link->report.xoff_longest_s << " s of the controller's time";
  const std::string program = expected_program(emitted, Vec3::Zero());
  const std::string sha = comms::sha256_hex(program);
  EXPECT_EQ(st.link->report.program_sha256, sha);
  const comms::SimLog& log = ctl_.log();
  EXPECT_EQ(log.program_sha256, sha);
  EXPECT_TRUE(log.alarms.empty());
  EXPECT_TRUE(log.program_end_executed);
  ASSERT_FALSE(log.moves.empty());
  EXPECT_NEAR(log.moves.back().p[0], 100.0, 5e-4);  // the cubic's end, to the encoder's µm
  EXPECT_NEAR(log.moves.back().p[1], 0.0, 5e-4);
}

TEST_F(LiveLink, LinkHoldHoldsTheMotionAndResumes) {
  comms::SimFaults f;
  f.hold_after_blocks = 4;
  f.hold_s = 5.0;
  start_controller(f);
  service::Service s(options());
  follow(s);
  auto events = s.subscribe(4096);
  std::vector<motion::Setpoint> emitted;
  s.submit(job(emitted));
  s.start();
  // Up to the controller's fourth block: from there it holds the line with DC3 for 5 s of its
  // time.
  for (int k = 0; k < 100000 && ctl_.sim().progress().blocks_received < 4; ++k) {
    paced_poll(s);
    step(0.005);
  }
  ASSERT_GE(ctl_.sim().progress().blocks_received, 4);
  ASSERT_EQ(s.state(), service::State::Running)
      << s.status().error << "; controller: " << alarms_and_errors(ctl_.log());
  // The sender times the hold on the controller's clock: that moves on, the service unpolled,
  // past the sender's xoff_timeout_s, and then stands still with DC3 still held while the
  // sender says so; the next poll() applies the link's hold before it drains anything.
  const double hold_from_s = ctl_.clock()->now_s();
  while (ctl_.clock()->now_s() - hold_from_s < kXoffTimeoutS + 0.2) step(0.005);
  const auto until = std::chrono::steady_clock::now() + 60s;
  while (!s.status().link->link_holds) {
    ASSERT_LT(std::chrono::steady_clock::now(), until) << "the link never held the motion";
    std::this_thread::sleep_for(1ms);
  }
  // The live counters show the controller's hold while the transfer runs: its DC3 counted,
  // the line held now, the program not yet all written.
  const service::LinkStatus held = *s.status().link;
  EXPECT_FALSE(held.done);
  EXPECT_GE(held.counts.xoff_count, 1);
  EXPECT_TRUE(held.counts.xoff_held);
  EXPECT_GT(held.counts.bytes_written, 0);
  s.poll();
  EXPECT_EQ(s.state(), service::State::Holding);
  EXPECT_EQ(s.status().holder, service::HoldHolder::Link);
  // An operator's resume does not release the link's hold.
  EXPECT_THROW(s.resume(service::HoldHolder::Operator), InputError);
  const std::size_t at_hold = emitted.size();
  for (int k = 0; k < 200000 && (s.busy() || !ctl_.done()); ++k) {
    if (s.state() == service::State::Holding) {
      s.poll();  // the motion comes to rest while the link holds
    } else {
      paced_poll(s);
    }
    step(0.005);
  }
  ctl_.stop();
  ASSERT_EQ(s.state(), service::State::Done)
      << s.status().error << "; controller: " << alarms_and_errors(ctl_.log());
  const service::Status st = s.status();
  ASSERT_TRUE(st.link && st.link->done);
  EXPECT_TRUE(st.link->report.completed) << st.link->report.failure;
  EXPECT_GE(st.link->report.xoff_timeouts, 1);
  // The motion came to rest during the hold and went on to the end, within the limits.
  bool rested = false;
  for (std::size_t k = at_hold; k < emitted.size(); ++k) rested |= emitted[k].v_mm_per_s == 0.0;
  EXPECT_TRUE(rested);
  const motion::JobConfig c;
  for (const auto& sp : emitted) {
    ASSERT_LE(std::abs(sp.a_mm_per_s2), c.limits.max_accel_mm_per_s2 * (1 + 1e-9));
    ASSERT_LE(std::abs(sp.j_mm_per_s3), c.limits.max_jerk_mm_per_s3 * (1 + 1e-9));
  }
  EXPECT_NEAR(emitted.back().p.x(), 100.0, 1e-9);
  const std::string sha = comms::sha256_hex(expected_program(emitted, Vec3::Zero()));
  EXPECT_EQ(st.link->report.program_sha256, sha);
  EXPECT_EQ(ctl_.log().program_sha256, sha);
  EXPECT_TRUE(ctl_.log().alarms.empty());
  // The events: held by the link, then resumed by it.
  std::vector<std::string> holds;
  service::Event e;
  while (events->pop(e)) {
    if (e.kind == service::EventKind::State &&
        (e.state == service::State::Holding || e.state == service::State::Running)) {
      holds.push_back(std::string(service::to_string(e.state)) + "/" +
                      service::to_string(e.holder));
    }
  }
  const std::vector<std::string> want = {"running/none", "holding/link", "running/none"};
  EXPECT_EQ(holds, want);
}

}  // namespace
