// What `ncd replay` refuses before any motion (a chamfer whose checks failed, a chamfer made for
// another tool, a path outside the machine's envelope, a run too long or too large) and what it
// refuses after the walk (the step rule, a report with violations): exit 2 or 3, a message
// naming the value and the limit, no setpoints and no blocks written.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>
#include <tuple>

#include "tests/app/cli_fixture.hpp"
#include "tests/common/sanitized.hpp"

namespace {

using ncd::test::Cli;
using ncd::test::CmdResult;
using ncd::test::slurp;
namespace fs = std::filesystem;

const std::string kSource = std::string(NCD_SOURCE_DIR);

class RefuseCli : public Cli {
 protected:
  std::string chamfer(const std::string& name, double ball_radius_mm) {
    const std::string out = (dir_ / name).string();
    const CmdResult r =
        ncd("chamfer --pipe-radius 18 --drill-radius 13 --width 0.7 --tolerance 0.01 -q "
            "--ball-radius " +
            std::to_string(ball_radius_mm) + " -o " + out);
    EXPECT_EQ(r.status, 0) << r.err;
    return out;
  }
  // The outputs of a refused run: none of them may exist.
  void expect_nothing_written() {
    EXPECT_FALSE(fs::exists(dir_ / "sp.csv"));
    EXPECT_FALSE(fs::exists(dir_ / "b.ngc"));
    for (const auto& e : fs::directory_iterator(dir_)) {
      EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
    }
  }
  std::string outputs() const {
    return " --setpoints " + (dir_ / "sp.csv").string() + " --blocks " + (dir_ / "b.ngc").string();
  }
};

TEST_F(RefuseCli, ChamferWhoseChecksFailedIsRefusedUnlessAllowed) {
  const std::string big = chamfer("big.json", 12.0);  // a 12 mm ball in a 13 mm hole
  const auto checks = nlohmann::json::parse(slurp(big))["checks"];
  ASSERT_FALSE(checks["local"]["ok"].get<bool>() && checks["global"]["ok"].get<bool>() &&
               checks["rod"]["ok"].get<bool>());
  const CmdResult r = ncd("replay -q " + big + outputs());
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("failed its interference checks"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--allow-interference"), std::string::npos) << r.err;
  expect_nothing_written();
  // Allowed: walked, and every output says so.
  const std::string report = (dir_ / "r.json").string();
  const CmdResult ok = ncd("replay -q --allow-interference " + big + " --report " + report +
                           " --blocks " + (dir_ / "b.ngc").string());
  ASSERT_EQ(ok.status, 0) << ok.err;
  EXPECT_NE(ok.err.find("WARNING"), std::string::npos) << ok.err;
  EXPECT_TRUE(nlohmann::json::parse(slurp(report))["interference_allowed"].get<bool>());
  EXPECT_EQ(slurp(dir_ / "b.ngc").rfind("(ncd: the chamfer failed its interference checks", 0), 0u);
}

TEST_F(RefuseCli, ChamferForAnotherBallRadiusIsAnErrorNamingBoth) {
  const std::string exp3 = chamfer("exp3.json", 3.0);
  const std::string m5 = write("m5.toml", "[cutting]\nball_radius_mm = 5.0\n");
  const CmdResult r = ncd("replay -q " + exp3 + " --machine " + m5 + outputs());
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("ball radius of 3 mm"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("ball_radius_mm = 5 mm"), std::string::npos) << r.err;
  expect_nothing_written();
  // On the documented defaults the chamfer's own tool is used (its ball, a single pass): the
  // same walk as with the defaults and that tool in a machine file, not the default 5 mm ball.
  const std::string a = (dir_ / "a.json").string(), b = (dir_ / "b.json").string();
  ASSERT_EQ(ncd("replay -q " + exp3 + " --report " + a).status, 0);
  const std::string m3_defaults =
      write("m3d.toml", "[cutting]\nball_radius_mm = 3.0\npick_feed_mm = 0.0\n");
  ASSERT_EQ(ncd("replay -q " + exp3 + " --machine " + m3_defaults + " --report " + b).status, 0);
  const auto ja = nlohmann::json::parse(slurp(a)), jb = nlohmann::json::parse(slurp(b));
  EXPECT_EQ(ja["machine"]["cutting"]["ball_radius_mm"].get<double>(), 3.0);
  EXPECT_EQ(ja["feed_max_mm_per_min"], jb["feed_max_mm_per_min"]);
  EXPECT_EQ(ja["duration_s"], jb["duration_s"]);
}

TEST_F(RefuseCli, HeavyWeightNurbsIsRefusedBeforeAnyMotion) {
  // The two fuzz curves of issues 11 and 13: a rational NURBS whose middle weight is 1576461
  // crawled 8888 s, then jumped 28.1 mm in one period; the rational circle with one weight
  // 517688461 walked at 2e-5 mm/s. Both are refused up front: exit 2, the weights, their ratio
  // and the limit named, nothing written.
  const std::string crawl = write("crawl.json",
                                  R"({"nurbs": {"degree": 2, "knots": [0,0,0,1,1,2,2,2],
          "weights": [1,0.7071067811865476,1576461,0.7071067811865476,1],
          "points": [[0,20,0],[-20,20,0],[-20,0,0],[-20,-20,0],[0,-20,0]]}})");
  const std::string circle = write("circle.json",
                                   R"({"nurbs": {"degree": 2,
          "knots": [0,0,0,0.25,0.25,0.5,0.5,0.75,0.75,1,1,1],
          "points": [[20,0,0],[20,20,0],[0,20,0],[-20,20,0],[-20,0,0],[-20,-20,0],[0,-20,0],
                     [20,-20,0],[20,0,0]],
          "weights": [1,0.7071067811865476,517688461,0.7071067811865476,1,0.7071067811865476,1,
                      0.7071067811865476,1]}})");
  const std::string report = (dir_ / "r.json").string();
  for (const auto& [file, weight, ratio] : {std::tuple<std::string, std::string, std::string>{
                                                crawl, "weight[2] = 1576461", "2229452.52675"},
                                            {circle, "weight[2] = 517688461", "732122042.63"}}) {
    const CmdResult r = ncd("replay -q " + file + outputs() + " --report " + report);
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_NE(r.err.find(weight), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(ratio), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("times weight[1] = 0.7071067811865476"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("at most 100"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("re-export the curve"), std::string::npos) << r.err;
    expect_nothing_written();
  }
}

TEST_F(RefuseCli, PathOutsideTheEnvelopeIsRefusedBeforeAnyMotion) {
  // G1 X20 Y99999999: before, three minutes of CSV and "internal error ... 100 h".
  // The interpreter refuses a coordinate beyond 1 km itself, naming the word and the line.
  const std::string absurd =
      write("absurd.ngc", "G21 G90\nG0 X0 Y0 Z0\nG1 F600 X20 Y99999999\nM2\n");
  const CmdResult a = ncd("replay -q " + absurd + outputs());
  EXPECT_EQ(a.status, 2) << a.err;
  EXPECT_NE(a.err.find("absurd.ngc:3: Y1e+08"), std::string::npos) << a.err;
  expect_nothing_written();
  // A plausible coordinate beyond the machine's travel is the envelope's refusal.
  const std::string far = write("far.ngc", "G21 G90\nG0 X0 Y0 Z0\nG1 F600 X20 Y99999\nM2\n");
  const CmdResult r = ncd("replay -q " + far + outputs());
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("Y = 99999 mm is outside the machine's travel -2000 .. 2000 mm"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("line 3"), std::string::npos) << r.err;
  expect_nothing_written();
  // The machine file's own envelope.
  const std::string cubic = kSource + "/examples/cubic.json";  // x 0 .. 100 mm, y -10 .. 30
  const std::string small = write("small.toml", "[envelope]\nx_max_mm = 50\n");
  const CmdResult s = ncd("replay -q " + cubic + " --machine " + small + outputs());
  EXPECT_EQ(s.status, 2) << s.err;
  EXPECT_NE(s.err.find("X = "), std::string::npos) << s.err;
  EXPECT_NE(s.err.find("outside the machine's travel -2000 .. 50 mm"), std::string::npos) << s.err;
  expect_nothing_written();
  const std::string wide = write("wide.toml", "[envelope]\nx_max_mm = 100.5\n");
  EXPECT_EQ(ncd("replay -q " + cubic + " --machine " + wide).status, 0);
  // An envelope that is no envelope.
  const std::string bad = write("bad.toml", "[envelope]\nz_min_mm = 5\nz_max_mm = -5\n");
  const CmdResult b = ncd("replay -q " + cubic + " --machine " + bad);
  EXPECT_EQ(b.status, 2);
  EXPECT_NE(b.err.find("z_min_mm"), std::string::npos) << b.err;
}

TEST_F(RefuseCli, RunTooLongOrTooLargeIsRefusedBeforeItStarts) {
  // 1900 mm at 1 mm/min: at least 31.7 h, more than the 24 h of one job (the whole program
  // adds 1 mm of approach at the same feed: 1901 min = 31.6833 h, and its rapids).
  const std::string slow =
      write("slow.json", R"({"polyline":{"points":[[0,0,0],[1900,0,0]]},"feed_mm_per_min":1})");
  const CmdResult r = ncd("replay -q " + slow + outputs());
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("at least 31.683"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("limit of 24 h"), std::string::npos) << r.err;
  expect_nothing_written();
  // 1900 mm at 10 mm/min in 0.1 ms periods: 114 000 000 setpoint rows, about 7.3 GB (and
  // 1 mm of approach: 60 000 more, and the rapids: 114062900).
  const std::string fine = write("fine.toml", "period_s = 0.0001\n");
  const std::string ten =
      write("ten.json", R"({"polyline":{"points":[[0,0,0],[1900,0,0]]},"feed_mm_per_min":10})");
  const CmdResult s = ncd("replay -q " + ten + " --machine " + fine + outputs());
  EXPECT_EQ(s.status, 2) << s.err;
  EXPECT_NE(s.err.find("11406"), std::string::npos) << s.err;
  expect_nothing_written();
}

}  // namespace
