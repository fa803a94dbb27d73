// A chamfer job submitted to the service is the whole program `ncd replay` makes for it
// (docs/whole-program.md, docs/service.md "Jobs"), streamed live with its events at their place.
// The job goes through the service's own request mapping (api::submitted_job, what `ncd serve`
// does with a submit) into the service library, which streams it live to the simulated
// controller in process: the controller in simulated time (tests/common/paced_controller.hpp),
// the cycle on the simulated clock with a 64-setpoint ring drained only once the sender has
// taken every block queued so far. For the iso dialect (drip, with its tool change) and grbl
// (ack, no M6) the controller must execute, with no alarm and no error reply: the spindle on
// (and its dwell) before the first feed move, the approach from the clearance plane (up to it
// before any move across, then down), spindle stop after the last feed move and the program
// end. The blocks it executed must be those `ncd replay --blocks` writes for the same chamfer
// and machine file, block for block (the header comments apart, which name the command).
//
// Before the service walked whole programs it streamed the bare loop: no M3, so the controller's
// interlock raised spindle_stopped at the first G1, and no M2.
#include <gtest/gtest.h>

#include <algorithm>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "api/intake.hpp"
#include "cam/chamfer_ngc.hpp"
#include "service/machine_config.hpp"
#include "service/service.hpp"
#include "sim/sim_controller.hpp"
#include "tests/app/cli_fixture.hpp"
#include "tests/common/paced_controller.hpp"

namespace {

using namespace ncd;
using nlohmann::json;

// A small inner chamfer (an 11 mm loop) so that the run is short in the controller's time.
const char* kChamferFlags =
    "--pipe-radius 10 --drill-radius 2 --ball-radius 0.5 --width 0.2 --feed 600 --edge inner "
    "--side upper";

toolpath::ChamferSpec whole_job_chamfer_spec() {
  toolpath::ChamferSpec s;
  s.pipe_radius_mm = 10.0;
  s.drill_radius_mm = 2.0;
  s.ball_radius_mm = 0.5;
  s.width_mm = 0.2;
  return s;
}

json whole_job_chamfer_request(const std::string& port) {
  return {{"cmd", "submit"},
          {"job",
           {{"pipe-radius", 10},
            {"drill-radius", 2},
            {"ball-radius", 0.5},
            {"width", 0.2},
            {"feed", 600},
            {"edge", "inner"},
            {"side", "upper"}}},
          {"port", port}};
}

std::string whole_job_machine_text(bool grbl) {
  std::string link =
      grbl ? "baud = 115200\nframe = \"8N1\"\nflow = \"none\"\nprotocol = \"ack\"\neob = \"lf\"\n"
             "percent = false\ndialect = \"grbl\"\nrx_buffer_bytes = 128\n"
           : "baud = 115200\nframe = \"8N1\"\nflow = \"xonxoff\"\nprotocol = \"drip\"\n"
             "eob = \"lf\"\npercent = true\ndialect = \"iso\"\nrx_buffer_bytes = 256\n";
  return "period_s = 0.004\nmax_feed_mm_per_min = 6000.0\nmax_accel_mm_per_s2 = 1000.0\n"
         "max_jerk_mm_per_s3 = 20000.0\nchord_tolerance_mm = 0.001\n\n"
         "[cutting]\nball_radius_mm = 0.5\npick_feed_mm = 0.0\nteeth = 2\n"
         "spindle_rpm = 6000.0\nroughness_target_um = 1.0\n\n[link]\n" +
         link +
         "\n[encoder]\nchord_tolerance_mm = 0.002\nmax_block_s = 0.5\n\n"
         "[tool]\nprogrammed_point = \"tip\"\nnumber = 2\nspindle_dwell_s = 0.5\n";
}

// The lines of a program that are blocks: no `%`, no comment line.
std::vector<std::string> blocks(const std::vector<std::string>& lines) {
  std::vector<std::string> out;
  for (const std::string& l : lines) {
    if (!l.empty() && l != "%" && l.front() != '(') out.push_back(l);
  }
  return out;
}

std::vector<std::string> whole_job_lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

class ServedWholeJob : public ncd::test::Cli, public ::testing::WithParamInterface<bool> {
 protected:
  void TearDown() override {
    ctl_.stop();
    Cli::TearDown();
  }
  ncd::test::PacedController ctl_;
};

TEST_P(ServedWholeJob, ChamferJobRunsAsTheWholeProgramReplayWrites) {
  const bool grbl = GetParam();
  const std::string machine_file = write("machine.toml", whole_job_machine_text(grbl));
  const std::string port = (dir_ / "cnc").string();

  // What `ncd replay --blocks` writes for the same chamfer and machine.
  const std::string chamfer_json = (dir_ / "c.json").string();
  const std::string replay_blocks = (dir_ / "replay.ngc").string();
  test::CmdResult r = ncd(std::string("chamfer ") + kChamferFlags + " --machine " + machine_file +
                          " --format json -q -o " + chamfer_json);
  ASSERT_EQ(r.status, 0) << r.err;
  r = ncd("replay " + chamfer_json + " --machine " + machine_file + " -q --blocks " +
          replay_blocks);
  ASSERT_EQ(r.status, 0) << r.err;
  const std::vector<std::string> want = blocks(whole_job_lines_of(test::slurp(replay_blocks)));

  api::ServiceConfig config;
  config.machine = service::load_machine_config(machine_file);
  config.clock = motion::ClockKind::Simulated;
  config.realtime = false;
  comms::SimControllerConfig c;
  c.line = config.machine.link.line;
  c.line.device = port;
  c.dialect = config.machine.link.dialect;
  c.exit_at_end = true;
  c.tool_change_s = 0.2;
  if (grbl) {  // an Arduino: reset when the port opens, its banner after a short boot
    c.reset_on_open = true;
    c.boot_s = 0.2;
  } else {  // drip: room for the sender's thread to be late (tests/service/live_link_test)
    c.buffer_bytes = 4096;
    c.xoff_at = 192;
    c.xon_at = 96;
  }
  ctl_.start(c);

  api::SubmittedJob job = api::submitted_job(whole_job_chamfer_request(port), config);
  ASSERT_TRUE(job.spec.program) << "the service walks the whole program";
  ASSERT_TRUE(job.spec.link);
  // The controller's holds timed on its own clock, whatever the load on the test's thread.
  job.spec.link->sender.hold_clock = ctl_.clock();
  service::ServiceOptions o;
  o.clock = motion::ClockKind::Simulated;
  o.realtime = false;
  o.ring_capacity = 64;
  service::Service s(o);
  ctl_.while_sender_reads([&s] {  // until the job's link is done
    const service::Status st = s.status();
    return !st.link || !st.link->done;
  });
  s.submit(std::move(job.spec));
  s.start();
  // The link's live counters in the socket's status (api::to_json), read during the transfer:
  // each counter only grows, the controller's buffer stays within its limit.
  const char* kGrowing[] = {"bytes_written", "blocks_taken",    "blocks_written",
                            "blocks_acked",  "blocks_executed", "xoff_count",
                            "underruns",     "reconnects",      "link_losses"};
  json prev, mid;
  int polled_live = 0;
  for (int k = 0; k < 100000 && (s.busy() || !ctl_.done()); ++k) {
    const service::Status st = s.status();
    if (st.link) {
      const json now = api::to_json(st)["stream"];
      for (const char* key : kGrowing) {
        if (!prev.is_null() && now[key].is_number() && prev[key].is_number()) {
          ASSERT_GE(now[key].get<std::int64_t>(), prev[key].get<std::int64_t>())
              << key << " went down: " << prev.dump() << " then " << now.dump();
        }
      }
      ASSERT_EQ(now["blocks_acked"].is_null(), !grbl) << now.dump();
      ASSERT_LE(now["controller_buffer_bytes"].get<int>(),
                now["controller_buffer_limit_bytes"].get<int>())
          << now.dump();
      if (!st.link->done) {
        ++polled_live;
        if (mid.is_null() && now["blocks_written"].get<int>() >= 20) mid = api::to_json(st);
      }
      prev = now;
    }
    if (!st.link || st.link->blocks_waiting == 0) s.poll();
    ctl_.step(0.005);
  }
  ctl_.stop();
  const comms::SimLog& log = ctl_.log();
  const json log_json = comms::to_json(log);
  ASSERT_EQ(s.state(), service::State::Done)
      << s.status().error << "; alarms " << log_json["alarms"].dump() << ", errors "
      << log_json["errors"].dump();
  const service::Status st = s.status();
  ASSERT_TRUE(st.link && st.link->done);
  EXPECT_TRUE(st.link->report.completed) << st.link->report.failure;
  // At the end the counters are the report's and the controller's own count.
  ASSERT_FALSE(mid.is_null()) << "no status read while 20 blocks had gone and more were to go";
  EXPECT_GT(polled_live, 100);
  std::cout << "[ measured ] status mid-transfer: " << mid["stream"].dump() << "\n";
  const comms::SenderReport& report = st.link->report;
  const comms::SenderCounts& end = st.link->counts;
  EXPECT_EQ(end.bytes_written, report.bytes_written);
  EXPECT_EQ(end.blocks_taken, report.blocks);
  EXPECT_EQ(end.blocks_written, report.blocks_sent);
  EXPECT_EQ(end.xoff_count, report.xoff_count);
  EXPECT_EQ(end.reconnects, report.reconnects);
  EXPECT_FALSE(end.xoff_held);
  EXPECT_EQ(end.blocks_written, log.blocks_received);
  EXPECT_EQ(end.xoff_count, log.xoff_sent);
  EXPECT_EQ(end.bytes_written, static_cast<std::int64_t>(log.bytes_received))
      << log_json.dump().substr(0, 600);
  EXPECT_EQ(api::to_json(st)["stream"]["bytes_written"], end.bytes_written);
  if (grbl) {
    EXPECT_EQ(end.blocks_acked, report.blocks_queued);
    EXPECT_EQ(end.blocks_acked, log.blocks_received);
    EXPECT_EQ(end.blocks_executed, report.blocks_executed);
  }
  EXPECT_TRUE(log.alarms.empty()) << log_json["alarms"].dump();
  EXPECT_TRUE(log.errors.empty()) << log_json["errors"].dump();
  EXPECT_TRUE(log.program_end_executed);

  // Block for block what replay writes.
  std::vector<std::string> ran;
  for (const comms::SimExecuted& e : log.executed) ran.push_back(e.text);
  EXPECT_EQ(blocks(ran), want);

  // The order of what the controller executed: the seq (blocks accepted) of each event and of
  // each move.
  const auto event_seq = [&](const std::string& kind) {
    for (const comms::SimEvent& e : log.events) {
      if (e.kind == kind) return e.seq;
    }
    return -1L;
  };
  const auto move_seq = [](const comms::SimMove& m) { return m.seq; };
  const auto first_feed = std::find_if(log.moves.begin(), log.moves.end(),
                                       [](const comms::SimMove& m) { return m.g == 1; });
  ASSERT_NE(first_feed, log.moves.end()) << "no feed move executed";
  const auto last_feed = std::find_if(log.moves.rbegin(), log.moves.rend(),
                                      [](const comms::SimMove& m) { return m.g == 1; });
  const long spindle_on = event_seq("spindle_cw"), dwell = event_seq("dwell");
  ASSERT_GT(spindle_on, 0) << log_json["events"].dump();
  EXPECT_LT(spindle_on, move_seq(*first_feed));
  ASSERT_GT(dwell, 0) << "the machine file's spindle_dwell_s";
  EXPECT_LT(spindle_on, dwell);
  EXPECT_LT(dwell, move_seq(*first_feed));
  EXPECT_GT(event_seq("spindle_stop"), move_seq(*last_feed));
  EXPECT_GE(event_seq("program_end"), event_seq("spindle_stop"));
  EXPECT_EQ(log.events.back().kind, "program_end");
  if (grbl) {
    EXPECT_EQ(event_seq("tool_change"), -1L) << "grbl has no M6: the header asks for the tool";
  } else {
    EXPECT_GT(event_seq("tool_change"), 0L);
    EXPECT_LT(event_seq("tool_change"), spindle_on);
  }

  // The approach: from where the controller stands (the origin) straight up to the clearance
  // plane, across at it, then down; every move before the first feed a rapid.
  const double clear_mm = toolpath::default_safe_z_mm(whole_job_chamfer_spec());
  const auto before = static_cast<std::size_t>(first_feed - log.moves.begin());
  ASSERT_GE(before, 2u);
  std::array<double, 3> at{0.0, 0.0, 0.0};
  for (std::size_t i = 0; i < before; ++i) {
    const comms::SimMove& m = log.moves[i];
    SCOPED_TRACE("move " + std::to_string(i + 1) + " before the first feed");
    EXPECT_EQ(m.g, 0);
    const bool vertical = std::abs(m.p[0] - at[0]) < 1e-9 && std::abs(m.p[1] - at[1]) < 1e-9;
    if (i == 0) {
      EXPECT_TRUE(vertical);
      EXPECT_NEAR(m.p[2], clear_mm, 1e-3);
    } else if (!vertical) {
      EXPECT_NEAR(at[2], clear_mm, 1e-3) << "across only at the clearance plane";
      EXPECT_NEAR(m.p[2], clear_mm, 1e-3);
    } else {
      EXPECT_LE(m.p[2], at[2]);  // down
    }
    at = m.p;
  }
  // The first feed goes on down the drill axis (an inner edge), then out to the edge.
  EXPECT_NEAR(first_feed->p[0], at[0], 1e-9);
  EXPECT_NEAR(first_feed->p[1], at[1], 1e-9);
  EXPECT_LT(first_feed->p[2], at[2]);
  EXPECT_NEAR(std::hypot(at[0], at[1]), 0.0, 1e-9) << "over the drill axis";
  // The last move: back up to the clearance plane.
  EXPECT_EQ(log.moves.back().g, 0);
  EXPECT_NEAR(log.moves.back().p[2], clear_mm, 1e-3);
  std::printf(
      "[ measured ] %s: %zu blocks executed as replay wrote them; events %s; clearance Z %.3f "
      "mm; 0 alarms\n",
      grbl ? "grbl (ack)" : "iso (drip)", ran.size(), log_json["events"].dump().c_str(), clear_mm);
}

INSTANTIATE_TEST_SUITE_P(Dialects, ServedWholeJob, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool>& p) {
                           return std::string(p.param ? "GrblAck" : "IsoDrip");
                         });

}  // namespace
