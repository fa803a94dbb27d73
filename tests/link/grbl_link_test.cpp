// grbl's `Bf:` lag, in simulated time over real pseudo-terminals. grbl 1.1 drops a block from
// its planner (and so from Bf:'s count, and from Ln:) once the stepper has prepared the block's
// last segment, up to 5 segments of at most 10 ms before the motion gets there (stepper.c,
// st_prep_buffer; docs/dnc-link.md). The first test checks each status report of the simulated
// controller against that rule computed here from the reported position; the second runs the
// sender against it and checks that no block is ever counted executed before the controller has
// executed it.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "link/dnc_sender.hpp"
#include "link/program_file.hpp"
#include "sim/sim_controller.hpp"
#include "tests/common/temp_dir.hpp"

namespace ncd::comms {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

double since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// A fresh folder per test (tests/common/temp_dir.hpp).
struct TempDir : ncd::test::TempDir {
  TempDir() : ncd::test::TempDir("ncd_grbl_") {}
};

SimControllerConfig grbl_config(const fs::path& link, std::shared_ptr<ManualClock> clock) {
  SimControllerConfig c;
  c.line.device = link.string();
  c.line.baud = 115200;
  parse_frame("8N1", c.line);
  c.line.protocol = Protocol::Ack;
  c.clock = std::move(clock);
  c.seed = 1;
  return c;
}

// The controller on its own thread, its clock moved on by the test.
class Running {
 public:
  Running(SimControllerConfig cfg, std::shared_ptr<ManualClock> clock)
      : sim(std::move(cfg)),
        clock_(std::move(clock)),
        t0_(clock_->now_s()),
        thread_([this] { sim.run(); }) {}
  ~Running() { stop(); }
  // Stops the controller; its log is complete after this.
  const SimLog& stop() {
    if (thread_.joinable()) {
      sim.request_stop();
      thread_.join();
    }
    return sim.log();
  }
  Running(const Running&) = delete;
  Running& operator=(const Running&) = delete;
  // Moves the controller's time on by dt_s and waits until its loop has run at the new time.
  bool step(double dt_s) {
    clock_->advance(dt_s);
    const double target = clock_->now_s() - t0_;
    const auto t0 = Clock::now();
    while (since(t0) < 30.0) {
      if (sim.progress().t_s >= target - 1e-12) return true;
      std::this_thread::sleep_for(200us);
    }
    return false;
  }
  SimController sim;

 private:
  std::shared_ptr<ManualClock> clock_;
  double t0_;
  std::thread thread_;
};

// The sender's end, raw and non-blocking; collects the controller's lines.
class Peer {
 public:
  explicit Peer(const std::string& path) {
    fd_ = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK);
    EXPECT_GE(fd_, 0) << path;
    termios t{};
    if (fd_ >= 0 && ::tcgetattr(fd_, &t) == 0) {
      ::cfmakeraw(&t);
      ::tcsetattr(fd_, TCSANOW, &t);
    }
  }
  ~Peer() {
    if (fd_ >= 0) ::close(fd_);
  }
  Peer(const Peer&) = delete;
  Peer& operator=(const Peer&) = delete;
  void write_all(const std::string& bytes) {
    std::size_t off = 0;
    while (off < bytes.size()) {
      const ssize_t n = ::write(fd_, bytes.data() + off, bytes.size() - off);
      if (n > 0) off += static_cast<std::size_t>(n);
    }
  }
  void pump() {
    char buf[256];
    for (ssize_t n; (n = ::read(fd_, buf, sizeof buf)) > 0;) {
      for (ssize_t i = 0; i < n; ++i) {
        if (buf[i] == '\n') {
          if (!line_.empty() && line_.back() == '\r') line_.pop_back();
          lines.push_back(line_);
          line_.clear();
        } else {
          line_ += buf[i];
        }
      }
    }
  }
  std::vector<std::string> lines;

 private:
  int fd_ = -1;
  std::string line_;
};

// A number after `key` in a status report.
double field(const std::string& report, const std::string& key, int index = 0) {
  auto p = report.find(key);
  EXPECT_NE(p, std::string::npos) << report;
  p += key.size();
  for (int i = 0; i < index; ++i) p = report.find(',', p) + 1;
  return std::stod(report.substr(p));
}

// Three moves of 100 ms (10 segments each) and ten of 5 ms (one segment each), along X at
// 600 mm/min, all in the planner at once. Every report's Bf: must equal grbl's rule computed
// here: from the reported X, the move executing and its time left; it has left the planner when
// its remaining segments, ceil(left / 10 ms), are at most 5, and each following move too while
// the segments counted so far (one per 10 ms or part) stay within 5.
TEST(GrblBf, ABlockLeavesThePlannerWhenItsLastSegmentIsPreparedNotWhenItEnds) {
  TempDir dir;
  auto clock = std::make_shared<ManualClock>();
  Running run(grbl_config(dir / "cnc", clock), clock);
  Peer peer((dir / "cnc").string());
  std::vector<double> ends;  // X at the end of each move
  std::string program;
  double x = 0.0;
  for (int i = 0; i < 13; ++i) {
    x += i < 3 ? 1.0 : 0.05;
    ends.push_back(x);
    char line[48];
    std::snprintf(line, sizeof line, "G1X%.2fF600\n", x);
    program += line;
  }
  // 156 characters: they arrive in 14 ms, and each line leaves the ring for the planner at once.
  peer.write_all(program);
  // Until every line is answered: all 13 moves are planned.
  for (int i = 0; i < 20000; ++i) {
    ASSERT_TRUE(run.step(0.0001));
    peer.pump();
    if (std::count(peer.lines.begin(), peer.lines.end(), "ok") == 13) break;
  }
  ASSERT_EQ(std::count(peer.lines.begin(), peer.lines.end(), "ok"), 13);
  const double v_mm_per_s = 10.0;
  int checked = 0, lagging = 0, max_prepared = 0;
  std::string idle;
  for (int q = 0; q < 2000 && idle.empty(); ++q) {
    ASSERT_TRUE(run.step(0.0004));  // a report every half millisecond or so
    const std::size_t from = peer.lines.size();
    peer.write_all("?");
    std::string report;
    for (int i = 0; i < 1000 && report.empty(); ++i) {
      ASSERT_TRUE(run.step(0.0001));
      peer.pump();
      for (std::size_t k = from; k < peer.lines.size(); ++k) {
        if (peer.lines[k].front() == '<') report = peer.lines[k];
      }
    }
    ASSERT_FALSE(report.empty());
    if (report.rfind("<Idle", 0) == 0) {
      idle = report;
      break;
    }
    const double px = field(report, "MPos:");
    const int free_blocks = static_cast<int>(field(report, "Bf:"));
    EXPECT_EQ(field(report, "Bf:", 1), 128.0) << report;  // every line taken out of the ring
    // The move executing: the first whose end lies ahead; skip reports within 0.002 mm (the
    // 3 decimals) of an end point or of a segment boundary.
    if (std::any_of(ends.begin(), ends.end(),
                    [&](double e) { return std::abs(e - px) <= 0.002; })) {
      continue;
    }
    std::size_t m = 0;
    while (m < ends.size() && ends[m] < px) ++m;
    if (m == ends.size()) continue;
    const double left_s = (ends[m] - px) / v_mm_per_s;
    const double segs = left_s / 0.01;
    if (std::abs(segs - std::round(segs)) < 0.0002 / 0.01) continue;
    int used = static_cast<int>(std::ceil(segs));
    int prepared = used <= 5 ? 1 : 0;
    for (std::size_t j = m + 1; prepared > 0 && j < ends.size(); ++j) {
      used += static_cast<int>(std::ceil((ends[j] - ends[j - 1]) / v_mm_per_s / 0.01 - 1e-9));
      if (used > 5) break;
      ++prepared;
    }
    const int unfinished = static_cast<int>(ends.size() - m);
    EXPECT_EQ(free_blocks, 15 - (unfinished - prepared))
        << report << " (move " << m + 1 << ", " << left_s << " s left)";
    ++checked;
    lagging += prepared > 0 ? 1 : 0;
    max_prepared = std::max(max_prepared, prepared);
  }
  std::cout << "[ measured ] " << checked << " reports checked against grbl's segment rule; "
            << lagging << " showed moves still running as gone from the planner (up to "
            << max_prepared << ")\n";
  EXPECT_GT(checked, 30);
  EXPECT_GT(lagging, 5);
  EXPECT_GE(max_prepared, 4);  // the 5 ms moves: one segment each
  EXPECT_NE(idle.find("|Bf:15,128"), std::string::npos) << idle;
}

// The sender against that controller: every time it counts a block executed, the controller
// has executed at least as many. Short moves (5 ms, one segment) make Bf: run up to 5 moves
// ahead of the motion; counting executed from Bf: alone would be ahead of the controller. The
// same with Ln: (grbl built with USE_LINE_NUMBERS), which names the planner's first block not
// prepared, as far ahead.
class GrblTracking : public ::testing::TestWithParam<bool> {};

TEST_P(GrblTracking, SenderNeverCountsABlockExecutedBeforeTheControllerHas) {
  TempDir dir;
  auto clock = std::make_shared<ManualClock>();
  SimControllerConfig cfg = grbl_config(dir / "cnc", clock);
  cfg.report_line_numbers = GetParam();
  Running run(cfg, clock);
  std::string text = "G21 G90 G94\n";
  double x = 0.0;
  const int moves = 160;
  for (int i = 1; i <= moves; ++i) {
    x += i % 10 == 0 ? 0.5 : 0.05;  // 5 ms, and every tenth 50 ms
    char line[48];
    std::snprintf(line, sizeof line, "N%d G1 X%.3f F600\n", i, x);
    text += line;
  }
  text += "M2\n";
  const fs::path path = dir / "prog.ngc";
  std::ofstream(path) << text;
  const long blocks = moves + 2;

  SenderSettings s;
  s.line.device = (dir / "cnc").string();
  s.line.baud = 115200;
  parse_frame("8N1", s.line);
  s.line.protocol = Protocol::Ack;
  s.status_hz = 50.0;
  s.banner_wait_s = 0.2;
  s.startup_timeout_s = 60.0;
  ProgramFile source(path.string());
  DncSender sender(s, source);
  std::atomic<long> claims{0}, ahead{0}, max_lead{0}, claims_running{0};
  sender.on_executed([&](std::int64_t executed, std::int64_t) {
    // The controller's count only grows: read after the claim, it is at least what it was.
    const long have = run.sim.progress().blocks_executed;
    ++claims;
    if (executed > have) {
      ++ahead;
      max_lead = std::max(max_lead.load(), static_cast<long>(executed - have));
    }
    if (executed < blocks - 1) ++claims_running;
  });
  std::atomic<bool> stop{false}, done{false};
  SenderReport report;
  std::thread t([&] {
    report = sender.run(stop);
    done = true;
  });
  const auto t0 = Clock::now();
  while (!done && since(t0) < 120.0) {
    if (!run.step(0.0005)) break;
  }
  stop = true;
  t.join();
  std::cout << "[ measured ] " << claims << " blocks counted executed (" << claims_running
            << " while moving): " << ahead << " ahead of the controller (most " << max_lead << "); "
            << report.status_reports << " status reports\n";
  EXPECT_EQ(ahead, 0);
  EXPECT_EQ(max_lead, 0);
  EXPECT_TRUE(report.completed) << report.failure;
  EXPECT_EQ(report.blocks_executed, blocks);
  EXPECT_GT(claims_running, 20);  // counted while the program ran, not only at the end
  const SimLog& log = run.stop();
  std::vector<std::string> ran, want;
  for (const SimExecuted& e : log.executed) ran.push_back(e.text);
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) want.push_back(line);
  EXPECT_EQ(ran, want);  // every block once, in order
}

INSTANTIATE_TEST_SUITE_P(GrblBf, GrblTracking, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool>& p) {
                           return std::string(p.param ? "Ln" : "Bf");
                         });

}  // namespace
}  // namespace ncd::comms

namespace ncd::comms {
namespace {

// The half line a cut leaves in grbl's line buffer, in-process (the same case as
// Stream.AckHalfLineAfterACutNeverMergesWithTheNextBlock, here so that it also runs under ASan
// with the comms tests): the link is cut inside X's number of N30, then inside its `;` comment.
// The sender's flush is refused whole in the first case and completes the block in the second;
// either way every block runs once, none cut short.
TEST(GrblHalfLine, ACutLineNeverRunsCutShortNorTwice) {
  for (const bool in_comment : {false, true}) {
    SCOPED_TRACE(in_comment ? "cut in the comment" : "cut in the number");
    TempDir dir;
    std::string text;
    std::vector<std::string> code;  // what grbl runs of each line
    for (int i = 1; i <= 60; ++i) {
      char line[80];
      std::snprintf(line, sizeof line, "N%d G1 X%.3f Y0.5 F20000 ; pass %d", i, 0.25 * i, i);
      text += std::string(line) + "\n";
      code.push_back(std::string(line).substr(0, std::string(line).find(';')));
    }
    const std::string n30 = "N30 G1 X7.500 Y0.5 F20000 ; pass 30";
    const std::size_t offset = in_comment ? n30.find(';') + 3 : n30.find('X') + 3;
    const fs::path path = dir / "prog.ngc";
    std::ofstream(path) << text;
    SimControllerConfig cfg;
    cfg.line.device = (dir / "cnc").string();
    cfg.line.baud = 115200;
    parse_frame("8N1", cfg.line);
    cfg.line.protocol = Protocol::Ack;
    cfg.faults.drop_link_after_chars =
        static_cast<long>(3 + text.find(n30) + offset);  // after the wake-up line "))" LF
    cfg.faults.down_s = 0.5;
    SimController sim(cfg);
    std::thread controller([&] { sim.run(); });
    SenderSettings s;
    s.line = cfg.line;
    s.banner_wait_s = 0.3;
    s.reconnect_max_s = 10.0;
    ProgramFile source(path.string());
    DncSender sender(s, source);
    std::atomic<bool> stop{false};
    const SenderReport report = sender.run(stop);
    sim.request_stop();
    controller.join();
    const SimLog& log = sim.log();
    EXPECT_TRUE(report.completed) << report.failure;
    EXPECT_EQ(report.reconnects, 1);
    EXPECT_EQ(log.link_drops, 1);
    std::vector<std::string> ran;
    for (const SimExecuted& e : log.executed) ran.push_back(e.text.substr(0, e.text.find(';')));
    EXPECT_EQ(ran, code);
    bool refused = false;
    for (const SimErrorReply& e : log.errors)
      refused = refused || e.text == n30.substr(0, offset) + "))";
    EXPECT_EQ(refused, !in_comment);
  }
}

}  // namespace
}  // namespace ncd::comms

namespace ncd::comms {
namespace {

// The sender and a grbl controller on a ManualClock: the test's thread moves the controller's
// time on in steps of dt_s while the sender runs on its own thread, until run() returns.
struct SenderRun {
  SenderReport report;
  bool finished = false;
};

SenderRun run_sender(DncSender& sender, Running& run, const std::atomic<bool>& stop, double dt_s,
                     const std::function<void(double)>& at_time = {}) {
  SenderRun r;
  std::atomic<bool> done{false};
  std::thread t([&] {
    r.report = sender.run(stop);
    done = true;
  });
  const auto t0 = Clock::now();
  double sim_t = 0.0;
  while (!done && since(t0) < 120.0) {
    if (!run.step(dt_s)) break;
    sim_t += dt_s;
    if (at_time) at_time(sim_t);
  }
  t.join();
  r.finished = done;
  return r;
}

std::string slow_moves(int moves) {
  std::string text = "G21 G90 G94\n";
  for (int i = 1; i <= moves; ++i) {
    char line[48];
    std::snprintf(line, sizeof line, "N%d G1 X%d F600\n", i, i);  // 1 mm at 10 mm/s: 0.1 s
    text += line;
  }
  return text + "M2\n";
}

SenderSettings grbl_sender(const fs::path& link) {
  SenderSettings s;
  s.line.device = link.string();
  s.line.baud = 115200;
  parse_frame("8N1", s.line);
  s.line.protocol = Protocol::Ack;
  s.status_hz = 10.0;
  s.banner_wait_s = 0.2;
  s.startup_timeout_s = 60.0;
  return s;
}

// DncSender::request_halt, the primitive a stop calls: asked while grbl moves, it holds, waits
// for Hold:0 (the 100 mm/s² deceleration from 10 mm/s takes 0.1 s of the controller's time,
// however late the sender's thread runs), and only then resets: no ALARM:3, nothing queued runs
// after it, grbl Idle. At rest the count of executed blocks is exact: it equals the controller's.
TEST(GrblHalt, RequestHaltResetsOnlyOnceTheHoldIsAtRest) {
  TempDir dir;
  auto clock = std::make_shared<ManualClock>();
  Running run(grbl_config(dir / "cnc", clock), clock);
  const fs::path path = dir / "prog.ngc";
  std::ofstream(path) << slow_moves(60);
  ProgramFile source(path.string());
  DncSender sender(grbl_sender(dir / "cnc"), source);
  std::atomic<bool> stop{false};
  bool asked = false;
  const SenderRun r = run_sender(sender, run, stop, 0.0005, [&](double t) {
    if (!asked && t >= 2.0) {  // some 18 moves in, the planner full
      asked = true;
      sender.request_halt();
    }
  });
  ASSERT_TRUE(r.finished);
  const SenderReport& rep = r.report;
  EXPECT_TRUE(rep.stopped);
  EXPECT_FALSE(rep.completed);
  EXPECT_TRUE(rep.halt.attempted);
  EXPECT_TRUE(rep.halt.ok()) << rep.halt.detail;
  EXPECT_EQ(rep.halt.state, "Idle");
  EXPECT_EQ(rep.controller_state, "Idle");
  for (int i = 0; i < 200; ++i) ASSERT_TRUE(run.step(0.005));  // 1 s more: nothing moves
  const SimLog& log = run.stop();
  ASSERT_EQ(log.resets.size(), 1U);
  EXPECT_EQ(log.resets[0].cause, "soft_reset");
  EXPECT_FALSE(log.resets[0].in_motion);
  EXPECT_GT(log.resets[0].blocks_lost, 0);
  EXPECT_EQ(log.feed_holds, 1);
  EXPECT_EQ(log.cycle_starts, 0);
  EXPECT_EQ(rep.blocks_executed, log.blocks_executed);  // exact at rest
  EXPECT_GE(log.blocks_executed, 10);
  std::cout << "[ measured ] halted after " << log.blocks_executed << " blocks, at rest after "
            << rep.halt.rest_s << " s of the sender's time; " << log.resets[0].blocks_lost
            << " queued blocks thrown away, no alarm\n";
}

// A hold that cannot come to rest within halt_timeout_s (a slow deceleration: 0.01 mm/s²) is
// not reset: a reset in motion would raise ALARM:3 and lose the position. The controller stays
// held (its motion slowing down), and the report says so.
TEST(GrblHalt, NoResetBeforeTheMotionIsAtRest) {
  TempDir dir;
  auto clock = std::make_shared<ManualClock>();
  SimControllerConfig cfg = grbl_config(dir / "cnc", clock);
  cfg.hold_accel_mm_per_s2 = 0.01;
  Running run(cfg, clock);
  const fs::path path = dir / "prog.ngc";
  std::ofstream(path) << "G21 G90 G94\nG1 X1000 F600\nM2\n";  // 100 s of motion
  ProgramFile source(path.string());
  SenderSettings s = grbl_sender(dir / "cnc");
  s.halt_timeout_s = 1.0;
  DncSender sender(s, source);
  std::atomic<bool> stop{false};
  bool asked = false;
  const SenderRun r = run_sender(sender, run, stop, 0.001, [&](double t) {
    if (!asked && t >= 1.0) {
      asked = true;
      sender.request_halt();
    }
  });
  ASSERT_TRUE(r.finished);
  EXPECT_TRUE(r.report.halt.attempted);
  EXPECT_FALSE(r.report.halt.at_rest);
  EXPECT_FALSE(r.report.halt.reset);
  EXPECT_EQ(r.report.halt.state, "Hold:1");
  EXPECT_NE(r.report.halt.detail.find("not reset"), std::string::npos) << r.report.halt.detail;
  const SimLog& log = run.stop();
  EXPECT_TRUE(log.resets.empty());
  EXPECT_EQ(log.feed_holds, 1);
}

// A controller left held (Hold:0: its protocol loop reads no line, so a wake-up line gets no
// answer) is brought to a safe halt at start-up, and the program then runs whole. Before, the
// next `ncd stream` waited for an answer and gave up: "did not speak within 10 s".
TEST(GrblHalt, AControllerLeftHeldIsHaltedAtStartUpThenTheProgramRuns) {
  TempDir dir;
  auto clock = std::make_shared<ManualClock>();
  Running run(grbl_config(dir / "cnc", clock), clock);
  {
    Peer peer((dir / "cnc").string());
    peer.write_all("!");
    for (int i = 0; i < 50; ++i) ASSERT_TRUE(run.step(0.001));
  }
  const fs::path path = dir / "prog.ngc";
  const std::string text = slow_moves(10);
  std::ofstream(path) << text;
  ProgramFile source(path.string());
  SenderSettings s = grbl_sender(dir / "cnc");
  s.startup_timeout_s = 10.0;
  DncSender sender(s, source);
  std::atomic<bool> stop{false};
  const SenderRun r = run_sender(sender, run, stop, 0.0005);
  ASSERT_TRUE(r.finished);
  EXPECT_TRUE(r.report.completed) << r.report.failure;
  EXPECT_TRUE(r.report.halt.ok()) << r.report.halt.detail << " / " << r.report.halt.state;
  ASSERT_FALSE(r.report.notes.empty());
  EXPECT_NE(r.report.notes[0].find("held (Hold:0) at start-up"), std::string::npos)
      << r.report.notes[0];
  const SimLog& log = run.stop();
  ASSERT_EQ(log.resets.size(), 1U);
  EXPECT_FALSE(log.resets[0].in_motion);
  std::vector<std::string> ran, want;
  for (const SimExecuted& e : log.executed) ran.push_back(e.text);
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) want.push_back(line);
  EXPECT_EQ(ran, want);
}

}  // namespace
}  // namespace ncd::comms
