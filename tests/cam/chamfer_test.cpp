// Chamfer generator (paper 000) against the paper's figures as settled in docs/chamfer.md, exact
// identities over random geometries, and slow references written here (dense scans,
// brute-force chord deviation, Simpson arc length).
#include "cam/chamfer.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <iostream>
#include <random>

#include "core/error.hpp"
#include "tests/common/sanitized.hpp"
#include "tests/common/seed.hpp"

namespace ncd::toolpath {
namespace {

constexpr double kHalfPi = 0.5 * kPi;

// The paper's section 5.1 geometry (radii, docs/chamfer.md): R_I = 18, r = 13, R_B = 3, W = 0.7.
ChamferSpec paper_geometry() {
  ChamferSpec s;
  s.pipe_radius_mm = 18.0;
  s.drill_radius_mm = 13.0;
  s.ball_radius_mm = 3.0;
  s.width_mm = 0.7;
  return s;
}

ChamferSpec experiment(int n) {
  ChamferSpec s = paper_geometry();
  s.rod_radius_mm = 1.8;
  s.non_knife_angle_rad = deg_to_rad(n == 1 ? 72.0 : 93.0);
  s.tolerance_mm = n == 1 ? 0.02 : 0.01;
  s.avoid = n == 3;
  return s;
}

// A random but valid chamfer set-up: edge, side, radii, and a width that fits everywhere.
ChamferSpec random_spec(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  ChamferSpec s;
  s.pipe_radius_mm = 5.0 + 195.0 * u(rng);
  s.drill_radius_mm = s.pipe_radius_mm * (0.2 + 0.75 * u(rng));
  s.ball_radius_mm = s.drill_radius_mm * (0.05 + 0.4 * u(rng));
  s.edge = u(rng) < 0.5 ? Edge::Inner : Edge::Outer;
  s.side = u(rng) < 0.5 ? Side::Upper : Side::Lower;
  s.width_mm = 1.0;  // replaced below once the model can tell what fits
  const ChamferModel probe(s);
  double fits = 1e300;
  for (int i = 0; i < 64; ++i) {
    fits = std::min(fits, probe.max_width(probe.frame(i * 2.0 * kPi / 64), 1.0));
  }
  s.width_mm = fits * (0.05 + 0.4 * u(rng));
  return s;
}

// ---------------------------------------------------------------- the paper's figures
// (docs/chamfer.md)

TEST(ChamferPaper, LocalCheckOfExperiment1IsSmallestAtHalfPi) {
  const ChamferModel m(paper_geometry());
  double best = 1e300, at = -1.0;
  for (int i = 0; i <= 7200; ++i) {
    const double th = i * 2.0 * kPi / 7200;
    const double v = m.pose_at(th, 1.0).inv_ke_mm;
    if (v < best) best = v, at = th;
  }
  EXPECT_NEAR(best, 10.675, 5e-4);  // docs/chamfer.md: 10.675 at θ = π/2
  EXPECT_NEAR(std::fmod(at, kPi), kHalfPi, 1e-9);
  EXPECT_GT(best, 3.0);  // > R_B: no local interference
}

TEST(ChamferPaper, GlobalCheckOfExperiment1PeaksAtZeroAndPi) {
  const ChamferModel m(paper_geometry());
  double best = -1e300;
  for (int i = 0; i <= 7200; ++i)
    best = std::max(best, m.pose_at(i * 2.0 * kPi / 7200, 1.0).minus_ez);
  EXPECT_NEAR(best, -0.3727, 5e-5);
  EXPECT_NEAR(m.pose_at(0.0, 1.0).minus_ez, best, 1e-12);
  EXPECT_NEAR(m.pose_at(kPi, 1.0).minus_ez, best, 1e-12);
}

TEST(ChamferPaper, CutterLocationRadiusRangeWithAlphaOne) {
  const ChamferModel m(paper_geometry());
  double lo = 1e300, hi = -1e300;
  for (int i = 0; i <= 7200; ++i) {
    const double v = m.pose_at(i * 2.0 * kPi / 7200, 1.0).cl_radius_mm;
    lo = std::min(lo, v), hi = std::max(hi, v);
  }
  EXPECT_NEAR(lo, 10.366, 5e-4);
  EXPECT_NEAR(hi, 11.141, 5e-4);
}

TEST(ChamferPaper, RodLimitRadiiOfTheExperiments) {
  EXPECT_NEAR(*ChamferModel(experiment(2)).rod_limit_radius_mm(), 10.824, 5e-4);  // cap binds
  EXPECT_NEAR(*ChamferModel(experiment(1)).rod_limit_radius_mm(), 11.2, 1e-12);   // rod binds
}

// θ in [40°, 60°] where the α = 1 CL radius crosses `radius`, by bisection (a slow reference).
double crossing_deg(const ChamferModel& m, double radius) {
  double lo = deg_to_rad(40.0), hi = deg_to_rad(60.0);
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    (m.pose_at(mid, 1.0).cl_radius_mm > radius ? hi : lo) = mid;
  }
  return rad_to_deg(lo);
}

TEST(ChamferPaper, Experiment2InterferesBetween50And130Degrees) {
  const ChamferModel m(experiment(2));
  const double rr = *m.rod_limit_radius_mm();
  // The 50.05° of docs/chamfer.md is for R_R as printed, 10.824 mm; the exact 13 − 3 sin 46.5° is
  // 10.82388 mm, which crosses 0.006° earlier.
  EXPECT_NEAR(crossing_deg(m, 10.824), 50.05, 5e-3);
  const double lo = deg_to_rad(crossing_deg(m, rr));
  EXPECT_NEAR(rad_to_deg(lo), 50.044, 1e-3);
  // Symmetry about π/2: the interval is (50.05°, 129.95°), and its mirror below the x axis.
  EXPECT_NEAR(m.pose_at(kPi - lo, 1.0).cl_radius_mm, rr, 1e-9);
  EXPECT_NEAR(m.pose_at(kPi + lo, 1.0).cl_radius_mm, rr, 1e-9);
  const ChamferPath path = generate_chamfer(experiment(2));
  EXPECT_FALSE(path.checks.rod_ok);
  EXPECT_EQ(path.checks.adjusted_points, 0);
  for (const auto& p : path.points) {
    const double deg = rad_to_deg(std::fmod(p.theta_rad, kPi));
    EXPECT_EQ(p.cl_radius_mm > rr, deg > 50.06 && deg < 129.94) << "θ = " << deg;
    EXPECT_EQ(p.alpha, 1.0);
  }
}

TEST(ChamferPaper, Experiment3HoldsTheLimitWithAlphaUpTo1446) {
  const ChamferPath path = generate_chamfer(experiment(3));
  const double rr = *path.checks.limit_radius_mm;
  double a_max = 0.0;
  for (const auto& p : path.points) {
    EXPECT_LE(p.cl_radius_mm, rr) << "θ = " << p.theta_rad;
    if (p.alpha > 1.0) {
      EXPECT_NEAR(p.cl_radius_mm, rr, 1e-9);
    }
    a_max = std::max(a_max, p.alpha);
  }
  EXPECT_NEAR(a_max, 1.446, 5e-4);
  EXPECT_TRUE(path.checks.rod_ok);
  EXPECT_TRUE(path.checks.local_ok);  // Fig. 14(f), (g): still clear with α ≠ 1
  EXPECT_TRUE(path.checks.global_ok);
  EXPECT_GT(path.checks.adjusted_points, 0);
}

TEST(ChamferPaper, Experiment1IsClearEverywhere) {
  const ChamferPath path = generate_chamfer(experiment(1));
  EXPECT_TRUE(path.checks.local_ok);
  EXPECT_TRUE(path.checks.global_ok);
  EXPECT_TRUE(path.checks.rod_ok);
  EXPECT_EQ(path.checks.adjusted_points, 0);
  EXPECT_NEAR(path.checks.max_cl_radius_mm, 11.141, 5e-4);
}

TEST(ChamferPaper, ProjectedWidthRangeAndTable2Value) {
  const ChamferModel m(paper_geometry());
  EXPECT_NEAR(m.pose_at(0.0, 1.0).projected_width_mm, 0.2609, 5e-5);
  // Exact at π/2: AB lies in the y–z plane at 45°, so its top view is W/√2.
  EXPECT_NEAR(m.pose_at(kHalfPi, 1.0).projected_width_mm, 0.7 / std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(m.pose_at(deg_to_rad(74.0), 1.0).projected_width_mm, 0.491, 5e-4);
}

TEST(ChamferPaper, AdmissibleAlphaAtThetaZero) {
  const ChamferModel m(paper_geometry());
  const EdgeFrame f = m.frame(0.0);
  EXPECT_NEAR(f.c, -13.0 / 18.0, 1e-15);
  const AlphaRange r = m.alpha_range(f);
  EXPECT_NEAR(r.lo, 13.0 / 18.0, 1e-15);  // docs/chamfer.md: 0.722 < α < 1.385
  EXPECT_NEAR(r.hi, 18.0 / 13.0, 1e-15);
  EXPECT_TRUE(m.solve_delta(f, 1.3).has_value());
  EXPECT_FALSE(m.solve_delta(f, 0.70).has_value());
  EXPECT_FALSE(m.solve_delta(f, 1.40).has_value());
}

TEST(ChamferPaper, Eq41IsTheGlobalBoundOnTheInnerUpperEdge) {
  const ChamferModel m(paper_geometry());
  for (const double th : {0.3, 0.7, 1.2, 2.0, 2.9, 4.0, 5.5}) {
    const double cos2 = std::cos(th) * std::cos(th);
    const EdgeFrame f = m.frame(th);
    EXPECT_NEAR(m.alpha_range(f).hi, std::min(18.0 / (13.0 * cos2), -1.0 / f.c), 1e-12);
  }
}

// ---------------------------------------------------------------- identities, random sweeps

TEST(ChamferIdentity, WidthIsExactlyWOverRandomGeometries) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 300; ++trial) {
    const ChamferSpec s = random_spec(rng);
    const ChamferModel m(s);
    for (int k = 0; k < 16; ++k) {
      const double th = 2.0 * kPi * u(rng);
      const EdgeFrame f = m.frame(th);
      const AlphaRange r = m.alpha_range(f);
      const double hi = std::min(r.hi, 3.0);
      const double alpha = r.lo + (hi - r.lo) * (0.02 + 0.96 * u(rng));
      const auto delta = m.solve_delta(f, alpha);
      if (!delta) {
        EXPECT_LE(m.max_width(f, alpha), s.width_mm) << "no δ although W fits, θ = " << th;
        continue;
      }
      const CutterPose p = m.pose(f, alpha, *delta);
      EXPECT_NEAR(p.width_mm, s.width_mm, 1e-9) << "trial " << trial << " θ " << th;
      EXPECT_GT(*delta, 0.0);
      EXPECT_LT(*delta, 2.0 * s.ball_radius_mm);
      // A and B lie on the ball, on their tangent lines, in the normal plane T.
      EXPECT_NEAR((p.a - p.cl).norm(), s.ball_radius_mm, 1e-9);
      EXPECT_NEAR((p.b - p.cl).norm(), s.ball_radius_mm, 1e-9);
      EXPECT_NEAR((p.a - p.xp).cross(f.t1).norm(), 0.0, 1e-9);
      EXPECT_NEAR((p.b - p.xp).cross(f.t2).norm(), 0.0, 1e-9);
      EXPECT_NEAR((p.cl - p.xp).dot(f.t), 0.0, 1e-9);
      EXPECT_NEAR((p.cl - p.xp).norm(), s.ball_radius_mm - *delta, 1e-9);
    }
  }
}

TEST(ChamferIdentity, AlphaOneCutsEqualArcsAndMatchesTheClosedForm) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 300; ++trial) {
    const ChamferSpec s = random_spec(rng);
    const ChamferModel m(s);
    for (int k = 0; k < 16; ++k) {
      const EdgeFrame f = m.frame(2.0 * kPi * u(rng));
      const CutterPose p = m.pose(f, 1.0, *m.solve_delta(f, 1.0));
      EXPECT_NEAR((p.a - p.xp).norm(), (p.b - p.xp).norm(), 1e-9);
      // Closed form for α = 1 (docs/chamfer.md): ζ = W / (2 sin(φ/2)), q² + 2ζ cos(φ/2) q + ζ² −
      // R_B² = 0.
      const double phi = std::acos(f.c);
      const double zeta = s.width_mm / (2.0 * std::sin(0.5 * phi));
      const double b = zeta * std::cos(0.5 * phi);
      const double q = -b + std::sqrt(b * b - zeta * zeta + s.ball_radius_mm * s.ball_radius_mm);
      EXPECT_NEAR(p.delta_mm, s.ball_radius_mm - q, 1e-9);
    }
  }
}

TEST(ChamferIdentity, FrameIsOrthonormalWhereItShouldBe) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    const ChamferModel m(random_spec(rng));
    const EdgeFrame f = m.frame(2.0 * kPi * u(rng));
    EXPECT_NEAR(f.t.norm(), 1.0, 1e-14);
    EXPECT_NEAR(f.t1.norm(), 1.0, 1e-14);
    EXPECT_NEAR(f.t2.norm(), 1.0, 1e-14);
    EXPECT_NEAR(f.t1.dot(f.t), 0.0, 1e-14);
    EXPECT_NEAR(f.t2.dot(f.t), 0.0, 1e-14);
    EXPECT_NEAR(f.k.dot(f.t), 0.0, 1e-12);  // curvature is normal to the tangent
    EXPECT_LT(f.c, 1.0);
  }
}

TEST(ChamferIdentity, CurvatureMatchesFiniteDifferencesOfTheTangent) {
  // κ n = dt/ds: compare with a central difference of t over arc length.
  const ChamferModel m(paper_geometry());
  for (const double th : {0.1, 0.9, 1.5707963267948966, 2.5, 4.2}) {
    const double h = 1e-5;
    const Vec3 dt = (m.frame(th + h).t - m.frame(th - h).t) / (2.0 * h * m.speed(th));
    EXPECT_NEAR((m.frame(th).k - dt).norm(), 0.0, 1e-8);
  }
}

TEST(ChamferIdentity, LowerEdgesMirrorUpperOnes) {
  for (const Edge edge : {Edge::Inner, Edge::Outer}) {
    ChamferSpec up = paper_geometry();
    up.edge = edge;
    ChamferSpec low = up;
    low.side = Side::Lower;
    const ChamferModel mu(up), ml(low);
    for (const double th : {0.0, 0.4, 1.3, 2.2, 3.7, 5.9}) {
      const CutterPose a = mu.pose_at(th, 1.0), b = ml.pose_at(th, 1.0);
      const Vec3 flip(1.0, 1.0, -1.0);
      EXPECT_NEAR((b.cl - a.cl.cwiseProduct(flip)).norm(), 0.0, 1e-12);
      EXPECT_NEAR((b.e - a.e.cwiseProduct(flip)).norm(), 0.0, 1e-12);
      EXPECT_NEAR(a.delta_mm, b.delta_mm, 1e-12);
      EXPECT_NEAR(a.minus_ez, -b.minus_ez, 1e-12);
    }
  }
}

TEST(ChamferIdentity, SharpWedgeNeedsTheSafeguard) {
  // docs/chamfer.md: an outer edge with r/R = 13/14 has δ ≈ 1.8 mm; Newton alone leaves the domain
  // there.
  ChamferSpec s = paper_geometry();
  s.pipe_radius_mm = 14.0;
  s.edge = Edge::Outer;
  const ChamferModel m(s);
  const CutterPose p = m.pose_at(0.0, 1.0);
  EXPECT_NEAR(p.delta_mm, 1.8, 0.05);
  EXPECT_NEAR(p.width_mm, 0.7, 1e-9);
  const ChamferPath path = generate_chamfer(s);
  for (const auto& q : path.points) EXPECT_NEAR(q.width_mm, 0.7, 1e-9);
  EXPECT_TRUE(path.checks.global_ok);  // −e_z ≥ 0 on an outer upper edge
  EXPECT_GE(path.checks.min_minus_ez, 0.0);
}

// ---------------------------------------------------------------- segmentation

// Largest distance from C to the chord over a piece: a dense scan, then golden-section search
// around the best sample. The slow reference for ChamferModel::chord_deviation.
double brute_deviation(const ChamferModel& m, double a, double b) {
  const Vec3 p0 = m.point(a), chord = m.point(b) - p0;
  const auto dist = [&](double th) {
    return (m.point(th) - p0).cross(chord).norm() / chord.norm();
  };
  const int n = 400;
  int best = 0;
  for (int i = 1; i <= n; ++i) {
    if (dist(a + (b - a) * i / n) > dist(a + (b - a) * best / n)) best = i;
  }
  double lo = a + (b - a) * std::max(0, best - 1) / n, hi = a + (b - a) * std::min(n, best + 1) / n;
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  for (int i = 0; i < 100; ++i) {
    const double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
    (dist(x1) < dist(x2) ? lo : hi) = dist(x1) < dist(x2) ? x1 : x2;
  }
  return std::max(dist(a + (b - a) * best / n), dist(0.5 * (lo + hi)));
}

TEST(ChamferSegmentation, EveryPieceIsWithinTolerance) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < ncd::test::sweep_cases(20); ++trial) {
    ChamferSpec s = random_spec(rng);
    s.tolerance_mm = std::pow(10.0, -3.0 + 2.0 * u(rng));
    const ChamferModel m(s);
    const std::vector<double> th = m.segment();
    for (std::size_t i = 0; i < th.size(); ++i) {
      const double b = i + 1 < th.size() ? th[i + 1] : 2.0 * kPi;
      EXPECT_LE(brute_deviation(m, th[i], b), s.tolerance_mm * (1.0 + 1e-9))
          << "trial " << trial << " piece " << i;
      EXPECT_NEAR(m.chord_deviation(th[i], b), brute_deviation(m, th[i], b), 1e-6 * s.tolerance_mm);
    }
  }
}

TEST(ChamferSegmentation, CountsAreMultiplesOfFourOnSymmetricSetups) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 40; ++trial) {
    ChamferSpec s = random_spec(rng);
    s.tolerance_mm = std::pow(10.0, -3.0 + 2.0 * u(rng));
    const std::size_t n = ChamferModel(s).segment().size();
    EXPECT_EQ(n % 4, 0u) << "trial " << trial << ": " << n << " pieces";
  }
  for (const double eps : {0.02, 0.01, 0.005, 0.001}) {
    ChamferSpec s = paper_geometry();
    s.tolerance_mm = eps;
    EXPECT_EQ(ChamferModel(s).segment().size() % 4, 0u) << "ε = " << eps;
  }
}

TEST(ChamferSegmentation, CountIsMonotoneInTolerance) {
  std::size_t previous = 0;
  for (const double eps : {0.5, 0.1, 0.05, 0.02, 0.01, 0.005, 0.002, 0.001, 0.0005}) {
    ChamferSpec s = paper_geometry();
    s.tolerance_mm = eps;
    const std::size_t n = ChamferModel(s).segment().size();
    EXPECT_GE(n, previous) << "ε = " << eps;
    previous = n;
  }
}

TEST(ChamferSegmentation, InitialPiecesHaveEqualArcLength) {
  // With ε = 1 mm nothing is split: the N = 60 pieces must have equal arcs, checked against a
  // composite Simpson rule with many panels (independent of the Gauss–Legendre code).
  ChamferSpec s = paper_geometry();
  s.tolerance_mm = 1.0;
  const ChamferModel m(s);
  const std::vector<double> th = m.segment();
  ASSERT_EQ(th.size(), 60u);
  const auto simpson = [&](double a, double b) {
    const int n = 2000;
    const double h = (b - a) / n;
    double sum = m.speed(a) + m.speed(b);
    for (int i = 1; i < n; ++i) sum += (i % 2 ? 4.0 : 2.0) * m.speed(a + i * h);
    return sum * h / 3.0;
  };
  const double total = simpson(0.0, 2.0 * kPi);
  for (std::size_t i = 0; i < th.size(); ++i) {
    const double b = i + 1 < th.size() ? th[i + 1] : 2.0 * kPi;
    EXPECT_NEAR(simpson(th[i], b), total / 60.0, 1e-11 * total) << "piece " << i;
  }
  EXPECT_NEAR(th[15], kHalfPi, 1e-12);  // quarter points by symmetry
  EXPECT_NEAR(th[30], kPi, 1e-12);
}

// ---------------------------------------------------------------- Algorithm 1

TEST(ChamferAlgorithm1, ClearsTheRodWithTheSmallestAlphaOverRandomGeometries) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int adjusted_total = 0;
  for (int trial = 0; trial < 60; ++trial) {
    ChamferSpec s = random_spec(rng);
    s.edge = Edge::Inner;
    const ChamferModel probe(s);
    // A limit between the smallest and largest α = 1 CL radius, so that some points interfere.
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
      // Allowed only when the message says the limit cannot be met; check that it is true.
      EXPECT_NE(std::string(e.what()).find("cannot be met"), std::string::npos) << e.what();
      continue;
    }
    const ChamferModel m(s);
    const double rr = *m.rod_limit_radius_mm();
    for (const auto& p : path.points) {
      EXPECT_LE(p.cl_radius_mm, rr) << "trial " << trial;
      EXPECT_NEAR(p.width_mm, s.width_mm, 1e-9);
      if (p.alpha > 1.0) {
        ++adjusted_total;
        // Minimal: a slightly smaller α interferes again.
        const EdgeFrame f = m.frame(p.theta_rad);
        const double a = p.alpha * (1.0 - 1e-8);
        EXPECT_GT(m.pose(f, a, *m.solve_delta(f, a)).cl_radius_mm, rr);
      }
    }
  }
  EXPECT_GT(adjusted_total, 0);
}

TEST(ChamferAlgorithm1, DegenerateAnglesNeedNoSpecialCase) {
  // c = t1·t2 = 0 exactly at θ = π/2 and 3π/2, where the paper switches to line–line
  // intersections and where the rod binds hardest.
  const ChamferModel m(experiment(3));
  for (const double th : {kHalfPi, 3.0 * kHalfPi}) {
    const EdgeFrame f = m.frame(th);
    EXPECT_NEAR(f.c, 0.0, 1e-15);
    const RodAvoidance r = m.avoid_rod(f);
    EXPECT_TRUE(r.cleared);
    EXPECT_NEAR(r.alpha, 1.446, 5e-4);
    EXPECT_NEAR(m.pose(f, r.alpha, *m.solve_delta(f, r.alpha)).cl_radius_mm,
                *m.rod_limit_radius_mm(), 1e-9);
  }
  for (const double th : {0.0, kPi}) {  // no interference there: α stays 1
    const RodAvoidance r = m.avoid_rod(m.frame(th));
    EXPECT_EQ(r.alpha, 1.0);
    EXPECT_FALSE(r.adjusted);
  }
}

TEST(ChamferAlgorithm1, OuterEdgesHaveNoRodCheck) {
  ChamferSpec s = experiment(3);
  s.edge = Edge::Outer;
  s.pipe_radius_mm = 20.0;
  const ChamferPath path = generate_chamfer(s);
  EXPECT_FALSE(path.checks.rod_applies);
  EXPECT_FALSE(path.checks.limit_radius_mm.has_value());
  EXPECT_EQ(path.checks.adjusted_points, 0);
}

TEST(ChamferAlgorithm1, UnreachableLimitIsAnErrorNamingTheLimit) {
  ChamferSpec s = experiment(3);
  s.rod_radius_mm = 4.0;  // R_R = 9 mm: below any admissible CL radius
  try {
    (void)generate_chamfer(s);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("R_R = 9 mm"), std::string::npos) << e.what();
  }
  s.avoid = false;  // reported instead
  const ChamferPath path = generate_chamfer(s);
  EXPECT_FALSE(path.checks.rod_ok);
}

TEST(ChamferChecks, LocalInterferenceIsReported) {
  ChamferSpec s;
  s.pipe_radius_mm = 10.0;
  s.drill_radius_mm = 2.0;
  s.ball_radius_mm = 5.0;
  s.width_mm = 0.5;
  s.edge = Edge::Outer;
  const ChamferPath path = generate_chamfer(s);
  EXPECT_FALSE(path.checks.local_ok);
  EXPECT_LT(path.checks.min_inv_ke_mm, 5.0);
}

// ---------------------------------------------------------------- bad input

void expect_input_error(const ChamferSpec& s, const std::string& fragment) {
  try {
    (void)generate_chamfer(s);
    FAIL() << "expected InputError containing \"" << fragment << "\"";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
}

TEST(ChamferInput, InvalidGeometriesAreClearErrors) {
  ChamferSpec s = paper_geometry();
  s.drill_radius_mm = 18.0;
  expect_input_error(s, "drill radius r = 18 mm must be smaller than the pipe radius 18 mm");
  s = paper_geometry();
  s.width_mm = 0.0;
  expect_input_error(s, "--width");
  s.width_mm = -1.0;
  expect_input_error(s, "--width");
  s = paper_geometry();
  s.ball_radius_mm = 0.0;
  expect_input_error(s, "--ball-radius");
  s.ball_radius_mm = std::nan("");
  expect_input_error(s, "nan");
  s = paper_geometry();
  s.width_mm = 5.0;
  expect_input_error(s, "widest the wedge");
  s = paper_geometry();
  s.tolerance_mm = 1e-7;
  expect_input_error(s, "tolerance");
  s = paper_geometry();
  s.non_knife_angle_rad = deg_to_rad(200.0);
  expect_input_error(s, "non-knife angle");
}

}  // namespace
}  // namespace ncd::toolpath
