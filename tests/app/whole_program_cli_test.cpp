// The programs ncd writes for one chamfer agree on the point they drive (docs/whole-program.md,
// "One programmed point"): the chamfer's NGC program and the blocks `ncd replay --blocks`
// streams are read back here, their Z words converted to the ball tip as their own headers
// say, and their lowest points compared. Before the [tool] programmed_point setting the blocks
// drove the ball centre while the chamfer program drove the tip: 3 mm apart.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <regex>
#include <sstream>
#include <string>

#include "tests/app/cli_fixture.hpp"

namespace {

using ncd::test::Cli;
using ncd::test::CmdResult;
using ncd::test::slurp;

const std::string kWholeChamfer =
    "chamfer --pipe-radius 18 --drill-radius 13 --ball-radius 3 --width 0.7 --tolerance 0.01 "
    "--rod-radius 1.8 --non-knife-angle 93 --edge inner --side upper -q";
const std::string kWholeMachine = std::string(NCD_SOURCE_DIR) + "/config/chamfer-exp3.toml";
constexpr double kBallRadiusMm = 3.0;
constexpr double kEncoderChordMm = 0.002;  // config/chamfer-exp3.toml [encoder]

struct ProgramZ {
  double lowest = std::numeric_limits<double>::infinity();
  bool tip = false, centre = false;  // what the header says it drives
};

// The lowest Z word of a program (comments stripped) and its header's programmed point.
ProgramZ read_program(const std::string& text) {
  ProgramZ z;
  z.tip = text.find("programmed point: ball TIP") != std::string::npos;
  z.centre = text.find("programmed point: ball CENTRE") != std::string::npos;
  std::istringstream in(text);
  std::string line;
  const std::regex word("[Zz]\\s*(-?[0-9]*\\.?[0-9]+)");
  while (std::getline(in, line)) {
    line = std::regex_replace(line, std::regex("\\([^)]*\\)"), "");
    for (std::sregex_iterator it(line.begin(), line.end(), word), end; it != end; ++it) {
      z.lowest = std::min(z.lowest, std::stod((*it)[1].str()));
    }
  }
  return z;
}

double to_tip(const ProgramZ& z) {
  return z.centre ? z.lowest - kBallRadiusMm : z.lowest;
}

class WholeProgram : public Cli {
 protected:
  // The exp3 machine file with another [tool] programmed_point.
  std::string machine_with_point(const std::string& point) {
    std::string text = slurp(kWholeMachine);
    const std::string key = "programmed_point = \"tip\"";
    const std::size_t at = text.find(key);
    EXPECT_NE(at, std::string::npos);
    text.replace(at, key.size(), "programmed_point = \"" + point + "\"");
    return write(point + ".toml", text);
  }
  // The chamfer's NGC program and the replayed blocks, for the machine file `machine`.
  std::pair<ProgramZ, ProgramZ> programs(const std::string& machine) {
    const std::string ngc = (dir_ / "exp3.ngc").string(), json_out = (dir_ / "exp3.json").string(),
                      blocks = (dir_ / "exp3-dnc.ngc").string();
    CmdResult r = ncd(kWholeChamfer + " --format ngc --machine " + machine + " -o " + ngc);
    EXPECT_EQ(r.status, 0) << r.err;
    r = ncd(kWholeChamfer + " --format json -o " + json_out);
    EXPECT_EQ(r.status, 0) << r.err;
    r = ncd("replay " + json_out + " --machine " + machine + " --blocks " + blocks + " -q");
    EXPECT_EQ(r.status, 0) << r.err;
    return {read_program(slurp(ngc)), read_program(slurp(blocks))};
  }
};

TEST_F(WholeProgram, StreamedLowestTipZEqualsTheChamferProgramsTip) {
  const auto [ngc, blocks] = programs(kWholeMachine);
  ASSERT_TRUE(ngc.tip) << "the chamfer program states the tip (the machine file's default)";
  ASSERT_TRUE(blocks.tip) << "the blocks state the same point in their header";
  ASSERT_TRUE(std::isfinite(ngc.lowest) && std::isfinite(blocks.lowest));
  std::printf(
      "exp3 lowest tip Z: chamfer NGC %.4f mm, --blocks %.4f mm, difference %.5f mm "
      "(chord tolerance %.4f mm)\n",
      to_tip(ngc), to_tip(blocks), to_tip(blocks) - to_tip(ngc), kEncoderChordMm);
  EXPECT_NEAR(to_tip(blocks), to_tip(ngc), kEncoderChordMm);
}

TEST_F(WholeProgram, CentreInTheMachineFileMovesBothProgramsToTheCentre) {
  const std::string machine = machine_with_point("centre");
  const auto [ngc, blocks] = programs(machine);
  ASSERT_TRUE(ngc.centre);
  ASSERT_TRUE(blocks.centre);
  EXPECT_NEAR(blocks.lowest, ngc.lowest, kEncoderChordMm);
  // The same cut as the tip programs, R_B higher.
  const auto [ngc_tip, blocks_tip] = programs(kWholeMachine);
  EXPECT_NEAR(ngc.lowest - kBallRadiusMm, ngc_tip.lowest, 1e-4);
  EXPECT_NEAR(blocks.lowest - kBallRadiusMm, blocks_tip.lowest, kEncoderChordMm);
}

TEST_F(WholeProgram, ContradictingProgramPointIsRefused) {
  const std::string machine = machine_with_point("centre");
  const CmdResult r = ncd(kWholeChamfer + " --format ngc --program-point tip --machine " + machine);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("programmed_point is centre"), std::string::npos) << r.err;
  EXPECT_TRUE(r.out.empty());
}

TEST_F(WholeProgram, UnknownProgrammedPointNamesTheValue) {
  const std::string machine = machine_with_point("flute");
  const CmdResult r = ncd(kWholeChamfer + " --format ngc --machine " + machine);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("tool.programmed_point = \"flute\""), std::string::npos) << r.err;
}

}  // namespace
