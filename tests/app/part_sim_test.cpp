// The manifold of docs/part.md through the simulated controller, as a test of the suite: the
// program `ncd chamfer --part examples/manifold.toml --machine examples/machine-rotary.toml`
// writes, walked by `ncd replay --blocks` into the blocks a live job streams (about a thousand
// blocks, 92 s of motion), sent by the DNC sender (drip feed, DC1/DC3, 115 200 baud 7E2, a
// ProgramFile source: what `ncd stream` does) to the simulated controller (linuxcnc dialect,
// which alarms on a feed move with the spindle stopped; a 4096-byte buffer, DC3 at 1024, DC1 at
// 512: the manual run docs/part.md described). The verdict is read from the controller's log,
// the independent record of what ran, against the program file read here: every block executed,
// in order, the program's SHA-256 received whole, no alarm, the program end executed; every
// index (a move of A alone) made at Z at or above the clearance plane (the pipe's radius plus
// the part file's margin) with the spindle as the program's M3/M5 left it, at the program's
// angles; every G1 move executed with the spindle turning. The negative check: the same blocks
// with the M3 taken out make the controller alarm at the first feed move (so the assertions
// above can fail), and no feed move runs.
//
// What is real and what is simulated. Real: the `ncd` executable for chamfer and replay, the
// pseudo-terminal and every byte on it, the sender's code (its loop, its wire model, DC1/DC3, the
// NAK of an alarm) and the controller's (reception, receive buffer, DC1/DC3, the linuxcnc
// dialect's check, the spindle interlock, the executor). Simulated: time, for both ends. The
// controller's clock is a ManualClock the test moves on (tests/common/paced_controller.hpp),
// only once the sender has read everything the controller wrote (a DC3 is seen before time
// moves on) and once the controller's loop has run at the time before; in that time the
// controller reads the line no faster than the baud rate (10 472 characters/s at 115 200 7E2),
// executes each block for its length at its feed (G0 at the rapid rate, A at its rate in
// deg/min) and logs when it did. The sender's wire model runs on the same clock
// (SenderSettings::wire_clock: it writes at most 16 characters ahead of what the line can have
// carried in the controller's time, at 98 % of the baud rate), and so does its timing of the
// controller's holds (hold_clock). Only the sender's loop runs on the wall clock (a pass every
// millisecond or so, 16 characters at most each), which bounds how fast it can write in the
// controller's time: so the test moves the clock on kStepS at a step while the controller's
// buffer holds at least its low-water mark and kSlowStepS while it holds less, and after each
// step waits for the sender to write (wait_for_a_write), so that the sender keeps ahead of the
// execution however the machine's load delays its thread (the run prints its underruns: 0).
// Without that wait CI's loaded machine starved the controller: 40 underruns, no DC3. The 92 s of
// motion take a few seconds here (the test prints the controller's time, the wall time and the CPU
// time).
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "link/dnc_sender.hpp"
#include "link/program_file.hpp"
#include "link/sha256.hpp"
#include "sim/sim_controller.hpp"
#include "tests/app/cli_fixture.hpp"
#include "tests/common/paced_controller.hpp"

namespace {

using namespace ncd;
namespace fs = std::filesystem;

const std::string kManifoldToml = std::string(NCD_SOURCE_DIR) + "/examples/manifold.toml";
const std::string kRotaryMachine = std::string(NCD_SOURCE_DIR) + "/examples/machine-rotary.toml";
// [pipe] outer_radius_mm (a cylinder) + [cut] clearance_margin_mm of examples/manifold.toml, for
// the ball's tip (the machine file's programmed point).
constexpr double kClearanceMm = 30.0 + 10.0;
// The controller's time moved on at each step of the test (a step then waits for a pass of the
// sender's loop, which writes up to 16 characters): kStepS while the controller's buffer holds
// at least its low-water mark, kSlowStepS while it holds less.
constexpr double kStepS = 0.02, kSlowStepS = 0.002;
// The longest wall time a step waits for the sender to write (wait_for_a_write).
constexpr double kSenderWaitS = 2.0;

double cpu_seconds() {
  rusage u{};
  ::getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

// The program's blocks as the sender sends them and the controller logs them (`%` and empty
// lines are framing).
std::vector<std::string> part_sim_blocks(const std::string& path) {
  std::vector<std::string> out;
  std::istringstream in(ncd::test::slurp(path));
  for (std::string line; std::getline(in, line);) {
    const std::string b = comms::block_of_line(line);
    if (!b.empty()) out.push_back(b);
  }
  return out;
}

// The words of a block (letter upper case, value), comments in parentheses and after `;` left
// out: read here, not by ncd's lexer.
std::vector<std::pair<char, double>> part_sim_words(const std::string& block) {
  std::string text;
  int depth = 0;
  for (char c : block) {
    if (c == ';' && depth == 0) break;
    if (c == '(') ++depth;
    if (depth == 0 && c != ' ' && c != '\t') text += c;
    if (c == ')' && depth > 0) --depth;
  }
  std::vector<std::pair<char, double>> words;
  std::size_t i = 0;
  while (i < text.size()) {
    const char letter = static_cast<char>(std::toupper(static_cast<unsigned char>(text[i])));
    std::size_t used = 0;
    const double v = std::stod(text.substr(i + 1), &used);
    words.emplace_back(letter, v);
    i += 1 + used;
  }
  return words;
}

// What the program says at each index: the angle, and whether the spindle turns (the M3/M4/M5
// in force once the block's own M codes took effect, as a controller runs them before the
// motion).
struct ProgramIndex {
  double angle_deg = 0.0;
  bool spindle_on = false;
};

std::vector<ProgramIndex> part_sim_indexes(const std::vector<std::string>& blocks) {
  std::vector<ProgramIndex> out;
  bool on = false;
  for (const std::string& b : blocks) {
    const auto words = part_sim_words(b);
    for (const auto& [letter, v] : words) {
      if (letter == 'M' && (v == 3.0 || v == 4.0)) on = true;
      if (letter == 'M' && (v == 5.0 || v == 2.0 || v == 30.0)) on = false;
    }
    for (const auto& [letter, v] : words) {
      if (letter == 'A') out.push_back({v, on});
    }
  }
  return out;
}

// The spindle as the controller had executed it when the block `seq` moved: its spindle events
// up to that block (a block's M3/M5 run before its motion).
bool part_sim_spindle_on(const comms::SimLog& log, long seq) {
  bool on = false;
  for (const comms::SimEvent& e : log.events) {
    if (e.seq > seq) break;
    if (e.kind == "spindle_cw" || e.kind == "spindle_ccw") on = true;
    if (e.kind == "spindle_stop") on = false;
  }
  return on;
}

struct PartSimRun {
  comms::SimLog log;
  comms::SenderReport report;
  double controller_s = 0.0, wall_s = 0.0, cpu_s = 0.0;
  long steps = 0;
  long sender_waits_over = 0;  // steps after which the sender wrote nothing within kSenderWaitS
};

// After a step of the controller's time: waits until the sender has written since `before`
// (the line has carried what it had ahead, so it has room), or needs not (the controller holds
// the line, all the program's `blocks` are written, the sender is done), for up to kSenderWaitS of
// wall time. The sender writes at most its 16 characters ahead of the line at a pass of its loop,
// so without this wait a step quicker than its pass (the test's thread outrunning the sender's on
// a loaded machine) starves the controller in its time, and the flow control under test is
// never reached. False when the wait ran out (counted and printed; the run goes on).
bool wait_for_a_write(const comms::DncSender& sender, const comms::SenderCounts& before,
                      std::int64_t blocks, const std::atomic<bool>& sender_done) {
  const auto until = std::chrono::steady_clock::now() +
                     std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                         std::chrono::duration<double>(kSenderWaitS));
  while (!sender_done.load()) {
    const comms::SenderCounts now = sender.counters().load();
    if (now.bytes_written > before.bytes_written || now.xoff_held || now.blocks_written >= blocks) {
      return true;
    }
    if (std::chrono::steady_clock::now() > until) return false;
    std::this_thread::sleep_for(std::chrono::microseconds(50));
  }
  return true;
}

class PartSim : public ncd::test::Cli {
 protected:
  // The manifold's blocks as `ncd replay --blocks` writes them for the machine with an A axis.
  std::string manifold_blocks() {
    const std::string program = (dir_ / "manifold.ngc").string();
    const std::string blocks = (dir_ / "manifold-dnc.ngc").string();
    ncd::test::CmdResult r = ncd("chamfer --part " + kManifoldToml + " --machine " +
                                 kRotaryMachine + " -q -o " + program);
    EXPECT_EQ(r.status, 0) << r.err;
    r = ncd("replay " + program + " --machine " + kRotaryMachine + " --start 0,0,50 -q --blocks " +
            blocks);
    EXPECT_EQ(r.status, 0) << r.err;
    return blocks;
  }

  // Streams `program` with the sender to the controller, both in this process, the controller
  // in simulated time; returns once both are done (the controller exits at the program end, or
  // a second of its time after an alarm).
  PartSimRun stream(const std::string& program) {
    comms::SimControllerConfig c;
    c.line.device = (dir_ / "cnc").string();
    c.line.baud = 115200;  // 7E2, DC1/DC3, drip, LF, `%` framing: both ends' defaults
    c.dialect = comms::Dialect::linuxcnc;
    c.buffer_bytes = 4096;
    c.xoff_at = 1024;
    c.xon_at = 512;
    c.exit_at_end = true;
    ncd::test::PacedController ctl;
    ctl.start(c);

    comms::SenderSettings s;
    s.line = c.line;
    s.hold_clock = ctl.clock();  // the controller's holds timed on its own clock
    s.wire_clock = ctl.clock();  // and the line's carriage: its DC3 always in reach
    comms::ProgramFile source(program);
    comms::DncSender sender(s, source);
    const auto blocks = static_cast<std::int64_t>(part_sim_blocks(program).size());
    std::atomic<bool> stop{false}, sender_done{false};
    PartSimRun run;
    ctl.while_sender_reads([&sender_done] { return !sender_done.load(); });
    const double cpu0 = cpu_seconds();
    const auto wall0 = std::chrono::steady_clock::now();
    const auto wall = [&wall0] {
      return std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    };
    std::thread sending([&] {
      run.report = sender.run(stop);
      sender_done = true;
    });
    // 120 s of wall time at most (a few seconds expected): then the sender is stopped and the
    // test fails below on what did not run.
    while (!(ctl.done() && sender_done.load()) && wall() < 120.0 &&
           !::testing::Test::HasFatalFailure()) {
      if (ctl.done()) {  // the controller's time no longer moves: only the sender is left
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
        continue;
      }
      // Faster while the controller's buffer holds what it will run for a while, slower once
      // it holds less: the sender, paced by the wall clock, keeps ahead of the execution.
      const bool fed = ctl.sim().progress().buffer_fill >= *c.xon_at;
      const comms::SenderCounts before = sender.counters().load();
      ctl.step(fed ? kStepS : kSlowStepS);
      ++run.steps;
      // After an alarm the controller reads no more: the sender has nothing to wait for.
      if (ctl.sim().progress().alarms == 0 &&
          !wait_for_a_write(sender, before, blocks, sender_done)) {
        ++run.sender_waits_over;
      }
    }
    EXPECT_TRUE(ctl.done() && sender_done.load()) << "not done after " << wall() << " s";
    stop = true;
    sending.join();
    ctl.stop();
    run.log = ctl.log();
    run.wall_s = wall();
    run.cpu_s = cpu_seconds() - cpu0;
    run.controller_s = run.log.duration_s;
    return run;
  }
};

TEST_F(PartSim, ManifoldRunsWholeOnTheSimulatedControllerWithEveryIndexAboveTheClearance) {
  const std::string path = manifold_blocks();
  ASSERT_FALSE(HasFailure());
  const std::vector<std::string> blocks = part_sim_blocks(path);
  std::string text;
  for (const std::string& b : blocks) text += b + "\n";
  const std::string sha = comms::sha256_hex(text);
  const std::vector<ProgramIndex> want = part_sim_indexes(blocks);
  ASSERT_GE(want.size(), 7u) << "one index before each of the eight holes but the first";

  const PartSimRun run = stream(path);
  const comms::SimLog& log = run.log;
  const nlohmann::json log_json = comms::to_json(log);
  long g1 = 0;
  for (const comms::SimMove& m : log.moves) g1 += m.g == 1 ? 1 : 0;
  std::cout << "[ measured ] " << blocks.size() << " blocks, " << text.size() << " bytes, "
            << want.size() << " indexes, " << g1 << " G1 moves: controller's time "
            << run.controller_s << " s (execution " << log.execution_start_t_s << " to "
            << log.execution_end_t_s << " s), wall " << run.wall_s << " s, CPU " << run.cpu_s
            << " s (this process), " << run.steps << " steps; DC3 " << log.xoff_sent
            << ", largest fill " << log.max_buffer_fill << " of " << log.config.buffer_bytes
            << ", underruns " << log.underruns << " (" << log.dwell_s
            << " s dwelt); steps the sender did not write after: " << run.sender_waits_over << "\n";

  EXPECT_TRUE(run.report.completed) << run.report.failure;
  EXPECT_TRUE(log.alarms.empty()) << log_json["alarms"].dump();
  EXPECT_TRUE(run.report.alarms.empty());
  EXPECT_EQ(log.program_sha256, sha);
  EXPECT_EQ(run.report.program_sha256, sha);
  EXPECT_TRUE(log.program_end_executed);
  EXPECT_EQ(log.stop_reason, "program_end");
  // Every block executed once, in the program's order.
  EXPECT_EQ(log.blocks_executed, static_cast<long>(blocks.size()));
  std::vector<std::string> ran;
  for (const comms::SimExecuted& e : log.executed) ran.push_back(e.text);
  EXPECT_EQ(ran, blocks);
  // The flow control was exercised: the program is longer than the buffer's high-water mark.
  EXPECT_GT(log.xoff_sent, 0);
  EXPECT_LE(log.max_buffer_fill, log.config.buffer_bytes);

  // Every index at or above the clearance plane, with the spindle as the program says, at the
  // program's angles in the program's order.
  std::vector<ProgramIndex> indexed;
  double index_z_min = 1e9, index_z_max = -1e9;
  for (const comms::SimMove& m : log.moves) {
    if (!m.rotary_deg) continue;
    index_z_min = std::min(index_z_min, m.p[2]);
    index_z_max = std::max(index_z_max, m.p[2]);
    EXPECT_EQ(m.rotary_axis, 'A');
    EXPECT_GE(m.p[2], kClearanceMm - 1e-9) << "index at block " << m.seq << " below the clearance";
    indexed.push_back({*m.rotary_deg, part_sim_spindle_on(log, m.seq)});
  }
  std::cout << "[ measured ] the indexes at Z " << index_z_min << " to " << index_z_max
            << " mm (clearance " << kClearanceMm << ")\n";
  ASSERT_EQ(indexed.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    EXPECT_NEAR(indexed[i].angle_deg, want[i].angle_deg, 1e-9) << "index " << i + 1;
    EXPECT_EQ(indexed[i].spindle_on, want[i].spindle_on) << "index " << i + 1;
  }
  // Every feed move with the spindle turning.
  ASSERT_GT(g1, 0);
  for (const comms::SimMove& m : log.moves) {
    if (m.g == 1) {
      EXPECT_TRUE(part_sim_spindle_on(log, m.seq)) << "G1 at block " << m.seq << " spindle off";
    }
  }
}

// The negative check: without its M3 the same program stops at its first feed move (the
// controller's interlock), the sender sees the alarm, and no feed move runs.
TEST_F(PartSim, ManifoldWithoutItsM3AlarmsAtTheFirstFeedMove) {
  const std::vector<std::string> blocks = part_sim_blocks(manifold_blocks());
  ASSERT_FALSE(HasFailure());
  std::string text;
  int removed = 0;
  long first_feed = 0;  // 1-based block of the first G1
  std::string first_feed_text;
  for (const std::string& b : blocks) {
    bool m3 = false, g1 = false;
    std::string kept;
    for (const auto& [letter, v] : part_sim_words(b)) {
      m3 = m3 || (letter == 'M' && v == 3.0);
      g1 = g1 || (letter == 'G' && v == 1.0);
    }
    kept = b;
    if (m3) {  // the block without its M3 word, the rest of it kept (N5M3S6000: N5S6000)
      std::size_t at = kept.find("M3");
      while (at != std::string::npos && at + 2 < kept.size() &&
             (std::isdigit(static_cast<unsigned char>(kept[at + 2])) != 0 || kept[at + 2] == '.')) {
        at = kept.find("M3", at + 1);
      }
      ASSERT_NE(at, std::string::npos) << b;
      kept.erase(at, 2);
      for (const auto& [letter, v] : part_sim_words(kept)) {
        ASSERT_FALSE(letter == 'M' && v == 3.0) << kept;
      }
      ++removed;
    }
    if (!kept.empty()) text += kept + "\n";
    if (g1 && first_feed == 0) {
      first_feed = static_cast<long>(std::count(text.begin(), text.end(), '\n'));
      first_feed_text = kept;
    }
  }
  ASSERT_EQ(removed, 1) << "the manifold's program starts the spindle once";
  ASSERT_GT(first_feed, 0);

  const PartSimRun run = stream(write("no-m3.ngc", text));
  const comms::SimLog& log = run.log;
  ASSERT_EQ(log.alarms.size(), 1u) << comms::to_json(log)["alarms"].dump();
  EXPECT_EQ(log.alarms[0].code, "spindle_stopped");
  // Raised on receiving the first feed move, which is not accepted: the blocks before it are.
  EXPECT_EQ(log.alarms[0].block, first_feed - 1);
  EXPECT_NE(log.alarms[0].detail.find("'" + first_feed_text + "'"), std::string::npos)
      << log.alarms[0].detail;
  EXPECT_EQ(log.stop_reason, "alarm");
  EXPECT_FALSE(log.program_end_executed);
  for (const comms::SimMove& m : log.moves) EXPECT_NE(m.g, 1) << "a feed move ran";
  EXPECT_FALSE(run.report.completed);
  EXPECT_TRUE(run.report.interrupted);
  EXPECT_FALSE(run.report.alarms.empty()) << "the sender saw the NAK";
}

}  // namespace
