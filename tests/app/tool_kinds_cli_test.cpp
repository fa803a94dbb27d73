// Tools as they are (docs/feedrate.md §1.5): the roughness law caps ball ends only. A flat end
// mill's pocket runs at its programmed feed, a ball end is capped at the law's closed form for
// its own radius and teeth, a tool of no stated kind is not capped and a drill gets no R_max.
// Every tool table here is first read by LinuxCNC's `rs274`, which must accept it as it is (the
// kind and teeth sit in its comment).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "tests/app/cli_fixture.hpp"
#include "tests/common/rs274.hpp"

namespace {

using ncd::test::Cli;
using ncd::test::CmdResult;
using ncd::test::slurp;
namespace fs = std::filesystem;

// A LinuxCNC-style pocket: 60 mm passes at F508 (20 in/min) 5 mm apart, plunge at F100.
const char* kPocket = R"((pocket: 60 mm passes at F508, the tool T1 of the table)
G21 G17 G90 G94 G40 G49 G64 P0.01
T1 M6
G43 H1
S2000 M3
G0 Z5
G0 X0 Y0
G1 Z-2 F100
G1 X60 F508
G1 Y5
G1 X0
G1 Y10
G1 X60
G1 Y15
G1 X0
G1 Y20
G1 X60
G0 Z5
M5
M2
)";

// Two drilled holes with tool T3.
const char* kDrill = R"((two holes, G81, tool T3)
G21 G17 G90 G94 G40 G49
T3 M6
G43 H3
S1000 M3
G0 Z10
G0 X10 Y10
G98 G81 X10 Y10 Z-5 R2 F150
X30
G80
G0 Z10
M5
M2
)";

// [cutting] such that the law would cap nothing at F508 with its own ball (r 5 mm, 4 teeth:
// 8000 sqrt(2 r R - R^2) = 1131 mm/min), but caps a ball of r 3.175 mm with 2 teeth.
const char* kToolKindsMachine = R"([cutting]
ball_radius_mm = 5.0
pick_feed_mm = 0.0
teeth = 4
spindle_rpm = 2000.0
roughness_target_um = 2.0

[program]
tool_table = "tool.tbl"
)";

// The law's feed on a horizontal surface (α = 0) with no pick feed (docs/feedrate.md §1): the
// dead-centre branch (eq. 6) R = r (1 - sqrt(1 - (f_t/r)^2)) gives f_t = sqrt(2 r R - R^2),
// below eq. 5's sqrt(8 r R); F = f_t z N.
double closed_form_mm_per_min(double r_mm, double target_um, int teeth, double rpm) {
  const double R = target_um * 1e-3;
  return std::sqrt(2.0 * r_mm * R - R * R) * teeth * rpm;
}

class ToolKinds : public Cli {
 protected:
  // rs274 reads the program with the table: it must accept both.
  void expect_rs274_accepts(const std::string& program, const std::string& table) {
    const fs::path home = dir_ / "rs274_home", out = dir_ / "rs274.out";
    fs::create_directories(home);
    const std::string cmd =
        ncd::test::rs274_command(home, "-t " + table + " -g " + program + " " + out.string() +
                                           " >" + (dir_ / "rs274.log").string() + " 2>&1");
    ASSERT_EQ(std::system(cmd.c_str()), 0) << slurp(dir_ / "rs274.log");
    const std::string text = slurp(out);
    EXPECT_EQ(ncd::test::rs274_complaint(text + slurp(dir_ / "rs274.log")), "") << text;
    EXPECT_TRUE(ncd::test::canonical_moves(text).program_end);
  }

  struct Run {
    CmdResult r;
    nlohmann::json report;
    std::string csv;
  };
  Run replay(const std::string& program_text, const std::string& table_text,
             const std::string& machine_text = kToolKindsMachine) {
    const std::string program = write("p.ngc", program_text);
    const std::string table = write("tool.tbl", table_text);
    const std::string machine = write("m.toml", machine_text);
    expect_rs274_accepts(program, table);
    const fs::path report = dir_ / "r.json", csv = dir_ / "sp.csv";
    Run run{ncd("replay " + program + " --machine " + machine + " --report " + report.string() +
                " --setpoints " + csv.string()),
            {},
            {}};
    if (run.r.status == 0) {
      run.report = nlohmann::json::parse(slurp(report));
      run.csv = slurp(csv);
    }
    return run;
  }

  // The feed between consecutive setpoints (mm/min, from their positions) on the pocket's long
  // passes (Y on a pass, X within 10..50 mm, the cutting depth), and the limits named there.
  struct Passes {
    double feed_min = 1e300, feed_max = 0.0;
    int periods = 0;
    std::vector<std::string> limits;
  };
  static Passes passes(const std::string& csv) {
    Passes p;
    std::istringstream in(csv);
    std::string line;
    std::getline(in, line);  // header
    double t0 = 0.0, x0 = 0.0, y0 = 0.0, z0 = 0.0;
    bool have = false;
    while (std::getline(in, line)) {
      double t, x, y, z, f;
      char limit[64] = {};
      if (std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf,%lf,%63s", &t, &x, &y, &z, &f, limit) != 6) {
        continue;
      }
      const bool on_pass = std::abs(z - 8.0) < 1e-6 && x > 10.0 && x < 50.0 && x0 > 10.0 &&
                           x0 < 50.0 && std::abs(y - y0) < 1e-9 &&
                           std::abs(y - 5.0 * std::round(y / 5.0)) < 1e-9;
      if (have && on_pass) {
        const double v = std::hypot(x - x0, y - y0, z - z0) / (t - t0) * 60.0;
        p.feed_min = std::min(p.feed_min, v);
        p.feed_max = std::max(p.feed_max, v);
        ++p.periods;
        p.limits.emplace_back(limit);
      }
      t0 = t, x0 = x, y0 = y, z0 = z;
      have = true;
    }
    return p;
  }
};

// The flat end mill: the walked feed is the program's F508 on the long passes, the binding
// limit is the program's, the law capped nothing and predicts no roughness.
TEST_F(ToolKinds, FlatEndMillPocketRunsAtItsProgrammedFeed) {
  const Run run = replay(kPocket, "T1 P1 D6.35 Z10 ;kind=flat teeth=2 1/4 in end mill\n");
  ASSERT_EQ(run.r.status, 0) << run.r.err;
  const Passes p = passes(run.csv);
  ASSERT_GT(p.periods, 500);
  // Positions are printed to 1e-6 mm: the feed from them is good to 60 * 2e-6 / 0.004 mm/min.
  EXPECT_NEAR(p.feed_max, 508.0, 0.05);
  EXPECT_NEAR(p.feed_min, 508.0, 0.05);
  for (const std::string& l : p.limits) EXPECT_NE(l, "roughness");
  const auto& j = run.report;
  EXPECT_FALSE(j["active_limit_share"].contains("roughness")) << j["active_limit_share"];
  EXPECT_EQ(j["capped_moves_total"].get<int>(), 0);
  EXPECT_EQ(j["roughness_max_um"].get<double>(), 0.0);
  ASSERT_EQ(j["tools"].size(), 1u);
  EXPECT_EQ(j["tools"][0]["tool"], 1);
  EXPECT_EQ(j["tools"][0]["kind"], "flat");
  EXPECT_EQ(j["tools"][0]["roughness_law"], false);
  EXPECT_EQ(j["tools"][0]["teeth"], 2);
  EXPECT_DOUBLE_EQ(j["tools"][0]["radius_mm"].get<double>(), 3.175);
  EXPECT_NEAR(j["tools"][0]["walked_feed_max_mm_per_min"].get<double>(), 508.0, 1e-9);
  EXPECT_NE(run.r.err.find("T1 flat"), std::string::npos) << run.r.err;
  EXPECT_NE(run.r.err.find("not capped"), std::string::npos) << run.r.err;
}

// The same pocket with a ball end of the table's radius and teeth: every long pass is capped
// at the law's closed form for that ball (r = 6.35 / 2 mm, z = 2), not [cutting]'s (r 5, z 4,
// which would leave F508 alone).
TEST_F(ToolKinds, BallEndIsCappedAtTheClosedFormOfItsOwnRadius) {
  const Run run = replay(kPocket, "T1 P1 D6.35 Z10 ;kind=ball teeth=2\n");
  ASSERT_EQ(run.r.status, 0) << run.r.err;
  const double law = closed_form_mm_per_min(3.175, 2.0, 2, 2000.0);  // 450.71 mm/min
  ASSERT_LT(law, 508.0);
  ASSERT_GT(closed_form_mm_per_min(5.0, 2.0, 4, 2000.0), 508.0);
  const auto& j = run.report;
  const auto& capped = j["capped_moves"];
  ASSERT_FALSE(capped.empty());
  bool pass_seen = false;
  for (const auto& c : capped) {
    EXPECT_EQ(c["tool"], 1);
    EXPECT_EQ(c["kind"], "ball");
    EXPECT_DOUBLE_EQ(c["ball_radius_mm"].get<double>(), 3.175);
    if (c["programmed_feed_mm_per_min"].is_null() ||
        c["programmed_feed_mm_per_min"].get<double>() != 508.0) {
      continue;
    }
    pass_seen = true;
    EXPECT_NEAR(c["capped_feed_mm_per_min"].get<double>(), law, 1e-9 * law);
    EXPECT_NEAR(c["walked_feed_max_mm_per_min"].get<double>(), law, 1e-9 * law);
  }
  EXPECT_TRUE(pass_seen) << capped;
  const Passes p = passes(run.csv);
  ASSERT_GT(p.periods, 500);
  EXPECT_NEAR(p.feed_max, law, 0.05);
  EXPECT_NEAR(p.feed_min, law, 0.05);
  for (const std::string& l : p.limits) EXPECT_EQ(l, "roughness");
  EXPECT_EQ(j["tools"][0]["roughness_law"], true);
  // At the capped feed the model's R_max on the horizontal passes is the target.
  EXPECT_NEAR(j["roughness_max_um"].get<double>(), 2.0, 1e-6);
}

// A ball of its own that the law cannot hold (target 2 um at or above a 1.5 um radius) is
// refused naming the tool and its line, as [cutting] would be.
TEST_F(ToolKinds, ABallTheLawCannotHoldIsRefusedNamingTheTool) {
  const Run run = replay(kPocket, "T1 P1 D0.003 Z10 ;kind=ball\n");
  EXPECT_EQ(run.r.status, 2) << run.r.err;
  for (const char* part : {"tool T1", "ball end of radius 0.0015 mm", "roughness_target_um"}) {
    EXPECT_NE(run.r.err.find(part), std::string::npos) << part << "\n" << run.r.err;
  }
}

// A table entry with no kind: nobody said it is a ball end, so the law does not cap it.
TEST_F(ToolKinds, TableEntryWithNoKindIsNotCapped) {
  const Run run = replay(kPocket, "T1 P1 D6.35 Z10 ;1/4 in cutter\n");
  ASSERT_EQ(run.r.status, 0) << run.r.err;
  const Passes p = passes(run.csv);
  ASSERT_GT(p.periods, 500);
  EXPECT_NEAR(p.feed_max, 508.0, 0.05);
  EXPECT_NEAR(p.feed_min, 508.0, 0.05);
  EXPECT_EQ(run.report["tools"][0]["kind"], "unknown");
  EXPECT_EQ(run.report["capped_moves_total"].get<int>(), 0);
  EXPECT_EQ(run.report["roughness_max_um"].get<double>(), 0.0);
  EXPECT_NE(run.r.err.find("no kind stated"), std::string::npos) << run.r.err;
}

// A drill's plunges get no R_max prediction; the same holes with a ball end do.
TEST_F(ToolKinds, DrillPlungeHasNoRoughnessPrediction) {
  const Run drill = replay(kDrill, "T3 P3 D8 Z20 ;kind=drill\n");
  ASSERT_EQ(drill.r.status, 0) << drill.r.err;
  EXPECT_EQ(drill.report["roughness_max_um"].get<double>(), 0.0);
  EXPECT_EQ(drill.report["tools"][0]["kind"], "drill");
  EXPECT_EQ(drill.report["capped_moves_total"].get<int>(), 0);
  EXPECT_NEAR(drill.report["tools"][0]["walked_feed_max_mm_per_min"].get<double>(), 150.0, 1e-9);
  const Run ball = replay(kDrill, "T3 P3 D8 Z20 ;kind=ball\n");
  ASSERT_EQ(ball.r.status, 0) << ball.r.err;
  EXPECT_GT(ball.report["roughness_max_um"].get<double>(), 0.0);
}

// A tool change between kinds: each move reports the tool that cut it.
TEST_F(ToolKinds, EachMoveNamesItsTool) {
  std::string two = kPocket;
  two.replace(two.find("M5\nM2\n"), 6,
              "T3 M6\nG43 H3\nG0 X10 Y10\nG81 X10 Y10 Z-5 R2 F150\nG80\nM5\nM2\n");
  const Run run = replay(two, "T1 P1 D6.35 Z10 ;kind=ball teeth=2\nT3 P3 D8 Z20 ;kind=drill\n");
  ASSERT_EQ(run.r.status, 0) << run.r.err;
  const auto& runs = run.report["tool_runs"];
  ASSERT_GE(runs.size(), 2u) << runs;
  EXPECT_EQ(runs.front()["tool"], 1);
  EXPECT_EQ(runs.front()["kind"], "ball");
  EXPECT_EQ(runs.back()["tool"], 3);
  EXPECT_EQ(runs.back()["kind"], "drill");
  for (const auto& c : run.report["capped_moves"]) EXPECT_EQ(c["tool"], 1);
}

// The machine file's [tools.N] declares the same as the table's comment.
TEST_F(ToolKinds, MachineFileDeclaresAKind) {
  const std::string machine =
      std::string(kToolKindsMachine) + "\n[tools.1]\nkind = \"flat\"\nteeth = 3\n";
  const Run run = replay(kPocket, "T1 P1 D6.35 Z10\n", machine);
  ASSERT_EQ(run.r.status, 0) << run.r.err;
  EXPECT_EQ(run.report["tools"][0]["kind"], "flat");
  EXPECT_EQ(run.report["tools"][0]["teeth"], 3);
  EXPECT_EQ(run.report["machine"]["tools"]["1"]["kind"], "flat");
  EXPECT_EQ(run.report["capped_moves_total"].get<int>(), 0);
}

TEST_F(ToolKinds, UnknownKindInTheTableNamesValueKindsAndLine) {
  const Run run = replay(kPocket, "; my tools\nT1 P1 D6.35 Z10 ;kind=ballnose\n");
  EXPECT_EQ(run.r.status, 2);
  for (const char* part : {"tool.tbl:2", "kind=ballnose", "ball, flat, bull_nose, drill"}) {
    EXPECT_NE(run.r.err.find(part), std::string::npos) << part << "\n" << run.r.err;
  }
  EXPECT_FALSE(fs::exists(dir_ / "r.json"));
}

TEST_F(ToolKinds, UnknownKindInTheMachineFileNamesKeyValueAndKinds) {
  const std::string machine = std::string(kToolKindsMachine) + "\n[tools.1]\nkind = \"endmill\"\n";
  const Run run = replay(kPocket, "T1 P1 D6.35 Z10\n", machine);
  EXPECT_EQ(run.r.status, 2);
  for (const char* part : {"m.toml", "tools.1.kind", "endmill", "ball, flat, bull_nose, drill"}) {
    EXPECT_NE(run.r.err.find(part), std::string::npos) << part << "\n" << run.r.err;
  }
}

TEST_F(ToolKinds, TableAndMachineFileThatDisagreeAreRefused) {
  const std::string machine = std::string(kToolKindsMachine) + "\n[tools.1]\nkind = \"ball\"\n";
  const Run run = replay(kPocket, "T1 P1 D6.35 Z10 ;kind=flat\n", machine);
  EXPECT_EQ(run.r.status, 2);
  for (const char* part : {"T1", "tool.tbl:1", "[tools.1]", "flat", "ball"}) {
    EXPECT_NE(run.r.err.find(part), std::string::npos) << part << "\n" << run.r.err;
  }
}

// [tool] is the ball end ncd's own jobs cut with: one declared flat is refused for such a job.
TEST_F(ToolKinds, TheChamferToolCannotBeDeclaredFlat) {
  const std::string machine = "[tool]\nnumber = 1\n\n[tools.1]\nkind = \"flat\"\n";
  const CmdResult r = ncd("replay " + std::string(NCD_SOURCE_DIR) +
                          "/examples/cubic.json --machine " + write("m.toml", machine));
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("[tool] number = 1"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("[tools.1]"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("flat"), std::string::npos) << r.err;
}

// ncd's own jobs (a chamfer, a path file) are cut by [tool], a ball end: still capped.
TEST_F(ToolKinds, GeneratedJobsAreCutByABallEnd) {
  const fs::path report = dir_ / "r.json";
  const CmdResult r = ncd("replay " + std::string(NCD_SOURCE_DIR) +
                          "/examples/cubic.json --report " + report.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = nlohmann::json::parse(slurp(report));
  ASSERT_EQ(j["tools"].size(), 1u) << j["tools"];
  EXPECT_EQ(j["tools"][0]["tool"], 1);
  EXPECT_EQ(j["tools"][0]["kind"], "ball");
  EXPECT_EQ(j["tools"][0]["roughness_law"], true);
  EXPECT_DOUBLE_EQ(j["tools"][0]["ball_radius_mm"].get<double>(), 5.0);  // [cutting]'s default
  EXPECT_GT(j["roughness_max_um"].get<double>(), 0.0);
}

}  // namespace
