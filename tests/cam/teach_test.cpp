// Off-line teaching (paper 003) against the paper's table and program as settled in
// docs/teach.md, exact identities (orthonormal frame, planted frame coordinates, offset distance,
// radial normals on a circle, rigid-motion invariance, wrap-around), a slow reference for the
// paper's parabola (a Vandermonde solve), the program read back by our G-code reader, and one
// error per invalid input.
#include "cam/teach.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <functional>
#include <iostream>
#include <limits>
#include <numeric>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "gcode/gcode_reader.hpp"
#include "tests/common/seed.hpp"

namespace ncd::toolpath {
namespace {

using Vec2 = Eigen::Vector2d;

const std::array<Vec3, 3> kPaperFrame{Vec3(47.45, 111.55, 236.60), Vec3(229.17, 327.47, 274.28),
                                      Vec3(-17.55, 327.77, 316.35)};

const std::vector<Vec3> kPaperPoints{{66.15, 124.57, 236.76}, {70.98, 125.20, 236.12},
                                     {76.49, 125.79, 235.45}, {83.01, 127.46, 235.11},
                                     {87.55, 128.68, 235.07}, {92.32, 130.68, 234.88}};

std::vector<TaughtPoint> taught(const std::vector<Vec3>& pts) {
  std::vector<TaughtPoint> out;
  for (const Vec3& p : pts) out.push_back({p, "", 0});
  return out;
}

// The identity frame: world = frame coordinates.
TeachFrame identity_frame() {
  return make_frame({Vec3(0, 0, 0), Vec3(100, 0, 0), Vec3(0, 100, 0)}, "test frame");
}

TeachSpec spec(double d, double l, TravelSide side = TravelSide::Left, bool closed = false) {
  TeachSpec s;
  s.tool_diameter_mm = d;
  s.depth_mm = l;
  s.side = side;
  s.closed = closed;
  return s;
}

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no InputError thrown";
  return "";
}

// The program without its header comment: the lines a machine executes.
std::string motion_lines(const std::string& program) {
  std::istringstream in(program);
  std::string line, out;
  while (std::getline(in, line)) {
    if (!line.empty() && line.front() != '(') out += line + "\n";
  }
  return out;
}

// A random rotation from a uniformly random unit quaternion.
Eigen::Matrix3d random_rotation_matrix(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return Eigen::Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized().toRotationMatrix();
}

// Frame points whose frame is R (columns e_x, e_y, e_z) at origin P1.
std::array<Vec3, 3> frame_points_for(const Eigen::Matrix3d& r, const Vec3& p1,
                                     std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double a = 20.0 + 300.0 * u(rng), b = -200.0 + 400.0 * u(rng), c = 20.0 + 300.0 * u(rng);
  return {p1, p1 + a * r.col(0), p1 + b * r.col(0) + c * r.col(1)};
}

// A random smooth-ish path in frame coordinates: steps of 0.5–5 mm, heading turning by at
// most 100° per step (never straight back), z within ±3 mm.
std::vector<Vec3> random_path(std::mt19937_64& rng, std::size_t n) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vec3> q;
  Vec3 p(-50.0 + 100.0 * u(rng), -50.0 + 100.0 * u(rng), 0.0);
  double heading = 2.0 * kPi * u(rng);
  for (std::size_t i = 0; i < n; ++i) {
    p.z() = -3.0 + 6.0 * u(rng);
    q.push_back(p);
    heading += deg_to_rad(-100.0 + 200.0 * u(rng));
    const double step = 0.5 + 4.5 * u(rng);
    p += Vec3(step * std::cos(heading), step * std::sin(heading), 0.0);
  }
  return q;
}

// ------------------------------------------------------- the paper's figures (docs/teach.md)

TEST(Teach, FrameReproducesThePapersTable) {
  // §3.2 prints x and y truncated to 3 decimals and z rounded to 6 (29.1817 → 29.181, but
  // −0.7651540 → −0.765154 where truncation would give −0.765153).
  const std::vector<std::array<const char*, 3>> paper{
      {"21.830", "-6.489", "-0.747830"},  {"25.306", "-9.961", "-0.765154"},
      {"29.181", "-13.977", "-0.689908"}, {"34.564", "-18.025", "-0.465339"},
      {"38.382", "-20.750", "-0.140952"}, {"42.918", "-23.242", "-0.153992"}};
  const TeachFrame f = make_frame(kPaperFrame, "paper");
  for (std::size_t i = 0; i < paper.size(); ++i) {
    const Vec3 q = f.to_frame(kPaperPoints[i]);
    EXPECT_EQ(format_fixed(q.x(), 3, Rounding::Truncate), paper[i][0]) << "dp" << i + 1;
    EXPECT_EQ(format_fixed(q.y(), 3, Rounding::Truncate), paper[i][1]) << "dp" << i + 1;
    EXPECT_EQ(format_fixed(q.z(), 6, Rounding::Nearest), paper[i][2]) << "dp" << i + 1;
  }
}

TEST(Teach, ProgramReproducesThePapersLines) {
  // D = 10, l = 0.2, F300 S2000, truncated: the paper's lines for dp2..dp5 (dp1 and dp6 depend
  // on neighbours the paper does not list).
  const TeachPath path =
      teach(taught(kPaperPoints), make_frame(kPaperFrame, "paper"), spec(10.0, 0.2));
  TeachProgramOptions o;
  o.feed_mm_per_min = 300.0;
  o.spindle_rpm = 2000.0;
  o.rounding = Rounding::Truncate;
  const std::string program = teach_program(path, o);
  std::istringstream in(program);
  std::vector<std::string> g01;
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("G01", 0) == 0) g01.push_back(line);
  }
  ASSERT_EQ(g01.size(), 6u);
  EXPECT_EQ(g01[1], "G01X28.728Y-6.595Z-0.765");
  EXPECT_EQ(g01[2], "G01X32.426Y-10.440Z-0.689");
  EXPECT_EQ(g01[3], "G01X37.393Y-14.148Z-0.465");
  EXPECT_EQ(g01[4], "G01X40.965Y-16.704Z-0.140");
  EXPECT_NE(program.find("\nG90F300S2000\n"), std::string::npos);
  for (const OffsetPoint& p : path.points) EXPECT_EQ(p.fit, TangentFit::PaperParabola);
  // The header states the frame points, D, l, the side and the precision.
  for (const char* s :
       {"P1 = 47.45, 111.55, 236.6", "P2 = 229.17, 327.47, 274.28", "P3 = -17.55, 327.77, 316.35",
        "D = 10", "l = 0.2", "4.8 left", "truncated toward zero to 3 decimals"}) {
    EXPECT_NE(program.find(s), std::string::npos) << s;
  }
}

TEST(Teach, RoundingIsTheDefault) {
  const TeachPath path =
      teach(taught(kPaperPoints), make_frame(kPaperFrame, "paper"), spec(10.0, 0.2));
  const std::string program = teach_program(path, TeachProgramOptions{});
  // 32.42656 → 32.427 and −0.68991 → −0.690 when rounded (the paper truncates).
  EXPECT_NE(program.find("\nG01X32.427Y-10.440Z-0.690\n"), std::string::npos) << program;
  EXPECT_NE(program.find("(coordinates rounded to 3 decimals"), std::string::npos);
}

// ---------------------------------------------------------------- identities

TEST(Teach, FrameIsOrthonormalRightHandedAndRecoversPlantedCoordinates) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(-500.0, 500.0);
  for (int trial = 0; trial < 500; ++trial) {
    const Eigen::Matrix3d r = random_rotation_matrix(rng);
    const Vec3 p1(u(rng), u(rng), u(rng));
    const auto fp = frame_points_for(r, p1, rng);
    const TeachFrame f = make_frame(fp, "random");
    EXPECT_LE((f.r.transpose() * f.r - Eigen::Matrix3d::Identity()).norm(), 1e-14);
    EXPECT_NEAR(f.r.determinant(), 1.0, 1e-14);
    EXPECT_LE((f.r - r).norm(), 1e-12);
    const Vec3 p2 = f.to_frame(fp[1]), p3 = f.to_frame(fp[2]);
    EXPECT_NEAR(p2.x(), (fp[1] - fp[0]).norm(), 1e-10);
    EXPECT_NEAR(p2.y(), 0.0, 1e-10);
    EXPECT_NEAR(p2.z(), 0.0, 1e-10);
    EXPECT_GT(p3.y(), 0.0);
    EXPECT_NEAR(p3.z(), 0.0, 1e-10);
    const Vec3 q(u(rng), u(rng), u(rng));
    EXPECT_LE((f.to_frame(p1 + r * q) - q).norm(), 1e-10);
  }
}

TEST(Teach, ToolCentreIsDOver2MinusLFromEveryPointOnTheStatedSide) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 300; ++trial) {
    const auto q = random_path(rng, 3 + static_cast<std::size_t>(40.0 * u(rng)));
    const double d = 1.0 + 20.0 * u(rng), l = 0.45 * d * u(rng);
    const TravelSide side = u(rng) < 0.5 ? TravelSide::Left : TravelSide::Right;
    const bool closed = u(rng) < 0.5;
    const TeachPath path = teach(taught(q), identity_frame(), spec(d, l, side, closed));
    ASSERT_EQ(path.points.size(), q.size());
    EXPECT_DOUBLE_EQ(path.offset_mm, 0.5 * d - l);
    for (std::size_t k = 0; k < q.size(); ++k) {
      const OffsetPoint& o = path.points[k];
      EXPECT_LE((o.taught_mm - q[k]).norm(), 1e-12);
      const Vec3 step = o.tool_mm - o.taught_mm;
      EXPECT_NEAR(step.head<2>().norm(), 0.5 * d - l, 1e-12);
      EXPECT_EQ(step.z(), 0.0);  // Z is kept
      EXPECT_NEAR(o.tangent.norm(), 1.0, 1e-14);
      EXPECT_NEAR(o.tangent.dot(o.normal), 0.0, 1e-14);
      // The normal is on the stated side of the tangent, and the tangent points along travel:
      // inside a point it lies between the incoming and outgoing chords (both fits' tangents
      // are positive blends of the two), at an open end it leans along the end chord.
      const double cross = o.tangent.x() * o.normal.y() - o.tangent.y() * o.normal.x();
      EXPECT_NEAR(cross, side == TravelSide::Left ? 1.0 : -1.0, 1e-14);
      const std::size_t n = q.size();
      if (!closed && (k == 0 || k == n - 1)) {
        const Vec2 chord = k == 0 ? (q[1] - q[0]).head<2>() : (q[n - 1] - q[n - 2]).head<2>();
        EXPECT_GT(o.tangent.dot(chord), 0.0) << "point " << k;
        continue;
      }
      const Vec2 in = (q[k] - q[(k + n - 1) % n]).head<2>().normalized();
      const Vec2 out = (q[(k + 1) % n] - q[k]).head<2>().normalized();
      const auto cross2 = [](const Vec2& a, const Vec2& b) {
        return a.x() * b.y() - a.y() * b.x();
      };
      const double turn = cross2(in, out);
      EXPECT_GE(cross2(in, o.tangent) * turn, -1e-12) << "point " << k;
      EXPECT_GE(cross2(o.tangent, out) * turn, -1e-12) << "point " << k;
      EXPECT_GT(o.tangent.dot(in + out), 0.0) << "point " << k;
    }
  }
}

TEST(Teach, PaperParabolaAgreesWithAVandermondeSolveWhereItIsUsed) {
  std::mt19937_64 rng(ncd::test::seed());
  std::size_t checked = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const auto q = random_path(rng, 12);
    const TeachPath path = teach(taught(q), identity_frame(), spec(10.0, 0.2));
    for (std::size_t k = 0; k < q.size(); ++k) {
      if (path.points[k].fit != TangentFit::PaperParabola) continue;
      const std::size_t first = k == 0 ? 0 : std::min(k - 1, q.size() - 3);
      Eigen::Matrix3d v;
      Vec3 y;
      for (int i = 0; i < 3; ++i) {
        const Vec3& p = q[first + static_cast<std::size_t>(i)];
        v.row(i) << p.x() * p.x(), p.x(), 1.0;
        y[i] = p.y();
      }
      const Vec3 abc = v.colPivHouseholderQr().solve(y);
      const double m = 2.0 * abc[0] * q[k].x() + abc[1];  // the paper's slope
      const double travel = q[first + 2].x() > q[first].x() ? 1.0 : -1.0;
      const Vec2 t = travel * Vec2(1.0, m).normalized();
      EXPECT_LE((path.points[k].tangent - t).norm(), 1e-8) << "point " << k;
      ++checked;
    }
  }
  EXPECT_GT(checked, 100u);
}

TEST(Teach, ChordQuadraticNormalIsRadialOnAnyCircle) {
  // The chord-length quadratic's tangent at its middle point is exact on a circle for any
  // spacing: where it is used the tool centre lies at ρ ∓ (D/2 − l) from the centre exactly.
  // A closed loop of 40 unequal steps (0.5–1.5 times the mean), both senses, vertical tangents
  // included; the curvature (always the chord quadratic's) is within O(h²/ρ²) of 1/ρ.
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::size_t checked = 0;
  double worst_curvature = 0.0;
  for (int trial = 0; trial < 200; ++trial) {
    const double rho = 10.0 + 90.0 * u(rng);
    const Vec2 centre(-100.0 + 200.0 * u(rng), -100.0 + 200.0 * u(rng));
    const double sense = u(rng) < 0.5 ? 1.0 : -1.0;  // +1 counter-clockwise: turning left
    std::vector<double> steps(40);
    for (double& h : steps) h = 0.5 + u(rng);
    const double scale = 2.0 * kPi / std::accumulate(steps.begin(), steps.end(), 0.0);
    std::vector<Vec3> q;
    double phi = 2.0 * kPi * u(rng);
    for (double h : steps) {
      q.emplace_back(centre.x() + rho * std::cos(phi), centre.y() + rho * std::sin(phi), 0.0);
      phi += sense * h * scale;
    }
    const TravelSide side = u(rng) < 0.5 ? TravelSide::Left : TravelSide::Right;
    const TeachPath path = teach(taught(q), identity_frame(), spec(8.0, 0.5, side, true));
    // Left of a counter-clockwise circle is inside.
    const bool inside = (side == TravelSide::Left) == (sense > 0);
    for (const OffsetPoint& o : path.points) {
      worst_curvature = std::max(worst_curvature, std::abs(o.curvature_per_mm * sense * rho - 1));
      if (o.fit != TangentFit::ChordQuadratic) continue;
      EXPECT_NEAR((o.tool_mm.head<2>() - centre).norm(), rho + (inside ? -3.5 : 3.5), 1e-9);
      ++checked;
    }
    if (inside) {
      EXPECT_NEAR(path.min_tool_side_radius_mm, rho, 0.05 * rho);
    } else {
      EXPECT_TRUE(std::isinf(path.min_tool_side_radius_mm));
    }
  }
  // Steps up to 1.5 · 2π/40 = 0.24 rad: h²/ρ² ≈ 0.06.
  EXPECT_LE(worst_curvature, 0.05);
  std::cout << "[ circle   ] worst |κρ − 1| = " << worst_curvature << "\n";
  EXPECT_GT(checked, 2000u);
}

TEST(Teach, RigidMotionOfPartAndFrameGivesTheSameProgram) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    const auto q = random_path(rng, 3 + static_cast<std::size_t>(30.0 * u(rng)));
    const Eigen::Matrix3d r = random_rotation_matrix(rng);
    const Vec3 p1(-300.0 + 600.0 * u(rng), -300.0 + 600.0 * u(rng), -300.0 + 600.0 * u(rng));
    const auto fp = frame_points_for(r, p1, rng);
    std::vector<Vec3> world;
    for (const Vec3& p : q) world.push_back(p1 + r * p);
    // The same part moved: rotation m, translation t applied to the points and the frame.
    const Eigen::Matrix3d m = random_rotation_matrix(rng);
    const Vec3 t(-300.0 + 600.0 * u(rng), -300.0 + 600.0 * u(rng), -300.0 + 600.0 * u(rng));
    std::vector<Vec3> moved;
    for (const Vec3& p : world) moved.push_back(m * p + t);
    const std::array<Vec3, 3> fp_moved{m * fp[0] + t, m * fp[1] + t, m * fp[2] + t};
    const TeachSpec s =
        spec(6.0, 0.3, u(rng) < 0.5 ? TravelSide::Left : TravelSide::Right, u(rng) < 0.5);
    const TeachPath a = teach(taught(world), make_frame(fp, "a"), s);
    const TeachPath b = teach(taught(moved), make_frame(fp_moved, "b"), s);
    for (std::size_t k = 0; k < q.size(); ++k) {
      EXPECT_LE((a.points[k].tool_mm - b.points[k].tool_mm).norm(), 1e-9);
      EXPECT_EQ(a.points[k].fit, b.points[k].fit);
    }
    EXPECT_EQ(motion_lines(teach_program(a, {})), motion_lines(teach_program(b, {})));
  }
}

// ---------------------------------------------------------------- where y(x) fails

TEST(Teach, VerticalTangentKeepsWorking) {
  // A straight path along +Y: x is constant, the paper's parabola has no slope there.
  const std::vector<Vec3> q{{5, 0, 1}, {5, 2, 1}, {5, 3, 1}, {5, 7, 1}};
  const TeachPath left = teach(taught(q), identity_frame(), spec(10.0, 0.2));
  const TeachPath right = teach(taught(q), identity_frame(), spec(10.0, 0.2, TravelSide::Right));
  for (std::size_t k = 0; k < q.size(); ++k) {
    EXPECT_EQ(left.points[k].fit, TangentFit::ChordQuadratic);
    EXPECT_LE((left.points[k].tangent - Vec2(0, 1)).norm(), 1e-15);
    EXPECT_LE((left.points[k].tool_mm - (q[k] + Vec3(-4.8, 0, 0))).norm(), 1e-14);
    EXPECT_LE((right.points[k].tool_mm - (q[k] + Vec3(4.8, 0, 0))).norm(), 1e-14);
  }
}

TEST(Teach, HairpinDoublingBackInXKeepsTheSideOfTravel) {
  // Out along y = 0, round a half circle of radius 10 about (20, 10), back along y = 20.
  std::vector<Vec3> q{{0, 0, 0}, {5, 0, 0}, {10, 0, 0}, {15, 0, 0}, {20, 0, 0}};
  for (int i = 1; i < 12; ++i) {
    const double phi = -0.5 * kPi + kPi * i / 12.0;
    q.emplace_back(20.0 + 10.0 * std::cos(phi), 10.0 + 10.0 * std::sin(phi), 0.0);
  }
  for (double x : {20.0, 15.0, 10.0, 5.0, 0.0}) q.emplace_back(x, 20.0, 0.0);
  const TeachPath path = teach(taught(q), identity_frame(), spec(6.0, 1.0));  // offset 2
  // Left of travel is inside the hairpin on both legs and round the turn.
  // The straight legs, but for their last (first) point, whose fit reaches into the arc.
  for (std::size_t k = 0; k < 4; ++k) EXPECT_NEAR(path.points[k].tool_mm.y(), 2.0, 1e-12) << k;
  for (std::size_t k = q.size() - 4; k < q.size(); ++k) {
    EXPECT_NEAR(path.points[k].tool_mm.y(), 18.0, 1e-12) << k;
  }
  // The tip, x = 30 (x stops increasing and comes back): chord quadratic, tangent +Y, radial.
  const OffsetPoint& tip = path.points[10];
  EXPECT_NEAR(tip.taught_mm.x(), 30.0, 1e-12);
  EXPECT_EQ(tip.fit, TangentFit::ChordQuadratic);
  EXPECT_LE((tip.tangent - Vec2(0, 1)).norm(), 1e-12);
  EXPECT_LE((tip.tool_mm - Vec3(28, 10, 0)).norm(), 1e-12);
  EXPECT_NEAR(path.min_tool_side_radius_mm, 10.0, 0.2);
}

TEST(Teach, TurnTighterThanTheOffsetIsReportedNotRefused) {
  const std::vector<Vec3> q{{0, 0, 0}, {3, 0, 0}, {4, 1, 0}, {3, 2, 0}, {0, 2, 0}};
  const TeachPath path = teach(taught(q), identity_frame(), spec(10.0, 0.2));
  EXPECT_LT(path.min_tool_side_radius_mm, path.offset_mm);
  EXPECT_EQ(path.min_tool_side_radius_at, 2u);
  EXPECT_NE(teach_program(path, {}).find("(BELOW D/2 - l: the tool cuts deeper than l there)"),
            std::string::npos);
}

TEST(Teach, ClosedLoopWrapsItsNeighboursAround) {
  std::mt19937_64 rng(ncd::test::seed());
  for (int trial = 0; trial < 100; ++trial) {
    const auto q = random_path(rng, 10);
    const TeachPath closed =
        teach(taught(q), identity_frame(), spec(4.0, 0.1, TravelSide::Left, true));
    // Point 0 of the loop sees the last and second points: as the middle of an open path
    // through (last, 0, 1); the last point likewise as the middle of (n−2, last, 0).
    const std::size_t n = q.size();
    const TeachPath head = teach(taught({q[n - 1], q[0], q[1]}), identity_frame(), spec(4.0, 0.1));
    const TeachPath tail =
        teach(taught({q[n - 2], q[n - 1], q[0]}), identity_frame(), spec(4.0, 0.1));
    EXPECT_EQ(closed.points[0].tool_mm, head.points[1].tool_mm);
    EXPECT_EQ(closed.points[n - 1].tool_mm, tail.points[1].tool_mm);
    // The program returns to the first point.
    const std::string program = motion_lines(teach_program(closed, {}));
    std::vector<std::string> g01;
    std::istringstream in(program);
    for (std::string line; std::getline(in, line);) {
      if (line.rfind("G01", 0) == 0) g01.push_back(line);
    }
    ASSERT_EQ(g01.size(), n + 1);
    EXPECT_EQ(g01.front(), g01.back());
  }
}

TEST(Teach, OpenEndsUseTheFirstAndLastThreePoints) {
  std::mt19937_64 rng(ncd::test::seed());
  for (int trial = 0; trial < 100; ++trial) {
    const auto q = random_path(rng, 8);
    const TeachPath path = teach(taught(q), identity_frame(), spec(4.0, 0.1));
    const TeachPath head = teach(taught({q[0], q[1], q[2]}), identity_frame(), spec(4.0, 0.1));
    const TeachPath tail = teach(taught({q[5], q[6], q[7]}), identity_frame(), spec(4.0, 0.1));
    EXPECT_EQ(path.points[0].tool_mm, head.points[0].tool_mm);
    EXPECT_EQ(path.points[7].tool_mm, tail.points[2].tool_mm);
  }
}

// ---------------------------------------------------------------- the program read back

TEST(Teach, ProgramReadsBackThroughTheGcodeReader) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 100; ++trial) {
    const auto q = random_path(rng, 3 + static_cast<std::size_t>(30.0 * u(rng)));
    const bool closed = u(rng) < 0.5;
    const TeachPath path =
        teach(taught(q), identity_frame(), spec(5.0, 0.2, TravelSide::Right, closed));
    TeachProgramOptions o;
    o.decimals = 1 + static_cast<int>(5.0 * u(rng));
    o.rounding = u(rng) < 0.5 ? Rounding::Nearest : Rounding::Truncate;
    const std::string program = teach_program(path, o);
    // Plain 7-bit lines that fit an 80-character controller line buffer (grbl's).
    std::istringstream lines(program);
    for (std::string line; std::getline(lines, line);) {
      EXPECT_LE(line.size(), 80u) << line;
      for (char c : line) EXPECT_TRUE(c >= ' ' && c < 127) << line;
    }
    std::istringstream in(program);
    InterpretOptions tools;  // the tool in the spindle, whose length G43 H1 takes
    tools.machine_tools = {o.tool};
    const Path read = read_gcode(in, "teach.ngc", tools);
    // The rapid to the clearance plane above the first point only sets the position; then the
    // plunge and the cut at F, and a rapid back up.
    ASSERT_EQ(read.segments.size(), 2u);
    EXPECT_TRUE(read.segments[1].rapid);
    const PathSegment& cut = read.segments[0];
    EXPECT_FALSE(cut.rapid);
    EXPECT_EQ(cut.feed_mm_per_min, o.feed_mm_per_min);
    EXPECT_EQ(cut.spindle_rpm, o.spindle_rpm);
    // The cut passes through every tool point to the stated precision (one unit of the last
    // digit when truncated, half of one when rounded); repeats after rounding are dropped.
    const double tol = std::pow(10.0, -o.decimals) * (o.rounding == Rounding::Truncate ? 1.0 : 0.5);
    const auto& pts = std::get<Polyline>(cut.geometry).points;
    std::size_t j = 0;
    for (std::size_t k = 0; k <= q.size() - (closed ? 0 : 1); ++k) {
      const Vec3& want = path.points[k % q.size()].tool_mm;
      while (j + 1 < pts.size() && (pts[j] - want).lpNorm<Eigen::Infinity>() > tol + 1e-12) ++j;
      EXPECT_LE((pts[j] - want).lpNorm<Eigen::Infinity>(), tol + 1e-12) << "point " << k;
    }
  }
}

TEST(Teach, HeaderLinesFitEightyCharactersAtTheCoordinateLimit) {
  const double big = -TeachLimits::kMaxCoordinateMm + 0.123456789;
  const TeachFrame f = make_frame(
      {Vec3(big, big, big), Vec3(big + 100.0, big, big), Vec3(big, big + 100.0, big)}, "far");
  const std::vector<Vec3> q{
      {big, big + 50, big}, {big + 1, big + 51, big}, {big + 2, big + 53, big}};
  TeachProgramOptions o;
  o.decimals = TeachLimits::kMaxDecimals;
  o.feed_mm_per_min = 12345.678;
  o.spindle_rpm = 24000.5;
  const std::string program = teach_program(teach(taught(q), f, spec(12.345678, 0.123456)), o);
  std::istringstream lines(program);
  for (std::string line; std::getline(lines, line);) EXPECT_LE(line.size(), 80u) << line;
}

TEST(Teach, FormatFixedTruncatesTheDecimalNotTheBinary) {
  EXPECT_EQ(format_fixed(0.29, 3, Rounding::Truncate), "0.290");  // 0.29 × 1000 = 289.99…
  EXPECT_EQ(format_fixed(-0.140951965, 3, Rounding::Truncate), "-0.140");
  EXPECT_EQ(format_fixed(-0.140951965, 3, Rounding::Nearest), "-0.141");
  EXPECT_EQ(format_fixed(32.4265559, 3, Rounding::Truncate), "32.426");
  EXPECT_EQ(format_fixed(32.4265559, 3, Rounding::Nearest), "32.427");
  EXPECT_EQ(format_fixed(-0.0004, 3, Rounding::Truncate), "0.000");
  EXPECT_EQ(format_fixed(-0.0004, 3, Rounding::Nearest), "0.000");
  EXPECT_EQ(format_fixed(1e-7, 3, Rounding::Truncate), "0.000");
  EXPECT_EQ(format_fixed(12, 3, Rounding::Truncate), "12.000");
  EXPECT_EQ(format_fixed(123456.7891, 2, Rounding::Truncate), "123456.78");
  EXPECT_EQ(format_fixed(-9.9999, 3, Rounding::Nearest), "-10.000");
}

// ---------------------------------------------------------------- reading points

TEST(Teach, ParsesThePapersNamedLinesAndCsv) {
  const auto a = parse_points(
      "\xEF\xBB\xBF# digitized\n\ndp1 66.15 124.57 236.76\r\ndp2\t70.98\t125.20 236.12\n"
      "  76.49 125.79 +235.45  \n",
      "a.txt");
  ASSERT_EQ(a.size(), 3u);
  EXPECT_EQ(a[0].name, "dp1");
  EXPECT_EQ(a[0].line, 3);
  EXPECT_EQ(a[1].p_mm, Vec3(70.98, 125.20, 236.12));
  EXPECT_EQ(a[2].name, "");
  EXPECT_EQ(a[2].p_mm, Vec3(76.49, 125.79, 235.45));
  const auto b = parse_points("name, Z ,y,x,quality\ndp1,236.76,124.57,66.15,ok\n", "b.csv");
  ASSERT_EQ(b.size(), 1u);
  EXPECT_EQ(b[0].name, "dp1");
  EXPECT_EQ(b[0].p_mm, Vec3(66.15, 124.57, 236.76));
  EXPECT_EQ(b[0].line, 2);
  const auto c = parse_points("1,2,3\n4,5,6\n", "c.csv");
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c[1].p_mm, Vec3(4, 5, 6));
  const auto f = parse_frame_points(
      "47.45,111.55,236.60; 229.17,327.47,274.28;-17.55,327.77,316.35", "--frame-points");
  EXPECT_EQ(f[2], kPaperFrame[2]);
}

TEST(Teach, GarbageInTheFileNamesFileLineAndValue) {
  struct Case {
    const char* text;
    std::vector<const char*> says;
  };
  const std::vector<Case> cases{
      {"dp1 1 2 3\ndp2 1 nan 3\n", {"pts.txt:2", "'nan' (y) is not a number"}},
      {"dp1 1 2 3\ndp2 1 2 3.0.1\n", {"pts.txt:2", "'3.0.1' (z) is not a number"}},
      {"1 2 3\n\n1 2\n", {"pts.txt:3", "2 fields", "'name x y z' or 'x y z'"}},
      {"x,y,z\n1,2,3\n1,2\n", {"pts.txt:3", "2 fields where 3 are expected"}},
      {"x,y,height\n1,2,3\n", {"pts.txt:1", "no 'z' column"}},
      {"x,y,z\n1,2,inf\n", {"pts.txt:2", "'inf' (z) is not a number"}},
      {"x,y,z\n1,2,3mm\n", {"pts.txt:2", "'3mm' (z) is not a number"}},
  };
  for (const Case& c : cases) {
    const std::string msg = message_of([&] { parse_points(c.text, "pts.txt"); });
    for (const char* s : c.says) EXPECT_NE(msg.find(s), std::string::npos) << msg;
  }
  for (const char* bad : {"1,2,3;4,5,6", "1,2,3;4,5;7,8,9", "1,2,3;4,5,x;7,8,9"}) {
    const std::string msg = message_of([&] { parse_frame_points(bad, "--frame-points"); });
    EXPECT_NE(msg.find("--frame-points"), std::string::npos) << msg;
  }
}

// ---------------------------------------------------------------- invalid jobs

TEST(Teach, InvalidJobsSayWhatWhyAndHow) {
  const TeachFrame f = identity_frame();
  const std::vector<Vec3> ok{{0, 0, 0}, {1, 0, 0}, {2, 1, 0}, {3, 3, 0}};
  struct Case {
    std::function<void()> run;
    std::vector<const char*> says;
  };
  std::vector<TaughtPoint> dup = taught(ok);
  dup.insert(dup.begin() + 2, {Vec3(1, 0, 5), "dp3", 7});  // same XY as point 2, other Z
  const std::vector<Case> cases{
      {[&] {
         teach(taught({ok[0], ok[1]}), f, spec(10, 0.2));
       },
       {"2 point(s)", "fewer than the 3", "at least three"}},
      {[&] { teach(dup, f, spec(10, 0.2)); },
       {"point 2 and point 3 (dp3, line 7)", "0 mm apart", "closer than 0.001", "remove one"}},
      {[&] {
         teach(taught({ok[0], ok[1], ok[2], ok[3], ok[0]}), f, spec(10, 0.2, {}, true));
       },
       {"point 5 and point 1", "--closed already joins"}},
      {[&] {
         teach(taught({{0, 0, 0}, {2, 0, 0}, {0, 0, 0}}), f, spec(10, 0.2));
       },
       {"point 2", "turns straight back", "more points"}},
      {[&] { teach(taught(ok), f, spec(10, 5)); },
       {"depth l (--depth) = 5", "tool radius D/2 = 5", "smaller --depth"}},
      {[&] { teach(taught(ok), f, spec(10, 7.5)); }, {"= 7.5", "not below the tool radius"}},
      {[&] { teach(taught(ok), f, spec(10, -0.1)); }, {"--depth", "at least 0"}},
      {[&] { teach(taught(ok), f, spec(0, 0)); }, {"--tool-diameter", "greater than 0"}},
      {[&] {
         teach(taught({{0, 0, 0}, {1, std::numeric_limits<double>::quiet_NaN(), 0}, {2, 0, 0}}), f,
               spec(10, 0.2));
       },
       {"point 2", "finite"}},
      {[&] {
         teach(taught({{0, 0, 0}, {1, 2e6, 0}, {2, 0, 0}}), f, spec(10, 0.2));
       },
       {"point 2", "units"}},
      {[&] {
         make_frame({Vec3(0, 0, 0), Vec3(100, 0, 0), Vec3(300, 1, 0)}, "--frame-points");
       },
       {"--frame-points", "collinear", "angle P2-P1-P3 = 0.191 deg", "between 1 and 179",
        "away from the line"}},
      {[&] {
         make_frame({Vec3(0, 0, 0), Vec3(100, 0, 0), Vec3(-300, 1, 0)}, "--frame-points");
       },
       {"collinear", "179.809 deg"}},
      {[&] {
         make_frame({Vec3(0, 0, 0), Vec3(100, 0, 0), Vec3(100, 0.5, 0)}, "--frame-points");
       },
       {"P2 and P3 are 0.500 mm apart", "closer than 1 mm", "farther apart"}},
      {[&] {
         TeachProgramOptions o;
         o.decimals = 9;
         teach_program(teach(taught(ok), f, spec(10, 0.2)), o);
       },
       {"--decimals", "9", "1 to 6"}},
      {[&] {
         TeachProgramOptions o;
         o.feed_mm_per_min = 0;
         teach_program(teach(taught(ok), f, spec(10, 0.2)), o);
       },
       {"--feed"}},
  };
  for (const Case& c : cases) {
    const std::string msg = message_of(c.run);
    for (const char* s : c.says)
      EXPECT_NE(msg.find(s), std::string::npos) << msg << "\n  missing: " << s;
  }
}

}  // namespace
}  // namespace ncd::toolpath
