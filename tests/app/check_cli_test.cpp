// `ncd check` as a user meets it: the canonical listing with source lines, the summary's
// numbers against closed forms (a straight plunge and a full circle at known feeds, a dwell),
// --json with a tool table, and a refused construct (exit 2, file:line, nothing on stdout).
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <cmath>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/app/cli_fixture.hpp"

namespace {

using ncd::test::Cli;
using ncd::test::slurp;
namespace fs = std::filesystem;

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
  const auto r = ncd("check " + write("probe.ngc", "G21\nG0 X0 Y0 Z0\nG38.2 Z-1 F100\nM2\n"));
  EXPECT_EQ(r.status, 2);
  EXPECT_TRUE(r.out.empty()) << r.out;
  EXPECT_NE(r.err.find("probe.ngc:3: G38.2 (probing) is not supported"), std::string::npos)
      << r.err;
  const auto m = ncd("check " + write("m.ngc", "G0 X1e3\n"));
  EXPECT_EQ(m.status, 2);
  EXPECT_NE(m.err.find("m.ngc:1: E word is not supported"), std::string::npos) << m.err;
}

// --save-parameters: the offsets a program sets are written back (mode kept, other lines kept)
// and read by the next check; a refused program, a missing parameter file option and a folder
// where nothing can be created leave everything as it was (exit 2, nothing on stdout).
TEST_F(Cli, CheckSavesPersistentParametersOnlyAfterAProgramReadWhole) {
  const std::string var = write("p.var", "; shop offsets\n5221 1.5\n");
  ::chmod(var.c_str(), 0640);
  const auto r = ncd("check --summary --save-parameters --parameter-file " + var + " " +
                     write("set.ngc", "G21\nG10 L2 P2 X10 Y-20\nG0 X1 Y2 Z3\nG28.1\nM2\n"));
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string saved = slurp(dir_ / "p.var");
  EXPECT_EQ(saved.rfind("; shop offsets\n5161\t2.500000\n5162\t2.000000\n5163\t3.000000\n", 0), 0u)
      << saved;
  EXPECT_NE(saved.find("\n5221\t1.500000\n"), std::string::npos) << saved;
  EXPECT_NE(saved.find("\n5241\t10.000000\n5242\t-20.000000\n"), std::string::npos) << saved;
  struct stat st {};
  ASSERT_EQ(::stat(var.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 07777, 0640u);
  // G28.1 stored the machine position: X1 in G54 (X offset 1.5 from the file) is machine X2.5.
  // The next run reads them: G55 X0 Y0 is machine X10 Y-20, G28 goes to the stored home.
  const auto next = ncd("check --parameter-file " + var + " " +
                        write("use.ngc", "G21\nG55 G0 X0 Y0 Z0\nG28\nM2\n"));
  ASSERT_EQ(next.status, 0) << next.err;
  EXPECT_NE(next.out.find("X from 2.5000 to 10.0000"), std::string::npos) << next.out;
  EXPECT_NE(next.out.find("Y from -20.0000 to 2.0000"), std::string::npos) << next.out;

  const auto refused =
      ncd("check --save-parameters --parameter-file " + var + " " +
          write("bad.ngc", "G21\nG10 L2 P2 X99\nG0 X0 Y0 Z0\nG38.2 Z-1 F100\nM2\n"));
  EXPECT_EQ(refused.status, 2);
  EXPECT_TRUE(refused.out.empty()) << refused.out;
  EXPECT_EQ(slurp(dir_ / "p.var"), saved);

  const auto no_file = ncd("check --save-parameters " + write("m.ngc", "M2\n"));
  EXPECT_EQ(no_file.status, 2);
  EXPECT_NE(no_file.err.find("--save-parameters needs a parameter file"), std::string::npos)
      << no_file.err;
  // /proc takes no new files, even for root; a missing folder is refused before reading.
  const auto ro = ncd("check --save-parameters --parameter-file /proc/ncd_test.var " +
                      write("set2.ngc", "G10 L2 P1 X1\nM2\n"));
  EXPECT_EQ(ro.status, 2);
  EXPECT_TRUE(ro.out.empty()) << ro.out;
  EXPECT_NE(ro.err.find("/proc"), std::string::npos) << ro.err;
  const auto nodir = ncd("check --save-parameters --parameter-file " +
                         (dir_ / "nowhere" / "p.var").string() + " " + write("m2.ngc", "M2\n"));
  EXPECT_EQ(nodir.status, 2);
  EXPECT_NE(nodir.err.find("does not exist"), std::string::npos) << nodir.err;
  EXPECT_FALSE(fs::exists(dir_ / "nowhere"));
}

}  // namespace
