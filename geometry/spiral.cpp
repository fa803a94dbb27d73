// Archimedean spiral r(θ) = 100 − 0.1 θ / 2π mm sampled as control points of a cubic B-spline.
#include "geometry/spiral.hpp"

#include <cmath>
#include <string>

#include "core/error.hpp"

namespace ncd::toolpath {

Path spiral_path(int turns) {
  if (turns < 1 || turns > 999) {
    throw InputError("spiral of " + std::to_string(turns) +
                     " turns: it takes 1 to 999 (r from 100 mm inwards at 0.1 mm pitch)");
  }
  const int per_turn = 16, n = turns * per_turn + 1, degree = 3;
  std::vector<Vec3> pts;
  for (int i = 0; i < n; ++i) {
    const double th = 2.0 * kPi * i / per_turn, r = 100.0 - 0.1 * i / per_turn;
    pts.emplace_back(r * std::cos(th), r * std::sin(th), 2.0 * std::sin(0.05 * th));
  }
  std::vector<double> knots(degree + 1, 0.0);
  const int inner = n - degree - 1;
  for (int i = 1; i <= inner; ++i) knots.push_back(i);
  knots.insert(knots.end(), degree + 1, inner + 1.0);
  Path path;
  PathSegment segment;
  segment.geometry = NurbsCurve(degree, knots, pts);
  path.segments.push_back(std::move(segment));
  path.source = "spiral of " + std::to_string(turns) + " turns";
  return path;
}

double spiral_length_mm(int turns) {
  const double k = turns;
  return 2.0 * kPi * (100.0 * k - 0.05 * k * k);
}

}  // namespace ncd::toolpath
