// The planner's random programs (tests/motion/property_test.cpp walks them; the block encoder's
// rs274 suite writes them as blocks): lines with reversals, zero-length and 1 µm moves, dense runs
// of 0.01 mm moves along arcs, NURBS of degree 1–5 (rational, repeated interior knots up to C¹),
// rapids, G61, G61.1, G64 (with and without P, P0 included; with Q on some moves and on half of
// the dense runs under G64, whose points are all rounded to 1 µm) and stops before events. One
// generator for every suite that needs them; seed it from tests/common/seed.hpp.
#pragma once

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "geometry/path.hpp"

namespace ncd::test {

struct RandomProgram {
  std::mt19937_64 rng;
  Vec3 at{0, 0, 0};
  Vec3 heading{1, 0, 0};
  double max_feed_mm_per_min = 0.0;
  // Off for the jerk-vector suite, whose bound leaves them out (docs/planner.md §3c): runs of
  // pieces shorter than one period's travel (dense runs, 1 µm and 0.01 mm moves) and repeated
  // control points (a rest point where the curvature grows without bound).
  bool short_pieces = true;
  bool repeated_points = true;

  double uni(double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); }
  int pick(int n) { return std::uniform_int_distribution<int>(0, n - 1)(rng); }
  Vec3 random_unit() {
    Vec3 v(uni(-1, 1), uni(-1, 1), uni(-1, 1));
    while (v.norm() < 1e-3) v = Vec3(uni(-1, 1), uni(-1, 1), uni(-1, 1));
    return v.normalized();
  }

  void common(toolpath::PathSegment& s) {
    s.rapid = pick(8) == 0;
    if (!s.rapid) {
      s.feed_mm_per_min = uni(60.0, 6000.0);
      max_feed_mm_per_min = std::max(max_feed_mm_per_min, *s.feed_mm_per_min);
    }
    const int m = pick(6);
    s.path_control =
        m == 0 ? toolpath::PathControl::exact_stop
               : (m == 1 ? toolpath::PathControl::exact_path : toolpath::PathControl::blend);
    s.stop_before = pick(10) == 0;
    if (pick(3) == 0) s.blend_tolerance_mm = pick(2) == 0 ? 0.0 : uni(0.001, 0.5);  // G64 P
    if (pick(8) == 0) s.smoothing_tolerance_mm = uni(0.001, 0.05);                  // G64 Q
  }

  toolpath::PathSegment lines() {
    std::vector<Vec3> pts{at};
    const int n = 1 + pick(6);
    for (int i = 0; i < n; ++i) {
      const int kind = pick(10);
      Vec3 d = kind < 2 ? Vec3(-heading) : (kind < 5 ? random_unit() : heading);
      if (kind >= 5) d = (d + 0.3 * random_unit()).normalized();  // a mild turn
      const int lk = pick(10);
      double len = lk == 0 ? 0.0 : (lk == 1 ? 1e-3 : (lk == 2 ? 0.01 : uni(0.1, 15.0)));
      if (!short_pieces && len > 0.0 && len < 0.5) len = uni(0.5, 15.0);
      pts.push_back(pts.back() + len * d);
      if (len > 0.0) heading = d;
    }
    at = pts.back();
    toolpath::PathSegment s;
    s.geometry = toolpath::Polyline{pts, {}};
    common(s);
    return s;
  }

  toolpath::PathSegment dense() {
    // 0.01 mm moves along an arc of radius 20–200 mm, in a random plane.
    const Vec3 n = random_unit();
    Vec3 t = heading - heading.dot(n) * n;
    if (t.norm() < 1e-6) t = n.unitOrthogonal();
    t.normalize();
    const double radius = uni(20.0, 200.0), step = 0.01, dphi = step / radius;
    std::vector<Vec3> pts{at};
    const int count = 50 + pick(400);
    const Vec3 center = at + radius * n.cross(t);
    const Vec3 r0 = at - center;
    for (int i = 1; i <= count; ++i) {
      const double phi = -dphi * i;
      pts.push_back(center + std::cos(phi) * r0 + std::sin(phi) * n.cross(r0));
    }
    toolpath::PathSegment s;
    common(s);
    if (s.feed_mm_per_min) s.feed_mm_per_min = std::min(*s.feed_mm_per_min, 3000.0);
    // Half of the dense runs under G64 get a Q (the fit of docs/planner.md §3d; the others are
    // fitted within P − ε_c by the machine's default fit), and all of them have their points
    // rounded to 1 µm as a CAM post writes them (the first stays where the last move ended):
    // noise for the fit to smooth.
    if (s.path_control == toolpath::PathControl::blend) {
      if (pick(2) == 0) s.smoothing_tolerance_mm = uni(0.002, 0.05);
      for (std::size_t i = 1; i < pts.size(); ++i) {
        for (int k = 0; k < 3; ++k) pts[i][k] = std::round(pts[i][k] * 1000.0) / 1000.0;
      }
    }
    heading = (pts.back() - pts[pts.size() - 2]).normalized();
    at = pts.back();
    s.geometry = toolpath::Polyline{pts, {}};
    return s;
  }

  toolpath::PathSegment nurbs() {
    const int degree = 1 + pick(5);
    const int n = degree + 1 + pick(5);
    std::vector<Vec3> pts{at};
    for (int i = 1; i < n; ++i) pts.push_back(pts.back() + uni(1.0, 8.0) * random_unit());
    // Interior knots: uniform, one of them repeated up to degree − 1 times (stays C¹).
    std::vector<double> knots(static_cast<std::size_t>(degree + 1), 0.0);
    const int inner = n - degree - 1;
    std::vector<double> interior;
    for (int i = 1; i <= inner; ++i) interior.push_back(i);
    if (inner > 0 && degree >= 3 && pick(2) == 0) {
      const double k = interior[static_cast<std::size_t>(pick(inner))];
      for (int r = 0; r < pick(degree - 2) + 1 && static_cast<int>(interior.size()) < inner; ++r) {
        interior.push_back(k);
      }
    }
    interior.resize(static_cast<std::size_t>(inner));
    if (inner >= degree && degree >= 2 && pick(4) == 0) {
      // One interior knot of full multiplicity (= degree): C⁰, a corner at a control point.
      for (int r = 0; r < degree; ++r) interior[static_cast<std::size_t>(r)] = 1.0;
    }
    std::sort(interior.begin(), interior.end());
    // Repeated control points: the parametric speed vanishes at an end (or at the C⁰ knot).
    // (Degree ≥ 2: at degree 1 a repeated point is a zero-length span, not yet walked.)
    if (repeated_points && degree >= 2 && pick(4) == 0) pts[1] = pts[0];
    if (repeated_points && degree >= 2 && pick(4) == 0) {
      pts[static_cast<std::size_t>(n - 2)] = pts[static_cast<std::size_t>(n - 1)];
    }
    knots.insert(knots.end(), interior.begin(), interior.end());
    knots.insert(knots.end(), static_cast<std::size_t>(degree + 1), inner + 1.0);
    std::vector<double> weights;
    if (pick(2) == 0) {
      for (int i = 0; i < n; ++i) weights.push_back(uni(0.5, 2.0));
    }
    toolpath::NurbsCurve c = weights.empty() ? toolpath::NurbsCurve(degree, knots, pts)
                                             : toolpath::NurbsCurve(degree, knots, pts, weights);
    for (std::size_t i = pts.size() - 1; i > 0; --i) {  // the last leg that is not a point
      if ((pts[i] - pts[i - 1]).norm() > 0.0) {
        heading = (pts[i] - pts[i - 1]).normalized();
        break;
      }
    }
    at = pts.back();
    toolpath::PathSegment s;
    s.geometry = std::move(c);
    common(s);
    if (s.rapid) {  // G5.2 is a feed move
      s.rapid = false;
      s.feed_mm_per_min = 3000.0;
    }
    return s;
  }

  toolpath::Path program() {
    toolpath::Path p;
    const int n = 2 + pick(8);
    for (int i = 0; i < n; ++i) {
      const int k = pick(10);
      p.segments.push_back(k < 5 ? lines() : (k < 7 && short_pieces ? dense() : nurbs()));
    }
    return p;
  }
};

}  // namespace ncd::test
