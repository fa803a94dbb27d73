// Corner blending under G64 P (docs/planner.md §3a), checked against references written here:
//   - the exact distance of every setpoint (and of the walked geometry, densely sampled) from
//     the programmed polyline, by brute force over all its pieces: at most P;
//   - the arc's radius in closed form, R = P / (1 − cos(φ/2)), against the curvature
//     of the walked geometry;
//   - a phase-plane bound built from that closed-form geometry (lines at the feed, arcs at the
//     speed their curve laws allow, tangential acceleration only): ncd is never faster;
//   - the same program under G61.1 (exact stop): G64 P is never slower, and faster where the
//     corners are gentle enough or P large enough.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "feed/feed_limits.hpp"
#include "motion/job.hpp"
#include "tests/motion/planner_machine.hpp"
#include "tests/motion/reference.hpp"

namespace ncd::motion {
namespace {

using toolpath::NurbsCurve;
using toolpath::Path;
using toolpath::PathControl;
using toolpath::PathSegment;
using toolpath::Polyline;

constexpr double kT = 0.004, kA = 1000.0, kJ = 20000.0, kEps = 0.001;

PathSegment move(std::vector<Vec3> pts, double f_mm_per_min, std::optional<double> p_mm,
                 PathControl mode = PathControl::blend) {
  PathSegment s;
  s.geometry = Polyline{std::move(pts), {}};
  s.feed_mm_per_min = f_mm_per_min;
  s.path_control = mode;
  s.blend_tolerance_mm = p_mm;
  return s;
}

// The exact distance from q to the programmed polyline (every piece of every segment).
double distance_to_program(const std::vector<Vec3>& pts, const Vec3& q) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i + 1 < pts.size(); ++i) {
    best = std::min(best, test::distance_to_segment(q, pts[i], pts[i + 1]));
  }
  return best;
}

struct BlendWalk {
  std::vector<Setpoint> sp;
  double duration_s = 0.0;
  std::size_t blended = 0;
  Path walked;
};

BlendWalk run(const Path& path, const JobConfig& config = test::planner_machine()) {
  Job job(path, config);
  BlendWalk r;
  while (!job.done()) {
    job.prepare();
    r.sp.push_back(job.step());
    if (r.sp.size() > 2'000'000) break;
  }
  r.duration_s = r.sp.back().t_s;
  r.blended = job.blend_report().corners;
  r.walked = job.path();
  return r;
}

Path with_mode(Path p, PathControl mode) {
  for (auto& s : p.segments) s.path_control = mode;
  return p;
}

// Largest distance of the walked geometry, sampled every ~1 µm, from the programmed polyline,
// the largest curvature met on it, and (if asked) how far it passes from the programmed end
// point it passes farthest from (the inner vertices: the ends are walked exactly).
void sample_walked(const Path& walked, const std::vector<Vec3>& program, double& max_dev_mm,
                   double& max_kappa, double* max_vertex_mm = nullptr) {
  max_dev_mm = 0.0;
  max_kappa = 0.0;
  // The distance from a vertex is sharply curved near the apex: the nearest sample's u is
  // refined by a ternary search over its two neighbouring intervals.
  std::vector<double> vertex(program.size(), std::numeric_limits<double>::infinity());
  std::vector<double> vertex_u(program.size(), 0.0);
  std::vector<const NurbsCurve*> vertex_curve(program.size(), nullptr);
  const NurbsCurve* curve = nullptr;
  double u_at = 0.0;
  const auto near_vertices = [&](const Vec3& q) {
    for (std::size_t v = 1; v + 1 < program.size(); ++v) {
      const double d = (q - program[v]).norm();
      if (d < vertex[v]) vertex[v] = d, vertex_u[v] = u_at, vertex_curve[v] = curve;
    }
  };
  double du = 0.0;
  for (const auto& seg : walked.segments) {
    if (const auto* line = std::get_if<Polyline>(&seg.geometry)) {
      curve = nullptr;
      for (const auto& q : line->points) {
        max_dev_mm = std::max(max_dev_mm, distance_to_program(program, q));
        near_vertices(q);
      }
      continue;
    }
    const auto& c = std::get<NurbsCurve>(seg.geometry);
    // Every ~1 µm: u runs over the control polygon's length at most (the knots may be scaled).
    double polygon_mm = 0.0;
    for (std::size_t i = 1; i < c.points().size(); ++i) {
      polygon_mm += (c.points()[i] - c.points()[i - 1]).norm();
    }
    const int n = static_cast<int>(polygon_mm / 0.001) + 100;
    curve = &c;
    du = (c.u_end() - c.u_begin()) / n;
    for (int i = 0; i <= n; ++i) {
      u_at = c.u_begin() + (c.u_end() - c.u_begin()) * i / n;
      const auto p = c.eval(u_at);
      max_dev_mm = std::max(max_dev_mm, distance_to_program(program, p.p));
      max_kappa = std::max(max_kappa, p.d1.cross(p.d2).norm() / std::pow(p.d1.norm(), 3));
      near_vertices(p.p);
    }
  }
  if (max_vertex_mm) {
    *max_vertex_mm = 0.0;
    for (std::size_t v = 1; v + 1 < program.size(); ++v) {
      if (!vertex_curve[v]) continue;
      const NurbsCurve& c = *vertex_curve[v];
      const auto dist = [&](double u) { return (c.eval(u).p - program[v]).norm(); };
      double lo = std::max(c.u_begin(), vertex_u[v] - du);
      double hi = std::min(c.u_end(), vertex_u[v] + du);
      for (int k = 0; k < 100; ++k) {
        const double a = lo + (hi - lo) / 3.0, b = hi - (hi - lo) / 3.0;
        (dist(a) < dist(b) ? hi : lo) = dist(a) < dist(b) ? b : a;
      }
      vertex[v] = std::min(vertex[v], dist(0.5 * (lo + hi)));
    }
    for (std::size_t v = 1; v + 1 < program.size(); ++v) {
      *max_vertex_mm = std::max(*max_vertex_mm, vertex[v]);
    }
  }
}

// The arc of a corner turning by phi within p, in closed form, and the speed its curve laws
// allow (centripetal acceleration and jerk, chord error of one period, the feed).
// The midpoint lies R (1 − cos(φ/2)) / cos(φ/2) from the vertex: P less the chord tolerance.
double arc_radius_mm(double phi, double p_mm) {
  return (p_mm - kEps) * std::cos(0.5 * phi) / (1.0 - std::cos(0.5 * phi));
}
double arc_speed(double r_mm, double feed) {
  const double chord = 2.0 * std::sqrt(2.0 * r_mm * kEps - kEps * kEps) / kT;
  return std::min({feed, std::sqrt(kA * r_mm), std::cbrt(kJ * r_mm * r_mm), chord});
}

// Phase-plane bound (tangential acceleration only) over pieces (length, constant limit),
// from rest to rest.
double phase_plane_s(const std::vector<std::pair<double, double>>& pieces) {
  std::vector<double> s{0.0}, v{0.0};
  for (const auto& [len, lim] : pieces) {
    const int n = std::max(4, static_cast<int>(len / 0.0005));
    for (int i = 1; i <= n; ++i) {
      s.push_back(s.back() + len / n);
      v.push_back(lim);
    }
    // The node at a piece's start takes the lower limit of the two pieces.
    const std::size_t first = s.size() - static_cast<std::size_t>(n) - 1;
    v[first] = std::min(v[first], lim);
  }
  v.back() = 0.0;
  const std::size_t m = s.size();
  for (std::size_t i = 1; i < m; ++i) {
    v[i] = std::min(v[i], std::sqrt(v[i - 1] * v[i - 1] + 2 * kA * (s[i] - s[i - 1])));
  }
  for (std::size_t i = m - 1; i-- > 0;) {
    v[i] = std::min(v[i], std::sqrt(v[i + 1] * v[i + 1] + 2 * kA * (s[i + 1] - s[i])));
  }
  double t = 0.0;
  for (std::size_t i = 0; i + 1 < m; ++i) t += 2.0 * (s[i + 1] - s[i]) / (v[i] + v[i + 1]);
  return t;
}

// Jerk-limited S-curve estimate over the same pieces: each line from the speed of the piece
// before to that of the piece after (0 at the path ends), rising towards its limit and
// returning with a = 0 at both ends (closed form, peak by bisection); each arc at its constant
// limit. Not a strict lower bound (a motion may enter an arc with a != 0), but the time the
// jerk limit adds to the phase-plane bound.
double scurve_pieces_s(const std::vector<std::pair<double, double>>& pieces) {
  const auto ramp_t = [](double dv) {
    return dv >= kA * kA / kJ ? dv / kA + kA / kJ : 2.0 * std::sqrt(std::max(dv, 0.0) / kJ);
  };
  double t = 0.0;
  for (std::size_t i = 0; i < pieces.size(); ++i) {
    const auto [len, lim] = pieces[i];
    const bool arc = i % 2 == 1;
    if (arc) {
      t += len / lim;
      continue;
    }
    const double w0 = i > 0 ? pieces[i - 1].second : 0.0;
    const double w1 = i + 1 < pieces.size() ? pieces[i + 1].second : 0.0;
    const auto dist = [&](double peak) {
      return 0.5 * (w0 + peak) * ramp_t(peak - w0) + 0.5 * (peak + w1) * ramp_t(peak - w1);
    };
    double peak = lim;
    if (dist(lim) > len) {
      double lo = std::max(w0, w1), hi = lim;
      for (int k = 0; k < 200; ++k) (dist(0.5 * (lo + hi)) < len ? lo : hi) = 0.5 * (lo + hi);
      peak = 0.5 * (lo + hi);
    }
    t += ramp_t(peak - w0) + ramp_t(peak - w1) + std::max(len - dist(peak), 0.0) / peak;
  }
  return t;
}

// A zig-zag of `legs` legs of `leg` mm, turning by ±phi at each vertex.
std::vector<Vec3> zigzag(int legs, double leg, double phi) {
  std::vector<Vec3> pts{{0, 0, 0}};
  for (int i = 0; i < legs; ++i) {
    const double ang = (i % 2 ? -0.5 : 0.5) * phi;
    pts.push_back(pts.back() + leg * Vec3(std::cos(ang), std::sin(ang), 0.0));
  }
  return pts;
}

TEST(Blend, GentleZigZagStaysWithinPAndBeatsExactStopAndTheSharpCorner) {
  const double phi = 30.0 * M_PI / 180.0, p_mm = 0.01, leg = 10.0, feed = 100.0;
  const std::vector<Vec3> pts = zigzag(12, leg, phi);
  Path path;
  path.segments.push_back(move(pts, 60.0 * feed, p_mm));
  const BlendWalk g64 = run(path);
  EXPECT_EQ(g64.blended, 11U);
  double worst = 0.0;
  for (const auto& sp : g64.sp) worst = std::max(worst, distance_to_program(pts, sp.p));
  EXPECT_LE(worst, p_mm * (1.0 + 1e-9));
  double dev = 0.0, kappa = 0.0, vertex = 0.0;
  sample_walked(g64.walked, pts, dev, kappa, &vertex);
  // Every programmed end point is passed within P: by P less the chord tolerance, no less (a
  // chord between setpoints on the arc lies up to the chord tolerance farther).
  EXPECT_LE(vertex, p_mm - kEps + 1e-9);
  EXPECT_GE(vertex, 0.999 * (p_mm - kEps));
  EXPECT_LE(dev, (p_mm - kEps) * std::cos(0.5 * phi) + 1e-9);  // off the pieces: cos(φ/2) less
  const double r_mm = arc_radius_mm(phi, p_mm);
  EXPECT_NEAR(kappa, 1.0 / r_mm, 1e-6 / r_mm);
  EXPECT_LT((g64.sp.back().p - pts.back()).norm(), 1e-9);
  // Bound: lines at the feed, arcs at their closed-form speed.
  const double v_arc = arc_speed(r_mm, feed), tangent = r_mm * std::tan(0.5 * phi);
  std::vector<std::pair<double, double>> pieces;
  for (int i = 0; i < 12; ++i) {
    pieces.push_back({leg - (i > 0 ? tangent : 0.0) - (i < 11 ? tangent : 0.0), feed});
    if (i < 11) pieces.push_back({r_mm * phi, v_arc});
  }
  const double bound = phase_plane_s(pieces), estimate = scurve_pieces_s(pieces);
  const BlendWalk stop = run(with_mode(path, PathControl::exact_stop));
  Path sharp = path;
  sharp.segments[0].blend_tolerance_mm = 0.0;  // G64 P0: no rounding
  const BlendWalk p0 = run(sharp);
  std::printf(
      "zig-zag 30 deg 10 mm, G64 P0.01: %.3f s (%zu corners, deviation %.5f mm, arc %.2f "
      "mm/s); phase-plane bound %.3f s (ratio %.3f), S-curve estimate %.3f s (ratio "
      "%.3f); G61.1 %.3f s; G64 P0 %.3f s\n",
      g64.duration_s, g64.blended, dev, v_arc, bound, g64.duration_s / bound, estimate,
      g64.duration_s / estimate, stop.duration_s, p0.duration_s);
  EXPECT_GE(g64.duration_s, bound);
  // 2.960 s against 2.885 and 3.120 (docs/planner.md §3a; 3.040 s with guards of a whole
  // period's travel beside the arcs).
  EXPECT_LE(g64.duration_s, 1.05 * estimate);
  EXPECT_LT(g64.duration_s, 0.97 * stop.duration_s);
  EXPECT_LT(g64.duration_s, p0.duration_s);
  // Through every corner the speed reaches the arc's speed and never exceeds it on the arc.
  double v_min_arc = std::numeric_limits<double>::infinity();
  int on_arcs = 0;
  for (std::size_t i = 1; i < g64.sp.size(); ++i) {
    const Vec3& q = g64.sp[i].p;
    for (int k = 1; k < 12; ++k) {
      // On the arc: closer to the vertex than its tangent points, R tan(φ/2) away (the arc's
      // midpoint is P / cos(φ/2) from it; the lines beside the arc are farther than R tan(φ/2)).
      if ((q - pts[static_cast<std::size_t>(k)]).norm() < tangent) {
        EXPECT_LE(g64.sp[i].v_mm_per_s, v_arc * (1.0 + 1e-6));
        v_min_arc = std::min(v_min_arc, g64.sp[i].v_mm_per_s);
        ++on_arcs;
      }
    }
  }
  EXPECT_GE(on_arcs, 11);  // every arc is crossed by at least one setpoint (0.15 mm at 12 mm/s)
  EXPECT_GE(v_min_arc, 0.5 * v_arc);
}

// A plain G64 (no P) takes the machine file's blend_tolerance_mm; 0 there keeps the corners.
TEST(Blend, PlainG64TakesTheMachinesBlendTolerance) {
  // 30° turns, 10 mm legs: gentle enough to be rounded at 0.01 mm (as the test above).
  const std::vector<Vec3> pts = zigzag(12, 10.0, 30.0 * M_PI / 180.0);
  Path path;
  path.segments.push_back(move(pts, 6000.0, std::nullopt));
  for (const double tol_mm : {0.01, 0.05, 0.0}) {
    JobConfig c = test::planner_machine();
    c.limits.blend_tolerance_mm = tol_mm;
    const BlendWalk w = run(path, c);
    double dev = 0.0, kappa = 0.0, vertex = 0.0;
    sample_walked(w.walked, pts, dev, kappa, &vertex);
    for (const Setpoint& sp : w.sp) dev = std::max(dev, distance_to_program(pts, sp.p));
    std::printf(
        "plain G64, blend_tolerance_mm %.2f: %zu corners rounded, deviation %.5f mm, end "
        "points passed %.5f mm away at most\n",
        tol_mm, w.blended, dev, vertex);
    EXPECT_LE(dev, tol_mm + 1e-9);
    EXPECT_LE(vertex, tol_mm + 1e-9);
    if (tol_mm > 0.0) {
      EXPECT_EQ(w.blended, 11u);
      EXPECT_GE(vertex, 0.999 * (tol_mm - kEps));  // rounded by the whole tolerance, as G64 P
    } else {
      EXPECT_EQ(w.blended, 0u);
    }
    EXPECT_LT((w.sp.back().p - pts.back()).norm(), 1e-9);
  }
}

// G61, G61.1 and G64 P0 (and a plain G64 with blend_tolerance_mm 0) hold every programmed end
// point exactly: a setpoint lands on it, gentle corners included (passed at the sampler's corner
// speed they would be missed by up to the chord tolerance). G64 P0.01 passes them within P.
TEST(Blend, ExactModesAndP0HoldEveryEndPointExactly) {
  const std::vector<Vec3> pts{{0, 0, 0}, {10, 0, 0}, {20, 1, 0}, {30, 1.5, 0}, {40, 4, 0}};
  const auto nearest = [&](const std::vector<Setpoint>& sp, const Vec3& v) {
    double d = v.norm();  // the start, before the first period
    Vec3 before = Vec3::Zero();
    for (const Setpoint& x : sp) {
      d = std::min(d, test::distance_to_segment(v, before, x.p));
      before = x.p;
    }
    return d;
  };
  const auto on_a_setpoint = [&](const std::vector<Setpoint>& sp, const Vec3& v) {
    return std::any_of(sp.begin(), sp.end(),
                       [&](const Setpoint& x) { return (x.p - v).norm() <= 1e-9; });
  };
  struct Case {
    const char* name;
    PathControl mode;
    std::optional<double> p_mm;
    double machine_tolerance_mm;
  };
  for (const Case& c : {Case{"G61", PathControl::exact_stop, std::nullopt, 0.01},
                        Case{"G61.1", PathControl::exact_path, std::nullopt, 0.01},
                        Case{"G64 P0", PathControl::blend, 0.0, 0.01},
                        Case{"G64, blend_tolerance_mm 0", PathControl::blend, std::nullopt, 0.0},
                        Case{"G64 P0.01", PathControl::blend, 0.01, 0.01}}) {
    Path path;
    path.segments.push_back(move(pts, 3000.0, c.p_mm, c.mode));
    JobConfig config = test::planner_machine();
    config.limits.blend_tolerance_mm = c.machine_tolerance_mm;
    const BlendWalk w = run(path, config);
    double worst = 0.0;
    bool exact = true;
    for (std::size_t v = 1; v + 1 < pts.size(); ++v) {
      worst = std::max(worst, nearest(w.sp, pts[v]));
      exact = exact && on_a_setpoint(w.sp, pts[v]);
    }
    std::printf("%s: %.3f s, end points passed %.2g mm away at most, %s\n", c.name, w.duration_s,
                worst, exact ? "each on a setpoint" : "not all on a setpoint");
    if (c.p_mm.value_or(c.machine_tolerance_mm) > 0.0 && c.mode == PathControl::blend) {
      EXPECT_LE(worst, 0.01) << c.name;
      EXPECT_FALSE(exact) << c.name << ": the gentle corners are passed, not stopped at";
    } else {
      EXPECT_TRUE(exact) << c.name;
    }
  }
}

TEST(Blend, LargeToleranceRoundsTheSquareFasterThanExactStop) {
  const std::vector<Vec3> pts{{0, 0, 0}, {10, 0, 0}, {10, 10, 0}, {0, 10, 0}, {0, 0, 0}};
  Path path;
  path.segments.push_back(move(pts, 6000.0, 0.5));
  const BlendWalk g64 = run(path);
  EXPECT_EQ(g64.blended, 3U);
  double worst = 0.0;
  for (const auto& sp : g64.sp) worst = std::max(worst, distance_to_program(pts, sp.p));
  EXPECT_LE(worst, 0.5 * (1.0 + 1e-9));
  const BlendWalk stop = run(with_mode(path, PathControl::exact_stop));
  const double r_mm = arc_radius_mm(0.5 * M_PI, 0.5), tangent = r_mm;
  const double v_arc = arc_speed(r_mm, 100.0);
  std::vector<std::pair<double, double>> pieces;
  for (int i = 0; i < 4; ++i) {
    pieces.push_back({10.0 - (i > 0 ? tangent : 0.0) - (i < 3 ? tangent : 0.0), 100.0});
    if (i < 3) pieces.push_back({r_mm * 0.5 * M_PI, v_arc});
  }
  const double bound = phase_plane_s(pieces), estimate = scurve_pieces_s(pieces);
  std::printf(
      "square 10 mm, G64 P0.5: %.3f s (max deviation %.4f mm); phase-plane bound %.3f s "
      "(ratio %.3f), S-curve estimate %.3f s (ratio %.3f); G61.1 %.3f s\n",
      g64.duration_s, worst, bound, g64.duration_s / bound, estimate, g64.duration_s / estimate,
      stop.duration_s);
  EXPECT_GE(g64.duration_s, bound);
  EXPECT_LE(g64.duration_s, 1.05 * estimate);
  EXPECT_LT(g64.duration_s, stop.duration_s - kT);
}

TEST(Blend, SharpCornersWithASmallToleranceStopRatherThanCrawl) {
  // At P0.01 a 90° arc allows 2.3 mm/s: crossing it costs more than stopping, so the square
  // keeps its exact stops (never slower than G61.1).
  const std::vector<Vec3> pts{{0, 0, 0}, {10, 0, 0}, {10, 10, 0}, {0, 10, 0}, {0, 0, 0}};
  Path path;
  path.segments.push_back(move(pts, 6000.0, 0.01));
  const BlendWalk g64 = run(path);
  const BlendWalk stop = run(with_mode(path, PathControl::exact_stop));
  EXPECT_EQ(g64.blended, 0U);
  EXPECT_LE(g64.duration_s, stop.duration_s + 1e-9);
}

TEST(Blend, ReversalAndExactPathAreNeverRounded) {
  Path rev;
  rev.segments.push_back(move({{0, 0, 0}, {10, 0, 0}, {3, 0.0, 0}}, 3000.0, 1.0));
  const BlendWalk r = run(rev);
  EXPECT_EQ(r.blended, 0U);
  bool at_turn = false;
  for (const auto& sp : r.sp) {
    at_turn |= sp.v_mm_per_s == 0.0 && (sp.p - Vec3(10, 0, 0)).norm() < 1e-9;
  }
  EXPECT_TRUE(at_turn);
  const std::vector<Vec3> pts = zigzag(6, 10.0, 30.0 * M_PI / 180.0);
  Path g61;
  g61.segments.push_back(move(pts, 6000.0, 0.5, PathControl::exact_path));
  const BlendWalk e = run(g61);
  EXPECT_EQ(e.blended, 0U);
  for (const auto& sp : e.sp) ASSERT_LE(distance_to_program(pts, sp.p), 1e-9);
}

TEST(Blend, JointBetweenMovesKeepsTheSegmentsAndTheirFeeds) {
  // Two G1 moves at different feeds meeting at 45°: the arc belongs to the first move.
  const std::vector<Vec3> pts{{0, 0, 0}, {20, 0, 0}, {20 + 10 * M_SQRT1_2, 10 * M_SQRT1_2, 0}};
  Path path;
  path.segments.push_back(move({pts[0], pts[1]}, 6000.0, 0.05));
  path.segments.push_back(move({pts[1], pts[2]}, 1200.0, 0.05));
  Job job(path, test::planner_machine());
  ASSERT_EQ(job.path().segments.size(), 2U);
  EXPECT_EQ(job.blend_report().corners, 1U);
  EXPECT_TRUE(std::holds_alternative<NurbsCurve>(job.path().segments[0].geometry));
  EXPECT_TRUE(std::holds_alternative<Polyline>(job.path().segments[1].geometry));
  double worst = 0.0, v_max_second = 0.0;
  Vec3 last = Vec3::Zero();
  while (!job.done()) {
    job.prepare();
    const Setpoint sp = job.step();
    worst = std::max(worst, distance_to_program(pts, sp.p));
    if (job.walker().segment() == 1) v_max_second = std::max(v_max_second, sp.v_mm_per_s);
    last = sp.p;
  }
  EXPECT_LE(worst, 0.05 * (1.0 + 1e-9));
  EXPECT_LE(v_max_second, 20.0 * (1.0 + 1e-9));
  EXPECT_LT((last - pts[2]).norm(), 1e-9);
}

}  // namespace
}  // namespace ncd::motion
