// The `ncd` executable as a user meets it: exit codes, messages, files written or not, and the
// JSON contract and NC program of `ncd chamfer`.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <numbers>
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

const std::string kExp3 =
    "chamfer --pipe-radius 18 --drill-radius 13 --ball-radius 3 --width 0.7 --tolerance 0.01 "
    "--rod-radius 1.8 --non-knife-angle 93";

TEST_F(Cli, HelpOnEverySubcommandExitsZero) {
  EXPECT_EQ(ncd("--help").status, 0);
  const CmdResult r = ncd("chamfer --help");
  EXPECT_EQ(r.status, 0);
  for (const char* flag : {"--pipe-radius", "--drill-radius", "--ball-radius", "--width",
                           "--tolerance", "--edge", "--side", "--rod-radius", "--non-knife-angle",
                           "--no-avoid", "--format", "--feed", "--spindle"}) {
    EXPECT_NE(r.out.find(flag), std::string::npos) << flag;
  }
}

TEST_F(Cli, NoSubcommandOrUnknownFlagIsInvalidInput) {
  EXPECT_EQ(ncd("").status, 2);
  EXPECT_EQ(ncd("chamfer --frobnicate 3").status, 2);
}

// As people type (issue: `--pipe-raduis` said "--pipe-radius is required", `ncd chamfr --help`
// printed the main help with exit 0): a misspelt command or flag is named, with the nearest
// known one, exit 2, and nothing runs.
TEST_F(Cli, MisspeltCommandsAndFlagsAreNamedWithTheNearestOne) {
  struct Case {
    std::string args, says;
  };
  const std::vector<Case> cases = {
      {"chamfr --help", "unknown command 'chamfr'; did you mean 'chamfer'?"},
      {"chamfer --pipe-raduis 18",
       "unknown flag --pipe-raduis of ncd chamfer; did you mean "
       "--pipe-radius? (`ncd help chamfer` lists the flags)"},
      {"replay p.ngc --machin m.toml",
       "unknown flag --machin of ncd replay; did you mean --machine?"},
      {"bench latncy", "unknown command 'latncy' of ncd bench; did you mean 'latency'?"},
      {"bench latency --secnds 1",
       "unknown flag --secnds of ncd bench latency; did you mean "
       "--seconds?"},
      {"--versoin", "unknown flag --versoin of ncd; did you mean --version?"},
      {"help strem", "unknown command 'strem'; did you mean 'stream'?"},
      {"frobnicate", "unknown command 'frobnicate'; the commands are chamfer, replay"},
      {"chamfer -z", "unknown flag -z of ncd chamfer (`ncd help chamfer` lists the flags)"},
  };
  for (const Case& c : cases) {
    const CmdResult r = ncd(c.args);
    EXPECT_EQ(r.status, 2) << c.args;
    EXPECT_NE(r.err.find("ncd: error: " + c.says), std::string::npos) << c.args << ": " << r.err;
  }
  // Values that look like flags are values: a negative start, a list of them.
  const CmdResult r = ncd("replay missing.ngc --start -1,-2.5,3");
  EXPECT_EQ(r.err.find("unknown flag"), std::string::npos) << r.err;
}

TEST_F(Cli, HelpAndVersionAsPeopleType) {
  const CmdResult help = ncd("help");
  EXPECT_EQ(help.status, 0);
  EXPECT_EQ(help.out, ncd("--help").out);
  const CmdResult chamfer = ncd("help chamfer");
  EXPECT_EQ(chamfer.status, 0);
  EXPECT_EQ(chamfer.out, ncd("chamfer --help").out);
  EXPECT_NE(chamfer.out.find("--pipe-radius"), std::string::npos) << chamfer.out;
  EXPECT_EQ(ncd("help bench latency").out, ncd("bench latency --help").out);
  // The version names the commit: the checkout's own, as git describes it.
  const CmdResult v = ncd("--version");
  EXPECT_EQ(v.status, 0);
  EXPECT_EQ(ncd("-V").out, v.out);
  EXPECT_EQ(v.out.rfind("ncd ", 0), 0U) << v.out;
  const fs::path head_file = dir_ / "head";
  // As app/commit_header.cmake asks (a tag, if there is one, names the commit as it does).
  const std::string git = "git -C " + std::string(NCD_SOURCE_DIR) +
                          " describe --always --abbrev=12 >" + head_file.string() + " 2>/dev/null";
  if (std::system(git.c_str()) != 0) {  // a source tree that is not a checkout
    EXPECT_NE(v.out.find("(commit unknown: not built from a git checkout)"), std::string::npos)
        << v.out;
    return;
  }
  std::string head = slurp(head_file);
  head = head.substr(0, head.find('\n'));
  EXPECT_NE(v.out.find("(commit " + head), std::string::npos) << v.out << " vs HEAD " << head;
}

TEST_F(Cli, JsonContractOfExperiment3) {
  const CmdResult r = ncd(kExp3 + " -q");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  for (const char* key : {"pipe_radius_mm", "drill_radius_mm", "ball_radius_mm", "width_mm",
                          "tolerance_mm", "edge", "side", "rod_radius_mm", "non_knife_angle_deg",
                          "avoid", "feed_mm_per_min", "spindle_rpm"}) {
    EXPECT_TRUE(j["input"].contains(key)) << key;
  }
  EXPECT_EQ(j["input"]["non_knife_angle_deg"].get<double>(), 93.0);
  ASSERT_EQ(j["segments"].get<std::size_t>(), j["points"].size());
  for (const auto& p : j["points"]) {
    for (const char* key : {"theta", "xp", "cl", "e", "alpha", "delta", "width", "projected_width",
                            "inv_ke", "minus_ez", "cl_radius"}) {
      ASSERT_TRUE(p.contains(key)) << key;
    }
    EXPECT_NEAR(p["width"].get<double>(), 0.7, 1e-9);
    const auto cl = p["cl"].get<std::vector<double>>();
    EXPECT_NEAR(std::hypot(cl[0], cl[1]), p["cl_radius"].get<double>(), 1e-12);
  }
  const auto& ck = j["checks"];
  EXPECT_TRUE(ck["local"]["ok"].get<bool>());
  EXPECT_TRUE(ck["global"]["ok"].get<bool>());
  EXPECT_TRUE(ck["rod"]["ok"].get<bool>());
  EXPECT_LE(ck["rod"]["max_cl_radius"].get<double>(), ck["rod"]["limit_radius"].get<double>());
  EXPECT_GT(ck["rod"]["adjusted_points"].get<int>(), 0);
  EXPECT_GE(j["elapsed_ms"].get<double>(), 0.0);
}

TEST_F(Cli, SameInputsGiveTheSameOutputBesidesTheClock) {
  auto a = nlohmann::json::parse(ncd(kExp3 + " -q").out);
  auto b = nlohmann::json::parse(ncd(kExp3 + " -q").out);
  a.erase("elapsed_ms");
  b.erase("elapsed_ms");
  EXPECT_EQ(a.dump(), b.dump());
  EXPECT_EQ(ncd(kExp3 + " -q --format ngc").out, ncd(kExp3 + " -q --format ngc").out);
}

TEST_F(Cli, CsvHasOneRowPerPoint) {
  const CmdResult r = ncd(kExp3 + " -q --format csv");
  ASSERT_EQ(r.status, 0);
  const auto j = nlohmann::json::parse(ncd(kExp3 + " -q").out);
  std::istringstream in(r.out);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line.rfind("theta_rad,", 0), 0u);
  std::size_t rows = 0;
  while (std::getline(in, line)) ++rows;
  EXPECT_EQ(rows, j["points"].size());
}

// The G1 targets with X, Y and Z of an NC program, in order (not the moves to the drill axis).
std::vector<std::array<double, 3>> g1_points(const std::string& program) {
  std::vector<std::array<double, 3>> pts;
  std::istringstream in(program);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("G1 X", 0) != 0) continue;
    std::array<double, 3> p{};
    if (std::sscanf(line.c_str(), "G1 X%lf Y%lf Z%lf", &p[0], &p[1], &p[2]) == 3) pts.push_back(p);
  }
  return pts;
}

TEST_F(Cli, NcProgramIsAClosedLoopOfTheBallTip) {
  const CmdResult r = ncd(kExp3 + " -q --format ngc --feed 1800 --spindle 3000");
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string& g = r.out;
  EXPECT_EQ(g.rfind("%\n", 0), 0u);
  for (const char* word : {"G21", "G90", "F1800", "S3000 M3", "M5", "M2", "TIP", "width 0.7000"}) {
    EXPECT_NE(g.find(word), std::string::npos) << word;
  }
  const auto j = nlohmann::json::parse(ncd(kExp3 + " -q").out);
  const auto pts = g1_points(g);
  // Approach point, the loop, then the point closing it.
  ASSERT_EQ(pts.size(), j["points"].size() + 1);
  for (std::size_t i = 0; i < j["points"].size(); ++i) {
    const auto cl = j["points"][i]["cl"].get<std::vector<double>>();
    EXPECT_NEAR(pts[i][0], cl[0], 5e-5);
    EXPECT_NEAR(pts[i][1], cl[1], 5e-5);
    EXPECT_NEAR(pts[i][2], cl[2] - 3.0, 5e-5);  // the tip is R_B below the centre
  }
  EXPECT_EQ(pts.front(), pts.back());
}

TEST_F(Cli, LowerEdgeProgramIsForThePartTurnedOver) {
  const std::string lower = kExp3 + " --side lower -q";
  const auto j = nlohmann::json::parse(ncd(lower).out);
  const CmdResult r = ncd(lower + " --format ngc --program-point centre");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("TURNED OVER"), std::string::npos);
  const auto pts = g1_points(r.out);
  const auto cl = j["points"][5]["cl"].get<std::vector<double>>();
  EXPECT_LT(cl[2], 0.0);  // the model keeps the lower edge below the pipe axis
  EXPECT_NEAR(pts[5][0], -cl[0], 5e-5);
  EXPECT_NEAR(pts[5][1], cl[1], 5e-5);
  EXPECT_NEAR(pts[5][2], -cl[2], 5e-5);
}

TEST_F(Cli, InclinedEccentricConeHoleIsWrittenInTheDrillFrame) {
  const std::string lateral =
      "chamfer --pipe-radius 18 --drill-radius 13 --ball-radius 3 --width 0.7 "
      "--drill-tilt-deg 45 --eccentricity 2 --pipe-half-angle-deg 5 --pipe-thickness 3 -q";
  const auto j = nlohmann::json::parse(ncd(lateral).out);
  EXPECT_EQ(j["input"]["drill_tilt_deg"].get<double>(), 45.0);
  EXPECT_EQ(j["input"]["eccentricity_mm"].get<double>(), 2.0);
  EXPECT_EQ(j["input"]["frame"].get<std::string>(), "drill");
  const CmdResult r = ncd(lateral + " --format ngc --program-point centre");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("DRILL AXIS VERTICAL"), std::string::npos) << r.out.substr(0, 1500);
  EXPECT_NE(r.out.find("rising 45.000 deg"), std::string::npos) << r.out.substr(0, 1500);
  const auto pts = g1_points(r.out);
  ASSERT_EQ(pts.size(), j["points"].size() + 1);
  for (std::size_t i = 0; i < j["points"].size(); ++i) {
    const auto cl = j["points"][i]["cl"].get<std::vector<double>>();
    EXPECT_NEAR(pts[i][0], cl[0], 5e-5);
    EXPECT_NEAR(pts[i][2], cl[2], 5e-5);
  }
  // LinuxCNC's own interpreter reads the program: one straight feed per point, plus the
  // approach down the axis, the closing move and the way back to the axis.
  const fs::path ngc = dir_ / "lateral.ngc", canon = dir_ / "lateral.canon";
  ASSERT_EQ(ncd(lateral + " --format ngc -o " + ngc.string()).status, 0);
  if (fs::exists(ncd::test::kRs274)) {
    const std::string cmd =
        ncd::test::rs274_command(dir_, "-g " + ngc.string()) + " > " + canon.string() + " 2>&1";
    EXPECT_EQ(std::system(cmd.c_str()), 0) << slurp(canon);
    std::istringstream lines(slurp(canon));
    std::size_t feeds = 0;
    for (std::string line; std::getline(lines, line);) {
      feeds += line.find("STRAIGHT_FEED") != std::string::npos;
    }
    EXPECT_EQ(feeds, j["points"].size() + 3);
  }
  const CmdResult pipe = ncd(lateral + " --format ngc --frame pipe");
  EXPECT_EQ(pipe.status, 2);
  EXPECT_NE(pipe.err.find("tilt τ = 45.000 deg"), std::string::npos) << pipe.err;
  const CmdResult miss = ncd(
      "chamfer --pipe-radius 18 --drill-radius 13 --ball-radius 3 --width 0.7 --eccentricity 6");
  EXPECT_EQ(miss.status, 2);
  EXPECT_NE(miss.err.find("does not pierce the inner pipe surface"), std::string::npos) << miss.err;
  const CmdResult tight = ncd(
      "chamfer --pipe-radius 18 --drill-radius 8 --ball-radius 3 --width 0.7 --drill-tilt-deg 60 "
      "--format ngc");
  EXPECT_EQ(tight.status, 2);
  EXPECT_NE(tight.err.find("local: the edge curves more tightly than the ball"), std::string::npos)
      << tight.err;
  EXPECT_NE(tight.err.find("θ ∈ ["), std::string::npos) << tight.err;
  // The JSON reports the same range (no program is refused there).
  const auto tj = nlohmann::json::parse(
      ncd("chamfer --pipe-radius 18 --drill-radius 8 --ball-radius 3 --width 0.7 "
          "--drill-tilt-deg 60 -q")
          .out);
  ASSERT_EQ(tj["checks"]["local"]["fail_theta_deg"].size(), 1u);
  const auto range = tj["checks"]["local"]["fail_theta_deg"][0].get<std::vector<double>>();
  EXPECT_LT(range[0], 90.0);
  EXPECT_GT(range[1], 90.0);
  for (const auto& p : tj["points"]) {
    const double deg = p["theta"].get<double>() * 180.0 / std::numbers::pi;
    EXPECT_EQ(deg >= range[0] && deg <= range[1], p["inv_ke"].get<double>() < 3.0) << deg;
  }
}

TEST_F(Cli, OutputFileAndPlotAreWritten) {
  const fs::path out = dir_ / "exp3.ngc", plot = dir_ / "exp3.svg";
  const CmdResult r = ncd(kExp3 + " --format ngc -o " + out.string() + " --plot " + plot.string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(r.out.empty());
  EXPECT_NE(r.err.find("rod check         ok"), std::string::npos) << r.err;
  EXPECT_NE(slurp(out).find("G1 X"), std::string::npos);
  const std::string svg = slurp(plot);
  EXPECT_NE(svg.find("<svg"), std::string::npos);
  EXPECT_NE(svg.find("R_R (CL must stay below)"), std::string::npos);
  EXPECT_EQ(std::count(svg.begin(), svg.end(), '\n') > 50, true);
}

struct BadCase {
  std::string args, message;
};

TEST_F(Cli, BadInputExitsTwoNamesTheValueAndLeavesNoFile) {
  const std::string geo = "chamfer --pipe-radius 18 --drill-radius 13 --ball-radius 3 ";
  const std::vector<BadCase> cases = {
      {"chamfer --pipe-radius 18 --drill-radius 18 --ball-radius 3 --width 0.7",
       "drill radius r = 18 mm must be smaller than the pipe radius 18 mm"},
      {geo + "--width 0", "--width"},
      {geo + "--width -0.5", "--width"},
      {"chamfer --pipe-radius 18 --drill-radius 13 --ball-radius 0 --width 0.7", "--ball-radius"},
      {geo + "--width nan", "nan"},
      {geo + "--width abc", "--width"},
      {geo + "--width 5", "widest the wedge"},
      {geo + "--width 0.7 --rod-radius 4", "R_R = 9 mm cannot be met"},
      {geo + "--width 0.7 --edge sideways", "--edge"},
      {geo + "--width 0.7 --feed 0 --format ngc", "--feed"},
      {geo + "--width 0.7 --safe-z 5 --format ngc", "safe Z"},
      {"chamfer --pipe-radius 10 --drill-radius 2 --ball-radius 5 --width 0.5 --edge outer "
       "--format ngc",
       "interferes"},
  };
  for (const auto& c : cases) {
    const fs::path out = dir_ / "out.json";
    const CmdResult r =
        ncd(c.args + " -o " + out.string() + " --plot " + (dir_ / "p.svg").string());
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.message), std::string::npos) << c.args << "\n" << r.err;
    EXPECT_FALSE(fs::exists(out)) << c.args;
    EXPECT_FALSE(fs::exists(dir_ / "p.svg")) << c.args;
    for (const auto& entry : fs::directory_iterator(dir_)) {
      const std::string name = entry.path().filename().string();
      EXPECT_TRUE(name == "stdout" || name == "stderr") << "left behind: " << name;
    }
  }
}

TEST_F(Cli, NoAvoidReportsTheInterferenceOfExperiment2) {
  const CmdResult r = ncd(kExp3 + " --no-avoid -q");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_FALSE(j["checks"]["rod"]["ok"].get<bool>());
  EXPECT_EQ(j["checks"]["rod"]["adjusted_points"].get<int>(), 0);
  EXPECT_NEAR(j["checks"]["rod"]["max_cl_radius"].get<double>(), 11.141, 5e-4);
  // A deliberate test cut may still be written as a program, with the header saying so.
  const CmdResult g = ncd(kExp3 + " --no-avoid -q --format ngc");
  EXPECT_EQ(g.status, 0);
  EXPECT_NE(g.out.find("rod INTERFERES"), std::string::npos);
}

TEST_F(Cli, UnwritableOutputIsInvalidInput) {
  const CmdResult r = ncd(kExp3 + " -q -o " + (dir_ / "missing" / "out.json").string());
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("cannot create"), std::string::npos) << r.err;
}

}  // namespace
