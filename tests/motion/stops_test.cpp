// Full stops inside a path: reversals, sharp corners, zero-length moves, G61, G61.1 and
// stop_before. Each must end one planned stretch at rest exactly at the point and start the
// next from rest; never a stall. Durations are compared with the closed-form time-optimal
// S-curve of each stretch (tests/motion/reference.hpp, written independently of the planner).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "core/error.hpp"
#include "geometry/nurbs.hpp"
#include "motion/cycle.hpp"
#include "motion/job.hpp"
#include "tests/motion/planner_machine.hpp"
#include "tests/motion/reference.hpp"

namespace ncd::motion {
namespace {

using toolpath::Path;
using toolpath::PathControl;
using toolpath::PathSegment;
using toolpath::Polyline;

constexpr double kStopsT = 0.004, kStopsA = 1000.0, kStopsJ = 20000.0;

PathSegment line_segment(std::vector<Vec3> points, double feed_mm_per_min,
                         PathControl mode = PathControl::blend) {
  PathSegment s;
  s.geometry = Polyline{std::move(points), {}};
  s.feed_mm_per_min = feed_mm_per_min;
  s.path_control = mode;
  return s;
}

struct Motion {
  std::vector<Setpoint> sp;
  double duration_s = 0.0;
  std::size_t overlap_saved = 0;  // periods saved at corners passed without their stop
};

// Runs a job to its end (at most max_periods) and records every setpoint.
Motion stops_run(const Path& path, const JobConfig& cfg = test::planner_machine(),
                 std::size_t max_periods = 2'000'000) {
  Job job(path, cfg);
  Motion r;
  while (!job.done() && r.sp.size() < max_periods) {
    job.prepare();
    r.sp.push_back(job.step());
  }
  r.duration_s = r.sp.empty() ? 0.0 : r.sp.back().t_s;
  r.overlap_saved = job.overlap_report().periods_saved;
  return r;
}

// Indices of the setpoints at rest (v = a = 0) strictly before the end.
std::vector<std::size_t> rests(const Motion& r) {
  std::vector<std::size_t> out;
  for (std::size_t i = 0; i + 1 < r.sp.size(); ++i) {
    if (r.sp[i].v_mm_per_s == 0.0 && r.sp[i].a_mm_per_s2 == 0.0) out.push_back(i);
  }
  return out;
}

void expect_at_rest_at(const Motion& r, const Vec3& end) {
  ASSERT_FALSE(r.sp.empty());
  const Setpoint& last = r.sp.back();
  EXPECT_TRUE(last.done);
  EXPECT_EQ(last.v_mm_per_s, 0.0);
  EXPECT_EQ(last.a_mm_per_s2, 0.0);
  EXPECT_LT((last.p - end).norm(), 1e-9);
}

// The duration of stretches planned rest to rest, each at most `v` fast: the sum of the
// closed-form time-optimal S-curves, rounded up to whole periods.
double exact_stop_bound_s(const std::vector<double>& lengths_mm, double v_mm_per_s) {
  double t = 0.0;
  for (const double d : lengths_mm) t += test::scurve_time_s(d, v_mm_per_s, kStopsA, kStopsJ);
  return t;
}

TEST(Stops, PlungeAndRetractStopsAtTheBottomAndFinishes) {
  // G1 Z0 F300 then G1 Z5: the move straight back stalled the motion (issue 13).
  Path path;
  path.segments.push_back(line_segment({{0, 0, 5}, {0, 0, 0}}, 300.0));
  path.segments.push_back(line_segment({{0, 0, 0}, {0, 0, 5}}, 300.0));
  const Motion r = stops_run(path);
  expect_at_rest_at(r, {0, 0, 5});
  const auto at_rest = rests(r);
  ASSERT_FALSE(at_rest.empty());
  // At rest exactly at the bottom of the plunge.
  bool bottom = false;
  for (const std::size_t i : at_rest) bottom |= r.sp[i].p.norm() < 1e-9;
  EXPECT_TRUE(bottom);
  const double bound = exact_stop_bound_s({5.0, 5.0}, 5.0);
  std::cout << "plunge/retract: " << r.duration_s << " s, bound " << bound << " s\n";
  EXPECT_GE(r.duration_s, bound - 2 * kStopsT);
  EXPECT_LE(r.duration_s, 1.05 * bound + 2 * kStopsT);
}

TEST(Stops, ReversalInsideOnePolyline) {
  Path path;
  path.segments.push_back(line_segment({{0, 0, 0}, {10, 0, 0}, {3, 0, 0}}, 3000.0));
  const Motion r = stops_run(path);
  expect_at_rest_at(r, {3, 0, 0});
  bool at_turn = false;
  for (const std::size_t i : rests(r)) at_turn |= (r.sp[i].p - Vec3(10, 0, 0)).norm() < 1e-9;
  EXPECT_TRUE(at_turn);
  const double bound = exact_stop_bound_s({10.0, 7.0}, 50.0);
  EXPECT_LE(r.duration_s, 1.05 * bound + 2 * kStopsT);
  EXPECT_GE(r.duration_s, bound - 2 * kStopsT);
}

// The square: 10 × 10 mm at 6000 mm/min took 4.41 s, against 1.04 s for an exact
// stop at every corner. Its corners are too sharp to pass within 1 µm at a_max T (4 mm/s).
// Under G64 P0 they stop (with a tolerance they are overlapped instead: overlap_test.cpp).
TEST(Stops, SquareCornersStopAndMatchTheExactStopBound) {
  Path path;
  path.segments.push_back(
      line_segment({{0, 0, 0}, {10, 0, 0}, {10, 10, 0}, {0, 10, 0}, {0, 0, 0}}, 6000.0));
  path.segments[0].blend_tolerance_mm = 0.0;
  const Motion r = stops_run(path);
  expect_at_rest_at(r, {0, 0, 0});
  EXPECT_EQ(rests(r).size(), 3U);
  const double bound = exact_stop_bound_s({10, 10, 10, 10}, 100.0);
  std::cout << "square: " << r.duration_s << " s, exact-stop bound " << bound << " s\n";
  EXPECT_GE(r.duration_s, bound - kStopsT);
  EXPECT_LE(r.duration_s, 1.05 * bound);
}

TEST(Stops, ZigZagCornersStop) {
  // A 30° zig-zag: legs of 5 mm, alternating ±75° from the x axis.
  std::vector<Vec3> pts{{0, 0, 0}};
  const double leg = 5.0, half = 15.0 * M_PI / 180.0;
  for (int i = 0; i < 8; ++i) {
    const double ang = (i % 2 ? -1.0 : 1.0) * (0.5 * M_PI - half);
    pts.push_back(pts.back() + leg * Vec3(std::cos(ang), std::sin(ang), 0.0));
  }
  Path path;
  path.segments.push_back(line_segment(pts, 6000.0));
  path.segments[0].blend_tolerance_mm = 0.0;  // G64 P0 (overlap_test.cpp passes them within P)
  const Motion r = stops_run(path);
  expect_at_rest_at(r, pts.back());
  EXPECT_EQ(rests(r).size(), 7U);
  const double bound = exact_stop_bound_s(std::vector<double>(8, leg), 100.0);
  std::cout << "zig-zag: " << r.duration_s << " s, exact-stop bound " << bound << " s\n";
  // Goal 1.05; on 5 mm legs each stretch loses about three periods in its landing (1.06).
  EXPECT_LE(r.duration_s, 1.07 * bound);
}

TEST(Stops, GentleCornerIsBlendedUnderG64AndStoppedUnderG61) {
  const double turn = 10.0 * M_PI / 180.0;
  const std::vector<Vec3> pts{
      {0, 0, 0}, {10, 0, 0}, {10 + 10 * std::cos(turn), 10 * std::sin(turn), 0}};
  for (const PathControl mode : {PathControl::blend, PathControl::exact_path}) {
    Path path;
    path.segments.push_back(line_segment(pts, 6000.0, mode));
    const Motion r = stops_run(path);
    expect_at_rest_at(r, pts.back());
    EXPECT_EQ(rests(r).size(), mode == PathControl::blend ? 0U : 1U);
  }
}

TEST(Stops, ExactStopEndsEveryMoveEvenWhenStraight) {
  Path path;
  for (int i = 0; i < 3; ++i) {
    path.segments.push_back(
        line_segment({{2.0 * i, 0, 0}, {2.0 * i + 2.0, 0, 0}}, 6000.0, PathControl::exact_stop));
  }
  const Motion r = stops_run(path);
  expect_at_rest_at(r, {6, 0, 0});
  EXPECT_EQ(rests(r).size(), 2U);
  const double bound = exact_stop_bound_s({2, 2, 2}, 100.0);
  EXPECT_LE(r.duration_s, 1.05 * bound + 2 * kStopsT);
  // Straight under G64: no stop.
  Path blended = path;
  for (auto& s : blended.segments) s.path_control = PathControl::blend;
  EXPECT_EQ(rests(stops_run(blended)).size(), 0U);
}

TEST(Stops, StopBeforeAnEvent) {
  Path path;
  path.segments.push_back(line_segment({{0, 0, 0}, {4, 0, 0}}, 6000.0));
  path.segments.push_back(line_segment({{4, 0, 0}, {8, 0, 0}}, 6000.0));
  path.segments[1].stop_before = true;
  const Motion r = stops_run(path);
  expect_at_rest_at(r, {8, 0, 0});
  const auto at_rest = rests(r);
  ASSERT_EQ(at_rest.size(), 1U);
  EXPECT_LT((r.sp[at_rest[0]].p - Vec3(4, 0, 0)).norm(), 1e-9);
}

TEST(Stops, ZeroLengthMoveIsAStop) {
  Path path;
  path.segments.push_back(line_segment({{0, 0, 0}, {3, 0, 0}, {3, 0, 0}, {6, 0, 0}}, 6000.0));
  path.segments.push_back(line_segment({{6, 0, 0}, {6, 0, 0}}, 6000.0));
  path.segments.push_back(line_segment({{6, 0, 0}, {6, 1e-3, 0}}, 6000.0));  // a 1 µm move
  const Motion r = stops_run(path);
  expect_at_rest_at(r, {6, 1e-3, 0});
  const auto at_rest = rests(r);
  ASSERT_EQ(at_rest.size(), 2U);
  EXPECT_LT((r.sp[at_rest[0]].p - Vec3(3, 0, 0)).norm(), 1e-9);
  EXPECT_LT((r.sp[at_rest[1]].p - Vec3(6, 0, 0)).norm(), 1e-9);
}

// A path of length 0 (only zero-length moves: a random program found it) ends at once, at rest
// where it starts; the sampler's last node had no interval and an infinite limit, which the job
// refused as "a cusp".
TEST(Stops, PathOfLengthZeroEndsAtOnce) {
  Path path;
  path.segments.push_back(line_segment({{1, 2, 3}, {1, 2, 3}}, 4800.0));
  path.segments.push_back(line_segment({{1, 2, 3}, {1, 2, 3}}, 5000.0));
  const Motion r = stops_run(path);
  expect_at_rest_at(r, {1, 2, 3});
  EXPECT_LE(r.sp.size(), 3U);
}

// A NURBS whose first control point repeats has zero parametric speed and unbounded curvature
// at its start (C = a u² + b u³: κ ~ 1/u): the joint into it is a stop. Found by the property
// suite (seed 1337050818, program 4): rounding left the curve's first derivative a few ulps off
// zero, so the joint was taken as a corner in a noise direction and the motion crawled at
// 3e-5 mm/s before it until the stall check fired.
TEST(Stops, JointIntoANurbsWithARepeatedFirstPointIsAStop) {
  Path path;
  const Vec3 joint(-14.305234174108218, 0, 0);
  path.segments.push_back(line_segment({{0, 0, 0}, joint}, 5819.7061490395863));
  PathSegment nurbs;
  nurbs.geometry =
      toolpath::NurbsCurve(2, {0, 0, 0, 1, 2, 3, 3, 3},
                           {joint,
                            joint,
                            {-16.999016741964546, -2.7969141898254524, 2.9297403396583968},
                            {-19.073612407750691, -10.419599862055808, 1.4608671514717062},
                            {-19.073612407750691, -10.419599862055808, 1.4608671514717062}},
                           {1.5185872632563802, 1.4333857695871282, 1.7735670960480514,
                            1.054813254742849, 1.182959955725484});
  nurbs.feed_mm_per_min = 1758.0660368489998;
  path.segments.push_back(nurbs);
  const Motion r = stops_run(path, test::planner_machine(), 100'000);
  expect_at_rest_at(r, {-19.073612407750691, -10.419599862055808, 1.4608671514717062});
  const auto at_rest = rests(r);
  ASSERT_EQ(at_rest.size(), 1U);
  EXPECT_LT((r.sp[at_rest[0]].p - joint).norm(), 1e-9);
  // Never a crawl: every 0.25 s (62 periods) away from a rest the tool advances 0.1 µm.
  for (std::size_t i = 62; i < r.sp.size(); ++i) {
    if (r.sp[i].s_mm - r.sp[i - 62].s_mm < 1e-4) {
      ADD_FAILURE() << "no progress from t = " << r.sp[i - 62].t_s << " s to " << r.sp[i].t_s
                    << " s at s = " << r.sp[i].s_mm << " mm";
      break;
    }
  }
}

// A corner at a knot of full multiplicity, after a span that nearly reverses (|C'| falls from
// about 30 to 1 and back): the stop is at the knot itself, under both jerk bounds. Its arc length
// was once summed with four fixed Gauss–Legendre panels, 11.80719 mm for a span of 11.80651 mm
// (a slow reference in the test: the midpoint rule on 200 000 points), and the motion turned
// the corner at 0.1 mm/s before resting (a jerk vector of 36 500 mm/s³; seed 47 of
// Property.RandomProgramsKeepTheJerkVectorBound, program 272).
TEST(Stops, CornerAfterANearlyReversingSpanStopsAtTheKnot) {
  const std::vector<Vec3> pts{{-8.4032558467997216, 22.365131266210554, -0.069592772124472901},
                              {-14.441175130404671, 20.454642477349903, -2.9063812498620463},
                              {-15.389626355431991, 17.314213143167994, -8.2425111627821437},
                              {-12.259836815441108, 20.67156310013927, -2.3280190613279679},
                              {-9.3288558181059713, 19.55596148220085, -6.5076814429995364},
                              {-7.8287392642222891, 17.718377404707493, -7.4302298913393425},
                              {-6.6908031590136661, 16.189045792617645, -5.5162665620990126},
                              {-6.1181092915409536, 17.496319648852506, -4.2223837390758341}};
  // The first span is the Bézier of the first four points: its length by the midpoint rule.
  const auto speed = [&pts](double u) {
    const Vec3 d = 3.0 * ((pts[1] - pts[0]) * (1 - u) * (1 - u) +
                          2.0 * (pts[2] - pts[1]) * (1 - u) * u + (pts[3] - pts[2]) * u * u);
    return d.norm();
  };
  const int n = 200000;
  double span_mm = 0.0;
  for (int k = 0; k < n; ++k) span_mm += speed((k + 0.5) / n) / n;
  for (const auto bound : {feed::JerkBound::tangential, feed::JerkBound::vector}) {
    Path path;
    PathSegment seg;
    seg.geometry = toolpath::NurbsCurve(3, {0, 0, 0, 0, 1, 1, 1, 4, 5, 5, 5, 5}, pts, {});
    seg.feed_mm_per_min = 4355.4465837584821;
    path.segments.push_back(seg);
    JobConfig cfg = test::planner_machine();
    cfg.limits.jerk_bound = bound;
    const Motion r = stops_run(path, cfg, 100'000);
    expect_at_rest_at(r, pts.back());
    const auto at_rest = rests(r);
    ASSERT_EQ(at_rest.size(), 1U);
    EXPECT_NEAR(r.sp[at_rest[0]].s_mm, span_mm, 1e-9);
    EXPECT_LT((r.sp[at_rest[0]].p - pts[3]).norm(), 1e-9);
  }
}

TEST(Stops, DrillingProgramFinishesWithinTheExactStopBound) {
  // Five holes: rapid over, plunge 3 mm at F300, retract at the rapid rate.
  Path path;
  Vec3 at(0, 0, 2);
  std::vector<double> lengths;
  for (int h = 0; h < 5; ++h) {
    const Vec3 over(5.0 * h + 5.0, 0, 2), bottom(5.0 * h + 5.0, 0, -3);
    PathSegment rapid = line_segment({at, over}, 0.0);
    rapid.rapid = true;
    rapid.feed_mm_per_min.reset();
    path.segments.push_back(rapid);
    path.segments.push_back(line_segment({over, bottom}, 300.0));
    PathSegment up = line_segment({bottom, over}, 0.0);
    up.rapid = true;
    up.feed_mm_per_min.reset();
    path.segments.push_back(up);
    at = over;
  }
  const Motion r = stops_run(path);
  expect_at_rest_at(r, at);
  double bound = 0.0;
  for (int h = 0; h < 5; ++h) {
    bound += test::scurve_time_s(5.0, 100.0, kStopsA, kStopsJ) +
             test::scurve_time_s(5.0, 5.0, kStopsA, kStopsJ) +
             test::scurve_time_s(5.0, 100.0, kStopsA, kStopsJ);
  }
  // The bottom of each hole, a reversal, stops. The corners at the rapids keep their stops too
  // (a rapid is never overlapped, docs/planner.md §3b): nothing is saved here.
  const double saved_s = static_cast<double>(r.overlap_saved) * kStopsT;
  std::cout << "drilling: " << r.duration_s << " s, exact-stop bound " << bound << " s, " << saved_s
            << " s saved at the corners\n";
  for (int h = 0; h < 5; ++h) {
    bool stopped = false;
    for (const std::size_t i : rests(r)) {
      stopped |= (r.sp[i].p - Vec3(5.0 * h + 5.0, 0, -3)).norm() < 1e-9;
    }
    EXPECT_TRUE(stopped) << "hole " << h;
  }
  EXPECT_EQ(r.overlap_saved, 0U);
  EXPECT_GE(r.duration_s, bound - kStopsT);
  EXPECT_LE(r.duration_s, 1.05 * bound);
}

// Issue 11's robustness: buffers are sized from v / a, so extreme limits must be refused with
// the numbers, not overflow a cast, exhaust memory or hang.
TEST(Stops, ExtremeLimitsAreRefusedNotAllocated) {
  Path path;
  path.segments.push_back(line_segment({{0, 0, 0}, {1, 0, 0}}, 6000.0));
  for (const double feed : {1e300, 1e12}) {
    JobConfig c = test::planner_machine();
    c.limits.max_feed_mm_per_min = feed;
    EXPECT_THROW(Job(path, c), InputError) << feed;
  }
  JobConfig c = test::planner_machine();
  c.limits.max_jerk_mm_per_s3 = 1e-300;
  EXPECT_THROW(Job(path, c), InputError);
  Planner p(PlannerLimits{}, 1.0);
  EXPECT_THROW(p.reserve_for_speed(1e300), InputError);
  EXPECT_NO_THROW(p.reserve_for_speed(1000.0));
}

// The no-progress watchdog: forced with a feed of 6e-4 mm/min (1e-5 mm/s, 1e-6 mm in the
// 0.1 s timeout); a drilling program with stops runs to its end under a 0.05 s timeout.
TEST(Stops, WatchdogStopsAJobThatDoesNotAdvance) {
  Path path;
  path.segments.push_back(line_segment({{0, 0, 0}, {1, 0, 0}}, 6e-4));
  JobConfig c = test::planner_machine();
  c.limits.stall_timeout_s = 0.1;
  CycleOptions o;
  o.clock = ClockKind::Simulated;
  o.realtime = false;
  o.block_when_full = false;
  Cycle cycle(std::make_unique<Job>(path, c), o);
  cycle.start();
  cycle.join();
  EXPECT_EQ(cycle.status().state, CycleState::Error);
  EXPECT_NE(cycle.error().find("no progress for 0.1"), std::string::npos) << cycle.error();
  EXPECT_NE(cycle.error().find("program"), std::string::npos) << cycle.error();
  EXPECT_LE(cycle.status().t_s, 0.1 + 2 * kStopsT);
}

TEST(Stops, WatchdogDoesNotFireAtStops) {
  Path path;
  path.segments.push_back(line_segment({{0, 0, 5}, {0, 0, 0}}, 300.0));
  path.segments.push_back(line_segment({{0, 0, 0}, {0, 0, 5}, {3, 0, 5}, {3, 0, 0}}, 300.0));
  JobConfig c = test::planner_machine();
  c.limits.stall_timeout_s = 0.05;
  CycleOptions o;
  o.clock = ClockKind::Simulated;
  o.realtime = false;
  o.block_when_full = false;
  Cycle cycle(std::make_unique<Job>(path, c), o);
  cycle.start();
  cycle.join();
  EXPECT_EQ(cycle.status().state, CycleState::Done) << cycle.error();
}

}  // namespace
}  // namespace ncd::motion
