// A dense program walked by the real Job and measured against its programmed points, and the
// speed limit of a program's geometry as read (lines at their cap, curves at their curvature):
// shared by tests/motion/dense_bound_test.cpp and bench/dense_bound_bench.cpp (issue 34).
// The distances are taken from the setpoints alone against the program (tests/motion/
// reference.hpp): each setpoint from the programmed path, each programmed polyline vertex from
// the chords between setpoints. The limit feeds tests/common/shape_bound.hpp's phase plane.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "feed/limit_sampler_detail.hpp"
#include "motion/job.hpp"
#include "tests/common/shape_bound.hpp"
#include "tests/motion/reference.hpp"

namespace ncd::test {

// A curve's length by the midpoint rule on |C'| (4096 steps).
inline double curve_length_mm(const toolpath::NurbsCurve& c) {
  const int n = 4096;
  const double du = (c.u_end() - c.u_begin()) / n;
  double len = 0.0;
  for (int k = 0; k < n; ++k) len += du * c.eval(c.u_begin() + du * (k + 0.5)).d1.norm();
  return len;
}

struct DenseWalk {
  double t_s = 0.0;
  double setpoint_off_mm = 0.0;  // largest distance of a setpoint from the programmed path
  double vertex_off_mm = 0.0;    // largest distance of a programmed vertex from the chords
  feed::FitReport fit;
};

// Walks the path with cfg; measures the two distances against the programmed path.
inline DenseWalk walk_dense(const toolpath::Path& path, const motion::JobConfig& cfg) {
  motion::Job job(path, cfg);
  const GeometryTable program = tabulate(path);
  DenseWalk w;
  w.fit = job.fit_report();
  std::vector<Vec3> sp_p;
  std::vector<double> sp_s;
  while (!job.done()) {
    job.prepare();
    const motion::Setpoint sp = job.step();
    w.t_s = sp.t_s;
    w.setpoint_off_mm = std::max(w.setpoint_off_mm, distance_to_path(program, sp.p, sp.s_mm, 1.0));
    sp_p.push_back(sp.p);
    sp_s.push_back(sp.s_mm);
  }
  // Every polyline vertex against the chords between setpoints within 1 mm of its arc length.
  double s0 = 0.0;
  for (const auto& seg : path.segments) {
    const auto* line = std::get_if<toolpath::Polyline>(&seg.geometry);
    if (!line) {
      const auto& c = std::get<toolpath::NurbsCurve>(seg.geometry);
      s0 += curve_length_mm(c);
      continue;
    }
    double s = s0;
    for (std::size_t i = 0; i < line->points.size(); ++i) {
      if (i > 0) s += (line->points[i] - line->points[i - 1]).norm();
      const auto lo = std::lower_bound(sp_s.begin(), sp_s.end(), s - 1.0) - sp_s.begin();
      const auto hi = std::upper_bound(sp_s.begin(), sp_s.end(), s + 1.0) - sp_s.begin();
      double best = std::numeric_limits<double>::infinity();
      for (auto j = std::max<std::ptrdiff_t>(lo, 1); j < hi; ++j) {
        best = std::min(best, distance_to_segment(line->points[i], sp_p[j - 1], sp_p[j]));
      }
      w.vertex_off_mm = std::max(w.vertex_off_mm, best);
    }
    s0 = s;
  }
  return w;
}

// The programmed geometry's limit (3dtest): polyline pieces at their cap, arcs (NURBS) sampled
// every ~2 µm with the curve laws at their curvature, each joint at the corner limit within P
// (0 under G61/G61.1/P0 and at a stop).
inline ShapeLimit program_limit(const toolpath::Path& path, const feed::MachineLimits& l) {
  ShapeLimit lim;
  Vec3 prev_dir = Vec3::Zero();
  for (const auto& seg : path.segments) {
    const double cap =
        std::min(l.max_feed_mm_per_min,
                 seg.rapid || !seg.feed_mm_per_min ? l.max_feed_mm_per_min : *seg.feed_mm_per_min) /
        60.0;
    const bool blend = feed::sampler_detail::corner_mode(seg, l) == toolpath::PathControl::blend;
    const double p_mm = blend ? seg.blend_tolerance_mm.value_or(l.blend_tolerance_mm) : 0.0;
    const auto joint = [&](const Vec3& dir) {  // the corner into a piece of direction dir
      if (lim.s_mm.empty()) return;
      const double turn =
          prev_dir.norm() > 0.0 && dir.norm() > 0.0
              ? std::acos(std::clamp(prev_dir.normalized().dot(dir.normalized()), -1.0, 1.0))
              : 0.0;
      lim.v_mm_per_s.back() =
          std::min({lim.v_mm_per_s.back(), cap, corner_limit_mm_per_s(turn, p_mm, l)});
    };
    if (seg.stop_before && !lim.s_mm.empty()) lim.v_mm_per_s.back() = 0.0;
    if (const auto* line = std::get_if<toolpath::Polyline>(&seg.geometry)) {
      for (std::size_t i = 0; i + 1 < line->points.size(); ++i) {
        const Vec3 d = line->points[i + 1] - line->points[i];
        if (!(d.norm() > 0.0)) continue;
        joint(d);
        if (lim.s_mm.empty()) lim.add(0.0, cap);
        lim.add_line(d.norm(), cap);
        prev_dir = d;
      }
      continue;
    }
    const auto& c = std::get<toolpath::NurbsCurve>(seg.geometry);
    joint(c.eval(c.u_begin()).d1);
    if (lim.s_mm.empty()) lim.add(0.0, cap);
    const double len = curve_length_mm(c);
    const int n = std::max(64, static_cast<int>(len / 0.002));
    const double du = (c.u_end() - c.u_begin()) / n;
    for (int k = 1; k <= n; ++k) {
      const auto at = c.eval(c.u_begin() + du * k);
      const auto mid = c.eval(c.u_begin() + du * (k - 0.5));
      const double kappa = at.d1.cross(at.d2).norm() / std::pow(at.d1.norm(), 3);
      lim.add(du * mid.d1.norm(), curve_limit_mm_per_s(kappa, cap, l));
    }
    prev_dir = c.eval(c.u_end()).d1;
  }
  return lim;
}

}  // namespace ncd::test
