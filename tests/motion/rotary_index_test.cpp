// The rotary index (motion/rotary_index.hpp, docs/planner.md §3g):
//   - the closed-form double S against a slow reference: the peak speed found by bisection on
//     "accelerate to vp and back covers vp·Ta(vp)" (not the closed form's roots), the jerk
//     sequence it implies integrated phase by phase in steps of constant jerk: the same
//     duration, the same position at 2100 instants, the end at rest on the target; over a random
//     sweep of angles and limits (seed printed) and the degenerate ones (a hair of a degree, a jerk
//     so low the acceleration is never reached, a speed so low it is reached at once);
//   - the job: a program that indexes A between cuts walks with X, Y, Z standing still during
//     every index period, the rotary coordinate in every setpoint, its differences within the
//     axis's speed, acceleration and jerk, each index landing exactly on its angle after
//     ceil(duration / T) periods, one at the path's start and one after its end included;
//   - a path turning an axis the machine does not have is refused by the job.
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "gcode/ngc/interpreter.hpp"
#include "gcode/program.hpp"
#include "motion/job.hpp"
#include "motion/rotary_index.hpp"
#include "tests/common/seed.hpp"

namespace ncd::motion {
namespace {

// The acceleration phase's length to reach vp from rest (a, j limits).
double accel_phase_s(double vp, double a, double j) {
  return vp >= a * a / j ? vp / a + a / j : 2.0 * std::sqrt(vp / j);
}

struct Reference {
  double vp = 0.0, ta = 0.0, tj = 0.0, tv = 0.0;
  double duration() const { return 2.0 * ta + tv; }
};

Reference reference(double h, const IndexLimits& l) {
  const double v = l.max_speed_deg_per_s, a = l.max_accel_deg_per_s2, j = l.max_jerk_deg_per_s3;
  Reference r;
  if (v * accel_phase_s(v, a, j) <= h) {
    r.vp = v;
  } else {
    double lo = 0.0, hi = v;
    for (int i = 0; i < 200; ++i) {
      const double mid = 0.5 * (lo + hi);
      (mid * accel_phase_s(mid, a, j) < h ? lo : hi) = mid;
    }
    r.vp = 0.5 * (lo + hi);
  }
  r.ta = accel_phase_s(r.vp, a, j);
  r.tj = std::min(a / j, std::sqrt(r.vp / j));
  r.tv = std::max(0.0, (h - r.vp * r.ta) / r.vp);
  return r;
}

// The reference's jerk phases: (length, jerk) — +j, 0, −j over the acceleration phase, 0
// cruising, the mirror.
std::vector<std::pair<double, double>> reference_phases(const Reference& r, double j) {
  return {{r.tj, j},  {r.ta - 2 * r.tj, 0.0}, {r.tj, -j}, {r.tv, 0.0},
          {r.tj, -j}, {r.ta - 2 * r.tj, 0.0}, {r.tj, j}};
}

void expect_matches_reference(double from, double to, const IndexLimits& l) {
  const IndexProfile p(from, to, l);
  const double h = std::abs(to - from), sign = to >= from ? 1.0 : -1.0;
  const Reference r = reference(h, l);
  EXPECT_NEAR(p.duration_s(), r.duration(), 1e-9 * std::max(1.0, r.duration()));
  EXPECT_NEAR(p.peak_speed_deg_per_s(), r.vp, 1e-9 * r.vp);
  EXPECT_LE(p.peak_speed_deg_per_s(), l.max_speed_deg_per_s * (1 + 1e-12));
  EXPECT_LE(p.peak_accel_deg_per_s2(), l.max_accel_deg_per_s2 * (1 + 1e-12));
  // Each phase integrated in 300 000 steps of constant jerk, the profile compared every 1000.
  const int n = 300'000;
  double q = 0.0, v = 0.0, a = 0.0, t = 0.0, worst = 0.0;
  for (const auto& [length, jt] : reference_phases(r, l.max_jerk_deg_per_s3)) {
    if (!(length > 0.0)) continue;
    const double dt = length / n;
    for (int i = 0; i < n; ++i) {
      q += v * dt + a * dt * dt / 2 + jt * dt * dt * dt / 6;  // exact over a step
      v += a * dt + jt * dt * dt / 2;
      a += jt * dt;
      t += dt;
      if ((i + 1) % 1000 == 0) {
        worst = std::max(worst, std::abs(p.position_deg(t) - (from + sign * q)));
      }
    }
  }
  const double tol = 1e-6 * std::max(1.0, h);
  EXPECT_LE(worst, tol) << "profile against the integrated reference";
  EXPECT_NEAR(t, p.duration_s(), 1e-9 * std::max(1.0, t));
  EXPECT_NEAR(q, h, tol);
  EXPECT_NEAR(v, 0.0, 1e-6 * std::max(1.0, r.vp));
  EXPECT_EQ(p.position_deg(p.duration_s()), to);
  EXPECT_EQ(p.position_deg(-1.0), from);
}

TEST(RotaryIndexProfile, MatchesTheIntegratedReferenceOverARandomSweep) {
  std::mt19937_64 rng(test::seed());
  std::uniform_real_distribution<double> log_angle(-3.0, 3.5), log_v(0.0, 3.5), log_a(1.0, 5.0),
      log_j(2.0, 7.0), unit(0.0, 1.0);
  for (int k = 0; k < 40; ++k) {
    const IndexLimits l{std::pow(10.0, log_v(rng)), std::pow(10.0, log_a(rng)),
                        std::pow(10.0, log_j(rng))};
    const double from = 720.0 * (unit(rng) - 0.5);
    const double to = from + (unit(rng) < 0.5 ? -1 : 1) * std::pow(10.0, log_angle(rng));
    SCOPED_TRACE("case " + std::to_string(k) + ": " + std::to_string(from) + " -> " +
                 std::to_string(to) + " v " + std::to_string(l.max_speed_deg_per_s) + " a " +
                 std::to_string(l.max_accel_deg_per_s2) + " j " +
                 std::to_string(l.max_jerk_deg_per_s3));
    expect_matches_reference(from, to, l);
  }
}

TEST(RotaryIndexProfile, DegenerateCasesMatchTheReferenceToo) {
  expect_matches_reference(0.0, 1e-6, {60.0, 1800.0, 36000.0});  // a hair: jerk phases only
  expect_matches_reference(0.0, 90.0, {60.0, 1800.0, 36000.0});  // the defaults, cruising
  expect_matches_reference(0.0, 3600.0, {6000.0, 1e6, 100.0});   // a never reached (low j)
  expect_matches_reference(90.0, -270.0, {0.5, 1e6, 1e8});       // v reached at once
  expect_matches_reference(10.0, 10.0 + 2.0 * 1800.0 * 1800.0 * 1800.0 / (36000.0 * 36000.0),
                           {1e4, 1800.0, 36000.0});  // the border between the no-cruise cases
  const IndexProfile none(5.0, 5.0, {});
  EXPECT_EQ(none.duration_s(), 0.0);
  EXPECT_EQ(none.position_deg(1.0), 5.0);
}

JobConfig config_with(char axis) {
  JobConfig c;
  c.limits.rotary.axis = axis;
  c.limits.rotary.max_feed_deg_per_min = 5400.0;  // 90 deg/s
  c.limits.rotary.max_accel_deg_per_s2 = 900.0;
  c.limits.rotary.max_jerk_deg_per_s3 = 20000.0;
  return c;
}

toolpath::Path indexed_path(char axis) {
  toolpath::InterpretOptions opt;
  opt.rotary_axis = axis;
  opt.start_machine_mm = Vec3(0, 0, 50);
  const std::string w(1, static_cast<char>(std::toupper(axis)));
  const std::string program = "G21 G90\nG0 " + w + "30\nG0 X10 Y0 Z5\nG1 Z-1 F300\nG1 X20\n" +
                              "G0 Z5\nG0 " + w + "120\nG1 X10 F300\nG0 Z50\nG1 " + w +
                              "-45 F1200\nM2\n";
  return toolpath::to_path(toolpath::interpret_ngc(program, "ix.ngc", opt));
}

struct IndexWalk {
  std::vector<Setpoint> sp;
};

IndexWalk index_walk(Job& job) {
  IndexWalk w;
  for (int n = 0; n < 200000 && !job.done(); ++n) {
    EXPECT_TRUE(job.prepare());
    w.sp.push_back(job.step());
    EXPECT_EQ(w.sp.back().fault, StepFault::None) << job.fault_message();
    if (w.sp.back().fault != StepFault::None) break;
  }
  return w;
}

TEST(RotaryIndexJob, IndexesAtRestWithinTheAxisLimitsAndLandOnTheirAngles) {
  const JobConfig cfg = config_with('a');
  const toolpath::Path path = indexed_path('a');
  Job job(path, cfg);
  ASSERT_EQ(job.indexes().size(), 3u);
  EXPECT_EQ(job.indexes()[0].s_mm, 0.0);              // before any motion
  EXPECT_EQ(job.indexes()[2].s_mm, job.length_mm());  // after the last
  const IndexWalk w = index_walk(job);
  ASSERT_TRUE(job.done());
  const double T = cfg.limits.period_s;
  const auto& r = cfg.limits.rotary;
  std::vector<double> prev(3, 0.0);  // rotary at rest at 0 before the first period
  std::vector<double> landed;
  std::size_t periods = 0, expect_periods = 0;
  for (const IndexAt& ix : job.indexes()) {
    expect_periods += static_cast<std::size_t>(std::ceil(ix.profile.duration_s() / T - 1e-9));
  }
  for (std::size_t i = 0; i < w.sp.size(); ++i) {
    const Setpoint& s = w.sp[i];
    const bool index_period = s.limit_id == kLimitIdIndex;
    if (index_period) {
      ++periods;
      EXPECT_EQ(s.v_mm_per_s, 0.0);
      // X, Y, Z stand where the motion rested (the first index: at the path's start).
      const Vec3 before =
          i > 0 ? w.sp[i - 1].p
                : std::get<toolpath::Polyline>(path.segments[0].geometry).points.front();
      EXPECT_EQ(s.p, before) << "period " << i;
      if (!s.indexing) landed.push_back(s.rotary_deg);
    } else if (i > 0) {
      EXPECT_EQ(s.rotary_deg, w.sp[i - 1].rotary_deg) << "the axis turns only in an index";
    } else {
      EXPECT_EQ(s.rotary_deg, 0.0);
    }
    const double rr = s.rotary_deg;
    const double v = std::abs(rr - prev[2]) / T;
    const double a = std::abs(rr - 2 * prev[2] + prev[1]) / (T * T);
    const double j = std::abs(rr - 3 * prev[2] + 3 * prev[1] - prev[0]) / (T * T * T);
    EXPECT_LE(v, r.max_feed_deg_per_min / 60.0 * (1 + 1e-9)) << i;
    EXPECT_LE(a, r.max_accel_deg_per_s2 * (1 + 1e-9)) << i;
    EXPECT_LE(j, r.max_jerk_deg_per_s3 * (1 + 1e-9)) << i;
    prev = {prev[1], prev[2], rr};
    if (i > 0) {
      EXPECT_NEAR(s.t_s - w.sp[i - 1].t_s, T, 1e-9);
    }
  }
  EXPECT_EQ(periods, expect_periods);
  ASSERT_EQ(landed.size(), 3u);
  EXPECT_EQ(landed[0], 30.0);
  EXPECT_EQ(landed[1], 120.0);
  EXPECT_EQ(landed[2], -45.0);
  EXPECT_EQ(w.sp.back().rotary_deg, -45.0);
  EXPECT_TRUE(w.sp.back().done);
  // The G1 index at F1200 deg/min: its profile's peak is the feed, not the axis's maximum.
  EXPECT_NEAR(job.indexes()[2].profile.peak_speed_deg_per_s(), 20.0, 1e-9);
  // The first setpoint after each index is a planner period from rest at the same place.
  for (std::size_t i = 1; i + 1 < w.sp.size(); ++i) {
    if (w.sp[i].limit_id == kLimitIdIndex && !w.sp[i].indexing) {
      EXPECT_EQ(w.sp[i].p, w.sp[i - 1].p);
    }
  }
}

TEST(RotaryIndexJob, APathTurningAnAxisTheMachineLacksIsRefused) {
  const toolpath::Path path = indexed_path('b');
  try {
    Job job(path, config_with('a'));
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("turns B"), std::string::npos) << what;
    EXPECT_NE(what.find("[axis.b]"), std::string::npos) << what;
  }
  try {
    Job job(path, JobConfig{});
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no rotary axis"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace ncd::motion
