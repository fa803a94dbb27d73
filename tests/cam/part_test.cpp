// A part, not a hole (cam/part.hpp, docs/part.md). The frames are written out again here from
// the documented conventions (part coordinates s, v, w; a hole at angle θ has the radial
// direction (0, sin θ, cos θ) and its pipe frame X = (0, −cos θ, sin θ), Y = s, Z = radial; the
// table turns the part right-handed about +s by sense · A; A: X Y Z = s v w, B: X Y Z = −v s w),
// and every cutter location of the program is carried back through them and compared with the
// hole's chamfer computed alone from the part's values (1e-9 mm). The order against brute force
// over every order, the trapezoids against their closed forms, the tool axis of the global check
// against the single hole's, and the part file's refusals.
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

double uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

// ---------------------------------------------------------------- the frames, written here

// The hole alone, from the part's values: the surface carrying the edge at the hole's station.
ChamferSpec alone(const Part& p, const PartHole& h) {
  ChamferSpec s;
  const double outer = p.pipe.outer_radius_mm + h.station_mm * std::tan(p.pipe.half_angle_rad);
  s.pipe_radius_mm =
      h.edge == Edge::Outer ? outer : outer - p.pipe.wall_mm / std::cos(p.pipe.half_angle_rad);
  s.pipe_thickness_mm = p.pipe.wall_mm;
  s.pipe_half_angle_rad = p.pipe.half_angle_rad;
  s.drill_radius_mm = h.drill_radius_mm;
  s.ball_radius_mm = p.tool.ball_radius_mm;
  s.width_mm = h.width_mm;
  s.tolerance_mm = p.cut.tolerance_mm;
  s.edge = h.edge;
  s.side = h.side;
  s.rod_radius_mm = p.tool.rod_radius_mm;
  s.non_knife_angle_rad = p.tool.non_knife_angle_rad;
  s.drill_tilt_rad = h.tilt_rad;
  s.drill_azimuth_rad = h.azimuth_rad;
  s.eccentricity_mm = h.eccentricity_mm;
  return s;
}

struct Frame {
  Vec3 origin, x, y, z;  // the hole's pipe frame in part coordinates
};

Frame pipe_frame(const PartHole& h) {
  const double t = h.angle_rad;
  return {Vec3(h.station_mm, 0.0, 0.0), Vec3(0.0, -std::cos(t), std::sin(t)), Vec3(1.0, 0.0, 0.0),
          Vec3(0.0, std::sin(t), std::cos(t))};
}

Vec3 part_to_pipe(const Frame& f, const Vec3& q) {
  const Vec3 d = q - f.origin;
  return {d.dot(f.x), d.dot(f.y), d.dot(f.z)};
}

Vec3 pipe_to_part(const Frame& f, const Vec3& p) {
  return f.origin + p.x() * f.x + p.y() * f.y + p.z() * f.z;
}

// A machine point at the rotary word `a_deg` back in part coordinates.
Vec3 machine_to_part(const Part& p, double a_deg, const Vec3& m) {
  const Vec3 q = p.rotary.axis == RotaryAxis::A ? m : Vec3(m.y(), -m.x(), m.z());
  const double turn = p.rotary.sense * a_deg * kPi / 180.0;
  const double c = std::cos(turn), s = std::sin(turn);
  return {q.x(), q.y() * c + q.z() * s, -q.y() * s + q.z() * c};  // turned back by −turn
}

Vec3 part_direction_to_machine(const Part& p, double a_deg, const Vec3& d) {
  const double turn = p.rotary.sense * a_deg * kPi / 180.0;
  const double c = std::cos(turn), s = std::sin(turn);
  const Vec3 q(d.x(), d.y() * c - d.z() * s, d.y() * s + d.z() * c);
  return p.rotary.axis == RotaryAxis::A ? q : Vec3(-q.y(), q.x(), q.z());
}

// ---------------------------------------------------------------- random parts

enum class Kind { RadialOuter, RadialInner, AcrossOuter, LateralOuter, CrossLower };

Part random_part(std::mt19937_64& rng, int holes) {
  Part p;
  p.source = "random part";
  p.pipe.outer_radius_mm = uniform(rng, 22.0, 40.0);
  p.pipe.wall_mm = uniform(rng, 3.0, 7.0);
  p.pipe.half_angle_rad = rng() % 3 == 0 ? uniform(rng, -4.0, 4.0) * kPi / 180.0 : 0.0;
  p.pipe.length_mm = uniform(rng, 200.0, 400.0);
  p.tool.ball_radius_mm = uniform(rng, 1.0, 2.0);
  if (rng() % 2 == 0) p.tool.non_knife_angle_rad = uniform(rng, 60.0, 100.0) * kPi / 180.0;
  p.rotary.axis = rng() % 2 == 0 ? RotaryAxis::A : RotaryAxis::B;
  p.rotary.sense = rng() % 2 == 0 ? 1.0 : -1.0;
  for (int i = 0; i < holes; ++i) {
    PartHole h;
    h.name = "h" + std::to_string(i + 1);
    h.station_mm = uniform(rng, 40.0, p.pipe.length_mm - 40.0);
    h.angle_rad = uniform(rng, -kPi, kPi);
    h.drill_radius_mm = uniform(rng, 4.0, 8.0);
    h.width_mm = uniform(rng, 0.3, 0.7);
    switch (static_cast<Kind>(rng() % 5)) {
      case Kind::RadialOuter:
        break;
      case Kind::RadialInner:
        h.edge = Edge::Inner;
        break;
      case Kind::AcrossOuter:
        h.tilt_rad = uniform(rng, 0.0, 20.0) * kPi / 180.0;
        h.azimuth_rad = (rng() % 2 == 0 ? 90.0 : -90.0) * kPi / 180.0;
        h.eccentricity_mm = uniform(rng, -4.0, 4.0);
        break;
      case Kind::LateralOuter:
        h.tilt_rad = uniform(rng, 5.0, 30.0) * kPi / 180.0;
        h.azimuth_rad = (rng() % 2 == 0 ? 0.0 : 180.0) * kPi / 180.0;
        break;
      case Kind::CrossLower:
        h.side = Side::Lower;
        h.edge = rng() % 2 == 0 ? Edge::Outer : Edge::Inner;
        break;
    }
    p.holes.push_back(h);
  }
  return p;
}

// ---------------------------------------------------------------- the identity

TEST(Part, EveryCutterLocationLiesOnItsHolesChamferComputedAlone) {
  std::mt19937_64 rng(test::seed());
  int accepted = 0, refused = 0, holes = 0, tilted = 0, points = 0;
  double worst_cl = 0.0, worst_surface = 0.0, worst_vertical = 0.0;
  double air_ordered = 0.0, air_file = 0.0, best_saving = 0.0;
  while (accepted < 25 && refused < 200) {
    const Part part = random_part(rng, 1 + static_cast<int>(rng() % 6));
    PartProgram prog;
    try {
      prog = plan_part(part, AirModel{}, NgcOptions{});
    } catch (const InputError& e) {
      ++refused;  // a hole the machine cannot cut (the message names it)
      EXPECT_NE(std::string(e.what()).find("hole "), std::string::npos) << e.what();
      continue;
    }
    ++accepted;
    ASSERT_EQ(prog.cuts.size(), part.holes.size());
    std::vector<bool> seen(part.holes.size(), false);
    for (const HoleCut& cut : prog.cuts) {
      seen.at(cut.hole) = true;
      ++holes;
      const PartHole& h = part.holes[cut.hole];
      const ChamferSpec spec = alone(part, h);
      const ChamferPath path = generate_chamfer(spec);
      const DrillPlacement place = drill_placement(spec);
      const Frame f = pipe_frame(h);
      ASSERT_EQ(cut.points.size(), path.points.size());
      const double rb = part.tool.ball_radius_mm;
      for (std::size_t k = 0; k < path.points.size(); ++k) {
        const Vec3 centre = cut.points[k] + Vec3(0.0, 0.0, rb);  // the program drives the tip
        const Vec3 got = part_to_pipe(f, machine_to_part(part, cut.a_deg, centre));
        const Vec3 want = place.to_pipe(path.points[k].cl);
        worst_cl = std::max(worst_cl, (got - want).norm());
        // The edge on the part's own surface at its station: the holes are where the part says.
        const Vec3 xp = pipe_to_part(f, place.to_pipe(path.points[k].xp));
        const double outer =
            part.pipe.outer_radius_mm + xp.x() * std::tan(part.pipe.half_angle_rad);
        const double surface = h.edge == Edge::Outer
                                   ? outer
                                   : outer - part.pipe.wall_mm / std::cos(part.pipe.half_angle_rad);
        worst_surface = std::max(worst_surface, std::abs(std::hypot(xp.y(), xp.z()) - surface));
        EXPECT_LT(cut.points[k].z() + 2.0 * rb, prog.clearance_z_mm);
        ++points;
      }
      // The spindle side of the drill axis as vertical as the index can make it: exactly so
      // where it is perpendicular to the rotary axis, else within its along-axis part.
      const Vec3 d_pipe = place.direction_to_pipe(Vec3(0, 0, h.side == Side::Upper ? 1.0 : -1.0));
      const Vec3 d = part_direction_to_machine(
          part, cut.a_deg, d_pipe.x() * f.x + d_pipe.y() * f.y + d_pipe.z() * f.z);
      const double along = std::abs(d_pipe.y());  // the pipe frame's Y is the rotary axis
      worst_vertical = std::max(worst_vertical, std::abs(d.z() - std::sqrt(1.0 - along * along)));
      if (along > 1e-9) ++tilted;
    }
    EXPECT_TRUE(std::all_of(seen.begin(), seen.end(), [](bool b) { return b; }));
    EXPECT_LE(prog.air_ordered_s, prog.air_file_order_s + 1e-12);
    air_ordered += prog.air_ordered_s;
    air_file += prog.air_file_order_s;
    best_saving = std::max(best_saving, 1.0 - prog.air_ordered_s / prog.air_file_order_s);
  }
  std::cout << "[ parts    ] " << accepted << " accepted (" << holes << " holes, " << tilted
            << " laterals, " << points << " points), " << refused << " refused; worst CL "
            << worst_cl << " mm, edge off the part's surface " << worst_surface
            << " mm, drill axis from its best vertical " << worst_vertical << "; air time "
            << air_ordered << " s ordered against " << air_file
            << " s in the files' order (best part " << 100.0 * best_saving << " % less)\n";
  EXPECT_GE(accepted, 25);
  EXPECT_GT(tilted, 0);
  EXPECT_LE(worst_cl, 1e-9);
  EXPECT_LE(worst_surface, 1e-9);
  EXPECT_LE(worst_vertical, 1e-12);
}

// ---------------------------------------------------------------- the rapid descents

// How deep a point (part coordinates) lies in the part's material: between the pipe's surfaces,
// on the pipe, outside every drill; ≤ 0 outside the material.
double material_depth(const Part& p, const std::vector<std::pair<Vec3, Vec3>>& drills,
                      const Vec3& q) {
  const double outer = p.pipe.outer_radius_mm + q.x() * std::tan(p.pipe.half_angle_rad);
  const double inner = outer - p.pipe.wall_mm / std::cos(p.pipe.half_angle_rad);
  const double r = std::hypot(q.y(), q.z());
  double depth = std::min({r - inner, outer - r, q.x(), p.pipe.length_mm - q.x()});
  for (std::size_t i = 0; i < drills.size(); ++i) {
    const Vec3 w = q - drills[i].first;
    const double off_axis = (w - w.dot(drills[i].second) * drills[i].second).norm();
    depth = std::min(depth, off_axis - p.holes[i].drill_radius_mm);
  }
  return depth;
}

// The ball never enters the part on a rapid: the descent from the clearance plane to the
// approach gap above each hole's first point (and the retract, the same line up), sampled
// every 0.2 mm with 400 points of the ball's surface, turned back to the part at the hole's
// rotary word, against the part described here (the wall between its surfaces, on the pipe,
// outside every drilled hole). The feed from the gap to the cut and the cut itself are the
// single hole's.
TEST(Part, RapidDescentsNeverEnterThePart) {
  std::mt19937_64 rng(test::seed());
  std::vector<Vec3> sphere;
  for (int i = 0; i < 400; ++i) {  // a Fibonacci sphere
    const double z = 1.0 - (2.0 * i + 1.0) / 400.0, r = std::sqrt(1.0 - z * z);
    const double phi = i * kPi * (3.0 - std::sqrt(5.0));
    sphere.emplace_back(r * std::cos(phi), r * std::sin(phi), z);
  }
  int parts = 0, descents = 0;
  double deepest = -1e300;
  const auto check = [&](const Part& part, const PartProgram& prog) {
    ++parts;
    std::vector<std::pair<Vec3, Vec3>> drills;
    for (const PartHole& h : part.holes) {
      const DrillPlacement place = drill_placement(alone(part, h));
      const Frame f = pipe_frame(h);
      const Vec3 dir = place.direction_to_pipe(Vec3(0, 0, 1));
      drills.emplace_back(pipe_to_part(f, place.origin),
                          dir.x() * f.x + dir.y() * f.y + dir.z() * f.z);
    }
    const double rb = part.tool.ball_radius_mm;
    for (const HoleCut& cut : prog.cuts) {
      ++descents;
      const double bottom = cut.points.front().z() + part.cut.approach_gap_mm + rb;
      const double top = prog.clearance_z_mm + rb;
      for (double z = bottom; z <= top; z += 0.2) {
        for (const Vec3& u : sphere) {
          const Vec3 m = Vec3(cut.over.x(), cut.over.y(), z) + rb * u;
          deepest =
              std::max(deepest, material_depth(part, drills, machine_to_part(part, cut.a_deg, m)));
        }
      }
    }
  };
  const Part manifold = load_part(std::string(NCD_SOURCE_DIR) + "/examples/manifold.toml");
  check(manifold, plan_part(manifold, AirModel{}, NgcOptions{}));
  const double clear = deepest;
  {  // the sampler sees the part: the manifold's first hole (an outer edge), 1 mm below its cut
    const PartProgram prog = plan_part(manifold, AirModel{}, NgcOptions{});
    const HoleCut& cut = prog.cuts.front();
    ASSERT_EQ(cut.setup.spec.edge, Edge::Outer);
    std::vector<std::pair<Vec3, Vec3>> drills;
    for (const PartHole& h : manifold.holes) {
      const DrillPlacement place = drill_placement(alone(manifold, h));
      const Frame f = pipe_frame(h);
      const Vec3 dir = place.direction_to_pipe(Vec3(0, 0, 1));
      drills.emplace_back(pipe_to_part(f, place.origin),
                          dir.x() * f.x + dir.y() * f.y + dir.z() * f.z);
    }
    double below = -1e300;
    for (const Vec3& u : sphere) {
      const Vec3 m = cut.points.front() + Vec3(0.0, 0.0, manifold.tool.ball_radius_mm - 1.0) +
                     manifold.tool.ball_radius_mm * u;
      below = std::max(below,
                       material_depth(manifold, drills, machine_to_part(manifold, cut.a_deg, m)));
    }
    EXPECT_GT(below, 0.5);
  }
  deepest = clear;
  while (parts < 16) {
    const Part part = random_part(rng, 1 + static_cast<int>(rng() % 6));
    try {
      check(part, plan_part(part, AirModel{}, NgcOptions{}));
    } catch (const InputError&) {
      continue;
    }
  }
  std::cout << "[ descents ] " << descents << " rapid descents of " << parts
            << " parts (the manifold and random ones); the ball's deepest point in the part: "
            << deepest << " mm\n";
  EXPECT_LE(deepest, 0.0);
}

// ---------------------------------------------------------------- the tool axis

ChamferSpec random_part_hole_spec(std::mt19937_64& rng) {
  ChamferSpec s;
  s.pipe_radius_mm = uniform(rng, 15.0, 30.0);
  s.drill_radius_mm = uniform(rng, 3.0, 0.5 * s.pipe_radius_mm);
  s.ball_radius_mm = uniform(rng, 1.0, 0.5 * s.drill_radius_mm);
  s.width_mm = uniform(rng, 0.3, 0.8);
  s.pipe_thickness_mm = uniform(rng, 2.0, 5.0);
  s.edge = rng() % 2 == 0 ? Edge::Inner : Edge::Outer;
  if (s.edge == Edge::Inner) s.pipe_radius_mm -= *s.pipe_thickness_mm;
  s.side = rng() % 2 == 0 ? Side::Upper : Side::Lower;
  s.drill_tilt_rad = uniform(rng, 0.0, 30.0) * kPi / 180.0;
  s.drill_azimuth_rad = uniform(rng, -kPi, kPi);
  s.avoid = false;
  return s;
}

TEST(PartToolAxis, TheDrillAxisAsToolAxisChangesNothing) {
  std::mt19937_64 rng(test::seed());
  for (int i = 0; i < 40; ++i) {
    const ChamferSpec s = random_part_hole_spec(rng);
    ChamferSpec t = s;
    t.tool_axis = Vec3(0.0, 0.0, s.side == Side::Upper ? 1.0 : -1.0);
    const ChamferPath a = generate_chamfer(s), b = generate_chamfer(t);
    ASSERT_EQ(a.points.size(), b.points.size());
    for (std::size_t k = 0; k < a.points.size(); ++k) {
      EXPECT_EQ(a.points[k].cl, b.points[k].cl);
      EXPECT_EQ(a.points[k].minus_ez, b.points[k].minus_ez);
    }
    EXPECT_EQ(a.checks.global_ok, b.checks.global_ok);
    EXPECT_EQ(a.checks.max_minus_ez, b.checks.max_minus_ez);
    EXPECT_EQ(a.checks.min_minus_ez, b.checks.min_minus_ez);
    EXPECT_EQ(a.checks.global_fail.size(), b.checks.global_fail.size());
  }
}

TEST(PartToolAxis, ATiltedToolAxisMovesOnlyTheGlobalCheck) {
  // An outer upper edge: the check is −e·a ≥ 0 at every point; tilting the axis far over the
  // hole breaks it somewhere, and the cutter locations stay where they were.
  ChamferSpec s;
  s.pipe_radius_mm = 30.0;
  s.drill_radius_mm = 8.0;
  s.ball_radius_mm = 2.0;
  s.width_mm = 0.5;
  s.edge = Edge::Outer;
  ChamferSpec t = s;
  const double tilt = 70.0 * kPi / 180.0;
  t.tool_axis = Vec3(0.0, std::sin(tilt), std::cos(tilt));
  const ChamferPath a = generate_chamfer(s), b = generate_chamfer(t);
  ASSERT_EQ(a.points.size(), b.points.size());
  double worst = 0.0, min_check = 1e300;
  for (std::size_t k = 0; k < a.points.size(); ++k) {
    worst = std::max(worst, (a.points[k].cl - b.points[k].cl).norm());
    min_check = std::min(min_check, -a.points[k].e.dot(*t.tool_axis));
  }
  EXPECT_EQ(worst, 0.0);
  EXPECT_TRUE(a.checks.global_ok);
  EXPECT_FALSE(b.checks.global_ok);
  EXPECT_EQ(b.checks.min_minus_ez, min_check);
  EXPECT_NE(interference_reasons(b).find("machine's vertical"), std::string::npos);
  // An inner edge cannot take a tilted tool: the rod check assumes the drill axis.
  t.edge = Edge::Inner;
  t.pipe_radius_mm = 25.0;
  t.pipe_thickness_mm = 5.0;
  EXPECT_THROW(validate(t), InputError);
}

// ---------------------------------------------------------------- the order and its time

TEST(PartOrder, TrapezoidsAgainstTheirClosedForms) {
  // 100 mm at 100 mm/s and 1000 mm/s²: 0.1 s up, 0.9 s at speed (90 mm), 0.1 s down.
  EXPECT_DOUBLE_EQ(trapezoid_time_s(100.0, 100.0, 1000.0), 1.1);
  // 1 mm never reaches the speed: a triangle, 2 √(d/a).
  EXPECT_DOUBLE_EQ(trapezoid_time_s(1.0, 100.0, 1000.0), 2.0 * std::sqrt(0.001));
  // At the border both forms agree: d = v²/a = 10 mm takes 2 v/a = 0.2 s.
  EXPECT_DOUBLE_EQ(trapezoid_time_s(10.0, 100.0, 1000.0), 0.2);
  EXPECT_EQ(trapezoid_time_s(0.0, 100.0, 1000.0), 0.0);
  AirModel m;
  m.axis_mm_per_s = {100.0, 10.0, 100.0};  // a slow Y
  EXPECT_DOUBLE_EQ(rapid_time_s(m, Vec3(0, 0, 0), Vec3(0, 100, 0)),
                   trapezoid_time_s(100.0, 10.0, 1000.0));
  EXPECT_DOUBLE_EQ(shortest_turn_deg(170.0, -170.0), 20.0);
  EXPECT_DOUBLE_EQ(shortest_turn_deg(-170.0, 170.0), -20.0);
  EXPECT_DOUBLE_EQ(shortest_turn_deg(0.0, 180.0), -180.0);
  EXPECT_DOUBLE_EQ(index_time_s(m, -90.0), index_time_s(m, 90.0));
}

AirCosts random_costs(std::mt19937_64& rng, std::size_t n) {
  AirModel m;
  m.index_deg_per_s = uniform(rng, 20.0, 200.0);
  std::vector<Vec3> at(n);
  std::vector<double> a(n);
  for (std::size_t i = 0; i < n; ++i) {
    at[i] = Vec3(uniform(rng, 0.0, 400.0), uniform(rng, -30.0, 30.0), 50.0);
    a[i] = uniform(rng, -180.0, 180.0);
  }
  AirCosts c;
  c.from_start.resize(n);
  c.between.assign(n, std::vector<double>(n, 0.0));
  for (std::size_t i = 0; i < n; ++i) {
    c.from_start[i] = index_time_s(m, shortest_turn_deg(0.0, a[i]));
    for (std::size_t j = 0; j < n; ++j) {
      if (i != j) {
        c.between[i][j] =
            index_time_s(m, shortest_turn_deg(a[i], a[j])) + rapid_time_s(m, at[i], at[j]);
      }
    }
  }
  return c;
}

TEST(PartOrder, TwoOptAgainstBruteForceOverEveryOrder) {
  std::mt19937_64 rng(test::seed());
  int optimal = 0, trials = 0;
  double worst_ratio = 1.0, sum_saving = 0.0;
  for (std::size_t n = 1; n <= 7; ++n) {
    for (int t = 0; t < 60; ++t) {
      const AirCosts c = random_costs(rng, n);
      const std::vector<std::size_t> order = order_holes(c);
      std::vector<std::size_t> perm(n);
      std::iota(perm.begin(), perm.end(), 0);
      const double file = c.tour_s(perm);
      ASSERT_TRUE(std::is_permutation(order.begin(), order.end(), perm.begin()));
      double best = 1e300;
      do {
        best = std::min(best, c.tour_s(perm));
      } while (std::next_permutation(perm.begin(), perm.end()));
      const double got = c.tour_s(order);
      EXPECT_GE(got, best - 1e-12);
      EXPECT_LE(got, file + 1e-12);
      if (got <= best + 1e-12) ++optimal;
      worst_ratio = std::max(worst_ratio, got / best);
      sum_saving += 1.0 - got / file;
      ++trials;
    }
  }
  std::cout << "[ order    ] " << optimal << " of " << trials
            << " orders optimal (brute force over all), worst " << worst_ratio
            << " of the optimum; mean saving against the file's order "
            << 100.0 * sum_saving / trials << " %\n";
  EXPECT_LE(worst_ratio, 1.2);
}

// A part of one radial hole at angle 0 on A is the single hole's program in the pipe frame
// (cam/chamfer_ngc.hpp, --frame pipe: the pipe along Y), turned a quarter about Z and moved to
// its station: machine (X, Y, Z) = (station + y, −x, z), exactly.
TEST(Part, OneRadialHoleIsTheSingleHolesPipeFrameProgram) {
  Part p;
  p.pipe = {30.0, 5.0, 0.0, 200.0};
  p.tool.ball_radius_mm = 2.0;
  p.tool.non_knife_angle_rad = 93.0 * kPi / 180.0;
  for (const Edge edge : {Edge::Outer, Edge::Inner}) {
    PartHole h;
    h.station_mm = 80.0;
    h.drill_radius_mm = 8.0;
    h.width_mm = 0.5;
    h.edge = edge;
    p.holes = {h};
    const PartProgram prog = plan_part(p, AirModel{}, NgcOptions{});
    ASSERT_EQ(prog.cuts.size(), 1u);
    EXPECT_EQ(prog.cuts[0].a_deg, 0.0);
    EXPECT_EQ(prog.air_ordered_s, 0.0);
    const ChamferSpec spec = alone(p, h);
    const ChamferPath path = generate_chamfer(spec);
    ASSERT_EQ(path.points.size(), prog.cuts[0].points.size());
    double worst = 0.0;
    for (std::size_t k = 0; k < path.points.size(); ++k) {
      const Vec3 q = program_point(spec, path.points[k], ProgramPoint::Tip, ProgramFrame::Pipe);
      worst = std::max(worst, (prog.cuts[0].points[k] - Vec3(80.0 + q.y(), -q.x(), q.z())).norm());
    }
    EXPECT_LE(worst, 1e-12) << to_string(edge);
  }
}

TEST(Part, AHoleAtTheEndOfThePipeIsRefused) {
  Part p;
  p.source = "p.toml";
  p.pipe = {30.0, 5.0, 0.0, 200.0};
  p.tool.ball_radius_mm = 2.0;
  PartHole h;
  h.name = "end";
  h.station_mm = 0.0;  // half the hole off the pipe
  h.drill_radius_mm = 8.0;
  h.width_mm = 0.5;
  p.holes = {h};
  try {
    (void)plan_part(p, AirModel{}, NgcOptions{});
    FAIL() << "a hole half off the pipe was planned";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("hole 1 (\"end\"): its edge reaches station -"),
              std::string::npos)
        << e.what();
  }
}

// ---------------------------------------------------------------- the part file

const std::string kPart = R"(
[pipe]
outer_radius_mm = 30
wall_mm = 5
length_mm = 300
[tool]
ball_radius_mm = 2
[[hole]]
name = "top"
position_mm = 100
angle_deg = 0
drill_radius_mm = 6
edge = "outer"
width_mm = 0.5
[[hole]]
name = "lateral"
position_mm = 200
angle_deg = 90
drill_radius_mm = 6
tilt_deg = 30
edge = "outer"
width_mm = 0.5
)";

std::string refusal(const std::string& text) {
  try {
    const Part p = parse_part(text, "p.toml");
    (void)plan_part(p, AirModel{}, NgcOptions{});
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const std::size_t at = text.find(from);
  if (at == std::string::npos) throw std::logic_error("no " + from);
  return text.replace(at, from.size(), to);
}

TEST(PartFile, ReadsAndPlans) {
  const Part p = parse_part(kPart, "p.toml");
  ASSERT_EQ(p.holes.size(), 2u);
  EXPECT_EQ(p.holes[1].name, "lateral");
  EXPECT_EQ(p.tool.length_offset, 1);
  const PartProgram prog = plan_part(p, AirModel{}, NgcOptions{});
  EXPECT_DOUBLE_EQ(prog.clearance_tip_z_mm, 30.0 + 8.0);
  const std::string text = part_program_text(prog);
  EXPECT_NE(text.find("G0 A"), std::string::npos);
  EXPECT_NE(text.find("G43 H1"), std::string::npos);
}

TEST(PartFile, RefusalsNameTheHoleTheKeyAndAWayOut) {
  const auto has = [](const std::string& msg, std::initializer_list<const char*> parts) {
    for (const char* s : parts) {
      if (msg.find(s) == std::string::npos) return ::testing::AssertionFailure() << msg;
    }
    return ::testing::AssertionSuccess();
  };
  EXPECT_TRUE(has(refusal(replaced(kPart, "tilt_deg = 30", "tilt = 30")),
                  {"hole 2 (\"lateral\")", "unknown key", "tilt", "tilt_deg"}));
  EXPECT_TRUE(
      has(refusal(replaced(kPart, "drill_radius_mm = 6\nedge", "drill_radius_mm = -6\nedge")),
          {"hole 1 (\"top\")", "drill_radius_mm", "-6", "greater than 0"}));
  EXPECT_TRUE(has(refusal(replaced(kPart, "position_mm = 200", "position_mm = 400")),
                  {"hole 2", "position_mm = 400", "[0, 300]"}));
  // An inner edge of a lateral: no index makes its axis vertical.
  EXPECT_TRUE(has(refusal(replaced(kPart, "tilt_deg = 30\nedge = \"outer\"",
                                   "tilt_deg = 30\nedge = \"inner\"")),
                  {"hole 2 (\"lateral\")", "30°", "lacks that tilt"}));
  // A lateral tilted so far that its edge curves more tightly than the ball at the acute side:
  // the single hole's local check, the hole named.
  EXPECT_TRUE(has(refusal(replaced(kPart, "tilt_deg = 30", "tilt_deg = 75")),
                  {"hole 2 (\"lateral\")", "cannot be chamfered", "local", "smaller ball"}));
  EXPECT_TRUE(
      has(refusal(replaced(kPart, "wall_mm = 5", "wall_mm = 31")), {"pipe.wall_mm", "no bore"}));
  EXPECT_TRUE(has(refusal(replaced(kPart, "edge = \"outer\"\nwidth_mm = 0.5\n[[hole]]",
                                   "edge = \"outer\"\n[[hole]]")),
                  {"hole 1 (\"top\") has no width_mm"}));
  EXPECT_TRUE(has(refusal(replaced(kPart, "[tool]", "[tool]\nnumber = 2.5")),
                  {"tool.number", "whole number"}));
  EXPECT_TRUE(has(refusal("[pipe]\nouter_radius_mm = 30\nwall_mm = 5\nlength_mm = 100\n"
                          "[tool]\nball_radius_mm = 2\n"),
                  {"no [[hole]]"}));
  // A drill wider than the bore: the single hole's own check, with the hole named.
  EXPECT_TRUE(
      has(refusal(replaced(kPart, "drill_radius_mm = 6\nedge", "drill_radius_mm = 29\nedge")),
          {"hole 1 (\"top\")", "drill"}));
}

}  // namespace
}  // namespace ncd::toolpath
