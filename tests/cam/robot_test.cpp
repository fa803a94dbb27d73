// Robot chamfering (paper 002) against identities and independent references: the edge on
// both implicit surfaces, the 45° of the paper against normals computed here from the surface
// gradients, the closed-form attitude figures of the flat-plate limit, W, P, R against Eigen's
// angle-axis products, the min-change turn against a brute-force scan, and the touch-point fit
// against a three-point frame construction and least-squares optimality.
#include "cam/robot.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "core/error.hpp"
#include "tests/common/seed.hpp"

namespace ncd::toolpath {
namespace {

constexpr double kQuarterPi = 0.25 * kPi;

RobotSpec paper_experiment() {
  RobotSpec s;  // R = 30, r = 15 (the paper's 60 mm cylinder and 30 mm hole), N = 72
  s.cylinder_radius_mm = 30.0;
  s.hole_radius_mm = 15.0;
  return s;
}

// A random valid spec: radii from 1 to 500 mm, r/R up to 0.95, any start, 8 to 400 points.
RobotSpec random_robot_spec(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  RobotSpec s;
  s.cylinder_radius_mm = 1.0 + 499.0 * u(rng);
  s.hole_radius_mm = s.cylinder_radius_mm * (0.05 + 0.9 * u(rng));
  s.points = 8 + static_cast<int>(392.0 * u(rng));
  s.start_angle_rad = 2.0 * kPi * u(rng);
  s.passes = 1 + static_cast<int>(3.0 * u(rng));
  const double wall =
      std::sqrt(s.cylinder_radius_mm * s.cylinder_radius_mm - s.hole_radius_mm * s.hole_radius_mm);
  s.depth_mm = 0.05 * std::min(s.hole_radius_mm, wall) / (std::sqrt(2.0) * s.passes) * u(rng) +
               1e-6 * s.hole_radius_mm;
  const int rule = static_cast<int>(3.0 * u(rng));
  s.rule = rule == 0 ? TgRule::Paper : rule == 1 ? TgRule::MinChange : TgRule::Naive;
  return s;
}

// Unit normals from the gradients of the implicit surfaces, written here, not taken from the
// library: the hole wall x² + y² = r² and the cylinder x² + z² = R², both out of the material.
Vec3 hole_wall_normal_out(const Vec3& x) {
  return -Vec3(x.x(), x.y(), 0.0).normalized();
}
Vec3 cylinder_normal_out(const Vec3& x) {
  return Vec3(x.x(), 0.0, x.z()).normalized();
}

double angle_between(const Vec3& a, const Vec3& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}
double angle_to_plane(const Vec3& v, const Vec3& n) {
  return 0.5 * kPi - angle_between(v, n.dot(v) >= 0.0 ? n : Vec3(-n));
}

Mat3 random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return Eigen::Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized().toRotationMatrix();
}

// The rotation W, P, R independently: Eigen's angle-axis products about the fixed axes.
Mat3 reference_wpr(double w, double p, double r) {
  return (Eigen::AngleAxisd(r, Vec3::UnitZ()) * Eigen::AngleAxisd(p, Vec3::UnitY()) *
          Eigen::AngleAxisd(w, Vec3::UnitX()))
      .toRotationMatrix();
}

double max_abs(const Mat3& m) {
  return m.cwiseAbs().maxCoeff();
}

// ------------------------------------------------------------------- edge and surface data

TEST(RobotEdge, PointsLieOnBothTheCylinderAndTheHoleWall) {
  std::mt19937_64 rng(ncd::test::seed());
  for (int trial = 0; trial < 200; ++trial) {
    const RobotSpec s = random_robot_spec(rng);
    const RobotPath path = generate_robot_path(s);
    for (const auto& p : path.poses) {
      const Vec3& e = p.edge_mm;
      const double r = s.hole_radius_mm, big_r = s.cylinder_radius_mm;
      ASSERT_NEAR(e.x() * e.x() + e.y() * e.y(), r * r, 1e-14 * big_r * big_r) << trial;
      ASSERT_NEAR(e.x() * e.x() + e.z() * e.z(), big_r * big_r, 1e-14 * big_r * big_r) << trial;
      ASSERT_GT(e.z(), 0.0);
    }
    EXPECT_LE(path.checks.surface_residual_mm, 1e-13 * s.cylinder_radius_mm);
  }
}

TEST(RobotEdge, PointsAreTheEqualDivisionOfTheHoleCircleTravelledClockwise) {
  const RobotSpec s = paper_experiment();
  const RobotEdge edge(s);
  const RobotPath path = generate_robot_path(s);
  ASSERT_EQ(path.poses.size(), static_cast<std::size_t>(s.points + 1));
  for (int n = 0; n < s.points; ++n) {
    const Vec3& a = path.poses[static_cast<std::size_t>(n)].edge_mm;
    const Vec3& b = path.poses[static_cast<std::size_t>(n) + 1].edge_mm;
    // Seen from +z the projection turns by −2π/N per point (clockwise).
    const double turn = std::atan2(a.x() * b.y() - a.y() * b.x(), a.x() * b.x() + a.y() * b.y());
    EXPECT_NEAR(turn, -2.0 * kPi / s.points, 1e-13);
  }
  EXPECT_LT((path.poses.back().edge_mm - path.poses.front().edge_mm).norm(), 1e-13);
}

TEST(RobotEdge, DAndTfAre45DegreesToTheHoleWallAndTheFlankPlane) {
  std::mt19937_64 rng(ncd::test::seed());
  for (int trial = 0; trial < 200; ++trial) {
    const RobotSpec s = random_robot_spec(rng);
    const RobotPath path = generate_robot_path(s);
    for (const auto& p : path.poses) {
      const Vec3 wall = hole_wall_normal_out(p.edge_mm);
      const Vec3 cyl = cylinder_normal_out(p.edge_mm);
      // The edge tangent is normal to both gradients; plane A is ⟂ the wall through it.
      const Vec3 tangent = wall.cross(cyl).normalized();
      const Vec3 flank = wall.cross(tangent);
      ASSERT_NEAR(std::abs(p.f.dot(tangent)), 1.0, 1e-13);
      ASSERT_NEAR(angle_to_plane(p.d, wall), kQuarterPi, 1e-13) << trial;
      ASSERT_NEAR(angle_to_plane(p.tf, wall), kQuarterPi, 1e-13) << trial;
      ASSERT_NEAR(angle_to_plane(p.d, flank), kQuarterPi, 1e-13) << trial;
      ASSERT_NEAR(angle_to_plane(p.tf, flank), kQuarterPi, 1e-13) << trial;
      // D and T_f are normal to the edge and to each other.
      ASSERT_NEAR(p.d.dot(tangent), 0.0, 1e-14);
      ASSERT_NEAR(p.tf.dot(tangent), 0.0, 1e-14);
      ASSERT_NEAR(p.d.dot(p.tf), 0.0, 1e-14);
      // T_f pushes into the material through the wall (and through the cylinder where the
      // wedge is wider than 45°, see below); D points into the hole and down.
      ASSERT_LT(p.tf.dot(wall), 0.0);
      ASSERT_GT(p.d.dot(wall), 0.0);
      ASSERT_LT(p.d.z(), 0.0);
    }
  }
}

// The cylinder meets the wall at 90° − δ, δ = asin((r/R) cos² θ): T_f is at 45° − δ and D at
// 45° + δ to it, both 45° where the edge is a right angle (θ = ±90°, or a flat plate).
TEST(RobotEdge, AnglesToTheCylinderSurfaceDepartFrom45ByTheEdgeAngle) {
  std::mt19937_64 rng(ncd::test::seed());
  for (int trial = 0; trial < 200; ++trial) {
    const RobotSpec s = random_robot_spec(rng);
    const RobotPath path = generate_robot_path(s);
    double lo = kPi, hi = -kPi;
    for (const auto& p : path.poses) {
      const Vec3 cyl = cylinder_normal_out(p.edge_mm);
      const double c = std::cos(p.theta_rad);
      const double delta = std::asin(s.hole_radius_mm / s.cylinder_radius_mm * c * c);
      // Signed: T_f leans into the material while δ < 45°, out of it beyond (r/R > 0.707).
      const double signed_tf =
          p.tf.dot(cyl) <= 0.0 ? angle_to_plane(p.tf, cyl) : -angle_to_plane(p.tf, cyl);
      ASSERT_NEAR(signed_tf, kQuarterPi - delta, 1e-12) << trial;
      // D · n_c = −cos(45° − δ): D at 45° + δ to the surface (folded past 90° beyond δ = 45°).
      ASSERT_NEAR(p.d.dot(cyl), -std::cos(kQuarterPi - delta), 1e-14) << trial;
      lo = std::min(lo, kQuarterPi - delta);
      hi = std::max(hi, kQuarterPi - delta);
    }
    EXPECT_NEAR(path.checks.tf_cylinder_angle_min_rad, lo, 1e-12);
    EXPECT_NEAR(path.checks.tf_cylinder_angle_max_rad, hi, 1e-12);
  }
  RobotSpec s = paper_experiment();
  s.start_angle_rad = 0.5 * kPi;
  const SurfacePoint top = RobotEdge(s).surface(s.start_angle_rad);
  const Vec3 cyl = cylinder_normal_out(top.p_mm);
  EXPECT_NEAR(angle_to_plane(top.n, cyl), kQuarterPi, 1e-14);
  EXPECT_NEAR(angle_to_plane(top.d, cyl), kQuarterPi, 1e-14);
  s.cylinder_radius_mm = 1e9;  // a flat plate: 45° to both faces everywhere
  const RobotPath flat = generate_robot_path(s);
  EXPECT_NEAR(flat.checks.tf_cylinder_angle_min_rad, kQuarterPi, 1e-7);
  EXPECT_NEAR(flat.checks.tf_cylinder_angle_max_rad, kQuarterPi, 1e-12);
}

TEST(RobotEdge, TcpIsTheDepthOfEachPassPlusTheBarRadiusAlongTf) {
  RobotSpec s = paper_experiment();
  s.passes = 3;
  s.depth_mm = 0.1;
  s.bar_radius_mm = 2.5;
  const RobotPath path = generate_robot_path(s);
  ASSERT_EQ(path.poses.size(), static_cast<std::size_t>(3 * s.points + 1));
  for (std::size_t i = 0; i < path.poses.size(); ++i) {
    const auto& p = path.poses[i];
    const int pass = i == path.poses.size() - 1 ? 3 : 1 + static_cast<int>(i) / s.points;
    EXPECT_EQ(p.pass, pass);
    EXPECT_NEAR((p.p_mm - p.edge_mm).norm(), 0.1 * pass + 2.5, 1e-13);
    EXPECT_NEAR((p.p_mm - p.edge_mm).normalized().dot(p.tf), 1.0, 1e-15);
  }
}

// ------------------------------------------------------------------------------- frames

TEST(RobotFrames, OrthonormalRightHandedWithTgNormalToDForEveryRule) {
  std::mt19937_64 rng(ncd::test::seed());
  for (int trial = 0; trial < 100; ++trial) {
    RobotSpec s = random_robot_spec(rng);
    for (TgRule rule : {TgRule::Paper, TgRule::MinChange, TgRule::Naive}) {
      s.rule = rule;
      const RobotPath path = generate_robot_path(s);
      for (const auto& p : path.poses) {
        const Mat3 m = p.rotation();
        ASSERT_LT(max_abs(m.transpose() * m - Mat3::Identity()), 4e-15) << to_string(rule);
        ASSERT_NEAR(m.determinant(), 1.0, 4e-15);
        ASSERT_NEAR(p.tg.dot(p.d), 0.0, 1e-15);
        ASSERT_NEAR(p.tg.norm(), 1.0, 1e-15);
        ASSERT_LT((m.col(0).cross(m.col(1)) - p.d).norm(), 4e-15);  // x × y = z = D
      }
      EXPECT_LT(path.checks.frame_error, 1e-14);
    }
  }
}

// ----------------------------------------------------------------------------- W, P, R

TEST(RobotWpr, MatrixIsTheFixedAxisProductXThenYThenZ) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> a(-kPi, kPi), b(-0.5 * kPi, 0.5 * kPi);
  for (int i = 0; i < 10000; ++i) {
    const double w = a(rng), p = b(rng), r = a(rng);
    ASSERT_LT(max_abs(wpr_to_matrix({w, p, r}) - reference_wpr(w, p, r)), 4e-15);
  }
  // W = 90° alone turns y onto z; P = 90° turns z onto x; R = 90° turns x onto y.
  EXPECT_LT((wpr_to_matrix({0.5 * kPi, 0, 0}) * Vec3::UnitY() - Vec3::UnitZ()).norm(), 1e-15);
  EXPECT_LT((wpr_to_matrix({0, 0.5 * kPi, 0}) * Vec3::UnitZ() - Vec3::UnitX()).norm(), 1e-15);
  EXPECT_LT((wpr_to_matrix({0, 0, 0.5 * kPi}) * Vec3::UnitX() - Vec3::UnitY()).norm(), 1e-15);
}

TEST(RobotWpr, RoundTripsRandomRotationsTo1e12) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> a(-kPi, kPi), b(-0.5 * kPi, 0.5 * kPi);
  for (int i = 0; i < 100000; ++i) {
    const Mat3 m = random_rotation(rng);
    const Wpr wpr = matrix_to_wpr(m);
    ASSERT_LT(max_abs(wpr_to_matrix(wpr) - m), 1e-12) << i;
    ASSERT_GT(wpr.w_rad, -kPi);
    ASSERT_LE(wpr.w_rad, kPi);
    ASSERT_GE(wpr.p_rad, -0.5 * kPi);
    ASSERT_LE(wpr.p_rad, 0.5 * kPi);
    ASSERT_GT(wpr.r_rad, -kPi);
    ASSERT_LE(wpr.r_rad, kPi);
    // Angles away from the lock come back as themselves.
    const double w = a(rng), p = 0.999 * b(rng), r = a(rng);
    const Wpr back = matrix_to_wpr(reference_wpr(w, p, r));
    ASSERT_NEAR(back.w_rad, w, 1e-12);
    ASSERT_NEAR(back.p_rad, p, 1e-12);
    ASSERT_NEAR(back.r_rad, r, 1e-12);
  }
}

TEST(RobotWpr, GimbalLockAtPPlusMinus90KeepsTheRotationAndSetsRToZero) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> a(-kPi, kPi);
  for (int i = 0; i < 10000; ++i) {
    const double w = a(rng), r = a(rng);
    for (double sign : {1.0, -1.0}) {
      const Mat3 m = reference_wpr(w, sign * 0.5 * kPi, r);
      const Wpr wpr = matrix_to_wpr(m);
      ASSERT_LT(max_abs(wpr_to_matrix(wpr) - m), 1e-12);
      ASSERT_NEAR(wpr.p_rad, sign * 0.5 * kPi, 1e-7);  // acos-level: |(M00, M10)| ~ 1e-16
      // Only w ∓ r is defined there: the whole turn goes to W.
      if (std::hypot(m(0, 0), m(1, 0)) < 1e-13) {
        ASSERT_EQ(wpr.r_rad, 0.0);
      }
      // Next to the lock: cos P from 1e-16 to 1e-6.
      for (double eps : {1e-16, 1e-14, 1e-13, 1e-12, 1e-10, 1e-8, 1e-6}) {
        const Mat3 near = reference_wpr(w, sign * (0.5 * kPi - eps), r);
        ASSERT_LT(max_abs(wpr_to_matrix(matrix_to_wpr(near)) - near), 1e-12) << eps;
      }
    }
  }
  const Wpr exact = matrix_to_wpr(wpr_to_matrix({0.3, 0.5 * kPi, 0.0}));
  EXPECT_NEAR(exact.w_rad, 0.3, 1e-12);
  EXPECT_EQ(exact.r_rad, 0.0);
}

// -------------------------------------------------------------------- attitude and rules

TEST(RobotAttitude, ChangeIsTheRotationAngleOfRprevTransposeRnext) {
  std::mt19937_64 rng(ncd::test::seed());
  for (int i = 0; i < 10000; ++i) {
    const Mat3 a = random_rotation(rng), b = random_rotation(rng);
    const double ref = Eigen::AngleAxisd(a.transpose() * b).angle();
    ASSERT_NEAR(attitude_change_rad(a, b), ref, 1e-9);
    ASSERT_NEAR(attitude_change_rad(a, b), attitude_change_rad(b, a), 1e-14);
  }
  const Mat3 a = random_rotation(rng);
  EXPECT_NEAR(attitude_change_rad(a, a), 0.0, 1e-15);
  const Mat3 tiny = Eigen::AngleAxisd(1e-9, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  EXPECT_NEAR(attitude_change_rad(a, a * tiny), 1e-9, 1e-15);
}

TEST(RobotAttitude, MinChangeTurnBeatsABruteForceScan) {
  std::mt19937_64 rng(ncd::test::seed());
  for (int i = 0; i < 300; ++i) {
    const Mat3 prev = random_rotation(rng);
    const Mat3 cur = random_rotation(rng);
    const Vec3 d = cur.col(2), tf = cur.col(0);
    const auto frame = [&](double psi) {
      ToolPose p;
      p.d = d;
      p.tg = rotate_about(d, psi, tf);
      return p.rotation();
    };
    const double best = attitude_change_rad(prev, frame(min_change_turn_rad(prev, d, tf)));
    double scan = kPi;
    for (int k = 0; k < 20000; ++k) {
      scan = std::min(scan, attitude_change_rad(prev, frame(2.0 * kPi * k / 20000)));
    }
    ASSERT_LE(best, scan + 1e-12);
    ASSERT_GT(best, scan - 2.0 * kPi / 20000);  // and the scan comes within its grid
  }
}

TEST(RobotAttitude, PaperRuleTurnsTgByMinusMStepAboutD) {
  RobotSpec s = paper_experiment();
  s.passes = 2;
  const RobotPath path = generate_robot_path(s);
  const double step = 2.0 * kPi / s.points;
  for (std::size_t m = 0; m < path.poses.size(); ++m) {
    const auto& p = path.poses[m];
    const Vec3 ref =
        Eigen::AngleAxisd(-static_cast<double>(m) * step, p.d).toRotationMatrix() * p.tf;
    ASSERT_LT((p.tg - ref).norm(), 1e-12) << m;
  }
  // Each loop turns T_g by −2π about D: the closing pose has the first attitude again.
  EXPECT_LT(attitude_change_rad(path.poses.front().rotation(), path.poses.back().rotation()),
            1e-12);
  EXPECT_LT(attitude_change_rad(path.poses.front().rotation(),
                                path.poses[static_cast<std::size_t>(s.points)].rotation()),
            1e-12);
}

// Step by step, min-change is never worse than naive or paper (the proof is in robot.cpp).
TEST(RobotAttitude, MinChangeNeverWorseThanNaiveOrPaperStepByStep) {
  std::mt19937_64 rng(ncd::test::seed());
  for (int trial = 0; trial < 200; ++trial) {
    const RobotSpec s = random_robot_spec(rng);
    const RobotPath base = generate_robot_path(s);
    std::vector<ToolPose> naive = base.poses, paper = base.poses, mc = base.poses;
    const double step = 2.0 * kPi / s.points;
    apply_rule(TgRule::Naive, step, naive);
    apply_rule(TgRule::Paper, step, paper);
    apply_rule(TgRule::MinChange, step, mc);
    for (std::size_t i = 1; i < mc.size(); ++i) {
      const double a_mc = attitude_change_rad(mc[i - 1].rotation(), mc[i].rotation());
      ASSERT_LE(a_mc, attitude_change_rad(naive[i - 1].rotation(), naive[i].rotation()) + 1e-12);
      ASSERT_LE(a_mc, attitude_change_rad(paper[i - 1].rotation(), paper[i].rotation()) + 1e-12);
    }
    EXPECT_LE(base.min_change.total_rad, base.naive.total_rad + 1e-10);
    EXPECT_LE(base.min_change.total_rad, base.paper.total_rad + 1e-10);
    EXPECT_LE(base.min_change.max_rad, base.naive.max_rad + 1e-12);
    EXPECT_LE(base.min_change.max_rad, base.paper.max_rad + 1e-12);
  }
}

// Flat plate (R → ∞): the frames turn rigidly by Δθ about the hole axis ω, ω · D = 1/√2, so
// per step naive Δθ, paper 2 acos(c² + s²/√2) and min-change 2 acos(sqrt(1 − s²/2)),
// c = cos(Δθ/2), s = sin(Δθ/2).
TEST(RobotAttitude, FlatPlateLimitMatchesTheClosedForms) {
  for (int n : {8, 72, 360}) {
    RobotSpec s = paper_experiment();
    s.cylinder_radius_mm = 1.5e9;
    s.points = n;
    const RobotPath path = generate_robot_path(s);
    const double half = kPi / n, c = std::cos(half), sn = std::sin(half);
    const double naive = 2.0 * kPi;
    const double paper = n * 2.0 * std::acos(c * c + sn * sn * std::sqrt(0.5));
    const double mc = n * 2.0 * std::acos(std::sqrt(1.0 - 0.5 * sn * sn));
    EXPECT_NEAR(path.naive.total_rad, naive, 1e-6) << n;
    EXPECT_NEAR(path.paper.total_rad, paper, 1e-6) << n;
    EXPECT_NEAR(path.min_change.total_rad, mc, 1e-6) << n;
    EXPECT_NEAR(path.naive.max_rad, 2.0 * half, 1e-7);
    EXPECT_NEAR(path.naive.excursion_max_rad, kPi, 1e-6);
    // Paper: R_1ᵀ R_m = Rot(ω, φ) Rot(D, −φ), largest at φ = π: 2 acos(1/√2) = 90°.
    EXPECT_NEAR(path.paper.excursion_max_rad, 0.5 * kPi, 1e-6);
  }
}

// The paper's experiment (R = 30, r = 15 mm, N = 72): the figures quoted in the README. The
// ordering is the claim; the values pin the implementation (measured, 1e-3°).
TEST(RobotAttitude, PaperExperimentFigures) {
  const RobotPath path = generate_robot_path(paper_experiment());
  const auto deg = [](double rad) { return rad_to_deg(rad); };
  EXPECT_LT(path.paper.total_rad, path.naive.total_rad);
  EXPECT_LE(path.min_change.total_rad, path.paper.total_rad);
  EXPECT_LT(path.paper.excursion_max_rad, path.naive.excursion_max_rad);
  // The paper's rule lowers the total but not the largest step: near θ = 0 the edge is steep
  // and its fixed −Δθ overshoots.
  EXPECT_GT(path.paper.max_rad, path.naive.max_rad);
  EXPECT_NEAR(deg(path.naive.total_rad), 383.773, 1e-3);
  EXPECT_NEAR(deg(path.naive.max_rad), 5.763, 1e-3);
  EXPECT_NEAR(deg(path.paper.total_rad), 288.926, 1e-3);
  EXPECT_NEAR(deg(path.paper.max_rad), 6.197, 1e-3);
  EXPECT_NEAR(deg(path.min_change.total_rad), 259.464, 1e-3);
  EXPECT_NEAR(deg(path.min_change.max_rad), 5.294, 1e-3);
}

// -------------------------------------------------------------------------- touch points

// Independent three-point reference: the frame (origin a, x to b, z normal to the plane).
RigidTransform frame_of(const Vec3& a, const Vec3& b, const Vec3& c) {
  RigidTransform f;
  const Vec3 x = (b - a).normalized(), z = (b - a).cross(c - a).normalized();
  f.rotation.col(0) = x;
  f.rotation.col(1) = z.cross(x);
  f.rotation.col(2) = z;
  f.translation_mm = a;
  return f;
}

std::vector<TouchPoint> random_touches(std::mt19937_64& rng, const RigidTransform& t, int n,
                                       double noise_mm) {
  std::uniform_real_distribution<double> u(-100.0, 100.0);
  std::normal_distribution<double> g(0.0, noise_mm > 0.0 ? noise_mm : 1.0);
  // Valid sets only: the first three well off one line (twice their triangle's area at
  // least 2000 mm²) and no two points within 5 mm.
  const auto valid = [](const std::vector<Vec3>& w) {
    for (std::size_t i = 0; i < w.size(); ++i) {
      for (std::size_t j = i + 1; j < w.size(); ++j) {
        if ((w[i] - w[j]).norm() < 5.0) return false;
      }
    }
    return (w[1] - w[0]).cross(w[2] - w[0]).norm() >= 2000.0;
  };
  std::vector<Vec3> w;
  do {
    w.clear();
    for (int i = 0; i < n; ++i) w.emplace_back(u(rng), u(rng), u(rng));
  } while (!valid(w));
  std::vector<TouchPoint> touches;
  for (const Vec3& x : w) {
    Vec3 m = t.point(x);
    if (noise_mm > 0.0) m += Vec3(g(rng), g(rng), g(rng));
    touches.push_back({x, m});
  }
  return touches;
}

RigidTransform random_transform(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1500.0, 1500.0);
  return {random_rotation(rng), Vec3(u(rng), u(rng), u(rng))};
}

TEST(RobotTouch, ThreePointsGiveTheExactTransform) {
  std::mt19937_64 rng(ncd::test::seed());
  for (int i = 0; i < 1000; ++i) {
    const RigidTransform truth = random_transform(rng);
    const auto touches = random_touches(rng, truth, 3, 0.0);
    const TouchFit fit = fit_touch_points(touches);
    ASSERT_LT(max_abs(fit.transform.rotation - truth.rotation), 1e-12) << i;
    ASSERT_LT((fit.transform.translation_mm - truth.translation_mm).norm(), 1e-9) << i;
    ASSERT_LT(fit.max_mm, 1e-9);
    // Against the frame construction: T = F_robot F_workᵀ.
    const RigidTransform fw =
        frame_of(touches[0].workpiece_mm, touches[1].workpiece_mm, touches[2].workpiece_mm);
    const RigidTransform fr =
        frame_of(touches[0].robot_mm, touches[1].robot_mm, touches[2].robot_mm);
    ASSERT_LT(max_abs(fit.transform.rotation - fr.rotation * fw.rotation.transpose()), 1e-12);
  }
}

TEST(RobotTouch, MoreThanThreePointsRecoverAKnownTransform) {
  std::mt19937_64 rng(ncd::test::seed());
  for (int i = 0; i < 500; ++i) {
    const RigidTransform truth = random_transform(rng);
    const TouchFit fit = fit_touch_points(random_touches(rng, truth, 4 + i % 20, 0.0));
    ASSERT_LT(max_abs(fit.transform.rotation - truth.rotation), 1e-12) << i;
    ASSERT_LT((fit.transform.translation_mm - truth.translation_mm).norm(), 1e-9) << i;
    ASSERT_LT(fit.rms_mm, 1e-9);
  }
}

TEST(RobotTouch, NoisyPointsGiveTheLeastSquaresFitAndItsResidual) {
  std::mt19937_64 rng(ncd::test::seed());
  const double noise_mm = 0.05;
  for (int i = 0; i < 300; ++i) {
    const RigidTransform truth = random_transform(rng);
    const auto touches = random_touches(rng, truth, 4 + i % 12, noise_mm);
    const TouchFit fit = fit_touch_points(touches);
    double sse_fit = 0.0, sse_truth = 0.0, max_e = 0.0;
    ASSERT_EQ(fit.residual_mm.size(), touches.size());
    for (std::size_t k = 0; k < touches.size(); ++k) {
      const double e = (fit.transform.point(touches[k].workpiece_mm) - touches[k].robot_mm).norm();
      ASSERT_NEAR(fit.residual_mm[k], e, 1e-12);
      sse_fit += e * e;
      max_e = std::max(max_e, e);
      sse_truth += (truth.point(touches[k].workpiece_mm) - touches[k].robot_mm).squaredNorm();
    }
    EXPECT_NEAR(fit.rms_mm, std::sqrt(sse_fit / static_cast<double>(touches.size())), 1e-12);
    EXPECT_NEAR(fit.max_mm, max_e, 1e-15);
    EXPECT_GT(fit.rms_mm, 0.0);
    // Least squares: no worse than the truth on the data, and no small turn or shift helps.
    EXPECT_LE(sse_fit, sse_truth + 1e-12);
    for (int k = 0; k < 12; ++k) {
      RigidTransform moved = fit.transform;
      const Vec3 axis = Vec3::Unit(k % 3);
      if (k < 6) {
        moved.rotation =
            Eigen::AngleAxisd(k < 3 ? 1e-5 : -1e-5, axis).toRotationMatrix() * moved.rotation;
      } else {
        moved.translation_mm += (k < 9 ? 1e-4 : -1e-4) * axis;
      }
      double sse = 0.0;
      for (const auto& t : touches) sse += (moved.point(t.workpiece_mm) - t.robot_mm).squaredNorm();
      EXPECT_GE(sse, sse_fit - 1e-12);
    }
    EXPECT_LT(attitude_change_rad(fit.transform.rotation, truth.rotation), 1e-2);
  }
}

std::string error_of(const std::vector<TouchPoint>& touches) {
  try {
    (void)fit_touch_points(touches);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(RobotTouch, TooFewDuplicateOrCollinearPointsAreClearErrors) {
  const Vec3 a(0, 0, 0), b(50, 0, 0), c(0, 40, 0), d(10, 10, 30);
  std::string e = error_of({{a, a}, {b, b}});
  EXPECT_NE(e.find("at least 3"), std::string::npos) << e;
  EXPECT_NE(e.find("got 2"), std::string::npos) << e;

  e = error_of({{a, a}, {b, b}, {b + Vec3(0.2, 0, 0), b + Vec3(0.2, 0, 0)}, {c, c}});
  EXPECT_NE(e.find("touch points 2 and 3"), std::string::npos) << e;
  EXPECT_NE(e.find("0.2 mm"), std::string::npos) << e;
  EXPECT_NE(e.find("less than 1 mm"), std::string::npos) << e;

  e = error_of(
      {{a, a}, {b, b}, {Vec3(100, 0, 0), Vec3(100, 0, 0)}, {Vec3(30, 0, 0), Vec3(30, 0, 0)}});
  EXPECT_NE(e.find("collinear in the workpiece frame"), std::string::npos) << e;
  EXPECT_NE(e.find("RMS distance from the best-fit line is 0 mm"), std::string::npos) << e;
  EXPECT_NE(e.find("touch a point off the line"), std::string::npos) << e;

  // Nearly collinear: 0.3 mm off a 100 mm line.
  e = error_of({{a, a}, {Vec3(100, 0.3, 0), Vec3(100, 0.3, 0)}, {Vec3(50, 0, 0.3), c}});
  EXPECT_NE(e.find("collinear in the workpiece frame"), std::string::npos) << e;

  // Robot side collinear while the workpiece side is not.
  e = error_of({{a, a}, {c, Vec3(40, 0, 0)}, {d, Vec3(80, 0, 0)}});
  EXPECT_NE(e.find("collinear in the robot frame"), std::string::npos) << e;

  EXPECT_EQ(error_of({{a, a}, {b, b}, {c, c}, {d, d}}), "");
}

// ---------------------------------------------------------------------------- validation

std::string spec_error(const RobotSpec& s) {
  try {
    validate(s);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(RobotValidate, HoleAsWideAsTheCylinderOrWiderIsAClearError) {
  RobotSpec s = paper_experiment();
  for (double r : {30.0, 45.0}) {
    s.hole_radius_mm = r;
    const std::string e = spec_error(s);
    EXPECT_NE(e.find("hole radius r = " + std::to_string(static_cast<int>(r)) + " mm"),
              std::string::npos)
        << e;
    EXPECT_NE(e.find("cylinder radius R = 30 mm"), std::string::npos) << e;
    EXPECT_NE(e.find("--hole-radius"), std::string::npos) << e;
    EXPECT_THROW((void)generate_robot_path(s), InputError);
  }
  s = paper_experiment();
  s.hole_radius_mm = 29.9;
  EXPECT_EQ(spec_error(s), "");
}

TEST(RobotValidate, OutOfRangeParametersNameTheValueAndTheLimit) {
  RobotSpec s = paper_experiment();
  s.points = 7;
  EXPECT_NE(spec_error(s).find("N = 7 is outside [8, 100000]"), std::string::npos);
  s = paper_experiment();
  s.passes = 0;
  EXPECT_NE(spec_error(s).find("passes = 0"), std::string::npos);
  s = paper_experiment();
  s.depth_mm = 2.0;  // leg 2.83 mm > 0.1 × min(15, 25.98) = 1.5 mm
  const std::string e = spec_error(s);
  EXPECT_NE(e.find("2.82843 mm exceeds"), std::string::npos) << e;
  EXPECT_NE(e.find("= 1.5 mm"), std::string::npos) << e;
  s = paper_experiment();
  s.depth_mm = std::nan("");
  EXPECT_NE(spec_error(s).find("depth of cut"), std::string::npos);
  s = paper_experiment();
  s.bar_radius_mm = 15.0;
  EXPECT_NE(spec_error(s).find("bar radius = 15 mm"), std::string::npos);
  s = paper_experiment();
  s.cylinder_radius_mm = -1.0;
  EXPECT_NE(spec_error(s).find("cylinder radius R"), std::string::npos);
}

// ------------------------------------------------------------------------------- program

TEST(RobotProgram, ApproachAndRetractAlongNInTheRobotFrame) {
  std::mt19937_64 rng(ncd::test::seed());
  const RobotPath path = generate_robot_path(paper_experiment());
  const RigidTransform t = random_transform(rng);
  RobotProgramOptions o;
  o.approach_distance_mm = 7.0;
  o.speed_mm_per_s = 1.0;
  o.move_speed_mm_per_s = 20.0;
  const RobotProgram prog = make_robot_program(path, t, o);
  ASSERT_EQ(prog.moves.size(), path.poses.size() + 2);
  const auto& first = prog.moves[1].pose;
  EXPECT_EQ(prog.moves.front().mode, MoveMode::Move);
  EXPECT_EQ(prog.moves.back().mode, MoveMode::Move);
  EXPECT_LT((prog.moves.front().pose.p_mm - (first.p_mm - 7.0 * first.tf)).norm(), 1e-9);
  const auto& last = prog.moves[prog.moves.size() - 2].pose;
  EXPECT_LT((prog.moves.back().pose.p_mm - (last.p_mm - 7.0 * last.tf)).norm(), 1e-9);
  double cut = 0.0, duration = 0.0;
  for (std::size_t i = 0; i < prog.moves.size(); ++i) {
    const auto& mv = prog.moves[i];
    if (i > 0 && i + 1 < prog.moves.size()) {
      const auto& w = path.poses[i - 1];
      EXPECT_EQ(mv.mode, MoveMode::Cut);
      EXPECT_EQ(mv.speed_mm_per_s, 1.0);
      EXPECT_LT((mv.pose.p_mm - t.point(w.p_mm)).norm(), 1e-9);
      EXPECT_LT(max_abs(mv.pose.rotation() - t.rotation * w.rotation()), 1e-12);
    }
    EXPECT_LT(max_abs(wpr_to_matrix(mv.wpr) - mv.pose.rotation()), 1e-12);
    if (i > 0) {
      const double len = (mv.pose.p_mm - prog.moves[i - 1].pose.p_mm).norm();
      if (mv.mode == MoveMode::Cut) cut += len;
      duration += len / mv.speed_mm_per_s;
      EXPECT_NEAR(mv.attitude_change_rad,
                  attitude_change_rad(prog.moves[i - 1].pose.rotation(), mv.pose.rotation()),
                  1e-15);
    }
  }
  EXPECT_NEAR(prog.cut_length_mm, cut, 1e-9);
  EXPECT_NEAR(prog.duration_s, duration, 1e-9);
  EXPECT_LT(prog.wpr_roundtrip_error, 1e-12);
  o.speed_mm_per_s = 0.0;
  EXPECT_THROW((void)make_robot_program(path, t, o), InputError);
}

}  // namespace
}  // namespace ncd::toolpath
