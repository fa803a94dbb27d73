// The Z-map simulation against closed forms (a ball's sagitta across a pass, the cusp of two
// passes, the spherical dent of a fixed tool with one edge), against itself (grid refinement,
// threads, setpoints against one move) and against paper 004's simulated figures; and the
// input errors. Geometry: docs/surface-simulation.md.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <sstream>

#include "core/error.hpp"
#include "feed/roughness.hpp"
#include "surface/cutter.hpp"
#include "surface/measure.hpp"
#include "surface/raster.hpp"
#include "surface/zmap.hpp"

namespace ncd::surface {
namespace {

constexpr double kR = 5.0;

// A tool whose feed marks are negligible: many teeth, a small feed per tooth.
BallEndMill fine_tool(int teeth = 4) {
  BallEndMill t;
  t.radius_mm = kR;
  t.teeth = teeth;
  t.spindle_rpm = 10000.0;
  return t;
}

// A straight pass of the tip along +x at height z_tip, feed per tooth ft.
Move pass(const BallEndMill& tool, double y, double z_tip, double x0, double x1, double ft,
          double t0 = 0.0) {
  const double v = ft * tool.teeth * tool.spindle_rpm / 60.0;
  Move m;
  m.from_mm = Vec3(x0, y, z_tip);
  m.to_mm = Vec3(x1, y, z_tip);
  m.t0_s = t0;
  m.t1_s = t0 + (x1 - x0) / v;
  return m;
}

double exact_cusp_mm(double r, double fp) {
  return r - std::sqrt(r * r - 0.25 * fp * fp);
}

TEST(ZMapClosedForms, SinglePassLeavesTheSagittaAcrossTheFeed) {
  const BallEndMill tool = fine_tool();
  const double stock = 0.01, ft = 0.004, h = 0.005;  // feed marks ~ft²/2r = 1.6 nm
  const double half_width = std::sqrt(2.0 * kR * stock - stock * stock);
  InitialSurface plane;
  plane.z0_mm = stock;
  // A cell centre sits on the pass (y = 0).
  ZMap map({0.0, 0.2, -0.5 * h - 0.4, 0.4 + 0.5 * h, h}, plane);
  const SimStats st = simulate(map, tool, {pass(tool, 0.0, 0.0, -0.5, 0.7, ft)});
  EXPECT_GT(st.cell_updates, 0);
  int band = 0, outside = 0;
  double worst = 0.0;
  for (int i = 0; i < map.nx(); ++i) {
    for (int j = 0; j < map.ny(); ++j) {
      const double y = map.y_mm(j);
      const double sagitta = kR - std::sqrt(kR * kR - y * y);
      if (std::abs(y) < half_width - h) {
        worst = std::max(worst, std::abs(map.z_mm(i, j) - sagitta));
        ++band;
      } else if (std::abs(y) > half_width + h) {
        EXPECT_EQ(map.z_mm(i, j), stock) << "outside the cut at y = " << y;
        EXPECT_EQ(map.cut_by(i, j), -1);
        ++outside;
      }
    }
  }
  EXPECT_GT(band, 100 * map.nx());
  EXPECT_GT(outside, 0);
  EXPECT_LT(worst, 2e-5) << "largest departure from r - sqrt(r^2 - y^2), mm";
}

TEST(ZMapClosedForms, TwoPassesLeaveTheCusp) {
  const BallEndMill tool = fine_tool();
  const double stock = 0.01, ft = 0.004, h = 0.005, fp = 0.3;
  InitialSurface plane;
  plane.z0_mm = stock;
  // Cell centres at y = k h, so one lies on the cusp at f_p / 2 = 30 h.
  ZMap map({0.0, 0.1, -0.5 * h, fp + 0.5 * h, h}, plane);
  simulate(map, tool,
           {pass(tool, 0.0, 0.0, -0.4, 0.5, ft), pass(tool, fp, 0.0, -0.4, 0.5, ft, 1.0)});
  const Roughness r = measure(map, Plane{}, {0, map.nx(), 0, map.ny()});
  EXPECT_EQ(r.uncut_cells, 0);
  const double exact_um = exact_cusp_mm(kR, fp) * 1e3;  // 2.2513 µm
  EXPECT_NEAR(r.peak_um, exact_um, 0.01);
  EXPECT_NEAR(r.peak_y_mm, 0.5 * fp, 0.5 * h);
  EXPECT_NEAR(r.peak_um, fp * fp / (8.0 * kR) * 1e3, 0.01);  // the small-f_p form, 2.25 µm
  EXPECT_NEAR(r.valley_um, 0.0, 0.01);
  EXPECT_NEAR(r.across_um, exact_um, 0.01);
  EXPECT_LT(r.along_um, 0.02);  // no feed marks to speak of
}

// Fits x² + y² + z² + D x + E y + F z + G = 0 to the points; returns centre and radius.
std::pair<Vec3, double> fit_sphere(const std::vector<Vec3>& pts) {
  Eigen::MatrixXd a(static_cast<Eigen::Index>(pts.size()), 4);
  Eigen::VectorXd b(static_cast<Eigen::Index>(pts.size()));
  for (std::size_t k = 0; k < pts.size(); ++k) {
    const auto e = static_cast<Eigen::Index>(k);
    a.row(e) << pts[k].x(), pts[k].y(), pts[k].z(), 1.0;
    b(e) = -pts[k].squaredNorm();
  }
  const Eigen::Vector4d s = a.colPivHouseholderQr().solve(b);
  const Vec3 c = -0.5 * s.head<3>();
  return {c, std::sqrt(c.squaredNorm() - s(3))};
}

// The slow reference: the residual left at (x, y) by a 2-tooth tool with straight edges through
// the tip, its centre on y = 0 at x = v t, its edges the line at angle θ(t) = −ω t (M3), found by
// sampling time finely and taking the deepest cut among the moments the line crosses the point.
double brute_force_residual_mm(double x, double y, double ft) {
  const double n_rpm = 10000.0, v = ft * 2.0 * n_rpm / 60.0, w = 2.0 * kPi * n_rpm / 60.0;
  double best = std::numeric_limits<double>::infinity(), prev = 0.0;
  const int n = 200000;
  const double t0 = (x - 1.0) / v, t1 = (x + 1.0) / v;
  for (int k = 0; k <= n; ++k) {
    const double t = t0 + (t1 - t0) * k / n;
    const double dx = x - v * t;
    const double f = std::sin(-w * t - std::atan2(y, dx));
    if (k > 0 && (f > 0.0) != (prev > 0.0)) best = std::min(best, dx * dx + y * y);
    prev = f;
  }
  return kR - std::sqrt(kR * kR - best);
}

TEST(ZMapDeadCentre, OneSideOfThePassKeepsTheSagittaOverTheFeedPerTooth) {
  // Eq. 3 at α = 0 from the edges' motion alone: beside the centre line, on the side where a
  // point's direction from the axis turns with the spindle (y < 0 for M3 feeding +x), an edge
  // meets the point only up to f_t from the axis, leaving up to r − sqrt(r² − f_t²) = 25 µm; on
  // the other side an edge cuts it near the axis, leaving a few µm at most.
  const BallEndMill tool;
  const double ft = 0.5, h = 0.0025;
  InitialSurface plane;
  plane.z0_mm = 0.05;
  ZMap map({0.0, 0.5, -0.2, 0.2, h}, plane);
  const double v = ft * tool.teeth * tool.spindle_rpm / 60.0;
  Move m = pass(tool, 0.0, 0.0, -1.0, 1.5, ft, -1.0 / v);  // the centre is at x = 0 at t = 0
  m.spindle0_rad = 2.0 * kPi * tool.spindle_rpm / 60.0 * (1.0 / v);  // θ(t) = −ω t
  simulate(map, tool, {m});
  for (const double y : {-0.1, -0.03, 0.03, 0.1}) {
    const int j = static_cast<int>((y - map.y0_mm()) / h);
    double sim = 0.0, ref = 0.0;
    for (int i = 0; i < map.nx(); i += 10) {
      sim = std::max(sim, map.z_mm(i, j));
      ref = std::max(ref, brute_force_residual_mm(map.x_mm(i), map.y_mm(j), ft));
    }
    std::cout << "y = " << map.y_mm(j) << " mm: simulated " << sim * 1e3 << " um, reference "
              << ref * 1e3 << " um\n";
    EXPECT_NEAR(sim * 1e3, ref * 1e3, 0.3) << "y = " << y;
    if (y < 0.0) {
      EXPECT_GT(ref * 1e3, 20.0);
    } else {
      EXPECT_LT(ref * 1e3, 3.0);
    }
  }
}

class FixedToolDent : public ::testing::TestWithParam<double> {};

TEST_P(FixedToolDent, OneEdgeOneTurnMakesASphericalDentOfTheBallRadius) {
  BallEndMill tool = fine_tool(1);
  tool.helix_deg = GetParam();
  const double depth = 0.02, h = 0.004;
  const double rim = std::sqrt(2.0 * kR * depth - depth * depth);  // 0.447 mm
  ZMap map({-0.5, 0.5, -0.5, 0.5, h}, InitialSurface{});
  Move m;
  m.from_mm = m.to_mm = Vec3(0.0, 0.0, -depth);
  m.t1_s = 60.0 / tool.spindle_rpm;  // one revolution
  simulate(map, tool, {m});
  std::vector<Vec3> cut;
  for (int j = 0; j < map.ny(); ++j) {
    for (int i = 0; i < map.nx(); ++i) {
      const double rho = std::hypot(map.x_mm(i), map.y_mm(j));
      if (rho < rim - 2 * h) {
        ASSERT_EQ(map.cut_by(i, j), 0) << "a gap in the dent at rho = " << rho;
        cut.emplace_back(map.x_mm(i), map.y_mm(j), map.z_mm(i, j));
      } else if (rho > rim + 2 * h) {
        ASSERT_EQ(map.z_mm(i, j), 0.0) << "cut outside the dent at rho = " << rho;
      }
    }
  }
  const auto [centre, radius] = fit_sphere(cut);
  EXPECT_NEAR(radius, kR, 1e-9);
  EXPECT_NEAR(centre.x(), 0.0, 1e-9);
  EXPECT_NEAR(centre.y(), 0.0, 1e-9);
  EXPECT_NEAR(centre.z(), kR - depth, 1e-9);
  const int mid = map.nx() / 2;
  EXPECT_NEAR(-map.z_mm(mid, mid), depth - (kR - std::sqrt(kR * kR - 2 * 0.25 * h * h)), 1e-12);
}

INSTANTIATE_TEST_SUITE_P(StraightAndHelical, FixedToolDent, ::testing::Values(0.0, 30.0));

TEST(ZMapClosedForms, HalfATurnOfOneEdgeCutsHalfTheDent) {
  // Clockwise (M3), edge 0 starting along +X: in half a turn it sweeps the −Y half only.
  const BallEndMill tool = fine_tool(1);
  ZMap map({-0.5, 0.5, -0.5, 0.5, 0.004}, InitialSurface{});
  Move m;
  m.from_mm = m.to_mm = Vec3(0.0, 0.0, -0.02);
  m.t1_s = 0.5 * 60.0 / tool.spindle_rpm;
  simulate(map, tool, {m});
  int below = 0, above = 0;
  for (int j = 0; j < map.ny(); ++j) {
    for (int i = 0; i < map.nx(); ++i) {
      if (map.cut_by(i, j) < 0) continue;
      (map.y_mm(j) < 0.0 ? below : above) += 1;
      EXPECT_LT(map.y_mm(j), 0.01) << "cut at y = " << map.y_mm(j);
    }
  }
  EXPECT_GT(below, 1000);
  EXPECT_LT(above, 200);  // the row of cells on y = 0 only
}

double fig13_rmax_um(double cell_mm) {
  RasterSpec s;
  s.inclination_deg = 10.0;
  s.patch_x_mm = 0.5;
  s.patch_y_mm = 0.5;
  s.cell_mm = cell_mm;
  const BallEndMill tool;
  const RasterRun run = make_raster(s, tool);
  ZMap map(run.grid, run.initial);
  simulate(map, tool, run.moves);
  const Roughness r = measure(map, run.nominal, {0, map.nx(), 0, map.ny()});
  EXPECT_EQ(r.uncut_cells, 0);
  return r.rmax_um;
}

TEST(ZMapConvergence, RefiningTheGridConverges) {
  // The cells sample the surface at their centres, so the grid's R_max misses the true peak
  // (where three cut surfaces meet) by at most the residual's slope times the distance to the
  // nearest centre: K h with K ≤ ρ/r ≈ 0.1 for the marks of f_t = f_p = 0.5 mm on r = 5 mm.
  // Halving the cell must therefore change R_max by at most K h, and the changes must shrink.
  const double cells_mm[] = {0.02, 0.01, 0.005, 0.0025};
  double prev = fig13_rmax_um(cells_mm[0]);
  std::cout << "R_max at " << cells_mm[0] * 1e3 << " um cells: " << prev << " um\n";
  for (int k = 1; k < 4; ++k) {
    const double next = fig13_rmax_um(cells_mm[k]);
    std::cout << "R_max at " << cells_mm[k] * 1e3 << " um cells: " << next << " um\n";
    EXPECT_LE(std::abs(next - prev), 0.1 * cells_mm[k - 1] * 1e3) << "from " << cells_mm[k - 1];
    prev = next;
  }
}

TEST(ZMapDeterminism, ThreadsAndTilesDoNotChangeTheSurface) {
  RasterSpec s;
  s.inclination_deg = 5.0;
  s.patch_x_mm = 0.4;
  s.patch_y_mm = 0.3;
  s.cell_mm = 0.01;
  const BallEndMill tool;
  const RasterRun run = make_raster(s, tool);
  ZMap one(run.grid, run.initial), many(run.grid, run.initial);
  const SimStats a = simulate(one, tool, run.moves, {1, 0.5, 192});
  const SimStats b = simulate(many, tool, run.moves, {3, 0.5, 8});
  EXPECT_EQ(a.threads, 1);
  EXPECT_GT(b.tiles, a.tiles);
  for (int j = 0; j < one.ny(); ++j) {
    for (int i = 0; i < one.nx(); ++i) {
      ASSERT_EQ(one.z_mm(i, j), many.z_mm(i, j)) << i << ", " << j;
      ASSERT_EQ(one.cut_by(i, j), many.cut_by(i, j));
    }
  }
}

TEST(ZMapInitialSurface, AHeightFunctionBelowItsPlaneEndsAsThePlaneDoes) {
  // Where every cell is cut, the final surface cannot depend on the material that was there:
  // a wavy initial surface under the same bounding plane leaves the same heights.
  RasterSpec s;
  s.inclination_deg = 10.0;
  s.patch_x_mm = 0.5;
  s.patch_y_mm = 0.5;
  s.cell_mm = 0.01;
  const BallEndMill tool;
  const RasterRun run = make_raster(s, tool);
  InitialSurface wavy = run.initial;
  wavy.height = [p = run.initial](double x, double y) {
    return p.plane_mm(x, y) - 0.002 * (1.0 + std::sin(40.0 * x) * std::cos(25.0 * y));
  };
  ZMap plane(run.grid, run.initial), waves(run.grid, wavy);
  EXPECT_NE(plane.z_mm(3, 7), waves.z_mm(3, 7));
  simulate(plane, tool, run.moves);
  simulate(waves, tool, run.moves);
  for (int j = 0; j < plane.ny(); ++j) {
    for (int i = 0; i < plane.nx(); ++i) {
      ASSERT_GE(plane.cut_by(i, j), 0);
      ASSERT_EQ(plane.z_mm(i, j), waves.z_mm(i, j)) << i << ", " << j;
    }
  }
}

TEST(ZMapSetpoints, FourMsSetpointsCutLikeOneMove) {
  // The same straight pass as one move and as 4 ms setpoints read from the replay CSV: the
  // time steps differ, the surface may not (beyond the step's own resolution).
  const BallEndMill tool;
  const Move whole = pass(tool, 0.0, 0.0, -0.8, 0.8, 0.5);
  std::ostringstream csv;
  csv << "t_s,x_mm,y_mm,z_mm,feed_mm_per_min,limit\n";
  const double dt = 0.004, dur = whole.t1_s;
  const auto n = static_cast<int>(std::ceil(dur / dt));
  for (int k = 0; k <= n; ++k) {
    const double t = std::min(dur, k * dt);
    const Vec3 p = whole.from_mm + (whole.to_mm - whole.from_mm) * (t / dur);
    csv << t << "," << p.x() << "," << p.y() << "," << p.z() << ",10000,roughness\n";
  }
  std::istringstream in(csv.str());
  const std::vector<Move> moves = read_setpoints_csv(in, "pass.csv", tool);
  ASSERT_EQ(moves.size(), static_cast<std::size_t>(n));
  InitialSurface plane;
  plane.z0_mm = 0.04;
  ZMap a({-0.2, 0.2, -0.3, 0.3, 0.005}, plane), b({-0.2, 0.2, -0.3, 0.3, 0.005}, plane);
  simulate(a, tool, {whole});
  simulate(b, tool, moves);
  // A cell the edge only grazes within one step may take the other of two nearby events; those
  // are isolated (the point where the edge moves along itself), so count them.
  int differ = 0;
  for (int j = 0; j < a.ny(); ++j) {
    for (int i = 0; i < a.nx(); ++i) differ += std::abs(a.z_mm(i, j) - b.z_mm(i, j)) > 2e-4;
  }
  EXPECT_LE(differ, a.cells() / 1000) << "cells that differ by more than 0.2 um";
  const Roughness ra = measure(a, Plane{}, {0, a.nx(), 0, a.ny()});
  const Roughness rb = measure(b, Plane{}, {0, b.nx(), 0, b.ny()});
  EXPECT_NEAR(ra.along_um, rb.along_um, 0.3);
  EXPECT_NEAR(ra.rmax_um, rb.rmax_um, 0.3);
  EXPECT_NEAR(ra.across_um, rb.across_um, 0.3);
}

struct PaperCase {
  const char* name;
  double alpha_deg, ft_over_fp, paper_um, tolerance_um;
};

class PaperFigure : public ::testing::TestWithParam<PaperCase> {};

TEST_P(PaperFigure, SimulatedRmaxIsWithinTheIssueToleranceOfThePaper) {
  const PaperCase c = GetParam();
  RasterSpec s;
  s.inclination_deg = c.alpha_deg;
  s.feed_per_tooth_mm = c.ft_over_fp * s.pick_feed_mm;
  const BallEndMill tool;
  const RasterRun run = make_raster(s, tool);
  ZMap map(run.grid, run.initial);
  simulate(map, tool, run.moves);
  const Roughness r = measure(map, run.nominal, {0, map.nx(), 0, map.ny()});
  EXPECT_EQ(r.uncut_cells, 0);
  const double model_um =
      feed::roughness_mm(kR, s.pick_feed_mm, s.feed_per_tooth_mm, deg_to_rad(c.alpha_deg)) * 1e3;
  std::cout << c.name << ": simulated " << r.rmax_um << " um, paper " << c.paper_um << " um, model "
            << model_um << " um\n";
  EXPECT_NEAR(r.rmax_um, c.paper_um, c.tolerance_um);
}

INSTANTIATE_TEST_SUITE_P(Choi2003, PaperFigure,
                         ::testing::Values(PaperCase{"Fig13", 10.0, 1.0, 10.7, 1.0},
                                           PaperCase{"Fig14", 0.0, 1.0, 24.9, 1.5},
                                           PaperCase{"Fig15", 0.0, 0.65, 10.2, 1.0}),
                         [](const auto& p) { return std::string(p.param.name); });

TEST(ZMapInput, BadGridsToolsAndMovesAreNamed) {
  const auto msg = [](auto f) -> std::string {
    try {
      f();
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_NE(msg([] { ZMap({1.0, 1.0, 0.0, 1.0, 0.01}, {}); }).find("x range"), std::string::npos);
  EXPECT_NE(msg([] { ZMap({0.0, 1.0, 0.0, 1.0, 0.0}, {}); }).find("cell_mm"), std::string::npos);
  EXPECT_NE(msg([] { ZMap({0.0, 1e4, 0.0, 1e4, 1e-4}, {}); }).find("coarser"), std::string::npos);
  InitialSurface nan_surface;
  nan_surface.height = [](double x, double) { return x > 0.5 ? std::nan("") : 0.0; };
  EXPECT_NE(msg([&] {
              ZMap({0.0, 1.0, 0.0, 1.0, 0.1}, nan_surface);
            }).find("not finite"),
            std::string::npos);
  ZMap map({0.0, 1.0, 0.0, 1.0, 0.1}, {});
  BallEndMill no_teeth;
  no_teeth.teeth = 0;
  EXPECT_NE(msg([&] { simulate(map, no_teeth, {}); }).find("teeth = 0"), std::string::npos);
  Move back;
  back.t0_s = 1.0;
  back.t1_s = 0.5;
  EXPECT_NE(msg([&] { simulate(map, BallEndMill{}, {back}); }).find("time order"),
            std::string::npos);
  Move forever;
  forever.from_mm = forever.to_mm = Vec3(0.5, 0.5, -0.01);
  forever.t1_s = 1e9;  // a billion seconds of spindle turns
  EXPECT_NE(msg([&] { simulate(map, BallEndMill{}, {forever}); }).find("shorter stretch"),
            std::string::npos);
  Move inf;
  inf.to_mm.x() = std::numeric_limits<double>::infinity();
  EXPECT_NE(msg([&] { simulate(map, BallEndMill{}, {inf}); }).find("not finite"),
            std::string::npos);
  RasterSpec wide;
  wide.pick_feed_mm = 10.0;
  EXPECT_NE(msg([&] { make_raster(wide, BallEndMill{}); }).find("diameter"), std::string::npos);
  std::istringstream no_header("1,2,3,4\n");
  EXPECT_NE(msg([&] { read_setpoints_csv(no_header, "a.csv", BallEndMill{}); }).find("a.csv:1"),
            std::string::npos);
  std::istringstream backwards("t_s,x_mm,y_mm,z_mm\n0.1,0,0,0\n0.05,1,0,0\n");
  EXPECT_NE(msg([&] { read_setpoints_csv(backwards, "b.csv", BallEndMill{}); }).find("b.csv:3"),
            std::string::npos);
  std::istringstream garbage("t_s,x_mm,y_mm,z_mm\n0,0,0,0\n0.1,x,0,0\n");
  EXPECT_NE(msg([&] { read_setpoints_csv(garbage, "c.csv", BallEndMill{}); }).find("c.csv:3"),
            std::string::npos);
  std::istringstream one_row("t_s,x_mm,y_mm,z_mm\n0,0,0,0\n");
  EXPECT_NE(
      msg([&] { read_setpoints_csv(one_row, "d.csv", BallEndMill{}); }).find("fewer than two"),
      std::string::npos);
  EXPECT_NE(msg([&] { measure(map, Plane{}, {0, 0, 0, 5}); }).find("empty"), std::string::npos);
}

}  // namespace
}  // namespace ncd::surface
