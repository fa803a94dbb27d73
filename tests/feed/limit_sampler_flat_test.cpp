// Flat intervals (feed/limit_sampler.cpp, docs/planner.md "Flat intervals"): where a
// curvature bound proves the limit is the cap all along an interval, the sampler skips the
// search for its minimum. The node stream must be the same bit for bit as the one of the full
// search (SamplerConfig::skip_flat_intervals = false, the reference kept in the sampler): on
// the spiral, with the cap from the machine, from a program F, on a rapid, where the curvature
// laws bind, on rational curves (never skipped), on curves with double knots, and on random
// B-splines of degrees 2–5 (the seed is printed).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <iostream>
#include <limits>
#include <random>
#include <vector>

#include "feed/limit_sampler.hpp"
#include "feed/path_walker.hpp"
#include "gcode/path_io.hpp"
#include "geometry/spiral.hpp"
#include "tests/common/sanitized.hpp"
#include "tests/common/seed.hpp"

namespace ncd::feed {
namespace {

struct Stream {
  std::vector<LimitNode> nodes;
  std::size_t intervals = 0, flat = 0, turn_skips = 0;
};

Stream sample(const toolpath::Path& path, const MachineLimits& limits, bool skip) {
  const PathWalker walker(path, WalkerConfig{});
  std::vector<double> starts;
  for (std::size_t k = 0; k <= path.segments.size(); ++k) {
    starts.push_back(walker.segment_start_mm(k));
  }
  CuttingParams cutting;
  cutting.teeth = 4;
  cutting.spindle_rpm = 12000.0;
  SamplerConfig config;
  config.skip_flat_intervals = skip;
  LimitSampler sampler(path, starts, limits, cutting, config);
  Stream out;
  LimitNode node;
  while (sampler.next(node)) out.nodes.push_back(node);
  out.intervals = sampler.curve_intervals();
  out.flat = sampler.flat_intervals();
  out.turn_skips = sampler.axis_turn_skips();
  return out;
}

// Compares the stream `fast` (the skips on) with the reference's node by node, exactly; returns
// the skipped share.
double expect_same_nodes(const Stream& fast, const toolpath::Path& path,
                         const MachineLimits& limits, const std::string& what) {
  const Stream slow = sample(path, limits, false);
  EXPECT_EQ(slow.flat, 0u) << what;
  EXPECT_EQ(slow.turn_skips, 0u) << what;
  EXPECT_EQ(fast.intervals, slow.intervals) << what;
  EXPECT_EQ(fast.nodes.size(), slow.nodes.size()) << what;
  const std::size_t n = std::min(fast.nodes.size(), slow.nodes.size());
  int reported = 0;
  for (std::size_t i = 0; i < n && reported < 5; ++i) {
    const LimitNode& a = fast.nodes[i];
    const LimitNode& b = slow.nodes[i];
    const bool same = a.s_mm == b.s_mm && a.feed_mm_per_s == b.feed_mm_per_s &&
                      a.limit == b.limit && a.left_mm_per_s == b.left_mm_per_s &&
                      a.right_mm_per_s == b.right_mm_per_s && a.right_limit == b.right_limit &&
                      a.axis_scale.accel == b.axis_scale.accel &&
                      a.axis_scale.jerk == b.axis_scale.jerk;
    if (!same) {
      ++reported;
      ADD_FAILURE() << what << ": node " << i << " differs: s " << a.s_mm << " / " << b.s_mm
                    << ", feed " << a.feed_mm_per_s << " / " << b.feed_mm_per_s << ", limit "
                    << to_string(a.limit) << " / " << to_string(b.limit);
    }
  }
  return fast.intervals > 0 ? static_cast<double>(fast.flat) / static_cast<double>(fast.intervals)
                            : 0.0;
}

double expect_same_nodes(const toolpath::Path& path, const MachineLimits& limits,
                         const std::string& what) {
  return expect_same_nodes(sample(path, limits, true), path, limits, what);
}

toolpath::Path from_json(const char* json) {
  return toolpath::read_path_text(json, "test.json");
}

TEST(LimitSamplerFlat, SpiralAtTheMachineCapSkipsAlmostEveryInterval) {
  const toolpath::Path path = toolpath::spiral_path(3);
  const double share = expect_same_nodes(path, MachineLimits{}, "spiral, 6000 mm/min");
  // 100 mm/s against chord ≈ 210, accel ≈ 300, roughness ≥ 105 mm/s at r ≥ 99.7 mm.
  EXPECT_GT(share, 0.95);
}

TEST(LimitSamplerFlat, ProgramFeedAndRapidCaps) {
  toolpath::Path path = toolpath::spiral_path(2);
  path.segments[0].feed_mm_per_min = 3000.0;
  EXPECT_GT(expect_same_nodes(path, MachineLimits{}, "spiral, F3000"), 0.95);
  path.segments[0].feed_mm_per_min = 6000.0;  // equal to the machine's: MaxFeed wins ties
  EXPECT_GT(expect_same_nodes(path, MachineLimits{}, "spiral, F6000"), 0.95);
  path.segments[0].feed_mm_per_min.reset();
  path.segments[0].rapid = true;
  MachineLimits fast;
  fast.max_feed_mm_per_min = 9000.0;  // above the roughness law, which a rapid ignores
  EXPECT_GT(expect_same_nodes(path, fast, "spiral, G0 at 9000"), 0.9);
}

TEST(LimitSamplerFlat, WhereTheCurvatureLawsBindNothingIsSkipped) {
  const toolpath::Path path = toolpath::spiral_path(2);
  MachineLimits limits;
  limits.max_feed_mm_per_min = 30000.0;  // 500 mm/s: roughness and chord bind everywhere
  EXPECT_EQ(expect_same_nodes(path, limits, "spiral, 30000 mm/min"), 0.0);
  limits.max_feed_mm_per_min = 6000.0;
  limits.chord_tolerance_mm = 1e-5;  // chord feed ≈ 21 mm/s at r = 100 mm
  EXPECT_EQ(expect_same_nodes(path, limits, "spiral, 0.01 um chord"), 0.0);
}

TEST(LimitSamplerFlat, RationalCurvesAndSharpKnotsAreNeverSkipped) {
  // The rational circle of radius 20 mm (double knots) and a cubic with a knot of full
  // multiplicity (a corner): no bound is claimed, and the nodes are the reference's.
  const char* circle = R"({"nurbs": {"degree": 2,
    "knots": [0,0,0,0.25,0.25,0.5,0.5,0.75,0.75,1,1,1],
    "points": [[200,0,0],[200,200,0],[0,200,0],[-200,200,0],[-200,0,0],[-200,-200,0],
               [0,-200,0],[200,-200,0],[200,0,0]],
    "weights": [1,0.7071067811865476,1,0.7071067811865476,1,0.7071067811865476,1,
                0.7071067811865476,1]}})";
  EXPECT_EQ(expect_same_nodes(from_json(circle), MachineLimits{}, "rational circle"), 0.0);
  const char* corner = R"({"nurbs": {"degree": 3, "knots": [0,0,0,0,1,1,1,2,2,2,2],
    "points": [[0,0,0],[100,0,0],[200,0,0],[300,0,0],[300,100,0],[300,200,0],[300,300,0]]}})";
  EXPECT_EQ(expect_same_nodes(from_json(corner), MachineLimits{}, "cubic with a corner knot"), 0.0);
}

TEST(LimitSamplerFlat, StraightAndGentleCurvesWithDoubleKnots) {
  // Degree 3 with a double interior knot (C¹, so the bound holds across it); a nearly straight
  // quadratic; a degree-5 curve. Long spans at a low curvature: mostly flat.
  const char* doubled = R"({"nurbs": {"degree": 3, "knots": [0,0,0,0,1,2,2,3,4,4,4,4],
    "points": [[0,0,0],[100,10,0],[200,0,1],[300,15,0],[400,0,0],[500,10,2],[600,0,0],
               [700,5,0]]}})";
  EXPECT_GT(expect_same_nodes(from_json(doubled), MachineLimits{}, "cubic, double knot"), 0.5);
  const char* line = R"({"nurbs": {"degree": 2, "knots": [0,0,0,1,2,2,2],
    "points": [[0,0,0],[50,0,0],[100,1e-9,0],[150,0,0]]}})";
  EXPECT_GT(expect_same_nodes(from_json(line), MachineLimits{}, "nearly straight quadratic"), 0.9);
  const char* quintic = R"({"nurbs": {"degree": 5, "knots": [0,0,0,0,0,0,1,2,3,3,3,3,3,3],
    "points": [[0,0,0],[80,20,0],[160,-10,5],[240,30,0],[320,0,-5],[400,25,0],[480,0,0],
               [560,10,0]]}})";
  EXPECT_GT(expect_same_nodes(from_json(quintic), MachineLimits{}, "quintic"), 0.3);
}

// A random B-spline of degree 2–5 (p), tight on even trials and gentle on odd ones, now and
// then with repeated knots; f (0–3) picks the cap: the machine's, F2400, a rapid, F12000.
toolpath::Path random_bspline(std::mt19937_64& rng, int trial, int& p, int& f) {
  std::uniform_real_distribution<double> coord(-100.0, 100.0), gap(0.2, 2.0);
  std::uniform_int_distribution<int> degree_of(2, 5), extra_of(0, 6), feed_of(0, 3);
  {
    p = degree_of(rng);
    const int n = p + 1 + extra_of(rng);  // control points
    std::vector<double> k2(static_cast<std::size_t>(p + 1), 0.0);
    double u = 0.0;
    int run = 0;
    for (int i = 0; i < n - p - 1; ++i) {
      // Now and then a repeated interior knot: up to p − 1 times (C¹, eligible) or p (a
      // corner, not).
      if (i > 0 && run < p && rng() % 4 == 0) {
        ++run;
      } else {
        u += gap(rng);
        run = 1;
      }
      k2.push_back(u);
    }
    u += gap(rng);
    for (int i = 0; i <= p; ++i) k2.push_back(u);
    std::vector<Vec3> pts;
    const double scale = trial % 2 == 0 ? 1.0 : 5.0;  // tight curves and gentle ones
    for (std::size_t i = 0; i + static_cast<std::size_t>(p) + 1 < k2.size(); ++i) {
      pts.emplace_back(scale * coord(rng), scale * coord(rng), 0.1 * coord(rng));
    }
    toolpath::Path path;
    toolpath::PathSegment seg;
    seg.geometry = toolpath::NurbsCurve(p, k2, pts);
    f = feed_of(rng);
    if (f == 1) seg.feed_mm_per_min = 2400.0;
    if (f == 2) seg.rapid = true;
    path.segments.push_back(std::move(seg));
    return path;
  }
}

TEST(LimitSamplerFlat, RandomBSplinesGiveTheReferenceNodes) {
  const std::uint64_t seed = test::seed();
  std::mt19937_64 rng(seed);
  std::size_t flat = 0, total = 0;
  // Under the sanitizers a quarter of the curves (docs/testing.md, "The heaviest sweeps"): six,
  // three tight and three gentle, enough for both the skip and the search to run.
  const int trials = test::kSanitized ? 6 : 24;
  for (int trial = 0; trial < trials; ++trial) {
    int p = 0, f = 0;
    const toolpath::Path path = random_bspline(rng, trial, p, f);
    MachineLimits limits;
    if (f == 3) limits.max_feed_mm_per_min = 12000.0;
    const Stream fast = sample(path, limits, true);
    flat += fast.flat;
    total += fast.intervals;
    expect_same_nodes(fast, path, limits,
                      "random curve " + std::to_string(trial) + " (degree " + std::to_string(p) +
                          ", seed " + std::to_string(seed) + ")");
  }
  std::cout << "[ flat     ] " << flat << " of " << total << " curve intervals\n";
  EXPECT_GT(flat, total / 4) << "seed " << seed;  // the skip is exercised
  EXPECT_LT(flat, total) << "seed " << seed;      // and so is the search
}

// Per-axis limits (docs/planner.md §3f): the flat test bounds each axis's tangent and curvature
// components, and under per-axis jerk the nine-point curve sampling is left out where the
// span's bounds prove the axes' curve-jerk law idle. Both must leave every node as the
// reference's: on the spiral under examples/machine-slow-z.toml's Z and with X and Y at
// 10 000 mm/s³ besides, and on random B-splines under random axis limits (seed printed).
MachineLimits slow_z_limits() {
  MachineLimits limits;
  limits.axes[2].max_feed_mm_per_min = 1500.0;
  limits.axes[2].max_accel_mm_per_s2 = 250.0;
  limits.axes[2].max_jerk_mm_per_s3 = 4000.0;
  return limits;
}

TEST(LimitSamplerFlat, PerAxisLimitsOnTheSpiral) {
  const toolpath::Path path = toolpath::spiral_path(3);
  MachineLimits limits = slow_z_limits();
  // Z's share of the spiral's tangent is about 0.001: its 25 mm/s allow 25 000 mm/s there.
  EXPECT_GT(expect_same_nodes(path, limits, "spiral, slow Z"), 0.95);
  limits.axes[0].max_jerk_mm_per_s3 = limits.axes[1].max_jerk_mm_per_s3 = 10000.0;
  EXPECT_GT(expect_same_nodes(path, limits, "spiral, slow Z, X/Y jerk 10000"), 0.95);
  const Stream s = sample(path, limits, true);
  // (85 % on 3 turns: the clamped end spans' hulls are loose; the 100-turn spiral's ends are
  // a smaller share.)
  EXPECT_GT(s.turn_skips, s.intervals * 80 / 100) << s.turn_skips << " of " << s.intervals;
  // Where the axes' jerk binds on the curve (X and Y at 3000 mm/s³: 3 v a k_x alone is about
  // 3300 at the cap), nothing is left out.
  limits.axes[0].max_jerk_mm_per_s3 = limits.axes[1].max_jerk_mm_per_s3 = 3000.0;
  expect_same_nodes(path, limits, "spiral, X/Y jerk 3000");
  EXPECT_EQ(sample(path, limits, true).turn_skips, 0u);
}

TEST(LimitSamplerFlat, RandomBSplinesUnderAxisLimitsGiveTheReferenceNodes) {
  const std::uint64_t seed = test::seed();
  std::mt19937_64 rng(seed ^ 0x5a5a5a5aULL);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::size_t flat = 0, skips = 0, total = 0;
  const int trials = test::kSanitized ? 6 : 30;  // two of each kind of limits under the sanitizers
  for (int trial = 0; trial < trials; ++trial) {
    int p = 0, f = 0;
    const toolpath::Path path = random_bspline(rng, trial, p, f);
    MachineLimits limits = slow_z_limits();
    if (f == 3) limits.max_feed_mm_per_min = 12000.0;
    if (trial % 3 >= 1) {
      limits.axes[0].max_jerk_mm_per_s3 = limits.axes[1].max_jerk_mm_per_s3 = 10000.0;
    }
    if (trial % 3 == 2) {  // every axis random, some limits left out
      for (AxisLimits& ax : limits.axes) {
        const double inf = std::numeric_limits<double>::infinity();
        ax.max_feed_mm_per_min = unit(rng) < 0.3 ? inf : 600.0 + 5400.0 * unit(rng);
        ax.max_accel_mm_per_s2 = unit(rng) < 0.3 ? inf : 100.0 + 900.0 * unit(rng);
        ax.max_jerk_mm_per_s3 = unit(rng) < 0.2 ? inf : 1000.0 + 19000.0 * unit(rng);
      }
    }
    const Stream fast = sample(path, limits, true);
    flat += fast.flat;
    skips += fast.turn_skips;
    total += fast.intervals;
    expect_same_nodes(fast, path, limits,
                      "random curve " + std::to_string(trial) + " (degree " + std::to_string(p) +
                          ", seed " + std::to_string(seed) + ")");
  }
  std::cout << "[ axes     ] seed " << seed << ": " << flat << " flat and " << skips
            << " curve-jerk samplings left out of " << total << " curve intervals\n";
  EXPECT_GT(flat, 0u) << "seed " << seed;  // both skips are exercised
  EXPECT_GT(skips, 0u) << "seed " << seed;
  EXPECT_LT(skips, total) << "seed " << seed;  // and so is the sampling
}

}  // namespace
}  // namespace ncd::feed
