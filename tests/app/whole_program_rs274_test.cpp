// Every NC program ncd writes is read by LinuxCNC's own interpreter, `rs274 -g FILE OUT`
// (docs/whole-program.md, "Checked by rs274"): it must parse with no error and no warning and
// end with PROGRAM_END, and the canonical moves rs274 prints must match what ncd planned:
//   - the blocks of `ncd replay --blocks`: every end point of a canonical move lies within the
//     encoder's chord tolerance (plus rs274's 4-decimal print) of the setpoint polyline ncd
//     walked (the --setpoints file of the same run);
//   - the chamfer's NGC program: every point of the loop (the chamfer JSON's ball centres,
//     turned over for a lower edge, less R_B for the tip) is the end of a canonical feed.
// Without /usr/bin/rs274 (linuxcnc-uspace) the suite is skipped.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "gcode/dialect/dialect.hpp"
#include "tests/app/cli_fixture.hpp"
#include "tests/common/rs274.hpp"

namespace {

using ncd::test::Cli;
using ncd::test::CmdResult;
using ncd::test::slurp;
namespace fs = std::filesystem;

using ncd::test::kRs274;
// A point written or printed with 4 decimals is within half a unit of the last digit on each
// axis: √3 · 5e-5 mm in space (plus 1e-6 for the arithmetic).
const double kPrint4Mm = std::sqrt(3.0) * 5e-5 + 1e-6;
constexpr double kExp3ChordMm = 0.002;  // config/chamfer-exp3.toml [encoder]
const std::string kExp3Machine = std::string(NCD_SOURCE_DIR) + "/config/chamfer-exp3.toml";
const std::string kExp3Geometry =
    "--pipe-radius 18 --drill-radius 13 --ball-radius 3 --width 0.7 --tolerance 0.01 "
    "--rod-radius 1.8 --non-knife-angle 93";

struct Pt3 {
  double x, y, z;
};
double pt_dist(const Pt3& a, const Pt3& b) {
  return std::hypot(a.x - b.x, a.y - b.y, a.z - b.z);
}
double pt_dist_to_segment(const Pt3& p, const Pt3& a, const Pt3& b) {
  const Pt3 ab{b.x - a.x, b.y - a.y, b.z - a.z};
  const double l2 = ab.x * ab.x + ab.y * ab.y + ab.z * ab.z;
  double t = l2 > 0 ? ((p.x - a.x) * ab.x + (p.y - a.y) * ab.y + (p.z - a.z) * ab.z) / l2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  return pt_dist(p, {a.x + t * ab.x, a.y + t * ab.y, a.z + t * ab.z});
}

struct ProgramCanonical {
  int status = -1;
  std::string out, log;
  std::vector<Pt3> moves;    // STRAIGHT_TRAVERSE / STRAIGHT_FEED end points, in order
  std::vector<bool> feed;    // true for STRAIGHT_FEED
  bool program_end = false;  // PROGRAM_END seen
};

class Rs274 : public Cli {
 protected:
  void SetUp() override {
    Cli::SetUp();
    if (!fs::exists(kRs274)) GTEST_SKIP() << kRs274 << " not installed (linuxcnc-uspace)";
  }
  // rs274 -g on `file`; `options` go before -g (e.g. "-t TOOL_TABLE").
  ProgramCanonical canonical(const std::string& file, const std::string& options = "") {
    const fs::path out = dir_ / "canon.out", log = dir_ / "canon.log";
    const std::string cmd =
        ncd::test::rs274_command(dir_, options + " -g " + file + " " + out.string()) + " >" +
        log.string() + " 2>&1";
    const int raw = std::system(cmd.c_str());
    ProgramCanonical c;
    c.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    c.out = slurp(out);
    c.log = slurp(log);
    const ncd::test::CanonicalMoves m = ncd::test::canonical_moves(c.out);
    for (const auto& p : m.end) c.moves.push_back({p[0], p[1], p[2]});
    c.feed = m.feed;
    c.program_end = m.program_end;
    return c;
  }
  static void expect_clean(const ProgramCanonical& c, const std::string& what) {
    EXPECT_EQ(c.status, 0) << what << "\n" << c.log;
    EXPECT_EQ(ncd::test::rs274_complaint(c.log), "") << what << ": " << c.log;
    EXPECT_EQ(ncd::test::rs274_complaint(c.out), "") << what;
    EXPECT_TRUE(c.program_end) << what << ": no PROGRAM_END";
  }
  // The setpoints CSV of a replay: x, y, z of each row.
  static std::vector<Pt3> setpoints(const std::string& csv) {
    std::vector<Pt3> pts;
    std::istringstream in(csv);
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line)) {
      Pt3 p{};
      double t = 0;
      if (std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf", &t, &p.x, &p.y, &p.z) == 4) pts.push_back(p);
    }
    return pts;
  }
  // replay --blocks and --setpoints of `path`; rs274 on the blocks; the largest distance of a
  // canonical end point (after the first, the rise from wherever the tool stands) from the
  // setpoint polyline.
  double blocks_deviation(const std::string& path, const std::string& what,
                          const std::string& machine = kExp3Machine) {
    const std::string blocks = (dir_ / "b.ngc").string(), csv = (dir_ / "sp.csv").string();
    const CmdResult r = ncd("replay " + path + " --machine " + machine + " -q --blocks " + blocks +
                            " --setpoints " + csv);
    EXPECT_EQ(r.status, 0) << r.err;
    const ProgramCanonical c = canonical(blocks);
    expect_clean(c, what);
    const std::vector<Pt3> sp = setpoints(slurp(csv));
    EXPECT_GT(sp.size(), 10u);
    EXPECT_GT(c.moves.size(), 3u) << what;
    double worst = 0.0;
    for (std::size_t i = 1; i < c.moves.size(); ++i) {
      double d = std::numeric_limits<double>::infinity();
      for (std::size_t k = 0; k + 1 < sp.size(); ++k) {
        d = std::min(d, pt_dist_to_segment(c.moves[i], sp[k], sp[k + 1]));
      }
      worst = std::max(worst, d);
    }
    std::printf(
        "rs274 %-28s %3zu canonical moves, max distance from the planned setpoints "
        "%.5f mm (tolerance %.5f)\n",
        what.c_str(), c.moves.size(), worst, kExp3ChordMm + kPrint4Mm);
    EXPECT_LE(worst, kExp3ChordMm + kPrint4Mm) << what;
    return worst;
  }
};

TEST_F(Rs274, BlocksOfTheExp3ChamferParseAndFollowThePlan) {
  const std::string json_out = (dir_ / "exp3.json").string();
  ASSERT_EQ(ncd("chamfer " + kExp3Geometry + " -q -o " + json_out).status, 0);
  blocks_deviation(json_out, "blocks of the exp3 chamfer");
}

TEST_F(Rs274, BlocksOfANurbsParseAndFollowThePlan) {
  const std::string cubic = write("cubic.json", R"({"nurbs": {"degree": 3,
    "knots": [0,0,0,0,0.25,0.5,0.75,1,1,1,1],
    "points": [[0,0,0],[10,25,0],[30,-10,2],[45,30,4],[60,0,3],[80,20,0],[100,0,0]]},
    "feed_mm_per_min": 1200})");
  blocks_deviation(cubic, "blocks of a NURBS");
}

TEST_F(Rs274, BlocksOfAnInterpretedSampleParseAndFollowThePlan) {
  const std::string sample = std::string(NCD_SOURCE_DIR) + "/tests/ngc/stops_dwell.ngc";
  ASSERT_TRUE(fs::exists(sample));
  blocks_deviation(sample, "blocks of stops_dwell.ngc");
}

TEST_F(Rs274, TeachProgramAndItsBlocksParseAndFollowThePlan) {
  const std::string ex = std::string(NCD_SOURCE_DIR) + "/examples/";
  const std::string ngc = (dir_ / "teach.ngc").string();
  const CmdResult t = ncd("teach " + ex + "teach-burr.txt --frame-points " + ex +
                          "teach-burr-frame.txt --tool-diameter 10 --depth 0.2 --feed 300 "
                          "--spindle 2000 -q -o " +
                          ngc);
  ASSERT_EQ(t.status, 0) << t.err;
  expect_clean(canonical(ngc), "teach program");
  const double worst = blocks_deviation(ngc, "blocks of the teach job");
  EXPECT_GE(worst, 0.0);
  // Its events travel into the blocks: the spindle at its speed before the first G1, M5, M30.
  const std::string blocks = slurp(dir_ / "b.ngc");
  const std::size_t m3 = blocks.find("M3S2000");
  std::smatch first_g1;
  ASSERT_TRUE(std::regex_search(blocks, first_g1, std::regex("G1[XYZF]")));
  const auto g1 = static_cast<std::size_t>(first_g1.position(0));
  EXPECT_NE(m3, std::string::npos);
  EXPECT_LT(m3, g1);
  EXPECT_NE(blocks.find("M5\n"), std::string::npos);
  EXPECT_NE(blocks.find("M30\n"), std::string::npos);
}

TEST_F(Rs274, ChamferProgramsOfEveryEdgeAndSideParseAndHoldTheLoop) {
  for (const char* edge : {"inner", "outer"}) {
    for (const char* side : {"upper", "lower"}) {
      const std::string what = std::string("chamfer ") + edge + " " + side;
      // Outer edges need a pipe radius on the outside (36 mm bore, 3 mm wall).
      const std::string geometry =
          std::string(edge) == "outer"
              ? "--pipe-radius 21 --drill-radius 13 --ball-radius 3 --width 0.7 --tolerance 0.01"
              : kExp3Geometry;
      const std::string args = "chamfer " + geometry + " --edge " + edge + " --side " + side +
                               " --machine " + kExp3Machine + " -q";
      const std::string ngc = (dir_ / "c.ngc").string(), json_out = (dir_ / "c.json").string();
      const CmdResult g = ncd(args + " --format ngc -o " + ngc);
      ASSERT_EQ(g.status, 0) << what << "\n" << g.err;
      ASSERT_EQ(ncd(args + " --format json -o " + json_out).status, 0);
      const ProgramCanonical c = canonical(ngc);
      expect_clean(c, what);
      const auto doc = nlohmann::json::parse(slurp(json_out));
      const bool lower = std::string(side) == "lower";
      double worst = 0.0;
      std::size_t n = 0;
      for (const auto& pt : doc["points"]) {
        const auto cl = pt["cl"];
        Pt3 q{cl[0].get<double>(), cl[1].get<double>(), cl[2].get<double>()};
        if (lower) q = {-q.x, q.y, -q.z};  // turned over (docs/chamfer.md)
        q.z -= 3.0;                        // the tip, as the machine file says
        double d = std::numeric_limits<double>::infinity();
        for (std::size_t i = 0; i < c.moves.size(); ++i) {
          if (c.feed[i]) d = std::min(d, pt_dist(q, c.moves[i]));
        }
        worst = std::max(worst, d);
        ++n;
      }
      std::printf("rs274 %-28s %3zu canonical moves, %zu loop points, max distance %.6f mm\n",
                  what.c_str(), c.moves.size(), n, worst);
      EXPECT_LE(worst, kPrint4Mm) << what;
    }
  }
}

// The exp3 machine with a grbl 1.1 controller on its link ([link] dialect = "grbl").
std::string grbl_machine_text() {
  std::string text = slurp(kExp3Machine);
  const std::string from = "dialect = \"iso\"";
  const std::size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << "config/chamfer-exp3.toml names no iso dialect";
  if (at != std::string::npos) text.replace(at, from.size(), "dialect = \"grbl\"");
  return text;
}

// The blocks and the chamfer program written for a grbl machine: what grbl takes, line by line
// (comms/dialect's grbl model: no %, no N, no M6, no G64), and still what LinuxCNC reads and
// what ncd planned.
TEST_F(Rs274, ProgramsForAGrblMachineAreWhatGrblTakesAndFollowThePlan) {
  const std::string machine = write("grbl.toml", grbl_machine_text());
  const std::string json_out = (dir_ / "exp3.json").string();
  ASSERT_EQ(ncd("chamfer " + kExp3Geometry + " -q -o " + json_out).status, 0);
  blocks_deviation(json_out, "grbl blocks of exp3", machine);
  const std::string blocks = slurp(dir_ / "b.ngc");
  EXPECT_FALSE(ncd::comms::check_program(ncd::comms::Dialect::grbl, blocks).has_value());
  EXPECT_EQ(blocks.find('%'), std::string::npos);
  EXPECT_EQ(blocks.find("T1M6"), std::string::npos);
  EXPECT_EQ(blocks.find("\nN"), std::string::npos);
  EXPECT_NE(blocks.find("load tool 1 before the start"), std::string::npos);
  EXPECT_NE(blocks.find("M3S3000"), std::string::npos);
  const std::string ngc = (dir_ / "c.ngc").string();
  const CmdResult g =
      ncd("chamfer " + kExp3Geometry + " --machine " + machine + " -q --format ngc -o " + ngc);
  ASSERT_EQ(g.status, 0) << g.err;
  const std::string text = slurp(ngc);
  EXPECT_FALSE(ncd::comms::check_program(ncd::comms::Dialect::grbl, text).has_value());
  EXPECT_EQ(text.find("\nG64"), std::string::npos);
  EXPECT_EQ(text.find('%'), std::string::npos);
  const ProgramCanonical c = canonical(ngc);
  EXPECT_EQ(c.status, 0) << c.log;
  EXPECT_TRUE(c.program_end);
  // The same program for the iso machine keeps its G64 P and its % lines; both are accepted by
  // the iso rules.
  const std::string iso = (dir_ / "iso.ngc").string();
  ASSERT_EQ(
      ncd("chamfer " + kExp3Geometry + " --machine " + kExp3Machine + " -q --format ngc -o " + iso)
          .status,
      0);
  const std::string iso_text = slurp(iso);
  EXPECT_NE(iso_text.find("G64 P"), std::string::npos);
  EXPECT_FALSE(ncd::comms::check_program(ncd::comms::Dialect::iso, iso_text).has_value());
}

// A program the machine's dialect cannot take is refused before anything is written: an NGC
// program replayed for a grbl machine keeps its events, and grbl's refusal of mist coolant (M7,
// compiled out of grbl 1.1 by default: error:20) names the line and the word.
TEST_F(Rs274, BlocksTheDialectCannotTakeAreRefusedAndNothingIsWritten) {
  const std::string machine = write("grbl.toml", grbl_machine_text());
  const std::string prog = write("tc.ngc",
                                 "G21 G90 G94\nM3 S1000\nM7\nG0 Z5\nG0 X0 Y0\nG1 Z-1 F300\n"
                                 "G1 X10\nG0 Z5\nM9\nM5\nM2\n");
  const std::string blocks = (dir_ / "tc-blocks.ngc").string();
  const CmdResult r = ncd("replay " + prog + " --machine " + machine + " -q --blocks " + blocks);
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("'M7'"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("error:20"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(blocks));
}

// The exp3 machine with its tool numbered 4 and a 1.5 s spin-up ([tool] number,
// spindle_dwell_s), for the dialect `dialect`.
std::string tool_machine_text(const std::string& dialect) {
  std::string text = dialect == "grbl" ? grbl_machine_text() : slurp(kExp3Machine);
  const std::string key = "programmed_point = \"tip\"";
  const std::size_t at = text.find(key);
  EXPECT_NE(at, std::string::npos) << "config/chamfer-exp3.toml has no [tool] programmed_point";
  if (at != std::string::npos) {
    text.insert(at + key.size(), "\nnumber = 4\nspindle_dwell_s = 1.5");
  }
  return text;
}

// Where `what` first appears in rs274's canonical output; npos if nowhere.
std::size_t at(const ProgramCanonical& c, const std::string& what) {
  return c.out.find(what);
}

// The chamfer's NGC program changes to the machine file's tool and waits for the spindle before
// it cuts, as the whole job of the blocks does (docs/whole-program.md): rs274 reads T4 M6 (the
// tool from a tool table in the test's folder), the spindle start and a 1.5 s dwell, in that
// order, all before the first feed, with no error or warning. For grbl (no M6) the header asks
// for tool 4 instead, and the program is still what grbl takes.
TEST_F(Rs274, ChamferProgramChangesTheToolAndWaitsForTheSpindleAsTheBlocksDo) {
  const std::string table = write("tool.tbl", "T4 P4 Z0 D6 ;6 mm ball\n");
  for (const std::string dialect : {"iso", "grbl"}) {
    SCOPED_TRACE(dialect);
    const std::string machine = write(dialect + ".toml", tool_machine_text(dialect));
    const std::string ngc = (dir_ / "c.ngc").string();
    const CmdResult g =
        ncd("chamfer " + kExp3Geometry + " --machine " + machine + " -q --format ngc -o " + ngc);
    ASSERT_EQ(g.status, 0) << g.err;
    const std::string text = slurp(ngc);
    const ProgramCanonical c = canonical(ngc, "-t " + table);
    expect_clean(c, "chamfer program for tool 4 (" + dialect + ")");
    const std::size_t spindle = at(c, "START_SPINDLE_CLOCKWISE"), dwell = at(c, "DWELL(1.5000)"),
                      feed = at(c, "STRAIGHT_FEED(");
    ASSERT_NE(spindle, std::string::npos) << c.out;
    ASSERT_NE(dwell, std::string::npos) << c.out;
    ASSERT_NE(feed, std::string::npos) << c.out;
    EXPECT_LT(spindle, dwell);
    EXPECT_LT(dwell, feed);
    // The blocks of the same chamfer for the same machine: the same events in the same order.
    const std::string json_out = (dir_ / "c.json").string(), blocks = (dir_ / "b.ngc").string();
    ASSERT_EQ(ncd("chamfer " + kExp3Geometry + " -q -o " + json_out).status, 0);
    const CmdResult r =
        ncd("replay " + json_out + " --machine " + machine + " -q --blocks " + blocks);
    ASSERT_EQ(r.status, 0) << r.err;
    const std::string b = slurp(blocks);
    std::smatch first_g1;
    ASSERT_TRUE(std::regex_search(b, first_g1, std::regex("G1[XYZF]"))) << b;
    const std::size_t b_spindle = b.find("M3S3000"), b_dwell = b.find("G4P1.5"),
                      b_feed = static_cast<std::size_t>(first_g1.position(0));
    ASSERT_NE(b_spindle, std::string::npos) << b;
    EXPECT_LT(b_spindle, b_dwell);
    EXPECT_LT(b_dwell, b_feed);
    if (dialect == "grbl") {
      EXPECT_EQ(text.find("T4 M6"), std::string::npos) << text;
      EXPECT_NE(text.find("(load tool 4 before the start"), std::string::npos) << text;
      EXPECT_EQ(b.find("T4M6"), std::string::npos);
      EXPECT_NE(b.find("(load tool 4 before the start"), std::string::npos);
      EXPECT_EQ(at(c, "CHANGE_TOOL"), std::string::npos);
      EXPECT_FALSE(ncd::comms::check_program(ncd::comms::Dialect::grbl, text).has_value());
    } else {
      const std::size_t select = at(c, "SELECT_TOOL(4)"), change = at(c, "CHANGE_TOOL(");
      ASSERT_NE(select, std::string::npos) << c.out;
      ASSERT_NE(change, std::string::npos) << c.out;
      EXPECT_LT(select, change);
      EXPECT_LT(change, spindle);
      EXPECT_NE(text.find("\nT4 M6\n"), std::string::npos) << text;
      const std::size_t b_tool = b.find("T4M6");
      ASSERT_NE(b_tool, std::string::npos) << b;
      EXPECT_LT(b_tool, b_spindle);
      EXPECT_FALSE(ncd::comms::check_program(ncd::comms::Dialect::iso, text).has_value());
    }
  }
}

}  // namespace
