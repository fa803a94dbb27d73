// `ncd simulate` as a user meets it: a paper case with its report and pictures, a replay's
// setpoints with the model per move, and inputs that cannot be simulated.
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "tests/app/cli_fixture.hpp"

namespace {

using ncd::test::Cli;
using ncd::test::CmdResult;
using ncd::test::slurp;

class Simulate : public Cli {};

TEST_F(Simulate, Fig13ReportAndPictures) {
  const std::string d = dir_.string();
  const CmdResult r =
      ncd("simulate --case fig13 --cell-um 10 --report " + d + "/r.json" + " --heightmap " + d +
          "/h.svg --rmax-map " + d + "/m.svg --profile " + d + "/p.svg");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = nlohmann::json::parse(slurp(dir_ / "r.json"));
  EXPECT_EQ(j["paper"]["figure"], "Fig. 13");
  EXPECT_EQ(j["raster"]["inclination_deg"], 10.0);
  EXPECT_NEAR(j["model"]["rmax_um"].get<double>(), 10.669,
              0.001);  // eq. 2 (docs/surface-simulation.md §6)
  EXPECT_EQ(j["model"]["branch"], "eq. 2 (outside)");
  const double sim = j["rmax_um"]["areal"].get<double>();
  EXPECT_NEAR(sim, 10.7, 1.0);
  EXPECT_NEAR(j["difference_um"]["simulation_minus_paper"].get<double>(), sim - 10.7, 1e-3);
  EXPECT_EQ(j["rmax_um"]["uncut_cells"], 0);
  EXPECT_GT(j["simulation"]["cell_updates"].get<double>(), 0.0);
  for (const char* f : {"h.svg", "m.svg"}) {
    const std::string svg = slurp(dir_ / f);
    EXPECT_EQ(svg.rfind("<svg", 0), 0u) << f;
    EXPECT_NE(svg.find("data:image/png;base64,iVBORw0KGgo"), std::string::npos) << f;
  }
  EXPECT_NE(slurp(dir_ / "p.svg").find("across the feed"), std::string::npos);
}

TEST_F(Simulate, ReplaySetpointsGetTheModelOfTheirOwnFeed) {
  // One straight level pass at f_t = 0.5 mm (2 teeth, 10000 rpm: 10000 mm/min) in 4 ms rows; a
  // single pass (f_p = 0) at α = 0 is in the dead-centre zone: eq. 3 gives 25.06 µm.
  std::ostringstream csv;
  csv << "t_s,x_mm,y_mm,z_mm,feed_mm_per_min,limit\n";
  const double v = 10000.0 / 60.0;
  int rows = 0;
  for (double t = 0.0; t <= 2.0 / v + 1e-12; t += 0.004, ++rows) {
    csv << t << "," << -1.0 + v * t << ",0,0,10000,roughness\n";
  }
  const std::string path = write("sp.csv", csv.str());
  const CmdResult r = ncd("simulate --setpoints " + path +
                          " --patch -0.5 -0.2 0.5 0.2 --surface-z 0.04 --pick-feed-mm 0 "
                          "--cell-um 10 -q");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["moves"].get<int>(), rows - 1);
  EXPECT_NEAR(j["feed_per_tooth_median_by_length_mm"].get<double>(), 0.5, 1e-3);
  EXPECT_NEAR(j["rmax_map"]["model_max_um"].get<double>(), 25.06, 0.01);
  EXPECT_EQ(j["rmax_um"]["uncut_cells"], 0);
  // A patch the tool never reaches is an error, not a report of zeros.
  const CmdResult away =
      ncd("simulate --setpoints " + path + " --patch 5 5 6 6 --surface-z 0.04 --cell-um 10 -q");
  EXPECT_EQ(away.status, 2);
  EXPECT_NE(away.err.find("never cuts"), std::string::npos) << away.err;
  EXPECT_TRUE(away.out.empty());
}

TEST_F(Simulate, TheFeedNcdPlansLeavesTheRoughnessItPromises) {
  // A level raster replayed at the roughness-bounded feed (target 10.67 um: the law lowers f_t to
  // 0.3265 mm at alpha = 0, the paper's Fig. 15), then cut on the Z-map from its setpoints.
  const std::string src = NCD_SOURCE_DIR;
  const std::string sp = (dir_ / "sp.csv").string();
  ASSERT_EQ(ncd("replay " + src + "/examples/raster-level.ngc --machine " + src +
                "/examples/raster-finish.toml --setpoints " + sp + " -q --report " +
                (dir_ / "replay.json").string())
                .status,
            0);
  const CmdResult r = ncd("simulate --setpoints " + sp + " --machine " + src +
                          "/examples/raster-finish.toml --patch 0 0 1.3 1 --surface-z 0.05 "
                          "--nominal-z 0 --cell-um 5 -q");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  // The planner may run below the law's f_t (stops at the raster's reversals, chord limits), never
  // above it.
  const double ft_mm = j["feed_per_tooth_median_by_length_mm"].get<double>();
  EXPECT_LE(ft_mm, 0.3265 + 0.0005);
  EXPECT_GE(ft_mm, 0.3265 * 0.985);
  EXPECT_NEAR(j["rmax_map"]["model_max_um"].get<double>(), 10.67, 0.01);
  EXPECT_EQ(j["rmax_um"]["uncut_cells"], 0);
  EXPECT_NEAR(j["rmax_um"]["areal"].get<double>(), 10.67, 1.0);
}

TEST_F(Simulate, InputsThatCannotBeSimulatedAreClearErrors) {
  struct Case {
    std::string args, expect;
  };
  const std::string missing = (dir_ / "none.csv").string();
  const Case cases[] = {
      {"simulate", "either --case"},
      {"simulate --case fig13 --alpha-deg 5", "--case raster"},
      {"simulate --case raster --alpha-deg 5", "--ft-mm"},
      {"simulate --case fig14 --cell-um 0", "--cell-um"},
      {"simulate --case fig14 --stock-mm 0.005", "uncut"},
      {"simulate --case fig13 --teeth 0", "teeth = 0"},
      {"simulate --case fig13 --pick-feed-mm 12", "diameter"},
      {"simulate --setpoints " + missing, "--patch"},
      {"simulate --setpoints " + missing + " --patch 0 0 1 1 --surface-z 0", "cannot open"},
      {"simulate --case fig99", "fig99"},
  };
  for (const Case& c : cases) {
    const CmdResult r = ncd(c.args);
    EXPECT_EQ(r.status, 2) << c.args;
    EXPECT_NE(r.err.find(c.expect), std::string::npos) << c.args << "\n" << r.err;
    EXPECT_TRUE(r.out.empty()) << c.args;
  }
}

}  // namespace
