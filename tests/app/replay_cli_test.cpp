// `ncd replay` as a user meets it: the report contract, the setpoints file, determinism, every
// input format, and configurations that cannot be met.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "tests/app/cli_fixture.hpp"

namespace {

using ncd::test::Cli;
using ncd::test::CmdResult;
using ncd::test::slurp;
namespace fs = std::filesystem;

const std::string kChamfer =
    "chamfer --pipe-radius 18 --drill-radius 13 --ball-radius 3 --width 0.7 --rod-radius 1.8 "
    "--non-knife-angle 93 -q";
const std::string kMachine = std::string(NCD_SOURCE_DIR) + "/config/chamfer-exp3.toml";

const char* kCubic = R"({"nurbs": {"degree": 3, "knots": [0,0,0,0,0.25,0.5,0.75,1,1,1,1],
  "points": [[0,0,0],[10,25,0],[30,-10,2],[45,30,4],[60,0,3],[80,20,0],[100,0,0]]}})";

class Replay : public Cli {
 protected:
  // The experiment-3 chamfer JSON, written by `ncd chamfer` itself.
  std::string chamfer_json() {
    const std::string path = (dir_ / "exp3.json").string();
    EXPECT_EQ(ncd(kChamfer + " -o " + path).status, 0);
    return path;
  }
};

TEST_F(Replay, HelpNamesTheOutputs) {
  const CmdResult r = ncd("replay --help");
  EXPECT_EQ(r.status, 0);
  for (const char* flag : {"--machine", "--setpoints", "--report", "--plot"}) {
    EXPECT_NE(r.out.find(flag), std::string::npos) << flag;
  }
}

TEST_F(Replay, ReportAndSetpointsOfTheChamfer) {
  const std::string json = chamfer_json();
  const fs::path csv = dir_ / "sp.csv", report = dir_ / "r.json", plot = dir_ / "p.svg";
  const CmdResult r =
      ncd("replay " + json + " --machine " + kMachine + " --setpoints " + csv.string() +
          " --report " + report.string() + " --plot " + plot.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = nlohmann::json::parse(slurp(report));
  for (const char* key :
       {"cycles", "duration_s", "path_length_mm", "feed_error", "arc_length_drift_mm",
        "chord_error_max_mm", "accel_max", "jerk_max", "limit_violations", "roughness_max_um",
        "active_limit_share", "step_time_ns"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  for (const char* key : {"median", "p99", "max"}) EXPECT_TRUE(j["step_time_ns"].contains(key));
  EXPECT_TRUE(j["feed_error"].contains("max_rel"));
  EXPECT_TRUE(j["feed_error"].contains("rms_rel"));
  EXPECT_EQ(j["limit_violations"].get<int>(), 0);
  EXPECT_LE(std::abs(j["arc_length_drift_mm"].get<double>()), 1e-6);
  EXPECT_LE(j["chord_error_max_mm"].get<double>(), 0.001 * (1 + 1e-6));
  EXPECT_LE(j["roughness_max_um"].get<double>(), 0.05 * (1 + 1e-6));  // the machine's target
  EXPECT_GT(j["active_limit_share"]["roughness"].get<double>(), 0.5);
  double share = 0.0;
  for (const auto& [name, v] : j["active_limit_share"].items()) share += v.get<double>();
  EXPECT_NEAR(share, 1.0, 1e-12);
  // One row per period, the header as documented, the last row at the end of the run.
  std::istringstream in(slurp(csv));
  std::string line, last;
  std::getline(in, line);
  EXPECT_EQ(line, "t_s,x_mm,y_mm,z_mm,feed_mm_per_min,limit");
  std::int64_t rows = 0;
  while (std::getline(in, line)) ++rows, last = line;
  EXPECT_EQ(rows, j["cycles"].get<std::int64_t>());
  EXPECT_NEAR(std::stod(last.substr(0, last.find(','))), j["duration_s"].get<double>(), 1e-9);
  EXPECT_NE(last.find(",0.0000,"), std::string::npos) << "ends at rest: " << last;
  EXPECT_NE(slurp(plot).find("roughness"), std::string::npos);
}

TEST_F(Replay, SameInputsGiveByteIdenticalOutputs) {
  const std::string json = chamfer_json();
  std::string csv[2], svg[2];
  nlohmann::json rep[2];
  for (int i = 0; i < 2; ++i) {
    const std::string n = std::to_string(i);
    ASSERT_EQ(ncd("replay " + json + " --machine " + kMachine + " -q --setpoints " +
                  (dir_ / ("s" + n)).string() + " --plot " + (dir_ / ("p" + n)).string() +
                  " --report " + (dir_ / ("r" + n)).string())
                  .status,
              0);
    csv[i] = slurp(dir_ / ("s" + n));
    svg[i] = slurp(dir_ / ("p" + n));
    rep[i] = nlohmann::json::parse(slurp(dir_ / ("r" + n)));
    rep[i].erase("step_time_ns");  // wall-clock measurements: the only fields that may differ
    rep[i].erase("lookahead_sampling_ms");
  }
  EXPECT_FALSE(csv[0].empty());
  EXPECT_EQ(csv[0], csv[1]);
  EXPECT_EQ(svg[0], svg[1]);
  EXPECT_EQ(rep[0].dump(), rep[1].dump());
}

TEST_F(Replay, NurbsJsonAndGcodeInputs) {
  const std::string cubic = write("cubic.json", kCubic);
  CmdResult r = ncd("replay " + cubic + " -q --report " + (dir_ / "c.json").string());
  ASSERT_EQ(r.status, 0) << r.err;
  auto j = nlohmann::json::parse(slurp(dir_ / "c.json"));
  EXPECT_EQ(j["limit_violations"].get<int>(), 0);
  EXPECT_LE(j["feed_error"]["max_rel"].get<double>(), 1e-9);
  // The chamfer's own NC program, with its approach and retract, replays too.
  const std::string ngc = (dir_ / "exp3.ngc").string();
  ASSERT_EQ(ncd(kChamfer + " --format ngc -o " + ngc).status, 0);
  r = ncd("replay " + ngc + " --machine " + kMachine + " -q --report " +
          (dir_ / "g.json").string());
  ASSERT_EQ(r.status, 0) << r.err;
  j = nlohmann::json::parse(slurp(dir_ / "g.json"));
  EXPECT_EQ(j["limit_violations"].get<int>(), 0);
  EXPECT_GT(j["path_length_mm"].get<double>(), 70.6);  // the loop plus approach and retract
  // A LinuxCNC G5.2 block (the current position is its first control point).
  const std::string g52 = write("g52.ngc",
                                "G21 G90\nG0 X0 Y0 Z1\nG1 F1200\n"
                                "G5.2 X10 Y20 P1 L4\nX30 Y-10 P2\nX40 Y10 P1\nX45 Y0 P1\nG5.3\n"
                                "G1 X50 Y10\nM2\n");
  r = ncd("replay " + g52 + " -q --report " + (dir_ / "n.json").string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(slurp(dir_ / "n.json"))["limit_violations"].get<int>(), 0);
}

struct BadReplay {
  std::string machine, path, message;
};

TEST_F(Replay, ConfigurationsThatCannotBeMetAreClearErrors) {
  const std::string cubic = write("cubic.json", kCubic);
  const std::vector<BadReplay> cases = {
      {"max_feed_mm_per_min = 6000\nfeedrate = 3\n", cubic, "unknown key"},
      {"[cutting]\nball_radius_mm = 5\npick_feed_mm = 0.5\nroughness_target_um = 1\n", cubic,
       "pick"},
      {"max_accel_mm_per_s2 = -1000\n", cubic, "max_accel"},
      {"period_s = 0\n", cubic, "period"},
      {"max_jerk_mm_per_s3 = \"fast\"\n", cubic, "must be a number"},
      {"", write("arc.ngc", "G21 G90\nG0 X0 Y0 Z0\nG2 X10 Y0 I5 J0 F100\n"), "arc.ngc:3:"},
      // A G5.2 block whose first point repeats the current position: a cusp at the start.
      {"",
       write("cusp.ngc",
             "G21 G90\nG0 X0 Y0 Z1\nG1 F600\nG5.2 X0 Y0 P1 L4\nX10 Y20 P1\n"
             "X30 Y-10 P1\nG5.3\nM2\n"),
       "full stop"},
      {"", (dir_ / "missing.json").string(), "missing.json"},
  };
  for (const auto& c : cases) {
    const std::string machine = write("m.toml", c.machine);
    const fs::path csv = dir_ / "out.csv";
    const CmdResult r =
        ncd("replay " + c.path + " --machine " + machine + " --setpoints " + csv.string());
    EXPECT_EQ(r.status, 2) << c.machine << "\n" << r.err;
    EXPECT_NE(r.err.find(c.message), std::string::npos) << c.machine << "\n" << r.err;
    EXPECT_FALSE(fs::exists(csv));
  }
}

}  // namespace
