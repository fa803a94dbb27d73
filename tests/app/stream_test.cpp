// `ncd stream` against `ncd sim-controller` over real pseudo-terminals: the program arrives
// byte-exact (the controller's SHA-256 of the blocks equals the file's), with each protocol,
// through XOFF storms and long holds, a link cut while the controller runs, a controller reset,
// an error reply, a sender killed and restarted from its journal, a restart from block N, and
// noise from the controller. The controller logs each block it executed; the tests compare that
// log with the program (docs/dnc-link.md states what each dialect guarantees).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <optional>
#include <random>

#include "link/sha256.hpp"
#include "link/transfer_journal.hpp"
#include "tests/app/cli_fixture.hpp"
#include "tests/app/sim_controller_fixture.hpp"
#include "tests/common/process.hpp"
#include "tests/common/seed.hpp"

namespace ncd::test {
namespace {

class Stream : public SimControllerCli {
 protected:
  // A numbered program of `blocks` short G1 moves at a feed the controller runs quickly.
  std::string program(int blocks, double feed_mm_per_min, std::string* sha) {
    std::string text = "(ncd stream test program)\n", body;
    std::mt19937 rng(static_cast<unsigned>(blocks));
    std::uniform_real_distribution<double> d(-0.5, 0.5);
    double x = 0.0, y = 0.0;
    for (int i = 1; i <= blocks; ++i) {
      x += 0.5 + d(rng);
      y += d(rng);
      char line[96];
      std::snprintf(line, sizeof line, "N%dG1X%.3fY%.3fF%.0f", i, x, y, feed_mm_per_min);
      body += std::string(line) + "\n";
    }
    body += "M2\n";
    text += body;
    *sha = comms::sha256_hex("(ncd stream test program)\n" + body);
    return write("prog.ngc", text);
  }

  // Waits (up to 10 s) until the controller has printed `text` among its events: the bytes ncd
  // sent last (a hold, a soft reset) have been taken. A fixed sleep would race a loaded machine.
  void wait_for_event(const std::string& text) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (slurp(dir_ / "cnc.err").find(text) == std::string::npos) {
      ASSERT_LT(std::chrono::steady_clock::now(), end)
          << "the controller never printed '" << text << "': " << slurp(dir_ / "cnc.err");
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }

  // Stops a controller that will not end on its own (an interrupted job) and reads its log.
  nlohmann::json stopped_log(Process& p) {
    p.signal(SIGTERM);
    EXPECT_EQ(p.wait(10.0), 0) << slurp(dir_ / "cnc.err");
    return nlohmann::json::parse(slurp(log_));
  }

  // The program's blocks as the controller hashes and logs them (block_of_line of each line).
  std::vector<std::string> blocks_of(const std::string& path) {
    std::vector<std::string> out;
    std::istringstream in(slurp(path));
    for (std::string line; std::getline(in, line);) {
      if (!line.empty() && line != "%") out.push_back(line);
    }
    return out;
  }

  static std::vector<std::string> executed(const nlohmann::json& log) {
    std::vector<std::string> out;
    for (const auto& e : log["executed"]) out.push_back(e["text"].get<std::string>());
    return out;
  }

  // The controller ran a prefix of the program, each block once, in order; returns its length.
  static std::size_t ran_prefix(const std::vector<std::string>& ran,
                                const std::vector<std::string>& program) {
    EXPECT_LE(ran.size(), program.size());
    for (std::size_t i = 0; i < ran.size() && i < program.size(); ++i) {
      EXPECT_EQ(ran[i], program[i]) << "executed block " << i + 1;
      if (ran[i] != program[i]) return i;
    }
    return ran.size();
  }

  // The flags ncd advises for the next run: what follows "plus: " on its advice line, or "".
  static std::string advised(const std::string& text) {
    const auto at = text.find("plus: ");
    if (at == std::string::npos) return "";
    const auto end = text.find('\n', at);
    return text.substr(at + 6, end == std::string::npos ? std::string::npos : end - at - 6);
  }

  // The controller's log after a restart: the first run's blocks (a prefix of the program), the
  // restart lines (no N word), then blocks K… to the end. Checks that shape and returns the
  // length of the first run's prefix.
  static std::size_t check_restart_log(const std::vector<std::string>& ran,
                                       const std::vector<std::string>& blocks, std::size_t k) {
    const std::vector<std::string> tail(blocks.begin() + static_cast<long>(k) - 1, blocks.end());
    EXPECT_GE(ran.size(), tail.size());
    if (ran.size() < tail.size()) return 0;
    EXPECT_EQ(std::vector<std::string>(ran.end() - static_cast<long>(tail.size()), ran.end()), tail)
        << "blocks " << k << " to the end, once each, after the restart lines";
    const std::vector<std::string> head(ran.begin(), ran.end() - static_cast<long>(tail.size()));
    std::size_t e = 0;
    while (e < head.size() && e < blocks.size() && head[e] == blocks[e]) ++e;
    EXPECT_LE(head.size() - e, 10U) << "only restart lines between the two runs";
    for (std::size_t i = e; i < head.size(); ++i) {
      EXPECT_NE(head[i][0], 'N') << "a numbered block ran between the two runs: " << head[i];
    }
    return e;
  }
};

// A program of slow moves (about 0.1 s each at 600 mm/min), so that grbl's 15-block planner
// holds 1.5 s of motion: a fault lands while the controller is busy.
std::string slow_program(int moves) {
  std::string text = "(slow)\nG21 G90 G94\nG0 Z5\nS1000 M3\nG0 X0 Y0\nG1 Z-1 F600\n";
  for (int i = 1; i <= moves; ++i) {
    char line[64];
    std::snprintf(line, sizeof line, "N%d G1 X%d Y%.1f F600", i * 10, i, (i % 2) * 0.5);
    text += std::string(line) + "\n";
  }
  return text + "G0 Z5\nM5\nM2\n";
}

TEST_F(Stream, DripArrivesByteExact) {
  std::string sha;
  const std::string prog = program(300, 20000, &sha);
  auto cnc = controller("--baud 38400 --frame 7E2");
  const auto r = ncd("stream " + prog + " --port " + link_ + " --baud 38400 --frame 7E2 -q" +
                     " --report " + (dir_ / "r.json").string());
  EXPECT_EQ(r.status, 0) << r.err;
  const auto log = controller_log(*cnc);
  EXPECT_EQ(log["program_sha256"], sha);
  EXPECT_EQ(log["blocks_received"], 302);  // the comment line, 300 moves, M2
  EXPECT_TRUE(log["alarms"].empty()) << log["alarms"];
  const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
  EXPECT_EQ(rep["program_sha256"], sha);
  EXPECT_LE(rep["max_queued_estimate"].get<int>(), 16);
  EXPECT_FALSE(fs::exists(prog + ".journal"));
}

TEST_F(Stream, AckArrivesByteExactAndExecuted) {
  std::string sha;
  const std::string prog = program(300, 20000, &sha);
  // grbl ends a line at CR and at LF: CR LF would be answered twice. Refused before sending.
  const auto crlf = ncd("stream " + prog + " --port /dev/null --protocol ack --eob crlf");
  EXPECT_EQ(crlf.status, 2);
  EXPECT_NE(crlf.err.find("--eob lf"), std::string::npos) << crlf.err;
  auto cnc = controller("--baud 115200 --frame 8N1 --protocol ack");
  const auto r =
      ncd("stream " + prog + " --port " + link_ +
          " --baud 115200 --frame 8N1 --protocol ack --rx-buffer 128 -q --banner-wait 0.3" +
          " --report " + (dir_ / "r.json").string());
  EXPECT_EQ(r.status, 0) << r.err;
  const auto log = controller_log(*cnc);
  EXPECT_EQ(log["program_sha256"], sha);
  EXPECT_TRUE(log["alarms"].empty()) << log["alarms"];
  EXPECT_EQ(executed(log), blocks_of(prog));
  const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
  EXPECT_LE(rep["max_unacked_bytes"].get<int>(), 128);
  EXPECT_EQ(rep["transfer"]["startup"], "woken");  // no reset on open: no banner to wait for
  EXPECT_EQ(rep["transfer"]["blocks_executed"], 302);
  EXPECT_EQ(rep["program_summary"]["blocks"], 302);
  EXPECT_EQ(rep["program_summary"]["sha256"], sha);
}

// An Arduino resets when the port opens and boots for a while: nothing may be sent before its
// banner (the bytes would be lost, or worse, half a line).
TEST_F(Stream, AckSendsNothingBeforeTheBanner) {
  std::string sha;
  const std::string prog = program(50, 20000, &sha);
  auto cnc = controller("--baud 115200 --frame 8N1 --protocol ack --reset-on-open --boot-s 1.5");
  const auto r = ncd("stream " + prog + " --port " + link_ +
                     " --baud 115200 --frame 8N1 --protocol ack -q --banner-wait 3 --report " +
                     (dir_ / "r.json").string());
  EXPECT_EQ(r.status, 0) << r.err;
  const auto log = controller_log(*cnc);
  EXPECT_EQ(log["bytes_before_banner"], 0);
  EXPECT_EQ(log["banners_sent"], 1);
  EXPECT_EQ(executed(log), blocks_of(prog));
  const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
  EXPECT_EQ(rep["transfer"]["startup"], "banner");
  // A controller that never speaks: a clear message, not a wait at "0 % of the line".
  auto mute = controller("--baud 115200 --frame 8N1 --protocol ack --reset-on-open --boot-s 60");
  const auto m = ncd("stream " + prog + " --port " + link_ +
                     " --baud 115200 --frame 8N1 --protocol ack -q --no-journal --banner-wait 0.5 "
                     "--startup-timeout 1.5");
  EXPECT_EQ(m.status, 3) << m.err;
  EXPECT_NE(m.out.find("did not speak within 1.5 s"), std::string::npos) << m.out;
  const auto mlog = stopped_log(*mute);
  // Only a status request `?` (a real-time byte, never part of a line) and the wake-up line
  // ("))" and LF, which grbl must refuse) went out, into a controller still booting: 4 bytes,
  // or 1 if the machine's load delayed the wake-up past the time-out.
  EXPECT_GE(mlog["bytes_before_banner"].get<int>(), 1);
  EXPECT_LE(mlog["bytes_before_banner"].get<int>(), 4);
  EXPECT_TRUE(mlog["executed"].empty());
}

TEST_F(Stream, XoffStormAndLongHoldLoseNothing) {
  std::string sha;
  const std::string prog = program(400, 20000, &sha);
  const std::uint64_t seed = ncd::test::seed();
  auto cnc = controller("--baud 38400 --frame 7E2 --buffer 256 --xoff-storm --seed " +
                        std::to_string(seed) + " --hold-after-blocks 150 --hold-s 2.5");
  const auto r =
      ncd("stream " + prog + " --port " + link_ +
          " --baud 38400 --frame 7E2 --xoff-timeout 1 -q --report " + (dir_ / "r.json").string());
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("held the link"), std::string::npos) << r.err;
  const auto log = controller_log(*cnc);
  EXPECT_EQ(log["program_sha256"], sha);
  EXPECT_TRUE(log["alarms"].empty()) << log["alarms"];
  EXPECT_LT(log["max_buffer_fill"].get<int>(), 256);  // never full: the sender stopped in time
  const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
  EXPECT_GT(rep["xoff_count"].get<int>(), 3);
  EXPECT_EQ(rep["xoff_timeouts"], 1);
  EXPECT_GE(rep["xoff_longest_s"].get<double>(), 2.0);
}

// A link cut while the controller keeps running. grbl: the sender holds the controller, reads
// its position and resumes because the position proves what it holds; no block runs twice or
// is skipped. Drip: resent blocks would run twice, so the job stops as interrupted unless the
// controller is documented to skip repeated N numbers.
TEST_F(Stream, LinkCutWithTheControllerRunningRunsNoBlockTwice) {
  struct Case {
    std::string protocol, sim_flags, stream_flags;
    int status;
  };
  for (const Case& k : {Case{"ack", "", "--banner-wait 0.3", 0},
                        Case{"drip", "--skip-duplicate-n", "--controller-skips-repeated-n", 0},
                        Case{"drip", "", "", 3}}) {
    SCOPED_TRACE(k.protocol + " " + k.sim_flags);
    std::string sha;
    const std::string prog = program(400, 20000, &sha);
    auto cnc = controller("--baud 38400 --frame 7E2 --protocol " + k.protocol +
                          " --drop-link-after-blocks 120 --down-s 1 " + k.sim_flags);
    const auto r =
        ncd("stream " + prog + " --port " + link_ +
            " --baud 38400 --frame 7E2 -q --no-journal --reconnect-max 5 --protocol " + k.protocol +
            " " + k.stream_flags + " --report " + (dir_ / "r.json").string());
    EXPECT_EQ(r.status, k.status) << r.out << r.err;
    const auto log = k.status == 0 ? controller_log(*cnc) : stopped_log(*cnc);
    EXPECT_EQ(log["link_drops"], 1);
    const auto ran = executed(log);
    const auto blocks = blocks_of(prog);
    const std::size_t n = ran_prefix(ran, blocks);
    const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
    std::cout << "[ measured ] link cut, " << k.protocol << " " << k.sim_flags
              << ": the controller executed blocks 1-" << n << " of " << blocks.size()
              << " in order, each once (" << ran.size() << " executions)\n";
    if (k.status == 0) {
      EXPECT_EQ(n, blocks.size());
      EXPECT_EQ(log["program_sha256"], sha);
      EXPECT_EQ(rep["transfer"]["reconnects"], 1);
    } else {
      EXPECT_TRUE(rep["transfer"]["interrupted"].get<bool>());
      EXPECT_EQ(rep["transfer"]["reconnects"], 0);
      EXPECT_NE(r.out.find("run twice"), std::string::npos) << r.out;
      // Drip knows what it wrote, not what arrived (the cut loses the bytes in flight): the
      // controller cannot have run a block ncd had not written.
      EXPECT_GE(rep["transfer"]["blocks_sent"].get<std::size_t>(), n);
      EXPECT_FALSE(rep["transfer"]["first_block_not_sent"].is_null());
      EXPECT_TRUE(rep["transfer"]["blocks_executed"].is_null());
    }
  }
}

// A link cut while grbl is moving with a full planner: on reconnecting ncd holds it (`!`), finds
// the move under way from the position, counts the moves its planner holds (Bf:), resends only
// what the cut lost, and resumes (`~`).
TEST_F(Stream, AckLinkCutWhileMovingResumesFromTheHeldPosition) {
  const std::string prog = write("slow.ngc", slow_program(80));
  auto cnc = controller(
      "--baud 115200 --frame 8N1 --protocol ack --drop-link-after-blocks 40 "
      "--down-s 0.5");
  const auto r = ncd("stream " + prog + " --port " + link_ +
                     " --baud 115200 --frame 8N1 --protocol ack -q --no-journal --banner-wait 0.3 "
                     "--reconnect-max 5 --report " +
                     (dir_ / "r.json").string());
  EXPECT_EQ(r.status, 0) << r.out << r.err;
  const auto log = controller_log(*cnc);
  EXPECT_EQ(log["link_drops"], 1);
  EXPECT_EQ(log["feed_holds"], 1);
  EXPECT_EQ(log["cycle_starts"], 1);  // it was held mid-move, then resumed
  const auto ran = executed(log);
  const auto blocks = blocks_of(prog);
  EXPECT_EQ(ran, blocks);  // every block once, in order
  const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
  EXPECT_EQ(rep["transfer"]["reconnects"], 1);
  std::cout << "[ measured ] link cut while moving: " << ran.size() << " of " << blocks.size()
            << " blocks executed once each; " << rep["blocks_resent"] << " resent\n";
}

// A link cut in the middle of a line, with `;` comments in the program. grbl keeps a half line
// in its line buffer and the next bytes complete it, from whatever connection: a line end alone
// would run "N50 G1 X2" for "N50 G1 X24.118 …", and a resent block would merge with it. ncd
// first sends "))" and a line end, which grbl refuses whole (error:1) unless the half line was
// inside its `;` comment, its code whole: then grbl queues that block (ok), and ncd must not
// send it again. The cut lands (1) in the number after X, (2) inside the comment. Either way the
// controller runs every block once, in order, and never a cut one.
TEST_F(Stream, AckHalfLineAfterACutNeverMergesWithTheNextBlock) {
  std::string text = "(ncd half-line test)\n";
  double x = 0.0;
  for (int i = 1; i <= 120; ++i) {
    x += 0.2 + 0.001 * (i % 7);
    char line[96];
    std::snprintf(line, sizeof line, "N%d G1 X%.3f Y%.3f F20000 ; pass %d", i, x, 0.1 * (i % 3), i);
    text += std::string(line) + "\n";
  }
  text += "M2\n";
  const std::string prog = write("half.ngc", text);
  const auto blocks = blocks_of(prog);
  const std::string cut_block = blocks[50];  // N50
  const std::size_t at = text.find(cut_block);
  struct Case {
    std::string where;
    std::size_t offset;  // in the block
    std::string reply;   // grbl's answer to the half line and the flush
  };
  for (const Case& k : {Case{"in X's number", cut_block.find('X') + 3, "error"},
                        Case{"in the ; comment", cut_block.find(';') + 3, "ok"}}) {
    SCOPED_TRACE(k.where);
    // The wake-up line "))\n" (3 characters: this controller sends no banner) comes first.
    const std::size_t chars = 3 + at + k.offset;
    auto cnc = controller(
        "--baud 115200 --frame 8N1 --protocol ack --down-s 0.5 "
        "--drop-link-after-chars " +
        std::to_string(chars));
    const auto r = ncd("stream " + prog + " --port " + link_ +
                       " --baud 115200 --frame 8N1 --protocol ack -q --no-journal "
                       "--banner-wait 0.3 --reconnect-max 5 --report " +
                       (dir_ / "r.json").string());
    EXPECT_EQ(r.status, 0) << r.out << r.err;
    const auto log = controller_log(*cnc);
    EXPECT_EQ(log["link_drops"], 1);
    // Every block once, in order, none cut short. What grbl runs of a line is its code: the
    // half line completed inside its comment is logged with the flush after the `;`.
    const auto code = [](std::vector<std::string> lines) {
      for (auto& l : lines) l = l.substr(0, l.find(';'));
      return lines;
    };
    EXPECT_EQ(code(executed(log)), code(blocks));
    // The half line the cut left, completed by the flush.
    const std::string half = cut_block.substr(0, k.offset) + "))";
    bool refused = false;
    for (const auto& e : log["errors"]) refused = refused || e["text"] == half;
    EXPECT_EQ(refused, k.reply == "error") << log["errors"];
    const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
    EXPECT_EQ(rep["transfer"]["reconnects"], 1);
    std::cout << "[ measured ] cut " << k.where << " of " << cut_block << ": '" << half
              << "' answered " << k.reply << "; the controller executed " << executed(log).size()
              << " of " << blocks.size() << " blocks, each once\n";
  }
}

// A controller reset mid-program (power cycle, watchdog): the job is interrupted, names the
// last block known executed and the first not known executed, and never resumes past it. What
// ncd can know is what the last status report before the reset said; the controller logs how
// many blocks it had executed when it sent that report (resets[].executed_at_last_report).
TEST_F(Stream, ControllerResetInterruptsNamingTheBlocks) {
  for (const std::string protocol : {"ack", "drip"}) {
    SCOPED_TRACE(protocol);
    const std::string prog = write("slow.ngc", slow_program(80));
    auto cnc = controller("--baud 115200 --frame 8N1 --reset-after-blocks 40 --protocol " +
                          protocol + (protocol == "drip" ? " --buffer 1024" : ""));
    const auto r = ncd("stream " + prog + " --port " + link_ +
                       " --baud 115200 --frame 8N1 -q --no-journal --banner-wait 0.3 --protocol " +
                       protocol + " --report " + (dir_ / "r.json").string());
    EXPECT_EQ(r.status, 3) << r.err;
    if (protocol == "ack") wait_for_event("reset (soft_reset)");
    const auto log = stopped_log(*cnc);
    ASSERT_EQ(log["resets"].size(), protocol == "ack" ? 2U : 1U);  // the fault, then ncd's 0x18
    const auto ran = executed(log);
    const auto blocks = blocks_of(prog);
    const std::size_t n = ran_prefix(ran, blocks);
    EXPECT_LT(n, blocks.size());
    const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
    EXPECT_TRUE(rep["transfer"]["interrupted"].get<bool>());
    const auto first = rep["transfer"]["first_block_not_known_executed"].get<std::size_t>();
    const auto& at_report = log["resets"][0]["executed_at_last_report"];
    std::cout << "[ measured ] " << protocol << " reset: the controller executed blocks 1-" << n
              << " of " << blocks.size() << " (" << at_report
              << " when it sent its last status report); ncd: first block not known executed "
              << first << "\n";
    // Everything before the block ncd names was executed; nothing after the reset ran. Drip
    // knows no executed block: it names block 1, and says so.
    EXPECT_LE(first, n + 1);
    if (protocol == "drip") {
      EXPECT_EQ(first, 1U);
      EXPECT_TRUE(rep["transfer"]["blocks_executed"].is_null());
      EXPECT_NE(r.out.find("not known"), std::string::npos) << r.out;
    } else {
      // ncd knows what the last status report before the reset told: how far that report lags
      // the reset depends on the scheduler (a status period of 0.2 s is 2 moves, more on a
      // loaded machine), so the bound is the report's, not the reset's. The inference from a
      // report (Bf, the position) may be a block short where a move is just ending.
      ASSERT_TRUE(at_report.is_number()) << "no status report before the reset";
      const auto reported = at_report.get<std::size_t>();
      EXPECT_LE(first, reported + 1);
      EXPECT_GE(first + 1, reported + 1);
      EXPECT_GE(reported, 1U);  // ncd asked while the moves ran (every 0.2 s; 19 moves take 2 s)
      EXPECT_NE(r.out.find("--restart-from " + std::to_string(first)), std::string::npos) << r.out;
    }
  }
}

// An error reply: the sender holds and resets grbl, so no block queued after the bad one runs.
TEST_F(Stream, ErrorReplyLeavesNoLaterBlockExecuted) {
  std::string text = slow_program(60);
  const auto at = text.find("N300 ");
  text.insert(at, "N295 G91 X1\n");  // grbl (and the simulation) refuse G91 here: error:20
  const std::string prog = write("bad.ngc", text);
  auto cnc = controller("--baud 115200 --frame 8N1 --protocol ack");
  const auto r = ncd("stream " + prog + " --port " + link_ +
                     " --baud 115200 --frame 8N1 --protocol ack -q --no-journal --banner-wait 0.3 "
                     "--report " +
                     (dir_ / "r.json").string());
  EXPECT_EQ(r.status, 3) << r.err;
  EXPECT_NE(r.out.find("error:20"), std::string::npos) << r.out;
  wait_for_event("reset (soft_reset)");
  const auto log = stopped_log(*cnc);
  const auto ran = executed(log);
  const auto blocks = blocks_of(prog);
  const auto bad = static_cast<std::size_t>(std::find(blocks.begin(), blocks.end(), "N295 G91 X1") -
                                            blocks.begin());
  EXPECT_LT(ran_prefix(ran, blocks), bad);  // nothing at or after the bad block ran
  EXPECT_GE(log["feed_holds"].get<int>(), 1);
  ASSERT_FALSE(log["resets"].empty());
  EXPECT_EQ(log["resets"][0]["cause"], "soft_reset");
  const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
  EXPECT_NE(rep["transfer"]["dropped"].get<std::string>().find("queued"), std::string::npos)
      << rep["transfer"];
  std::cout << "[ measured ] error reply at block " << bad + 1 << ": the controller executed "
            << ran.size() << " blocks; dropped: " << rep["transfer"]["dropped"] << "\n";
}

// An error reply mid-program, as the issue met it on grbl 1.1h: ncd must bring grbl to a safe
// halt. It holds (`!`), waits until the status says the hold is complete (Hold:0: the
// deceleration at 100 mm/s² takes 0.1 s at 600 mm/min) and only then resets (0x18), so grbl
// raises no ALARM:3 and is left Idle, unlocked. The rejected block is neither queued nor
// credited with the oks that come while stopping. The advice, followed as printed once the bad
// block is fixed, sends the rest: each block from the advised one on runs once.
TEST_F(Stream, AckErrorReplyHaltsWithoutAlarmAndTheAdviceWorks) {
  std::string text = slow_program(60);
  const std::string bad_line = "N295 G91 X1";
  text.insert(text.find("N300 "), bad_line + "\n");  // grbl refuses G91 here: error:20
  const std::string prog = write("bad.ngc", text);
  const auto blocks_bad = blocks_of(prog);
  const auto bad = static_cast<std::size_t>(
      std::find(blocks_bad.begin(), blocks_bad.end(), bad_line) - blocks_bad.begin());
  auto cnc = controller("--baud 115200 --frame 8N1 --protocol ack");
  const std::string line = " --baud 115200 --frame 8N1 --protocol ack --banner-wait 0.3";
  const auto r = ncd("stream " + prog + " --port " + link_ + line + " -q --report " +
                     (dir_ / "r.json").string());
  EXPECT_EQ(r.status, 3) << r.err;
  EXPECT_NE(r.out.find("error:20"), std::string::npos) << r.out;
  wait_for_event("reset (soft_reset)");
  EXPECT_EQ(slurp(dir_ / "cnc.err").find("ALARM:3"), std::string::npos) << slurp(dir_ / "cnc.err");
  const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
  EXPECT_EQ(rep["transfer"]["controller_state"], "Idle") << rep["transfer"];
  EXPECT_EQ(rep["transfer"]["rejected_block"], bad + 1);
  const std::string dropped = rep["transfer"]["dropped"].get<std::string>();
  EXPECT_NE(dropped.find("block " + std::to_string(bad + 1) + " was refused"), std::string::npos)
      << dropped;
  EXPECT_EQ(dropped.find("-" + std::to_string(bad + 1) + " "), std::string::npos) << dropped;
  const std::string next = advised(r.out);
  ASSERT_NE(next.find("--restart-from "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("fix block " + std::to_string(bad + 1)), std::string::npos) << r.out;
  const std::size_t k = std::stoul(next.substr(next.find("--restart-from ") + 15));
  EXPECT_LE(k, bad + 1);
  // The operator fixes the block and follows the advice.
  text.replace(text.find(bad_line), bad_line.size(), "N295 G1 X29.5 Y0.5 F600");
  write("bad.ngc", text);
  const auto again = ncd("stream " + prog + " --port " + link_ + line + " -q " + next);
  EXPECT_EQ(again.status, 0) << again.out << again.err;
  const auto log = controller_log(*cnc);
  EXPECT_TRUE(log["alarms"].empty()) << log["alarms"];
  ASSERT_GE(log["resets"].size(), 1U);
  EXPECT_EQ(log["resets"][0]["cause"], "soft_reset");
  EXPECT_FALSE(log["resets"][0]["in_motion"].get<bool>()) << log["resets"][0];
  const std::size_t first_run = check_restart_log(executed(log), blocks_of(prog), k);
  EXPECT_GE(first_run + 1, k);  // nothing skipped: the first run reached the advised block
  EXPECT_LT(first_run, bad);    // and nothing at or after the bad block ran in it
  std::cout << "[ measured ] error:20 at block " << bad + 1 << ": grbl ran blocks 1-" << first_run
            << ", was halted without alarm; ncd advised " << next << "\n";
}

// A reset while grbl moves (injected here) raises ALARM:3 and locks it: every line is error:9
// until `$X`. ncd's advice then includes --unlock (which sends `$X` at start-up, after the
// operator has checked the machine), and following it works. Without it, ncd sends nothing and
// says so, instead of failing with error:9 and advising the same again.
TEST_F(Stream, AckAlarm3AdviceUnlocksAndTheRestartWorks) {
  const std::string prog = write("slow.ngc", slow_program(80));
  auto cnc = controller("--baud 115200 --frame 8N1 --protocol ack --reset-after-blocks 40");
  const std::string line = " --baud 115200 --frame 8N1 --protocol ack --banner-wait 0.3 -q";
  const auto r = ncd("stream " + prog + " --port " + link_ + line + " --no-journal");
  EXPECT_EQ(r.status, 3) << r.err;
  const std::string next = advised(r.out);
  EXPECT_NE(next.find("--unlock"), std::string::npos) << r.out;
  ASSERT_NE(next.find("--restart-from "), std::string::npos) << r.out;
  const std::size_t k = std::stoul(next.substr(next.find("--restart-from ") + 15));
  // The restart without the unlock: refused at start-up, nothing sent, the advice repeated.
  const std::string restart = next.substr(next.find("--restart-from "));
  const auto locked =
      ncd("stream " + prog + " --port " + link_ + line + " --no-journal " + restart);
  EXPECT_EQ(locked.status, 3) << locked.out;
  EXPECT_NE(advised(locked.out).find("--unlock"), std::string::npos) << locked.out;
  EXPECT_EQ(locked.out.find("rejected"), std::string::npos) << locked.out;  // no line was sent
  const auto again = ncd("stream " + prog + " --port " + link_ + line + " --no-journal " + next);
  EXPECT_EQ(again.status, 0) << again.out << again.err;
  const auto log = controller_log(*cnc);
  EXPECT_EQ(log["unlocks"], 1);
  ASSERT_GE(log["resets"].size(), 1U);
  EXPECT_TRUE(log["resets"][0]["in_motion"].get<bool>());
  for (const auto& e : log["errors"]) {  // after the reset in motion, lines met the lock
    if (e["t_s"].get<double>() > log["resets"][0]["t_s"].get<double>()) {
      EXPECT_EQ(e["code"], 9) << e;
    }
  }
  const std::size_t first_run = check_restart_log(executed(log), blocks_of(prog), k);
  EXPECT_GE(first_run + 1, k);
  std::cout << "[ measured ] ALARM:3 after block " << first_run << " ran; ncd advised " << next
            << "\n";
}

// The controller restarts (a power-up) while its USB link is gone; its banner is sent while the
// port is closed, so ncd never sees it. On reconnecting ncd holds it and reads its status: the
// spindle stopped though the program has it turning (and the position back at 0) tells a
// reset, not a cut. ncd does not resume, and does not leave the controller held (grbl would
// then read no line and the next run could not wake it): it completes the hold and resets it.
// The advice works as printed.
TEST_F(Stream, AckUnseenRestartIsToldAndTheControllerIsNotLeftHeld) {
  const std::string prog = write("slow.ngc", slow_program(80));
  auto cnc =
      controller("--baud 115200 --frame 8N1 --protocol ack --restart-after-blocks 40 --down-s 0.5");
  const std::string line = " --baud 115200 --frame 8N1 --protocol ack --banner-wait 0.3 -q";
  const auto r = ncd("stream " + prog + " --port " + link_ + line +
                     " --no-journal --reconnect-max 5 --report " + (dir_ / "r.json").string());
  EXPECT_EQ(r.status, 3) << r.out << r.err;
  EXPECT_NE(r.out.find("spindle"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("reset"), std::string::npos) << r.out;
  const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
  EXPECT_EQ(rep["transfer"]["controller_state"], "Idle") << rep["transfer"];
  EXPECT_EQ(rep["transfer"]["reconnects"], 0);
  const std::string next = advised(r.out);
  ASSERT_NE(next.find("--restart-from "), std::string::npos) << r.out;
  const std::size_t k = std::stoul(next.substr(next.find("--restart-from ") + 15));
  const auto again = ncd("stream " + prog + " --port " + link_ + line + " --no-journal " + next);
  EXPECT_EQ(again.status, 0) << again.out << again.err;
  const auto log = controller_log(*cnc);
  EXPECT_EQ(log["banners_lost"], 1);
  ASSERT_GE(log["resets"].size(), 2U);
  EXPECT_EQ(log["resets"][0]["cause"], "power_cycle");
  EXPECT_EQ(log["resets"][1]["cause"], "soft_reset");  // ncd's, from a complete hold
  EXPECT_FALSE(log["resets"][1]["in_motion"].get<bool>());
  EXPECT_EQ(log["cycle_starts"], 0);  // never resumed past the restart
  EXPECT_TRUE(log["alarms"].empty()) << log["alarms"];
  const std::size_t first_run = check_restart_log(executed(log), blocks_of(prog), k);
  EXPECT_GE(first_run + 1, k);
}

// ncd is killed mid-program: grbl runs on through its queue and stops. The journal's first block
// not known executed lags the machine by up to the queue (15 blocks and the receive buffer); on
// the next run ncd reads grbl's position (Idle, the end point of exactly one block sent) and
// advises a restart from the block after it, the first the machine's position says is not
// done. --resume, refused for grbl, is not advised. Following the advice sends each remaining
// block once.
TEST_F(Stream, AckKilledSenderIsAdvisedTheBlockThePositionProves) {
  const std::string prog = write("slow.ngc", slow_program(80));
  const std::string journal = prog + ".journal";
  auto cnc = controller("--baud 115200 --frame 8N1 --protocol ack");
  const std::string line = " --baud 115200 --frame 8N1 --protocol ack --banner-wait 0.3";
  {
    Process sender({NCD_EXE, "stream", prog, "--port", link_, "--baud", "115200", "--frame", "8N1",
                    "--protocol", "ack", "--banner-wait", "0.3"},
                   (dir_ / "s1.out").string(), (dir_ / "s1.err").string());
    wait_journal(journal, 20);
    ASSERT_TRUE(sender.running()) << slurp(dir_ / "s1.err");
    sender.signal(SIGKILL);
    sender.wait(5.0);
  }
  const auto at_kill = comms::TransferJournal::read(journal);
  ASSERT_TRUE(at_kill);
  const auto r = ncd("stream " + prog + " --port " + link_ + line + " -q");
  EXPECT_EQ(r.status, 2) << r.out << r.err;
  const std::string next = advised(r.err);
  EXPECT_EQ(next.find("--resume"), std::string::npos) << r.err;
  ASSERT_NE(next.find("--restart-from "), std::string::npos) << r.err;
  const std::size_t k = std::stoul(next.substr(next.find("--restart-from ") + 15));
  // --resume is refused for grbl, with the same advice.
  const auto resume = ncd("stream " + prog + " --port " + link_ + line + " -q --resume");
  EXPECT_EQ(resume.status, 2) << resume.err;
  EXPECT_EQ(advised(resume.err), next) << resume.err;
  const auto again = ncd("stream " + prog + " --port " + link_ + line + " -q " + next);
  EXPECT_EQ(again.status, 0) << again.out << again.err;
  const auto log = controller_log(*cnc);
  const std::size_t first_run = check_restart_log(executed(log), blocks_of(prog), k);
  EXPECT_EQ(first_run + 1, k) << "the advised block is the first the machine had not run";
  EXPECT_GT(k, static_cast<std::size_t>(at_kill->confirmed + 1));  // past the journal's point
  std::cout << "[ measured ] killed: the journal's first block not known executed was "
            << at_kill->confirmed + 1 << "; grbl ran on to block " << first_run << "; ncd advised "
            << next << "\n";
}

// Ctrl-C on ncd stream to grbl: ncd brings grbl to a safe halt (hold, Hold:0, reset: no alarm,
// nothing queued runs on) and advises the restart from the first block not executed, not
// --resume, which grbl cannot take.
TEST_F(Stream, AckCtrlCHaltsTheControllerAndAdvisesARestart) {
  const std::string prog = write("slow.ngc", slow_program(80));
  const std::string journal = prog + ".journal";
  auto cnc = controller("--baud 115200 --frame 8N1 --protocol ack");
  const std::string line = " --baud 115200 --frame 8N1 --protocol ack --banner-wait 0.3";
  std::string out;
  {
    Process sender({NCD_EXE, "stream", prog, "--port", link_, "--baud", "115200", "--frame", "8N1",
                    "--protocol", "ack", "--banner-wait", "0.3", "-q"},
                   (dir_ / "s1.out").string(), (dir_ / "s1.err").string());
    wait_journal(journal, 20);
    sender.signal(SIGINT);
    EXPECT_EQ(sender.wait(20.0), 3) << slurp(dir_ / "s1.err");
    out = slurp(dir_ / "s1.out");
  }
  EXPECT_EQ(out.find("--resume"), std::string::npos) << out;
  const std::string next = advised(out);
  ASSERT_NE(next.find("--restart-from "), std::string::npos) << out;
  const std::size_t k = std::stoul(next.substr(next.find("--restart-from ") + 15));
  wait_for_event("reset (soft_reset)");
  const auto again = ncd("stream " + prog + " --port " + link_ + line + " -q " + next);
  EXPECT_EQ(again.status, 0) << again.out << again.err;
  const auto log = controller_log(*cnc);
  EXPECT_TRUE(log["alarms"].empty()) << log["alarms"];
  ASSERT_GE(log["resets"].size(), 1U);
  EXPECT_FALSE(log["resets"][0]["in_motion"].get<bool>()) << log["resets"][0];
  const std::size_t first_run = check_restart_log(executed(log), blocks_of(prog), k);
  // Held at rest, the position tells exactly: the advised block is the one the hold stopped in.
  EXPECT_EQ(first_run + 1, k);
}

// grbl's factory status mask ($10=1) has no Bf: field. ncd then knows executed blocks from the
// position and the Idle state only, and says so: not "by Bf".
TEST_F(Stream, AckWithoutBfSaysHowExecutedIsKnown) {
  std::string sha;
  const std::string prog = program(60, 20000, &sha);
  auto cnc = controller("--baud 115200 --frame 8N1 --protocol ack --status-mask 1");
  const auto r = ncd("stream " + prog + " --port " + link_ +
                     " --baud 115200 --frame 8N1 --protocol ack -q --no-journal --banner-wait 0.3");
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.out.find("by Bf"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("executed (by position"), std::string::npos) << r.out;
  const auto log = controller_log(*cnc);
  EXPECT_EQ(log["program_sha256"], sha);
}

// Restart from block N: the modal state at N, up to the clearance plane, over N's start, down
// at feed, then N onwards, each exactly once.
TEST_F(Stream, RestartFromNRunsEachBlockOnceThroughTheClearancePlane) {
  for (const std::string protocol : {"ack", "drip"}) {
    SCOPED_TRACE(protocol);
    const std::string prog = write("slow.ngc", slow_program(40));
    const auto blocks = blocks_of(prog);
    const std::size_t n = 30;  // "N240 G1 X24 Y0.0 F600", its start is N230's end (23, 0.5, -1)
    auto cnc = controller("--baud 115200 --frame 8N1 --rapid 20000 --protocol " + protocol);
    const auto r = ncd("stream " + prog + " --port " + link_ +
                       " --baud 115200 --frame 8N1 -q --no-journal --banner-wait 0.3 --protocol " +
                       protocol + " --restart-from " + std::to_string(n));
    EXPECT_EQ(r.status, 0) << r.out << r.err;
    const auto log = controller_log(*cnc);
    const auto ran = executed(log);
    // The program's blocks from N, once each, in order, after the restart lines.
    const std::vector<std::string> tail(blocks.begin() + static_cast<long>(n) - 1, blocks.end());
    ASSERT_GE(ran.size(), tail.size());
    EXPECT_EQ(std::vector<std::string>(ran.end() - static_cast<long>(tail.size()), ran.end()),
              tail);
    // Before them only ncd's restart lines (which repeat setup blocks such as "G0 Z5"), none
    // of the program's numbered moves.
    EXPECT_LE(ran.size() - tail.size(), 10U);
    for (std::size_t i = 0; i + tail.size() < ran.size(); ++i) {
      EXPECT_NE(ran[i][0], 'N') << "a numbered block before N ran: " << ran[i];
    }
    // The re-entry moves: up to Z5 (the highest Z before N), over (23, 0.5), down to Z-1 at F600.
    const auto& moves = log["moves"];
    std::size_t k = 0;
    while (k < moves.size() && moves[k]["p"][2].get<double>() != 5.0) ++k;
    ASSERT_LT(k + 3, moves.size());
    EXPECT_EQ(moves[k + 1]["p"], nlohmann::json::array({23.0, 0.5, 5.0}));
    EXPECT_EQ(moves[k + 2]["p"], nlohmann::json::array({23.0, 0.5, -1.0}));
    EXPECT_EQ(moves[k + 2]["feed_mm_per_min"], 600.0);
    EXPECT_EQ(moves[k + 2]["g"], 1);
    EXPECT_EQ(moves[k + 3]["n"], 240);
  }
}

TEST_F(Stream, KilledSenderResumesFromItsJournal) {
  std::string sha;
  const std::string prog = program(500, 20000, &sha);
  auto cnc = controller("--baud 9600 --frame 7E2 --skip-duplicate-n");
  {
    Process sender({NCD_EXE, "stream", prog, "--port", link_, "--baud", "9600", "--frame", "7E2"},
                   (dir_ / "s1.out").string(), (dir_ / "s1.err").string());
    // Killed once its journal confirms more than 55 blocks (about 3 s at 9600 baud; a loaded
    // host starts the sender later, so the journal is asked rather than the clock).
    std::int64_t confirmed = 0;
    for (int i = 0; i < 3000 && confirmed <= 55 && sender.running(); ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      const auto j = comms::TransferJournal::read(prog + ".journal");
      if (j) confirmed = j->confirmed;
    }
    ASSERT_GT(confirmed, 55) << slurp(dir_ / "s1.err");
    ASSERT_TRUE(sender.running()) << slurp(dir_ / "s1.err");
    sender.signal(SIGKILL);
    sender.wait(5.0);
  }
  ASSERT_TRUE(fs::exists(prog + ".journal"));
  const auto again = ncd("stream " + prog + " --port " + link_ + " --baud 9600 --frame 7E2 -q");
  EXPECT_EQ(again.status, 2) << again.err;  // an unfinished transfer needs --resume or --restart
  EXPECT_NE(again.err.find("--resume"), std::string::npos) << again.err;
  const auto unsafe =
      ncd("stream " + prog + " --port " + link_ + " --baud 9600 --frame 7E2 --resume");
  EXPECT_EQ(unsafe.status, 2) << unsafe.err;  // a controller that runs repeats: not resumed
  EXPECT_NE(unsafe.err.find("--controller-skips-repeated-n"), std::string::npos) << unsafe.err;
  const auto r = ncd("stream " + prog + " --port " + link_ +
                     " --baud 9600 --frame 7E2 --resume --controller-skips-repeated-n --report " +
                     (dir_ / "r.json").string());
  EXPECT_EQ(r.status, 0) << r.err;
  const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
  EXPECT_GT(rep["first_block"].get<int>(), 50);
  const auto log = controller_log(*cnc);
  EXPECT_EQ(log["program_sha256"], sha);
  EXPECT_EQ(log["blocks_received"], 502);
  EXPECT_FALSE(fs::exists(prog + ".journal"));
}

TEST_F(Stream, NoiseFromTheControllerIsSurvived) {
  for (const std::string protocol : {"drip", "ack"}) {
    SCOPED_TRACE(protocol);
    std::string sha;
    const std::string prog = program(300, 20000, &sha);
    auto cnc =
        controller("--baud 38400 --frame 8N1 --noise-bytes-per-s 200 --protocol " + protocol);
    const auto r = ncd("stream " + prog + " --port " + link_ + " --baud 38400 --frame 8N1 -q" +
                       " --banner-wait 0.3 --protocol " + protocol + " --report " +
                       (dir_ / "r.json").string());
    EXPECT_EQ(r.status, 0) << r.err;
    const auto log = controller_log(*cnc);
    EXPECT_EQ(log["program_sha256"], sha);
    EXPECT_GT(log["noise_bytes_sent"].get<int>(), 0);
    const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
    EXPECT_GT(rep["noise_bytes"].get<int>(), 0);
  }
}

TEST_F(Stream, ControllerAlarmStopsTheTransfer) {
  std::string sha;
  const std::string prog = program(300, 20000, &sha);
  auto cnc = controller("--baud 38400 --alarm-after-blocks 40");
  const auto r = ncd("stream " + prog + " --port " + link_ + " --baud 38400 -q");
  EXPECT_EQ(r.status, 3) << r.err;
  EXPECT_NE(r.out.find("NAK"), std::string::npos) << r.out;
  cnc->signal(SIGTERM);
  cnc->wait(5.0);
}

TEST_F(Stream, BadInputExitsTwoAndSendsNothing) {
  std::string sha;
  const std::string prog = program(10, 1000, &sha);
  EXPECT_EQ(ncd("stream " + prog + " --port /dev/null --frame 9X1").status, 2);
  EXPECT_EQ(ncd("stream " + prog + " --port /dev/null --baud 12345").status, 2);
  EXPECT_EQ(ncd("stream " + prog + " --port /dev/null --flow maybe").status, 2);
  EXPECT_EQ(ncd("stream " + (dir_ / "missing.ngc").string() + " --port /dev/null").status, 2);
  const std::string bad = write("bad.ngc", "N1G1X1\nN2G1X\xe9\n");
  const auto r = ncd("stream " + bad + " --port /dev/null --frame 7E2");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("bad.ngc:2"), std::string::npos) << r.err;
  // A port that does not exist fails at once (no reconnect attempts); a file is no port.
  const auto gone =
      ncd("stream " + prog + " --port " + (dir_ / "nothing").string() + " --reconnect-max 30 -q");
  EXPECT_EQ(gone.status, 2) << gone.err;
  EXPECT_NE(gone.err.find("no such file"), std::string::npos) << gone.err;
  for (const std::string& port : {std::string("/dev/null"), write("hole.json", "{}")}) {
    const auto not_tty = ncd("stream " + prog + " --port " + port + " -q");
    EXPECT_EQ(not_tty.status, 2) << port << ": " << not_tty.err;
    EXPECT_NE(not_tty.err.find("not a serial port"), std::string::npos) << not_tty.err;
  }
}

// The whole program of a job, written for a grbl machine ([link] dialect = "grbl"): the
// simulated controller in grbl mode answers `ok` to every line, executes the spindle before the
// first cut and the program end, with no alarm (issue: a whole, safe program in the controller's
// own dialect). A short job (a 2 mm square, at the feed the roughness target allows) keeps the
// real-time run brief.
TEST_F(Stream, WholeJobForAGrblMachineIsTakenLineByLineAndExecuted) {
  std::string machine = slurp(std::string(NCD_SOURCE_DIR) + "/config/chamfer-exp3.toml");
  const std::string iso = "dialect = \"iso\"";
  ASSERT_NE(machine.find(iso), std::string::npos);
  machine.replace(machine.find(iso), iso.size(), "dialect = \"grbl\"");
  const std::string m = write("grbl.toml", machine);
  const std::string path =
      write("square.json",
            R"({"polyline": {"points": [[0,0,0],[2,0,0],[2,2,0],[0,2,0],[0,0,0]]},
          "feed_mm_per_min": 3000})");
  const std::string blocks = (dir_ / "square.ngc").string();
  const auto r = ncd("replay " + path + " --machine " + m + " -q --blocks " + blocks);
  ASSERT_EQ(r.status, 0) << r.err;
  auto cnc = controller(
      "--baud 115200 --frame 8N1 --protocol ack --dialect grbl --reset-on-open --boot-s 0.2");
  const auto s = ncd("stream " + blocks + " --port " + link_ +
                     " --baud 115200 --frame 8N1 --protocol ack --dialect grbl -q --no-journal "
                     "--banner-wait 3");
  EXPECT_EQ(s.status, 0) << s.err << s.out;
  const auto log = controller_log(*cnc);
  EXPECT_TRUE(log["errors"].empty()) << log["errors"].dump();
  EXPECT_TRUE(log["alarms"].empty()) << log["alarms"].dump();
  EXPECT_TRUE(log["program_end_executed"].get<bool>());
  // Every block of the program executed, once, in order.
  EXPECT_EQ(executed(log), blocks_of(blocks));
  std::vector<std::string> kinds;
  for (const auto& e : log["events"]) kinds.push_back(e["kind"].get<std::string>());
  const auto at = [&](const std::string& k) {
    return std::find(kinds.begin(), kinds.end(), k) - kinds.begin();
  };
  ASSERT_LT(at("spindle_cw"), static_cast<long>(kinds.size())) << log["events"].dump();
  EXPECT_LT(at("spindle_cw"), at("spindle_stop"));
  EXPECT_LT(at("spindle_stop"), at("program_end"));
  EXPECT_EQ(at("tool_change"), static_cast<long>(kinds.size())) << "grbl has no M6";
}

}  // namespace
}  // namespace ncd::test
