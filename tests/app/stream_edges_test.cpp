// The rough edges of `ncd stream` from issue 33, each against a real pseudo-terminal:
// - after Ctrl-C (and on a second run over the journal, with or without --resume) the advice
//   is one command line; run as printed, it is accepted and completes the job, each numbered
//   block reaching the controller once;
// - a line on which nothing ever answers (a pty the test only reads) ends with a WARNING and
//   exit 4, not "done" and 0;
// - the link use is a fraction of the line, bytes carried · bits per character over baud ·
//   duration, also for a transfer stopped at once (which used to count bytes still in flight);
// - holds the program explains (two 6 s tool changes) raise no hold warning at the default
//   5 s, and a stall with no such block still does.
#include <gtest/gtest.h>
#include <poll.h>
#include <unistd.h>

#include <atomic>
#include <nlohmann/json.hpp>
#include <thread>

#include "link/pty.hpp"
#include "link/transfer_journal.hpp"
#include "tests/app/cli_fixture.hpp"
#include "tests/app/sim_controller_fixture.hpp"
#include "tests/common/process.hpp"

namespace ncd::test {
namespace {

class StreamEdges : public SimControllerCli {
 protected:
  // The command after "run: " at the start of a line of the advice, or "".
  static std::string run_line(const std::string& text) {
    std::istringstream in(text);
    for (std::string l; std::getline(in, l);) {
      if (l.rfind("run: ", 0) == 0) return l.substr(5);
    }
    return "";
  }

  // Runs a command line as the shell would, in the test's folder.
  CmdResult shell(const std::string& cmd) {
    const fs::path out = dir_ / "stdout", err = dir_ / "stderr";
    const int raw = std::system(
        ("cd " + dir_.string() + " && " + cmd + " >" + out.string() + " 2>" + err.string())
            .c_str());
    CmdResult r;
    r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    r.out = slurp(out);
    r.err = slurp(err);
    return r;
  }
};

// Slow numbered moves (0.1 s each at F600), framed by a start and an end without N.
std::string edge_slow_program(int moves) {
  std::string text = "G21 G90 G94\nG0 Z5\nS1000 M3\nG0 X0 Y0\nG1 Z-1 F600\n";
  for (int i = 1; i <= moves; ++i) {
    text += "N" + std::to_string(i * 10) + " G1 X" + std::to_string(i) + " Y" +
            (i % 2 ? "0.5" : "0.0") + " F600\n";
  }
  return text + "G0 Z5\nM5\nM2\n";
}

std::vector<std::string> numbered(const nlohmann::json& log) {
  std::vector<std::string> out;
  for (const auto& e : log["executed"]) {
    const std::string t = e["text"].get<std::string>();
    if (!t.empty() && t[0] == 'N') out.push_back(t);
  }
  return out;
}

// Ctrl-C on a drip transfer: the block begun is finished, the controller has whole blocks, and
// the advice is a command with the exact first block not sent. A second run, with or without
// --resume, refuses with the same command; run as printed, it completes the job and every
// numbered block ran exactly once, in order.
TEST_F(StreamEdges, DripCtrlCAdvisesOneCommandThatCompletesTheJob) {
  const std::string prog = write("slow.ngc", edge_slow_program(60));
  const std::string journal = prog + ".journal";
  auto cnc = controller("--baud 9600 --dialect iso");
  std::string out;
  {
    Process sender({NCD_EXE, "stream", prog, "--port", link_, "--baud", "9600"},
                   (dir_ / "s1.out").string(), (dir_ / "s1.err").string());
    wait_journal(journal, 15);
    sender.signal(SIGINT);
    EXPECT_EQ(sender.wait(20.0), 3) << slurp(dir_ / "s1.err");
    out = slurp(dir_ / "s1.out");
  }
  const std::string advised = run_line(out);
  ASSERT_NE(advised.find("--restart-from "), std::string::npos) << out;
  EXPECT_EQ(advised.find("--resume"), std::string::npos) << out;
  const auto again = ncd("stream " + prog + " --port " + link_ + " --baud 9600");
  EXPECT_EQ(again.status, 2) << again.err;
  const auto resume = ncd("stream " + prog + " --port " + link_ + " --baud 9600 --resume");
  EXPECT_EQ(resume.status, 2) << resume.err;
  // One advice: the same command (the shell's run differs from the spawned one only in quoting).
  for (const CmdResult* r : {&again, &resume}) {
    const std::string cmd = run_line(r->err);
    EXPECT_EQ(cmd.substr(cmd.find("--restart-from")),
              advised.substr(advised.find("--restart-from")))
        << r->err;
  }
  const auto done = shell(run_line(resume.err) + " -q");
  EXPECT_EQ(done.status, 0) << done.out << done.err;
  const auto log = controller_log(*cnc, 120.0);
  std::vector<std::string> want;
  std::istringstream in(slurp(prog));
  for (std::string l; std::getline(in, l);) {
    if (!l.empty() && l[0] == 'N') want.push_back(l);
  }
  EXPECT_EQ(numbered(log), want) << "each numbered block once, in order";
  EXPECT_TRUE(log["alarms"].empty()) << log["alarms"];
  EXPECT_FALSE(fs::exists(journal));
}

// A line with nothing on the other end: the test holds the pty and only reads it. Every block
// is written (the reader gets them all), and the command says nothing ever answered: exit 4.
TEST_F(StreamEdges, NothingAnsweredWarnsAndExitsFour) {
  std::string text;
  for (int i = 1; i <= 140; ++i)
    text += "N" + std::to_string(i) + " G0 X" + std::to_string(i) + "\n";
  const std::string prog = write("p.ngc", text + "M2\n");
  comms::Pty pty((dir_ / "line").string());
  std::atomic<bool> stop{false};
  std::atomic<long> got{0};
  std::thread reader([&] {
    char buf[512];
    while (!stop.load()) {
      pollfd p{pty.master(), POLLIN, 0};
      if (::poll(&p, 1, 50) <= 0) continue;
      const ssize_t n = ::read(pty.master(), buf, sizeof buf);
      if (n > 0) got += n;
    }
  });
  const auto r = ncd("stream " + prog + " --port " + (dir_ / "line").string() +
                     " --baud 115200 -q --no-journal --report " + (dir_ / "r.json").string());
  stop.store(true);
  reader.join();
  EXPECT_EQ(r.status, 4) << r.out << r.err;
  EXPECT_NE(r.out.find("WARNING: nothing ever answered on " + (dir_ / "line").string()),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("check the cable"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("the 141 blocks sent may not have arrived"), std::string::npos) << r.out;
  const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
  EXPECT_TRUE(rep["controller_silent"].get<bool>());
  EXPECT_EQ(rep["bytes_written"].get<long>(), got.load());  // all of it went to the line
  // With a controller that speaks (the simulated one sends DC1 on connecting): exit 0.
  auto cnc = controller("--baud 115200");
  const auto ok = ncd("stream " + prog + " --port " + link_ + " --baud 115200 -q --no-journal");
  EXPECT_EQ(ok.status, 0) << ok.out << ok.err;
  EXPECT_EQ(ok.out.find("WARNING"), std::string::npos) << ok.out;
  controller_log(*cnc, 120.0);
}

// The link use against the definition, computed here from the report: bytes carried (written,
// less those not known to have left) times 11 bits (7E2) over baud times duration; within
// (0, 1]. Once for a whole transfer and once for one stopped at once at 300 baud, where the
// first characters written (ahead of the wire) used to be counted as carried.
TEST_F(StreamEdges, LinkUseIsAFractionOfTheLine) {
  const std::string prog = write("slow.ngc", edge_slow_program(30));
  for (const int baud : {9600, 300}) {
    SCOPED_TRACE(baud);
    auto cnc = controller("--baud " + std::to_string(baud));
    const std::string rep = (dir_ / "r.json").string();
    Process sender({NCD_EXE, "stream", prog, "--port", link_, "--baud", std::to_string(baud),
                    "--no-journal", "--report", rep},
                   (dir_ / "s.out").string(), (dir_ / "s.err").string());
    if (baud == 300) {  // stop as soon as the port is open and the first bytes are written
      const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(10);
      while (slurp(dir_ / "s.err").find("opened") == std::string::npos) {
        ASSERT_LT(std::chrono::steady_clock::now(), end) << slurp(dir_ / "s.err");
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
      }
      sender.signal(SIGINT);
    }
    const int status = sender.wait(120.0);
    EXPECT_EQ(status, baud == 300 ? 3 : 0) << slurp(dir_ / "s.err");
    if (baud == 300) {
      cnc->signal(SIGTERM);
      cnc->wait(10.0);
    } else {
      controller_log(*cnc, 120.0);
    }
    const auto r = nlohmann::json::parse(slurp(rep));
    const double carried = r["bytes_written"].get<double>() - r["bytes_in_flight"].get<double>();
    const double use = carried * 11.0 / (baud * r["duration_s"].get<double>());
    EXPECT_GT(carried, 0.0);
    EXPECT_GT(r["link_use"].get<double>(), 0.0);
    EXPECT_LE(r["link_use"].get<double>(), 1.0);
    EXPECT_NEAR(r["link_use"].get<double>(), use, 1e-9);
    std::cout << "[ measured ] " << baud << " baud: " << r["bytes_written"] << " bytes written, "
              << r["bytes_in_flight"] << " in flight, " << r["duration_s"] << " s, link use "
              << r["link_use"] << "\n";
  }
}

// Two 6 s tool changes hold the line longer than the default 5 s: explained by the M6 the
// controller was sent, no warning; the job completes. A 10 s stall with no such block warns.
TEST_F(StreamEdges, ToolChangeHoldsAreExplainedAndARealStallWarns) {
  std::string text = "G21 G90 G94\nT1 M6\nG43 H1\nS1000 M3\nG0 X0 Y0 Z5\nG1 Z-1 F600\n";
  for (int i = 1; i <= 20; ++i)
    text += "N" + std::to_string(i) + " G0 X" + std::to_string(i) + "\n";
  text += "G0 Z5\nM5\nT2 M6\nG43 H2\nS1000 M3\nG1 Z-1 F600\n";
  for (int i = 21; i <= 40; ++i)
    text += "N" + std::to_string(i) + " G0 X" + std::to_string(i) + "\n";
  const std::string prog = write("tc.ngc", text + "G0 Z5\nM5\nM2\n");
  {
    auto cnc = controller("--baud 19200 --dialect iso --tool-change-s 6");
    const auto r = ncd("stream " + prog + " --port " + link_ +
                       " --baud 19200 --no-journal --report " + (dir_ / "r.json").string());
    EXPECT_EQ(r.status, 0) << r.out << r.err;
    EXPECT_EQ(r.err.find("has held the link"), std::string::npos) << r.err;
    const auto rep = nlohmann::json::parse(slurp(dir_ / "r.json"));
    EXPECT_EQ(rep["xoff_timeouts"], 0);
    EXPECT_EQ(rep["holds_explained"], 2);  // each tool change held the line over 5 s
    EXPECT_GT(rep["xoff_longest_s"].get<double>(), 5.0);
    const auto log = controller_log(*cnc, 120.0);
    EXPECT_TRUE(log["program_end_executed"].get<bool>());
  }
  std::string plain;
  for (int i = 1; i <= 200; ++i)
    plain += "N" + std::to_string(i) + " G1 X" + std::to_string(i) + " F20000\n";
  const std::string stall = write("stall.ngc", plain + "M2\n");
  auto cnc = controller("--baud 19200 --hold-after-blocks 30 --hold-s 10");
  const auto r = ncd("stream " + stall + " --port " + link_ +
                     " --baud 19200 --no-journal --report " + (dir_ / "r2.json").string());
  EXPECT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_NE(r.err.find("has held the link for more than 5.0 s"), std::string::npos) << r.err;
  const auto rep = nlohmann::json::parse(slurp(dir_ / "r2.json"));
  EXPECT_EQ(rep["xoff_timeouts"], 1);
  controller_log(*cnc, 120.0);
}

}  // namespace
}  // namespace ncd::test
