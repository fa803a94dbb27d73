// Polyline validation and measures. A polyline is walked segment by segment, so a zero-length
// segment has no direction and is an error rather than something to skip silently.
#include "geometry/polyline.hpp"

#include <array>
#include <charconv>
#include <cmath>

#include "core/error.hpp"
#include "core/number_text.hpp"

namespace ncd::toolpath {

void validate(const Polyline& pl, const std::string& what) {
  if (pl.points.size() < 2) {
    throw InputError(what + " has " + std::to_string(pl.points.size()) +
                     " point(s), fewer than the 2 a move needs; give at least two points");
  }
  if (!pl.normals.empty() && pl.normals.size() != pl.points.size()) {
    throw InputError(what + " has " + std::to_string(pl.normals.size()) + " normals for " +
                     std::to_string(pl.points.size()) +
                     " points; give one contact normal per point, or none");
  }
  for (std::size_t i = 0; i < pl.points.size(); ++i) {
    if (!pl.points[i].allFinite()) {
      throw InputError(what + " point[" + std::to_string(i) + "] = " + text::point(pl.points[i]) +
                       " is not finite; every coordinate must be a number");
    }
    if (i > 0 && pl.points[i] == pl.points[i - 1]) {
      throw InputError(what + " point[" + std::to_string(i) + "] = " + text::point(pl.points[i]) +
                       " repeats point[" + std::to_string(i - 1) +
                       "]: a zero-length move has no direction; remove the duplicate");
    }
  }
  for (std::size_t i = 0; i < pl.normals.size(); ++i) {
    const double norm = pl.normals[i].norm();
    if (!std::isfinite(norm) || std::abs(norm - 1.0) > PolylineLimits::kUnitNormalTolerance) {
      throw InputError(what + " normal[" + std::to_string(i) + "] = " + text::point(pl.normals[i]) +
                       " has length " + text::shortest(norm) + ", not 1 within " +
                       text::shortest(PolylineLimits::kUnitNormalTolerance) + "; normalise it");
    }
  }
}

std::size_t segment_count(const Polyline& pl) {
  return pl.points.empty() ? 0 : pl.points.size() - 1;
}

double length_mm(const Polyline& pl) {
  double sum = 0.0;
  for (std::size_t i = 1; i < pl.points.size(); ++i)
    sum += (pl.points[i] - pl.points[i - 1]).norm();
  return sum;
}

}  // namespace ncd::toolpath
