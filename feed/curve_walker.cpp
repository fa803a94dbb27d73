// The curve walker: one parameter step per interpolation period.
//
// Given the arc length Δs the planned motion covers in this period (s(t+T) − s(t), not F·T:
// with a varying feed only the planned s(t) is right, docs/feedrate.md §2), find u_{i+1} with
//
//     g(u) = ∫_{u_i}^{u} |P'(w)| dw − Δs = 0.
//
// Predictor: the second-order Taylor expansion of u(s) at u_i (paper 004, eq. 7),
//
//     u* = u_i + Δs / |P'| − Δs² (P'·P'') / (2 |P'|⁴),
//
// (where P' = 0, at a repeated control point, the corrected walk predicts from P'' instead:
// s ≈ |P''| (u − u_i)² / 2, so u* = u_i + √(2 Δs / |P''|); docs/feedrate.md §5.1),
// which alone leaves a relative arc-length error (the feedrate fluctuation) of order
// 1e-4–1e-3 at Δs = 0.4 mm, more where P'' jumps at a C¹ knot. If the quadratic term turns
// the step backwards (a strongly accelerating parametrisation), the first-order step is used.
//
// Corrector: Newton on g, whose derivative is g'(u) = |P'(u)|, so each update is
//
//     u ← u − (L(u_i, u) − Δs) / |P'(u)|,
//
// with L integrated by 5-point Gauss–Legendre on every piece of [u_i, u] between breakpoints
// (the curve's interior knots, where P'' may jump and the integrand is not smooth; repeated
// knots give empty pieces, which are skipped). From the Taylor start Newton converges
// quadratically: 1e-4 → ~1e-8 → ~1e-16, i.e. one or two updates for the default 1e-10. An
// update that moves u by less than 1 % of the step does not re-integrate from u_i: L gains the
// integral over [u_old, u_new] by 3-point Gauss–Legendre, whose error there (∝ h⁷) is far below
// the rounding of L, so each such iteration costs 4 evaluations instead of 11. The iterate
// is kept inside a bracket [lo, hi] on which g changes sign (g(u_i) = −Δs < 0); an update that
// leaves it bisects instead, so a zero speed or a bad predictor cannot throw the walk off the
// curve. The tolerance is floored at the parameter's own resolution, so tiny Δs at the ends
// of a ramp converge too.
//
//     u_i          u*   u_{i+1}            u_end
//      ●━━━━━━━━━━━━○━━━●━━━━━━━━━━━━━━━━━━━━┃
//      └──── L(u_i, u_{i+1}) = Δs ────┘
//
// End of the curve: the bracket's upper end is u_end. When an update would pass it, u_end is
// tried once: if L(u_i, u_end) ≤ Δs (+ tolerance) the step lands on u_end exactly and reports
// the shorter arc; otherwise u_end becomes the upper bracket. In TaylorOnly mode the predictor
// is clamped to u_end.
//
// Cost per corrected step: 1 evaluation for the predictor, 10 per piece for L at u*, then per
// iteration 1 for |P'(u)| and 3 per piece for the update of L. Nothing is allocated.
#include "feed/curve_walker.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>

#include "core/error.hpp"
#include "core/number_text.hpp"
#include "core/quadrature.hpp"

namespace ncd::feed {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr double kResolutionUlps = 4.0;  // arc-length noise of L in units of ε·|u|·|P'|
constexpr double kSmallUpdate = 1e-2;    // Newton update / step below which L is updated

// 3-point Gauss–Legendre on [a, b] (exact to degree 5), for the short updates of L.
template <class F>
double gauss_legendre3(const F& f, double a, double b) {
  const double half = 0.5 * (b - a), mid = 0.5 * (a + b);
  const double x = half * 0.7745966692414833770358531;  // sqrt(3/5)
  return half * (5.0 / 9.0 * (f(mid - x) + f(mid + x)) + 8.0 / 9.0 * f(mid));
}

}  // namespace

void validate(const WalkerConfig& config) {
  using L = WalkerLimits;
  if (!(config.tolerance_rel >= L::kMinToleranceRel &&
        config.tolerance_rel <= L::kMaxToleranceRel)) {
    throw InputError("tolerance_rel = " + text::sig(config.tolerance_rel, 17) + " is outside [" +
                     text::sig(L::kMinToleranceRel, 17) + ", " +
                     text::sig(L::kMaxToleranceRel, 17) + "]; 1e-10 is the default");
  }
  if (config.max_iterations < 1 || config.max_iterations > L::kMaxIterations) {
    throw InputError("max_iterations = " + std::to_string(config.max_iterations) +
                     " is outside [1, " + std::to_string(L::kMaxIterations) +
                     "]; 30 is the default");
  }
}

CurveWalker::CurveWalker(const toolpath::ParametricCurve& curve, const WalkerConfig& config)
    : curve_(curve),
      config_(config),
      breakpoints_(curve.breakpoints()),
      u_begin_(curve.u_begin()),
      u_end_(curve.u_end()),
      u_(u_begin_) {
  validate(config_);
  if (!(std::isfinite(u_begin_) && std::isfinite(u_end_) && u_begin_ < u_end_)) {
    throw InputError("curve parameter range [" + text::sig(u_begin_, 17) + ", " +
                     text::sig(u_end_, 17) +
                     "] is invalid: it must be finite with u_begin < u_end");
  }
  for (std::size_t k = 0; k < breakpoints_.size(); ++k) {
    const double b = breakpoints_[k];
    if (!(b >= u_begin_ && b <= u_end_) || (k > 0 && b < breakpoints_[k - 1])) {
      throw InputError("curve breakpoint " + std::to_string(k) + " = " + text::sig(b, 17) +
                       " is invalid: breakpoints must ascend within [" + text::sig(u_begin_, 17) +
                       ", " + text::sig(u_end_, 17) + "]");
    }
  }
}

void CurveWalker::reset(double u) {
  u_ = std::clamp(u, u_begin_, u_end_);
}

template <class Rule>
double CurveWalker::integrate_speed(double u0, double u1, Rule&& rule) const {
  if (u1 < u0) return -integrate_speed(u1, u0, rule);
  const auto speed = [this](double u) { return curve_.derivative(u).norm(); };
  double sum = 0.0;
  double a = u0;
  for (auto it = std::upper_bound(breakpoints_.begin(), breakpoints_.end(), u0);
       it != breakpoints_.end() && *it < u1; ++it) {
    if (*it > a) {
      sum += rule(speed, a, *it);
      a = *it;
    }
  }
  if (u1 > a) sum += rule(speed, a, u1);
  return sum;
}

double CurveWalker::arc_length_mm(double u0, double u1) const {
  // Five points per piece: a period's step is short against the scale on which |P'| varies,
  // so the degree-9 rule is at rounding level (the tests hold it to independent references),
  // and it halves the cost of a corrected step against the 10-point rule.
  return integrate_speed(
      u0, u1, [](const auto& f, double a, double b) { return GaussLegendre5::integrate(f, a, b); });
}

double CurveWalker::arc_increment_mm(double u0, double u1) const {
  return integrate_speed(
      u0, u1, [](const auto& f, double a, double b) { return gauss_legendre3(f, a, b); });
}

StepResult CurveWalker::step(double delta_s_mm) {
  if (!(delta_s_mm >= 0.0) || !std::isfinite(delta_s_mm)) {
    return {u_, 0.0, 0, StepStatus::InvalidStep};
  }
  if (u_ >= u_end_) return {u_end_, 0.0, 0, StepStatus::ReachedEnd};
  if (delta_s_mm == 0.0) return {u_, 0.0, 0, StepStatus::Ok};

  const toolpath::CurvePoint cp = curve_.eval(u_);
  const double speed2 = cp.d1.squaredNorm();
  const double speed = std::sqrt(speed2);
  double u_predicted = u_ + delta_s_mm / speed -
                       delta_s_mm * delta_s_mm * cp.d1.dot(cp.d2) / (2.0 * speed2 * speed2);
  if (!(u_predicted > u_) || !std::isfinite(u_predicted)) {
    u_predicted = u_ + delta_s_mm / speed;  // NaN/inf when P' = 0
  }
  if (config_.mode == StepMode::Corrected &&
      (!std::isfinite(u_predicted) || speed <= kEps * cp.d2.norm())) {
    // P' = 0 (a repeated control point): s ≈ |P''| (u − u_i)² / 2 there. (Eq. 7 alone, the
    // TaylorOnly baseline, stalls there.)
    const double acc = cp.d2.norm();
    if (acc > 0.0) u_predicted = u_ + std::sqrt(2.0 * delta_s_mm / acc);
  }
  return config_.mode == StepMode::TaylorOnly ? taylor_only(u_predicted)
                                              : correct(delta_s_mm, u_predicted, speed);
}

StepResult CurveWalker::taylor_only(double u_predicted) {
  if (!(u_predicted > u_) || !std::isfinite(u_predicted)) {
    return {u_, 0.0, 0, StepStatus::Stalled};
  }
  StepResult r;
  r.status = StepStatus::Ok;
  r.u = u_predicted;
  if (r.u >= u_end_) {
    r.u = u_end_;
    r.status = StepStatus::ReachedEnd;
  }
  r.arc_length_mm = config_.measure_arc_length ? arc_length_mm(u_, r.u) : kNaN;
  u_ = r.u;
  return r;
}

StepResult CurveWalker::correct(double delta_s_mm, double u_predicted, double speed_i) {
  double lo = u_;
  double hi = u_end_;
  bool end_tried = false;
  double u = std::isfinite(u_predicted) ? std::min(u_predicted, u_end_) : u_end_;
  if (u == u_end_) end_tried = true;

  // Arc-length resolution of a parameter step near u_i (doubles are spaced ε|u| there, not
  // ε|u_end|): below it no u does better.
  const double floor_mm = kResolutionUlps * kEps * std::max(std::abs(u_), std::abs(u)) * speed_i;
  const double tol_mm = std::max(config_.tolerance_rel * delta_s_mm, floor_mm);

  StepResult r;
  double arc_mm = arc_length_mm(u_, u);
  for (int it = 0;; ++it) {
    const double g = arc_mm - delta_s_mm;
    r = {u, arc_mm, it, StepStatus::Ok};
    if (u >= u_end_ && g <= tol_mm) {
      r.status = StepStatus::ReachedEnd;
      break;
    }
    if (std::abs(g) <= tol_mm) break;
    if (it == config_.max_iterations) {
      r.status = StepStatus::NotConverged;
      break;
    }
    if (g < 0.0) {
      lo = u;
    } else {
      hi = u;
    }
    double next = u - g / curve_.derivative(u).norm();
    if (!(next > lo && next < hi)) {
      if (next >= hi && hi == u_end_ && !end_tried) {
        next = u_end_;
        end_tried = true;
      } else {
        next = 0.5 * (lo + hi);
      }
    }
    if (next == u) break;  // bracket down to adjacent doubles: u is as close as it gets
    arc_mm = std::abs(next - u) <= kSmallUpdate * (u - u_) ? arc_mm + arc_increment_mm(u, next)
                                                           : arc_length_mm(u_, next);
    u = next;
  }
  u_ = r.u;
  return r;
}

}  // namespace ncd::feed
