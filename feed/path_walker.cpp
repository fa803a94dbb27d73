// Walking a Path by planned arc length.
//
// The planner hands one arc length per period, Δs = s(t+T) − s(t). The walker keeps the debt
// D = Σ Δs − Σ (true arc travelled), itself a small number updated by small numbers (never the
// difference of two long totals, whose rounding would swamp a 1 µm step after 300 m), and asks
// each period for D + Δs, so the per-step residual of the curve walker (≤ its tolerance) never
// accumulates: the drift at the end is one step's residual, not the sum of all of them.
//
//   segment k (NURBS)          segment k+1 (polyline)
//   ─────────────●════════════════●─────●─────●────
//            u_i   CurveWalker      exact: p_i + (s − s_i) t_i
//
// On a NURBS segment the CurveWalker (Taylor predictor of eq. 7 + Newton on the true arc
// length) moves; on a polyline the position at arc length s is exact. A period that reaches a
// segment's end carries the rest of its arc into the next segment.
//
// Chord error: the controller moves straight between setpoints, so the error of a period is
// the largest distance of the path from that chord: for a curve portion we take its parametric
// midpoint (eq. 34 of paper 000), for a polyline every vertex crossed, and every joint between
// segments. These points are found again after the step from the recorded start, so nothing is
// stored per period.
#include "feed/path_walker.hpp"

#include <algorithm>
#include <cmath>

#include "core/error.hpp"
#include "core/quadrature.hpp"

namespace ncd::feed {
namespace {

double distance_to_chord(const Vec3& q, const Vec3& a, const Vec3& b) {
  const Vec3 chord = b - a;
  const double len = chord.norm();
  return len > 0.0 ? (q - a).cross(chord).norm() / len : (q - a).norm();
}

}  // namespace

double arc_length_mm(const toolpath::ParametricCurve& curve, double u0, double u1) {
  const auto speed = [&curve](double u) { return curve.derivative(u).norm(); };
  // Four panels before the adaptive check: the path length is what the last period lands on,
  // so its error would show up there as a feed error.
  constexpr int kPanels = 4;
  const double h = (u1 - u0) / kPanels;
  double total = 0.0;
  for (int k = 0; k < kPanels; ++k) {
    const double a = u0 + k * h, b = k + 1 == kPanels ? u1 : a + h;
    total += GaussLegendre10::adaptive(speed, a, b, GaussLegendre10::integrate(speed, a, b));
  }
  return total;
}

double curve_length_mm(const toolpath::ParametricCurve& curve) {
  const std::vector<double> knots = curve.breakpoints();
  double total = 0.0;
  for (std::size_t i = 0; i + 1 < knots.size(); ++i) {
    if (knots[i + 1] > knots[i]) total += arc_length_mm(curve, knots[i], knots[i + 1]);
  }
  return total;
}

PathWalker::PathWalker(const toolpath::Path& path, const WalkerConfig& config)
    : path_(path), config_(config) {
  if (path.segments.empty()) throw InputError("the path " + path.source + " has no moves");
  for (const auto& seg : path.segments) {
    starts_mm_.push_back(total_length_mm_);
    if (const auto* line = std::get_if<toolpath::Polyline>(&seg.geometry)) {
      std::vector<double> s{0.0};
      for (std::size_t i = 1; i < line->points.size(); ++i) {
        s.push_back(s.back() + (line->points[i] - line->points[i - 1]).norm());
      }
      total_length_mm_ += s.back();
      vertex_s_mm_.push_back(std::move(s));
      curves_.push_back(nullptr);
    } else {
      const auto& curve = std::get<toolpath::NurbsCurve>(seg.geometry);
      total_length_mm_ += curve_length_mm(curve);
      vertex_s_mm_.emplace_back();
      curves_.push_back(std::make_unique<CurveWalker>(curve, config_));
    }
  }
  starts_mm_.push_back(total_length_mm_);
  const auto& first = path.segments.front().geometry;
  position_ = std::holds_alternative<toolpath::Polyline>(first)
                  ? std::get<toolpath::Polyline>(first).points.front()
                  : std::get<toolpath::NurbsCurve>(first).eval(curves_[0]->u()).p;
}

double PathWalker::curve_u() const {
  return curves_[segment_] ? curves_[segment_]->u() : 0.0;
}

Vec3 PathWalker::polyline_point(const toolpath::Polyline& line, double s_mm) const {
  const auto& s = vertex_s_mm_[segment_];
  const double len = s[vertex_ + 1] - s[vertex_];
  const double f = len > 0.0 ? (s_mm - s[vertex_]) / len : 0.0;
  return line.points[vertex_] + f * (line.points[vertex_ + 1] - line.points[vertex_]);
}

double PathWalker::advance_in_segment(double delta_s_mm, WalkStep& out) {
  const auto& geometry = path_.segments[segment_].geometry;
  if (const auto* line = std::get_if<toolpath::Polyline>(&geometry)) {
    const auto& s = vertex_s_mm_[segment_];
    const double target = s_in_segment_mm_ + delta_s_mm;
    if (target >= s.back()) {
      const double moved = s.back() - s_in_segment_mm_;
      s_in_segment_mm_ = s.back();
      vertex_ = s.size() - 2;
      position_ = line->points.back();
      return moved;
    }
    s_in_segment_mm_ = target;
    while (vertex_ + 2 < s.size() && s[vertex_ + 1] <= target) ++vertex_;
    position_ = polyline_point(*line, target);
    return delta_s_mm;
  }
  CurveWalker& walker = *curves_[segment_];
  const StepResult r = walker.step(delta_s_mm);
  out.iterations += r.iterations;
  if (r.status == StepStatus::NotConverged) out.converged = false;
  position_ = std::get<toolpath::NurbsCurve>(geometry).eval(r.u).p;
  const double moved = std::isfinite(r.arc_length_mm) ? r.arc_length_mm : 0.0;
  s_in_segment_mm_ += moved;
  return r.status == StepStatus::ReachedEnd ? moved : delta_s_mm;
}

WalkStep PathWalker::advance(double delta_s_mm) {
  WalkStep out;
  const Vec3 start = position_;
  const std::size_t seg0 = segment_, vertex0 = vertex_;
  const double u0 = curves_[segment_] ? curves_[segment_]->u() : 0.0;
  debt_mm_ += delta_s_mm;
  double remaining = debt_mm_;
  double moved_total = 0.0;
  while (remaining > 0.0) {
    const double before = s_in_segment_mm_;
    const double moved = advance_in_segment(remaining, out);
    const bool curve = curves_[segment_] != nullptr;
    const double actual = curve ? s_in_segment_mm_ - before : moved;
    moved_total += actual;
    remaining -= actual;
    const bool segment_done =
        curve ? curves_[segment_]->at_end() : s_in_segment_mm_ >= vertex_s_mm_[segment_].back();
    if (!segment_done) break;  // the curve walker met the request to its tolerance
    if (segment_ + 1 == path_.segments.size()) {
      out.at_end = true;
      break;
    }
    ++segment_;
    s_in_segment_mm_ = 0.0;
    vertex_ = 0;
    if (curves_[segment_]) {
      curves_[segment_]->reset(
          std::get<toolpath::NurbsCurve>(path_.segments[segment_].geometry).u_begin());
    }
  }
  debt_mm_ -= moved_total;
  out.p = position_;
  out.travelled_mm = moved_total;
  out.segment = segment_;

  // Chord error of this period, from the points between start and end found again.
  double err = 0.0;
  for (std::size_t k = seg0; k <= segment_; ++k) {
    const auto& geometry = path_.segments[k].geometry;
    if (k > seg0) {  // the joint where segment k begins
      const Vec3 joint = curves_[k] ? std::get<toolpath::NurbsCurve>(geometry)
                                          .eval(std::get<toolpath::NurbsCurve>(geometry).u_begin())
                                          .p
                                    : std::get<toolpath::Polyline>(geometry).points.front();
      err = std::max(err, distance_to_chord(joint, start, position_));
    }
    if (const auto* line = std::get_if<toolpath::Polyline>(&geometry)) {
      // Vertices crossed: those after the start's piece up to the end's piece.
      const std::size_t first = k == seg0 ? vertex0 + 1 : 1;
      const std::size_t last = k == segment_ ? vertex_ : line->points.size() - 1;
      for (std::size_t v = first; v <= last; ++v) {
        err = std::max(err, distance_to_chord(line->points[v], start, position_));
      }
    } else {
      const auto& curve = std::get<toolpath::NurbsCurve>(geometry);
      const double ua = k == seg0 ? u0 : curve.u_begin();
      const double ub = k == segment_ ? curves_[k]->u() : curve.u_end();
      err = std::max(err, distance_to_chord(curve.eval(0.5 * (ua + ub)).p, start, position_));
    }
  }
  out.chord_error_mm = err;
  return out;
}

}  // namespace ncd::feed
