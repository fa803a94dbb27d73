// Smoothing of dense polylines under G64 P (within P − ε_c) and G64 P Q (within Q): runs of short,
// gently turning G1 moves are replaced by a cubic B-spline proven to lie within Q of them. The
// algorithm, the run rules and the proof are explained in polyline_fit.cpp and docs/planner.md §3d.
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include "core/geometry.hpp"
#include "feed/feed_limits.hpp"
#include "geometry/nurbs.hpp"
#include "geometry/path.hpp"

namespace ncd::feed {

struct FitReport {
  std::size_t runs = 0;           // runs replaced by a curve
  std::size_t spans = 0;          // cubic spans of those curves
  std::size_t points = 0;         // polyline vertices the curves replace
  std::size_t refused = 0;        // runs (or parts of runs) left as polylines by the check
  double max_deviation_mm = 0.0;  // largest proven curve ↔ polyline distance bound
  // For each segment of the fitted path, the index of the program's segment it comes from
  // (a segment with fitted runs is split; every piece keeps the program segment's data).
  std::vector<std::size_t> source_segment;
};

struct FittedRun {
  toolpath::NurbsCurve curve;  // degree 3, clamped, u = chord length (mm) of the polyline
  double deviation_mm = 0.0;   // proven bound on the two-sided distance to the polyline
};

// A cubic B-spline from points.front() to points.back() (exactly) whose distance to the
// polyline through `points`, and the polyline's distance to it, are proven ≤ tolerance_mm; none
// if no such curve was found down to the finest knot spacing. Consecutive duplicate points
// are skipped; fewer than two distinct points give none.
std::optional<FittedRun> fit_polyline_run(const std::vector<Vec3>& points, double tolerance_mm);

// The path with every eligible run (polyline segments under G64 P > 0 with Q > 0, or no Q and
// P > ε_c unless limits.fit_dense_runs is false; no contact
// normals; see polyline_fit.cpp for the run rules) replaced by a fitted curve. Segments
// without runs are copied unchanged.
toolpath::Path fit_polylines(const toolpath::Path& path, const MachineLimits& limits,
                             FitReport* report = nullptr);

}  // namespace ncd::feed
