// The dense CAM program of issue 13, shared by the bound table (tests/motion/bound_test.cpp)
// and the fit's benchmarks (bench/planner_bench.cpp): `moves` G1 moves of 0.01 mm along an arc
// of radius 50 mm at F3000 under G64 P0.01 and Q = q_mm, as a CAM post writes them
// (coordinates rounded to `decimals` decimals; 0 keeps them exact).
#pragma once

#include <cmath>
#include <cstddef>
#include <optional>

#include "geometry/path.hpp"

namespace ncd::test {

inline toolpath::Path dense_cam(std::size_t moves, int decimals, std::optional<double> q_mm) {
  constexpr double kRadiusMm = 50.0, kStepMm = 0.01;
  const double scale = std::pow(10.0, decimals);
  toolpath::Polyline line;
  for (std::size_t i = 0; i <= moves; ++i) {
    const double phi = kStepMm * static_cast<double>(i) / kRadiusMm;
    Vec3 p(kRadiusMm * std::sin(phi), kRadiusMm * (1.0 - std::cos(phi)), 0.0);
    if (decimals > 0) {
      for (int k = 0; k < 3; ++k) p[k] = std::round(p[k] * scale) / scale;
    }
    line.points.push_back(p);
  }
  toolpath::Path path;
  toolpath::PathSegment s;
  s.geometry = std::move(line);
  s.feed_mm_per_min = 3000.0;
  s.blend_tolerance_mm = 0.01;
  s.smoothing_tolerance_mm = q_mm;
  path.segments.push_back(std::move(s));
  return path;
}

}  // namespace ncd::test
