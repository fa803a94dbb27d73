// Two holes of a part whose chamfers meet are refused (docs/part.md, "Overlapping holes"), and
// the rotary axis's start angle ([rotary] start_deg) moves the order's air time as it should.
//
// Overlap: the criterion is checked against a brute force written here. Each hole's edge is
// the intersection of its drill cylinder with the pipe's surface, solved in the test for every
// angle around the drill axis (a quadratic along each generator of the drill, the pipe a
// cylinder), sampled densely (1440 points), its closest approach to the other edge found over
// every pair of samples and then refined three times around the best pairs (41 × 41 samples,
// each grid ten times finer);
// an edge is inside the other hole where a sample lies nearer that hole's drill axis than its
// radius, on the wall the hole's edge is on. The brute force refuses where the distance is at
// most the sum of the widths, or an edge enters the other hole. Random pairs (seed printed) at
// any distance, and pairs moved along the pipe to the limit found by bisection on the brute
// force, then 0.05, 0.01 and 0.004 mm either side of it.
//
// Start: for small parts and several start angles, every order's air time written here
// (trapezoids of the index from the start and between holes, the rapid across) against the
// planner's: its reported time is its order's time in this model, never shorter than the best
// order's, and its first rotary word leaves from the start the shortest way.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <numeric>
#include <random>

#include "cam/chamfer.hpp"
#include "cam/part.hpp"
#include "core/error.hpp"
#include "tests/common/seed.hpp"

namespace ncd::toolpath {
namespace {

double uniform_in(std::mt19937_64& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

// ---------------------------------------------------------------- the brute force

// A drill cylinder in part coordinates and the surface its edge is on.
struct Drill {
  Vec3 c, d, u, v;  // a point of the axis, its unit direction (+z of the drill frame), across
  double r = 0.0;
  double surface_r = 0.0;  // the pipe surface's radius (a cylinder about the s axis)
  bool upper = true;       // the larger root along d
  double side = 1.0;       // sign of the edge's offset along d from c
  double width = 0.0;
};

Drill drill_of(const Part& part, std::size_t i) {
  const HoleSetup s = hole_setup(part, i);
  const DrillPlacement place = drill_placement(s.spec);
  Drill g;
  g.c = s.pipe_to_part(place.origin);
  g.d = (s.pipe_to_part(place.to_pipe(Vec3(0, 0, 1))) - g.c).normalized();
  g.u = (s.pipe_to_part(place.to_pipe(Vec3(1, 0, 0))) - g.c).normalized();
  g.v = g.d.cross(g.u);
  g.r = part.holes[i].drill_radius_mm;
  g.surface_r = part.holes[i].edge == Edge::Outer ? part.pipe.outer_radius_mm
                                                  : part.pipe.outer_radius_mm - part.pipe.wall_mm;
  g.upper = part.holes[i].side == Side::Upper;
  g.width = part.holes[i].width_mm;
  g.side = g.upper ? 1.0 : -1.0;
  // The side of the edge: the root's sign along d, taken at one generator.
  const Vec3 p = g.c + g.r * g.u;
  const double a = g.d.y() * g.d.y() + g.d.z() * g.d.z();
  const double b = 2.0 * (p.y() * g.d.y() + p.z() * g.d.z());
  const double cc = p.y() * p.y() + p.z() * p.z() - g.surface_r * g.surface_r;
  const double disc = std::sqrt(b * b - 4.0 * a * cc);
  const double t = g.upper ? (-b + disc) / (2.0 * a) : (-b - disc) / (2.0 * a);
  g.side = t >= 0.0 ? 1.0 : -1.0;
  return g;
}

// The edge point at angle θ about the drill axis: the generator c + r(cos θ u + sin θ v) + t d
// meets y² + z² = R² (the pipe along s = x) where the quadratic in t says.
Vec3 edge_at(const Drill& g, double theta) {
  const Vec3 p = g.c + g.r * (std::cos(theta) * g.u + std::sin(theta) * g.v);
  const double a = g.d.y() * g.d.y() + g.d.z() * g.d.z();
  const double b = 2.0 * (p.y() * g.d.y() + p.z() * g.d.z());
  const double c = p.y() * p.y() + p.z() * p.z() - g.surface_r * g.surface_r;
  const double disc = std::sqrt(std::max(0.0, b * b - 4.0 * a * c));
  const double t = g.upper ? (-b + disc) / (2.0 * a) : (-b - disc) / (2.0 * a);
  return p + t * g.d;
}

bool inside_drill(const Drill& g, const Vec3& p) {
  const Vec3 w = p - g.c;
  const double along = w.dot(g.d);
  return along * g.side > 0.0 && (w - along * g.d).norm() < g.r;
}

struct Brute {
  double distance = 0.0;
  bool inside = false;
  bool refused(double limit) const { return inside || distance <= limit; }
};

Brute brute(const Drill& a, const Drill& b) {
  constexpr int kN = 1440;
  std::vector<Vec3> ea(kN), eb(kN);
  for (int k = 0; k < kN; ++k) {
    ea[k] = edge_at(a, 2.0 * kPi * k / kN);
    eb[k] = edge_at(b, 2.0 * kPi * k / kN);
  }
  Brute out;
  for (int k = 0; k < kN && !out.inside; ++k) {
    out.inside = inside_drill(a, eb[k]) || inside_drill(b, ea[k]);
  }
  // The closest sample of b to each sample of a; the three best pairs refined three times on
  // a 41 × 41 grid around them, each ten times finer than the last.
  std::vector<std::tuple<double, int, int>> pairs;
  for (int i = 0; i < kN; ++i) {
    double best = 1e300;
    int at = 0;
    for (int j = 0; j < kN; ++j) {
      const double dd = (ea[i] - eb[j]).squaredNorm();
      if (dd < best) best = dd, at = j;
    }
    pairs.emplace_back(best, i, at);
  }
  std::partial_sort(pairs.begin(), pairs.begin() + 3, pairs.end());
  out.distance = 1e300;
  for (int q = 0; q < 3; ++q) {
    double ta = 2.0 * kPi * std::get<1>(pairs[q]) / kN, tb = 2.0 * kPi * std::get<2>(pairs[q]) / kN;
    double span = 2.0 * (2.0 * kPi / kN);
    double best = std::sqrt(std::get<0>(pairs[q]));
    for (int round = 0; round < 3; ++round) {
      std::vector<Vec3> pb(41);
      for (int j = 0; j < 41; ++j) pb[j] = edge_at(b, tb + span * (j - 20) / 20.0);
      double bta = ta, btb = tb;
      for (int i = 0; i < 41; ++i) {
        const Vec3 pa = edge_at(a, ta + span * (i - 20) / 20.0);
        for (int j = 0; j < 41; ++j) {
          const double dd = (pa - pb[j]).norm();
          if (dd < best)
            best = dd, bta = ta + span * (i - 20) / 20.0, btb = tb + span * (j - 20) / 20.0;
        }
      }
      ta = bta, tb = btb, span /= 10.0;
    }
    out.distance = std::min(out.distance, best);
  }
  return out;
}

// ---------------------------------------------------------------- random pairs

Part pair_part(std::mt19937_64& rng) {
  Part p;
  p.source = "pair";
  p.pipe.outer_radius_mm = uniform_in(rng, 25.0, 40.0);
  p.pipe.wall_mm = uniform_in(rng, 3.0, 6.0);
  p.pipe.length_mm = 300.0;
  p.tool.ball_radius_mm = uniform_in(rng, 0.8, 1.5);
  for (int i = 0; i < 2; ++i) {
    PartHole h;
    h.name = "h" + std::to_string(i + 1);
    h.station_mm = 150.0;
    h.angle_rad = uniform_in(rng, -kPi, kPi);
    h.drill_radius_mm = uniform_in(rng, 4.0, 8.0);
    h.width_mm = uniform_in(rng, 0.3, 1.2);
    switch (rng() % 4) {
      case 0:
        break;
      case 1:
        h.edge = Edge::Inner;
        break;
      case 2:
        h.tilt_rad = uniform_in(rng, 0.0, 15.0) * kPi / 180.0;
        h.azimuth_rad = (rng() % 2 == 0 ? 90.0 : -90.0) * kPi / 180.0;
        h.eccentricity_mm = uniform_in(rng, -3.0, 3.0);
        break;
      default:
        h.edge = rng() % 2 == 0 ? Edge::Outer : Edge::Inner;
        h.side = Side::Lower;
        break;
    }
    p.holes.push_back(h);
  }
  return p;
}

// The planner's verdict: refused for an overlap (the message names both holes), accepted, or
// refused for another reason (a hole the machine cannot cut alone: left out of the sweep).
enum class Verdict { Accepted, Overlap, Other };
Verdict planned(const Part& p, std::string* message = nullptr) {
  try {
    plan_part(p, AirModel{}, NgcOptions{});
    return Verdict::Accepted;
  } catch (const InputError& e) {
    const std::string m = e.what();
    if (message) *message = m;
    if (m.find(" overlap: ") == std::string::npos) return Verdict::Other;
    EXPECT_NE(m.find(hole_label(p, 0)), std::string::npos) << m;
    EXPECT_NE(m.find(hole_label(p, 1)), std::string::npos) << m;
    return Verdict::Overlap;
  }
}

// The planner's distance, from its message ("come within X mm"), or -1.
double reported_distance(const std::string& m) {
  const std::size_t k = m.find("come within ");
  return k == std::string::npos ? -1.0 : std::stod(m.substr(k + 12));
}

TEST(PartOverlap, AgainstABruteForceOverRandomPairs) {
  std::mt19937_64 rng(test::seed());
  int agree = 0, near_band = 0, refused = 0, accepted = 0, inside = 0, boundary = 0;
  double worst_distance = 0.0;    // |planner − brute force| where the planner reports it
  constexpr double kBand = 2e-3;  // mm: the decision may differ only this close to the limit
  int trials = 0;
  while (trials < 60) {
    Part p = pair_part(rng);
    // Hole 2 placed near hole 1: along the pipe and around it, at up to a few drill radii.
    p.holes[1].station_mm = 150.0 + uniform_in(rng, -1.0, 1.0) * 3.0 * p.holes[0].drill_radius_mm;
    p.holes[1].angle_rad = p.holes[0].angle_rad + uniform_in(rng, -1.0, 1.0) * 2.5 *
                                                      p.holes[0].drill_radius_mm /
                                                      p.pipe.outer_radius_mm;
    if (rng() % 6 == 0) {  // a small hole in a large one
      p.holes[1].station_mm = 150.0;
      p.holes[1].angle_rad = p.holes[0].angle_rad;
      p.holes[1].drill_radius_mm = 0.4 * p.holes[0].drill_radius_mm;
      p.holes[1].tilt_rad = 0.0;
      p.holes[1].eccentricity_mm = 0.0;
      p.holes[1].side = p.holes[0].side;
    }
    std::string message;
    const Verdict v = planned(p, &message);
    if (v == Verdict::Other) continue;
    ++trials;
    const Brute b = brute(drill_of(p, 0), drill_of(p, 1));
    const double limit = p.holes[0].width_mm + p.holes[1].width_mm;
    if (b.inside) ++inside;
    if (v == Verdict::Overlap) {
      ++refused;
      const double d = reported_distance(message);
      if (d >= 0.0) worst_distance = std::max(worst_distance, std::abs(d - b.distance) - 5e-4);
    } else {
      ++accepted;
    }
    if (!b.inside && std::abs(b.distance - limit) < kBand) {
      ++near_band;
      continue;
    }
    EXPECT_EQ(v == Verdict::Overlap, b.refused(limit))
        << "brute force: distance " << b.distance << " mm, limit " << limit << " mm, inside "
        << b.inside << "; planner: " << (message.empty() ? "accepted" : message);
    ++agree;
  }
  // At the limit: hole 2 moved along the pipe until the brute force's distance is the sum of
  // the widths (bisection), then either side of it.
  for (int t = 0; t < 12; ++t) {
    Part p = pair_part(rng);
    p.holes[1].angle_rad = p.holes[0].angle_rad + uniform_in(rng, -0.1, 0.1);
    p.holes[1].side = p.holes[0].side;
    const double limit = p.holes[0].width_mm + p.holes[1].width_mm;
    const double sign = rng() % 2 == 0 ? 1.0 : -1.0;
    const auto gap = [&](double offset) {
      Part q = p;
      q.holes[1].station_mm = 150.0 + sign * offset;
      return brute(drill_of(q, 0), drill_of(q, 1));
    };
    double lo = 0.0, hi = 3.0 * (p.holes[0].drill_radius_mm + p.holes[1].drill_radius_mm);
    if (gap(hi).distance <= limit) continue;
    for (int k = 0; k < 18; ++k) {
      const double mid = 0.5 * (lo + hi);
      const Brute g = gap(mid);
      (g.refused(limit) ? lo : hi) = mid;
    }
    for (const double delta : {-0.05, -0.01, -0.004, 0.004, 0.01, 0.05}) {
      // delta > 0: the edges this much farther apart than the limit (to first order in the
      // offset, measured again).
      double offset = hi;
      for (int k = 0; k < 3; ++k) {
        const double h = 1e-3;
        const double d0 = gap(offset).distance, d1 = gap(offset + h).distance;
        offset += (limit + delta - d0) / ((d1 - d0) / h);
      }
      Part q = p;
      q.holes[1].station_mm = 150.0 + sign * offset;
      std::string message;
      const Verdict v = planned(q, &message);
      if (v == Verdict::Other) continue;
      const Brute b = gap(offset);
      ++boundary;
      if (v == Verdict::Overlap) {
        const double d = reported_distance(message);
        if (d >= 0.0) worst_distance = std::max(worst_distance, std::abs(d - b.distance) - 5e-4);
      }
      if (!b.inside && std::abs(b.distance - limit) < kBand) {
        ++near_band;
        continue;
      }
      EXPECT_EQ(v == Verdict::Overlap, b.refused(limit))
          << "at the limit " << delta << " mm: brute force " << b.distance << " mm, limit " << limit
          << " mm; planner: " << (message.empty() ? "accepted" : message);
      ++agree;
    }
  }
  std::cout << "[ overlap  ] " << trials << " random pairs (" << refused << " refused, " << accepted
            << " accepted, " << inside << " with an edge inside the other hole), " << boundary
            << " pairs 0.004-0.05 mm either side of the limit; " << agree
            << " decisions agree with the brute force, " << near_band << " within " << kBand
            << " mm of the limit left undecided; planner's distance within " << worst_distance
            << " mm of the brute force's (beyond the 3-decimal print)\n";
  EXPECT_GE(refused, 10);
  EXPECT_GE(accepted, 10);
  EXPECT_GE(boundary, 30);
  EXPECT_LE(worst_distance, kBand);
}

TEST(PartOverlap, TheMessageNamesBothHolesAndTheWidths) {
  Part p;
  p.source = "two.toml";
  p.pipe.outer_radius_mm = 30.0;
  p.pipe.wall_mm = 5.0;
  p.pipe.length_mm = 300.0;
  p.tool.ball_radius_mm = 1.0;
  for (const double station : {100.0, 117.0}) {
    PartHole h;
    h.name = "at " + std::to_string(static_cast<int>(station));
    h.station_mm = station;
    h.drill_radius_mm = 8.0;
    h.width_mm = 0.6;
    p.holes.push_back(h);
  }
  // Radial holes on the same generator, 17 mm apart: their edges 1 mm apart (at the top, where
  // the drill axes meet the surface), less than 1.2.
  std::string m;
  ASSERT_EQ(planned(p, &m), Verdict::Overlap);
  EXPECT_NE(m.find("two.toml: hole 1 (\"at 100\") and hole 2 (\"at 117\") overlap"),
            std::string::npos)
      << m;
  EXPECT_NE(m.find("1.2 mm (0.6 + 0.6)"), std::string::npos) << m;
  EXPECT_NEAR(reported_distance(m), 1.0, 2e-3) << m;
  p.holes[1].station_mm = 117.3;  // 1.3 mm apart: accepted
  EXPECT_EQ(planned(p), Verdict::Accepted);
}

// ---------------------------------------------------------------- the start angle

double trapezoid(double d, double v, double a) {
  d = std::abs(d);
  return d >= v * v / a ? d / v + v / a : 2.0 * std::sqrt(d / a);
}

double turn(double from, double to) {  // the shortest way, degrees
  double t = std::remainder(to - from, 360.0);
  if (t == 180.0) t = -180.0;
  return t;
}

TEST(PartStart, AirTimeFromTheStartAngleAgainstEveryOrder) {
  std::mt19937_64 rng(test::seed());
  const AirModel m;  // 100 mm/s, 1000 mm/s², 60 °/s, 1800 °/s²
  int parts = 0, optimal = 0, cases = 0;
  double worst = 1.0, spread = 0.0;
  while (parts < 12) {
    Part p;
    p.source = "start";
    p.pipe.outer_radius_mm = 30.0;
    p.pipe.wall_mm = 5.0;
    p.pipe.length_mm = 300.0;
    p.tool.ball_radius_mm = 1.0;
    p.rotary.sense = rng() % 2 == 0 ? 1.0 : -1.0;
    const int n = 2 + static_cast<int>(rng() % 3);
    for (int i = 0; i < n; ++i) {
      PartHole h;
      h.station_mm = 30.0 + 60.0 * i + uniform_in(rng, 0.0, 20.0);
      h.angle_rad = uniform_in(rng, -kPi, kPi);
      h.drill_radius_mm = 5.0;
      h.width_mm = 0.5;
      p.holes.push_back(h);
    }
    ++parts;
    double lo = 1e300, hi = 0.0;
    for (const double start : {0.0, 90.0, -135.0, 181.0, 725.0, uniform_in(rng, -720.0, 720.0)}) {
      p.rotary.start_deg = start;
      const PartProgram prog = plan_part(p, m, NgcOptions{});
      // The holes' rotary words and where they are approached, from the program.
      std::vector<double> a(n);
      std::vector<Vec3> over(n);
      for (const HoleCut& c : prog.cuts) {
        a[c.hole] = p.rotary.sense * c.setup.index_rad * 180.0 / kPi;
        over[c.hole] = c.over;
      }
      const auto tour = [&](const std::vector<std::size_t>& order) {
        double t = trapezoid(turn(start, a[order[0]]), 60.0, 1800.0);
        for (std::size_t k = 1; k < order.size(); ++k) {
          t += trapezoid(turn(a[order[k - 1]], a[order[k]]), 60.0, 1800.0) +
               trapezoid((over[order[k]] - over[order[k - 1]]).norm(), 100.0, 1000.0);
        }
        return t;
      };
      std::vector<std::size_t> perm(n);
      std::iota(perm.begin(), perm.end(), 0);
      const double file = tour(perm);
      double best = 1e300;
      do {
        best = std::min(best, tour(perm));
      } while (std::next_permutation(perm.begin(), perm.end()));
      EXPECT_NEAR(prog.air_ordered_s, tour(prog.order), 1e-9) << "start " << start;
      EXPECT_NEAR(prog.air_file_order_s, file, 1e-9) << "start " << start;
      EXPECT_GE(prog.air_ordered_s, best - 1e-9);
      if (prog.air_ordered_s <= best + 1e-9) ++optimal;
      worst = std::max(worst, prog.air_ordered_s / best);
      ++cases;
      // The first rotary word leaves from the start the shortest way; the next from it.
      double at = start;
      for (const HoleCut& c : prog.cuts) {
        at += turn(at, a[c.hole]);
        EXPECT_NEAR(c.a_deg, at, 1e-9) << "start " << start;
      }
      EXPECT_LE(std::abs(prog.cuts.front().a_deg - start), 180.0 + 1e-9);
      lo = std::min(lo, prog.air_ordered_s);
      hi = std::max(hi, prog.air_ordered_s);
    }
    spread = std::max(spread, hi - lo);
  }
  std::cout << "[ start    ] " << cases << " start angles over " << parts
            << " parts of 2-4 holes: " << optimal << " orders optimal against every order, worst "
            << worst << " of the optimum; the air time moved by up to " << spread
            << " s with the start\n";
  EXPECT_LE(worst, 1.2);
  EXPECT_GT(spread, 0.5);  // the start does move it
}

TEST(PartStart, TheFileKeyIsReadAndWrittenInTheHeader) {
  const std::string text =
      "[pipe]\nouter_radius_mm = 30.0\nwall_mm = 5.0\nlength_mm = 300.0\n[tool]\n"
      "ball_radius_mm = 1.0\n[rotary]\nstart_deg = 350.0\n[[hole]]\nposition_mm = 100.0\n"
      "angle_deg = 10.0\ndrill_radius_mm = 5.0\nwidth_mm = 0.5\nedge = \"outer\"\n";
  const Part p = parse_part(text, "s.toml");
  EXPECT_EQ(p.rotary.start_deg, 350.0);
  const std::string program = part_program_text(plan_part(p, AirModel{}, NgcOptions{}));
  EXPECT_NE(program.find("G0 A370.0000"), std::string::npos) << program;  // 20° on, not −340
  EXPECT_NE(program.find("stands at A350.0000 at the start"), std::string::npos) << program;
  std::string bad = text;
  bad.replace(bad.find("350.0"), 5, "1e9");
  try {
    parse_part(bad, "s.toml");
    ADD_FAILURE() << "start_deg 1e9 accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("s.toml: rotary.start_deg = 1e+09"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace ncd::toolpath
