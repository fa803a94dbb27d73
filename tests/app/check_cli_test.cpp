// `ncd check` as a user meets it: the canonical listing with source lines, the summary's
// numbers against closed forms (a straight plunge and a full circle at known feeds, a dwell),
// --json with a tool table, and a refused construct (exit 2, file:line, nothing on stdout).
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/app/cli_fixture.hpp"

namespace {

using ncd::test::Cli;

constexpr double kPi = 3.14159265358979323846;

const std::string kProgram =
    "G21 G90 G17\n"
    "G0 X0 Y0 Z5\n"
    "G1 Z0 F100\n"
    "G2 X0 Y0 I10 J0 F200\n"
    "G4 P2\n"
    "G0 Z5\n"
    "M2\n";

TEST_F(Cli, CheckListsTheProgramAndSummarisesIt) {
  const auto r = ncd("check " + write("p.ngc", kProgram));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("p.ngc:3 LINE X0.0 Y0.0 Z0.0 F100.0 mm"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("p.ngc:4 ARC G17 X0.0 Y0.0 Z0.0 centre X10.0 Y0.0 Z0.0 turns -1 radius "
                       "10.0 sweep_deg -360.0"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("p.ngc:5 DWELL 2.0 s"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("X from 0.0000 to 20.0000"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("Y from -10.0000 to 10.0000"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("Z from 0.0000 to 5.0000"), std::string::npos) << r.out;
}

TEST_F(Cli, CheckJsonNumbersMatchClosedForms) {
  const std::string tools = write("tool.tbl", "T1 P1 Z10 D6 ;six mm end mill\n");
  const auto r = ncd("check --json --tool-table " + tools + " " +
                     write("p.ngc", "T1 M6\nS3000 M3\n" + kProgram));
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  const auto& s = j.at("summary");
  const double circle = 2 * kPi * 10.0;
  EXPECT_NEAR(s.at("cut_length_mm").get<double>(), 5.0 + circle, 1e-6);
  // The first rapid comes from an unknown place: no length, no time. Then 5 mm at 100 mm/min,
  // the circle at 200 mm/min, 2 s of dwell; a rapid back up at the default machine maximum.
  EXPECT_NEAR(s.at("rapid_length_mm").get<double>(), 5.0, 1e-12);
  const double want_s = 5.0 / 100 * 60 + circle / 200 * 60 + 2.0 + 5.0 / 6000 * 60;
  EXPECT_NEAR(s.at("estimated_time_s").get<double>(), want_s, 1e-6);
  EXPECT_EQ(s.at("tools"), nlohmann::json::array({1}));
  EXPECT_EQ(s.at("spindle_rpm"), nlohmann::json::array({3000.0}));
  EXPECT_EQ(s.at("feed_mm_per_min").at("min").get<double>(), 100.0);
  EXPECT_EQ(s.at("feed_mm_per_min").at("max").get<double>(), 200.0);
  EXPECT_EQ(s.at("extents_mm").at("x"), nlohmann::json::array({0.0, 20.0}));
}

TEST_F(Cli, CheckRefusesOutOfScopeConstructsWithTheLine) {
  const auto r = ncd("check " + write("comp.ngc", "G21\nG0 X0 Y0 Z0\nG41 G1 X5 F100\nM2\n"));
  EXPECT_EQ(r.status, 2);
  EXPECT_TRUE(r.out.empty()) << r.out;
  EXPECT_NE(r.err.find("comp.ngc:3: G41 (cutter radius compensation) is not supported"),
            std::string::npos)
      << r.err;
  const auto m = ncd("check " + write("m.ngc", "G0 X1e3\n"));
  EXPECT_EQ(m.status, 2);
  EXPECT_NE(m.err.find("m.ngc:1: E word is not supported"), std::string::npos) << m.err;
}

}  // namespace
