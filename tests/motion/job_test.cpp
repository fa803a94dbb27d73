// A whole job walked period by period (sampler → planner → walker) on the curves the issue
// names: a cubic NURBS with interior knots, a rational circle with double knots, and the
// experiment-3 chamfer path. Each period's travel is checked against an independent arc
// length (a 64-panel Simpson rule written here), and the run against every limit.
#include "motion/job.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "gcode/path_io.hpp"
#include "geometry/spiral.hpp"
#include "motion/run_stats.hpp"
#include "tests/common/test_paths.hpp"
#include "tests/motion/chamfer_exp3.hpp"

namespace ncd::motion {
namespace {

JobConfig fast_machine() {
  JobConfig c;  // 100 mm/s, 1000 mm/s², 2e4 mm/s³, 4 ms, chord 1 µm: the defaults
  c.cutting.ball_radius_mm = 5.0;
  c.cutting.pick_feed_mm = 0.5;
  c.cutting.teeth = 4;
  c.cutting.spindle_rpm = 12000.0;
  c.cutting.roughness_target_um = 10.0;
  return c;
}

// Arc length of a NURBS over [u0, u1] by a composite Simpson rule on each piece between knots
// (P'' jumps there): the slow reference.
double simpson_arc(const toolpath::NurbsCurve& c, double u0, double u1) {
  const auto piece = [&c](double a, double b) {
    const int n = 64;
    const double h = (b - a) / n;
    double sum = c.eval(a).d1.norm() + c.eval(b).d1.norm();
    for (int i = 1; i < n; ++i) sum += (i % 2 ? 4.0 : 2.0) * c.eval(a + i * h).d1.norm();
    return sum * h / 3.0;
  };
  double total = 0.0, a = u0;
  for (const double k : c.breakpoints()) {
    if (k > a && k < u1) {
      total += piece(a, k);
      a = k;
    }
  }
  return total + piece(a, u1);
}

struct Outcome {
  RunStats stats;
  double ref_feed_error_max_rel = 0.0;  // against the Simpson reference, steps ≥ 1 µm
  Setpoint last;
  std::int64_t knot_crossings = 0;
};

Outcome job_run(const toolpath::Path& path, const JobConfig& cfg) {
  Job job(path, cfg);
  Outcome o;
  o.stats.path_length_mm = job.length_mm();
  const auto* curve = std::get_if<toolpath::NurbsCurve>(&path.segments.front().geometry);
  const std::vector<double> knots = curve ? curve->breakpoints() : std::vector<double>{};
  double u_prev = curve ? curve->u_begin() : 0.0;
  for (int guard = 0; guard < 10'000'000; ++guard) {
    job.prepare();
    const Setpoint sp = job.step();
    record(o.stats, cfg, sp, job.limit_here().feed_mm_per_s, job.roughness_here_um(sp.v_mm_per_s),
           0.0);
    if (curve) {
      const double u = job.walker().curve_u();
      for (const double k : knots) o.knot_crossings += (u_prev < k && k < u) ? 1 : 0;
      if (sp.planned_ds_mm >= kFeedErrorMinStepMm && !sp.done) {
        const double ref = simpson_arc(*curve, u_prev, u);
        o.ref_feed_error_max_rel =
            std::max(o.ref_feed_error_max_rel, std::abs(ref - sp.planned_ds_mm) / sp.planned_ds_mm);
      }
      u_prev = u;
    }
    o.last = sp;
    if (sp.done) break;
  }
  return o;
}

void expect_clean_run(const Outcome& o, const JobConfig& cfg, double end_mm_tolerance) {
  const RunStats& st = o.stats;
  EXPECT_TRUE(o.last.done);
  EXPECT_LE(st.feed_error_max_rel, 1e-9);
  EXPECT_LE(std::abs(st.drift_mm()), 1e-6);
  EXPECT_LE(st.chord_error_max_mm, cfg.limits.chord_tolerance_mm * (1.0 + kViolationRel));
  EXPECT_EQ(st.violations_feed, 0);
  EXPECT_EQ(st.violations_accel, 0);
  EXPECT_EQ(st.violations_jerk, 0);
  EXPECT_EQ(st.violations_chord, 0);
  EXPECT_EQ(st.not_converged, 0);
  EXPECT_NEAR(o.last.s_mm, st.path_length_mm, end_mm_tolerance);
  EXPECT_EQ(o.last.v_mm_per_s, 0.0);
}

TEST(Job, CubicNurbsAcrossKnotsAndRamps) {
  const toolpath::Path path = toolpath::read_path_text(ncd::test::kCubicJson, "cubic");
  const JobConfig cfg = fast_machine();
  const Outcome o = job_run(path, cfg);
  expect_clean_run(o, cfg, 1e-9);
  EXPECT_LE(o.ref_feed_error_max_rel, 1e-9);  // against the independent Simpson arc
  EXPECT_GE(o.knot_crossings, 3);
  EXPECT_GT(o.stats.feed_max_mm_per_s, 99.0);  // reaches 100 mm/s where it may
  const auto& c = std::get<toolpath::NurbsCurve>(path.segments[0].geometry);
  EXPECT_NEAR((o.last.p - c.eval(c.u_end()).p).norm(), 0.0, 1e-9);
}

TEST(Job, RationalCircleWithDoubleKnots) {
  const toolpath::Path path = toolpath::read_path_text(ncd::test::kCircleJson, "circle");
  const JobConfig cfg = fast_machine();
  const Outcome o = job_run(path, cfg);
  expect_clean_run(o, cfg, 1e-9);
  EXPECT_LE(o.ref_feed_error_max_rel, 1e-9);
  EXPECT_NEAR(o.stats.path_length_mm, 2.0 * kPi * 20.0, 1e-9);  // closed form
  EXPECT_GE(o.knot_crossings, 3);
  // On a circle of 20 mm, the chord limit at 1 µm allows 2 sqrt(2·20·0.001)/T = 316 mm/s and
  // centripetal acceleration sqrt(1000·20) = 141 mm/s, so 100 mm/s (max feed) binds.
  EXPECT_GT(o.stats.feed_max_mm_per_s, 99.0);
}

TEST(Job, ChamferPathOfExperiment3) {
  const toolpath::Path path = toolpath::read_path_text(test::chamfer_exp3_json(), "exp3");
  JobConfig cfg;
  cfg.cutting.ball_radius_mm = 3.0;
  cfg.cutting.pick_feed_mm = 0.0;
  cfg.cutting.teeth = 2;
  cfg.cutting.spindle_rpm = 3000.0;
  cfg.cutting.roughness_target_um = 0.05;  // f_t = sqrt(8 r R) → 208 mm/min, below F300
  const Outcome o = job_run(path, cfg);
  expect_clean_run(o, cfg, 1e-9);
  EXPECT_LE(o.stats.roughness_max_um, 0.05 * (1.0 + 1e-6));
  EXPECT_GT(o.stats.cycles_by_limit[static_cast<std::size_t>(feed::FeedLimit::Roughness)], 0);
  // The loop closes: the last setpoint is the first cutter location.
  const auto& line = std::get<toolpath::Polyline>(path.segments[0].geometry);
  EXPECT_NEAR((o.last.p - line.points.front()).norm(), 0.0, 1e-9);
}

TEST(Job, ProgramFeedBindsOnTheChamfer) {
  const toolpath::Path path = toolpath::read_path_text(test::chamfer_exp3_json(), "exp3");
  JobConfig cfg;
  cfg.cutting.ball_radius_mm = 3.0;
  cfg.cutting.pick_feed_mm = 0.0;
  cfg.cutting.spindle_rpm = 3000.0;
  cfg.cutting.roughness_target_um = 1.0;
  const Outcome o = job_run(path, cfg);
  expect_clean_run(o, cfg, 1e-9);
  EXPECT_NEAR(o.stats.feed_max_mm_per_s * 60.0, 300.0, 1e-6);  // F300 of the chamfer JSON
}

TEST(Job, SameInputsGiveTheSameSetpoints) {
  const toolpath::Path path = toolpath::read_path_text(ncd::test::kCubicJson, "cubic");
  Job a(path, fast_machine()), b(path, fast_machine());
  for (;;) {
    a.prepare();
    b.prepare();
    const Setpoint x = a.step(), y = b.step();
    ASSERT_EQ(x.p, y.p);
    ASSERT_EQ(x.v_mm_per_s, y.v_mm_per_s);
    ASSERT_EQ(x.limit_id, y.limit_id);
    if (x.done) break;
  }
}

// Skipping the search on flat intervals (docs/planner.md "Flat intervals") must not change a
// single setpoint: the job with the skip against the job that searches every interval, on the
// spiral of the replay benchmark and on the cubic (where the curvature laws bind in places).
TEST(Job, FlatIntervalSkipGivesTheSameSetpoints) {
  const auto compare = [](const toolpath::Path& path, const std::string& what,
                          const feed::MachineLimits& limits = {}) {
    JobConfig fast_cfg;
    fast_cfg.limits = limits;
    JobConfig slow_cfg = fast_cfg;
    slow_cfg.sampler.skip_flat_intervals = false;
    Job fast(path, fast_cfg), slow(path, slow_cfg);
    int periods = 0, differing = 0;
    for (;;) {
      fast.prepare();
      slow.prepare();
      const Setpoint a = fast.step(), b = slow.step();
      ++periods;
      const bool same = a.t_s == b.t_s && a.p == b.p && a.s_mm == b.s_mm &&
                        a.v_mm_per_s == b.v_mm_per_s && a.a_mm_per_s2 == b.a_mm_per_s2 &&
                        a.j_mm_per_s3 == b.j_mm_per_s3 && a.limit_id == b.limit_id &&
                        a.done == b.done;
      if (!same && ++differing <= 3) {
        ADD_FAILURE() << what << ": period " << periods << " differs: s " << a.s_mm << " / "
                      << b.s_mm << ", v " << a.v_mm_per_s << " / " << b.v_mm_per_s;
      }
      if (a.done || b.done || periods > 2'000'000) {
        EXPECT_TRUE(a.done && b.done) << what;
        break;
      }
    }
    EXPECT_EQ(differing, 0) << what << " over " << periods << " periods";
    return periods;
  };
  EXPECT_GT(compare(toolpath::spiral_path(2), "spiral, 2 turns"), 2000);
  EXPECT_GT(compare(toolpath::read_path_text(ncd::test::kCubicJson, "cubic.json"), "cubic"), 100);
  // Per-axis limits (docs/planner.md §3f): examples/machine-slow-z.toml's Z, then X and Y at
  // 10 000 mm/s³ besides; the skip then also leaves out the curve-jerk sampling it proves idle.
  feed::MachineLimits slow_z;
  slow_z.axes[2].max_feed_mm_per_min = 1500.0;
  slow_z.axes[2].max_accel_mm_per_s2 = 250.0;
  slow_z.axes[2].max_jerk_mm_per_s3 = 4000.0;
  EXPECT_GT(compare(toolpath::spiral_path(2), "spiral, slow Z", slow_z), 2000);
  feed::MachineLimits axis_jerk = slow_z;
  axis_jerk.axes[0].max_jerk_mm_per_s3 = axis_jerk.axes[1].max_jerk_mm_per_s3 = 10000.0;
  EXPECT_GT(compare(toolpath::spiral_path(2), "spiral, X/Y jerk", axis_jerk), 2000);
  EXPECT_GT(compare(toolpath::read_path_text(ncd::test::kCubicJson, "cubic.json"),
                    "cubic, X/Y jerk", axis_jerk),
            100);
}

TEST(Job, TaylorAloneIsWorseThanTheCorrectedWalk) {
  // The baseline the correction is measured against: eq. (7) alone at Δs = 0.4 mm on the cubic
  // drifts from the commanded arc by far more than 1e-9.
  const toolpath::Path path = toolpath::read_path_text(ncd::test::kCubicJson, "cubic");
  const auto& c = std::get<toolpath::NurbsCurve>(path.segments[0].geometry);
  feed::WalkerConfig w;
  w.mode = feed::StepMode::TaylorOnly;
  feed::CurveWalker walker(c, w);
  double worst = 0.0;
  while (!walker.at_end()) {
    const double u0 = walker.u();
    const feed::StepResult r = walker.step(0.4);
    if (r.status != feed::StepStatus::Ok) break;
    worst = std::max(worst, std::abs(simpson_arc(c, u0, r.u) - 0.4) / 0.4);
  }
  EXPECT_GT(worst, 1e-5);
}

toolpath::PathSegment line_of(std::vector<Vec3> points, double feed_mm_per_min) {
  toolpath::PathSegment seg;
  seg.geometry = toolpath::Polyline{std::move(points), {}};
  seg.feed_mm_per_min = feed_mm_per_min;
  return seg;
}

// A path's numbers are checked when the job is made, not in its periods: a feed of 0, below 0
// or not a number, a negative G64 tolerance or a point that is not finite is refused there,
// naming the segment and its line (the periods have only result codes).
TEST(Job, BadNumbersOfAPathAreRefusedAtTheStart) {
  const auto refused = [](const toolpath::Path& path) {
    try {
      Job job(path, fast_machine());
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  for (const double feed : {0.0, -300.0, std::nan(""), HUGE_VAL}) {
    toolpath::Path path;
    path.segments.push_back(line_of({{0, 0, 0}, {10, 0, 0}}, 600.0));
    path.segments.push_back(line_of({{10, 0, 0}, {10, 10, 0}}, feed));
    path.segments.back().source_line = 7;
    const std::string why = refused(path);
    EXPECT_NE(why.find("segment 2 (line 7): feed"), std::string::npos) << why;
    EXPECT_NE(why.find("F word above 0"), std::string::npos) << why;
  }
  toolpath::Path tol;
  tol.segments.push_back(line_of({{0, 0, 0}, {10, 0, 0}}, 600.0));
  tol.segments.back().blend_tolerance_mm = -0.1;
  EXPECT_NE(refused(tol).find("G64 tolerance"), std::string::npos);
  toolpath::Path nan_point;
  nan_point.segments.push_back(line_of({{0, 0, 0}, {std::nan(""), 0, 0}}, 600.0));
  EXPECT_NE(refused(nan_point).find("not a finite number"), std::string::npos);
}

}  // namespace
}  // namespace ncd::motion
