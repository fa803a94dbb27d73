// The ways a streamed job ends other than a stop (docs/service.md, "Ending early"), through the
// service's own request mapping (api::submitted_job) and the service library, live to the
// simulated controller on a real pseudo-terminal in simulated time (tests/common/
// paced_controller.hpp, as serve_whole_job_test.cpp does):
//   - a job error mid-cut (the setpoints file fails): the same safe ending as a stop;
//   - a block the controller's dialect refuses mid-program (a link-side error; the link still
//     carries): the refused block never reaches the controller, the ending follows the last
//     block it has;
//   - the link lost mid-cut: the job ends in error, and its status, error and log say the ending
//     could NOT be sent and what to do at the machine; a stop while an ack link is down says so
//     in its reply (link_down_note);
//   - a job restarted from a line, which streams no program events after the line, ends with
//     spindle stop, coolant off and program end after its last block;
//   - an operator hold longer than the link's hold timeout (xoff_timeout_s): no error, no link
//     hold, and the job completes after the resume.
// For the first two, in the iso (drip) and grbl (ack) dialects, the controller's log must end
// with spindle stop, coolant off and program end, its last move at the clearance plane.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "api/intake.hpp"
#include "cam/chamfer.hpp"
#include "cam/chamfer_ngc.hpp"
#include "service/machine_config.hpp"
#include "service/service.hpp"
#include "sim/sim_controller.hpp"
#include "tests/app/cli_fixture.hpp"
#include "tests/common/paced_controller.hpp"

namespace {

using namespace ncd;
using nlohmann::json;

// Experiment 3's chamfer (an inner edge) at 300 mm/min.
json chamfer_request(const std::string& port) {
  return {{"cmd", "submit"},
          {"job",
           {{"pipe-radius", 18},
            {"drill-radius", 13},
            {"ball-radius", 3},
            {"width", 0.7},
            {"rod-radius", 1.8},
            {"non-knife-angle", 93},
            {"feed", 300},
            {"edge", "inner"},
            {"side", "upper"}}},
          {"port", port}};
}

double chamfer_clearance_mm() {
  toolpath::ChamferSpec s;
  s.pipe_radius_mm = 18.0;
  s.drill_radius_mm = 13.0;
  s.ball_radius_mm = 3.0;
  s.width_mm = 0.7;
  return toolpath::default_safe_z_mm(s);
}

std::string faults_machine_text(bool grbl, double xoff_timeout_s = 5.0) {
  std::string link =
      grbl ? "baud = 115200\nframe = \"8N1\"\nflow = \"none\"\nprotocol = \"ack\"\neob = \"lf\"\n"
             "percent = false\ndialect = \"grbl\"\nrx_buffer_bytes = 128\n"
           : "baud = 115200\nframe = \"8N1\"\nflow = \"xonxoff\"\nprotocol = \"drip\"\n"
             "eob = \"lf\"\npercent = true\ndialect = \"iso\"\nrx_buffer_bytes = 256\n";
  link += "xoff_timeout_s = " + std::to_string(xoff_timeout_s) + "\nreconnect_max_s = 1.0\n";
  return "period_s = 0.004\nmax_feed_mm_per_min = 6000.0\nmax_accel_mm_per_s2 = 1000.0\n"
         "max_jerk_mm_per_s3 = 20000.0\nchord_tolerance_mm = 0.001\n\n"
         "[cutting]\nball_radius_mm = 3.0\npick_feed_mm = 0.0\nteeth = 2\n"
         "spindle_rpm = 3000.0\nroughness_target_um = 0.05\n\n[link]\n" +
         link +
         "\n[encoder]\nchord_tolerance_mm = 0.002\nmax_block_s = 0.5\n\n"
         "[tool]\nprogrammed_point = \"tip\"\nnumber = 1\nspindle_dwell_s = 0.5\n";
}

// The end of the controller's log, for the report: its last blocks, moves and events.
std::string faults_log_tail(const comms::SimLog& log) {
  std::string out = "executed:";
  const std::size_t e = log.executed.size();
  for (std::size_t i = e > 8 ? e - 8 : 0; i < e; ++i) out += " " + log.executed[i].text;
  out += "; moves:";
  const std::size_t m = log.moves.size();
  for (std::size_t i = m > 3 ? m - 3 : 0; i < m; ++i) {
    char b[96];
    std::snprintf(b, sizeof b, " G%d (%.3f, %.3f, %.3f) @%.3f s", log.moves[i].g, log.moves[i].p[0],
                  log.moves[i].p[1], log.moves[i].p[2], log.moves[i].t_s);
    out += b;
  }
  out += "; events:";
  const std::size_t v = log.events.size();
  for (std::size_t i = v > 4 ? v - 4 : 0; i < v; ++i) {
    char b[64];
    std::snprintf(b, sizeof b, " %s @%.3f s", log.events[i].kind.c_str(), log.events[i].t_s);
    out += b;
  }
  return out;
}

// The setpoints file fails (a full disk) past half the loop (Y below -3 mm, 10.5 mm from the
// axis): even a controller that lags the motion by its whole queue (grbl's 15 blocks) is then
// on the loop.
class FailingSink : public service::SetpointSink {
 public:
  void write(const motion::Setpoint& sp) override {
    if (sp.p.y() < -3.0 && std::hypot(sp.p.x(), sp.p.y()) > 10.0) {
      throw std::runtime_error("setpoints file: no space left on device");
    }
  }
  void commit() override {}
};

class ServedEnding : public test::Cli, public ::testing::WithParamInterface<bool> {
 protected:
  void TearDown() override {
    ctl_.stop();
    Cli::TearDown();
  }

  api::ServiceConfig config(bool grbl, double xoff_timeout_s = 5.0) {
    api::ServiceConfig c;
    c.machine = service::load_machine_config(
        write("machine.toml", faults_machine_text(grbl, xoff_timeout_s)));
    c.clock = motion::ClockKind::Simulated;
    c.realtime = false;
    return c;
  }

  void start_controller(const api::ServiceConfig& config, const comms::SimFaults& faults = {}) {
    comms::SimControllerConfig c;
    c.line = config.machine.link.line;
    c.line.device = port();
    c.dialect = config.machine.link.dialect;
    c.tool_change_s = 0.2;
    c.faults = faults;
    c.exit_at_end = true;
    if (c.line.protocol == comms::Protocol::Ack) {
      c.reset_on_open = true;
      c.boot_s = 0.2;
    } else {  // room for the sender's thread to be late (tests/service/live_link_test)
      c.buffer_bytes = 4096;
      c.xoff_at = 192;
      c.xon_at = 96;
    }
    ctl_.start(c);
  }

  std::string port() const { return (dir_ / "cnc").string(); }

  std::unique_ptr<service::Service> service() {
    service::ServiceOptions o;
    o.clock = motion::ClockKind::Simulated;
    o.realtime = false;
    o.ring_capacity = 64;
    o.log = [this](const std::string& line) {
      std::lock_guard lock(log_mutex_);
      log_ += line + "\n";
    };
    auto s = std::make_unique<service::Service>(o);
    service::Service* raw = s.get();
    ctl_.while_sender_reads([raw] {
      const service::Status st = raw->status();
      return !st.link || !st.link->done;
    });
    return s;
  }

  // One turn: the service drains the cycle only once the sender has taken every block queued
  // so far (the motion runs at most a ring and a block ahead of the controller), except when
  // the job is ending, or the link holds (a hold to apply) or is done (the sender then takes
  // nothing more); the controller's time moves on 5 ms.
  void turn(service::Service& s) {
    const service::Status st = s.status();
    if (!st.link || st.link->blocks_waiting == 0 || st.link->done || st.link->link_holds ||
        st.holder != service::HoldHolder::None ||
        st.ending.state != service::EndingStatus::State::None) {
      s.poll();
    }
    ctl_.step(0.005);
  }

  // Turns until pred() or the job and the controller are both over (100 000 turns at most).
  template <class Pred>
  void run_until(service::Service& s, Pred pred) {
    for (int k = 0; k < 100000 && !pred() && (s.busy() || !ctl_.done()); ++k) turn(s);
  }

  std::string service_log() {
    std::lock_guard lock(log_mutex_);
    return log_;
  }

  // The controller's log ends with the safe ending: spindle stop, coolant off, program end, the
  // last move up to clear_mm at (x, y).
  static void expect_safe_end(const comms::SimLog& log, double clear_mm) {
    const json j = comms::to_json(log);
    ASSERT_GE(log.events.size(), 3u) << j["events"].dump();
    const std::size_t n = log.events.size();
    EXPECT_EQ(log.events[n - 3].kind, "spindle_stop") << j["events"].dump();
    EXPECT_EQ(log.events[n - 2].kind, "coolant_off") << j["events"].dump();
    EXPECT_EQ(log.events[n - 1].kind, "program_end") << j["events"].dump();
    ASSERT_FALSE(log.moves.empty());
    EXPECT_EQ(log.moves.back().g, 0);
    EXPECT_NEAR(log.moves.back().p[2], clear_mm, 1e-3);
    EXPECT_TRUE(log.alarms.empty()) << j["alarms"].dump();
  }

  // Where the controller's motion stopped before the ending: grbl, where its hold left the tool
  // (the reset keeps it); drip, the end of the last move before the ending's `ending_moves`.
  static std::array<double, 3> stop_point(const comms::SimLog& log, bool grbl,
                                          std::size_t ending_moves) {
    if (grbl) return log.resets.back().position;
    return log.moves[log.moves.size() - ending_moves - 1].p;
  }

  test::PacedController ctl_;
  std::mutex log_mutex_;
  std::string log_;
};

TEST_P(ServedEnding, AJobErrorMidCutEndsWithTheInBoreRetract) {
  const bool grbl = GetParam();
  const api::ServiceConfig config = this->config(grbl);
  start_controller(config);
  api::SubmittedJob job = api::submitted_job(chamfer_request(port()), config);
  ASSERT_TRUE(job.spec.retract && job.spec.retract->axis_xy);
  job.spec.link->sender.hold_clock = ctl_.clock();
  job.spec.sink = std::make_unique<FailingSink>();
  auto s = service();
  s->submit(std::move(job.spec));
  s->start();
  run_until(*s, [] { return false; });
  ctl_.stop();
  const service::Status st = s->status();
  ASSERT_EQ(st.state, service::State::Error) << service_log();
  EXPECT_NE(st.error.find("no space left on device"), std::string::npos) << st.error;
  EXPECT_EQ(st.ending.state, service::EndingStatus::State::Sent) << st.ending.note;
  const comms::SimLog& log = ctl_.log();
  const double clear_mm = chamfer_clearance_mm();
  expect_safe_end(log, clear_mm);
  // In the bore, back to the drill axis at the stop's Z, then up over the axis.
  const auto stop = stop_point(log, grbl, 2);
  EXPECT_GT(std::hypot(stop[0], stop[1]), 10.0) << "stopped in the cut";
  const comms::SimMove& to_axis = log.moves[log.moves.size() - 2];
  EXPECT_EQ(to_axis.g, 1);
  EXPECT_NEAR(std::hypot(to_axis.p[0], to_axis.p[1]), 0.0, 1e-9);
  EXPECT_NEAR(to_axis.p[2], stop[2], 1e-3);
  EXPECT_NEAR(std::hypot(log.moves.back().p[0], log.moves.back().p[1]), 0.0, 1e-9);
  if (grbl) {
    EXPECT_FALSE(log.resets.back().in_motion) << "reset at Hold:0: no ALARM:3";
  }
  std::printf(
      "[ measured ] %s job error: stopped at (%.3f, %.3f, %.3f); ending %s; %s; log tail %s\n",
      grbl ? "grbl" : "iso", stop[0], stop[1], stop[2], json(st.ending.blocks).dump().c_str(),
      st.ending.note.c_str(), faults_log_tail(log).c_str());
}

TEST_P(ServedEnding, ABlockTheDialectRefusesMidProgramEndsTheJobSafely) {
  const bool grbl = GetParam();
  // A message with a non-ASCII letter (the iso line takes printable ASCII only), or mist
  // coolant (grbl's default build has no M7), between two cutting moves. The program's
  // highest Z is 10 mm: its clearance for the ending.
  const std::string refused = grbl ? "M7"
                                   : "(MSG, Pi\xc3\xa8"
                                     "ce retourn\xc3\xa9"
                                     "e)";
  const std::string program = write("prog.ngc",
                                    "G21 G90 G17\nS3000 M3\nG0 Z10\nG0 X0 Y0\n"
                                    "G1 Z-1 F300\nG1 X20\nG1 Y20\n" +
                                        refused + "\nG1 X0\nG1 Y0\nG0 Z10\nM5\nM2\n");
  const api::ServiceConfig config = this->config(grbl);
  start_controller(config);
  api::SubmittedJob job = api::submitted_job(
      {{"cmd", "submit"}, {"job", {{"path", program}}}, {"port", port()}}, config);
  ASSERT_TRUE(job.spec.retract);
  EXPECT_NEAR(job.spec.retract->clearance_z_mm, 10.0, 1e-12);
  EXPECT_FALSE(job.spec.retract->axis_xy);
  job.spec.link->sender.hold_clock = ctl_.clock();
  auto s = service();
  s->submit(std::move(job.spec));
  s->start();
  run_until(*s, [] { return false; });
  ctl_.stop();
  const service::Status st = s->status();
  ASSERT_EQ(st.state, service::State::Error) << service_log();
  EXPECT_NE(st.error.find("refused before it was queued"), std::string::npos) << st.error;
  EXPECT_EQ(st.ending.state, service::EndingStatus::State::Sent) << st.ending.note;
  const comms::SimLog& log = ctl_.log();
  EXPECT_TRUE(log.errors.empty()) << "the refused block never reached the controller";
  expect_safe_end(log, 10.0);
  // Straight up from where it stopped, on the program's path at Z -1.
  const auto stop = stop_point(log, grbl, 1);
  EXPECT_NEAR(stop[2], -1.0, 1e-3);
  EXPECT_NEAR(log.moves.back().p[0], stop[0], 1e-3);
  EXPECT_NEAR(log.moves.back().p[1], stop[1], 1e-3);
  std::printf(
      "[ measured ] %s refused block: stopped at (%.3f, %.3f, %.3f); ending %s; log tail %s\n",
      grbl ? "grbl" : "iso", stop[0], stop[1], stop[2], json(st.ending.blocks).dump().c_str(),
      faults_log_tail(log).c_str());
}

INSTANTIATE_TEST_SUITE_P(Dialects, ServedEnding, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool>& p) {
                           return std::string(p.param ? "GrblAck" : "IsoDrip");
                         });

TEST_F(ServedEnding, ALostDripLinkSaysTheEndingCouldNotBeSent) {
  const api::ServiceConfig config = this->config(false);
  comms::SimFaults f;
  f.drop_link_after_blocks = 25;  // mid-job, the spindle turning
  f.down_s = 5.0;
  start_controller(config, f);
  api::SubmittedJob job = api::submitted_job(chamfer_request(port()), config);
  job.spec.link->sender.hold_clock = ctl_.clock();
  auto s = service();
  s->submit(std::move(job.spec));
  s->start();
  run_until(*s, [&] { return !s->busy(); });
  const service::Status st = s->status();
  ctl_.stop();
  ASSERT_EQ(st.state, service::State::Error) << service_log();
  EXPECT_EQ(st.ending.state, service::EndingStatus::State::NotSent);
  for (const std::string& text : {st.error, st.ending.note, service_log()}) {
    EXPECT_NE(text.find("could NOT be sent"), std::string::npos) << text;
    EXPECT_NE(text.find("at the machine: stop the motion"), std::string::npos) << text;
    EXPECT_NE(text.find("back to the drill axis"), std::string::npos) << text;
  }
  const json status = api::to_json(st);
  EXPECT_EQ(status["ending"]["state"], "not_sent") << status.dump();
  EXPECT_NE(status["job_error"].get<std::string>().find("could NOT be sent"), std::string::npos);
  // The controller got no ending: its spindle still turns (what the operator is told to stop).
  const comms::SimLog& log = ctl_.log();
  EXPECT_EQ(log.link_drops, 1);
  EXPECT_FALSE(log.program_end_executed);
  ASSERT_FALSE(log.events.empty());
  EXPECT_EQ(log.events.back().kind, "dwell");
  std::printf("[ measured ] lost drip link: %s; log tail %s\n", st.error.c_str(),
              faults_log_tail(log).c_str());
}

TEST_F(ServedEnding, AStopWhileTheAckLinkIsDownSaysSoAndTheEndingIsNotSent) {
  api::ServiceConfig config = this->config(true);
  // The sender tries to reopen for 10 s of the controller's time (the hold clock), long beside
  // what one step of a loaded test thread catches up: the test sees the link down.
  config.machine.link.reconnect_max_s = 10.0;
  comms::SimFaults f;
  f.drop_link_after_blocks = 25;
  f.down_s = 30.0;  // longer than reconnect_max_s: the sender gives up
  start_controller(config, f);
  api::SubmittedJob job = api::submitted_job(chamfer_request(port()), config);
  job.spec.link->sender.hold_clock = ctl_.clock();
  auto s = service();
  s->submit(std::move(job.spec));
  s->start();
  run_until(*s, [&] {
    const service::Status st = s->status();
    return st.link && st.link->counts.link_losses > 0 && st.holder == service::HoldHolder::Link;
  });
  ASSERT_EQ(s->state(), service::State::Holding) << service_log();
  // Down while the sender still tries to reconnect, gone once it has given up: each state must
  // say what it means for the ending.
  const std::string down = s->link_down_note();
  if (down.find("is gone") != std::string::npos) {
    EXPECT_NE(down.find("the safe ending cannot be sent"), std::string::npos) << down;
  } else {
    EXPECT_NE(down.find("is down"), std::string::npos) << down;
    EXPECT_NE(down.find("only be sent if it comes back"), std::string::npos) << down;
  }
  s->stop("stop requested by a client");
  run_until(*s, [&] { return !s->busy(); });
  const service::Status st = s->status();
  ctl_.stop();
  ASSERT_EQ(st.state, service::State::Error) << service_log();
  EXPECT_EQ(st.ending.state, service::EndingStatus::State::NotSent);
  EXPECT_NE(st.error.find("could NOT be sent"), std::string::npos) << st.error;
  EXPECT_FALSE(ctl_.log().program_end_executed);
  std::printf("[ measured ] stop while the ack link is down: reply warning '%s'; error '%s'\n",
              down.c_str(), st.error.c_str());
}

// A job restarted from a line streams the path from there, without the program's events after
// the line (docs/service.md, "Restart from a line"): its end gets the ending after its last
// block, so the spindle stops and the program ends. Before, the stream ended on the last move.
TEST_F(ServedEnding, ARestartedJobEndsWithSpindleStopAndProgramEnd) {
  const std::string program =
      write("prog.ngc",
            "G21 G90 G17\nS3000 M3\nG0 Z10\nG0 X0 Y0\nG1 Z-1 F300\nG1 X20\nG1 Y20\nG1 X0\n"
            "G1 Y0\nG0 Z10\nM5\nM2\n");
  const api::ServiceConfig config = this->config(false);
  start_controller(config);
  api::SubmittedJob job = api::submitted_job(
      {{"cmd", "submit"}, {"job", {{"path", program}}}, {"port", port()}, {"restart_from", 7}},
      config);
  ASSERT_TRUE(job.spec.restart);
  job.spec.link->sender.hold_clock = ctl_.clock();
  auto s = service();
  s->submit(std::move(job.spec));
  s->start();
  run_until(*s, [] { return false; });
  ctl_.stop();
  const service::Status st = s->status();
  ASSERT_EQ(st.state, service::State::Done) << st.error << "\n" << service_log();
  EXPECT_EQ(st.ending.state, service::EndingStatus::State::Sent) << st.ending.note;
  const comms::SimLog& log = ctl_.log();
  const json j = comms::to_json(log);
  ASSERT_GE(log.events.size(), 3u);
  const std::size_t n = log.events.size();
  EXPECT_EQ(log.events[n - 3].kind, "spindle_stop") << j["events"].dump();
  EXPECT_EQ(log.events[n - 2].kind, "coolant_off") << j["events"].dump();
  EXPECT_EQ(log.events[n - 1].kind, "program_end") << j["events"].dump();
  EXPECT_TRUE(log.alarms.empty()) << j["alarms"].dump();
  // The program's own last move rose to Z 10, its clearance (a restart streams the path's
  // blocks, its rapids as feed blocks): nothing more moves.
  EXPECT_NEAR(log.moves.back().p[2], 10.0, 1e-3);
  EXPECT_NEAR(log.moves.back().p[0], 0.0, 1e-3);
  EXPECT_NEAR(log.moves.back().p[1], 0.0, 1e-3);
  EXPECT_EQ(st.ending.blocks.size(), 3u) << json(st.ending.blocks).dump();
  std::printf("[ measured ] restarted job: ending %s; log tail %s\n",
              json(st.ending.blocks).dump().c_str(), faults_log_tail(log).c_str());
}

// An operator hold longer than the link's hold timeout (xoff_timeout_s, 8 s here: above the
// controller's own XOFF spells, up to 5 s with its 192 characters of blocks at F300) is the
// operator's: the cycle stops on the path, the controller runs out of blocks and waits, the
// sender has nothing to write. It raises no link hold, no XOFF report, no error, counts no
// underrun at the sender (the tool is at rest), and the job completes after the resume.
TEST_P(ServedEnding, AnOperatorHoldLongerThanTheLinkTimeoutIsNoFault) {
  const bool grbl = GetParam();
  const api::ServiceConfig config = this->config(grbl, 8.0);
  start_controller(config);
  api::SubmittedJob job = api::submitted_job(chamfer_request(port()), config);
  job.spec.link->sender.hold_clock = ctl_.clock();
  auto s = service();
  auto events = s->subscribe(1024);
  s->submit(std::move(job.spec));
  s->start();
  run_until(*s, [&] { return std::abs(s->status().position_mm.y()) > 3.0; });
  ASSERT_EQ(s->state(), service::State::Running) << service_log();
  s->hold(service::HoldHolder::Operator);
  // The blocks on their way when the hold was asked may still run dry (a loaded machine delays
  // the test's thread): the hold's own count starts once it holds, 1 s of the controller's time
  // after it was asked.
  run_until(*s, [&] { return s->state() == service::State::Holding; });
  for (int k = 0; k < 200; ++k) turn(*s);
  const service::Status before = s->status();
  for (int k = 0; k < 3000; ++k) turn(*s);  // 15 s of the controller's time
  const service::Status held = s->status();
  EXPECT_EQ(held.state, service::State::Holding);
  EXPECT_EQ(held.holder, service::HoldHolder::Operator);
  ASSERT_TRUE(held.link);
  EXPECT_FALSE(held.link->counts.xoff_held);
  EXPECT_EQ(held.link->counts.underruns, before.link->counts.underruns);
  s->resume(service::HoldHolder::Operator);
  run_until(*s, [] { return false; });
  ctl_.stop();
  const service::Status st = s->status();
  ASSERT_EQ(st.state, service::State::Done) << st.error << "\n" << service_log();
  EXPECT_EQ(st.link->report.xoff_timeouts, 0);
  EXPECT_EQ(st.ending.state, service::EndingStatus::State::None);
  service::Event e;
  while (events->pop(e)) {
    EXPECT_NE(e.kind, service::EventKind::Alarm) << e.message();
    EXPECT_EQ(std::string(e.message()).find("held the link"), std::string::npos) << e.message();
  }
  const comms::SimLog& log = ctl_.log();
  EXPECT_TRUE(log.alarms.empty());
  EXPECT_TRUE(log.program_end_executed);
  std::printf(
      "[ measured ] %s operator hold of 15 s (xoff_timeout_s 8 s): sender underruns %lld at the "
      "hold, "
      "%lld held, %lld at the end; controller underruns %ld; longest XOFF %.3f s\n",
      grbl ? "grbl" : "iso", static_cast<long long>(before.link->counts.underruns),
      static_cast<long long>(held.link->counts.underruns),
      static_cast<long long>(st.link->counts.underruns), log.underruns,
      st.link->report.xoff_longest_s);
}

}  // namespace
