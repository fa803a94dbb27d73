// Non-uniform rational B-spline curve of degree 1–7 with a clamped knot vector: the curve the
// interpolator walks (paper 004) and the geometry of LinuxCNC's G5.2/G5.3 blocks. The
// evaluation algorithm is explained once, in nurbs.cpp.
#pragma once

#include <cstddef>
#include <vector>

#include "core/geometry.hpp"
#include "geometry/curve.hpp"

namespace ncd::toolpath {

class NurbsCurve final : public ParametricCurve {
 public:
  static constexpr int kMinDegree = 1;
  static constexpr int kMaxDegree = 7;  // fixes the size of the scratch arrays of eval()
  // The largest ratio of two weights among the p + 1 points of one span. Beyond it a span is
  // a near-corner (a conic whose shape factor w₁²/(w₀w₂) is near 0), which the limit sampler
  // does not resolve: ratio 424 breaks the chord limit, 1e3 crawls, 1e6 jumps (docs/feedrate.md
  // "Weights"). A conic arc of up to 170° has a ratio below 12.
  static constexpr double kMaxSpanWeightRatio = 100.0;

  // Validates and stores the curve; throws InputError naming the offending value, the limit and
  // a way out. knots: clamped (degree + 1 equal knots at each end), non-decreasing, interior
  // multiplicity ≤ degree, size = points + degree + 1. weights: empty (non-rational) or one
  // finite weight > 0 per point. Points in mm.
  NurbsCurve(int degree, std::vector<double> knots, std::vector<Vec3> points,
             std::vector<double> weights = {});

  int degree() const { return degree_; }
  const std::vector<double>& knots() const { return knots_; }
  const std::vector<Vec3>& points() const { return points_; }
  // One weight per point; all 1 when the curve was given without weights.
  const std::vector<double>& weights() const { return weights_; }
  bool rational() const { return rational_; }

  double u_begin() const override { return knots_.front(); }
  double u_end() const override { return knots_.back(); }
  // P, P', P'' at u (clamped to [u_begin, u_end]); at an interior knot, the derivatives of the
  // span that starts there. Does not allocate.
  CurvePoint eval(double u) const override;
  // P'(u) without the second derivative's work; the same bits as eval(u).d1.
  Vec3 derivative(double u) const override;
  // The same, where u most likely lies in the knot span *span_hint (a caller's sweep through
  // one span, as a quadrature's: two comparisons instead of the span search); the hint is
  // updated to u's span. Any hint gives the same bits.
  Vec3 derivative(double u, std::size_t& span_hint) const;
  // Distinct knot values, ascending, u_begin and u_end included.
  std::vector<double> breakpoints() const override;

 private:
  std::size_t find_span(double u) const;  // i with knots[i] ≤ u < knots[i+1] (A2.1)

  int degree_;
  std::vector<double> knots_;
  std::vector<Vec3> points_;
  std::vector<double> weights_;
  std::vector<Vec3> weighted_points_;  // w_i P_i, the homogeneous numerators
  bool rational_;
};

}  // namespace ncd::toolpath
