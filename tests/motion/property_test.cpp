// Random programs walked end to end (seed printed; NCD_TEST_SEED replays one sweep,
// NCD_PROPERTY_PROGRAMS sets how many: 200 here, thousands under `make soak`). Each program
// (tests/common/random_program.hpp) mixes lines with reversals, zero-length and 1 µm moves,
// dense runs of 0.01 mm moves, NURBS of degree 1–5 (rational, repeated interior knots up to
// C¹), rapids, G61, G61.1, G64 (with and without P, P0 included; with and without Q: dense
// runs under G64 are rounded to 1 µm and fitted with a curve, within Q or within P − ε_c by
// the machine's default fit, docs/planner.md §3d) and stops before events. For every program,
// checked from the setpoints alone against the programmed geometry (tests/motion/reference.hpp):
//   - it ends at rest exactly at its end point;
//   - every setpoint lies on the walked geometry (nearest-point distance ≤ 1e-5 mm), and within
//     the active tolerance of the programmed geometry (G64 P; on a fitted dense run Q under
//     G64 Q, P − ε_c under G64 P or a plain G64), and every programmed vertex of a fitted run
//     within Q + ε_c, or P, of a chord between two setpoints;
//   - every period's chord stays within the chord tolerance of the geometry it spans;
//   - the speed |Δp|/T stays within the machine's maximum feed, and the planned speed within
//     the F word of the move holding the setpoint;
//     the tangential acceleration and jerk (differences of the planned s) within their limits;
//     the acceleration vector |Δ²p|/T² within √2 a_max (tangential and centripetal each ≤ a_max);
//   - no stall: never 2 s without 0.1 µm of progress.
// A sharp corner passed without its stop (docs/planner.md §3b) superposes the end of one move
// and the start of the next: those setpoints lie off the walked path, so they are held to the
// programmed geometry (within the move's P, chord midpoints too) and to the jerk vector
// (j_max under "vector", √2 j_max under "tangential") instead of the walked path and the
// differences of s, which sums the two moves' progress there.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <utility>

#include "motion/job.hpp"
#include "tests/common/random_program.hpp"
#include "tests/common/sanitized.hpp"
#include "tests/common/seed.hpp"
#include "tests/motion/planner_machine.hpp"
#include "tests/motion/reference.hpp"

namespace ncd::motion {
namespace {

using toolpath::NurbsCurve;
using toolpath::Path;
using toolpath::PathControl;
using toolpath::PathSegment;
using toolpath::Polyline;

Vec3 end_point(const Path& p) {
  const auto& g = p.segments.back().geometry;
  if (const auto* l = std::get_if<Polyline>(&g)) return l->points.back();
  const auto& c = std::get<NurbsCurve>(g);
  return c.eval(c.u_end()).p;
}

// The program as text, for a failure's message.
std::string describe(const Path& path) {
  std::ostringstream o;
  o.precision(17);
  for (const auto& seg : path.segments) {
    if (const auto* l = std::get_if<Polyline>(&seg.geometry)) {
      o << "polyline";
      for (const auto& q : l->points) o << " (" << q.x() << "," << q.y() << "," << q.z() << ")";
    } else {
      const auto& c = std::get<NurbsCurve>(seg.geometry);
      o << "nurbs p" << c.degree() << " knots";
      for (const double k : c.knots()) o << " " << k;
      o << " points";
      for (const auto& q : c.points()) o << " (" << q.x() << "," << q.y() << "," << q.z() << ")";
      o << " weights";
      for (const double w : c.weights()) o << " " << w;
    }
    o << " control " << static_cast<int>(seg.path_control) << " stop_before " << seg.stop_before
      << " rapid " << seg.rapid << " P " << seg.blend_tolerance_mm.value_or(-1) << " Q "
      << seg.smoothing_tolerance_mm.value_or(-1) << " F " << seg.feed_mm_per_min.value_or(-1)
      << "\n";
  }
  return o.str();
}

// Corners passed without their stops over the programs checked (printed by the random tests).
std::size_t g_overlapped_corners = 0;

// The fitted runs over the programs checked (docs/planner.md §3d), under G64 P Q and under the
// machine's default fit (G64 P or a plain G64), and the largest distances, over the tolerance,
// of a setpoint of a fitted run from the programmed polyline and of a programmed vertex of a
// fitted run from the chords between setpoints (printed by the random tests).
struct FitStats {
  std::size_t runs_q = 0, runs_p = 0;
  double setpoint_ratio = 0.0, vertex_ratio = 0.0;
};
FitStats g_fit;

std::string fit_summary() {
  const FitStats f = std::exchange(g_fit, FitStats{});
  char line[200];
  std::snprintf(line, sizeof line,
                "%zu runs fitted under G64 Q, %zu under G64 P (default fit); setpoints within "
                "%.3f, vertices within %.3f of their tolerance",
                f.runs_q, f.runs_p, f.setpoint_ratio, f.vertex_ratio);
  return line;
}

// Every programmed vertex of each fitted run (the run's first and last vertices are the
// curve's end points) within `tol` of a chord between two setpoints of the walked curve (the
// chords that start, end or pass over it: a run of a few 2 µm facets lies inside one
// period): the fit's second guarantee (docs/planner.md §3d), the polyline → walk direction of
// the two-sided distance. tol: P under the default fit (the curve within P − ε_c of each
// vertex, the chord within ε_c of the curve), Q + ε_c under G64 Q.
std::string check_fitted_vertices(const Path& path, const Job& job, const std::vector<Vec3>& p,
                                  const std::vector<std::size_t>& seg_of,
                                  const feed::MachineLimits& l) {
  std::vector<std::size_t> cursor(path.segments.size(), 0);
  for (std::size_t w = 0; w < job.path().segments.size(); ++w) {
    const std::size_t k = job.fit_report().source_segment[w];
    const auto* curve = std::get_if<NurbsCurve>(&job.path().segments[w].geometry);
    const auto* line = std::get_if<Polyline>(&path.segments[k].geometry);
    if (!curve || !line || curve->degree() != 3) continue;
    const PathSegment& held = path.segments[k];
    const double tol = held.smoothing_tolerance_mm
                           ? *held.smoothing_tolerance_mm + l.chord_tolerance_mm
                           : held.blend_tolerance_mm.value_or(l.blend_tolerance_mm);
    // The run's vertices: from the curve's first control point to its last, in order.
    const auto& pts = line->points;
    std::size_t a = cursor[k];
    while (a < pts.size() && pts[a] != curve->points().front()) ++a;
    std::size_t b = a + 1;
    while (b < pts.size() && pts[b] != curve->points().back()) ++b;
    if (b >= pts.size()) return "fitted run " + std::to_string(w) + " not found in its segment";
    cursor[k] = b;
    (held.smoothing_tolerance_mm ? g_fit.runs_q : g_fit.runs_p) += 1;
    for (std::size_t i = a; i <= b; ++i) {
      double best = std::numeric_limits<double>::infinity();
      for (std::size_t j = 1; j < p.size(); ++j) {
        if (seg_of[j - 1] <= w && w <= seg_of[j])
          best = std::min(best, test::distance_to_segment(pts[i], p[j - 1], p[j]));
      }
      g_fit.vertex_ratio = std::max(g_fit.vertex_ratio, best / tol);
      if (!(best <= tol * (1.0 + 1e-9) + 1e-9)) {
        return "programmed vertex " + std::to_string(i) + " of segment " + std::to_string(k) +
               " is " + std::to_string(best) +
               " mm from the walk's chords (fitted run, tolerance " + std::to_string(tol) + " mm)";
      }
    }
  }
  return {};
}

// Checks one program; returns an empty string or the first failure.
// Under jerk_bound = "vector" also the jerk vector, the third difference of the setpoints.
std::string check(const Path& path, double max_program_feed_mm_per_min,
                  feed::JerkBound bound = feed::JerkBound::tangential,
                  const JobConfig& machine = test::planner_machine()) {
  JobConfig cfg = machine;
  cfg.limits.jerk_bound = bound;
  const double T = cfg.limits.period_s, a_max = cfg.limits.max_accel_mm_per_s2;
  const double j_max = cfg.limits.max_jerk_mm_per_s3, eps = cfg.limits.chord_tolerance_mm;
  const double v_cap = cfg.limits.max_feed_mm_per_min / 60.0;
  (void)max_program_feed_mm_per_min;
  Job job(path, cfg);
  // The programmed geometry, and the walked one (corners blended under G64 P): setpoints lie
  // on the walked geometry, and within the active tolerance of the programmed one; the chord
  // is checked against the walked one.
  // Both sampled every 0.5 µm: a blend arc, or a random curve's bend, of radius 0.08 mm bows
  // 1e-5 mm from a 2.5 µm chord (NCD_TEST_SEED=3989944120, program 30, failed on that with
  // the program sampled every 2.5 µm while the same point passed against the walked path).
  const test::GeometryTable program = test::tabulate(path, 0.0005);
  const test::GeometryTable geo = test::tabulate(job.path(), 0.0005);
  const double window = 0.5 + std::abs(program.s_mm.back() - geo.s_mm.back());
  std::vector<Vec3> p{geo.p.front()};
  std::vector<double> s{0.0};
  std::vector<std::size_t> seg_of{0};  // the walked segment of each setpoint
  std::int64_t still = 0;
  double still_s = 0.0;
  int since_overlap = 1000;  // setpoints since the last superposed one
  double prev_tol = 0.0;     // the tolerance of the setpoint before
  const double j_vector = bound == feed::JerkBound::vector ? j_max : std::sqrt(2.0) * j_max;
  const std::size_t cap = 5'000'000;
  while (!job.done()) {
    if (p.size() > cap) return "not done after " + std::to_string(cap) + " periods";
    job.prepare();
    const Setpoint sp = job.step();
    since_overlap = sp.overlapped ? 0 : since_overlap + 1;
    const double d = sp.overlapped ? 0.0 : test::distance_to_path(geo, sp.p, sp.s_mm, 0.5);
    if (!(d <= 1e-5)) {
      return "setpoint " + std::to_string(p.size()) + " at s = " + std::to_string(sp.s_mm) +
             " is " + std::to_string(d) + " mm off the walked path";
    }
    // The tolerance of the move holding the setpoint (a blend arc belongs to the move that
    // ends at its corner): its G64 P under G64, the machine's blend_tolerance_mm under a plain
    // G64; none under G61 or G61.1. A dense run fitted (docs/planner.md §3d) is a cubic in the
    // walked path, in a polyline of the program: its tolerance is Q under G64 P Q, and P − ε_c
    // under G64 P or a plain G64 (the machine's default fit, whose chords add ε_c to reach P).
    const std::size_t walked = sp.segment;
    const PathSegment& held = path.segments[job.fit_report().source_segment[walked]];
    const auto* walked_curve = std::get_if<NurbsCurve>(&job.path().segments[walked].geometry);
    const bool fitted = walked_curve && walked_curve->degree() == 3 &&
                        std::holds_alternative<Polyline>(held.geometry);
    const double p_mm =
        std::max(held.blend_tolerance_mm.value_or(cfg.limits.blend_tolerance_mm), 0.0);
    const double tol = held.path_control != PathControl::blend ? 0.0
                       : !fitted                               ? p_mm
                       : held.smoothing_tolerance_mm           ? *held.smoothing_tolerance_mm
                                                               : p_mm - eps;
    const double dp = test::distance_to_path(program, sp.p, sp.s_mm, window);
    if (fitted && tol > 0.0) g_fit.setpoint_ratio = std::max(g_fit.setpoint_ratio, dp / tol);
    if (!(dp <= tol * (1.0 + 1e-9) + 1e-5)) {
      return "setpoint " + std::to_string(p.size()) + " at s = " + std::to_string(sp.s_mm) +
             " is " + std::to_string(dp) + " mm off the programmed path (tolerance " +
             std::to_string(tol) + " mm)";
    }
    // A period that starts or ends off the walked path: its chord within the tolerance of the
    // corner's move (the one before; the last overlapped setpoint is back on the next move).
    if (since_overlap <= 1) {
      const double mid = test::distance_to_path(program, 0.5 * (sp.p + p.back()), sp.s_mm, window);
      const double t = std::max(tol, prev_tol);
      if (!(mid <= t * (1.0 + 1e-9) + 1e-9) || !(sp.chord_error_mm <= eps * (1.0 + 1e-9))) {
        return "overlapped period ending at s = " + std::to_string(sp.s_mm) + ": chord midpoint " +
               std::to_string(mid) + " mm off the programmed path, chord error " +
               std::to_string(sp.chord_error_mm) + " mm";
      }
    }
    // Chord: the geometry between the two setpoints against their chord.
    const auto lo = std::upper_bound(geo.s_mm.begin(), geo.s_mm.end(), s.back());
    const auto hi = std::lower_bound(geo.s_mm.begin(), geo.s_mm.end(), sp.s_mm);
    for (auto it = lo; since_overlap > 1 && it < hi; ++it) {
      const auto i = static_cast<std::size_t>(it - geo.s_mm.begin());
      const double e = test::distance_to_segment(geo.p[i], p.back(), sp.p);
      if (e > eps * (1.0 + 1e-3) + 1e-9) {
        const std::size_t seg = sp.segment;
        return "chord error " + std::to_string(e) + " mm at s = " + std::to_string(geo.s_mm[i]) +
               " (segment " + std::to_string(seg) +
               ", period from s = " + std::to_string(s.back()) + " to " + std::to_string(sp.s_mm) +
               ")";
      }
    }
    prev_tol = tol;
    const double v = (sp.p - p.back()).norm() / T;
    if (v > v_cap * (1.0 + 1e-9)) return "speed " + std::to_string(v) + " mm/s";
    // The programmed feed (F) of the move holding the setpoint, in the walked path (a blend
    // arc carries the feed of its corner's moves): the planned speed at the period's end never
    // above it (a superposed setpoint sums two moves' progress: held to v_cap above).
    const auto& walked_seg = job.path().segments[walked];
    if (!sp.overlapped && !walked_seg.rapid && walked_seg.feed_mm_per_min &&
        sp.v_mm_per_s > *walked_seg.feed_mm_per_min / 60.0 * (1.0 + 1e-9) + 1e-12) {
      return "speed " + std::to_string(sp.v_mm_per_s) + " mm/s at s = " + std::to_string(sp.s_mm) +
             " above the programmed feed F" + std::to_string(*walked_seg.feed_mm_per_min) +
             " of walked segment " + std::to_string(walked) + " (limit " + limit_name(sp.limit_id) +
             ")";
    }
    p.push_back(sp.p);
    s.push_back(sp.s_mm);
    seg_of.push_back(sp.segment);
    const std::size_t k = p.size() - 1;
    if (k >= 2) {
      const double acc = (p[k] - 2.0 * p[k - 1] + p[k - 2]).norm() / (T * T);
      if (acc > std::sqrt(2.0) * a_max * (1.0 + 1e-3)) {
        return "acceleration vector " + std::to_string(acc) +
               " mm/s^2 at s = " + std::to_string(sp.s_mm);
      }
      // Tangential: the average acceleration over two periods of the planned s.
      const double at = (s[k] - 2.0 * s[k - 1] + s[k - 2]) / (T * T);
      if (since_overlap > 2 && std::abs(at) > a_max * (1.0 + 1e-6))
        return "tangential acceleration " + std::to_string(at);
    }
    if (k >= 3) {
      const double jt = (s[k] - 3.0 * s[k - 1] + 3.0 * s[k - 2] - s[k - 3]) / (T * T * T);
      if (since_overlap > 3 && std::abs(jt) > j_max * (1.0 + 1e-6) + 1e-3)
        return "tangential jerk " + std::to_string(jt) + " at s = " + std::to_string(sp.s_mm) +
               " (segment " + std::to_string(sp.segment) + ", " + std::to_string(since_overlap) +
               " setpoints after an overlapped one)";
      const double jv = (p[k] - 3.0 * p[k - 1] + 3.0 * p[k - 2] - p[k - 3]).norm() / (T * T * T);
      const bool vector_bound = bound == feed::JerkBound::vector || since_overlap <= 3;
      if (vector_bound && jv > j_vector * (1.0 + 1e-6) + 1e-3) {
        return "jerk vector " + std::to_string(jv) + " mm/s^3 at s = " + std::to_string(sp.s_mm) +
               " (walked segment " + std::to_string(sp.segment) + ", v " +
               std::to_string(sp.v_mm_per_s) + " mm/s, a " + std::to_string(sp.a_mm_per_s2) +
               " mm/s^2, limit " + limit_name(sp.limit_id) + ")";
      }
    }
    if (sp.s_mm > still_s + 1e-4 || sp.done) {
      still_s = sp.s_mm;
      still = 0;
    } else if (static_cast<double>(++still) * T > 2.0) {
      return "stall at s = " + std::to_string(sp.s_mm) + " (v " + std::to_string(sp.v_mm_per_s) +
             " mm/s, a " + std::to_string(sp.a_mm_per_s2) + " mm/s^2, limit " +
             limit_name(sp.limit_id) + " at " + std::to_string(sp.feed_limit_mm_per_s) + " mm/s)";
    }
    if (sp.done) {
      g_overlapped_corners += job.overlap_report().corners;
      if (sp.v_mm_per_s != 0.0 || sp.a_mm_per_s2 != 0.0) return "not at rest at the end";
      const double miss = (sp.p - end_point(path)).norm();
      if (miss > 1e-9) return "ends " + std::to_string(miss) + " mm from the end point";
    }
  }
  return check_fitted_vertices(path, job, p, seg_of, cfg.limits);
}

// A dense CAM run rounded to 1 µm with a 90° corner in the middle, under G64 P0.01 Q0.01 (random
// radius, spacing and Q; seed printed): fitted on both sides of the corner, and walked through
// every check above (setpoints within Q of the programmed moves, chord, limits, at rest exactly
// at the end point).
TEST(Property, FittedDenseRunWithACornerIsWalkedWithinQ) {
  const std::uint64_t seed = test::seed();
  std::mt19937_64 rng(seed);
  const auto uni = [&](double a, double b) {
    return std::uniform_real_distribution<double>(a, b)(rng);
  };
  for (int k = 0; k < ncd::test::sweep_cases(4); ++k) {
    const double r = uni(10.0, 100.0), step = uni(0.005, 0.05), q = uni(0.005, 0.02);
    std::vector<Vec3> pts;
    const int n = 200 + static_cast<int>(rng() % 200);
    for (int i = 0; i <= n; ++i) {  // an arc, then a line turning 90° away from its end
      const double phi = step * i / r;
      pts.emplace_back(r * std::sin(phi), r * (1.0 - std::cos(phi)), 0.0);
    }
    const Vec3 corner = pts.back(), t(std::cos(step * n / r), std::sin(step * n / r), 0.0);
    const Vec3 away(-t.y(), t.x(), 0.0);
    for (int i = 1; i <= n; ++i) {
      pts.push_back(corner + step * i * away + Vec3(0, 0, 0.2 * std::sin(step * i)));
    }
    for (std::size_t i = 1; i < pts.size(); ++i) {
      for (int c = 0; c < 3; ++c) pts[i][c] = std::round(pts[i][c] * 1000.0) / 1000.0;
    }
    Path path;
    PathSegment s;
    s.geometry = Polyline{pts, {}};
    s.feed_mm_per_min = 3000.0;
    s.blend_tolerance_mm = 0.01;
    s.smoothing_tolerance_mm = q;
    path.segments.push_back(s);
    const std::string what = "case " + std::to_string(k) + " of seed " + std::to_string(seed);
    EXPECT_GE(Job(path, test::planner_machine()).fit_report().runs, 2u) << what;
    EXPECT_EQ(check(path, 3000.0), "") << what;
    if (HasFailure()) break;
  }
  std::printf("%s\n", fit_summary().c_str());
}

TEST(Property, RandomProgramsEndAtRestOnThePathWithinEveryLimit) {
  const std::uint64_t seed = test::seed();
  int programs = ncd::test::sweep_cases(200);  // a tenth under ASan
  if (const char* env = std::getenv("NCD_PROPERTY_PROGRAMS")) programs = std::atoi(env);
  ncd::test::RandomProgram g{std::mt19937_64(seed)};
  // NCD_PROPERTY_FROM=k replays program k of a seed without checking the ones before it.
  const int from =
      std::getenv("NCD_PROPERTY_FROM") ? std::atoi(std::getenv("NCD_PROPERTY_FROM")) : 0;
  for (int i = 0; i < programs; ++i) {
    g.at = Vec3::Zero();
    g.heading = Vec3::UnitX();
    g.max_feed_mm_per_min = 0.0;
    const Path path = g.program();
    if (i < from) continue;
    std::string failure;
    try {
      failure = check(path, g.max_feed_mm_per_min);
    } catch (const std::exception& e) {
      failure = std::string("exception: ") + e.what();
    }
    ASSERT_TRUE(failure.empty()) << "program " << i << " of seed " << seed << ": " << failure
                                 << "\n"
                                 << describe(path);
  }
  std::printf("%d programs, %zu corners passed without their stops; %s\n", programs,
              std::exchange(g_overlapped_corners, 0), fit_summary().c_str());
}

// Random polylines of sharp corners under G64 P (turns of 20–170°, legs of 0.2–20 mm, P of
// 1 µm–0.1 mm, feeds of 600–6000 mm/min, 3D), under both jerk bounds: every corner that gets
// no arc is a candidate for the corner overlap (docs/planner.md §3b), so these programs check
// it far more often than the mixed ones above. Seed printed; the count of overlapped corners too.
TEST(Property, RandomSharpCornersArePassedWithinEveryLimit) {
  const std::uint64_t seed = test::seed();
  std::mt19937_64 rng(seed);
  const auto uni = [&](double a, double b) {
    return std::uniform_real_distribution<double>(a, b)(rng);
  };
  int programs = ncd::test::sweep_cases(40);
  if (const char* env = std::getenv("NCD_PROPERTY_PROGRAMS")) programs = std::atoi(env);
  for (int i = 0; i < programs; ++i) {
    std::vector<Vec3> pts{Vec3::Zero()};
    Vec3 dir = Vec3::UnitX();
    const int legs = 4 + static_cast<int>(rng() % 8);
    for (int k = 0; k < legs; ++k) {
      pts.push_back(pts.back() + std::exp(uni(std::log(0.2), std::log(20.0))) * dir);
      // Turn by 20–170° about a random axis normal to dir.
      Vec3 axis = dir.cross(Vec3(uni(-1, 1), uni(-1, 1), uni(-1, 1))).normalized();
      if (!axis.allFinite()) axis = dir.unitOrthogonal();
      dir = Eigen::AngleAxisd(uni(20.0, 170.0) * M_PI / 180.0, axis) * dir;
    }
    Path path;
    PathSegment seg;
    seg.geometry = Polyline{pts, {}};
    seg.feed_mm_per_min = uni(600.0, 6000.0);
    seg.blend_tolerance_mm = std::exp(uni(std::log(1e-3), std::log(0.1)));
    path.segments.push_back(seg);
    for (const auto bound : {feed::JerkBound::tangential, feed::JerkBound::vector}) {
      std::string failure;
      try {
        failure = check(path, *seg.feed_mm_per_min, bound);
      } catch (const std::exception& e) {
        failure = std::string("exception: ") + e.what();
      }
      ASSERT_TRUE(failure.empty()) << "program " << i << " of seed " << seed << " ("
                                   << (bound == feed::JerkBound::vector ? "vector" : "tangential")
                                   << "): " << failure << "\n"
                                   << describe(path);
    }
  }
  std::printf("%d programs under both bounds, %zu corners passed without their stops; %s\n",
              programs, std::exchange(g_overlapped_corners, 0), fit_summary().c_str());
}

// The same checks and the jerk vector within j_max under jerk_bound = "vector", on random
// programs with every kind of piece: dense runs walked raw and 1 µm moves (several vertices in
// one period), repeated control points (rest points whose curvature grows without bound).
// 50 programs here, NCD_PROPERTY_PROGRAMS more.
TEST(Property, RandomProgramsKeepTheJerkVectorBound) {
  const std::uint64_t seed = test::seed();
  int programs = ncd::test::sweep_cases(50);
  if (const char* env = std::getenv("NCD_PROPERTY_PROGRAMS")) programs = std::atoi(env);
  ncd::test::RandomProgram g{std::mt19937_64(seed)};
  // NCD_PROPERTY_FROM=k replays program k of a seed without checking the ones before it.
  const int from =
      std::getenv("NCD_PROPERTY_FROM") ? std::atoi(std::getenv("NCD_PROPERTY_FROM")) : 0;
  for (int i = 0; i < programs; ++i) {
    g.at = Vec3::Zero();
    g.heading = Vec3::UnitX();
    g.max_feed_mm_per_min = 0.0;
    const Path path = g.program();
    if (i < from) continue;
    std::string failure;
    try {
      failure = check(path, g.max_feed_mm_per_min, feed::JerkBound::vector);
    } catch (const std::exception& e) {
      failure = std::string("exception: ") + e.what();
    }
    ASSERT_TRUE(failure.empty()) << "program " << i << " of seed " << seed << ": " << failure
                                 << "\n"
                                 << describe(path);
  }
  std::printf("%d programs, %zu corners passed without their stops; %s\n", programs,
              std::exchange(g_overlapped_corners, 0), fit_summary().c_str());
}

}  // namespace
}  // namespace ncd::motion

namespace ncd::motion {
namespace {

// An independent arc length of a NURBS (its points by test::nurbs_point, Cox–de Boor): the
// length of a fine inscribed polygon extrapolated with Richardson (the polygon's
// shortfall is O(h²) on every smooth span; each span is sampled on its own).
double polygon_length(const NurbsCurve& c, int n_per_span) {
  const auto bp = c.breakpoints();
  double total = 0.0;
  for (std::size_t k = 0; k + 1 < bp.size(); ++k) {
    // Interior samples of the span, its end approached from inside (the span's own polynomial).
    Vec3 prev = test::nurbs_point(c, bp[k]);
    for (int i = 1; i <= n_per_span; ++i) {
      const double u = i == n_per_span ? std::nextafter(bp[k + 1], bp[k])
                                       : bp[k] + (bp[k + 1] - bp[k]) * i / n_per_span;
      const Vec3 q = test::nurbs_point(c, u);
      total += (q - prev).norm();
      prev = q;
    }
  }
  return total;
}

double reference_length_mm(const NurbsCurve& c) {
  const double l1 = polygon_length(c, 4000), l2 = polygon_length(c, 8000);
  return (4.0 * l2 - l1) / 3.0;
}

PathSegment curve_segment(int degree, std::vector<double> knots, std::vector<Vec3> pts,
                          double feed_mm_per_min = 6000.0) {
  PathSegment s;
  s.geometry = NurbsCurve(degree, std::move(knots), std::move(pts));
  s.feed_mm_per_min = feed_mm_per_min;
  return s;
}

// Walks one curve: the property checks (at rest at the end, on the path, chord, speed,
// acceleration, jerk from the setpoints' differences, no stall), the walked length against the
// independent reference, and the rest inside where the curve stops.
void expect_walked(const PathSegment& seg, const char* name) {
  Path path;
  path.segments.push_back(seg);
  const NurbsCurve& c = std::get<NurbsCurve>(seg.geometry);
  EXPECT_EQ(check(path, 6000.0), "") << name;
  Job job(path, test::planner_machine());
  const double ref = reference_length_mm(c);
  EXPECT_NEAR(job.walker().length_mm(), ref, 1e-7 * ref) << name;
  double travelled = 0.0;
  Setpoint sp;
  std::size_t periods = 0;
  while (!job.done()) {
    job.prepare();
    sp = job.step();
    travelled += sp.travelled_mm;
    ++periods;
  }
  EXPECT_NEAR(travelled, ref, 1e-7 * ref) << name;
  EXPECT_LT((sp.p - c.points().back()).norm(), 1e-9) << name;
  // Not a crawl: within 2 s per knot of a walk at the programmed feed (independent of the
  // planner's figures; a crawl at the dip took hundreds of seconds).
  const double bound_s =
      ref / (*seg.feed_mm_per_min / 60.0) + 2.0 * static_cast<double>(c.breakpoints().size());
  EXPECT_LT(static_cast<double>(periods) * test::planner_machine().limits.period_s, bound_s)
      << name;
  std::cout << name << ": " << periods << " periods, length " << ref << " mm\n";
}

// A near-cusp inside a span (random programs, seed 2006778439, program 2436): a degree-5 curve
// whose parametric speed nearly vanishes at u ≈ 1.396, where κ passes 11 000 /mm within
// 0.001 mm of arc. Five samples per interval stepped over that peak and the chord error was
// 1.012 µm against 1 µm. Taking the limit at the bottom of the dip of |C'| kept the chord but
// crawled (26.5 s for the 20 mm, two whole intervals at the peak's chord speed); with
// intervals that halve towards the bottom and double away from it, the walk takes 6.8 s
// (6.7 s at the programmed feed). expect_walked checks every property, the walked length
// against an independent one, and a time within 2 s per knot of the programmed feed.
TEST(Property, NearCuspInsideASpanKeepsTheChordTolerance) {
  PathSegment seg = curve_segment(5, {0, 0, 0, 0, 0, 0, 1, 2, 3, 3, 3, 3, 3, 3},
                                  {{0, 0, 0},
                                   {0, 0, 0},
                                   {0.84126878803867822, 4.1270929047433027, 4.2923698449332441},
                                   {-3.5491048750945664, -1.034736971930327, 0.76549121527572739},
                                   {-0.85351233313636499, 3.3610341641520822, 1.3596744619847323},
                                   {-0.44693469728217217, 1.156256695039573, 4.8451055033942252},
                                   {8.3033811655266057, -5.8751899661476408, 11.165194526956277},
                                   {8.3033811655266057, -5.8751899661476408, 11.165194526956277}},
                                  182.19007591239671);
  expect_walked(seg, "near-cusp degree 5");
}

TEST(Property, DegenerateNurbsAreWalkedToRestAtTheEnd) {
  // A G5.2 whose first point repeats the current point (issue 13): P' = 0 at the start.
  expect_walked(curve_segment(3, {0, 0, 0, 0, 0.5, 1, 1, 1, 1},
                              {{0, 0, 0}, {0, 0, 0}, {10, 20, 0}, {30, -10, 0}, {40, 0, 0}}),
                "repeated first point");
  // Both ends at rest parametrically.
  expect_walked(curve_segment(3, {0, 0, 0, 0, 0.5, 1, 1, 1, 1},
                              {{0, 0, 0}, {0, 0, 0}, {10, 20, 0}, {40, 0, 0}, {40, 0, 0}}),
                "repeated end points");
  // A triple point of a quadratic: P' = 0 on both sides of the middle knot.
  expect_walked(curve_segment(2, {0, 0, 0, 1, 2, 2, 2},
                              {{0, 0, 0}, {10, 0, 0}, {10, 0, 0}, {10, 10, 5}}, 3000.0),
                "double interior point");
  // Interior knot of full multiplicity: a corner at the control point (20, 0).
  expect_walked(
      curve_segment(
          3, {0, 0, 0, 0, 1, 1, 1, 2, 2, 2, 2},
          {{0, 0, 0}, {5, 10, 0}, {15, 10, 0}, {20, 0, 0}, {30, 0, 0}, {35, 10, 0}, {40, 0, 0}}),
      "full multiplicity, corner");
  // Full multiplicity with the points around the knot repeated: P' = 0 on both sides.
  expect_walked(
      curve_segment(
          3, {0, 0, 0, 0, 1, 1, 1, 2, 2, 2, 2},
          {{0, 0, 0}, {5, 10, 0}, {20, 0, 0}, {20, 0, 0}, {20, 0, 0}, {35, -10, 0}, {40, 0, 0}}),
      "full multiplicity at rest");
  // Full multiplicity, tangent continuous: no stop needed, none made at rest.
  expect_walked(
      curve_segment(
          3, {0, 0, 0, 0, 1, 1, 1, 2, 2, 2, 2},
          {{0, 0, 0}, {5, 10, 0}, {15, 10, 0}, {20, 0, 0}, {25, -10, 0}, {35, -10, 0}, {40, 0, 0}}),
      "full multiplicity, smooth");
  // A repeated last point after a full-multiplicity knot (case 11 of seed 7414150 of the sweep
  // below): the sampler's step stopped 2 µm short of the end and that sliver's rest speed
  // slowed the whole 0.1 mm before it to 0.008 mm/s (14.3 s for 22.8 mm).
  expect_walked(curve_segment(3, {0, 0, 0, 0, 1, 1, 1, 2, 2, 2, 2},
                              {{0, 0, 0},
                               {0, 0, 0},
                               {4.0738981212241505, 0.88317184273403093, 0.84848618737429748},
                               {10.905794610818592, 1.9815821634476221, 1.4155977748592283},
                               {13.773056384302727, 0.80662929457206634, 0.93791277662501604},
                               {22.391334983128978, 0.81449180893664064, 0.78011410604517195},
                               {22.391334983128978, 0.81449180893664064, 0.78011410604517195}},
                              3000.0),
                "repeated last point after a full-multiplicity knot");
}

// Random degenerate curves: repeated first and last points, full-multiplicity interior knots,
// degrees 2–5, rational or not; each through the property checks and the length reference.
// NCD_TEST_SEED=7414150 (case 11) crawled for 14.3 s against the 6.6 s bound before the sampler
// stopped leaving slivers before a breakpoint (limit_sampler.cpp).
TEST(Property, RandomDegenerateNurbsWalkTheirTrueLength) {
  const std::uint64_t seed = test::seed();
  std::mt19937_64 rng(seed);
  const auto uni = [&](double a, double b) {
    return std::uniform_real_distribution<double>(a, b)(rng);
  };
  const int cases = ncd::test::sweep_cases(30);
  for (int k = 0; k < cases; ++k) {
    const int degree = 2 + static_cast<int>(rng() % 4);
    const int n = 2 * degree + 1;
    std::vector<Vec3> pts{Vec3::Zero()};
    for (int i = 1; i < n; ++i) pts.push_back(pts.back() + Vec3(uni(1, 8), uni(-5, 5), uni(-1, 1)));
    pts[1] = pts[0];
    if (rng() % 2) pts[static_cast<std::size_t>(n - 2)] = pts.back();
    std::vector<double> knots(static_cast<std::size_t>(degree + 1), 0.0);
    for (int r = 0; r < degree; ++r) knots.push_back(1.0);  // full multiplicity
    knots.insert(knots.end(), static_cast<std::size_t>(degree + 1), 2.0);
    std::vector<double> weights;
    if (rng() % 2) {
      for (int i = 0; i < n; ++i) weights.push_back(uni(0.5, 2.0));
    }
    PathSegment s;
    s.geometry = NurbsCurve(degree, knots, pts, weights);
    s.feed_mm_per_min = uni(600.0, 6000.0);
    const std::string name = "case " + std::to_string(k) + " of seed " + std::to_string(seed);
    expect_walked(s, name.c_str());
    if (HasFailure()) break;
  }
}

}  // namespace
}  // namespace ncd::motion

namespace ncd::motion {
namespace {

// A rational quintic whose last control point repeats (its end a rest point where κ grows
// without bound), then a polyline under G64 P: under "vector" the interval before the end was a
// sliver sampled over 0.02 mm of its span, that reached the end itself, where |C'| = 0 gave κ =
// 8e29 and a jerk-vector limit of 0 ("the path needs a full stop"; program 5 of seed 1 of
// Property.RandomProgramsKeepTheJerkVectorBound with repeated control points). Now walked, every
// check of the property suite kept, the jerk vector within j_max.
TEST(Property, RepeatedEndPointUnderTheJerkVectorBound) {
  const std::vector<Vec3> pts{{0, 0, 0},
                              {0, 0, 0},
                              {5.5443324161314091, -9.5786173677849256, 1.0796743316990058},
                              {0.16197075541984685, -9.1616261456560046, 1.002612159710788},
                              {-1.5463378199601983, -13.228121635648002, 2.4236111276336967},
                              {-1.2187471313561051, -10.706396824932312, 0.65383433371264954},
                              {-1.3214934439367931, -15.334952934186161, 1.4966282499175989},
                              {-2.9256225116881662, -12.824746954639124, -4.6848999339510389},
                              {-2.9256225116881662, -12.824746954639124, -4.6848999339510389}};
  const std::vector<double> weights{1.3910556331069324, 1.3375613315071322,  1.4014939522253484,
                                    1.506025667699004,  0.81374075883611308, 1.4467949956145516,
                                    1.8772489188103036, 1.2694955795477378,  1.9478966428191054};
  Path path;
  PathSegment curve;
  curve.geometry =
      toolpath::NurbsCurve(5, {0, 0, 0, 0, 0, 0, 1, 2, 3, 4, 4, 4, 4, 4, 4}, pts, weights);
  curve.feed_mm_per_min = 1972.6855305697597;
  path.segments.push_back(curve);
  PathSegment line;
  line.geometry =
      toolpath::Polyline{{pts.back(),
                          {-3.5820456717876503, -11.995045167942044, -9.091759962129295},
                          {2.7154271591749666, -6.6627622230029413, -2.6680389945676675}},
                         {}};
  line.feed_mm_per_min = 3309.7053898868589;
  line.blend_tolerance_mm = 0.26105293861097612;
  path.segments.push_back(line);
  EXPECT_EQ(check(path, 3309.7053898868589, feed::JerkBound::vector), "");
  EXPECT_EQ(check(path, 3309.7053898868589, feed::JerkBound::tangential), "");
}

}  // namespace
}  // namespace ncd::motion

namespace ncd::motion {
namespace {

// A corner a CAM post wrote as facets: n pieces of length l, each turning by φ (below the ~2°
// at which "vector" stops), between two 5 mm lines, at F3000. Several vertices then fall inside
// the three periods the jerk stencil spans, and the polyline acts as a curve whose curvature
// 2 sin(φ/2) / l starts and ends abruptly: the jump law takes that curvature jump (0.75 v² Δκ /
// T), not only each vertex's own turn. Before it, 35 of these 150 failed (12 facets of 0.5° and
// 0.01 mm: 49 656 mm/s³, 2.5 j_max). Every check of the property suite, under "vector".
TEST(Property, FacetedCornersKeepTheJerkVectorBound) {
  int cases = 0;
  for (const double deg : {0.2, 0.5, 1.0, 1.5, 1.9}) {
    for (const int facets : {2, 3, 5, 8, 12, 30}) {
      for (const double piece_mm : {0.002, 0.005, 0.01, 0.02, 0.05}) {
        std::vector<Vec3> pts{{0, 0, 0}, {5, 0, 0}};
        double heading = 0.0;
        for (int i = 0; i < facets; ++i) {
          heading += deg * M_PI / 180.0;
          pts.push_back(pts.back() + piece_mm * Vec3(std::cos(heading), std::sin(heading), 0));
        }
        pts.push_back(pts.back() + 5.0 * Vec3(std::cos(heading), std::sin(heading), 0));
        Path path;
        PathSegment s;
        s.geometry = toolpath::Polyline{pts, {}};
        s.feed_mm_per_min = 3000.0;
        path.segments.push_back(s);
        EXPECT_EQ(check(path, 3000.0, feed::JerkBound::vector), "")
            << facets << " facets of " << piece_mm << " mm turning " << deg << " deg each";
        ++cases;
      }
    }
  }
  std::printf("%d faceted corners checked; %s\n", cases, fit_summary().c_str());
}

// Moves programmed slower than a jerk-limited motion gets within its first periods from rest
// (under 0.64 mm/s here: G93 F0.5 over a quarter circle of 5 mm is 3.9 mm/min, 0.065 mm/s),
// on short random curves and lines that end in a reversal (a rest), on the machine of
// LinuxCNC's flowsnake.ngc (F15000, 3000 mm/s², 60 000 mm/s³): every setpoint within the
// move's feed up to the rest, and the walk ends at rest on the end point (check() above).
// tests/ngc/inverse_time.ngc found the rest refinement lifting the cap there (0.116 mm/s
// against F3.9 mm/min). Seed printed.
TEST(Property, SlowMovesKeepTheirFeedIntoAndOutOfRests) {
  const std::uint64_t seed = test::seed();
  std::mt19937_64 rng(seed);
  const auto uni = [&rng](double a, double b) {
    return std::uniform_real_distribution<double>(a, b)(rng);
  };
  JobConfig machine = test::planner_machine();
  machine.limits.max_feed_mm_per_min = 15000.0;
  machine.limits.max_accel_mm_per_s2 = 3000.0;
  machine.limits.max_jerk_mm_per_s3 = 60000.0;
  const int programs = ncd::test::sweep_cases(30);
  for (int i = 0; i < programs; ++i) {
    Path path;
    Vec3 at = Vec3::Zero();
    for (int k = 0; k < 3; ++k) {
      // A short curve (degree 1–5, 0.5–2 mm long), then a reversal line, both slow.
      const int degree = 1 + static_cast<int>(uni(0.0, 4.999));
      const int n = degree + 1 + static_cast<int>(uni(0.0, 2.999));
      std::vector<Vec3> pts{at};
      const Vec3 dir = Vec3(uni(-1, 1), uni(-1, 1), uni(-0.3, 0.3)).normalized();
      for (int j = 1; j < n; ++j) {
        const Vec3 wobble(uni(-0.5, 0.5), uni(-0.5, 0.5), uni(-0.1, 0.1));
        pts.push_back(pts.back() + uni(0.1, 0.4) * (dir + wobble).normalized());
      }
      std::vector<double> knots(static_cast<std::size_t>(degree + 1), 0.0);
      for (int j = 1; j < n - degree; ++j) knots.push_back(j);
      knots.insert(knots.end(), static_cast<std::size_t>(degree + 1), n - degree);
      const double feed = std::exp(uni(std::log(3.0), std::log(36.0)));  // mm/min
      PathSegment curve;
      curve.geometry = NurbsCurve(degree, knots, pts);
      curve.feed_mm_per_min = feed;
      path.segments.push_back(curve);
      const Vec3 end = pts.back(), back = (pts[pts.size() - 2] - end).normalized();
      PathSegment line;
      line.geometry = Polyline{{end, end + uni(0.05, 0.5) * back}, {}};
      line.feed_mm_per_min = std::exp(uni(std::log(3.0), std::log(36.0)));
      path.segments.push_back(line);
      at = std::get<Polyline>(line.geometry).points.back();
    }
    const std::string failure = check(path, 60.0, feed::JerkBound::tangential, machine);
    ASSERT_TRUE(failure.empty()) << "program " << i << " of seed " << seed << ": " << failure
                                 << "\n"
                                 << describe(path);
  }
}

}  // namespace
}  // namespace ncd::motion
