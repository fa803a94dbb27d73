// Sharp corners passed without their stops under G64 P (docs/planner.md §3b). The reference is
// the same program with its corners kept sharp (G64 P0), run by the same planner: the overlapped
// run must be exactly that run with, at each corner, the last m setpoints before the rest and
// the first m after it added together (the superposition, checked here setpoint by setpoint),
// and every limit must hold on what comes out, measured from the setpoints alone: the distance
// to the programmed polyline (brute force over every piece), the speed, the acceleration vector
// and the jerk vector by differences.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

#include "motion/job.hpp"
#include "tests/common/seed.hpp"
#include "tests/motion/planner_machine.hpp"
#include "tests/motion/reference.hpp"

namespace ncd::motion {
namespace {

using feed::JerkBound;
using toolpath::Path;
using toolpath::PathControl;
using toolpath::PathSegment;
using toolpath::Polyline;

constexpr double kOverlapT = 0.004, kOverlapA = 1000.0, kOverlapJ = 20000.0, kVmax = 100.0;

Path overlap_polyline(const std::vector<Vec3>& pts, std::optional<double> p_mm,
                      PathControl mode = PathControl::blend, double feed_mm_per_min = 6000.0) {
  Path path;
  PathSegment s;
  s.geometry = Polyline{pts, {}};
  s.feed_mm_per_min = feed_mm_per_min;
  s.path_control = mode;
  s.blend_tolerance_mm = p_mm;
  path.segments.push_back(s);
  return path;
}

std::vector<Setpoint> overlap_run(const Path& path, JerkBound bound = JerkBound::tangential) {
  JobConfig cfg = test::planner_machine();
  cfg.limits.jerk_bound = bound;
  Job job(path, cfg);
  std::vector<Setpoint> out;
  while (!job.done()) {
    job.prepare();
    out.push_back(job.step());
  }
  return out;
}

double overlap_distance_to_polyline(const std::vector<Vec3>& pts, const Vec3& q) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i + 1 < pts.size(); ++i)
    best = std::min(best, test::distance_to_segment(q, pts[i], pts[i + 1]));
  return best;
}

// The limits measured on setpoints (the start point first): the largest deviation from the
// polyline (setpoints and chord midpoints), speed, acceleration vector and jerk vector.
// Also the distance at which the programmed end point passed farthest from is passed: the
// nearest chord between two setpoints, for each inner vertex.
struct OverlapMeasured {
  double deviation_mm = 0.0, speed = 0.0, accel = 0.0, jerk = 0.0, vertex_mm = 0.0;
};

OverlapMeasured overlap_measure(const std::vector<Vec3>& program, const std::vector<Setpoint>& sp) {
  OverlapMeasured m;
  std::vector<Vec3> p{program.front()};
  for (const Setpoint& s : sp) p.push_back(s.p);
  for (std::size_t v = 1; v + 1 < program.size(); ++v) {
    double nearest = std::numeric_limits<double>::infinity();
    for (std::size_t k = 1; k < p.size(); ++k) {
      nearest = std::min(nearest, test::distance_to_segment(program[v], p[k - 1], p[k]));
    }
    m.vertex_mm = std::max(m.vertex_mm, nearest);
  }
  for (std::size_t k = 1; k < p.size(); ++k) {
    m.deviation_mm = std::max({m.deviation_mm, overlap_distance_to_polyline(program, p[k]),
                               overlap_distance_to_polyline(program, 0.5 * (p[k] + p[k - 1]))});
    m.speed = std::max(m.speed, (p[k] - p[k - 1]).norm() / kOverlapT);
    if (k >= 2)
      m.accel =
          std::max(m.accel, (p[k] - 2.0 * p[k - 1] + p[k - 2]).norm() / (kOverlapT * kOverlapT));
    if (k >= 3) {
      m.jerk = std::max(m.jerk, (p[k] - 3.0 * p[k - 1] + 3.0 * p[k - 2] - p[k - 3]).norm() /
                                    (kOverlapT * kOverlapT * kOverlapT));
    }
  }
  return m;
}

// The zig-zag of issue 13: legs of 5 mm, 30° between legs (150° turns).
std::vector<Vec3> overlap_zigzag(double leg_mm = 5.0, double between_deg = 30.0, int legs = 8) {
  std::vector<Vec3> pts{{0, 0, 0}};
  const double half = 0.5 * between_deg * M_PI / 180.0;
  for (int i = 0; i < legs; ++i) {
    const double ang = (i % 2 ? -1.0 : 1.0) * (0.5 * M_PI - half);
    pts.push_back(pts.back() + leg_mm * Vec3(std::cos(ang), std::sin(ang), 0.0));
  }
  return pts;
}

// Rebuilds the overlapped run from the sharp one: at each rest of the sharp run on one of the
// program's vertices, the overlap m is the one (0…16) with which the superposition matches the
// overlapped run's next setpoints exactly. Fails if none does; returns the m of each corner.
std::vector<int> superposition_of(const std::vector<Vec3>& program,
                                  const std::vector<Setpoint>& sharp,
                                  const std::vector<Setpoint>& over) {
  std::vector<int> ms;
  std::size_t i = 0, j = 0;  // sharp[i] and over[j] are the same setpoint
  const auto same = [](const Vec3& a, const Vec3& b) { return (a - b).norm() <= 1e-12; };
  while (i < sharp.size() && j < over.size()) {
    // A rest of the sharp run on an interior vertex ahead?
    std::size_t r = i;
    while (r + 1 < sharp.size() && sharp[r].v_mm_per_s != 0.0) ++r;
    if (r + 1 >= sharp.size()) break;
    Vec3 vertex = Vec3::Zero();
    bool on_vertex = false;
    for (std::size_t k = 1; k + 1 < program.size(); ++k) {
      if ((sharp[r].p - program[k]).norm() <= 1e-9) vertex = program[k], on_vertex = true;
    }
    int found = -1;
    for (int m = 16; m >= 0 && found < 0 && on_vertex; --m) {
      const auto mu = static_cast<std::size_t>(m);
      if (mu > r || r + mu >= sharp.size() || r - mu < i) continue;
      const std::size_t head = j + (r - mu - i);  // over's index of sharp[r - m]
      if (head + mu >= over.size()) continue;
      bool ok = true;
      for (std::size_t k = i; k <= r - mu && ok; ++k) ok = same(sharp[k].p, over[j + k - i].p);
      for (std::size_t k = 1; k <= mu && ok; ++k) {
        ok = same(sharp[r - mu + k].p + sharp[r + k].p - vertex, over[head + k].p);
      }
      if (ok) found = m;
    }
    if (found < 0) {
      ADD_FAILURE() << "no overlap m reproduces the setpoints after the rest at (" << sharp[r].p.x()
                    << ", " << sharp[r].p.y() << ")";
      return ms;
    }
    ms.push_back(found);
    const auto mu = static_cast<std::size_t>(found);
    j += (r - mu - i) + mu + 1;  // over's index just after sharp[r + m]
    i = r + mu + 1;
  }
  for (; i < sharp.size() && j < over.size(); ++i, ++j) EXPECT_TRUE(same(sharp[i].p, over[j].p));
  EXPECT_EQ(sharp.size() - i, over.size() - j) << "the runs end together";
  return ms;
}

TEST(Overlap, IsTheSharpRunWithEachCornersEndsAddedTogether) {
  std::printf(
      "| path | bound | sharp s | overlapped s | periods saved | m per corner | "
      "deviation mm | jerk vector / j_max |\n|---|---|---|---|---|---|---|---|\n");
  const struct {
    const char* name;
    std::vector<Vec3> pts;
  } cases[] = {{"square 10 mm", {{0, 0, 0}, {10, 0, 0}, {10, 10, 0}, {0, 10, 0}, {0, 0, 0}}},
               {"zig-zag 150 deg", overlap_zigzag()},
               {"zig-zag 120 deg, 2 mm", overlap_zigzag(2.0, 60.0, 6)}};
  for (const JerkBound bound : {JerkBound::tangential, JerkBound::vector}) {
    for (const auto& c : cases) {
      const std::vector<Setpoint> sharp = overlap_run(overlap_polyline(c.pts, 0.0), bound);
      const std::vector<Setpoint> over = overlap_run(overlap_polyline(c.pts, 0.01), bound);
      const std::vector<int> ms = superposition_of(c.pts, sharp, over);
      int saved = 0;
      std::string list;
      for (const int m : ms) saved += m, list += std::to_string(m) + " ";
      const OverlapMeasured g = overlap_measure(c.pts, over);
      std::printf("| %s | %s | %.3f | %.3f | %d | %s| %.5f | %.3f |\n", c.name,
                  bound == JerkBound::vector ? "vector" : "tangential", sharp.back().t_s,
                  over.back().t_s, saved, list.c_str(), g.deviation_mm, g.jerk / kOverlapJ);
      EXPECT_EQ(ms.size(), c.pts.size() - 2) << c.name << ": every corner a rest of the sharp run";
      EXPECT_EQ(sharp.size() - over.size(), static_cast<std::size_t>(saved)) << c.name;
      EXPECT_LE(g.deviation_mm, 0.01 * (1.0 + 1e-9)) << c.name;
      EXPECT_LE(g.vertex_mm, 0.01 * (1.0 + 1e-9)) << c.name << ": an end point passed beyond P";
      EXPECT_LE(g.speed, kVmax * (1.0 + 1e-9)) << c.name;
      EXPECT_LE(g.accel, kOverlapA * (1.0 + 1e-9)) << c.name;
      const double j_limit = bound == JerkBound::vector ? kOverlapJ : std::sqrt(2.0) * kOverlapJ;
      EXPECT_LE(g.jerk, j_limit * (1.0 + 1e-9)) << c.name;
      EXPECT_TRUE(over.back().done);
      EXPECT_LE((over.back().p - c.pts.back()).norm(), 1e-9);
    }
  }
}

// Where a stop is needed, it stays: a reversal, G61.1 and G61, a corner at a rapid, a corner
// before an event (stop_before), G64 P0. And paths without such corners get no delay.
TEST(Overlap, ReversalsRapidsEventsAndExactModesKeepTheirStops) {
  const std::vector<Vec3> square{{0, 0, 0}, {10, 0, 0}, {10, 10, 0}, {0, 10, 0}, {0, 0, 0}};
  const auto rests = [](const std::vector<Setpoint>& sp) {
    int n = 0;
    for (std::size_t i = 0; i + 1 < sp.size(); ++i) n += sp[i].v_mm_per_s == 0.0 ? 1 : 0;
    return n;
  };
  const auto overlapped = [](const std::vector<Setpoint>& sp) {
    int n = 0;
    for (const Setpoint& s : sp) n += s.overlapped ? 1 : 0;
    return n;
  };
  {  // plunge and retract: a reversal
    const std::vector<Setpoint> sp =
        overlap_run(overlap_polyline({{0, 0, 5}, {0, 0, 0}, {0, 0, 5}}, 0.1));
    EXPECT_EQ(rests(sp), 1);
    EXPECT_EQ(overlapped(sp), 0);
  }
  for (const PathControl mode : {PathControl::exact_stop, PathControl::exact_path}) {
    const std::vector<Setpoint> sp = overlap_run(overlap_polyline(square, 0.01, mode));
    EXPECT_EQ(rests(sp), 3);
    EXPECT_EQ(overlapped(sp), 0);
  }
  {  // G64 P0: sharp corners
    const std::vector<Setpoint> sp = overlap_run(overlap_polyline(square, 0.0));
    EXPECT_EQ(rests(sp), 3);
    EXPECT_EQ(overlapped(sp), 0);
  }
  {  // a rapid, then a cut; the cut, then an event before the next cut
    Path path = overlap_polyline({{0, 0, 0}, {10, 0, 0}}, 0.01);
    path.segments[0].rapid = true;
    path.segments[0].feed_mm_per_min.reset();
    Path cut = overlap_polyline({{10, 0, 0}, {10, 10, 0}}, 0.01);
    path.segments.push_back(cut.segments[0]);
    Path after = overlap_polyline({{10, 10, 0}, {0, 10, 0}}, 0.01);
    after.segments[0].stop_before = true;
    path.segments.push_back(after.segments[0]);
    const std::vector<Setpoint> sp = overlap_run(path);
    EXPECT_EQ(rests(sp), 2);
    EXPECT_EQ(overlapped(sp), 0);
  }
  {  // no sharp corner: no line of setpoints, no delay
    Job job(overlap_polyline({{0, 0, 0}, {10, 0, 0}}, 0.01), test::planner_machine());
    EXPECT_EQ(job.delay_periods(), 0U);
    Job square_job(overlap_polyline(square, 0.01), test::planner_machine());
    EXPECT_GT(square_job.delay_periods(), 0U);
    std::printf("the square's line of setpoints: %zu periods (%.0f ms)\n",
                square_job.delay_periods(),
                1e3 * kOverlapT * static_cast<double>(square_job.delay_periods()));
  }
}

// A feed hold at any period around a corner (before, during and after the overlap; seed
// printed for the resume delays): the motion comes to rest, resumes and ends at the end point,
// and every limit holds on the setpoints.
TEST(Overlap, HoldAroundAnOverlappedCornerKeepsEveryLimit) {
  std::mt19937_64 rng(test::seed());
  const std::vector<Vec3> pts = overlap_zigzag(5.0, 30.0, 3);
  const std::size_t sharp_periods = overlap_run(overlap_polyline(pts, 0.0)).size();
  for (std::size_t at = 20; at < sharp_periods; at += 3) {
    Job job(overlap_polyline(pts, 0.01), test::planner_machine());
    std::vector<Setpoint> sp;
    const std::size_t resume = at + 40 + rng() % 80;
    while (!job.done() && sp.size() < 100000) {
      if (sp.size() == at) job.planner().hold();
      if (sp.size() == resume) job.planner().resume();
      job.prepare();
      sp.push_back(job.step());
    }
    SCOPED_TRACE("hold at period " + std::to_string(at) + ", resume at " + std::to_string(resume));
    ASSERT_TRUE(job.done());
    EXPECT_LE((sp.back().p - pts.back()).norm(), 1e-9);
    const OverlapMeasured g = overlap_measure(pts, sp);
    EXPECT_LE(g.deviation_mm, 0.01 * (1.0 + 1e-9));
    EXPECT_LE(g.vertex_mm, 0.01 * (1.0 + 1e-9));
    EXPECT_LE(g.speed, kVmax * (1.0 + 1e-9));
    EXPECT_LE(g.accel, std::sqrt(2.0) * kOverlapA * (1.0 + 1e-9));
    EXPECT_LE(g.jerk, std::sqrt(2.0) * kOverlapJ * (1.0 + 1e-9));
    for (const Setpoint& s : sp) EXPECT_EQ(s.fault, StepFault::None);
  }
}

// The line of setpoints is deep only near a stop: a hold requested farther than
// line_depth_within_mm() from the next stop acts in the same period as in the same program with
// its corner kept sharp (G64 P0, no line at all); nearer, it acts at most delay_periods() later.
// The period a hold acts in is the first whose setpoint differs from the unheld run's (near the
// stop, where the motion already slows down, that can be late even without a line). Near a stop
// the held run with a line may also agree with the unheld one because both already brake as
// fast as a hold would (its planner, a line ahead, was braking for the stop when the hold came):
// there it acts from the period its final descent to rest starts, if that is sooner.
TEST(Overlap, FarFromAStopAHoldActsAtOnce) {
  // A 90° corner at F6000, a 150° turn at F600 (at that feed the 90° corner gets an arc).
  // The zone is 37 periods (docs/planner.md §3b, m_max = 14 at these limits) at the fastest the
  // move may go: 200 % of its feed, at most the maximum feed.
  for (const double feed : {6000.0, 600.0}) {
    const std::vector<Vec3> pts = {
        {0, 0, 0},
        {60, 0, 0},
        feed > 1000.0 ? Vec3(60, 10, 0) : Vec3(60 - 10 * std::cos(M_PI / 6), 5, 0)};
    const auto held = [&](std::optional<double> p_mm, std::size_t hold_at) {
      Job job(overlap_polyline(pts, p_mm, PathControl::blend, feed), test::planner_machine());
      std::vector<Setpoint> sp;
      while (!job.done() && sp.size() < 100000) {
        if (sp.size() == hold_at) job.planner().hold();
        if (sp.size() == hold_at + 100) job.planner().resume();
        job.prepare();
        sp.push_back(job.step());
      }
      return sp;
    };
    const auto acts_after = [](const std::vector<Setpoint>& free, const std::vector<Setpoint>& sp,
                               std::size_t hold_at) {
      std::size_t k = 0;
      while (k < free.size() && k < sp.size() && (free[k].p - sp[k].p).norm() == 0.0) ++k;
      return static_cast<long>(k) - static_cast<long>(hold_at);
    };
    const auto descent_after = [](const std::vector<Setpoint>& sp, std::size_t hold_at) {
      std::size_t rest = hold_at;  // the held motion's first rest after the hold
      while (rest < sp.size() && sp[rest].v_mm_per_s != 0.0) ++rest;
      std::size_t k = rest;  // the first period of its strict descent to that rest
      while (rest < sp.size() && k > hold_at && sp[k - 1].v_mm_per_s > sp[k].v_mm_per_s) --k;
      return static_cast<long>(k) - static_cast<long>(hold_at);
    };
    const Job probe(overlap_polyline(pts, 0.01, PathControl::blend, feed), test::planner_machine());
    const Job sharp_probe(overlap_polyline(pts, 0.0, PathControl::blend, feed),
                          test::planner_machine());
    ASSERT_GT(probe.delay_periods(), 0U);
    ASSERT_EQ(sharp_probe.delay_periods(), 0U);
    const double deep_mm = probe.line_depth_within_mm();
    EXPECT_NEAR(deep_mm, 37 * kOverlapT * std::min(kVmax, 2.0 * feed / 60.0), 1e-9);
    std::printf("F%.0f: the line is deep within %.2f mm of a stop (%zu periods at most)\n", feed,
                deep_mm, probe.delay_periods());
    const std::vector<Setpoint> free = held(0.01, 1000000), free_sharp = held(0.0, 1000000);
    const std::size_t every = feed > 1000.0 ? 5 : 25;
    int far = 0, near = 0;
    for (std::size_t at = 5; at < free.size() && free[at].s_mm < 60.0; at += every) {
      const std::vector<Setpoint> held_run = held(0.01, at);
      const long lag = acts_after(free, held_run, at);
      const long lag_sharp = acts_after(free_sharp, held(0.0, at), at);
      const double to_stop_mm = 60.0 - free[at].s_mm;
      SCOPED_TRACE("F" + std::to_string(feed) + ", hold at period " + std::to_string(at) + ", " +
                   std::to_string(to_stop_mm) + " mm before the corner");
      if (to_stop_mm > deep_mm) {
        EXPECT_EQ(lag, lag_sharp);
        ++far;
      } else {
        const long acts = std::min(lag, descent_after(held_run, at));
        EXPECT_LE(acts, lag_sharp + static_cast<long>(probe.delay_periods()));
        ++near;
        std::printf("  hold %5.2f mm before the corner: acts after %ld periods (%ld sharp)\n",
                    to_stop_mm, acts, lag_sharp);
      }
    }
    EXPECT_GT(far, 20);
    EXPECT_GT(near, 1);
  }
}

}  // namespace
}  // namespace ncd::motion
