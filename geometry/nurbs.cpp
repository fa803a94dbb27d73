// NURBS evaluation with two derivatives, allocation-free.
//
// A NURBS curve of degree p with control points P_i, weights w_i and knots U = {u_0 … u_m} is
// the projection of a polynomial B-spline in homogeneous space (Piegl and Tiller, The NURBS
// Book, 2nd ed., eq. 4.2):
//
//     A(u) = Σ N_{i,p}(u) w_i P_i,   w(u) = Σ N_{i,p}(u) w_i,   C(u) = A(u) / w(u).
//
// 1. Span: the index s with u_s ≤ u < u_{s+1} (A2.1, here a binary search with upper_bound;
//    u = u_end belongs to the last non-empty span). Only N_{s−p,p} … N_{s,p} are non-zero.
// 2. Basis functions and their first two derivatives on that span (A2.3): the triangular table
//    ndu holds the basis functions of every degree 0 … p and the knot differences; the
//    derivatives follow from eq. 2.9 as differences of lower-degree functions, computed with two
//    alternating rows of coefficients a_{k,j}.
// 3. Homogeneous derivatives A^(k), w^(k) (k = 0, 1, 2) as sums over the p + 1 active points.
// 4. Quotient rule (eq. 4.8, A4.2):
//        C   = A / w
//        C'  = (A'  − w' C) / w
//        C'' = (A'' − 2 w' C' − w'' C) / w
//
// Every array is a std::array sized for the degree (one instance of steps 2–4 per degree 1–7,
// chosen by a switch, so that the loops unroll), and eval() runs in the real-time cycle without
// touching the heap.
#include "geometry/nurbs.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <string>
#include <utility>

#include "core/error.hpp"
#include "core/number_text.hpp"

namespace ncd::toolpath {
namespace {

// The knot vector: finite, non-decreasing, clamped (p + 1 equal knots at each end), and no
// interior knot repeated more than p times.
void validate_knots(const std::vector<double>& knots, std::size_t p) {
  for (std::size_t i = 0; i < knots.size(); ++i) {
    if (!std::isfinite(knots[i])) {
      throw InputError("NURBS knot[" + std::to_string(i) + "] = " + text::shortest(knots[i]) +
                       " is not finite; every knot must be a number");
    }
    if (i > 0 && knots[i] < knots[i - 1]) {
      throw InputError("NURBS knot[" + std::to_string(i) + "] = " + text::shortest(knots[i]) +
                       " is less than knot[" + std::to_string(i - 1) +
                       "] = " + text::shortest(knots[i - 1]) +
                       ": knots must be non-decreasing; sort the knot vector");
    }
  }
  const std::size_t m = knots.size() - 1;
  for (std::size_t i = 1; i <= p; ++i) {
    if (knots[i] != knots[0] || knots[m - i] != knots[m]) {
      const bool front = knots[i] != knots[0];
      const std::size_t k = front ? i : m - i;
      throw InputError("NURBS knot[" + std::to_string(k) + "] = " + text::shortest(knots[k]) +
                       " differs from the end knot " + text::shortest(front ? knots[0] : knots[m]) +
                       ": the knot vector must be clamped, with degree + 1 = " +
                       std::to_string(p + 1) + " equal knots at each end; repeat the end knots");
    }
  }
  // Multiplicity of every distinct value: p + 1 at the ends (exactly), at most p inside.
  for (std::size_t i = 0; i <= m;) {
    std::size_t j = i;
    while (j + 1 <= m && knots[j + 1] == knots[i]) ++j;
    const std::size_t mult = j - i + 1;
    const bool end = i == 0 || j == m;
    if (end && mult > p + 1) {
      throw InputError("NURBS knot " + text::shortest(knots[i]) + " is repeated " +
                       std::to_string(mult) + " times at knot[" + std::to_string(i) + ".." +
                       std::to_string(j) + "], more than degree + 1 = " + std::to_string(p + 1) +
                       " at an end: the curve would have an empty parameter span; drop the "
                       "extra knots and their control points");
    }
    if (!end && mult > p) {
      throw InputError("NURBS interior knot " + text::shortest(knots[i]) + " is repeated " +
                       std::to_string(mult) + " times at knot[" + std::to_string(i) + ".." +
                       std::to_string(j) + "], more than the degree " + std::to_string(p) +
                       ": the curve would break apart there; split it into two curves");
    }
    i = j + 1;
  }
}

// The weights: one per point, finite and positive, and within one span's window at most
// kMaxSpanWeightRatio apart.
void validate_weights(const std::vector<double>& weights, std::size_t point_count, std::size_t p) {
  if (weights.size() != point_count) {
    throw InputError("NURBS has " + std::to_string(weights.size()) + " weights for " +
                     std::to_string(point_count) +
                     " control points; give one weight per point, or none for a "
                     "non-rational B-spline");
  }
  for (std::size_t i = 0; i < weights.size(); ++i) {
    if (!std::isfinite(weights[i]) || weights[i] <= 0.0) {
      throw InputError("NURBS weight[" + std::to_string(i) + "] = " + text::shortest(weights[i]) +
                       " is invalid: weights must be finite and greater than 0; fix the "
                       "weight or drop the weights for a non-rational curve");
    }
  }
  // The weights of one span's p + 1 points (a sliding window): see kMaxSpanWeightRatio.
  for (std::size_t first = 0; first + p < weights.size(); ++first) {
    std::size_t lo = first, hi = first;
    for (std::size_t i = first; i <= first + p; ++i) {
      if (weights[i] < weights[lo]) lo = i;
      if (weights[i] > weights[hi]) hi = i;
    }
    const double ratio = weights[hi] / weights[lo];
    if (ratio > NurbsCurve::kMaxSpanWeightRatio) {
      throw InputError(
          "NURBS weight[" + std::to_string(hi) + "] = " + text::shortest(weights[hi]) + " is " +
          text::shortest(ratio) + " times weight[" + std::to_string(lo) +
          "] = " + text::shortest(weights[lo]) + " within one span (points " +
          std::to_string(first) + ".." + std::to_string(first + p) +
          "); the ratio may be at most " + text::shortest(NurbsCurve::kMaxSpanWeightRatio) +
          ": such a curve runs almost straight into a near-corner that cannot be walked at "
          "speed (docs/feedrate.md §5.1); re-export the curve with weights nearer "
          "to 1, or as a polyline or a corner (G1 moves)");
    }
  }
}

void validate(int degree, const std::vector<double>& knots, const std::vector<Vec3>& points,
              const std::vector<double>& weights) {
  if (degree < NurbsCurve::kMinDegree || degree > NurbsCurve::kMaxDegree) {
    throw InputError("NURBS degree = " + std::to_string(degree) + " is out of range: it must be " +
                     std::to_string(NurbsCurve::kMinDegree) + " to " +
                     std::to_string(NurbsCurve::kMaxDegree) +
                     "; re-approximate the curve with a supported degree");
  }
  const auto p = static_cast<std::size_t>(degree);
  if (points.size() < p + 1) {
    throw InputError("NURBS of degree " + std::to_string(degree) + " has " +
                     std::to_string(points.size()) + " control points, fewer than degree + 1 = " +
                     std::to_string(p + 1) + "; add control points or lower the degree");
  }
  if (knots.size() != points.size() + p + 1) {
    throw InputError("NURBS knot vector has " + std::to_string(knots.size()) + " knots, but " +
                     std::to_string(points.size()) + " control points of degree " +
                     std::to_string(degree) +
                     " need points + degree + 1 = " + std::to_string(points.size() + p + 1) +
                     "; give one knot per point plus degree + 1");
  }
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) {
      throw InputError("NURBS control point[" + std::to_string(i) +
                       "] = " + text::point(points[i]) +
                       " is not finite; every coordinate must be a number");
    }
  }
  validate_knots(knots, p);
  if (!weights.empty()) validate_weights(weights, points.size(), p);
}

}  // namespace

NurbsCurve::NurbsCurve(int degree, std::vector<double> knots, std::vector<Vec3> points,
                       std::vector<double> weights)
    : degree_(degree),
      knots_(std::move(knots)),
      points_(std::move(points)),
      weights_(std::move(weights)),
      rational_(false) {
  validate(degree_, knots_, points_, weights_);
  if (weights_.empty()) weights_.assign(points_.size(), 1.0);
  rational_ = std::any_of(weights_.begin(), weights_.end(), [](double w) { return w != 1.0; });
  weighted_points_.resize(points_.size());
  for (std::size_t i = 0; i < points_.size(); ++i) weighted_points_[i] = weights_[i] * points_[i];
}

std::size_t NurbsCurve::find_span(double u) const {
  const auto p = static_cast<std::ptrdiff_t>(degree_);
  const auto n = static_cast<std::ptrdiff_t>(points_.size()) - 1;
  // Last knot ≤ u among knots[p .. n]; knots[p] = u_begin and knots[n] < knots[n+1] = u_end.
  const auto it = std::upper_bound(knots_.begin() + p, knots_.begin() + n + 1, u);
  return static_cast<std::size_t>(std::max(p, (it - knots_.begin()) - 1));
}

namespace {

// Steps 2–4 for a degree P known at compile time: the loops unroll and the arrays shrink to
// P + 1, but every operation and its order are those of the general algorithm, so the result
// is the same bit for bit whatever the degree. ND: the derivatives wanted (2, or 1 for P' alone,
// which skips the second derivative's work and leaves d2 zero; P and P' are the same bits).
template <std::size_t P, std::size_t ND = 2>
CurvePoint eval_on_span(double u, std::size_t s, const double* knots, const Vec3* weighted_points,
                        const double* weights) {
  constexpr std::size_t p = P;
  constexpr std::size_t kOrder = P + 1;
  // A2.3: ndu[j][r] (r ≤ j) knot differences, ndu[r][j] (r < j) basis functions of degree j.
  std::array<std::array<double, kOrder>, kOrder> ndu{};
  std::array<double, kOrder> left{}, right{};
  ndu[0][0] = 1.0;
  for (std::size_t j = 1; j <= p; ++j) {
    left[j] = u - knots[s + 1 - j];
    right[j] = knots[s + j] - u;
    double saved = 0.0;
    for (std::size_t r = 0; r < j; ++r) {
      ndu[j][r] = right[r + 1] + left[j - r];
      const double temp = ndu[r][j - 1] / ndu[j][r];
      ndu[r][j] = saved + right[r + 1] * temp;
      saved = left[j - r] * temp;
    }
    ndu[j][j] = saved;
  }
  std::array<std::array<double, kOrder>, ND + 1> ders{};  // ders[k][j] = d^k N_{s−p+j,p}/du^k
  for (std::size_t j = 0; j <= p; ++j) ders[0][j] = ndu[j][p];
  constexpr std::size_t nd = std::min<std::size_t>(ND, p);  // derivatives above p vanish
  constexpr auto pi = static_cast<std::ptrdiff_t>(p);
  for (std::ptrdiff_t r = 0; r <= pi; ++r) {
    std::array<std::array<double, kOrder>, 2> a{};
    std::size_t s1 = 0, s2 = 1;
    a[0][0] = 1.0;
    for (std::ptrdiff_t k = 1; k <= static_cast<std::ptrdiff_t>(nd); ++k) {
      double d = 0.0;
      const std::ptrdiff_t rk = r - k, pk = pi - k;
      const auto at = [](std::ptrdiff_t i) { return static_cast<std::size_t>(i); };
      if (r >= k) {
        a[s2][0] = a[s1][0] / ndu[at(pk + 1)][at(rk)];
        d = a[s2][0] * ndu[at(rk)][at(pk)];
      }
      const std::ptrdiff_t j1 = rk >= -1 ? 1 : -rk;
      const std::ptrdiff_t j2 = r - 1 <= pk ? k - 1 : pi - r;
      for (std::ptrdiff_t j = j1; j <= j2; ++j) {
        a[s2][at(j)] = (a[s1][at(j)] - a[s1][at(j - 1)]) / ndu[at(pk + 1)][at(rk + j)];
        d += a[s2][at(j)] * ndu[at(rk + j)][at(pk)];
      }
      if (r <= pk) {
        a[s2][at(k)] = -a[s1][at(k - 1)] / ndu[at(pk + 1)][at(r)];
        d += a[s2][at(k)] * ndu[at(r)][at(pk)];
      }
      ders[at(k)][at(r)] = d;
      std::swap(s1, s2);
    }
  }
  double factor = static_cast<double>(p);  // p!/(p−k)!
  for (std::size_t k = 1; k <= nd; ++k) {
    for (std::size_t j = 0; j <= p; ++j) ders[k][j] *= factor;
    factor *= static_cast<double>(p - k);
  }

  // Homogeneous sums over the active points s−p … s.
  std::array<Vec3, ND + 1> A;
  A.fill(Vec3::Zero());
  std::array<double, ND + 1> w{};
  for (std::size_t j = 0; j <= p; ++j) {
    const std::size_t i = s - p + j;
    for (std::size_t k = 0; k <= ND; ++k) {
      A[k] += ders[k][j] * weighted_points[i];
      w[k] += ders[k][j] * weights[i];
    }
  }
  CurvePoint c;
  c.p = A[0] / w[0];
  c.d1 = (A[1] - w[1] * c.p) / w[0];
  if constexpr (ND >= 2) {
    c.d2 = (A[2] - 2.0 * w[1] * c.d1 - w[2] * c.p) / w[0];
  } else {
    c.d2 = Vec3::Zero();
  }
  return c;
}

// The degree's instantiation of eval_on_span at u (clamped), after A2.1's span search.
template <std::size_t ND>
CurvePoint eval_at(int degree, double u, std::size_t s, const double* k, const Vec3* wp,
                   const double* w) {
  switch (degree) {
    case 1:
      return eval_on_span<1, ND>(u, s, k, wp, w);
    case 2:
      return eval_on_span<2, ND>(u, s, k, wp, w);
    case 3:
      return eval_on_span<3, ND>(u, s, k, wp, w);
    case 4:
      return eval_on_span<4, ND>(u, s, k, wp, w);
    case 5:
      return eval_on_span<5, ND>(u, s, k, wp, w);
    case 6:
      return eval_on_span<6, ND>(u, s, k, wp, w);
    default:
      static_assert(NurbsCurve::kMaxDegree == 7, "one case per degree");
      return eval_on_span<7, ND>(u, s, k, wp, w);
  }
}

}  // namespace

CurvePoint NurbsCurve::eval(double u) const {
  u = std::clamp(u, u_begin(), u_end());
  return eval_at<2>(degree_, u, find_span(u), knots_.data(), weighted_points_.data(),
                    weights_.data());
}

Vec3 NurbsCurve::derivative(double u) const {
  std::size_t no_hint = 0;  // never a valid span (< degree): the span search
  return derivative(u, no_hint);
}

Vec3 NurbsCurve::derivative(double u, std::size_t& span_hint) const {
  u = std::clamp(u, u_begin(), u_end());
  const std::size_t h = span_hint;  // valid: knots[h] ≤ u < knots[h+1] inside [p, n]
  if (!(h >= static_cast<std::size_t>(degree_) && h < points_.size() && knots_[h] <= u &&
        u < knots_[h + 1])) {
    span_hint = find_span(u);
  }
  return eval_at<1>(degree_, u, span_hint, knots_.data(), weighted_points_.data(), weights_.data())
      .d1;
}

std::vector<double> NurbsCurve::breakpoints() const {
  std::vector<double> b;
  for (double k : knots_) {
    if (b.empty() || k != b.back()) b.push_back(k);
  }
  return b;
}

}  // namespace ncd::toolpath
