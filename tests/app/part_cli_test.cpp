// `ncd chamfer --part` (docs/part.md) end to end: the manifold's program read by LinuxCNC's
// `rs274` (with its A words), judged on rs274's canonical moves, not on ncd's writer: every
// rotary move is a pure index made with the tool at or above the clearance plane (the pipe's
// largest radius plus the part file's margin, computed here), the spindle turns through every
// feed, and every cutter location of every hole, computed alone here and carried to the machine
// at the A rs274 reports for it, is the end of one of its feeds (within the 4-decimal print).
// Refusals: exit 2, the hole named, nothing written.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "cam/chamfer.hpp"
#include "cam/part.hpp"
#include "tests/app/cli_fixture.hpp"
#include "tests/common/rs274.hpp"

namespace {

using ncd::test::Cli;
using ncd::test::slurp;
namespace fs = std::filesystem;
namespace tp = ncd::toolpath;

const std::string kManifold = std::string(NCD_SOURCE_DIR) + "/examples/manifold.toml";
const double kPartPrintMm = std::sqrt(3.0) * 5e-5 + 1e-6;  // 4 decimals on three axes

struct Move {
  std::array<double, 5> end{};  // X Y Z A B
  bool feed = false;
  bool spindle_on = false;
};

// rs274's canonical output: every straight move with X Y Z A, and whether the spindle turns.
std::vector<Move> canonical_moves_xyza(const std::string& out, bool& program_end) {
  std::vector<Move> moves;
  std::istringstream in(out);
  std::string line;
  bool spindle = false;
  program_end = false;
  while (std::getline(in, line)) {
    if (line.find("START_SPINDLE_CLOCKWISE") != std::string::npos) spindle = true;
    if (line.find("STOP_SPINDLE_TURNING") != std::string::npos) spindle = false;
    if (line.find("PROGRAM_END") != std::string::npos) program_end = true;
    const bool traverse = line.find("STRAIGHT_TRAVERSE(") != std::string::npos;
    const bool feed = line.find("STRAIGHT_FEED(") != std::string::npos;
    if (!traverse && !feed) continue;
    Move m;
    m.feed = feed;
    m.spindle_on = spindle;
    const std::size_t open = line.find('(');
    if (std::sscanf(line.c_str() + open + 1, "%lf, %lf, %lf, %lf, %lf", &m.end[0], &m.end[1],
                    &m.end[2], &m.end[3], &m.end[4]) == 5) {
      moves.push_back(m);
    }
  }
  return moves;
}

class PartCli : public Cli {
 protected:
  std::string rs274(const std::string& program, bool& program_end, std::string& log_text) {
    const std::string table = write("tool.tbl", "T1 P1 Z0 D4 ;ball\n");
    const fs::path out = dir_ / "canon.out", log = dir_ / "canon.log";
    const std::string cmd =
        ncd::test::rs274_command(dir_, "-t " + table + " -g " + program + " " + out.string()) +
        " >" + log.string() + " 2>&1";
    EXPECT_EQ(std::system(cmd.c_str()), 0);
    log_text = slurp(log) + slurp(out);
    const std::string text = slurp(out);
    (void)canonical_moves_xyza(text, program_end);
    return text;
  }
};

// The hole's machine points at the table's turn `a_deg` (the frames of docs/part.md, written
// out here): tip of every cutter location of the chamfer computed alone.
std::vector<ncd::Vec3> alone_tips(const tp::Part& p, const tp::PartHole& h, double a_deg) {
  tp::ChamferSpec s;
  const double outer = p.pipe.outer_radius_mm + h.station_mm * std::tan(p.pipe.half_angle_rad);
  s.pipe_radius_mm =
      h.edge == tp::Edge::Outer ? outer : outer - p.pipe.wall_mm / std::cos(p.pipe.half_angle_rad);
  s.pipe_thickness_mm = p.pipe.wall_mm;
  s.drill_radius_mm = h.drill_radius_mm;
  s.ball_radius_mm = p.tool.ball_radius_mm;
  s.width_mm = h.width_mm;
  s.tolerance_mm = p.cut.tolerance_mm;
  s.edge = h.edge;
  s.rod_radius_mm = p.tool.rod_radius_mm;
  s.non_knife_angle_rad = p.tool.non_knife_angle_rad;
  s.drill_tilt_rad = h.tilt_rad;
  s.drill_azimuth_rad = h.azimuth_rad;
  const tp::ChamferPath path = tp::generate_chamfer(s);
  const tp::DrillPlacement place = tp::drill_placement(s);
  const double t = h.angle_rad, turn = a_deg * ncd::kPi / 180.0;
  const ncd::Vec3 ox(0.0, -std::cos(t), std::sin(t)), oz(0.0, std::sin(t), std::cos(t));
  std::vector<ncd::Vec3> tips;
  for (const tp::CutterPose& pose : path.points) {
    const ncd::Vec3 q = place.to_pipe(pose.cl);
    const ncd::Vec3 part = ncd::Vec3(h.station_mm, 0.0, 0.0) + q.x() * ox +
                           q.y() * ncd::Vec3(1.0, 0.0, 0.0) + q.z() * oz;
    const double c = std::cos(turn), sn = std::sin(turn);
    tips.emplace_back(part.x(), part.y() * c - part.z() * sn,
                      part.y() * sn + part.z() * c - s.ball_radius_mm);
  }
  return tips;
}

TEST_F(PartCli, ManifoldIsReadByRs274AndIndexesOnlyAboveTheClearance) {
  if (!fs::exists(ncd::test::kRs274)) GTEST_SKIP() << "rs274 not installed";
  const std::string program = (dir_ / "manifold.ngc").string();
  const auto r = ncd("chamfer --part " + kManifold + " -o " + program + " --plot " +
                     (dir_ / "m.svg").string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("air time"), std::string::npos) << r.err;
  bool program_end = false;
  std::string log;
  const std::string out = rs274(program, program_end, log);
  EXPECT_EQ(ncd::test::rs274_complaint(log), "") << log;
  const std::vector<Move> moves = canonical_moves_xyza(out, program_end);
  EXPECT_TRUE(program_end);
  ASSERT_GT(moves.size(), 100u);

  const tp::Part part = tp::load_part(kManifold);
  const double clearance = 30.0 + 10.0;  // [pipe] outer_radius_mm + [cut] clearance_margin_mm
  int indexes = 0, feeds = 0;
  for (std::size_t i = 1; i < moves.size(); ++i) {
    const Move &from = moves[i - 1], &to = moves[i];
    if (to.feed) {
      ++feeds;
      EXPECT_TRUE(to.spindle_on) << "feed " << i << " with the spindle off";
      EXPECT_EQ(to.end[3], from.end[3]) << "a feed that turns the table";
    }
    if (to.end[3] != from.end[3]) {
      ++indexes;
      EXPECT_FALSE(to.feed);
      EXPECT_GE(from.end[2], clearance - 1e-9) << "index " << indexes << " starts below";
      EXPECT_GE(to.end[2], clearance - 1e-9) << "index " << indexes << " ends below";
      EXPECT_EQ(to.end[0], from.end[0]);
      EXPECT_EQ(to.end[1], from.end[1]);
    }
  }
  EXPECT_GE(indexes, 7);  // eight holes; the first A may equal the start's 0
  // The first move rises to the clearance before any other axis moves.
  EXPECT_GE(moves.front().end[2], clearance - 1e-9);

  // Each hole's loop, computed alone, at the A rs274 reports for its feeds (all upper holes:
  // the A brings angle_deg up, so A ≡ angle_deg mod 360).
  double worst = 0.0;
  for (const tp::PartHole& h : part.holes) {
    std::vector<const Move*> mine;
    double a = 0.0;
    for (const Move& m : moves) {
      if (!m.feed) continue;
      const double diff = std::remainder(m.end[3] - h.angle_rad * 180.0 / ncd::kPi, 360.0);
      if (std::abs(diff) < 1e-3) {
        mine.push_back(&m);
        a = m.end[3];
      }
    }
    ASSERT_FALSE(mine.empty()) << h.name;
    for (const ncd::Vec3& tip : alone_tips(part, h, a)) {
      double best = 1e300;
      for (const Move* m : mine) {
        best = std::min(best,
                        std::hypot(m->end[0] - tip.x(), m->end[1] - tip.y(), m->end[2] - tip.z()));
      }
      worst = std::max(worst, best);
    }
  }
  std::cout << "[ manifold ] " << feeds << " feeds, " << indexes
            << " indexes; worst cutter location from its canonical feed " << worst << " mm\n";
  EXPECT_LE(worst, kPartPrintMm);
  const std::string svg = slurp(dir_ / "m.svg");
  EXPECT_NE(svg.find("<svg"), std::string::npos);
  EXPECT_NE(svg.find("(hole 8)"), std::string::npos);
}

// A cone on a B axis turning the other way, with a cross hole's lower edge (cut with the part
// turned over) and an eccentric hole tilted across the pipe: rs274 takes the B words, every
// turn of B is made above the cone's largest radius plus the margin, the spindle turns through
// every feed. (Where the cutter locations fall is held by the cam suite's identity test, which
// covers these cases.)
TEST_F(PartCli, ConeOnABAxisIndexesOnlyAboveItsLargestRadius) {
  if (!fs::exists(ncd::test::kRs274)) GTEST_SKIP() << "rs274 not installed";
  const std::string part = write("cone.toml", R"(
[pipe]
outer_radius_mm = 25
wall_mm = 4
half_angle_deg = 2
length_mm = 200
[tool]
ball_radius_mm = 1.5
number = 3
[cut]
clearance_margin_mm = 8
[rotary]
axis = "b"
sense = -1
[[hole]]
position_mm = 50
angle_deg = 30
drill_radius_mm = 5
edge = "outer"
width_mm = 0.4
[[hole]]
name = "cross, far wall"
position_mm = 120
angle_deg = 90
drill_radius_mm = 5
edge = "outer"
side = "lower"
width_mm = 0.4
[[hole]]
name = "eccentric"
position_mm = 160
angle_deg = -100
drill_radius_mm = 4
tilt_deg = 15
azimuth_deg = 90
eccentricity_mm = 3
edge = "inner"
width_mm = 0.3
)");
  const std::string program = (dir_ / "cone.ngc").string();
  const auto r = ncd("chamfer --part " + part + " -o " + program);
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string table = write("tool.tbl", "T3 P3 Z0 D3 ;ball\n");
  const fs::path out = dir_ / "canon.out", log = dir_ / "canon.log";
  ASSERT_EQ(std::system((ncd::test::rs274_command(
                             dir_, "-t " + table + " -g " + program + " " + out.string()) +
                         " >" + log.string() + " 2>&1")
                            .c_str()),
            0);
  EXPECT_EQ(ncd::test::rs274_complaint(slurp(log) + slurp(out)), "") << slurp(log);
  bool program_end = false;
  const std::vector<Move> moves = canonical_moves_xyza(slurp(out), program_end);
  EXPECT_TRUE(program_end);
  const double clearance = 25.0 + 200.0 * std::tan(2.0 * ncd::kPi / 180.0) + 8.0;
  int indexes = 0;
  for (std::size_t i = 1; i < moves.size(); ++i) {
    const Move &from = moves[i - 1], &to = moves[i];
    EXPECT_EQ(to.end[3], 0.0);  // no A on this machine
    if (to.feed) {
      EXPECT_TRUE(to.spindle_on);
    }
    if (to.end[4] != from.end[4]) {
      ++indexes;
      EXPECT_FALSE(to.feed);
      EXPECT_GE(from.end[2], clearance - 5e-5);
      EXPECT_GE(to.end[2], clearance - 5e-5);
      EXPECT_EQ(to.end[0], from.end[0]);
      EXPECT_EQ(to.end[1], from.end[1]);
    }
  }
  EXPECT_GE(indexes, 2);
}

// The air time the report gives is the program's own air moves, as rs274 reads them: every
// index (A, rest to rest at 60 deg/s and 1800 deg/s², the part file's [rotary]) and every rapid
// across at the clearance plane (100 mm/s, 1000 mm/s²: no machine file) but the first (from
// where the tool stands, which the order does not know), each a trapezoid computed here.
TEST_F(PartCli, ReportedAirTimeIsTheProgramsOwnAirMoves) {
  if (!fs::exists(ncd::test::kRs274)) GTEST_SKIP() << "rs274 not installed";
  const std::string program = (dir_ / "manifold.ngc").string();
  ASSERT_EQ(ncd("chamfer --part " + kManifold + " -q -o " + program).status, 0);
  const auto json_out = ncd("chamfer --part " + kManifold + " -q --format json");
  const std::size_t k = json_out.out.find("\"air_time_ordered_s\": ");
  ASSERT_NE(k, std::string::npos) << json_out.out;
  const double reported = std::stod(json_out.out.substr(k + 22));
  bool program_end = false;
  std::string log;
  const std::vector<Move> moves =
      canonical_moves_xyza(rs274(program, program_end, log), program_end);
  const auto trapezoid = [](double d, double v, double a) {
    d = std::abs(d);
    return d >= v * v / a ? d / v + v / a : 2.0 * std::sqrt(d / a);
  };
  const double clearance = 40.0;
  double air = 0.0;
  bool first_across = true;
  for (std::size_t i = 1; i < moves.size(); ++i) {
    const Move &from = moves[i - 1], &to = moves[i];
    if (to.feed) continue;
    if (to.end[3] != from.end[3]) air += trapezoid(to.end[3] - from.end[3], 60.0, 1800.0);
    const double across = std::hypot(to.end[0] - from.end[0], to.end[1] - from.end[1]);
    if (across > 0.0 && std::abs(from.end[2] - clearance) < 1e-9 &&
        std::abs(to.end[2] - clearance) < 1e-9) {
      if (!first_across) air += trapezoid(across, 100.0, 1000.0);
      first_across = false;
    }
  }
  std::cout << "[ air      ] reported " << reported << " s, from rs274's moves " << air << " s\n";
  EXPECT_NEAR(air, reported, 1e-4);
}

// The manifold's program on a machine with an A axis (examples/machine-rotary.toml): `ncd replay`
// walks it, its seven index moves at rest under the axis's limits, with no limit violated.
TEST_F(PartCli, ReplayWalksTheManifoldWithItsIndexes) {
  const std::string machine = std::string(NCD_SOURCE_DIR) + "/examples/machine-rotary.toml";
  const std::string program = (dir_ / "manifold.ngc").string();
  ASSERT_EQ(
      ncd("chamfer --part " + kManifold + " --machine " + machine + " -q -o " + program).status, 0);
  const auto r = ncd("replay " + program + " --machine " + machine + " --start 0,0,50");
  ASSERT_EQ(r.status, 0) << r.err << r.out;
  const std::string report = r.out + r.err;
  EXPECT_NE(report.find("limit violations 0"), std::string::npos) << report;
  EXPECT_NE(report.find("7 index moves"), std::string::npos) << report;
  EXPECT_NE(report.find("; 0 violations"), std::string::npos) << report;
}

// The double S of one index from rest to rest (Biagiotti and Melchiorri 2008, §3.4, zero end
// speeds), written here from the book: its duration for a turn of h degrees.
double double_s_s(double h, double v, double a, double j) {
  h = std::abs(h);
  double tj = 0.0, ta = 0.0;
  if (v * j >= a * a) {
    tj = a / j, ta = tj + v / a;
  } else {
    tj = std::sqrt(v / j), ta = 2.0 * tj;
  }
  if (h >= v * ta) return h / v + ta;  // cruise h/v − Ta between the two phases
  if (h >= 2.0 * a * a * a / (j * j)) {
    tj = a / j;
    ta = tj / 2.0 + std::sqrt(tj * tj / 4.0 + h / a);
  } else {
    tj = std::cbrt(h / (2.0 * j));
    ta = 2.0 * tj;
  }
  return 2.0 * ta;
}

// `ncd check` counts the indexes of the manifold's program in its time estimate: each the
// double S of its turn under [axis.a] (computed here from the program's A words), adding up to
// what `ncd replay` walks for them within two 4 ms periods an index (the replay counts whole
// periods, and the one that ends the index); and the estimate is the same program's without
// its A words plus that time.
TEST_F(PartCli, CheckCountsTheIndexMovesAsTheReplayWalksThem) {
  const std::string machine = std::string(NCD_SOURCE_DIR) + "/examples/machine-rotary.toml";
  const std::string program = (dir_ / "manifold.ngc").string();
  ASSERT_EQ(
      ncd("chamfer --part " + kManifold + " --machine " + machine + " -q -o " + program).status, 0);
  const auto check = ncd("check " + program + " --machine " + machine + " --json --summary -q");
  ASSERT_EQ(check.status, 0) << check.err;
  const auto sum = nlohmann::json::parse(check.out)["summary"];
  // The A words, from 0.
  std::istringstream in(slurp(program));
  double at = 0.0, want = 0.0;
  int turns = 0;
  std::string without;  // the program without its A words
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("G0 A", 0) == 0) {
      const double a = std::stod(line.substr(4));
      // The first hole, at A0, does not turn; the limits are examples/machine-rotary.toml's.
      if (a != at) {
        want += double_s_s(a - at, 60.0, 1800.0, 36000.0);
        ++turns;
      }
      at = a;
      continue;
    }
    without += line + "\n";
  }
  ASSERT_EQ(turns, 7);
  EXPECT_EQ(sum["index_moves"], 7);
  EXPECT_NEAR(sum["index_time_s"].get<double>(), want, 1e-9);
  const auto bare =
      ncd("check " + write("bare.ngc", without) + " --machine " + machine + " --json --summary -q");
  ASSERT_EQ(bare.status, 0) << bare.err;
  const auto bare_sum = nlohmann::json::parse(bare.out)["summary"];
  EXPECT_EQ(bare_sum["index_moves"], 0);
  EXPECT_NEAR(sum["estimated_time_s"].get<double>(),
              bare_sum["estimated_time_s"].get<double>() + want, 1e-9);
  // What the replay walks for them.
  const auto r = ncd("replay " + program + " --machine " + machine + " --start 0,0,50");
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string report = r.out + r.err;
  const std::size_t k = report.find("7 index moves in ");
  ASSERT_NE(k, std::string::npos) << report;
  const double walked = std::stod(report.substr(k + 17));
  std::cout << "[ indexes  ] ncd check " << sum["index_time_s"].get<double>() << " s, the replay "
            << walked << " s, of an estimate of " << sum["estimated_time_s"].get<double>()
            << " s\n";
  EXPECT_NEAR(sum["index_time_s"].get<double>(), walked, 7 * 2 * 0.004);
}

TEST_F(PartCli, JsonReportsTheOrderedAirTimeAgainstTheFilesOrder) {
  const auto r = ncd("chamfer --part " + kManifold + " --format json -q");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto at = [&](const std::string& key) {
    const std::size_t k = r.out.find("\"" + key + "\": ");
    EXPECT_NE(k, std::string::npos) << key;
    return std::stod(r.out.substr(k + key.size() + 4));
  };
  EXPECT_LE(at("air_time_ordered_s"), at("air_time_file_order_s"));
  EXPECT_GT(at("air_time_ordered_s"), 0.0);
}

TEST_F(PartCli, ARefusedHoleWritesNothingAndExits2) {
  std::string text = slurp(kManifold);
  const std::string from = "tilt_deg = 30.0\nazimuth_deg = 0.0\nedge = \"outer\"";
  const std::size_t at = text.find(from);
  ASSERT_NE(at, std::string::npos);
  text.replace(at, from.size(), "tilt_deg = 30.0\nazimuth_deg = 0.0\nedge = \"inner\"");
  const std::string part = write("bad.toml", text);
  const std::string out = (dir_ / "bad.ngc").string();
  const auto r = ncd("chamfer --part " + part + " -o " + out);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("hole 7 (\"lateral 90\")"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("lacks that tilt"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(PartCli, PartExcludesTheOneHoleFlags) {
  const auto r = ncd("chamfer --part " + kManifold + " --pipe-radius 18");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--pipe-radius"), std::string::npos) << r.err;
  const auto missing = ncd("chamfer --drill-radius 13 --ball-radius 3 --width 0.7");
  EXPECT_EQ(missing.status, 2);
  EXPECT_NE(missing.err.find("--pipe-radius is required"), std::string::npos) << missing.err;
}

}  // namespace
