// Chamfers of any drilled hole (docs/chamfer.md): inclined and eccentric drills, cone pipes.
// The numerical edge curve against the paper's closed form (eq. 4), identities over random
// geometries, a brute-force intersection written here (dense angle scan, bisection per angle),
// and interference checked against the part's geometry as point clouds, not against the code's
// own criteria. The part is described here independently, in the pipe frame: pipe axis Y,
// surfaces |(x, z)| = R + y tan ψ, drill axis through e·n̂ along d(τ, φ).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <random>
#include <sstream>

#include "cam/chamfer.hpp"
#include "cam/chamfer_ngc.hpp"
#include "core/error.hpp"
#include "tests/common/sanitized.hpp"
#include "tests/common/seed.hpp"

namespace ncd::toolpath {
namespace {

// ---------------------------------------------------------------- the part, described here

struct HolePart {
  double edge_radius_mm, other_radius_mm;  // at the origin, pipe frame
  double slope;                            // tan ψ
  double drill_radius_mm;
  Vec3 drill_point, drill_dir;  // drill axis in the pipe frame
};

Vec3 drill_direction(double tau, double phi) {
  return {std::sin(tau) * std::sin(phi), std::sin(tau) * std::cos(phi), std::cos(tau)};
}

HolePart part_of(const ChamferSpec& s) {
  HolePart p;
  p.edge_radius_mm = s.pipe_radius_mm;
  const double t = s.pipe_thickness_mm.value_or(0.0) / std::cos(s.pipe_half_angle_rad);
  p.other_radius_mm = s.edge == Edge::Inner ? s.pipe_radius_mm + t : s.pipe_radius_mm - t;
  p.slope = std::tan(s.pipe_half_angle_rad);
  p.drill_radius_mm = s.drill_radius_mm;
  p.drill_dir = drill_direction(s.drill_tilt_rad, s.drill_azimuth_rad);
  const Vec3 y(0.0, 1.0, 0.0);
  p.drill_point = s.eccentricity_mm * y.cross(p.drill_dir).normalized();
  return p;
}

// Signed radial excess over a pipe surface of radius `radius` at y = 0 (> 0 outside).
double pipe_excess(const HolePart& p, const Vec3& x, double radius) {
  return std::hypot(x.x(), x.z()) - (radius + p.slope * x.y());
}

double drill_excess(const HolePart& p, const Vec3& x) {
  const Vec3 w = x - p.drill_point;
  return (w - w.dot(p.drill_dir) * p.drill_dir).norm() - p.drill_radius_mm;
}

// How deep x lies inside the wall's material (between the two surfaces, outside the hole);
// ≤ 0 outside. Radial excesses overestimate the normal depth on a cone: conservative.
double hole_material_depth(const HolePart& p, const Vec3& x) {
  const double outer = std::max(p.edge_radius_mm, p.other_radius_mm);
  const double inner = std::min(p.edge_radius_mm, p.other_radius_mm);
  return std::min({-pipe_excess(p, x, outer), pipe_excess(p, x, inner), drill_excess(p, x)});
}

// The drill frame as the spec documents it, built here: z = d, y = part of +Y normal to d,
// x = y × z, origin on the drill axis nearest the pipe axis.
Vec3 generator_point(const HolePart& p, double theta, double z) {
  const Vec3 y0(0.0, 1.0, 0.0);
  const Vec3 yd = (y0 - y0.dot(p.drill_dir) * p.drill_dir).normalized();
  const Vec3 xd = yd.cross(p.drill_dir);
  return p.drill_point + p.drill_radius_mm * (std::cos(theta) * xd + std::sin(theta) * yd) +
         z * p.drill_dir;
}

// ---------------------------------------------------------------- random geometries

// A random inclined / eccentric / cone hole with a wall thickness; nullopt if it was refused
// (the drill does not pierce both surfaces) or the width cannot fit.
std::optional<ChamferSpec> random_hole(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  ChamferSpec s;
  const double outer = 10.0 + 90.0 * u(rng);
  const double thick = outer * (0.05 + 0.25 * u(rng));
  s.drill_radius_mm = (outer - thick) * (0.15 + 0.5 * u(rng));
  s.drill_tilt_rad = deg_to_rad(u(rng) < 0.2 ? 0.0 : 50.0 * u(rng));
  s.drill_azimuth_rad = deg_to_rad(360.0 * u(rng));
  s.eccentricity_mm =
      (u(rng) < 0.2 ? 0.0 : 1.0) * (2.0 * u(rng) - 1.0) * (outer - thick - s.drill_radius_mm) * 0.8;
  s.pipe_half_angle_rad = deg_to_rad(u(rng) < 0.3 ? 0.0 : 20.0 * (2.0 * u(rng) - 1.0));
  s.pipe_thickness_mm = thick;
  s.edge = u(rng) < 0.5 ? Edge::Inner : Edge::Outer;
  s.side = u(rng) < 0.5 ? Side::Upper : Side::Lower;
  s.pipe_radius_mm =
      s.edge == Edge::Outer ? outer : outer - thick / std::cos(s.pipe_half_angle_rad);
  s.ball_radius_mm = s.drill_radius_mm * (0.05 + 0.3 * u(rng));
  s.width_mm = 1.0;
  try {
    const ChamferModel probe(s);
    double fits = 1e300;
    for (int i = 0; i < 128; ++i) {
      fits = std::min(fits, probe.max_width(probe.frame(i * 2.0 * kPi / 128), 1.0));
    }
    s.width_mm = fits * (0.05 + 0.35 * u(rng));
    return s;
  } catch (const InputError&) {
    return std::nullopt;
  }
}

std::string describe(const ChamferSpec& s) {
  std::ostringstream o;
  o << to_string(s.edge) << "/" << to_string(s.side) << " R=" << s.pipe_radius_mm
    << " r=" << s.drill_radius_mm << " tilt=" << rad_to_deg(s.drill_tilt_rad)
    << " az=" << rad_to_deg(s.drill_azimuth_rad) << " e=" << s.eccentricity_mm
    << " psi=" << rad_to_deg(s.pipe_half_angle_rad) << " R_B=" << s.ball_radius_mm
    << " W=" << s.width_mm;
  return o.str();
}

// ---------------------------------------------------------------- the closed form recovered

ChamferSpec hole_experiment(int n, Edge edge, Side side) {
  ChamferSpec s;
  s.pipe_radius_mm = edge == Edge::Inner ? 18.0 : 21.0;
  s.drill_radius_mm = 13.0;
  s.ball_radius_mm = 3.0;
  s.width_mm = 0.7;
  s.rod_radius_mm = 1.8;
  s.non_knife_angle_rad = deg_to_rad(n == 1 ? 72.0 : 93.0);
  s.tolerance_mm = n == 1 ? 0.02 : 0.01;
  s.avoid = n == 3;
  s.edge = edge;
  s.side = side;
  return s;
}

TEST(ChamferHoles, NumericalEdgeEqualsEq4) {
  for (const Edge edge : {Edge::Inner, Edge::Outer}) {
    for (const Side side : {Side::Upper, Side::Lower}) {
      ChamferSpec closed = hole_experiment(3, edge, side);
      closed.edge_curve = EdgeCurve::ClosedForm;
      const ChamferModel mc(closed), mn(hole_experiment(3, edge, side));
      double worst = 0.0;
      for (int i = 0; i <= 3600; ++i) {
        const double th = 2.0 * kPi * i / 3600;
        // eq. (4)/(5) written out here.
        const double r = 13.0, rs = closed.pipe_radius_mm, c = std::cos(th);
        const Vec3 eq4(r * c, r * std::sin(th),
                       (side == Side::Upper ? 1.0 : -1.0) * std::sqrt(rs * rs - r * r * c * c));
        worst = std::max(worst, (mn.point(th) - eq4).norm());
        EXPECT_NEAR((mn.derivative(th) - mc.derivative(th)).norm(), 0.0, 1e-11);
        EXPECT_NEAR((mn.second_derivative(th) - mc.second_derivative(th)).norm(), 0.0, 1e-10);
        const EdgeFrame fn = mn.frame(th), fc = mc.frame(th);
        EXPECT_NEAR((fn.k - fc.k).norm(), 0.0, 1e-12);
        EXPECT_NEAR((fn.t2 - fc.t2).norm(), 0.0, 1e-14);
      }
      EXPECT_LE(worst, 1e-12) << to_string(edge) << " " << to_string(side);
      EXPECT_NEAR(mn.arc_length(0.0, 2.0 * kPi), mc.arc_length(0.0, 2.0 * kPi), 1e-11);
    }
  }
}

TEST(ChamferHoles, EveryDownstreamFigureEqualsTheClosedFormPath) {
  for (const int n : {1, 2, 3}) {
    for (const Edge edge : {Edge::Inner, Edge::Outer}) {
      for (const Side side : {Side::Upper, Side::Lower}) {
        ChamferSpec closed = hole_experiment(n, edge, side);
        closed.edge_curve = EdgeCurve::ClosedForm;
        const ChamferPath pc = generate_chamfer(closed);
        const ChamferPath pn = generate_chamfer(hole_experiment(n, edge, side));
        const std::string what =
            "exp " + std::to_string(n) + " " + to_string(edge) + " " + to_string(side);
        ASSERT_EQ(pn.points.size(), pc.points.size()) << what;
        for (std::size_t i = 0; i < pn.points.size(); ++i) {
          const CutterPose &a = pn.points[i], &b = pc.points[i];
          EXPECT_NEAR(a.theta_rad, b.theta_rad, 1e-12) << what;
          EXPECT_NEAR((a.xp - b.xp).norm(), 0.0, 1e-12) << what;
          EXPECT_NEAR((a.cl - b.cl).norm(), 0.0, 1e-10) << what;
          EXPECT_NEAR((a.a - b.a).norm(), 0.0, 1e-10) << what;
          EXPECT_NEAR((a.b - b.b).norm(), 0.0, 1e-10) << what;
          EXPECT_NEAR(a.delta_mm, b.delta_mm, 1e-10) << what;
          EXPECT_NEAR(a.alpha, b.alpha, 1e-9) << what;
          EXPECT_NEAR(a.minus_ez, b.minus_ez, 1e-10) << what;
          EXPECT_NEAR(a.cl_radius_mm, b.cl_radius_mm, 1e-10) << what;
          if (std::isfinite(b.inv_ke_mm)) {
            EXPECT_NEAR(a.inv_ke_mm, b.inv_ke_mm, 1e-6 * b.inv_ke_mm);
          }
        }
        const ChamferChecks &x = pn.checks, &y = pc.checks;
        EXPECT_EQ(x.local_ok, y.local_ok) << what;
        EXPECT_EQ(x.global_ok, y.global_ok) << what;
        EXPECT_EQ(x.rod_ok, y.rod_ok) << what;
        EXPECT_EQ(x.adjusted_points, y.adjusted_points) << what;
        EXPECT_NEAR(x.min_inv_ke_mm, y.min_inv_ke_mm, 1e-9) << what;
        EXPECT_NEAR(x.max_minus_ez, y.max_minus_ez, 1e-10) << what;
        EXPECT_NEAR(x.max_cl_radius_mm, y.max_cl_radius_mm, 1e-10) << what;
      }
    }
  }
}

TEST(ChamferHoles, TiltAcrossThePipeThroughItsAxisIsTheRadialHole) {
  // τ about the pipe axis (φ = 90°) with e = 0 is the paper's hole, the pipe turned about Y;
  // the azimuth alone is irrelevant without tilt.
  for (const auto& [tau, phi] : {std::pair{30.0, 90.0}, std::pair{0.0, 123.0}}) {
    ChamferSpec s = hole_experiment(3, Edge::Inner, Side::Upper);
    s.drill_tilt_rad = deg_to_rad(tau);
    s.drill_azimuth_rad = deg_to_rad(phi);
    const ChamferPath a = generate_chamfer(s),
                      b = generate_chamfer(hole_experiment(3, Edge::Inner, Side::Upper));
    ASSERT_EQ(a.points.size(), b.points.size());
    for (std::size_t i = 0; i < a.points.size(); ++i) {
      EXPECT_NEAR((a.points[i].cl - b.points[i].cl).norm(), 0.0, 1e-10);
    }
  }
}

TEST(ChamferHoles, NegativeEccentricityMirrorsPositive) {
  ChamferSpec s = hole_experiment(1, Edge::Inner, Side::Upper);
  s.drill_tilt_rad = deg_to_rad(30.0);
  s.pipe_half_angle_rad = deg_to_rad(4.0);
  s.eccentricity_mm = 2.5;
  const ChamferModel plus(s);
  s.eccentricity_mm = -2.5;
  const ChamferModel minus(s);
  for (const double th : {0.0, 0.3, 1.1, 2.0, 3.3, 4.4, 5.9}) {
    // x → −x maps the geometry onto itself with e → −e, θ → π − θ.
    const Vec3 p = plus.point(th), q = minus.point(kPi - th);
    EXPECT_NEAR((p - Vec3(-q.x(), q.y(), q.z())).norm(), 0.0, 1e-12) << th;
  }
}

// ---------------------------------------------------------------- frame

TEST(ChamferHoles, DrillFrameIsTheDocumentedOne) {
  std::mt19937_64 rng(ncd::test::seed());
  int checked = 0;
  while (checked < 200) {
    const auto s = random_hole(rng);
    if (!s) continue;
    ++checked;
    const HolePart part = part_of(*s);
    const DrillPlacement pl = drill_placement(*s);
    EXPECT_NEAR((pl.z - part.drill_dir).norm(), 0.0, 1e-15);
    EXPECT_NEAR((pl.origin - part.drill_point).norm(), 0.0, 1e-13);
    EXPECT_NEAR(pl.x.dot(pl.y), 0.0, 1e-15);
    EXPECT_NEAR(pl.x.cross(pl.y).dot(pl.z), 1.0, 1e-15);
    for (const double th : {0.0, 1.0, 4.0}) {
      EXPECT_NEAR((pl.to_pipe(ChamferModel(*s).point(th)) - generator_point(part, th, 0.0))
                      .cross(part.drill_dir)
                      .norm(),
                  0.0, 1e-11);
    }
  }
}

// ---------------------------------------------------------------- identities, random sweeps

TEST(ChamferHoles, IdentitiesOverRandomInclinedEccentricConeHoles) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int cases = 0, refused = 0;
  double worst_surface = 0.0, worst_width = 0.0, worst_arcs = 0.0, worst_plane = 0.0;
  while (cases < 400) {
    const auto spec = random_hole(rng);
    if (!spec) {
      ++refused;
      continue;
    }
    ++cases;
    const ChamferSpec& s = *spec;
    const HolePart part = part_of(s);
    const ChamferModel m(s);
    const DrillPlacement& pl = m.placement();
    for (int k = 0; k < 16; ++k) {
      const double th = 2.0 * kPi * u(rng);
      const EdgeFrame f = m.frame(th);
      const Vec3 x = pl.to_pipe(f.xp);
      // On both surfaces.
      worst_surface = std::max({worst_surface, std::abs(pipe_excess(part, x, s.pipe_radius_mm)),
                                std::abs(drill_excess(part, x))});
      // The pipe normal from this file's geometry: ∇ of |(x, z)| − R − y tan ψ.
      const Vec3 grad_pipe =
          Vec3(x.x() / std::hypot(x.x(), x.z()), -part.slope, x.z() / std::hypot(x.x(), x.z()));
      const double alpha = u(rng) < 0.5 ? 1.0 : [&] {
        const AlphaRange r = m.alpha_range(f);
        return r.lo + (std::min(r.hi, 3.0) - r.lo) * (0.05 + 0.9 * u(rng));
      }();
      const auto delta = m.solve_delta(f, alpha);
      if (!delta) {
        EXPECT_LE(m.max_width(f, alpha), s.width_mm) << describe(s);
        continue;
      }
      const CutterPose p = m.pose(f, alpha, *delta);
      worst_width = std::max(worst_width, std::abs((p.b - p.a).norm() - s.width_mm));
      // A in the hole's tangent plane, B in the pipe's, both in the normal plane T.
      const Vec3 na = pl.direction_to_pipe(p.a - p.xp), nb = pl.direction_to_pipe(p.b - p.xp);
      const Vec3 hole_normal =
          (x - part.drill_point) - (x - part.drill_point).dot(part.drill_dir) * part.drill_dir;
      worst_plane = std::max({worst_plane, std::abs(na.dot(hole_normal.normalized())),
                              std::abs(nb.dot(grad_pipe.normalized())),
                              std::abs((p.a - p.xp).dot(f.t)), std::abs((p.b - p.xp).dot(f.t))});
      EXPECT_NEAR((p.a - p.cl).norm(), s.ball_radius_mm, 1e-9);
      EXPECT_NEAR((p.b - p.cl).norm(), s.ball_radius_mm, 1e-9);
      if (alpha == 1.0) {
        // Two equal arcs of the ball from A and from B to where −e from x_p meets it.
        const double arc_a =
            s.ball_radius_mm * std::acos(std::min(1.0, (p.a - p.cl).normalized().dot(p.e)));
        const double arc_b =
            s.ball_radius_mm * std::acos(std::min(1.0, (p.b - p.cl).normalized().dot(p.e)));
        worst_arcs = std::max(worst_arcs, std::abs(arc_a - arc_b));
        EXPECT_NEAR((p.a - p.xp).norm(), (p.b - p.xp).norm(), 1e-9);
      }
      // The curvature vector is normal to t and equals dt/ds (a central difference, loose).
      EXPECT_NEAR(f.k.dot(f.t), 0.0, 1e-12 * std::max(1.0, f.k.norm()));
      const double h = 1e-5;
      const Vec3 dt = (m.frame(th + h).t - m.frame(th - h).t) / (2.0 * h * m.speed(th));
      EXPECT_NEAR((f.k - dt).norm(), 0.0, 1e-6 * std::max(1.0, f.k.norm())) << describe(s);
    }
  }
  std::cout << "[ sweep    ] " << cases << " geometries (" << refused
            << " refused as not piercing); worst: off-surface " << worst_surface << " mm, |AB| − W "
            << worst_width << " mm, arc difference " << worst_arcs << " mm, off-plane "
            << worst_plane << " mm\n";
  EXPECT_LE(worst_surface, 1e-12);
  EXPECT_LE(worst_width, 1e-9);
  EXPECT_LE(worst_arcs, 1e-9);
  EXPECT_LE(worst_plane, 1e-9);
}

TEST(ChamferHoles, RodLimitHeldOverRandomHoles) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int paths = 0, adjusted = 0, cannot = 0;
  while (paths < 60) {
    auto spec = random_hole(rng);
    if (!spec || spec->edge != Edge::Inner) continue;
    ChamferSpec s = *spec;
    s.tolerance_mm = 0.02 * s.pipe_radius_mm / 20.0;
    const ChamferModel probe(s);
    double lo = 1e300, hi = -1e300;
    for (int i = 0; i < 64; ++i) {
      const double v = probe.pose_at(i * 2.0 * kPi / 64, 1.0).cl_radius_mm;
      lo = std::min(lo, v), hi = std::max(hi, v);
    }
    s.rod_radius_mm = s.drill_radius_mm - (lo + (hi - lo) * (0.5 + 0.5 * u(rng)));
    ChamferPath path;
    try {
      path = generate_chamfer(s);
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("cannot be met"), std::string::npos) << e.what();
      ++cannot;
      continue;
    }
    ++paths;
    const double rr = *path.checks.limit_radius_mm;
    for (const auto& p : path.points) {
      EXPECT_LE(p.cl_radius_mm, rr) << describe(s);
      EXPECT_NEAR(p.width_mm, s.width_mm, 1e-9);
      adjusted += p.alpha > 1.0;
    }
  }
  std::cout << "[ sweep    ] " << paths << " paths, " << adjusted << " points adjusted, " << cannot
            << " refused (limit cannot be met)\n";
  EXPECT_GT(adjusted, 0);
}

// ---------------------------------------------------------------- the fast paths, held to the slow
// ones

// The segmentation as eqs. (29)–(34) state it, written here: each piece split at its midpoint
// while ChamferModel::chord_deviation (the true maximum) exceeds ε.
std::vector<double> reference_segment(const ChamferModel& m) {
  const std::vector<double> start = m.equal_arc_starts();
  std::vector<double> out;
  const std::function<void(double, double)> split = [&](double a, double b) {
    if (m.chord_deviation(a, b) > m.spec().tolerance_mm) {
      split(a, 0.5 * (a + b));
      split(0.5 * (a + b), b);
    } else {
      out.push_back(a);
    }
  };
  for (std::size_t k = 0; k + 1 < start.size(); ++k) split(start[k], start[k + 1]);
  return out;
}

TEST(ChamferHoles, SegmentationDecidesAsTheTrueDeviation) {
  // segment() stops chord_deviation's Newton once the answer is certain; the points must be
  // exactly those of the full maximum, over random holes and tolerances from 1 µm to 0.3 mm.
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int cases = 0;
  std::size_t points = 0;
  while (cases < ncd::test::sweep_cases(60)) {
    auto spec = random_hole(rng);
    if (!spec) continue;
    spec->tolerance_mm = std::pow(10.0, -3.0 + 2.5 * u(rng)) * spec->pipe_radius_mm / 20.0;
    spec->tolerance_mm = std::clamp(spec->tolerance_mm, 1e-3, 0.3);
    ++cases;
    const ChamferModel m(*spec);
    const std::vector<double> fast = m.segment(), slow = reference_segment(m);
    EXPECT_EQ(fast, slow) << describe(*spec) << " ε " << spec->tolerance_mm;
    points += fast.size();
  }
  std::cout << "[ measured ] " << points << " points over " << cases << " holes, all equal\n";
}

TEST(ChamferHoles, SegmentFramesAreTheFramesAtTheSegmentsThetas) {
  std::mt19937_64 rng(ncd::test::seed());
  int cases = 0;
  while (cases < ncd::test::sweep_cases(30)) {
    const auto spec = random_hole(rng);
    if (!spec) continue;
    ++cases;
    const ChamferModel m(*spec);
    const std::vector<double> th = m.segment();
    const std::vector<EdgeFrame> frames = m.segment_frames();
    ASSERT_EQ(frames.size(), th.size());
    for (std::size_t i = 0; i < th.size(); ++i) {
      const EdgeFrame f = m.frame(th[i]), &g = frames[i];
      EXPECT_EQ(g.theta_rad, f.theta_rad);
      EXPECT_EQ(g.xp, f.xp);  // bit for bit: the same jet at the same θ
      EXPECT_EQ(g.t, f.t);
      EXPECT_EQ(g.k, f.k);
      EXPECT_EQ(g.t1, f.t1);
      EXPECT_EQ(g.t2, f.t2);
      EXPECT_EQ(g.c, f.c);
    }
  }
}

TEST(ChamferHoles, DeltaAtTheBisectorIsNewtonsRootAtAlphaOne) {
  // The closed form of δ at α = 1 against solve_delta's Newton, including widths that do not
  // fit (both refuse) and wedges from sharp to nearly flat.
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int cases = 0, refused = 0;
  double worst = 0.0;
  while (cases < ncd::test::sweep_cases(100)) {
    auto spec = random_hole(rng);
    if (!spec) continue;
    ++cases;
    const ChamferModel probe(*spec);
    for (int k = 0; k < 32; ++k) {
      const EdgeFrame f = probe.frame(2.0 * kPi * u(rng));
      ChamferSpec s = *spec;
      s.width_mm = probe.max_width(f, 1.0) * (k % 8 == 0 ? 1.0 + u(rng) : 0.999 * u(rng));
      if (!(s.width_mm > 0.0)) continue;
      const ChamferModel m(s);
      const auto closed = m.delta_at_bisector(f), newton = m.solve_delta(f, 1.0);
      ASSERT_EQ(closed.has_value(), newton.has_value()) << describe(s);
      if (!closed) {
        ++refused;
        continue;
      }
      worst = std::max(worst, std::abs(*closed - *newton) / s.ball_radius_mm);
      EXPECT_NEAR(*closed, *newton, 1e-12 * s.ball_radius_mm) << describe(s);
      EXPECT_NEAR(m.pose(f, 1.0, *closed).width_mm, s.width_mm, 1e-9);
    }
  }
  std::cout << "[ measured ] largest |δ closed − δ Newton| / R_B " << worst << ", " << refused
            << " widths refused by both\n";
  EXPECT_GT(refused, 0);
}

TEST(ChamferHoles, AlgorithmOneFromAnyHintFindsTheSameAlpha) {
  // generate_chamfer starts Algorithm 1 at α extrapolated from the neighbouring points. From
  // any hint (good, poor, past the admissible bound, below 1) it must find the α found without
  // one: the same decision, α to 1e-9, CL within R_R and no further in than 1e-9 mm.
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int cases = 0, adjusted = 0, uncleared = 0;
  while (cases < ncd::test::sweep_cases(40)) {
    auto spec = random_hole(rng);
    if (!spec || spec->edge != Edge::Inner) continue;
    ChamferSpec s = *spec;
    const ChamferModel probe(s);
    double lo = 1e300, hi = -1e300;
    for (int i = 0; i < 64; ++i) {
      const double v = probe.pose_at(i * 2.0 * kPi / 64, 1.0).cl_radius_mm;
      lo = std::min(lo, v), hi = std::max(hi, v);
    }
    s.rod_radius_mm = s.drill_radius_mm - (lo + (hi - lo) * u(rng));
    const ChamferModel m(s);
    const double limit = *m.rod_limit_radius_mm();
    ++cases;
    for (int k = 0; k < 16; ++k) {
      const EdgeFrame f = m.frame(2.0 * kPi * u(rng));
      const RodAvoidance plain = m.avoid_rod(f);
      if (!plain.cleared) ++uncleared;
      if (plain.adjusted) ++adjusted;
      const double top = m.alpha_range(f).hi;
      for (const double hint :
           {0.5, 1.0, plain.alpha * (1.0 + 1e-6), plain.alpha * (1.0 - 1e-6), plain.alpha + 0.3,
            1.0 + 0.5 * (plain.alpha - 1.0), top * 0.9999, top * 2.0, 1e9}) {
        const RodAvoidance r = m.avoid_rod(f, hint);
        ASSERT_EQ(r.cleared, plain.cleared) << describe(s) << " hint " << hint;
        ASSERT_EQ(r.adjusted, plain.adjusted) << describe(s) << " hint " << hint;
        if (!r.cleared) continue;
        EXPECT_NEAR(r.alpha, plain.alpha, 1e-9 * plain.alpha) << describe(s) << " hint " << hint;
        EXPECT_NEAR(r.delta_mm, *m.solve_delta(f, r.alpha), 1e-12);
        const double radius = m.pose(f, r.alpha, r.delta_mm).cl_radius_mm;
        EXPECT_LE(radius, limit) << describe(s) << " hint " << hint;
        if (r.adjusted) {
          EXPECT_GE(radius, limit - 1e-9) << describe(s) << " hint " << hint;
        }
      }
    }
  }
  std::cout << "[ measured ] " << adjusted << " adjusted, " << uncleared << " uncleared of "
            << cases * 16 << " points\n";
  EXPECT_GT(adjusted, 0);
}

// ---------------------------------------------------------------- slow reference

// The edge by brute force: for each θ, bisection along the generator between the point most
// inside the pipe (golden section: the radial excess is convex along a line) and one outside,
// on this file's radial excess.
Vec3 brute_edge_point(const HolePart& p, double radius, double theta, bool upper) {
  const auto excess = [&](double z) {
    return pipe_excess(p, generator_point(p, theta, z), radius);
  };
  double lo = -8.0 * radius, hi = 8.0 * radius;
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  for (int i = 0; i < 120; ++i) {
    const double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
    (excess(x1) < excess(x2) ? hi : lo) = excess(x1) < excess(x2) ? x2 : x1;
  }
  double in = 0.5 * (lo + hi);
  EXPECT_LT(excess(in), 0.0) << "θ = " << theta << ": the generator misses the surface";
  const double dir = upper ? 1.0 : -1.0;
  double out = in + dir * radius;
  while (excess(out) < 0.0) out = in + 2.0 * (out - in);
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (in + out);
    if (mid == in || mid == out) break;
    (excess(mid) < 0.0 ? in : out) = mid;
  }
  return generator_point(p, theta, 0.5 * (in + out));
}

TEST(ChamferHoles, EqualArcsFromTheSpeedSeriesEqualTheQuadratureOnes) {
  // The segmentation's N equal arcs come from the Fourier series of |C'| (Halley on its
  // antiderivative); the composite Gauss–Legendre + Newton of eqs. (29)–(33) is the reference.
  std::mt19937_64 rng(ncd::test::seed());
  int cases = 0, with_series = 0;
  double worst = 0.0;
  while (cases < 100) {
    const auto spec = random_hole(rng);
    if (!spec) continue;
    ++cases;
    const ChamferModel m(*spec);
    if (m.speed_series()) ++with_series;
    const std::vector<double> a = m.equal_arc_starts(), b = m.equal_arc_starts_by_quadrature();
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t i = 0; i < a.size(); ++i) {
      worst = std::max(worst, std::abs(a[i] - b[i]));
      EXPECT_NEAR(a[i], b[i], 1e-12) << describe(*spec) << " θ_" << i;
    }
  }
  std::cout << "[ measured ] " << with_series << " of " << cases
            << " holes by the series; largest |Δθ| " << worst << " rad\n";
  EXPECT_GE(with_series, 90);
}

TEST(ChamferHoles, NearlyGrazingDrillFallsBackToQuadrature) {
  // r + e = 17.9999 against R = 18: the edge nearly touches the pipe's silhouette, |C'| has a
  // singularity 1e-3 rad off the real axis, and no series of 4096 samples resolves it.
  ChamferSpec s = hole_experiment(3, Edge::Inner, Side::Upper);
  s.eccentricity_mm = 4.9999;
  s.rod_radius_mm.reset();
  s.non_knife_angle_rad.reset();
  const ChamferModel m(s);
  EXPECT_FALSE(m.speed_series().has_value());
  EXPECT_EQ(m.equal_arc_starts(), m.equal_arc_starts_by_quadrature());
}

TEST(ChamferHoles, RodInterferenceSlopeIsItsDerivative) {
  // dF/dα by implicit differentiation against a central difference with δ re-solved.
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int cases = 0;
  double worst = 0.0;
  while (cases < 60) {
    auto spec = random_hole(rng);
    if (!spec || spec->edge != Edge::Inner) continue;
    spec->rod_radius_mm = 0.1 * spec->drill_radius_mm;
    ++cases;
    const ChamferModel m(*spec);
    for (int k = 0; k < 8; ++k) {
      const EdgeFrame f = m.frame(2.0 * kPi * u(rng));
      const AlphaRange r = m.alpha_range(f);
      const double alpha = r.lo + (std::min(r.hi, 3.0) - r.lo) * (0.1 + 0.8 * u(rng));
      const double h = 1e-6 * alpha;
      const auto d0 = m.solve_delta(f, alpha), dp = m.solve_delta(f, alpha + h),
                 dm = m.solve_delta(f, alpha - h);
      if (!d0 || !dp || !dm) continue;
      const RodInterference at = m.rod_interference_and_slope(f, alpha, *d0);
      EXPECT_NEAR(at.value_mm, m.rod_interference(f, alpha, *d0), 1e-12);
      const double fd =
          (m.rod_interference(f, alpha + h, *dp) - m.rod_interference(f, alpha - h, *dm)) / (2 * h);
      worst = std::max(worst, std::abs(at.slope_mm - fd) / std::max(1.0, std::abs(fd)));
      EXPECT_NEAR(at.slope_mm, fd, 1e-6 * std::max(1.0, std::abs(fd))) << describe(*spec);
    }
  }
  std::cout << "[ measured ] largest relative slope error " << worst << "\n";
}

TEST(ChamferHoles, BruteForceIntersectionGivesTheSameCurveAndLength) {
  std::mt19937_64 rng(ncd::test::seed());
  int cases = 0;
  double worst_point = 0.0, worst_length = 0.0;
  while (cases < ncd::test::sweep_cases(12)) {
    const auto spec = random_hole(rng);
    if (!spec) continue;
    ++cases;
    const ChamferSpec& s = *spec;
    const HolePart part = part_of(s);
    const ChamferModel m(s);
    const int n = 1 << 14;
    std::vector<Vec3> pts(n);
    for (int i = 0; i < n; ++i) {
      const double th = 2.0 * kPi * i / n;
      pts[static_cast<std::size_t>(i)] =
          brute_edge_point(part, s.pipe_radius_mm, th, s.side == Side::Upper);
      if (i % 64 == 0) {
        worst_point = std::max(
            worst_point,
            (m.placement().to_pipe(m.point(th)) - pts[static_cast<std::size_t>(i)]).norm());
      }
    }
    // Polygon lengths on n and n/2 points, Richardson-extrapolated (error O(n⁻⁴)).
    double fine = 0.0, coarse = 0.0;
    for (int i = 0; i < n; ++i)
      fine +=
          (pts[static_cast<std::size_t>((i + 1) % n)] - pts[static_cast<std::size_t>(i)]).norm();
    for (int i = 0; i < n; i += 2)
      coarse +=
          (pts[static_cast<std::size_t>((i + 2) % n)] - pts[static_cast<std::size_t>(i)]).norm();
    const double brute = (4.0 * fine - coarse) / 3.0;
    worst_length = std::max(worst_length, std::abs(brute - m.arc_length(0.0, 2.0 * kPi)));
    EXPECT_NEAR(m.arc_length(0.0, 2.0 * kPi), brute, 1e-9) << describe(s);
  }
  std::cout << "[ brute    ] worst point difference " << worst_point << " mm, arc length "
            << worst_length << " mm\n";
  EXPECT_LE(worst_point, 1e-9);
}

// ---------------------------------------------------------------- interference, point clouds

// Samples the ball's non-cutting cap (half-angle β about the tool axis) and the rod (radius
// R_od, from the ball up to well above the part) at every cutter location, in the pipe frame,
// and returns the deepest any lies inside the part's material.
double deepest_cap_or_rod(const ChamferSpec& s, const ChamferPath& path, const DrillPlacement& pl) {
  const HolePart part = part_of(s);
  const double beta = 0.5 * *s.non_knife_angle_rad, rb = s.ball_radius_mm, rod = *s.rod_radius_mm;
  const double up = s.side == Side::Upper ? 1.0 : -1.0;  // the tool axis, part turned over below
  const Vec3 z(0.0, 0.0, up), x(1.0, 0.0, 0.0), y(0.0, up, 0.0);
  const double height = 4.0 * std::max(part.edge_radius_mm, part.other_radius_mm);
  double deepest = -1e300;
  for (const auto& p : path.points) {
    for (int i = 0; i <= 8; ++i) {
      const double polar = beta * i / 8;
      for (int j = 0; j < 24; ++j) {
        const double az = 2.0 * kPi * j / 24;
        const Vec3 v =
            std::cos(polar) * z + std::sin(polar) * (std::cos(az) * x + std::sin(az) * y);
        deepest = std::max(deepest, hole_material_depth(part, pl.to_pipe(p.cl + rb * v)));
      }
    }
    const double h0 = std::sqrt(std::max(0.0, rb * rb - rod * rod));
    for (int i = 0; i <= 200; ++i) {
      const double h = h0 + (height - h0) * i / 200;
      for (int j = 0; j < 24; ++j) {
        const double az = 2.0 * kPi * j / 24;
        const Vec3 q = p.cl + h * z + rod * (std::cos(az) * x + std::sin(az) * y);
        deepest = std::max(deepest, hole_material_depth(part, pl.to_pipe(q)));
      }
    }
  }
  return deepest;
}

TEST(ChamferHoles, CapAndRodStayOutOfTheMaterial) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int inner = 0, outer = 0, refused = 0;
  double worst = -1e300;
  while (inner + outer < ncd::test::sweep_cases(80)) {
    auto spec = random_hole(rng);
    if (!spec) continue;
    ChamferSpec s = *spec;
    s.tolerance_mm = 0.05;
    s.non_knife_angle_rad = deg_to_rad(40.0 + 60.0 * u(rng));
    s.rod_radius_mm = s.ball_radius_mm * (0.3 + 0.5 * u(rng));
    ChamferPath path;
    try {
      path = generate_chamfer(s);
    } catch (const InputError&) {
      ++refused;  // the rod limit cannot be met: nothing to cut with
      continue;
    }
    if (!interference_reasons(path).empty()) {
      ++refused;  // refused for NC output: checked in GlobalFailureIsRefusedWithItsRange
      continue;
    }
    (s.edge == Edge::Inner ? inner : outer)++;
    const double d = deepest_cap_or_rod(s, path, ChamferModel(s).placement());
    worst = std::max(worst, d);
    EXPECT_LE(d, 1e-3) << describe(s);
  }
  std::cout << "[ clouds   ] " << inner << " inner and " << outer << " outer edges, " << refused
            << " refused; deepest cap or rod point in the material " << worst << " mm\n";
}

TEST(ChamferHoles, PointCloudsSeeTheInterferenceOfExperiment2) {
  // The paper's experiment 2 (α = 1, 2β = 93°) scars the chamfer: the clouds must see it, and
  // Algorithm 1 (experiment 3) must clear it; also for an inclined, eccentric cone hole.
  for (const bool inclined : {false, true}) {
    ChamferSpec s = hole_experiment(2, Edge::Inner, Side::Upper);
    s.pipe_thickness_mm = 3.0;
    if (inclined) {
      s.drill_tilt_rad = deg_to_rad(20.0);
      s.eccentricity_mm = 1.0;
      s.pipe_half_angle_rad = deg_to_rad(3.0);
    }
    const ChamferPath scarred = generate_chamfer(s);
    EXPECT_FALSE(scarred.checks.rod_ok);
    const DrillPlacement pl = drill_placement(s);
    EXPECT_GT(deepest_cap_or_rod(s, scarred, pl), 0.01);
    s.avoid = true;
    const ChamferPath clear = generate_chamfer(s);
    EXPECT_LE(deepest_cap_or_rod(s, clear, pl), 1e-3);
  }
}

TEST(ChamferHoles, FailedChecksAreRefusedWithTheirThetaRange) {
  // A 60° lateral of r = 8 mm: the acute side of the inner edge curves tighter than R_B = 3.
  ChamferSpec s;
  s.pipe_radius_mm = 18.0;
  s.drill_radius_mm = 8.0;
  s.ball_radius_mm = 3.0;
  s.width_mm = 0.7;
  s.drill_tilt_rad = deg_to_rad(60.0);
  const ChamferPath path = generate_chamfer(s);
  ASSERT_FALSE(path.checks.local_ok);
  ASSERT_EQ(path.checks.local_fail.size(), 1u);  // around the acute end, θ = 90°
  EXPECT_LT(path.checks.local_fail[0].from_rad, 0.5 * kPi);
  EXPECT_GT(path.checks.local_fail[0].to_rad, 0.5 * kPi);
  for (const auto& p : path.points) {
    bool inside = false;
    for (const auto& r : path.checks.local_fail) {
      inside |= p.theta_rad >= r.from_rad && p.theta_rad <= r.to_rad;
    }
    EXPECT_EQ(inside, p.inv_ke_mm < s.ball_radius_mm) << p.theta_rad;
  }
  const std::string why = interference_reasons(path);
  EXPECT_NE(why.find("local: the edge curves more tightly than the ball"), std::string::npos);
  EXPECT_NE(why.find("θ ∈ ["), std::string::npos) << why;
  EXPECT_EQ(why.find("global"), std::string::npos) << why;
  EXPECT_TRUE(
      interference_reasons(generate_chamfer(hole_experiment(3, Edge::Inner, Side::Upper))).empty());
}

// ---------------------------------------------------------------- refusals

void expect_error(const ChamferSpec& s, const std::string& fragment) {
  try {
    (void)generate_chamfer(s);
    FAIL() << "expected InputError containing \"" << fragment << "\"";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
}

TEST(ChamferHoles, DrillsThatDoNotPierceAreRefusedWithTheirValues) {
  ChamferSpec s = hole_experiment(1, Edge::Inner, Side::Upper);
  s.eccentricity_mm = 5.5;  // r + e = 18.5 > R_I = 18: the generator at θ = 0 misses
  expect_error(s, "does not pierce the inner pipe surface (radius 18 mm");
  expect_error(s, "θ = 0°");
  expect_error(s, "eccentricity 5.5 mm");
  s.eccentricity_mm = 5.0;  // r + e = R_I exactly: the generator at θ = 0 touches the bore
  expect_error(s, "θ = 0° only grazes it");
  s.eccentricity_mm = -5.0;  // and at θ = 180° on the other side
  expect_error(s, "θ = 180° only grazes it");
  s.eccentricity_mm = std::nan("");
  expect_error(s, "--eccentricity");
  s.eccentricity_mm = 4.0;
  s.pipe_thickness_mm = 3.0;  // fine inside; the outer surface (21 mm) is pierced too
  EXPECT_NO_THROW((void)generate_chamfer(s));
  s = hole_experiment(1, Edge::Outer, Side::Upper);
  s.eccentricity_mm = 4.0;
  s.pipe_thickness_mm = 3.0;  // inner surface 18 mm: 13 + 4 < 18 still pierced
  EXPECT_NO_THROW((void)ChamferModel(s));
  s.pipe_thickness_mm = 4.5;  // inner 16.5 mm < 17: missed
  expect_error(s, "does not pierce the inner pipe surface (radius 16.5 mm");
  s = hole_experiment(1, Edge::Inner, Side::Upper);
  s.drill_tilt_rad = deg_to_rad(90.0);
  expect_error(s, "drill tilt τ = 90° must lie in [0°, 90°)");
  s.drill_tilt_rad = deg_to_rad(60.0);  // along the cylinder: still pierced
  EXPECT_NO_THROW((void)ChamferModel(s));
  s.pipe_half_angle_rad = deg_to_rad(40.0);  // axes at 30° inside a 40° cone: no hole
  expect_error(s, "runs at 30° to the pipe axis, which must exceed the half-angle 40°");
  s.pipe_half_angle_rad = 0.0;
  s.drill_azimuth_rad = deg_to_rad(90.0);  // across the pipe: the offset counts as untilted,
  s.eccentricity_mm = 4.0;                 // 13 + 4 < 18 pierces, 13 + 5.5 > 18 does not
  EXPECT_NO_THROW((void)ChamferModel(s));
  s.eccentricity_mm = 5.5;
  expect_error(s, "does not pierce");
  s = hole_experiment(1, Edge::Inner, Side::Upper);
  s.pipe_half_angle_rad = deg_to_rad(70.0);
  expect_error(s, "half-angle ψ = 70° must lie in");
  s.pipe_half_angle_rad = std::nan("");
  expect_error(s, "--pipe-half-angle-deg");
  s = hole_experiment(1, Edge::Outer, Side::Upper);
  s.pipe_thickness_mm = 25.0;
  expect_error(s, "leaves no bore");
  s = hole_experiment(1, Edge::Outer, Side::Upper);  // a wide drill near a steep cone's apex
  s.pipe_radius_mm = 16.0;
  s.drill_radius_mm = 17.0;
  s.ball_radius_mm = 1.0;
  s.drill_tilt_rad = deg_to_rad(43.0);
  s.drill_azimuth_rad = deg_to_rad(167.5);
  s.eccentricity_mm = -6.4;
  s.pipe_half_angle_rad = deg_to_rad(-42.0);
  expect_error(s,
               "meets the outer pipe surface (radius 16 mm at the reference point, half-angle "
               "-42°) beyond the cone's apex at θ = 59°");
  s = hole_experiment(1, Edge::Inner, Side::Upper);
  s.eccentricity_mm = 1.0;
  s.edge_curve = EdgeCurve::ClosedForm;
  expect_error(s, "closed-form edge curve (eq. 4) holds only");
}

// The drill along one generator, written here in the pipe frame: P(z) = P0 + z d meets the
// surface x² + z² = (R + k y)² where A z² + B z + C = 0. Its half-gap (z₊ − z₋)/2, negative
// where it misses (−sqrt(−disc)/(2A)), and the smallest ρ = R + k y at its roots.
struct GeneratorMeets {
  double half_gap_mm;
  double least_rho_mm;  // +inf where it misses
};

GeneratorMeets generator_meets(const HolePart& p, double radius, double theta) {
  const Vec3 p0 = generator_point(p, theta, 0.0), &d = p.drill_dir;
  const double k = p.slope, rho0 = radius + k * p0.y();
  const double a = d.x() * d.x() + d.z() * d.z() - k * k * d.y() * d.y();
  const double b = 2.0 * (p0.x() * d.x() + p0.z() * d.z() - k * d.y() * rho0);
  const double c = p0.x() * p0.x() + p0.z() * p0.z() - rho0 * rho0;
  const double disc = b * b - 4.0 * a * c;
  if (disc < 0.0) return {-std::sqrt(-disc) / (2.0 * a), kInf};
  double least = kInf;
  for (const double sign : {-1.0, 1.0}) {
    least = std::min(least, rho0 + k * d.y() * (-b + sign * std::sqrt(disc)) / (2.0 * a));
  }
  return {std::sqrt(disc) / (2.0 * a), least};
}

// "… θ = 12.5° …" → 12.5.
double theta_named_deg(const std::string& what) {
  const auto at = what.find("θ = ");
  return at == std::string::npos ? std::nan("")
                                 : std::stod(what.substr(at + std::string("θ = ").size()));
}

TEST(ChamferHoles, PiercingRefusalsAgreeWithADenseScanOfTheWall) {
  // validate() finds the smallest half-gap and ρ at the roots as minima of trigonometric
  // polynomials in θ. Against 7200 generators per surface, each intersected here: an accepted
  // hole has every sampled generator through each wall surface (half-gap > 1 µm, ρ > 0 at both
  // roots); a refused one names a θ where, within ±0.05°, a generator grazes, misses, or meets
  // the far nappe.
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int accepted = 0, pierce = 0, apex = 0, cases = 0;
  while (cases < ncd::test::sweep_cases(300)) {
    ChamferSpec s;
    const bool wild = u(rng) < 0.5;  // wide drills far off the axis in steep cones: the apex
    s.pipe_radius_mm = 5.0 + 45.0 * u(rng);
    s.drill_radius_mm = s.pipe_radius_mm * (0.1 + (wild ? 1.9 : 0.9) * u(rng));
    s.drill_tilt_rad = deg_to_rad(u(rng) < 0.2 ? 0.0 : (wild ? 85.0 : 75.0) * u(rng));
    s.drill_azimuth_rad = deg_to_rad(360.0 * u(rng));
    s.eccentricity_mm = (2.0 * u(rng) - 1.0) * s.pipe_radius_mm * (wild ? 4.0 : 0.6);
    s.pipe_half_angle_rad =
        deg_to_rad(u(rng) < 0.2 ? 0.0 : (wild ? 55.0 : 40.0) * (2.0 * u(rng) - 1.0));
    s.edge = u(rng) < 0.5 ? Edge::Inner : Edge::Outer;
    if (u(rng) < 0.5) s.pipe_thickness_mm = s.pipe_radius_mm * 0.2 * u(rng);
    s.ball_radius_mm = 0.05 * s.drill_radius_mm;
    const HolePart part = part_of(s);
    const Vec3& d = part.drill_dir;
    if (!(d.x() * d.x() + d.z() * d.z() - part.slope * part.slope * d.y() * d.y() > 1e-6)) continue;
    if (s.pipe_half_angle_rad == 0.0 && s.drill_radius_mm >= s.pipe_radius_mm) continue;
    if (s.pipe_thickness_mm && !(part.other_radius_mm > 0.0)) continue;
    ++cases;
    std::vector<double> radii{part.edge_radius_mm};
    if (s.pipe_thickness_mm) radii.push_back(part.other_radius_mm);
    try {
      validate(s);
      ++accepted;
      for (const double radius : radii) {
        for (int i = 0; i < 7200; ++i) {
          const GeneratorMeets g = generator_meets(part, radius, 2.0 * kPi * i / 7200);
          ASSERT_GT(g.half_gap_mm, 1e-6) << describe(s) << " radius " << radius << " i " << i;
          ASSERT_GT(g.least_rho_mm, 0.0) << describe(s) << " radius " << radius << " i " << i;
        }
      }
    } catch (const InputError& e) {
      const std::string what = e.what();
      const double th = deg_to_rad(theta_named_deg(what));
      ASSERT_TRUE(std::isfinite(th)) << what;
      const bool inner_named = what.find("the inner pipe surface") != std::string::npos;
      const double radius =
          inner_named == (s.edge == Edge::Inner) ? part.edge_radius_mm : part.other_radius_mm;
      double least_gap = kInf, least_rho = kInf;
      for (int i = -50; i <= 50; ++i) {
        const GeneratorMeets g = generator_meets(part, radius, th + deg_to_rad(0.001 * i));
        least_gap = std::min(least_gap, g.half_gap_mm);
        least_rho = std::min(least_rho, g.least_rho_mm);
      }
      if (what.find("does not pierce") != std::string::npos) {
        ++pierce;
        EXPECT_LE(least_gap, 1e-6 + 1e-9) << what;
        EXPECT_EQ(what.find("only grazes") != std::string::npos, least_gap > -1e-6) << what;
      } else if (what.find("beyond the cone's apex") != std::string::npos) {
        ++apex;
        EXPECT_LE(least_rho, 1e-9 * radius) << what;
      } else {
        ADD_FAILURE() << "unexpected refusal: " << what;
      }
    }
  }
  std::cout << "[ measured ] " << accepted << " accepted, " << pierce << " not pierced, " << apex
            << " beyond the apex, of " << cases << "\n";
  EXPECT_GE(accepted, cases / 10);
  EXPECT_GE(pierce, cases / 10);
  EXPECT_GE(apex, cases / 300);
}

TEST(ChamferHoles, PipeFrameIsRefusedForATiltedDrillAndIsAShiftOtherwise) {
  ChamferSpec s = hole_experiment(3, Edge::Inner, Side::Upper);
  s.eccentricity_mm = 2.0;
  NgcOptions o;
  o.safe_z_mm = default_safe_z_mm(s);
  o.frame = ProgramFrame::Pipe;
  const ChamferPath path = generate_chamfer(s);
  const std::string ngc = chamfer_program(path, o);
  EXPECT_NE(ngc.find("PIPE frame"), std::string::npos);
  EXPECT_NE(ngc.find("G0 X2.0000 Y0.0000"), std::string::npos) << ngc.substr(0, 1200);
  const Vec3 q = program_point(s, path.points[3], ProgramPoint::Centre, ProgramFrame::Pipe);
  EXPECT_NEAR((q - path.points[3].cl - Vec3(2.0, 0.0, 0.0)).norm(), 0.0, 1e-15);
  s.drill_tilt_rad = deg_to_rad(20.0);
  s.rod_radius_mm.reset();
  s.non_knife_angle_rad.reset();
  try {
    (void)chamfer_program(generate_chamfer(s), o);
    FAIL() << "pipe frame with a tilted drill must be refused";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("tilt τ = 20.000 deg"), std::string::npos) << e.what();
  }
  o.frame = ProgramFrame::Drill;
  const std::string drill = chamfer_program(generate_chamfer(s), o);
  EXPECT_NE(drill.find("DRILL AXIS VERTICAL"), std::string::npos);
  // RS-274 comments do not nest: at most one '(' and one ')' per line.
  std::istringstream lines(drill);
  for (std::string line; std::getline(lines, line);) {
    EXPECT_LE(std::count(line.begin(), line.end(), '('), 1) << line;
    EXPECT_LE(std::count(line.begin(), line.end(), ')'), 1) << line;
  }
  EXPECT_NE(drill.find("rising 20.000 deg"), std::string::npos) << drill.substr(0, 1500);
}

}  // namespace
}  // namespace ncd::toolpath
