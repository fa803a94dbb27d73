// A path of straight moves through points, optionally with the cutter-contact normal at each
// point (the chamfer generator knows it; docs/feedrate.md §1.4 uses it for the inclination α).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "core/geometry.hpp"

namespace ncd::toolpath {

struct Polyline {
  std::vector<Vec3> points;   // mm
  std::vector<Vec3> normals;  // empty, or one unit contact normal per point
};

struct PolylineLimits {
  static constexpr double kUnitNormalTolerance = 1e-6;  // | |n| − 1 | allowed for a normal
};

// Throws InputError naming the offending index and value when the polyline has fewer than two
// points, a coordinate or normal that is not finite, a normal that is not unit length, a normal
// count other than 0 or one per point, or two equal consecutive points (a zero-length move).
// `what` names the polyline in the message (a file, a key, a line).
void validate(const Polyline& polyline, const std::string& what = "polyline");

std::size_t segment_count(const Polyline& polyline);  // points − 1 (0 when empty)
double length_mm(const Polyline& polyline);           // sum of the segment lengths

}  // namespace ncd::toolpath
