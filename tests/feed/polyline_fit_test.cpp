// The smoothing of dense polylines under G64 Q (feed/polyline_fit.cpp) against a slow
// reference written here: the two-sided distance between the fitted curve and the programmed
// polyline by brute force (every curve sample against every piece, every polyline sample
// against every curve sample), with the curve evaluated by Cox–de Boor recursion (not the
// library's algorithm). Random sweeps print their seed.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "feed/polyline_fit.hpp"
#include "tests/common/sanitized.hpp"
#include "tests/common/seed.hpp"
#include "tests/motion/reference.hpp"

namespace ncd::feed {
namespace {

using toolpath::NurbsCurve;
using toolpath::Path;
using toolpath::PathSegment;
using toolpath::Polyline;

double to_piece(const Vec3& x, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double l2 = ab.squaredNorm();
  const double t = l2 > 0.0 ? std::clamp((x - a).dot(ab) / l2, 0.0, 1.0) : 0.0;
  return (x - (a + t * ab)).norm();
}

// Brute-force two-sided distance: curve samples every `du` against every piece; polyline
// samples every `du` along each piece against every curve sample (an upper bound of the
// distance to the curve, larger by at most half a sample spacing).
double brute_deviation_mm(const NurbsCurve& c, const std::vector<Vec3>& pts, double du) {
  std::vector<Vec3> cs;
  const double u0 = c.u_begin(), u1 = c.u_end();
  const auto n = static_cast<int>(std::ceil((u1 - u0) / du));
  for (int i = 0; i <= n; ++i)
    cs.push_back(test::nurbs_point(c, i == n ? u1 : u0 + (u1 - u0) * i / n));
  double worst = 0.0;
  for (const Vec3& x : cs) {
    double best = 1e300;
    for (std::size_t k = 0; k + 1 < pts.size(); ++k)
      best = std::min(best, to_piece(x, pts[k], pts[k + 1]));
    worst = std::max(worst, best);
  }
  for (std::size_t k = 0; k + 1 < pts.size(); ++k) {
    const double len = (pts[k + 1] - pts[k]).norm();
    const int m = std::max(1, static_cast<int>(std::ceil(len / du)));
    for (int q = 0; q <= m; ++q) {
      const Vec3 y = pts[k] + (static_cast<double>(q) / m) * (pts[k + 1] - pts[k]);
      double best = 1e300;
      for (const Vec3& x : cs) best = std::min(best, (x - y).norm());
      worst = std::max(worst, best);
    }
  }
  return worst;
}

// The fit of `pts` within q: ends exactly at the polyline's ends, proven deviation ≤ q, and the
// brute-force deviation (less its sampling slack) below the proven one.
void expect_fit(const std::vector<Vec3>& pts, double q, const std::string& what) {
  const auto fit = fit_polyline_run(pts, q);
  ASSERT_TRUE(fit.has_value()) << what;
  const NurbsCurve& c = fit->curve;
  EXPECT_EQ(c.degree(), 3) << what;
  EXPECT_EQ(c.eval(c.u_begin()).p, pts.front()) << what;
  EXPECT_EQ(c.eval(c.u_end()).p, pts.back()) << what;
  EXPECT_LE(fit->deviation_mm, q) << what;
  const double du = q / 10.0;
  const double brute = brute_deviation_mm(c, pts, du);
  EXPECT_LE(brute, q + du) << what;
  EXPECT_LE(brute - du, fit->deviation_mm) << what << " (the proven bound is below the truth)";
}

// A gentle random curve: a circle arc of radius 20–200 mm plus a slow sine, in 3D.
struct Gentle {
  double r, amp, wave;
  Vec3 at(double s) const {
    const double phi = s / r;
    return {r * std::sin(phi), r * (1.0 - std::cos(phi)), amp * std::sin(s / wave)};
  }
};

TEST(PolylineFit, RandomGentleCurvesWithNoiseFitWithinTheTolerance) {
  const std::uint64_t seed = test::seed();
  std::mt19937_64 rng(seed);
  const auto uni = [&](double a, double b) {
    return std::uniform_real_distribution<double>(a, b)(rng);
  };
  const int cases = test::sweep_cases(12);
  for (int k = 0; k < cases; ++k) {
    const Gentle g{uni(20.0, 200.0), uni(0.0, 2.0), uni(5.0, 20.0)};
    const double q = uni(0.002, 0.05), step = uni(0.005, 0.05), noise = uni(0.0, 0.4) * q;
    const int n = 50 + static_cast<int>(rng() % 200);
    std::vector<Vec3> pts;
    for (int i = 0; i <= n; ++i) {
      Vec3 p = g.at(step * i);
      if (i > 0 && i < n) p += noise * Vec3(uni(-1, 1), uni(-1, 1), uni(-1, 1)) / std::sqrt(3.0);
      pts.push_back(p);
    }
    expect_fit(pts, q, "case " + std::to_string(k) + " of seed " + std::to_string(seed));
    if (HasFailure()) break;
  }
}

TEST(PolylineFit, DegenerateInputs) {
  // Two points: the straight line itself.
  {
    const std::vector<Vec3> pts{{0, 0, 0}, {1, 2, 3}};
    expect_fit(pts, 0.01, "two points");
    const auto fit = fit_polyline_run(pts, 0.01);
    ASSERT_TRUE(fit);
    for (int i = 0; i <= 100; ++i) {  // on the line itself (the proven bound has its slack)
      const double u = fit->curve.u_begin() + (fit->curve.u_end() - fit->curve.u_begin()) * i / 100;
      EXPECT_LT(to_piece(test::nurbs_point(fit->curve, u), pts[0], pts[1]), 1e-12);
    }
  }
  // Collinear, unevenly spaced, with duplicates.
  {
    std::vector<Vec3> pts;
    for (const double x : {0.0, 0.01, 0.01, 0.05, 0.06, 0.06, 0.06, 0.3, 0.31, 1.0}) {
      pts.emplace_back(x, 2 * x, 0);
    }
    expect_fit(pts, 0.005, "collinear with duplicates");
  }
  // All points equal, or fewer than two: no curve.
  EXPECT_FALSE(fit_polyline_run({{1, 1, 1}, {1, 1, 1}, {1, 1, 1}}, 0.01));
  EXPECT_FALSE(fit_polyline_run({{1, 1, 1}}, 0.01));
  EXPECT_FALSE(fit_polyline_run({}, 0.01));
  // Bad tolerances and points: no curve (never a NaN).
  EXPECT_FALSE(fit_polyline_run({{0, 0, 0}, {1, 0, 0}}, 0.0));
  EXPECT_FALSE(fit_polyline_run({{0, 0, 0}, {1, 0, 0}}, std::nan("")));
  EXPECT_FALSE(fit_polyline_run({{0, 0, 0}, {std::nan(""), 0, 0}}, 0.01));
  // A reversal: out 1 mm and back in 0.01 mm moves. Any curve the fit returns is within the
  // tolerance both ways (the tip of the spike is not skipped).
  {
    std::vector<Vec3> pts;
    for (int i = 0; i <= 100; ++i) pts.emplace_back(0.01 * i, 0, 0);
    for (int i = 99; i >= 0; --i) pts.emplace_back(0.01 * i, 0, 0);
    const auto fit = fit_polyline_run(pts, 0.01);
    if (fit) {
      EXPECT_LE(brute_deviation_mm(fit->curve, pts, 0.0005), 0.01 + 0.0005);
      EXPECT_NEAR(fit->curve.eval(0.5 * (fit->curve.u_begin() + fit->curve.u_end())).p.x(), 1.0,
                  0.0105);
    }
  }
}

PathSegment dense_segment(std::vector<Vec3> pts, double q_mm) {
  PathSegment s;
  s.geometry = Polyline{std::move(pts), {}};
  s.feed_mm_per_min = 3000.0;
  s.source_line = 7;
  s.blend_tolerance_mm = 0.01;
  s.smoothing_tolerance_mm = q_mm;
  return s;
}

// A real corner in the middle of a dense run (random angle 40–150°, noise below Q): the run is
// split there, the corner vertex is kept exactly, every part keeps the source line, and each
// fitted part is within Q of its own stretch of the polyline.
TEST(PolylineFit, RealCornerSplitsTheRun) {
  const std::uint64_t seed = test::seed();
  std::mt19937_64 rng(seed);
  const auto uni = [&](double a, double b) {
    return std::uniform_real_distribution<double>(a, b)(rng);
  };
  const int cases = test::sweep_cases(8);
  for (int k = 0; k < cases; ++k) {
    const std::string what = "case " + std::to_string(k) + " of seed " + std::to_string(seed);
    const double q = uni(0.005, 0.02), step = uni(0.005, 0.05), noise = uni(0.0, 0.3) * q;
    const double turn = deg_to_rad(uni(40.0, 150.0));
    const Vec3 d_in(1, 0, 0), d_out(std::cos(turn), std::sin(turn), 0);
    const int n = 60 + static_cast<int>(rng() % 100);
    std::vector<Vec3> pts;
    const Vec3 corner = n * step * d_in;
    for (int i = 0; i <= 2 * n; ++i) {
      Vec3 p = i <= n ? Vec3(i * step * d_in) : Vec3(corner + (i - n) * step * d_out);
      // gentle bow on each side, noise everywhere but at the ends and the corner
      const double x = i <= n ? i * step : (i - n) * step;
      p += 0.5 * std::sin(kPi * x / (n * step)) * Vec3(0, 0, 1);
      if (i != 0 && i != n && i != 2 * n) {
        p += noise * Vec3(uni(-1, 1), uni(-1, 1), uni(-1, 1)) / std::sqrt(3.0);
      }
      pts.push_back(p);
    }
    Path path;
    path.segments.push_back(dense_segment(pts, q));
    MachineLimits limits;
    FitReport rep;
    const Path out = fit_polylines(path, limits, &rep);
    ASSERT_EQ(rep.source_segment.size(), out.segments.size()) << what;
    ASSERT_GE(out.segments.size(), 2u) << what;
    EXPECT_GE(rep.runs, 2u) << what;
    bool corner_kept = false;
    std::size_t at = 0;  // index into pts of the current part's start
    for (std::size_t j = 0; j < out.segments.size(); ++j) {
      const PathSegment& s = out.segments[j];
      EXPECT_EQ(rep.source_segment[j], 0u) << what;
      EXPECT_EQ(s.source_line, 7) << what;
      EXPECT_EQ(s.feed_mm_per_min, 3000.0) << what;
      Vec3 first, last;
      if (const auto* l = std::get_if<Polyline>(&s.geometry)) {
        first = l->points.front();
        last = l->points.back();
      } else {
        const auto& c = std::get<NurbsCurve>(s.geometry);
        first = c.eval(c.u_begin()).p;
        last = c.eval(c.u_end()).p;
      }
      EXPECT_EQ(first, pts[at]) << what << " part " << j;
      std::size_t end = at + 1;
      while (end < pts.size() && pts[end] != last) ++end;
      ASSERT_LT(end, pts.size()) << what << ": part " << j << " does not end at a vertex";
      if (const auto* c = std::get_if<NurbsCurve>(&s.geometry)) {
        const std::vector<Vec3> stretch(pts.begin() + static_cast<std::ptrdiff_t>(at),
                                        pts.begin() + static_cast<std::ptrdiff_t>(end) + 1);
        EXPECT_LE(brute_deviation_mm(*c, stretch, q / 10.0), q * 1.1) << what << " part " << j;
      }
      if (end == static_cast<std::size_t>(n)) corner_kept = true;
      at = end;
    }
    EXPECT_EQ(at, pts.size() - 1) << what;
    EXPECT_TRUE(corner_kept) << what << ": the corner vertex is not a part boundary";
    EXPECT_LE(rep.max_deviation_mm, q) << what;
    if (HasFailure()) break;
  }
}

// Where the fit does not apply the path is copied: Q0, G61, a rapid, contact normals, long
// moves (every piece above the short-piece length), and without Q: G64 P0, P ≤ ε_c (no budget
// left after the chord tolerance) and a machine whose file says fit_dense_runs = false.
TEST(PolylineFit, IneligibleSegmentsAreCopied) {
  std::vector<Vec3> dense;
  for (int i = 0; i <= 200; ++i) dense.emplace_back(0.01 * i, 0.0001 * i * i, 0);
  std::vector<Vec3> longs;
  for (int i = 0; i <= 10; ++i) longs.emplace_back(5.0 * i, 0.01 * i * i, 0);
  MachineLimits limits;
  const auto copied = [&](PathSegment s, const char* what, const MachineLimits& l) {
    Path p;
    p.segments.push_back(s);
    FitReport rep;
    const Path out = fit_polylines(p, l, &rep);
    ASSERT_EQ(out.segments.size(), 1u) << what;
    EXPECT_EQ(rep.runs, 0u) << what;
    ASSERT_TRUE(std::holds_alternative<Polyline>(out.segments[0].geometry)) << what;
    EXPECT_EQ(std::get<Polyline>(out.segments[0].geometry).points,
              std::get<Polyline>(s.geometry).points)
        << what;
  };
  PathSegment s = dense_segment(dense, 0.01);
  s.smoothing_tolerance_mm = 0.0;
  copied(s, "Q0", limits);
  s.smoothing_tolerance_mm.reset();
  MachineLimits off = limits;
  off.fit_dense_runs = false;
  copied(s, "no Q, fit_dense_runs = false", off);
  s.blend_tolerance_mm = 0.0;
  copied(s, "no Q, G64 P0", limits);
  s.blend_tolerance_mm = limits.chord_tolerance_mm;
  copied(s, "no Q, G64 P = the chord tolerance (no budget)", limits);
  s.blend_tolerance_mm.reset();
  MachineLimits exact_corners = limits;
  exact_corners.blend_tolerance_mm = 0.0;
  copied(s, "plain G64 on a machine with blend_tolerance_mm = 0", exact_corners);
  s = dense_segment(dense, 0.01);
  s.path_control = toolpath::PathControl::exact_path;
  copied(s, "G61", limits);
  s.path_control = toolpath::PathControl::exact_stop;
  copied(s, "G61.1", limits);
  s = dense_segment(dense, 0.01);
  s.rapid = true;
  s.feed_mm_per_min.reset();
  copied(s, "G0", limits);
  s = dense_segment(dense, 0.01);
  std::get<Polyline>(s.geometry).normals.assign(dense.size(), Vec3(0, 0, 1));
  copied(s, "normals", limits);
  copied(dense_segment(longs, 0.01), "long moves", limits);
  // The same dense segment with Q, and without Q under G64 P0.01 or a plain G64 (the machine's
  // default fit): one curve, within Q, or within P − ε_c (docs/planner.md §3d), by the
  // brute-force distance of expect_fit.
  PathSegment plain = dense_segment(dense, 0.01);
  plain.smoothing_tolerance_mm.reset();
  plain.blend_tolerance_mm.reset();
  struct Case {
    PathSegment seg;
    double q_mm;
    const char* what;
  };
  PathSegment p_only = plain;
  p_only.blend_tolerance_mm = 0.004;
  for (const Case& c : {Case{dense_segment(dense, 0.01), 0.01, "Q0.01"},
                        Case{p_only, 0.004 - limits.chord_tolerance_mm, "G64 P0.004, no Q"},
                        Case{plain, limits.blend_tolerance_mm - limits.chord_tolerance_mm,
                             "plain G64 (the machine's P0.01)"}}) {
    Path p;
    p.segments.push_back(c.seg);
    FitReport rep;
    const Path out = fit_polylines(p, limits, &rep);
    ASSERT_EQ(out.segments.size(), 1u) << c.what;
    ASSERT_TRUE(std::holds_alternative<NurbsCurve>(out.segments[0].geometry)) << c.what;
    EXPECT_EQ(rep.runs, 1u) << c.what;
    EXPECT_EQ(rep.points, dense.size()) << c.what;
    EXPECT_LE(rep.max_deviation_mm, c.q_mm) << c.what;
    const double du = c.q_mm / 10.0;
    EXPECT_LE(brute_deviation_mm(std::get<NurbsCurve>(out.segments[0].geometry), dense, du),
              c.q_mm + du)
        << c.what;
  }
}

}  // namespace
}  // namespace ncd::feed
