// A program that indexes the rotary axis between cuts, end to end (docs/planner.md §3g): `ncd
// replay --blocks` writes each index as a G0 A block of its own, in the program's order among the
// spindle's M3/M5; LinuxCNC's rs274 reads the written program back to the same A angles; `ncd
// stream` sends it to `ncd sim-controller` over a real pseudo-terminal, and the controller's
// log (the independent record of what ran) shows each index with the tool at the program's Z
// and the spindle as the program left it (stopped); the grbl dialect refuses the program
// naming the line and the way out.
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "tests/app/serve_fixture.hpp"
#include "tests/common/process.hpp"
#include "tests/common/rs274.hpp"

namespace ncd::test {
namespace {

using nlohmann::json;

// Two holes on a pipe along X, turned 90° between them: index at Z20 with the spindle off.
constexpr const char* kRotaryProgram =
    "G21 G90 G17\n"
    "G0 X0 Y0 Z20\n"
    "G0 A90\n"
    "M3 S3000\n"
    "G0 Z2\n"
    "G1 Z-1 F300\n"
    "G1 X5\n"
    "G0 Z20\n"
    "M5\n"
    "G0 A180\n"
    "M3 S3000\n"
    "G0 Z2\n"
    "G1 Z-1 F300\n"
    "G1 X0\n"
    "G0 Z20\n"
    "M5\n"
    "G0 A0\n"
    "M2\n";

class RotaryStream : public ServeFixture {
 protected:
  void SetUp() override {
    ServeFixture::SetUp();
    log_ = (dir_ / "cnc.json").string();
  }
  std::string link() const { return (dir_ / "cnc").string(); }
  std::string machine(const std::string& link_keys, const std::string& more = "") {
    return write("m.toml", "[axis.a]\nmax_feed_deg_per_min = 7200\n[link]\ndevice = \"" + link() +
                               "\"\n" + link_keys + more);
  }
  std::string log_;
};

std::vector<std::string> rotary_lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

TEST_F(RotaryStream, IndexesReachTheControllerAtRestWithTheSpindleOff) {
  const std::string m = machine("");
  const std::string prog = write("p.ngc", kRotaryProgram);
  const std::string blocks = (dir_ / "out.ngc").string();
  CmdResult r = ncd("replay " + prog + " --machine " + m + " --start 0,0,50 -q --blocks " + blocks);
  ASSERT_EQ(r.status, 0) << r.err;
  // The written program: each index a block of its own, between the M5 and the M3 around it.
  const std::vector<std::string> lines = rotary_lines_of(slurp(blocks));
  std::vector<std::string> order;  // M3 / M5 / A… in the order written
  for (const std::string& l : lines) {
    if (l.find("M3") != std::string::npos) order.push_back("M3");
    if (l.find("M5") != std::string::npos) order.push_back("M5");
    const std::size_t a = l.find("G0A");
    if (a != std::string::npos) {
      EXPECT_EQ(l.find_first_of("XYZ"), std::string::npos) << "an index moves A alone: " << l;
      order.push_back("A" + std::to_string(std::lround(std::stod(l.substr(a + 3)))));
    }
  }
  const std::vector<std::string> want = {"A90", "M3", "M5", "A180", "M3", "M5", "A0"};
  EXPECT_EQ(order, want) << slurp(blocks);
  // rs274 reads the written program to the same angles, in order.
  if (std::filesystem::exists(kRs274)) {
    const std::string cmd = "cd '" + dir_.string() + "' && " +
                            rs274_command(dir_, "-g out.ngc canon.txt") + " > rs.log 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << slurp(dir_ / "rs.log");
    std::vector<double> angles;
    for (const std::string& l : rotary_lines_of(slurp(dir_ / "canon.txt"))) {
      if (l.find("STRAIGHT_TRAVERSE(") == std::string::npos) continue;
      double v[6] = {};
      if (std::sscanf(l.c_str() + l.find('(') + 1, "%lf, %lf, %lf, %lf, %lf, %lf", &v[0], &v[1],
                      &v[2], &v[3], &v[4], &v[5]) == 6 &&
          (angles.empty() || angles.back() != v[3])) {
        angles.push_back(v[3]);
      }
    }
    EXPECT_EQ(angles, (std::vector<double>{0.0, 90.0, 180.0, 0.0}));
  }
  // The controller runs it; its log holds each index with the tool's Z and the spindle's state.
  std::vector<std::string> argv{NCD_EXE, "sim-controller", "--machine", m, "--log",
                                log_,    "--exit-at-end"};
  Process cnc(argv, (dir_ / "cnc.out").string(), (dir_ / "cnc.err").string());
  ASSERT_TRUE(wait_for_path(link(), 10.0)) << slurp(dir_ / "cnc.err");
  const CmdResult s = ncd("stream " + blocks + " --machine " + m);
  EXPECT_EQ(s.status, 0) << s.err << s.out;
  ASSERT_EQ(cnc.wait(120.0), 0) << slurp(dir_ / "cnc.err");
  const json log = json::parse(slurp(log_));
  EXPECT_TRUE(log["errors"].empty()) << log["errors"].dump();
  EXPECT_TRUE(log["program_end_executed"].get<bool>());
  std::vector<double> indexed;
  for (const json& mv : log["moves"]) {
    if (!mv.contains("rotary_deg")) continue;
    indexed.push_back(mv["rotary_deg"].get<double>());
    EXPECT_EQ(mv["rotary_axis"], "A");
    EXPECT_NEAR(mv["p"][2].get<double>(), 20.0, 1e-9) << "Z at the index: " << mv.dump();
    // The spindle as the blocks before the index left it: stopped (or never started).
    std::string spindle = "spindle_stop";
    for (const json& e : log["events"]) {
      const std::string k = e["kind"];
      if (e["seq"].get<long>() < mv["seq"].get<long>() &&
          (k == "spindle_cw" || k == "spindle_ccw" || k == "spindle_stop")) {
        spindle = k;
      }
    }
    EXPECT_EQ(spindle, "spindle_stop") << "the spindle turns during the index " << mv.dump();
  }
  EXPECT_EQ(indexed, (std::vector<double>{90.0, 180.0, 0.0}));
}

TEST_F(RotaryStream, GrblRefusesTheIndexNamingTheLineAndTheWayOut) {
  const std::string grbl =
      "baud = 115200\nframe = \"8N1\"\nflow = \"none\"\nprotocol = \"ack\"\npercent = false\n"
      "dialect = \"grbl\"\n";
  const std::string prog = write("p.ngc", kRotaryProgram);
  const std::string blocks = (dir_ / "out.ngc").string();
  CmdResult r = ncd("replay " + prog + " --machine " + machine(grbl) +
                    " --start 0,0,50 -q --blocks " + blocks);
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("p.ngc:3"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("stock grbl 1.1"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("linuxcnc or iso dialect"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(blocks)) << "nothing half-written";
}

}  // namespace
}  // namespace ncd::test
