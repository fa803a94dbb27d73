// Per-axis limits in the machine file (docs/planner.md §3f): [axis.x], [axis.y], [axis.z], each
// key optional; read, checked with errors naming the table, the key, the value, the range and a
// way out; echoed in the machine's JSON only where given; and `ncd replay` reporting each axis's
// peaks against its limits, in text and JSON, measured from the setpoints it writes.
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "service/machine_config.hpp"
#include "tests/app/cli_fixture.hpp"

namespace ncd::app {
namespace {

std::string error_of(const std::string& toml) {
  try {
    (void)service::parse_machine_config(toml, "m.toml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

void expect_all(const std::string& what, std::vector<std::string> parts) {
  for (const std::string& p : parts)
    EXPECT_NE(what.find(p), std::string::npos) << p << " in: " << what;
}

TEST(AxisLimitsConfig, TablesAreReadAndKeysLeftOutAreNoLimit) {
  const service::MachineConfig c = service::parse_machine_config(
      "max_feed_mm_per_min = 6000\n[axis.z]\nmax_feed_mm_per_min = 1500\nmax_accel_mm_per_s2 = "
      "250\nmax_jerk_mm_per_s3 = 4000\n[axis.x]\nmax_accel_mm_per_s2 = 600\n",
      "m.toml");
  EXPECT_EQ(c.limits.axes[2].max_feed_mm_per_min, 1500.0);
  EXPECT_EQ(c.limits.axes[2].max_accel_mm_per_s2, 250.0);
  EXPECT_EQ(c.limits.axes[2].max_jerk_mm_per_s3, 4000.0);
  EXPECT_EQ(c.limits.axes[0].max_accel_mm_per_s2, 600.0);
  EXPECT_TRUE(std::isinf(c.limits.axes[0].max_feed_mm_per_min));
  EXPECT_TRUE(std::isinf(c.limits.axes[1].max_jerk_mm_per_s3));
  EXPECT_TRUE(c.limits.has_axis_limits());
  const auto j = to_json(c);
  ASSERT_TRUE(j.contains("axis"));
  EXPECT_EQ(j["axis"]["z"]["max_accel_mm_per_s2"].get<double>(), 250.0);
  EXPECT_TRUE(j["axis"]["x"]["max_feed_mm_per_min"].is_null());
  EXPECT_TRUE(j["axis"]["y"]["max_jerk_mm_per_s3"].is_null());
  // Without tables: no key, the JSON as it was.
  const service::MachineConfig none =
      service::parse_machine_config("max_feed_mm_per_min = 6000\n", "m.toml");
  EXPECT_FALSE(none.limits.has_axis_limits());
  EXPECT_FALSE(to_json(none).contains("axis"));
}

// jerk_bound = "axes": the jerk vector bounded by the smallest axis jerk (feed::
// with_axis_jerk; its law is held by AxisLimits.TheVectorBoundAtTheSmallestAxisJerk... in
// test_motion), and without an axis jerk it is an error naming the way out.
TEST(AxisLimitsConfig, JerkBoundAxesBoundsTheVectorByTheSmallestAxisJerk) {
  const service::MachineConfig c = service::parse_machine_config(
      "max_jerk_mm_per_s3 = 20000\njerk_bound = \"axes\"\n[axis.z]\nmax_jerk_mm_per_s3 = "
      "4000\n[axis.x]\nmax_jerk_mm_per_s3 = 9000\n",
      "m.toml");
  EXPECT_EQ(c.limits.max_jerk_mm_per_s3, 4000.0);
  EXPECT_EQ(c.limits.jerk_bound, feed::JerkBound::vector);
  EXPECT_EQ(c.limits.axes[0].max_jerk_mm_per_s3, 9000.0);
  EXPECT_EQ(to_json(c)["jerk_bound"], "axes");  // the echo says what the file asked for
  expect_all(error_of("jerk_bound = \"axes\"\n"),
             {"m.toml", "jerk_bound = \"axes\"", "max_jerk_mm_per_s3", "[axis.x]", "\"vector\""});
  expect_all(error_of("jerk_bound = \"axis\"\n"), {"\"axis\"", "\"axes\"", "\"tangential\""});
}

TEST(AxisLimitsConfig, BadValuesNameTheTableTheKeyTheValueTheRangeAndAWayOut) {
  expect_all(
      error_of("[axis.z]\nmax_accel_mm_per_s2 = 0\n"),
      {"m.toml: axis.z.max_accel_mm_per_s2 = 0", "[10, 100000]", "mm/s^2", "leave the key out"});
  expect_all(error_of("[axis.y]\nmax_feed_mm_per_min = -100\n"),
             {"axis.y.max_feed_mm_per_min = -100", "[1, 120000]", "mm/min"});
  expect_all(error_of("[axis.x]\nmax_jerk_mm_per_s3 = 1e9\n"),
             {"axis.x.max_jerk_mm_per_s3 = 1000000000", "[100, 10000000]",
              "the path's max_jerk_mm_per_s3"});
  expect_all(error_of("[axis.z]\nmax_feed_mm_per_min = nan\n"),
             {"axis.z.max_feed_mm_per_min", "nan"});
  expect_all(error_of("[axis.z]\nmax_feed_mm_per_min = \"fast\"\n"),
             {"axis.z.max_feed_mm_per_min must be a number"});
  expect_all(error_of("[axis.w]\nmax_feed_mm_per_min = 100\n"),
             {"[axis.w]", "[axis.x], [axis.y], [axis.z] and one rotary"});
  expect_all(error_of("[axis.z]\nmax_speed = 100\n"),
             {"unknown key m.toml: axis.z.max_speed", "max_feed_mm_per_min, max_accel_mm_per_s2"});
  expect_all(error_of("axis = 5\n"), {"m.toml: axis", "[axis.x]"});
  expect_all(error_of("axis = { z = 3 }\n"), {"axis.z must be a table"});
}

class AxisReplay : public test::Cli {};

// A plunge under a Z of 1500 mm/min, 250 mm/s², 4000 mm/s³: the replay reports Z's peaks at its
// limits (within 1e-9), in the JSON and in the text, and the peaks are the setpoints' own
// differences (recomputed here from the CSV, to its printed digits).
TEST_F(AxisReplay, ReportGivesEachAxisPeakAgainstItsLimit) {
  const std::string machine =
      write("m.toml",
            "[axis.z]\nmax_feed_mm_per_min = 1500\nmax_accel_mm_per_s2 = "
            "250\nmax_jerk_mm_per_s3 = 4000\n[axis.x]\nmax_accel_mm_per_s2 = 600\n");
  const std::string program =
      write("p.ngc", "G21 G90\nG0 X0 Y0 Z0\nG1 Z-20 F6000\nG1 X10 Y5\nM2\n");
  const std::string report = (dir_ / "r.json").string(), csv = (dir_ / "sp.csv").string();
  const test::CmdResult r = ncd("replay " + program + " --path-only --machine " + machine +
                                " --report " + report + " --setpoints " + csv);
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = nlohmann::json::parse(test::slurp(report));
  ASSERT_TRUE(j.contains("axis_peaks"));
  const auto& z = j["axis_peaks"]["z"];
  EXPECT_NEAR(z["feed_max_mm_per_min"].get<double>(), 1500.0, 1500.0 * 1e-9);
  // (the planner keeps 5e-6 mm/s2 below it for the walker's arc-length tolerance)
  EXPECT_NEAR(z["accel_max_mm_per_s2"].get<double>(), 250.0, 250.0 * 1e-7);
  EXPECT_LE(z["accel_max_mm_per_s2"].get<double>(), 250.0 * (1.0 + 1e-9));
  EXPECT_LE(z["jerk_max_mm_per_s3"].get<double>(), 4000.0 * (1.0 + 1e-9));
  EXPECT_GT(z["jerk_max_mm_per_s3"].get<double>(), 4000.0 * 0.99);
  EXPECT_EQ(z["feed_limit_mm_per_min"].get<double>(), 1500.0);
  EXPECT_LE(j["axis_peaks"]["x"]["accel_max_mm_per_s2"].get<double>(), 600.0 * (1.0 + 1e-9));
  EXPECT_TRUE(j["axis_peaks"]["y"]["accel_limit_mm_per_s2"].is_null());
  EXPECT_EQ(j["machine"]["axis"]["z"]["max_feed_mm_per_min"].get<double>(), 1500.0);
  expect_all(r.err, {"axis Z", "feed 1500.0 mm/min (limit 1500)", "accel 250.0 mm/s2 (limit 250)",
                     "axis X", "(limit 600)", "axis Y", "(limit none)"});
  // Z's peak speed from the CSV (t_s,x_mm,y_mm,z_mm,...): its largest |Δz| / T.
  std::istringstream rows(test::slurp(csv));
  std::string line;
  std::getline(rows, line);  // header
  double z_prev = 0.0, v_max = 0.0;
  while (std::getline(rows, line)) {
    std::istringstream f(line);
    std::string t, x, y, zz;
    std::getline(f, t, ',');
    std::getline(f, x, ',');
    std::getline(f, y, ',');
    std::getline(f, zz, ',');
    const double zv = std::stod(zz);
    v_max = std::max(v_max, std::abs(zv - z_prev) / 0.004);
    z_prev = zv;
  }
  EXPECT_NEAR(v_max * 60.0, 1500.0, 0.05);  // the CSV has 1e-6 mm
}

TEST_F(AxisReplay, ABadAxisLimitIsAClearErrorExit2) {
  const std::string machine = write("m.toml", "[axis.z]\nmax_accel_mm_per_s2 = -5\n");
  const std::string program = write("p.ngc", "G21 G90\nG0 X0 Y0 Z0\nG1 Z-2 F600\nM2\n");
  const test::CmdResult r = ncd("replay " + program + " --machine " + machine);
  EXPECT_EQ(r.status, 2) << r.err;
  expect_all(r.err, {"axis.z.max_accel_mm_per_s2 = -5", "leave the key out"});
}

// Without [axis.*] the report has no per-axis key and the text no axis line.
TEST_F(AxisReplay, NoTablesNoAxisReport) {
  const std::string program = write("p.ngc", "G21 G90\nG0 X0 Y0 Z0\nG1 Z-2 F600\nM2\n");
  const std::string report = (dir_ / "r.json").string();
  const test::CmdResult r = ncd("replay " + program + " --path-only --report " + report);
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = nlohmann::json::parse(test::slurp(report));
  EXPECT_FALSE(j.contains("axis_peaks"));
  EXPECT_FALSE(j["machine"].contains("axis"));
  EXPECT_EQ(r.err.find("axis Z"), std::string::npos);
}

}  // namespace
}  // namespace ncd::app
