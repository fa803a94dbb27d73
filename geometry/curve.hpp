// What the interpolator walks: a parametric curve P(u) with its first two derivatives.
// Implementations (NURBS, analytic test curves) must not allocate in eval(): it runs in the
// 4 ms cycle.
#pragma once

#include <vector>

#include "core/geometry.hpp"

namespace ncd::toolpath {

struct CurvePoint {
  Vec3 p;   // P(u), mm
  Vec3 d1;  // dP/du
  Vec3 d2;  // d²P/du²
};

class ParametricCurve {
 public:
  virtual ~ParametricCurve() = default;
  virtual double u_begin() const = 0;
  virtual double u_end() const = 0;
  virtual CurvePoint eval(double u) const = 0;
  // P'(u) alone, the same bits as eval(u).d1: what arc-length integrals need (a curve may do
  // less work for it).
  virtual Vec3 derivative(double u) const { return eval(u).d1; }
  // Parameters where P'' may jump (interior knots), ascending, begin and end included; arc
  // length integrals split there.
  virtual std::vector<double> breakpoints() const = 0;
};

}  // namespace ncd::toolpath
