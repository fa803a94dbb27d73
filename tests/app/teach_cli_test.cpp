// `ncd teach` as a user meets it: the paper's example end to end, the program read back by
// `ncd replay` and sent as it is by `ncd stream`, the input formats, and invalid input (exit 2, a
// message, no file written).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <termios.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "link/pty.hpp"
#include "tests/app/cli_fixture.hpp"

namespace {

using ncd::test::Cli;
using ncd::test::CmdResult;
using ncd::test::slurp;
namespace fs = std::filesystem;

const std::string kTeachExamples = std::string(NCD_SOURCE_DIR) + "/examples/";
const std::string kPaperFrame = "'47.45,111.55,236.60;229.17,327.47,274.28;-17.55,327.77,316.35'";
const std::string kTool = " --tool-diameter 10 --depth 0.2 --feed 300 --spindle 2000";

std::vector<std::string> lines_starting(const std::string& text, const std::string& prefix) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind(prefix, 0) == 0) out.push_back(line);
  }
  return out;
}

class TeachCli : public Cli {
 protected:
  // Runs `ncd teach ARGS -o program.ngc` and returns the result; the program is at program().
  CmdResult teach(const std::string& args) { return ncd("teach " + args + " -o " + program()); }
  std::string program() const { return (dir_ / "program.ngc").string(); }
};

TEST_F(TeachCli, HelpNamesEveryFlag) {
  const CmdResult r = ncd("teach --help");
  EXPECT_EQ(r.status, 0);
  for (const char* flag :
       {"POINTS", "--frame-points", "--tool-diameter", "--depth", "--feed", "--spindle", "--side",
        "--closed", "--truncate", "--decimals", "--clearance", "--output"}) {
    EXPECT_NE(r.out.find(flag), std::string::npos) << flag;
  }
}

TEST_F(TeachCli, PapersExampleGivesThePapersLinesAndReplays) {
  const CmdResult r = teach(kTeachExamples + "teach-burr.txt --frame-points " + kTeachExamples +
                            "teach-burr-frame.txt" + kTool + " --truncate");
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string text = slurp(program());
  const auto g01 = lines_starting(text, "G01");
  ASSERT_EQ(g01.size(), 6u) << text;
  EXPECT_EQ(g01[1], "G01X28.728Y-6.595Z-0.765");
  EXPECT_EQ(g01[2], "G01X32.426Y-10.440Z-0.689");
  EXPECT_EQ(g01[3], "G01X37.393Y-14.148Z-0.465");
  EXPECT_EQ(g01[4], "G01X40.965Y-16.704Z-0.140");
  EXPECT_EQ(lines_starting(text, "G90"), std::vector<std::string>{"G90F300S2000"});
  EXPECT_TRUE(lines_starting(text, "%").empty());
  EXPECT_NE(text.find("truncated toward zero to 3 decimals"), std::string::npos);
  EXPECT_NE(r.err.find("6 points"), std::string::npos) << r.err;
  // Our own reader takes it as it is, and walks it.
  const CmdResult replay = ncd("replay " + program() + " --report " + (dir_ / "r.json").string());
  EXPECT_EQ(replay.status, 0) << replay.err;
}

TEST_F(TeachCli, ProgramStreamsAsItIs) {
  ASSERT_EQ(teach(kTeachExamples + "teach-burr.txt --frame-points " + kPaperFrame + kTool).status,
            0);
  // The test plays the controller on the master side of the project's raw pty pair, which holds
  // its slave open, so the small program waits in the terminal's buffer until it is read.
  ncd::comms::Pty pty((dir_ / "cnc").string());
  const CmdResult r = ncd("stream " + program() + " --port " + pty.device() +
                          " --baud 115200 --frame 8N1 --flow none --no-journal -q");
  std::string got;
  char buf[512];
  for (pollfd p{pty.master(), POLLIN, 0}; ::poll(&p, 1, 200) > 0;) {
    const ssize_t n = ::read(pty.master(), buf, sizeof buf);
    if (n <= 0) break;
    got.append(buf, static_cast<std::size_t>(n));
  }
  // The test's controller reads and never answers: the stream says so (docs/cmd-stream.md,
  // "Nothing answered") and exits 4, sent but not confirmed.
  ASSERT_EQ(r.status, 4) << r.err;
  EXPECT_NE(r.err.find("WARNING: nothing ever answered"), std::string::npos) << r.err;
  EXPECT_EQ(got, "%\n" + slurp(program()) + "%\n");  // every line a block, % framing added
}

TEST_F(TeachCli, CsvAndInlineFrameGiveTheSameProgramAsTheExample) {
  const std::string csv = write("burr.csv",
                                "name,x,y,z\n"
                                "dp1,66.15,124.57,236.76\ndp2,70.98,125.20,236.12\n"
                                "dp3,76.49,125.79,235.45\ndp4,83.01,127.46,235.11\n"
                                "dp5,87.55,128.68,235.07\ndp6,92.32,130.68,234.88\n");
  const CmdResult a = ncd("teach " + csv + " --frame-points " + kPaperFrame + kTool + " -q");
  const CmdResult b = ncd("teach " + kTeachExamples + "teach-burr.txt --frame-points " +
                          kTeachExamples + "teach-burr-frame.txt" + kTool + " -q");
  ASSERT_EQ(a.status, 0) << a.err;
  ASSERT_EQ(b.status, 0) << b.err;
  EXPECT_EQ(a.out, b.out);  // standard output without -o
  EXPECT_TRUE(a.err.empty()) << a.err;
  EXPECT_NE(a.out.find("G01X32.427Y-10.440Z-0.690"), std::string::npos) << a.out;  // rounded
}

TEST_F(TeachCli, ClosedLoopInATiltedPlaneReplays) {
  // An ellipse of 24 points in a plane tilted 30° about X, digitized clockwise seen from +Z.
  std::ostringstream pts;
  pts.precision(17);
  for (int i = 0; i < 24; ++i) {
    const double phi = -2.0 * 3.14159265358979 * i / 24.0;
    const double x = 40.0 * std::cos(phi), y = 25.0 * std::sin(phi);
    pts << "p" << i << " " << 100.0 + x << " " << 50.0 + y * std::cos(0.5236) << " "
        << 20.0 + y * std::sin(0.5236) << "\n";
  }
  const std::string file = write("loop.txt", pts.str());
  const CmdResult r = teach(file + " --frame-points '0,0,0;100,0,0;0,86.6,50'" + kTool +
                            " --closed --side right --decimals 4 --clearance 5");
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string text = slurp(program());
  const auto g01 = lines_starting(text, "G01");
  ASSERT_EQ(g01.size(), 25u);
  EXPECT_EQ(g01.front(), g01.back());
  EXPECT_NE(text.find("closed loop"), std::string::npos);
  EXPECT_NE(text.find("4.8 right"), std::string::npos);
  const CmdResult replay = ncd("replay " + program() + " --report " + (dir_ / "r.json").string());
  EXPECT_EQ(replay.status, 0) << replay.err;
}

TEST_F(TeachCli, InvalidInputExitsTwoAndLeavesTheOldFileAlone) {
  const std::string ok = kTeachExamples + "teach-burr.txt";
  const std::string frame = " --frame-points " + kPaperFrame;
  const std::string two = write("two.txt", "dp1 66.15 124.57 236.76\ndp2 70.98 125.20 236.12\n");
  const std::string dup = write("dup.txt",
                                "dp1 66.15 124.57 236.76\ndp2 70.98 125.20 236.12\n"
                                "dp3 70.98 125.20 236.12\ndp4 76.49 125.79 235.45\n");
  const std::string nan = write("nan.txt", "dp1 66.15 124.57 236.76\ndp2 70.98 nan 236.12\n");
  const std::string junk = write("junk.csv", "x,y,z\n1,2,3\n4,five,6\n");
  const std::string frame2 = write("frame2.txt", "P1 0 0 0\nP2 100 0 0\n");
  struct Case {
    std::string args;
    std::vector<std::string> says;
  };
  const std::vector<Case> cases{
      {ok + frame + " --tool-diameter 10 --depth 5 --feed 300 --spindle 2000",
       {"depth l (--depth) = 5", "D/2 = 5", "smaller --depth"}},
      {ok + " --frame-points '0,0,0;100,0,0;200,0.1,0'" + kTool, {"collinear", "P3"}},
      {ok + " --frame-points " + frame2 + kTool, {"frame2.txt", "2 point(s)", "exactly three"}},
      {ok + " --frame-points '0,0,0;100,0,0'" + kTool, {"--frame-points", "2 point(s)"}},
      {two + frame + kTool, {"two.txt: the path has 2 point(s)", "at least three"}},
      {dup + frame + kTool,
       {"dup.txt: point 2 (dp2, line 2) and point 3 (dp3, line 3)", "remove one"}},
      {nan + frame + kTool, {"nan.txt:2", "'nan' (y) is not a number"}},
      {junk + frame + kTool, {"junk.csv:3", "'five' (y) is not a number"}},
      {(dir_ / "missing.txt").string() + frame + kTool, {"missing.txt", "cannot open"}},
      {ok + frame + kTool + " --decimals 9", {"--decimals"}},
      {ok + frame + kTool + " --side up", {"--side"}},
      {ok + frame + " --tool-diameter 10 --depth 0.2 --feed 300", {"--spindle"}},
  };
  for (const Case& c : cases) {
    std::ofstream(program()) << "old program\n";
    const CmdResult r = teach(c.args);
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.err;
    for (const std::string& s : c.says) {
      EXPECT_NE(r.err.find(s), std::string::npos) << c.args << "\n" << r.err << "missing: " << s;
    }
    EXPECT_EQ(slurp(program()), "old program\n") << c.args;
  }
  for (const auto& e : fs::directory_iterator(dir_)) {
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
  }
}

TEST_F(TeachCli, InvalidInputWritesNoFile) {
  const CmdResult r = teach(kTeachExamples + "teach-burr.txt --frame-points " + kPaperFrame +
                            " --tool-diameter 10 --depth 6 --feed 300 --spindle 2000");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("ncd: error: "), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(program()));
}

}  // namespace
