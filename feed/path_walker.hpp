// Walking a whole Path (NURBS and polyline segments end to end) by planned arc length, one
// period at a time. The algorithm is explained in path_walker.cpp.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

#include "feed/curve_walker.hpp"
#include "geometry/path.hpp"

namespace ncd::feed {

struct WalkStep {
  Vec3 p;                       // the setpoint, mm
  double travelled_mm = 0.0;    // true arc length of this period (Gauss–Legendre on curves)
  double chord_error_mm = 0.0;  // largest distance of the path from the chord of this period
  std::size_t segment = 0;      // segment holding p
  int iterations = 0;           // correction iterations spent on curves
  bool converged = true;        // every curve step met its tolerance
  bool at_end = false;          // p is the end of the path
};

class PathWalker {
 public:
  // Measures every segment (the only allocation); throws InputError on an empty path.
  PathWalker(const toolpath::Path& path, const WalkerConfig& config);

  double length_mm() const { return total_length_mm_; }
  double segment_start_mm(std::size_t segment) const { return starts_mm_[segment]; }
  // Advances by the planned arc length of one period, crossing segment ends; no allocation.
  WalkStep advance(double delta_s_mm);
  Vec3 position() const { return position_; }
  // Σ true arc length moved minus Σ Δs asked, mm: the accumulated drift.
  double drift_mm() const { return -debt_mm_; }
  std::size_t segment() const { return segment_; }
  std::size_t piece() const { return vertex_; }  // polyline piece holding the position
  double curve_u() const;                        // curve parameter, if the segment is NURBS

 private:
  double advance_in_segment(double delta_s_mm, WalkStep& out);
  Vec3 polyline_point(const toolpath::Polyline& line, double s_mm) const;

  const toolpath::Path& path_;
  WalkerConfig config_;
  std::vector<double> starts_mm_;                     // cumulative arc length at each segment start
  std::vector<std::vector<double>> vertex_s_mm_;      // per polyline: arc length at each vertex
  std::vector<std::unique_ptr<CurveWalker>> curves_;  // per NURBS segment, null otherwise
  double total_length_mm_ = 0.0;
  std::size_t segment_ = 0;
  double s_in_segment_mm_ = 0.0;  // arc length walked within the current segment
  std::size_t vertex_ = 0;        // current polyline piece
  double debt_mm_ = 0.0;          // Σ Δs asked − Σ true arc moved
  Vec3 position_;
};

// Arc length of a NURBS segment by adaptive Gauss–Legendre per knot span, mm.
double curve_length_mm(const toolpath::ParametricCurve& curve);
// Arc length between parameters u0 < u1 the same way (four panels, each adaptive), mm: where a
// span nearly reverses, |C'| has a narrow valley that four fixed panels miss by 7e-4 mm.
double arc_length_mm(const toolpath::ParametricCurve& curve, double u0, double u1);

}  // namespace ncd::feed
