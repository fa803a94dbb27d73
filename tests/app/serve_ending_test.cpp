// A streamed job that is stopped over the socket or shut down by SIGINT ends safely at the
// machine (docs/service.md, "Ending early"): `ncd serve` as a real process on the wall clock, the
// simulated controller in this process on a real pseudo-terminal and the wall clock too, and the
// chamfer of experiment 3 (an inner edge: in the bore, the only way out is back to the drill
// axis). The job is stopped once the controller has executed blocks of the cut; afterwards the
// controller's own log must end with spindle stop, coolant off and program end, its last move
// must be the rise to the clearance plane over the drill axis, and the move before it the
// horizontal move from where the tool stopped in the bore to the axis, at the Z it stopped at.
//   iso (drip): the ending follows the planned stop's blocks;
//   grbl (ack): the controller is held (`!`) at once, reset at Hold:0 (no ALARM:3), and the ending
//     starts where the hold left the tool.
// Before, the log ended with spindle_cw and no program end, the tool in the bore.
//
// The time from the request to the controller's motion stop is printed ([ measured ]): drip,
// the end of the last move on the path; grbl, the feed hold in the controller's log. It is not
// asserted (no wall-clock limits in tests).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>

#include <array>
#include <chrono>
#include <cmath>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "cam/chamfer.hpp"
#include "cam/chamfer_ngc.hpp"
#include "service/machine_config.hpp"
#include "sim/sim_controller.hpp"
#include "tests/app/serve_fixture.hpp"

namespace {

using namespace ncd;
using nlohmann::json;
using namespace std::chrono_literals;

struct Case {
  bool grbl = false;
  bool sigint = false;
};

// Experiment 3's chamfer (docs/chamfer.md) at 300 mm/min: the cut lasts about 25 s.
json chamfer_job() {
  return {{"pipe-radius", 18}, {"drill-radius", 13}, {"ball-radius", 3},
          {"width", 0.7},      {"rod-radius", 1.8},  {"non-knife-angle", 93},
          {"feed", 300},       {"edge", "inner"},    {"side", "upper"}};
}

toolpath::ChamferSpec chamfer_spec() {
  toolpath::ChamferSpec s;
  s.pipe_radius_mm = 18.0;
  s.drill_radius_mm = 13.0;
  s.ball_radius_mm = 3.0;
  s.width_mm = 0.7;
  return s;
}

std::string machine_text(bool grbl) {
  const std::string link =
      grbl ? "baud = 115200\nframe = \"8N1\"\nflow = \"none\"\nprotocol = \"ack\"\neob = \"lf\"\n"
             "percent = false\ndialect = \"grbl\"\nrx_buffer_bytes = 128\n"
           : "baud = 19200\nframe = \"7E2\"\nflow = \"xonxoff\"\nprotocol = \"drip\"\n"
             "eob = \"lf\"\npercent = true\ndialect = \"iso\"\nrx_buffer_bytes = 256\n";
  return "period_s = 0.004\nmax_feed_mm_per_min = 6000.0\nmax_accel_mm_per_s2 = 1000.0\n"
         "max_jerk_mm_per_s3 = 20000.0\nchord_tolerance_mm = 0.001\n\n"
         "[cutting]\nball_radius_mm = 3.0\npick_feed_mm = 0.0\nteeth = 2\n"
         "spindle_rpm = 3000.0\nroughness_target_um = 0.05\n\n[link]\n" +
         link +
         "\n[encoder]\nchord_tolerance_mm = 0.002\n\n"
         "[tool]\nprogrammed_point = \"tip\"\nnumber = 1\nspindle_dwell_s = 0.5\n";
}

// The end of the controller's log, for the report: its last blocks, moves and events.
std::string log_tail(const comms::SimLog& log) {
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

class ServeEnding : public test::ServeFixture, public ::testing::WithParamInterface<Case> {
 protected:
  void TearDown() override {
    stop_controller();
    ServeFixture::TearDown();
  }
  void start_controller(const service::MachineConfig& m, const std::string& port) {
    comms::SimControllerConfig c;
    c.line = m.link.line;
    c.line.device = port;
    c.dialect = m.link.dialect;
    c.tool_change_s = 0.2;
    if (m.link.line.protocol == comms::Protocol::Ack) {  // an Arduino: reset when opened
      c.reset_on_open = true;
      c.boot_s = 0.2;
    }
    sim_ = std::make_unique<comms::SimController>(c);  // the wall clock
    thread_ = std::thread([this] { sim_->run(); });
  }
  void stop_controller() {
    if (thread_.joinable()) {
      sim_->request_stop();
      thread_.join();
    }
  }
  // Waits (60 s at most) until pred() holds, polling every 10 ms.
  template <class Pred>
  static bool wait_until(Pred pred) {
    const auto end = std::chrono::steady_clock::now() + 60s;
    while (!pred()) {
      if (std::chrono::steady_clock::now() > end) return false;
      std::this_thread::sleep_for(10ms);
    }
    return true;
  }
  // The exit status of `ncd serve` once it has exited on its own (60 s at most), else -2.
  int wait_exit() {
    int status = 0;
    const bool exited = wait_until([&] { return waitpid(pid_, &status, WNOHANG) == pid_; });
    if (!exited) return -2;
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

  std::unique_ptr<comms::SimController> sim_;
  std::thread thread_;
};

TEST_P(ServeEnding, StoppedInTheBoreTheControllerRetractsByTheDrillAxisAndEnds) {
  const Case k = GetParam();
  const std::string machine_file = write("machine.toml", machine_text(k.grbl));
  const service::MachineConfig machine = service::load_machine_config(machine_file);
  const std::string port = (dir_ / "cnc").string();
  start_controller(machine, port);
  launch("wall", "machine = \"" + machine_file + "\"\n");
  test::ServeClient c(socket_);
  json r = c.request({{"cmd", "submit"}, {"job", chamfer_job()}, {"port", port}});
  ASSERT_TRUE(r["ok"].get<bool>()) << r.dump();
  r = c.request({{"cmd", "start"}});
  ASSERT_TRUE(r["ok"].get<bool>()) << r.dump();
  // In the cut: the controller's own position is on the loop at the edge, 10.5 mm from the axis
  // and past its start on the XZ plane where the approach ran (|Y| above 2 mm, about 11
  // degrees). ncd's motion runs ahead of it by the lead (a second or so; more on a loaded
  // machine), so the stop falls further along the loop. (A wait on ncd's position and 6 blocks
  // executed after it could still find the controller at the loop's start on a loaded machine:
  // it stopped at Y 0.006 mm.)
  ASSERT_TRUE(wait_until([&] {
    const std::array<double, 3> p = sim_->progress().position_mm;
    return std::hypot(p[0], p[1]) > 10.0 && std::abs(p[1]) > 2.0;
  })) << "the controller never reached the cut\n"
      << test::slurp(dir_ / "serve.err");
  const json ncd_at = c.request({{"cmd", "status"}})["position"];
  const double requested_t_s = sim_->progress().t_s;  // the controller's clock
  if (k.sigint) {
    ASSERT_EQ(kill(pid_, SIGINT), 0);
    EXPECT_EQ(wait_exit(), 0) << test::slurp(dir_ / "serve.err");
    const std::string err = test::slurp(dir_ / "serve.err");
    EXPECT_NE(err.find("ending: sent"), std::string::npos) << err;
  } else {
    r = c.request({{"cmd", "stop"}});
    ASSERT_TRUE(r["ok"].get<bool>()) << r.dump();
    EXPECT_EQ(r["ending"]["state"], "pending") << r.dump();
    EXPECT_FALSE(r.contains("warning")) << r.dump();
    const json s = wait_for(c, "stopped", 6000);
    EXPECT_EQ(s["ending"]["state"], "sent") << s.dump();
    const auto blocks = s["ending"]["blocks"].get<std::vector<std::string>>();
    ASSERT_GE(blocks.size(), 3u) << s.dump();
    const auto ends_with = [](const std::string& b, const std::string& w) {
      return b.size() >= w.size() && b.compare(b.size() - w.size(), w.size(), w) == 0;
    };
    EXPECT_TRUE(ends_with(blocks[blocks.size() - 3], "M5")) << s.dump();
    EXPECT_TRUE(ends_with(blocks[blocks.size() - 2], "M9")) << s.dump();
    EXPECT_TRUE(ends_with(blocks[blocks.size() - 1], "M2")) << s.dump();
    std::cout << "[ measured ] ending: " << s["ending"].dump() << "\n";
  }
  ASSERT_TRUE(wait_until([&] { return sim_->progress().program_end_executed; }))
      << "the controller never executed a program end";
  stop_controller();
  const comms::SimLog& log = sim_->log();
  const json log_json = comms::to_json(log);
  EXPECT_TRUE(log.alarms.empty()) << log_json["alarms"].dump();

  // The last events: spindle stop, coolant off, program end.
  ASSERT_GE(log.events.size(), 3u);
  const std::size_t n = log.events.size();
  EXPECT_EQ(log.events[n - 3].kind, "spindle_stop") << log_json["events"].dump();
  EXPECT_EQ(log.events[n - 2].kind, "coolant_off") << log_json["events"].dump();
  EXPECT_EQ(log.events[n - 1].kind, "program_end") << log_json["events"].dump();

  // Where the motion stopped: drip, the end of the last move on the path (the planned stop's);
  // grbl, where its feed hold left the tool (the reset keeps it), when the hold came.
  const double clear_mm = toolpath::default_safe_z_mm(chamfer_spec());
  ASSERT_GE(log.moves.size(), 3u);
  const comms::SimMove& rise = log.moves[log.moves.size() - 1];
  const comms::SimMove& to_axis = log.moves[log.moves.size() - 2];
  std::array<double, 3> stop{};
  double stopped_t_s = 0.0;
  if (k.grbl) {
    ASSERT_EQ(log.resets.size(), 2u) << "the reset on opening, then the ending's";
    const comms::SimReset& reset = log.resets.back();
    EXPECT_EQ(reset.cause, "soft_reset");
    EXPECT_FALSE(reset.in_motion) << "reset at Hold:0: no ALARM:3";
    stop = reset.position;
    const auto hold = std::find_if(log.events.begin(), log.events.end(),
                                   [](const comms::SimEvent& e) { return e.kind == "feed_hold"; });
    ASSERT_NE(hold, log.events.end()) << log_json["events"].dump();
    stopped_t_s = hold->t_s;
  } else {
    const comms::SimMove& last_cut = log.moves[log.moves.size() - 3];
    EXPECT_EQ(last_cut.g, 1);
    stop = last_cut.p;
    stopped_t_s = last_cut.t_s;
  }
  // It stopped in the bore, on the loop at the edge (about 10.5 mm from the axis, off the XZ
  // plane of the approach).
  EXPECT_GT(std::hypot(stop[0], stop[1]), 10.0) << "not stopped in the cut";
  EXPECT_GT(std::abs(stop[1]), 1.0) << "not stopped on the loop";
  EXPECT_LT(stop[2], clear_mm - 10.0);
  // Back to the drill axis, level, at feed; then straight up to the clearance plane.
  EXPECT_EQ(to_axis.g, 1);
  EXPECT_NEAR(to_axis.p[0], 0.0, 1e-9);
  EXPECT_NEAR(to_axis.p[1], 0.0, 1e-9);
  EXPECT_NEAR(to_axis.p[2], stop[2], 1e-3);
  EXPECT_EQ(rise.g, 0);
  EXPECT_NEAR(rise.p[0], 0.0, 1e-9);
  EXPECT_NEAR(rise.p[1], 0.0, 1e-9);
  EXPECT_NEAR(rise.p[2], clear_mm, 1e-3);
  // The spindle turned through the retract: its stop comes after the last move.
  EXPECT_GE(log.events[n - 3].t_s, rise.t_s - 1e-9);
  std::printf(
      "[ measured ] %s, %s: ncd's motion at %s at the request; the controller stopped at (%.3f, "
      "%.3f, %.3f), %.3f mm from the axis; request to motion stop at the controller %.3f s; "
      "log tail %s\n",
      k.grbl ? "grbl (ack)" : "iso (drip)", k.sigint ? "SIGINT" : "{\"cmd\":\"stop\"}",
      ncd_at.dump().c_str(), stop[0], stop[1], stop[2], std::hypot(stop[0], stop[1]),
      stopped_t_s - requested_t_s, log_tail(log).c_str());
}

INSTANTIATE_TEST_SUITE_P(Cases, ServeEnding,
                         ::testing::Values(Case{false, false}, Case{false, true}, Case{true, false},
                                           Case{true, true}),
                         [](const ::testing::TestParamInfo<Case>& p) {
                           return std::string(p.param.grbl ? "GrblAck" : "IsoDrip") +
                                  (p.param.sigint ? "Sigint" : "SocketStop");
                         });

}  // namespace
