// Per-axis limits (docs/planner.md §3f): the machine file's [axis.x|y|z] feed, acceleration and
// jerk, each held by every axis along the walked path, the path limits a further cap.
//
// Checked from the setpoints alone (their differences |Δp_i|/T, |Δ²p_i|/T², |Δ³p_i|/T³, as the
// property suites check the path's), never from the job's reports of itself:
//   - a Z plunge, a diagonal and a 3D helix are each timed by their slowest axis: against the
//     time-optimal rest-to-rest motion under |v| ≤ V, |a| ≤ A, |j| ≤ J (a closed form computed
//     here), with V, A, J what the slowest axis allows along the direction (a lower bound for
//     any motion within the limits; for the helix a phase-plane bound from Z's exact share of
//     the motion and the speed caps every point must keep);
//   - random programs (tests/common/random_program.hpp) under random per-axis limits: the worst
//     ratio of an axis's peak to its limit, and the duration against an independent lower
//     bound (the time at each point's speed cap), seed printed.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "gcode/ngc/interpreter.hpp"
#include "gcode/program.hpp"
#include "motion/job.hpp"
#include "tests/common/random_program.hpp"
#include "tests/common/sanitized.hpp"
#include "tests/common/seed.hpp"
#include "tests/motion/planner_machine.hpp"
#include "tests/motion/reference.hpp"

namespace ncd {
namespace {

using motion::Job;
using motion::JobConfig;
using toolpath::Path;

constexpr double kInf = std::numeric_limits<double>::infinity();

// The walked motion: every setpoint's position (the start first) and the duration.
struct Walk {
  std::vector<Vec3> p;
  std::vector<motion::Setpoint> sp;  // (the start has none: sp[k - 1] is p[k]'s)
  double duration_s = 0.0;
  std::string fault;
};

Walk walk(const Path& path, const JobConfig& cfg, std::size_t cap = 3'000'000) {
  Walk w;
  Job job(path, cfg);
  w.p.push_back(job.path().segments.empty() ? Vec3::Zero() : test::tabulate(job.path(), 1.0).p[0]);
  while (!job.done()) {
    if (w.p.size() > cap) {
      w.fault = "not done after " + std::to_string(cap) + " periods";
      return w;
    }
    job.prepare();
    const motion::Setpoint sp = job.step();
    if (sp.fault != motion::StepFault::None) {
      w.fault = "step fault: " + job.fault_message();
      return w;
    }
    w.p.push_back(sp.p);
    w.sp.push_back(sp);
    w.duration_s = sp.t_s;
  }
  return w;
}

// The largest |Δ^k p_i| / T^k of each axis (k = 1, 2, 3), divided by the axis's limit: the
// worst of the three axes for each k.
struct AxisRatios {
  std::array<double, 3> feed{}, accel{}, jerk{};  // per axis, peak / limit (0 without a limit)
  std::array<double, 3> feed_peak{}, accel_peak{}, jerk_peak{};  // mm/s, mm/s², mm/s³
  double worst(int k) const {
    const auto& a = k == 1 ? feed : (k == 2 ? accel : jerk);
    return *std::max_element(a.begin(), a.end());
  }
};

AxisRatios axis_ratios(const std::vector<Vec3>& p, const JobConfig& cfg) {
  AxisRatios r;
  const double T = cfg.limits.period_s;
  for (std::size_t k = 1; k < p.size(); ++k) {
    for (int i = 0; i < 3; ++i) {
      const auto a = static_cast<std::size_t>(i);
      const auto& ax = cfg.limits.axes[a];
      const double v = std::abs(p[k][i] - p[k - 1][i]) / T;
      r.feed_peak[a] = std::max(r.feed_peak[a], v);
      if (k >= 2) {
        const double acc = std::abs(p[k][i] - 2.0 * p[k - 1][i] + p[k - 2][i]) / (T * T);
        r.accel_peak[a] = std::max(r.accel_peak[a], acc);
      }
      if (k >= 3) {
        const double j =
            std::abs(p[k][i] - 3.0 * p[k - 1][i] + 3.0 * p[k - 2][i] - p[k - 3][i]) / (T * T * T);
        r.jerk_peak[a] = std::max(r.jerk_peak[a], j);
      }
      r.feed[a] = r.feed_peak[a] / (ax.max_feed_mm_per_min / 60.0);
      r.accel[a] = r.accel_peak[a] / ax.max_accel_mm_per_s2;
      r.jerk[a] = r.jerk_peak[a] / ax.max_jerk_mm_per_s3;
    }
  }
  return r;
}

// The time-optimal rest-to-rest motion over D under |v| ≤ V, |a| ≤ A, |j| ≤ J: a symmetric
// S-curve. Rising to a peak w takes t(w) = w/A + A/J (w ≥ A²/J) or 2 sqrt(w/J), over w t(w)/2;
// if the distance holds both ramps at V it cruises, else the peak w solves w t(w) = D.
double scurve_time_s(double D, double V, double A, double J) {
  const auto rise_s = [&](double w) {
    return w * J >= A * A ? w / A + A / J : 2.0 * std::sqrt(w / J);
  };
  if (V * rise_s(V) <= D) return 2.0 * rise_s(V) + (D - V * rise_s(V)) / V;
  double lo = 0.0, hi = V;
  for (int it = 0; it < 200; ++it) {
    const double mid = 0.5 * (lo + hi);
    (mid * rise_s(mid) <= D ? lo : hi) = mid;
  }
  return 2.0 * rise_s(lo);
}

Path ngc_path(const std::string& program) {
  toolpath::InterpretOptions opt;
  return toolpath::to_path(toolpath::interpret_ngc(program, "axis_limits.ngc", opt));
}

// The planner machine with Z at a quarter of the path's speed and acceleration and a fifth of
// its jerk, and X at 60 % of its acceleration.
JobConfig slow_z_machine() {
  JobConfig c = test::planner_machine();
  c.limits.axes[2] = {1500.0, 250.0, 4000.0};
  c.limits.axes[0].max_accel_mm_per_s2 = 600.0;
  return c;
}

void expect_within_axis_limits(const Walk& w, const JobConfig& cfg, bool jerk = true) {
  const AxisRatios r = axis_ratios(w.p, cfg);
  EXPECT_LE(r.worst(1), 1.0 + 1e-9);
  EXPECT_LE(r.worst(2), 1.0 + 1e-9);
  if (jerk) {
    EXPECT_LE(r.worst(3), 1.0 + 1e-9);
  }
}

// A Z plunge of 20 mm at F6000: Z's 25 mm/s, 250 mm/s² and 4000 mm/s³ time it.
TEST(AxisLimits, ZPlungeIsTimedByZ) {
  const JobConfig cfg = slow_z_machine();
  const Walk w = walk(ngc_path("G21 G90 G0 X0 Y0 Z0\nG1 Z-20 F6000\nM2\n"), cfg);
  ASSERT_TRUE(w.fault.empty()) << w.fault;
  const double bound = scurve_time_s(20.0, 25.0, 250.0, 4000.0);
  const double path_only = scurve_time_s(20.0, 100.0, 1000.0, 20000.0);
  std::printf("plunge: %.4f s, bound from Z %.4f s (%.4fx); path limits alone %.4f s\n",
              w.duration_s, bound, w.duration_s / bound, path_only);
  EXPECT_GE(w.duration_s, bound * (1.0 - 1e-9));
  EXPECT_LE(w.duration_s, bound * 1.01 + 2.0 * cfg.limits.period_s);
  const AxisRatios r = axis_ratios(w.p, cfg);
  EXPECT_GT(r.feed[2], 0.999);  // Z reaches its own speed: it binds
  expect_within_axis_limits(w, cfg);
}

// A diagonal (30, −20, −10) mm: each limit's slowest axis differs. Speed: X 100/(30/l), Z
// 25/(10/l); acceleration: X 600/(30/l), Z 250/(10/l); jerk: Z 4000/(10/l).
TEST(AxisLimits, DiagonalIsTimedByItsSlowestAxes) {
  const JobConfig cfg = slow_z_machine();
  const Walk w = walk(ngc_path("G21 G90 G0 X0 Y0 Z0\nG1 X30 Y-20 Z-10 F6000\nM2\n"), cfg);
  ASSERT_TRUE(w.fault.empty()) << w.fault;
  const Vec3 t = Vec3(30.0, -20.0, -10.0).normalized();
  const double l = std::sqrt(30.0 * 30.0 + 20.0 * 20.0 + 10.0 * 10.0);
  double V = 100.0, A = 1000.0, J = 20000.0;
  for (int i = 0; i < 3; ++i) {
    const auto& ax = cfg.limits.axes[static_cast<std::size_t>(i)];
    V = std::min(V, ax.max_feed_mm_per_min / 60.0 / std::abs(t[i]));
    A = std::min(A, ax.max_accel_mm_per_s2 / std::abs(t[i]));
    J = std::min(J, ax.max_jerk_mm_per_s3 / std::abs(t[i]));
  }
  const double bound = scurve_time_s(l, V, A, J);
  std::printf("diagonal: %.4f s, bound %.4f s (%.4fx; V %.3f mm/s, A %.1f mm/s2, J %.0f mm/s3)\n",
              w.duration_s, bound, w.duration_s / bound, V, A, J);
  EXPECT_GE(w.duration_s, bound * (1.0 - 1e-9));
  EXPECT_LE(w.duration_s, bound * 1.01 + 2.0 * cfg.limits.period_s);
  expect_within_axis_limits(w, cfg);
}

// A helix of radius 5 mm and 10 mm pitch, three turns down, under a Z of 300 mm/min: the
// helix's Z is exactly s sin(α) (its normal is horizontal), so no motion within Z's limits
// is faster than the S-curve under V = vz / sin α, A = az / sin α, J = jz / sin α; every
// point also caps the speed at vx / |t_x| (cos α where t_x is largest), at sqrt(a_x / κ)
// where t_x = 0 (the acceleration is then all centripetal) and at the path's laws.
TEST(AxisLimits, HelixIsTimedByZ) {
  JobConfig cfg = test::planner_machine();
  cfg.limits.axes[2] = {300.0, 60.0, 1500.0};
  const double R = 5.0, pitch = 10.0, turns = 3.0;
  const Walk w =
      walk(ngc_path("G21 G90 G17 G0 X5 Y0 Z0\nG2 X5 Y0 Z-30 I-5 J0 P3 F6000\nM2\n"), cfg);
  ASSERT_TRUE(w.fault.empty()) << w.fault;
  const double turn_len = std::hypot(2.0 * std::numbers::pi * R, pitch);
  const double sin_a = pitch / turn_len, cos_a = 2.0 * std::numbers::pi * R / turn_len;
  const double kappa = cos_a * cos_a / R;
  const auto& z = cfg.limits.axes[2];
  const auto& l = cfg.limits;
  const double eps = l.chord_tolerance_mm, rho = 1.0 / kappa;
  const double V = std::min({z.max_feed_mm_per_min / 60.0 / sin_a, l.max_feed_mm_per_min / 60.0,
                             std::sqrt(l.max_accel_mm_per_s2 / kappa),
                             std::cbrt(l.max_jerk_mm_per_s3 / (kappa * kappa)),
                             2.0 * std::sqrt(2.0 * rho * eps - eps * eps) / l.period_s});
  const double A = std::min(z.max_accel_mm_per_s2 / sin_a, l.max_accel_mm_per_s2);
  const double J = std::min(z.max_jerk_mm_per_s3 / sin_a, l.max_jerk_mm_per_s3);
  const double bound = scurve_time_s(turns * turn_len, V, A, J);
  const AxisRatios r = axis_ratios(w.p, cfg);
  std::printf(
      "helix: %.4f s, bound %.4f s (%.4fx; V %.3f mm/s, A %.1f mm/s2, J %.0f mm/s3); "
      "Z peaks %.3f mm/s, %.2f mm/s2, %.1f mm/s3\n",
      w.duration_s, bound, w.duration_s / bound, V, A, J, r.feed_peak[2], r.accel_peak[2],
      r.jerk_peak[2]);
  EXPECT_NEAR(V, z.max_feed_mm_per_min / 60.0 / sin_a, 1e-12);  // Z is the slowest
  EXPECT_GE(w.duration_s, bound * (1.0 - 1e-9));
  EXPECT_LE(w.duration_s, bound * 1.03);
  EXPECT_GT(r.feed[2], 0.999);
  expect_within_axis_limits(w, cfg);
}

// A G1 into a G3 of R 10 mm at F3000 under [axis.x|y] max_jerk_mm_per_s3 = 5000, the default
// (tangential) jerk bound: the centripetal acceleration v²/R appears where the line meets the
// arc, a jump of the curvature vector along X. The per-axis jump law slows the joint so that
// X's third difference stays within 5000 (before it: 46 382 mm/s³), and so do the arc's end
// and the line after it.
TEST(AxisLimits, LineIntoArcKeepsEveryAxissJerk) {
  JobConfig cfg = test::planner_machine();
  cfg.limits.axes[0].max_jerk_mm_per_s3 = 5000.0;
  cfg.limits.axes[1].max_jerk_mm_per_s3 = 5000.0;
  ASSERT_EQ(cfg.limits.jerk_bound, feed::JerkBound::tangential);
  const Walk w = walk(ngc_path("G21 G90 G17 G0 X0 Y0 Z0\nG1 X20 Y0 F3000\n"
                               "G3 X30 Y10 I0 J10\nG1 Y30\nM2\n"),
                      cfg);
  ASSERT_TRUE(w.fault.empty()) << w.fault;
  const AxisRatios r = axis_ratios(w.p, cfg);
  std::printf("G1 into G3 R10 at F3000: %.4f s; X jerk %.1f, Y jerk %.1f mm/s3 (limit 5000)\n",
              w.duration_s, r.jerk_peak[0], r.jerk_peak[1]);
  EXPECT_LE(r.jerk[0], 1.0 + 1e-9);
  EXPECT_LE(r.jerk[1], 1.0 + 1e-9);
  expect_within_axis_limits(w, cfg);
}

// Without [axis.*] the job is the one it was: the same setpoints, bit for bit, as a machine whose
// axis limits are all +inf (the default) — and an axis limit above every path limit changes
// nothing either on a line along that axis.
TEST(AxisLimits, AxisLimitsAboveThePathsLeaveALineAsItWas) {
  const Path path = ngc_path("G21 G90 G0 X0 Y0 Z0\nG1 X40 F6000\nM2\n");
  JobConfig loose = test::planner_machine();
  loose.limits.axes[0] = {12000.0, 5000.0, 1e5};
  const Walk a = walk(path, test::planner_machine()), b = walk(path, loose);
  ASSERT_EQ(a.p.size(), b.p.size());
  for (std::size_t k = 0; k < a.p.size(); ++k) ASSERT_EQ(a.p[k], b.p[k]) << k;
}

// Where an axis's acceleration (order 2: second difference) or jerk (3: third difference)
// first exceeds its limit, for the message.
std::string first_excess(const Walk& w, const JobConfig& cfg, int order) {
  const double T = cfg.limits.period_s;
  for (std::size_t k = static_cast<std::size_t>(order); k < w.p.size(); ++k) {
    for (int i = 0; i < 3; ++i) {
      const auto& ax = cfg.limits.axes[static_cast<std::size_t>(i)];
      const double lim = order == 2 ? ax.max_accel_mm_per_s2 : ax.max_jerk_mm_per_s3;
      const double d = order == 2
                           ? w.p[k][i] - 2.0 * w.p[k - 1][i] + w.p[k - 2][i]
                           : w.p[k][i] - 3.0 * w.p[k - 1][i] + 3.0 * w.p[k - 2][i] - w.p[k - 3][i];
      const double value = std::abs(d) / std::pow(T, order);
      if (value > lim * (1.0 + 1e-9)) {
        const motion::Setpoint& q = w.sp[k - 1];
        char text[280];
        std::snprintf(text, sizeof text,
                      "axis %c %.6f mm/s%d (limit %.6g) at setpoint %zu, s = %.6f mm, walked "
                      "segment %zu, v %.4f mm/s, a %.3f mm/s2, limit %s%s",
                      static_cast<char>('X' + i), value, order, lim, k, q.s_mm, q.segment,
                      q.v_mm_per_s, q.a_mm_per_s2, motion::limit_name(q.limit_id),
                      q.overlapped ? ", overlapped" : "");
        return text;
      }
    }
  }
  return "none";
}

// The lower bound on a program's duration: each point's speed cap (the F word or the machine's
// maximum, and min_i vmax_i / |t_i|), integrated over the walked geometry sampled every 5 µm.
double duration_bound_s(const Path& walked, const JobConfig& cfg) {
  double t = 0.0;
  for (const auto& s : walked.segments) {
    Path one;
    one.segments = {s};
    const test::GeometryTable g = test::tabulate(one, 0.005);
    double cap = cfg.limits.max_feed_mm_per_min / 60.0;
    if (!s.rapid && s.feed_mm_per_min) cap = std::min(cap, *s.feed_mm_per_min / 60.0);
    for (std::size_t k = 1; k < g.s_mm.size(); ++k) {
      const double ds = g.s_mm[k] - g.s_mm[k - 1];
      if (!(ds > 0.0)) continue;
      const Vec3 d = (g.p[k] - g.p[k - 1]) / ds;
      double v = cap;
      for (int i = 0; i < 3; ++i) {
        const double ti = std::min(std::abs(d[i]), 1.0);
        if (ti > 0.0) {
          v = std::min(
              v, cfg.limits.axes[static_cast<std::size_t>(i)].max_feed_mm_per_min / 60.0 / ti);
        }
      }
      t += ds / v;
    }
  }
  return t;
}

// The planner machine with random per-axis limits: each axis given each limit with probability
// 3/4, from a tenth of the path's to above it.
JobConfig random_axis_machine(std::mt19937_64& rng) {
  const auto uni = [&rng](double a, double b) {
    return std::uniform_real_distribution<double>(a, b)(rng);
  };
  JobConfig cfg = test::planner_machine();
  for (auto& ax : cfg.limits.axes) {
    if (uni(0, 1) < 0.75)
      ax.max_feed_mm_per_min = 6000.0 * std::exp(uni(std::log(0.1), std::log(1.5)));
    if (uni(0, 1) < 0.75)
      ax.max_accel_mm_per_s2 = 1000.0 * std::exp(uni(std::log(0.1), std::log(1.5)));
    if (uni(0, 1) < 0.75)
      ax.max_jerk_mm_per_s3 = 20000.0 * std::exp(uni(std::log(0.1), std::log(1.5)));
  }
  return cfg;
}

// The generator's next program, from the origin along X, at the machine's feed.
Path program_from_origin(test::RandomProgram& g) {
  g.at = Vec3::Zero();
  g.heading = Vec3::UnitX();
  g.max_feed_mm_per_min = 0.0;
  return g.program();
}

// Random programs under random per-axis limits (each axis given a limit with probability 3/4,
// from a tenth of the path's to above it). Every axis keeps its feed and acceleration, from the
// setpoints' differences, within 1 + 1e-9; the duration is at least the independent bound.
TEST(AxisLimits, RandomProgramsKeepEveryAxisWithinItsLimits) {
  const std::uint64_t seed = test::seed();
  int programs = test::sweep_cases(60);  // NCD_PROPERTY_PROGRAMS sets how many
  if (const char* env = std::getenv("NCD_PROPERTY_PROGRAMS")) programs = std::atoi(env);
  test::RandomProgram g{std::mt19937_64(seed)};
  std::mt19937_64 rng(seed ^ 0x5eedULL);
  double worst_feed = 0.0, worst_accel = 0.0, worst_jerk = 0.0;
  double ratio_sum = 0.0, ratio_min = kInf, ratio_max = 0.0;
  for (int n = 0; n < programs; ++n) {
    JobConfig cfg = random_axis_machine(rng);
    const Path path = program_from_origin(g);
    const Walk w = walk(path, cfg);
    ASSERT_TRUE(w.fault.empty()) << "program " << n << " of seed " << seed << ": " << w.fault;
    const AxisRatios r = axis_ratios(w.p, cfg);
    worst_feed = std::max(worst_feed, r.worst(1));
    worst_accel = std::max(worst_accel, r.worst(2));
    worst_jerk = std::max(worst_jerk, r.worst(3));
    EXPECT_LE(r.worst(1), 1.0 + 1e-9) << "program " << n << " of seed " << seed;
    EXPECT_LE(r.worst(2), 1.0 + 1e-9)
        << "program " << n << " of seed " << seed << ": " << first_excess(w, cfg, 2);
    EXPECT_LE(r.worst(3), 1.0 + 1e-9)
        << "program " << n << " of seed " << seed << ": " << first_excess(w, cfg, 3);
    const double bound = duration_bound_s(Job(path, cfg).path(), cfg);
    const double ratio = w.duration_s / bound;
    EXPECT_GE(ratio, 1.0 - 1e-6) << "program " << n << " of seed " << seed;
    ratio_sum += ratio;
    ratio_min = std::min(ratio_min, ratio);
    ratio_max = std::max(ratio_max, ratio);
  }
  std::printf(
      "%d programs: worst axis ratio feed %.12f, accel %.12f, jerk %.12f; duration / "
      "bound mean %.3f, min %.3f, max %.3f\n",
      programs, worst_feed, worst_accel, worst_jerk, ratio_sum / programs, ratio_min, ratio_max);
}

// The recipe for drives that trip on axis jerk (docs/planner.md §3f): the jerk vector bounded
// by the smallest axis jerk (feed::with_axis_jerk: jerk_bound = "vector",
// max_jerk_mm_per_s3 = min_i j_i). Each axis's jerk is a component of the vector: random
// programs under random per-axis limits keep every axis's feed, acceleration and jerk, from the
// setpoints' differences, within 1 + 1e-9 of its limit.
TEST(AxisLimits, TheVectorBoundAtTheSmallestAxisJerkHoldsEveryAxissJerk) {
  const std::uint64_t seed = test::seed();
  const int programs = test::sweep_cases(40);
  test::RandomProgram g{std::mt19937_64(seed)};
  std::mt19937_64 rng(seed ^ 0x5eedULL);
  double worst_feed = 0.0, worst_accel = 0.0, worst_jerk = 0.0;
  for (int n = 0; n < programs; ++n) {
    JobConfig cfg = random_axis_machine(rng);
    cfg.limits = feed::with_axis_jerk(cfg.limits);
    const Path path = program_from_origin(g);
    const Walk w = walk(path, cfg);
    ASSERT_TRUE(w.fault.empty()) << "program " << n << " of seed " << seed << ": " << w.fault;
    const AxisRatios r = axis_ratios(w.p, cfg);
    worst_feed = std::max(worst_feed, r.worst(1));
    worst_accel = std::max(worst_accel, r.worst(2));
    worst_jerk = std::max(worst_jerk, r.worst(3));
    EXPECT_LE(r.worst(1), 1.0 + 1e-9) << "program " << n << " of seed " << seed;
    EXPECT_LE(r.worst(2), 1.0 + 1e-9) << "program " << n << " of seed " << seed;
    EXPECT_LE(r.worst(3), 1.0 + 1e-9) << "program " << n << " of seed " << seed;
  }
  std::printf(
      "%d programs (vector bound at the smallest axis jerk): worst axis ratio feed %.12f, "
      "accel %.12f, jerk %.12f\n",
      programs, worst_feed, worst_accel, worst_jerk);
}

}  // namespace
}  // namespace ncd
