// Whether a position reported at Hold:0 can be trusted to write a retract from
// (comms::held_position_doubt, link/held_position.hpp). A hold stops the tool on a move the
// controller was sent and not known done, or where the last move known done ended; elsewhere the
// controller has reset or been moved, and the ending must move nothing. The cases are the one
// seen in a loaded run of the served ending test (the hold reported at (0, 0, 0) while the tool
// was in the bore, and the retract rose from the drill axis instead of from the tool), exact
// points on and off the moves, and a random sweep against a brute-force distance.
#include "link/held_position.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "tests/common/seed.hpp"

namespace {

using namespace ncd::comms;
using P = std::array<double, 3>;
constexpr double kTolMm = 0.002;

HeldCandidate sent_move(const P& from, const P& to, std::string_view text = "G1") {
  BlockMotion g;
  g.motion = true;
  g.from_mm = from;
  g.to_mm = to;
  return {g, text};
}

P lerp(const P& a, const P& b, double u) {
  return {a[0] + u * (b[0] - a[0]), a[1] + u * (b[1] - a[1]), a[2] + u * (b[2] - a[2])};
}

// Two moves of an inner edge's loop in the bore (radius about 10.8 mm, Z about 12).
const P kA{-5.972, 9.025, 11.762}, kB{-5.571, 9.279, 11.992}, kC{-4.9, 9.6, 12.1};

TEST(HeldPosition, OnAMoveItMayExecuteOrAtTheLastEndIsTrusted) {
  const std::vector<HeldCandidate> moves{sent_move(kA, kB), sent_move(kB, kC)};
  EXPECT_EQ(held_position_doubt(lerp(kA, kB, 0.37), kA, moves, kTolMm), "");
  EXPECT_EQ(held_position_doubt(kC, kA, moves, kTolMm), "");
  EXPECT_EQ(held_position_doubt(kA, kA, {}, kTolMm), "");  // all done: where the last ended
}

TEST(HeldPosition, ARestartedControllerAtZeroIsNotTrusted) {
  const std::vector<HeldCandidate> moves{sent_move(kA, kB), sent_move(kB, kC)};
  const std::string why = held_position_doubt({0.0, 0.0, 0.0}, kA, moves, kTolMm);
  EXPECT_NE(why.find("none of the moves"), std::string::npos) << why;
  EXPECT_NE(why.find("power-up"), std::string::npos) << why;
  // Nothing known at all (no move done, none in flight): nothing to trust it by.
  EXPECT_NE(held_position_doubt({0.0, 0.0, 0.0}, std::nullopt, {}, kTolMm), "");
}

TEST(HeldPosition, TheToleranceIsTheReportsRounding) {
  const std::vector<HeldCandidate> moves{sent_move({0, 0, 0}, {10, 0, 0})};
  EXPECT_EQ(held_position_doubt({5.0, 0.0019, 0.0}, std::nullopt, moves, kTolMm), "");
  EXPECT_NE(held_position_doubt({5.0, 0.0021, 0.0}, std::nullopt, moves, kTolMm), "");
  EXPECT_NE(held_position_doubt({10.0021, 0.0, 0.0}, std::nullopt, moves, kTolMm), "");
}

TEST(HeldPosition, ABlockTheTrackerCannotFollowMakesEveryPositionUntrusted) {
  HeldCandidate g92 = sent_move(kA, kA, "G92X0Y0Z0\n");
  g92.geo.motion = false;
  g92.geo.known = false;
  const std::vector<HeldCandidate> moves{sent_move(kA, kB), g92};
  const std::string why = held_position_doubt(kB, kA, moves, kTolMm);
  EXPECT_NE(why.find("(G92X0Y0Z0)"), std::string::npos) << why;
}

// Random chains of moves and random points: trusted exactly when a brute-force scan (20 001
// points along each move) finds one within the tolerance, away from its edge by 2e-4 mm (the scan's
// step is at most 0.18 um).
TEST(HeldPosition, AgreesWithABruteForceScanOnRandomMoves) {
  std::mt19937_64 rng(ncd::test::seed(20261129));
  std::uniform_real_distribution<double> coord(-20.0, 20.0), off(-0.004, 0.004), unit(0.0, 1.0);
  int trusted = 0, doubted = 0;
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<HeldCandidate> moves;
    P at{coord(rng), coord(rng), coord(rng)};
    const int n = 1 + static_cast<int>(unit(rng) * 4);
    for (int k = 0; k < n; ++k) {
      const P to{at[0] + off(rng) * 500.0, at[1] + off(rng) * 500.0, at[2] + off(rng) * 500.0};
      moves.push_back(sent_move(at, to));
      at = to;
    }
    const auto& m = moves[static_cast<std::size_t>(unit(rng) * n)].geo;
    const P on = lerp(m.from_mm, m.to_mm, unit(rng));
    const P pos{on[0] + off(rng), on[1] + off(rng), on[2] + off(rng)};
    double best = 1e300;
    for (const auto& c : moves) {
      for (int i = 0; i <= 20000; ++i) {
        const P q = lerp(c.geo.from_mm, c.geo.to_mm, i / 20000.0);
        best = std::min(best, std::hypot(pos[0] - q[0], pos[1] - q[1], pos[2] - q[2]));
      }
    }
    if (std::abs(best - kTolMm) < 2e-4) continue;  // the scan's own resolution
    const bool trust = held_position_doubt(pos, std::nullopt, moves, kTolMm).empty();
    EXPECT_EQ(trust, best <= kTolMm) << "trial " << trial << ", brute-force distance " << best;
    (trust ? trusted : doubted) += 1;
  }
  std::cout << "[ measured ] " << trusted << " trusted, " << doubted << " doubted\n";
  EXPECT_GT(trusted, 30);
  EXPECT_GT(doubted, 30);
}

}  // namespace
