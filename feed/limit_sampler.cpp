// The feed-limit curve along a Path, streamed for the planner.
//
// Contract with the planner: between two consecutive nodes the planner holds the feed below
// the smaller of their two values. So each node carries the minimum of the true limit over
// BOTH intervals it bounds; then min(v_k, v_k+1) is never above the true limit anywhere on
// [s_k, s_k+1], and a curvature peak cannot slip between two samples:
//
//     true limit  ‾‾‾\_/‾‾‾‾‾‾‾‾\___/‾‾‾
//     intervals   |  m0 | m1 | m2 | m3 |        m_i = min of the limit over interval i
//     nodes       v0    v1   v2   v3   v4       v_k = min(m_k-1, m_k)
//
// The job also hands the planner each interval's own minimum m_i (LimitNode::right_mm_per_s),
// which the planner holds instead of min(v_k, v_k+1) = min(m_k-1, m_k, m_k+1): on a slope of
// the limit that follows it an interval closer (docs/planner.md §2, "Each interval's own
// minimum").
//
// Intervals are at most `spacing_mm` long (0.2 mm: two per period at 100 mm/s and 4 ms; half
// that on a curve after an interval whose limit is below the cap and changing), with a node on
// every knot and vertex. The minimum over a curve interval: five samples, then
// Brent's method around the lowest (the minimum may sit just inside an end).
//
// What is limited (docs/planner.md §§1–3): on curves, feed_limit() at each point (roughness
// law with α = asin(t_z), chord error, centripetal acceleration and jerk, machine maximum); on
// polyline pieces the roughness law with α from the contact normals at both ends (or the
// piece's direction) and the machine maximum, plus, on a piece shorter than one period's
// travel, the curve laws at the discrete curvature 2 sin(φ/2) / min(l_in, l_out) of its end
// vertices (several vertices in one period: the polyline acts as a curve); everywhere the
// program's F word. Rapids (G0) take the machine maximum and the curve laws of short pieces.
// The roughness law applies to segments cut by a ball end only (geometry/tool.hpp), with the
// tool's own radius and teeth where it states them; other tools take the curve laws alone.
// At a corner (a polyline vertex, a joint, or an interior knot of a NURBS where the tangent
// turns by φ, next to curvature κ) the speed is bounded by
//
//     chord:     the chord of one period across the corner deviates (Δs/2) sin(φ/2) + κΔs²/8
//                ≤ ε_c → Δs, v ≤ Δs / T
//     junction:  the machine rounds the corner within ε_c at a_max (grbl's junction deviation)
//                → v² ≤ a_max ε_c cos(φ/2) / (1 − cos(φ/2))
//
// over the zone [c − v_c T, c + v_c T] (every period whose chord crosses the corner lies in
// it, since the planner checks whole periods). The zone has intervals of its own, with nodes
// at c ± v_c T and c ± 2 v_c T, so that the node rule slows only 4 v_c T of path, not the
// 0.2 mm intervals around it.
//
// Flat intervals (docs/planner.md §2a). On a long smooth curve the limit is mostly the cap
// (machine maximum or program F) and the search above spends ~45 curve evaluations per interval
// to find that. Where a bound proves every law above the cap over the whole interval, the
// search is skipped: its result would be the cap at every point it evaluates, and ties keep
// the first, so the node is the same bit for bit. The bound, for a non-rational curve of
// degree p ≥ 2 whose interior knots have multiplicity ≤ p − 1 (C' continuous):
//
//     |C''(u)| ≤ M2 = max |R_i| over the spans touched (convex hull of the second hodograph,
//                     R_i = (p−1)(Q_i+1 − Q_i)/(u_i+p+1 − u_i+2), Q_i = p(P_i+1 − P_i)/(u_i+p+1 −
//                     u_i+1), Piegl and Tiller eq. 3.8)
//     |C'(u)|  ≥ |C'(u0)| − M2 |u − u0|          (C' is continuous)
//     κ(u) = |C' × C''| / |C'|³ ≤ M2 / min|C'|²
//
// with margins for the rounding of eval(); the curve laws are decreasing in κ, and the
// roughness law is smallest at α = 0 (docs/feedrate.md §1), so the limit is at least
// min(roughness(0), chord(κ_max), accel(κ_max), jerk(κ_max)). The interval is flat if that
// exceeds the cap by 1e-6 (relative). Rational curves and corners at knots always search.
//
// Stops (stops_mm()): where the motion must rest, no zone is applied; the job plans the
// stretches between stops separately, and takes each node's left and right interval values
// at a stop for the stretch on that side.
//
// Jerk vector (JerkBound::vector, docs/planner.md §3c): every interval also gets its largest
// curvature κ and curvature turn g (nine points), its speed lowered where the jerk-vector law
// asks (jerk_vector_feed_mm_per_s) and a tangential scale σ for the planner; corners and
// curvature jumps (C¹ knots, tangent joints) get the jump law as a corner speed, and the
// intervals within two periods' travel of them the rest of the jerk budget.
//
// Rest refinement (docs/planner.md §3): at a rest point where a curve's limit dips towards 0
// (a repeated control point), the intervals double away from it from d₁ = J T³/6 and halve
// towards it; the innermost one takes at least v_rest(d₁) = (4.5 J d₁²)^(1/3), a speed no
// jerk-limited motion exceeds within d₁ of rest, so the dip at the point is no cap. The
// segment's own caps (programmed feed, maximum feed) stay caps there.
#include "feed/limit_sampler.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

#include "core/error.hpp"
#include "core/number_text.hpp"
#include "core/quadrature.hpp"
#include "feed/corner_blend.hpp"
#include "feed/path_walker.hpp"

namespace ncd::interpolator {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// Half intervals follow one whose limit is below the cap (by 0.1 %) and changed from the one
// before by more than kFineStep of itself (a slope of the limit; docs/planner.md §2).
constexpr double kFineBelowCap = 0.999;
constexpr double kFineStep = 0.005;

// The mode that decides whether a corner is a rest. G64 P0 (or a plain G64 with
// blend_tolerance_mm 0) holds its end points exactly, as G61.1 does: its corners are rests
// (docs/planner.md §3a; passed at the corner speed they would be missed by up to ε_c).
toolpath::PathControl corner_mode(const toolpath::PathSegment& s, const MachineLimits& l) {
  if (s.path_control != toolpath::PathControl::blend) return s.path_control;
  const double p_mm = s.blend_tolerance_mm.value_or(l.blend_tolerance_mm);
  return std::isfinite(p_mm) && p_mm > 0.0 ? toolpath::PathControl::blend
                                           : toolpath::PathControl::exact_path;
}

// The argument of the minimum of a unimodal f on [a, b], by golden section, to width tol.
template <typename F>
double golden_section_min(F&& f, double a, double b, double tol) {
  constexpr double kGolden = 0.6180339887498949;
  double x1 = b - kGolden * (b - a), x2 = a + kGolden * (b - a);
  double f1 = f(x1), f2 = f(x2);
  for (int it = 0; it < 100 && b - a > tol; ++it) {
    if (f1 <= f2) {
      b = x2, x2 = x1, f2 = f1, x1 = b - kGolden * (b - a), f1 = f(x1);
    } else {
      a = x1, x1 = x2, f1 = f2, x2 = a + kGolden * (b - a), f2 = f(x2);
    }
  }
  return f1 <= f2 ? x1 : x2;
}
constexpr double kMinTurnRad = 1e-9;  // below this a joint is straight
// Where the limit jumps at a smooth knot, the nodes beside it lie this many periods of travel
// (at the lower speed) from it: the slow stretch is the arc and these two guards. One whole
// period held the arc's speed two periods longer at each corner (gentle zig-zag under G64
// P0.01: 3.040 s; a quarter: 2.960 s, and a tenth the same; docs/planner.md §3a).
constexpr double kGuardPeriods = 0.25;

FeedLimitResult min_of(FeedLimitResult a, FeedLimitResult b) {
  return b.feed_mm_per_s < a.feed_mm_per_s ? b : a;
}

Vec3 unit_or_zero(const Vec3& v) {
  const double n = v.norm();
  return n > 0.0 ? Vec3(v / n) : Vec3::Zero();
}

// The arc length of c over [a, b] by the 10-point rule (the sampler's intervals hold no knot,
// so the rule is exact to rounding there), its nodes sharing one span search.
double gauss_arc_mm(const toolpath::NurbsCurve& c, double a, double b) {
  std::size_t span = 0;
  return GaussLegendre10::integrate([&c, &span](double w) { return c.derivative(w, span).norm(); },
                                    a, b);
}

// The parametric speed |C'| = |d1| vanishes to rounding: below 1e-9 of the curve's size (its
// largest control point, at least 1 mm) per unit of its parameter range.
bool speed_vanishes(const toolpath::NurbsCurve& c, const Vec3& d1) {
  double top = 0.0;
  for (const Vec3& q : c.points()) top = std::max(top, q.norm());
  return !(d1.norm() > 1e-9 * std::max(1.0, top) / std::max(c.u_end() - c.u_begin(), 1e-300));
}

}  // namespace

LimitSampler::LimitSampler(const toolpath::Path& path, std::vector<double> segment_starts_mm,
                           const MachineLimits& limits, const CuttingParams& cutting,
                           const SamplerConfig& config)
    : path_(path),
      starts_mm_(std::move(segment_starts_mm)),
      limits_(limits),
      cutting_(cutting),
      config_(config) {
  const std::size_t n = path.segments.size();
  set_tool_laws();  // before any limit is taken (the knot edges below take them)
  joint_corner_.assign(n + 1, FeedLimitResult{kInf, FeedLimit::Corner});
  joint_share_.assign(n + 1, 0.0);
  inner_corners_.resize(n);
  const auto direction = [&](std::size_t k, bool at_end) -> Vec3 {
    const auto& g = path.segments[k].geometry;
    if (const auto* line = std::get_if<toolpath::Polyline>(&g)) {
      const auto& p = line->points;
      return unit_or_zero(at_end ? Vec3(p[p.size() - 1] - p[p.size() - 2]) : Vec3(p[1] - p[0]));
    }
    // At an end whose control point repeats, the parametric speed vanishes and the curvature
    // grows without bound (C = a u² + b u³: κ ~ 1/u): a stop. Rounding leaves d1 a few ulps
    // off zero there (and a noise direction), so it is measured against the curve's mean
    // parametric speed, its control polygon's length over its parameter range.
    const auto& c = std::get<toolpath::NurbsCurve>(g);
    const Vec3 d1 = c.eval(at_end ? c.u_end() : c.u_begin()).d1;
    double polygon_mm = 0.0;
    for (std::size_t i = 0; i + 1 < c.points().size(); ++i) {
      polygon_mm += (c.points()[i + 1] - c.points()[i]).norm();
    }
    const double mean_speed = polygon_mm / (c.u_end() - c.u_begin());
    return d1.norm() > 1e-9 * mean_speed ? unit_or_zero(d1) : Vec3::Zero();
  };
  // The curvature next to a joint: the curve's, or on a polyline the discrete curvature of
  // the vertex next to the joint, 2 sin(φ/2) / min(l_in, l_out) (see limit_on_piece).
  const auto curvature = [&](std::size_t k, bool at_end) -> double {
    const auto& g = path.segments[k].geometry;
    if (const auto* c = std::get_if<toolpath::NurbsCurve>(&g)) {
      return curvature_per_mm(c->eval(at_end ? c->u_end() : c->u_begin()));
    }
    const auto& p = std::get<toolpath::Polyline>(g).points;
    if (p.size() < 3) return 0.0;
    const std::size_t v = at_end ? p.size() - 2 : 1;
    const Vec3 in = p[v] - p[v - 1], out = p[v + 1] - p[v];
    const double l = std::min(in.norm(), out.norm());
    if (!(l > 0.0)) return 0.0;
    const double cos_phi = std::clamp(in.dot(out) / (in.norm() * out.norm()), -1.0, 1.0);
    return 2.0 * std::sqrt(0.5 * (1.0 - cos_phi)) / l;
  };
  // The curvature vector next to a joint (JerkBound::vector): a curve's; zero on a polyline.
  const auto curvature_vector = [&](std::size_t k, bool at_end) -> Vec3 {
    const auto* c = std::get_if<toolpath::NurbsCurve>(&path.segments[k].geometry);
    if (c == nullptr || limits_.jerk_bound != JerkBound::vector) return Vec3::Zero();
    return curvature_vector_per_mm(c->eval(at_end ? c->u_end() : c->u_begin()));
  };
  // Joints (the corner where segment k begins belongs to the move ending there, k − 1) and
  // the interior vertices of polylines, in increasing s; the interior vertices' s is summed
  // exactly as next_interval() sums it, so that every stop is a node of the stream.
  for (std::size_t k = 0; k < n; ++k) {
    if (k > 0) {
      const Vec3 d_in = direction(k - 1, true), d_out = direction(k, false);
      const double dk = (curvature_vector(k, false) - curvature_vector(k - 1, true)).norm();
      const double kappa = std::max(curvature(k - 1, true), curvature(k, false));
      FeedLimitResult corner = corner_speed(d_in, d_out, kappa, dk);
      // Two joints within one period's step: a segment between them shorter than the step at
      // the corner speed puts both in one chord, which deviates by their summed turn (with the
      // short segment's own), not by either alone (the law above, with φ the sum, capped at π).
      const double step_mm =
          std::min(corner.feed_mm_per_s, limits_.max_feed_mm_per_min / 60.0) * limits_.period_s;
      const auto length = [&](std::size_t j) { return starts_mm_[j + 1] - starts_mm_[j]; };
      const auto turn = [](const Vec3& a, const Vec3& b) {
        return a.isZero() || b.isZero() ? 0.0 : std::acos(std::clamp(a.dot(b), -1.0, 1.0));
      };
      double phi_sum = turn(d_in, d_out);
      const double phi_alone = phi_sum;
      if (k + 1 < n && length(k) < step_mm) {
        phi_sum +=
            turn(d_out, direction(k, true)) + turn(direction(k, true), direction(k + 1, false));
      }
      if (k >= 2 && length(k - 1) < step_mm) {
        phi_sum += turn(direction(k - 1, false), d_in) +
                   turn(direction(k - 2, true), direction(k - 1, false));
      }
      if (phi_sum > phi_alone) {
        const double v =
            polyline_corner_speed_mm_per_s(limits_, std::min(phi_sum, std::numbers::pi), kappa);
        if (v < corner.feed_mm_per_s) corner = {v, FeedLimit::Corner};
      }
      // A summed turn can slow even a tangent joint below the stop threshold: it rests there.
      const bool summed_stop =
          phi_sum > phi_alone && !(corner.feed_mm_per_s >= stop_below_mm_per_s());
      if (path.segments[k].stop_before || summed_stop ||
          must_stop(d_in, d_out, corner_mode(path.segments[k - 1], limits_), corner)) {
        if (stops_mm_.empty() || starts_mm_[k] > stops_mm_.back()) {
          stops_mm_.push_back(starts_mm_[k]);
        }
      } else {
        joint_corner_[k] = corner;
        if (!d_in.isZero() && !d_out.isZero()) {
          joint_share_[k] = jump_share(std::acos(std::clamp(d_in.dot(d_out), -1.0, 1.0)), dk,
                                       corner.feed_mm_per_s);
        }
      }
    }
    if (const auto* c = std::get_if<toolpath::NurbsCurve>(&path.segments[k].geometry)) {
      // Interior knots where the tangent turns: a stop, or a corner with its zone. Their s is
      // the span lengths summed as the walker sums them (adaptive Gauss–Legendre): with four
      // fixed panels a span that nearly reverses (|C'| from 30 down to 1 and back) put a stop
      // 7e-4 mm past its knot, and the motion turned the corner at 0.1 mm/s before resting
      // (a jerk vector of 36 500 mm/s³: Property.RandomProgramsKeepTheJerkVectorBound, seed 47).
      const std::vector<double> bp = c->breakpoints();
      double s = starts_mm_[k];
      for (std::size_t i = 1; i + 1 < bp.size(); ++i) {
        s += arc_length_mm(*c, bp[i - 1], bp[i]);
        const toolpath::CurvePoint cl = c->eval(std::nextafter(bp[i], -kInf)), cr = c->eval(bp[i]);
        const Vec3 left = cl.d1, right = cr.d1;
        const Vec3 d_in = unit_or_zero(left), d_out = unit_or_zero(right);
        // JerkBound::vector: a jump of the curvature vector (a C¹ knot) is a corner of its own.
        const double dk = limits_.jerk_bound == JerkBound::vector
                              ? (curvature_vector_per_mm(cr) - curvature_vector_per_mm(cl)).norm()
                              : 0.0;
        const double k_scale = std::max(curvature_per_mm(cl), curvature_per_mm(cr));
        const double phi = d_in.isZero() || d_out.isZero()
                               ? M_PI
                               : std::acos(std::clamp(d_in.dot(d_out), -1.0, 1.0));
        const bool smooth = phi < kMinTurnRad;
        const FeedLimitResult corner = corner_speed(d_in, d_out, k_scale, dk);
        const double share = jump_share(smooth ? 0.0 : phi, dk, corner.feed_mm_per_s);
        if (smooth) {  // a curvature jump: a corner only where it takes a share that counts
          if (share > 1e-6) {
            inner_corners_[k].push_back({bp[i], s, left.norm(), right.norm(), corner, share});
          }
          continue;
        }
        if (must_stop(d_in, d_out, corner_mode(path.segments[k], limits_), corner)) {
          if (stops_mm_.empty() || s > stops_mm_.back()) stops_mm_.push_back(s);
        } else {
          inner_corners_[k].push_back({bp[i], s, left.norm(), right.norm(), corner, share});
        }
      }
    }
    if (const auto* line = std::get_if<toolpath::Polyline>(&path.segments[k].geometry)) {
      double s = starts_mm_[k];
      for (std::size_t v = 1; v + 1 < line->points.size(); ++v) {
        s += (line->points[v] - line->points[v - 1]).norm();
        if (vertex_is_stop(k, v) && (stops_mm_.empty() || s > stops_mm_.back())) {
          stops_mm_.push_back(s);
        }
      }
    }
  }
  const double total = starts_mm_[n];
  while (!stops_mm_.empty() && stops_mm_.back() >= total) stops_mm_.pop_back();
  std::erase_if(stops_mm_, [](double s) { return s <= 0.0; });
  breakpoints_.resize(n);  // here, so that walking the segments later allocates nothing
  knot_edges_.resize(n);
  // A jump of the limit by more than this factor gets nodes of its own (edge_speed).
  constexpr double kJumpRatio = 1.5;
  const auto jump = [&](double a, double b) {
    const double lo = std::min(a, b), hi = std::max(a, b);
    return lo > 0.0 && std::isfinite(lo) && hi > kJumpRatio * lo ? lo : kInf;
  };
  dips_.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    if (const auto* c = std::get_if<toolpath::NurbsCurve>(&path.segments[k].geometry)) {
      breakpoints_[k] = c->breakpoints();
      find_dips(*c, breakpoints_[k], dips_[k]);
      for (const double u : dips_[k]) refuse_cusp(path, k, *c, u);
      for (const double u : breakpoints_[k]) {
        const toolpath::CurvePoint cl = c->eval(std::nextafter(u, -kInf)), cr = c->eval(u);
        const bool interior = u > c->u_begin() && u < c->u_end();
        const double v = interior ? jump(limit_on_curve(k, std::nextafter(u, -kInf)).feed_mm_per_s,
                                         limit_on_curve(k, u).feed_mm_per_s)
                                  : kInf;
        knot_edges_[k].push_back({v, cl.d1.norm(), cr.d1.norm()});
      }
    }
  }
  // Flat intervals: the bounds of every span of the curves that qualify (see the top).
  span_bounds_.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const auto* c = std::get_if<toolpath::NurbsCurve>(&path.segments[k].geometry);
    if (c == nullptr || c->rational() || c->degree() < 2) continue;
    const auto p = static_cast<std::size_t>(c->degree());
    const auto& U = c->knots();
    const auto& P = c->points();
    bool c1 = true;  // every interior knot of multiplicity ≤ p − 1: C' is continuous
    for (std::size_t i = p + 1, m = U.size() - p - 1; i < m && c1;) {
      std::size_t j = i;
      while (j + 1 < m && U[j + 1] == U[i]) ++j;
      c1 = j - i + 1 <= p - 1;
      i = j + 1;
    }
    if (!c1) continue;
    // First and second hodographs (Piegl and Tiller eq. 3.8): Q_i = p (P_i+1 − P_i) /
    // (u_i+p+1 − u_i+1), R_i = (p − 1)(Q_i+1 − Q_i) / (u_i+p+1 − u_i+2); on span s, C'' is a
    // convex combination of R_s−p … R_s−2.
    const std::size_t np = P.size();
    std::vector<Vec3> q(np - 1), r(np - 2);
    for (std::size_t i = 0; i + 1 < np; ++i) {
      q[i] = static_cast<double>(p) * (P[i + 1] - P[i]) / (U[i + p + 1] - U[i + 1]);
    }
    bool finite = true;
    for (std::size_t i = 0; i + 2 < np; ++i) {
      r[i] = static_cast<double>(p - 1) * (q[i + 1] - q[i]) / (U[i + p + 1] - U[i + 2]);
      finite = finite && r[i].allFinite();
    }
    if (!finite) continue;
    auto& bounds = span_bounds_[k];
    bounds.assign(U.size(), SpanBound{kInf, kInf});
    for (std::size_t sp = p; sp < np; ++sp) {
      double d2 = 0.0, pm = 0.0;
      for (std::size_t i = sp - p; i + 2 <= sp; ++i) d2 = std::max(d2, r[i].norm());
      for (std::size_t i = sp - p; i <= sp; ++i) pm = std::max(pm, P[i].norm());
      bounds[sp] = {d2, pm};
    }
  }
  joint_edge_.assign(n + 1, kInf);
  for (std::size_t k = 1; k < n; ++k) {
    if (std::isfinite(joint_corner_[k].feed_mm_per_s)) {
      joint_edge_[k] = joint_corner_[k].feed_mm_per_s;  // a corner: its zone
    } else if (!std::binary_search(stops_mm_.begin(), stops_mm_.end(), starts_mm_[k])) {
      joint_edge_[k] =
          jump(side_limit(k - 1, true).feed_mm_per_s, side_limit(k, false).feed_mm_per_s);
    }
  }
}

// The roughness law caps a segment cut by a ball end (geometry/tool.hpp), with the tool's own
// ball radius and teeth where it states them; a ball of its own is checked as [cutting] is.
void LimitSampler::set_tool_laws() {
  const std::size_t n = path_.segments.size();
  seg_cutting_.assign(n, cutting_);
  law_.assign(n, 0);
  roughness_floor_mm_per_s_.assign(n, kInf);
  for (std::size_t k = 0; k < n; ++k) {
    const toolpath::PathSegment& seg = path_.segments[k];
    if (seg.rapid || !seg.tool.roughness_law()) continue;
    CuttingParams& c = seg_cutting_[k];
    if (seg.tool.radius_mm > 0.0) c.ball_radius_mm = seg.tool.radius_mm;
    if (seg.tool.teeth > 0) c.teeth = seg.tool.teeth;
    if (c.ball_radius_mm != cutting_.ball_radius_mm || c.teeth != cutting_.teeth) {
      try {
        validate(c);
      } catch (const InputError& e) {
        throw InputError(path_.source + ":" + std::to_string(seg.source_line) + ": tool T" +
                         std::to_string(seg.tool.number) + ", a ball end of radius " +
                         text::sig(c.ball_radius_mm) + " mm and " + std::to_string(c.teeth) +
                         " teeth: " + e.what() +
                         "; correct the tool's entry (D, teeth=) or its kind");
      }
    }
    law_[k] = 1;
    roughness_floor_mm_per_s_[k] = roughness_feed_mm_per_s(c, 0.0);
  }
}

FeedLimitResult LimitSampler::cutting_limit(std::size_t segment, double curvature_per_mm,
                                            double inclination_rad) const {
  if (law_[segment] == 0) return curve_feed_limit(limits_, curvature_per_mm);
  return feed_limit(limits_, seg_cutting_[segment], curvature_per_mm, inclination_rad);
}

FeedLimitResult LimitSampler::side_limit(std::size_t segment, bool at_end) const {
  const auto& g = path_.segments[segment].geometry;
  if (const auto* c = std::get_if<toolpath::NurbsCurve>(&g)) {
    return limit_on_curve(segment, at_end ? std::nextafter(c->u_end(), -kInf) : c->u_begin());
  }
  const auto& line = std::get<toolpath::Polyline>(g);
  return limit_on_piece(segment, at_end ? line.points.size() - 2 : 0);
}

// The speed that places the nodes around vertex `vertex` of a polyline (next_zone_edge_mm):
// its corner speed, or at a joint the corner's or the jump's (joint_edge_).
double LimitSampler::edge_speed(std::size_t segment, std::size_t vertex) const {
  const auto& line = std::get<toolpath::Polyline>(path_.segments[segment].geometry);
  if (vertex == 0) return joint_edge_[segment];
  if (vertex + 1 == line.points.size()) return joint_edge_[segment + 1];
  return corner_limit(segment, vertex).feed_mm_per_s;
}

double LimitSampler::stop_below_mm_per_s() const {
  return limits_.max_accel_mm_per_s2 * limits_.period_s;
}

bool LimitSampler::must_stop(const Vec3& d_in, const Vec3& d_out, toolpath::PathControl mode,
                             const FeedLimitResult& corner) const {
  if (d_in.isZero() || d_out.isZero()) return true;  // a zero-length move
  if (mode == toolpath::PathControl::exact_stop) return true;
  const double phi = std::acos(std::clamp(d_in.dot(d_out), -1.0, 1.0));
  if (phi < kMinTurnRad) return false;  // tangent: no corner
  if (mode == toolpath::PathControl::exact_path) return true;
  return !(corner.feed_mm_per_s >= stop_below_mm_per_s());
}

bool LimitSampler::vertex_is_stop(std::size_t segment, std::size_t vertex) const {
  const auto& line = std::get<toolpath::Polyline>(path_.segments[segment].geometry);
  const Vec3 d_in = unit_or_zero(line.points[vertex] - line.points[vertex - 1]);
  const Vec3 d_out = unit_or_zero(line.points[vertex + 1] - line.points[vertex]);
  return must_stop(d_in, d_out, corner_mode(path_.segments[segment], limits_),
                   corner_speed(d_in, d_out));
}

// κ: the larger curvature of the two sides at the corner (curves meeting there): the chord
// across the corner then also bows by κ Δs² / 8, so Δs solves
// (Δs / 2) sin(φ/2) + κ Δs² / 8 = ε_c (for κ = 0: Δs = 2 ε_c / sin(φ/2)).
// Under JerkBound::vector, also jump_feed_mm_per_s for the turn and the curvature jump Δκ
// (docs/planner.md §3c); on a tangent joint or a smooth knot that law alone.
FeedLimitResult LimitSampler::corner_speed(const Vec3& d_in, const Vec3& d_out,
                                           double curvature_per_mm,
                                           double curvature_jump_per_mm) const {
  if (d_in.isZero() || d_out.isZero()) return {0.0, FeedLimit::Corner};
  const double phi = std::acos(std::clamp(d_in.dot(d_out), -1.0, 1.0));
  FeedLimitResult r{polyline_corner_speed_mm_per_s(limits_, phi, curvature_per_mm),
                    FeedLimit::Corner};
  if (limits_.jerk_bound == JerkBound::vector && curvature_jump_per_mm > 0.0) {
    const double v =
        jump_feed_mm_per_s(limits_, phi < kMinTurnRad ? 0.0 : phi, curvature_jump_per_mm);
    if (v < r.feed_mm_per_s) r = {v, FeedLimit::JerkVector};
  }
  if (limits_.has_axis_limits() && phi >= kMinTurnRad) {
    // Per-axis limits (docs/planner.md §3f). The junction law with the acceleration the axes
    // allow along the direction change, min(a_max, min_i a_i / |u_i|), u the unit of
    // d_out − d_in; and the velocity jump v |Δd_i| of each axis, which the second difference
    // of the setpoints sees within one period: v |Δd_i| ≤ (1 − kAxisTangentialShare) a_i T,
    // the tangential motion around the corner keeping the rest (its intervals bend).
    const Vec3 dd = d_out - d_in, u = unit_or_zero(dd);
    const double T = limits_.period_s, keep = 1.0 - kAxisTangentialShare;
    double a = limits_.max_accel_mm_per_s2, v_jump = kInf;
    for (int i = 0; i < 3; ++i) {
      const double ai = axis_accel_for_planner(limits_, static_cast<std::size_t>(i));
      if (std::abs(u[i]) > 0.0) a = std::min(a, ai / std::abs(u[i]));
      if (std::abs(dd[i]) > 0.0) v_jump = std::min(v_jump, keep * ai * T / std::abs(dd[i]));
    }
    const double c = std::cos(0.5 * phi);
    const double junction =
        c < 1.0 ? std::sqrt(a * limits_.chord_tolerance_mm * c / (1.0 - c)) : kInf;
    const double v = std::min(junction, v_jump);
    if (v < r.feed_mm_per_s) r = {v, FeedLimit::Corner};
  }
  return r;
}

FeedLimitResult LimitSampler::segment_cap(std::size_t segment) const {
  const auto& seg = path_.segments[segment];
  FeedLimitResult cap{limits_.max_feed_mm_per_min / 60.0, FeedLimit::MaxFeed};
  if (!seg.rapid && seg.feed_mm_per_min) {
    cap = min_of(cap, {*seg.feed_mm_per_min / 60.0, FeedLimit::Program});
  }
  return cap;
}

FeedLimitResult LimitSampler::limit_on_curve(std::size_t segment, double u) const {
  const auto& seg = path_.segments[segment];
  const auto& c = std::get<toolpath::NurbsCurve>(seg.geometry);
  if (seg.rapid) {  // no cutting: the curve laws without the roughness law (a blended rapid)
    const toolpath::CurvePoint at = c.eval(u);
    const double kappa = curvature_per_mm(at);
    FeedLimitResult r = segment_cap(segment);
    if (limits_.has_axis_limits()) {
      r = min_of(r, axis_feed_limit(limits_, unit_or_zero(at.d1), curvature_vector_per_mm(at)));
    }
    r = min_of(r, {chord_feed_mm_per_s(kappa, limits_.chord_tolerance_mm, limits_.period_s),
                   FeedLimit::Chord});
    r = min_of(r, {centripetal_accel_feed_mm_per_s(kappa, limits_.max_accel_mm_per_s2),
                   FeedLimit::CentripetalAccel});
    return min_of(r, {centripetal_jerk_feed_mm_per_s(kappa, limits_.max_jerk_mm_per_s3),
                      FeedLimit::CentripetalJerk});
  }
  const toolpath::CurvePoint at = c.eval(u);
  const FeedLimitResult r =
      min_of(cutting_limit(segment, curvature_per_mm(at), inclination_from_tangent_rad(at.d1)),
             segment_cap(segment));
  if (!limits_.has_axis_limits()) return r;
  return min_of(r, axis_feed_limit(limits_, unit_or_zero(at.d1), curvature_vector_per_mm(at)));
}

FeedLimitResult LimitSampler::limit_on_piece(std::size_t segment, std::size_t piece) const {
  const auto& seg = path_.segments[segment];
  const auto& line = std::get<toolpath::Polyline>(seg.geometry);
  const auto& pts = line.points;
  const Vec3 dir = unit_or_zero(pts[piece + 1] - pts[piece]);
  FeedLimitResult r = segment_cap(segment);
  const double kappa = piece_curvature_per_mm(segment, piece);
  if (limits_.has_axis_limits()) {  // a dense piece's curvature vector: at most κ on each axis
    r = min_of(r, axis_feed_limit(limits_, dir, kappa * Vec3::Ones()));
  }
  if (seg.rapid) {  // no cutting: the curve laws without the roughness law
    r = min_of(r, {chord_feed_mm_per_s(kappa, limits_.chord_tolerance_mm, limits_.period_s),
                   FeedLimit::Chord});
    r = min_of(r, {centripetal_accel_feed_mm_per_s(kappa, limits_.max_accel_mm_per_s2),
                   FeedLimit::CentripetalAccel});
    r = min_of(r, {centripetal_jerk_feed_mm_per_s(kappa, limits_.max_jerk_mm_per_s3),
                   FeedLimit::CentripetalJerk});
    return r;
  }
  for (const std::size_t v : {piece, piece + 1}) {
    const double alpha = line.normals.empty() ? inclination_from_tangent_rad(dir)
                                              : inclination_from_normal_rad(line.normals[v], dir);
    r = min_of(r, cutting_limit(segment, kappa, alpha));
  }
  return r;
}

// The curvature a polyline piece acts with: 0, or on a piece shorter than one period's travel
// at its cap the discrete curvature of its end vertices (see limit_on_piece).
double LimitSampler::piece_curvature_per_mm(std::size_t segment, std::size_t piece) const {
  const auto& pts = std::get<toolpath::Polyline>(path_.segments[segment].geometry).points;
  const FeedLimitResult r = segment_cap(segment);
  // A piece shorter than one period's travel at the cap: several vertices fall inside one
  // period, so the polyline acts as a curve, of discrete curvature κ_v = 2 sin(φ_v / 2) /
  // min(l_in, l_out) at a vertex turning by φ_v (1/R on a polygon inscribed in a circle of
  // radius R); the piece takes the curve laws at the larger κ of its two ends (across a
  // joint with the neighbour's piece). Stops are left out: the motion rests there.
  double kappa = 0.0;
  if ((pts[piece + 1] - pts[piece]).norm() < r.feed_mm_per_s * limits_.period_s) {
    const auto& segs = path_.segments;
    // The piece before a vertex, or after it; across a joint, the neighbour's first or last
    // piece (a curve's tangent counts as a long piece); zero where there is none or the
    // motion rests at the vertex.
    const auto piece_before = [&](std::size_t v) -> Vec3 {
      if (v > 0) {  // (the last vertex is a joint: piece_after checks it)
        const bool stop = v + 1 < pts.size() && vertex_is_stop(segment, v);
        return stop ? Vec3::Zero() : Vec3(pts[v] - pts[v - 1]);
      }
      if (segment == 0 || !std::isfinite(joint_corner_[segment].feed_mm_per_s)) {
        return Vec3::Zero();
      }
      if (const auto* l = std::get_if<toolpath::Polyline>(&segs[segment - 1].geometry)) {
        return l->points.back() - l->points[l->points.size() - 2];
      }
      const auto& c = std::get<toolpath::NurbsCurve>(segs[segment - 1].geometry);
      return 1e9 * unit_or_zero(c.eval(c.u_end()).d1);
    };
    const auto piece_after = [&](std::size_t v) -> Vec3 {
      if (v + 1 < pts.size()) return pts[v + 1] - pts[v];
      if (segment + 1 == segs.size() || !std::isfinite(joint_corner_[segment + 1].feed_mm_per_s)) {
        return Vec3::Zero();
      }
      if (const auto* l = std::get_if<toolpath::Polyline>(&segs[segment + 1].geometry)) {
        return l->points[1] - l->points[0];
      }
      const auto& c = std::get<toolpath::NurbsCurve>(segs[segment + 1].geometry);
      return 1e9 * unit_or_zero(c.eval(c.u_begin()).d1);
    };
    for (const std::size_t v : {piece, piece + 1}) {
      const Vec3 in = piece_before(v), out = piece_after(v);
      const double l_in = in.norm(), l_out = out.norm();
      if (!(l_in > 0.0 && l_out > 0.0)) continue;
      const double cos_phi = std::clamp(in.dot(out) / (l_in * l_out), -1.0, 1.0);
      kappa = std::max(kappa, 2.0 * std::sqrt(0.5 * (1.0 - cos_phi)) / std::min(l_in, l_out));
    }
  }
  return kappa;
}

// JerkBound::vector: the discrete curvature vector of an interior vertex where a piece beside
// it is shorter than one period's travel at the cap (the polyline acts as a curve there:
// 2 sin(φ/2) / min(l_in, l_out) along the turn); 0 at a vertex between long pieces, where the
// motion rests, and at the ends.
Vec3 LimitSampler::vertex_curvature_vector(std::size_t segment, std::size_t vertex) const {
  const auto& pts = std::get<toolpath::Polyline>(path_.segments[segment].geometry).points;
  if (vertex == 0 || vertex + 1 >= pts.size() || vertex_is_stop(segment, vertex)) {
    return Vec3::Zero();
  }
  const Vec3 in = pts[vertex] - pts[vertex - 1], out = pts[vertex + 1] - pts[vertex];
  const double l_min = std::min(in.norm(), out.norm());
  if (!(l_min < segment_cap(segment).feed_mm_per_s * limits_.period_s)) return Vec3::Zero();
  const Vec3 turn = unit_or_zero(out) - unit_or_zero(in);  // |turn| = 2 sin(φ/2)
  return turn / l_min;
}

// The jump of the discrete curvature vector at a vertex of a dense run (the larger of its two
// sides): a curve whose curvature jumps there, for the jump law's 0.75 v² Δκ / T term.
double LimitSampler::vertex_curvature_jump_per_mm(std::size_t segment, std::size_t vertex) const {
  if (limits_.jerk_bound != JerkBound::vector) return 0.0;
  const auto& pts = std::get<toolpath::Polyline>(path_.segments[segment].geometry).points;
  const Vec3 here = vertex_curvature_vector(segment, vertex);
  const Vec3 before = vertex > 0 ? vertex_curvature_vector(segment, vertex - 1) : Vec3::Zero();
  const Vec3 after =
      vertex + 1 < pts.size() ? vertex_curvature_vector(segment, vertex + 1) : Vec3::Zero();
  return std::max((here - before).norm(), (after - here).norm());
}

FeedLimitResult LimitSampler::corner_limit(std::size_t segment, std::size_t vertex) const {
  const auto& line = std::get<toolpath::Polyline>(path_.segments[segment].geometry);
  if (vertex == 0) return joint_corner_[segment];
  if (vertex + 1 == line.points.size()) return joint_corner_[segment + 1];
  if (vertex_is_stop(segment, vertex)) return {kInf, FeedLimit::Corner};  // at rest there
  return corner_speed(unit_or_zero(line.points[vertex] - line.points[vertex - 1]),
                      unit_or_zero(line.points[vertex + 1] - line.points[vertex]), 0.0,
                      vertex_curvature_jump_per_mm(segment, vertex));
}

bool LimitSampler::interval_is_flat(std::size_t segment, double u0, double u1,
                                    double speed_u0) const {
  const auto& bounds = span_bounds_[segment];
  if (bounds.empty() || !(speed_u0 > 0.0) || !(u1 > u0)) return false;
  const auto& c = std::get<toolpath::NurbsCurve>(path_.segments[segment].geometry);
  const auto& U = c.knots();
  const auto p = static_cast<std::size_t>(c.degree());
  // Every point the search may evaluate lies in [u0 − δ, u1 + δ] (its steps reach tol =
  // 1e-9 (u1 − u0) past its bracket; the samples round by a few ulp).
  const double delta = 1e-6 * (u1 - u0) + 1e-12 * std::max(1.0, std::abs(u1));
  const double lo = std::max(u0 - delta, c.u_begin()), hi = std::min(u1 + delta, c.u_end());
  const auto span = [&](double u) {  // as NurbsCurve::find_span
    const auto it = std::upper_bound(U.begin() + static_cast<std::ptrdiff_t>(p),
                                     U.end() - static_cast<std::ptrdiff_t>(p) - 1, u);
    return std::max(p, static_cast<std::size_t>(it - U.begin()) - 1);
  };
  double d2 = 0.0, e1 = 0.0, e2 = 0.0;
  for (std::size_t s = span(lo), last = span(hi); s <= last; ++s) {
    const double h = U[s + 1] - U[s];
    if (!(h > 0.0)) continue;
    // Rounding of eval(): |N'| ≤ 2p / h and |N''| ≤ 4p(p − 1) / h² on the span, p + 1 terms,
    // each off by far less than 1e-12 of its size.
    const double pp = static_cast<double>(p), terms = pp + 1.0;
    e1 = std::max(e1, 1e-12 * terms * 2.0 * pp / h * bounds[s].p_max);
    e2 = std::max(e2, 1e-12 * terms * 4.0 * pp * (pp - 1.0) / (h * h) * bounds[s].p_max);
    d2 = std::max(d2, bounds[s].d2_max);
  }
  // |C'(u)| ≥ |C'(u0)| − max|C''| |u − u0| (C' is continuous), and κ = |C' × C''| / |C'|³ ≤
  // |C''| / |C'|².
  const double d1_min = speed_u0 - (d2 + e2) * (hi - u0 + delta) - 2.0 * e1;
  if (!(d1_min > 0.0)) return false;
  const double kappa = (d2 + e2) / (d1_min * d1_min) * (1.0 + 1e-9);
  const auto& seg = path_.segments[segment];
  double floor_mm_per_s =
      std::min({chord_feed_mm_per_s(kappa, limits_.chord_tolerance_mm, limits_.period_s),
                centripetal_accel_feed_mm_per_s(kappa, limits_.max_accel_mm_per_s2),
                centripetal_jerk_feed_mm_per_s(kappa, limits_.max_jerk_mm_per_s3)});
  if (!seg.rapid) floor_mm_per_s = std::min(floor_mm_per_s, roughness_floor_mm_per_s_[segment]);
  if (limits_.has_axis_limits()) {  // the axis laws at |t_i| ≤ 1 and |k_i| ≤ κ
    const FeedLimitResult ax = axis_feed_limit(limits_, Vec3::Ones(), kappa * Vec3::Ones());
    floor_mm_per_s = std::min(floor_mm_per_s, ax.feed_mm_per_s);
  }
  return floor_mm_per_s > segment_cap(segment).feed_mm_per_s * (1.0 + 1e-6);
}

FeedLimitResult LimitSampler::interval_min_on_curve(std::size_t segment, double u0, double u1,
                                                    bool open_end) const {
  // Five samples; the minimum lies within one sample step of the lowest of them (the limit is
  // smooth over 0.05 mm), where Brent's method (parabolic steps, golden-section fallback)
  // finds it in a few evaluations.
  // open_end: u1 is a knot where the limit jumps; it is left out, since the curve evaluates
  // there to the span that starts at it, whose limit belongs to the next interval.
  constexpr int kSamples = 5;
  if (open_end) u1 = std::max(u0, std::nextafter(u1, -kInf));
  const double step = (u1 - u0) / (kSamples - 1);
  FeedLimitResult best{std::numeric_limits<double>::infinity(), FeedLimit::MaxFeed};
  int at = 0;
  double f_at = kInf;  // the limit at the lowest sample
  const auto& c = std::get<toolpath::NurbsCurve>(path_.segments[segment].geometry);
  double speed_lo = kInf, speed_hi = 0.0;
  int slow = 0;
  for (int i = 0; i < kSamples; ++i) {
    const FeedLimitResult f = limit_on_curve(segment, u0 + step * i);
    if (f.feed_mm_per_s < best.feed_mm_per_s) best = f, at = i, f_at = f.feed_mm_per_s;
    const double speed = c.derivative(u0 + step * i).norm();
    if (speed < speed_lo) speed_lo = speed, slow = i;
    speed_hi = std::max(speed_hi, speed);
  }
  // A near-cusp inside a span: where the parametric speed |C'| dips, κ ≈ |C''| / |C'|² peaks
  // far more narrowly than the samples are spaced (a degree-5 curve of the random programs had
  // κ = 11 000 /mm within 0.001 mm, between two samples, and its chord error reached 1.2 % over
  // the tolerance). The dip of |C'| itself is broad: find its bottom (golden section) and take
  // the limit there too.
  if (speed_hi > 1.5 * speed_lo) {
    const double bottom = golden_section_min(
        [&c](double u) { return c.derivative(u).norm(); }, u0 + step * std::max(slow - 1, 0),
        u0 + step * std::min(slow + 1, kSamples - 1), 1e-12 * (u1 - u0));
    best = min_of(best, limit_on_curve(segment, bottom));
  }
  double a = u0 + step * std::max(at - 1, 0), b = u0 + step * std::min(at + 1, kSamples - 1);
  const double tol = 1e-9 * (u1 - u0);
  constexpr double kGolden = 0.3819660112501051;
  double x = u0 + step * at, w = x, v = x, e = 0.0, d = 0.0;
  // Brent starts from the lowest sample's own value: the bottom of a dip of |C'| above may
  // have lowered `best` below it, and a start below f(x) kept Brent at x (a minimum inside
  // [a, b] was then missed by up to 0.04 %: LimitSamplerInterval.RandomBSplines, seed 134).
  double fx = f_at, fw = fx, fv = fx;
  for (int it = 0; it < 60; ++it) {
    const double xm = 0.5 * (a + b);
    if (std::abs(x - xm) <= 2.0 * tol - 0.5 * (b - a)) break;
    bool golden = true;
    if (std::abs(e) > tol) {  // parabola through x, w, v
      const double r = (x - w) * (fx - fv);
      double q = (x - v) * (fx - fw);
      double p = (x - v) * q - (x - w) * r;
      q = 2.0 * (q - r);
      if (q > 0.0) p = -p;
      q = std::abs(q);
      if (std::abs(p) < std::abs(0.5 * q * e) && p > q * (a - x) && p < q * (b - x)) {
        e = d;
        d = p / q;
        golden = false;
      }
    }
    if (golden) {
      e = (x >= xm ? a : b) - x;
      d = kGolden * e;
    }
    const double u = std::abs(d) >= tol ? x + d : x + (d > 0.0 ? tol : -tol);
    const FeedLimitResult fu_r = limit_on_curve(segment, u);
    best = min_of(best, fu_r);
    const double fu = fu_r.feed_mm_per_s;
    if (fu <= fx) {
      (u >= x ? a : b) = x;
      v = w, fv = fw, w = x, fw = fx, x = u, fx = fu;
    } else {
      (u < x ? a : b) = u;
      if (fu <= fw || w == x) {
        v = w, fv = fw, w = u, fw = fu;
      } else if (fu <= fv || v == x || v == w) {
        v = u, fv = fu;
      }
    }
  }
  return best;
}

// The next edge past s_ of the corner zones at both ends of a piece (or a curve segment):
// c ± v T and c ± 2 v T for a corner of speed v at c. The intervals of the zone [c − vT, c + vT]
// take the corner speed; the ones just outside it keep their own limit, so that with the
// node rule (the minimum of both neighbours) the slow stretch is [c − 2vT, c + 2vT].
double LimitSampler::next_zone_edge_mm(double c0_mm, double v0, double c1_mm, double v1) const {
  const double tol = 1e-12 * std::max(1.0, std::abs(c1_mm));
  double best = kInf;
  const auto consider = [&](double e) {
    if (e > s_ + tol && e < c1_mm - tol && e < best) best = e;
  };
  if (std::isfinite(v0)) {
    consider(c0_mm + v0 * limits_.period_s);
    consider(c0_mm + 2.0 * v0 * limits_.period_s);
  }
  if (std::isfinite(v1)) {
    consider(c1_mm - 2.0 * v1 * limits_.period_s);
    consider(c1_mm - v1 * limits_.period_s);
  }
  return best;
}

double LimitSampler::jump_share(double phi, double dk, double v_corner) const {
  if (limits_.jerk_bound != JerkBound::vector) return 0.0;
  const double v = std::min(v_corner, limits_.max_feed_mm_per_min / 60.0);
  const double j = jump_jerk_mm_per_s3(limits_, phi < kMinTurnRad ? 0.0 : phi, dk, v);
  return std::min(kJumpJerkShare, j / limits_.max_jerk_mm_per_s3);
}

void LimitSampler::apply_zones(Interval& iv) const {
  const auto zone = [&](double center_mm, FeedLimitResult corner, double share) {
    if (!std::isfinite(corner.feed_mm_per_s)) return;
    const double half = corner.feed_mm_per_s * limits_.period_s;
    // The third difference of the setpoints spans three periods: the jump's share of the
    // jerk budget holds within two periods' travel of it.
    if (share > 0.0 && iv.a_mm < center_mm + 2.0 * half && iv.b_mm > center_mm - 2.0 * half) {
      iv.jump_share = std::max(iv.jump_share, share);
    }
    // Per-axis limits: the periods whose second difference sees the corner's jump keep the
    // tangential share (docs/planner.md §3f).
    if (limits_.has_axis_limits() && iv.a_mm < center_mm + 2.0 * half &&
        iv.b_mm > center_mm - 2.0 * half) {
      iv.bends = true;
    }
    if (iv.a_mm < center_mm + half && iv.b_mm > center_mm - half &&
        corner.feed_mm_per_s < iv.v_mm_per_s) {
      iv.v_mm_per_s = corner.feed_mm_per_s;
      iv.limit = corner.limit;
    }
  };
  const auto& g = path_.segments[segment_].geometry;
  if (const auto* line = std::get_if<toolpath::Polyline>(&g)) {
    // The two vertices of this piece, and the neighbours' (their zones may reach across).
    const std::size_t lo = piece_ > 0 ? piece_ - 1 : 0;
    const std::size_t hi = std::min(piece_ + 2, line->points.size() - 1);
    double s = piece_s_;
    for (std::size_t v = piece_; v > lo; --v) s -= (line->points[v] - line->points[v - 1]).norm();
    for (std::size_t v = lo; v <= hi; ++v) {
      const FeedLimitResult corner = corner_limit(segment_, v);
      double share = 0.0;
      if (v == 0 || v + 1 == line->points.size()) {
        share = joint_share_[v == 0 ? segment_ : segment_ + 1];
      } else if (std::isfinite(corner.feed_mm_per_s)) {
        const Vec3 d_in = unit_or_zero(line->points[v] - line->points[v - 1]);
        const Vec3 d_out = unit_or_zero(line->points[v + 1] - line->points[v]);
        share = jump_share(std::acos(std::clamp(d_in.dot(d_out), -1.0, 1.0)),
                           vertex_curvature_jump_per_mm(segment_, v), corner.feed_mm_per_s);
      }
      zone(s, corner, share);
      if (v + 1 < line->points.size()) s += (line->points[v + 1] - line->points[v]).norm();
    }
  } else {
    zone(starts_mm_[segment_], joint_corner_[segment_], joint_share_[segment_]);
    zone(starts_mm_[segment_ + 1], joint_corner_[segment_ + 1], joint_share_[segment_ + 1]);
    const auto& inner = inner_corners_[segment_];
    const double reach = 2.0 * limits_.max_feed_mm_per_min / 60.0 * limits_.period_s;
    auto it = std::lower_bound(inner.begin(), inner.end(), iv.a_mm - reach,
                               [](const InnerCorner& c, double s) { return c.s_mm < s; });
    for (; it != inner.end() && it->s_mm <= iv.b_mm + reach; ++it) {
      zone(it->s_mm, it->corner, it->share);
    }
  }
}

// The smallest u in (u_, u1) at an edge of the zone of a corner inside the curve (see
// next_zone_edge_mm), mapped to u with the parametric speed on its side; u1 if none.
double LimitSampler::inner_corner_edge_u(double u1) const {
  const auto& inner = inner_corners_[segment_];
  if (inner.empty()) return u1;
  const double T = limits_.period_s;
  const double reach = 2.0 * limits_.max_feed_mm_per_min / 60.0 * T;
  auto it = std::lower_bound(inner.begin(), inner.end(), s_ - reach,
                             [](const InnerCorner& k, double s) { return k.s_mm < s; });
  const double tiny = 1e-12 * std::max(1.0, std::abs(u1));
  for (; it != inner.end() && it->s_mm <= s_ + reach + config_.spacing_mm; ++it) {
    const double h = it->corner.feed_mm_per_s * T;
    for (const double off : {-2.0 * h, -h, h, 2.0 * h}) {
      const double speed = off < 0.0 ? it->speed_in : it->speed_out;
      if (!(speed > 0.0)) continue;
      const double u = it->u + off / speed;
      if (u > u_ + tiny && u < u1) u1 = u;
    }
  }
  return u1;
}

bool LimitSampler::next_interval(Interval& iv) {
  while (segment_ < path_.segments.size()) {
    const auto& g = path_.segments[segment_].geometry;
    if (const auto* line = std::get_if<toolpath::Polyline>(&g)) {
      if (piece_ + 1 >= line->points.size()) {
        ++segment_, piece_ = 0, sub_ = 0;
        if (segment_ < path_.segments.size()) enter_segment();
        continue;
      }
      const double len = (line->points[piece_ + 1] - line->points[piece_]).norm();
      const bool last_piece = piece_ + 2 == line->points.size();
      const double end = last_piece ? starts_mm_[segment_ + 1] : piece_s_ + len;
      const FeedLimitResult v = limit_on_piece(segment_, piece_);
      const double remaining = end - s_;
      const double subs = std::max(1.0, std::ceil(remaining / config_.spacing_mm - 1e-9));
      double b = subs <= 1.0 ? end : s_ + remaining / subs;
      b = std::min(b, next_zone_edge_mm(piece_s_, edge_speed(segment_, piece_), end,
                                        edge_speed(segment_, piece_ + 1)));
      iv.a_mm = s_;
      iv.b_mm = b;
      iv.v_mm_per_s = v.feed_mm_per_s;
      iv.limit = v.limit;
      iv.kappa_per_mm =
          limits_.jerk_bound == JerkBound::vector ? piece_curvature_per_mm(segment_, piece_) : 0.0;
      iv.turn_per_mm2 = 0.0;
      iv.jump_share = 0.0;
      iv.rest_speed = false;
      iv.tangent_max = (line->points[piece_ + 1] - line->points[piece_]).normalized().cwiseAbs();
      iv.bends = piece_curvature_per_mm(segment_, piece_) > 0.0;
      apply_zones(iv);
      bound_jerk_vector(iv);
      s_ = b;
      if (b >= end) {
        ++piece_, sub_ = 0;
        piece_s_ = end;
      }
      return true;
    }
    const auto& c = std::get<toolpath::NurbsCurve>(g);
    if (u_ >= c.u_end()) {
      ++segment_, piece_ = 0, sub_ = 0;
      if (segment_ < path_.segments.size()) enter_segment();
      continue;
    }
    const double speed = c.derivative(u_).norm();
    const double spacing_mm = fine_ ? 0.5 * config_.spacing_mm : config_.spacing_mm;
    double u1 = speed > 0.0 ? u_ + spacing_mm / speed : c.u_end();
    const std::vector<double>& knots = breakpoints_[segment_];
    while (knot_ < knots.size() && knots[knot_] <= u_) ++knot_;
    if (knot_ < knots.size()) u1 = std::min(u1, knots[knot_]);
    u1 = std::min(u1, c.u_end());
    // No sliver before a rest point: where the step leaves less than another step's worth of
    // parameter to the next breakpoint and the motion rests there, the arc up to it becomes
    // one interval or two equal ones, so that the rest refinement below sees an interval that
    // ends on the rest point. (Near a repeated end point the parametric speed falls to 0, the
    // step u + d/|C'| stopped 2 µm short of the end, and that sliver took the rest speed of
    // its length, 0.008 mm/s; the planner takes the smaller limit of an interval's two nodes,
    // so the whole 0.1 mm interval before it crawled: seed 7414150 of
    // Property.RandomDegenerateNurbs*.)
    {
      const double u_next = knot_ < knots.size() ? std::min(knots[knot_], c.u_end()) : c.u_end();
      if (u1 < u_next && u_next - u1 < u1 - u_) {
        const double to_next = gauss_arc_mm(c, u_, u_next);
        const double s_next = u_next >= c.u_end() ? starts_mm_[segment_ + 1] : s_ + to_next;
        if (is_rest_mm(s_next)) {
          if (to_next <= config_.spacing_mm) {
            u1 = u_next;
          } else if (to_next <= 2.0 * config_.spacing_mm) {
            u1 = u_at_arc(c, u_, u_next, 0.5 * to_next);
          }
        }
      }
    }
    // The corner zones at the joints get intervals of their own (their edges mapped to u at
    // the joint's parametric speed), so that a slow corner does not slow a whole interval.
    const double s0 = starts_mm_[segment_], s1 = starts_mm_[segment_ + 1];
    const double edge = next_zone_edge_mm(s0, joint_edge_[segment_], s1, joint_edge_[segment_ + 1]);
    if (std::isfinite(edge)) {
      const bool near_start = edge - s0 < s1 - edge;
      const double speed_joint = c.eval(near_start ? c.u_begin() : c.u_end()).d1.norm();
      if (speed_joint > 0.0) {
        const double ue = near_start ? c.u_begin() + (edge - s0) / speed_joint
                                     : c.u_end() - (s1 - edge) / speed_joint;
        if (ue > u_) u1 = std::min(u1, ue);
      }
    }
    u1 = inner_corner_edge_u(u1);
    // A jump of the limit at a smooth knot (a blend arc meeting its lines): a node a quarter of
    // a period's travel at the lower speed before and after it (kGuardPeriods).
    {
      const auto& edges = knot_edges_[segment_];
      const double tiny = 1e-12 * std::max(1.0, std::abs(u1));
      const auto consider = [&](double ue) {
        if (ue > u_ + tiny && ue < u1) u1 = ue;
      };
      const double T = limits_.period_s;
      if (knot_ > 0 && knot_ - 1 < edges.size() && std::isfinite(edges[knot_ - 1].v_mm_per_s) &&
          edges[knot_ - 1].speed_out > 0.0) {
        consider(knots[knot_ - 1] +
                 edges[knot_ - 1].v_mm_per_s * kGuardPeriods * T / edges[knot_ - 1].speed_out);
      }
      if (knot_ < edges.size() && std::isfinite(edges[knot_].v_mm_per_s) &&
          edges[knot_].speed_in > 0.0) {
        consider(knots[knot_] -
                 edges[knot_].v_mm_per_s * kGuardPeriods * T / edges[knot_].speed_in);
      }
    }
    // Rest refinement: where the motion rests at a point whose limit dips towards 0 (a
    // repeated control point), the intervals double away from it and halve towards it.
    bool innermost = false, rest_at_start = false, rest_at_end = false;
    double rest_d_mm = 0.0;
    const double d1 = rest_first_mm();
    const bool at_knot = u_ == c.u_begin() || (knot_ > 0 && knots[knot_ - 1] == u_);
    if (rest_origin_mm_ < 0.0 && at_knot && is_rest_mm(s_) && needs_rest_refinement(segment_, u_)) {
      rest_origin_mm_ = s_;
      innermost = rest_at_start = true;
      rest_d_mm = d1;
      const double ue = u_at_arc(c, u_, u1, d1);
      if (ue < u1) {
        u1 = ue;
      } else {
        rest_origin_mm_ = -1.0;
      }
    } else if (rest_origin_mm_ >= 0.0) {
      const double ue = u_at_arc(c, u_, u1, s_ - rest_origin_mm_);
      if (ue < u1) {
        u1 = ue;
      } else {
        rest_origin_mm_ = -1.0;
      }
    }
    // Near-cusps (docs/planner.md §2): intervals halve towards the bottom u* of a deep dip of
    // |C'| inside a span and double away from it, from kDipFirstMm, and one ends on u*: only
    // a few µm around it take the speed of its curvature peak, not two whole intervals.
    {
      const std::vector<double>& dips = dips_[segment_];
      const auto next = std::upper_bound(dips.begin(), dips.end(), u_);
      const auto arc_of = [&c](double a, double b) { return gauss_arc_mm(c, a, b); };
      if (next != dips.end() && *next <= u1) {
        const double d = arc_of(u_, *next);
        u1 = d <= 2.0 * kDipFirstMm ? *next : u_at_arc(c, u_, *next, 0.5 * d);
      }
      if (next != dips.begin()) {
        const double step = std::max(kDipFirstMm, arc_of(*(next - 1), u_));
        if (arc_of(u_, u1) > step) u1 = u_at_arc(c, u_, u1, step);
      }
    }
    const auto arc_to = [&c, this](double u) { return gauss_arc_mm(c, u_, u); };
    const bool end_knot = u1 >= c.u_end() || (knot_ < knots.size() && u1 == knots[knot_]);
    bool end_rest = false;  // the interval ends where the motion rests: its far side is not its
    if (end_knot) {
      const double d_mm = arc_to(u1);
      const double s_end = u1 >= c.u_end() ? starts_mm_[segment_ + 1] : s_ + d_mm;
      end_rest = is_rest_mm(s_end);
      if (end_rest && needs_rest_refinement(segment_, std::nextafter(u1, -kInf))) {
        if (d_mm > 2.0 * d1) {
          u1 = u_at_arc(c, u_, u1, 0.5 * d_mm);
          end_rest = false;
          rest_origin_mm_ = -1.0;
        } else {
          innermost = rest_at_end = true;
          rest_d_mm = std::max(rest_d_mm, d_mm);
        }
      }
    }
    const double arc = arc_to(u1);
    const bool open_end = (knot_ < knots.size() && u1 == knots[knot_] &&
                           std::isfinite(knot_edges_[segment_][knot_].v_mm_per_s)) ||
                          (end_rest && u1 < c.u_end());
    // A flat interval: every point the search would evaluate gives the cap, and ties keep the
    // first, so its result is the limit at any one point with every law above the cap.
    // (JerkBound::vector needs the curvature of every interval: no skip.)
    const bool flat = config_.skip_flat_intervals && limits_.jerk_bound != JerkBound::vector &&
                      interval_is_flat(segment_, u_, u1, speed);
    FeedLimitResult v = flat ? min_of({limits_.max_feed_mm_per_min / 60.0, FeedLimit::MaxFeed},
                                      segment_cap(segment_))
                             : interval_min_on_curve(segment_, u_, u1, open_end);
    ++curve_intervals_;
    if (flat) ++flat_intervals_;
    // Where the limit is below the cap and changes fast along the curve, shorter intervals
    // follow it closer (the planner holds each interval's minimum over the whole interval).
    fine_ = v.feed_mm_per_s < kFineBelowCap * segment_cap(segment_).feed_mm_per_s &&
            std::abs(v.feed_mm_per_s - last_curve_v_) > kFineStep * v.feed_mm_per_s;
    last_curve_v_ = v.feed_mm_per_s;
    bool raised = false;
    if (innermost) {
      // The first (last) period's travel from (to) rest: no jerk-limited motion is faster
      // there than the rest speed, so the limit's dip to 0 at the point itself is not a cap.
      // The segment's own caps (its programmed feed, the machine's maximum) are, whatever the
      // speed reachable: a move programmed slower than the rest speed (G93 F0.5 over 8 mm is
      // 3.9 mm/min) keeps its feed up to the rest. Nor is a limit the rest speed does not cover:
      // where the limit is below the rest speed at some distance from the rest (a tiny helix,
      // whose chord law is low all along, not a dip at the point), the raise stops at it
      // (rest_uncovered_min_mm_per_s).
      const FeedLimitResult cap = segment_cap(segment_);
      double raise = std::min(rest_speed_mm_per_s(rest_d_mm), cap.feed_mm_per_s);
      const double u_mid =
          rest_at_start && rest_at_end ? 0.5 * (u_ + u1) : (rest_at_start ? u1 : u_);
      if (rest_at_start && raise > v.feed_mm_per_s) {
        raise = std::min(raise, rest_uncovered_min_mm_per_s(segment_, u_, u_mid, v.feed_mm_per_s,
                                                            open_end && u_mid == u1));
      }
      if (rest_at_end && raise > v.feed_mm_per_s) {
        raise = std::min(raise,
                         rest_uncovered_min_mm_per_s(segment_, u1, u_mid, v.feed_mm_per_s, false));
      }
      if (raise > v.feed_mm_per_s) {
        raised = true;
        if (raise >= cap.feed_mm_per_s) {
          v = cap;
        } else {
          v.feed_mm_per_s = raise;
        }
      }
    }
    iv.a_mm = s_;
    iv.b_mm = u1 >= c.u_end() ? starts_mm_[segment_ + 1] : s_ + arc;
    iv.v_mm_per_s = v.feed_mm_per_s;
    iv.limit = v.limit;
    iv.kappa_per_mm = iv.turn_per_mm2 = 0.0;
    iv.jump_share = 0.0;
    iv.rest_speed = raised;
    if (limits_.has_axis_limits()) curve_tangent_max(c, u_, u1, iv);
    if (limits_.jerk_bound == JerkBound::vector) curve_turn(segment_, u_, u1, iv);
    apply_zones(iv);
    bound_jerk_vector(iv);
    s_ = iv.b_mm;
    u_ = u1;
    return true;
  }
  return false;
}

// JerkBound::vector (docs/planner.md §3c): the largest curvature κ and curvature turn
// g = |κ' N + κ τ B| on [u0, u1], from nine points: κ from the curvature vector k = κ N, g
// from the part of Δk / Δs normal to the mid tangent between neighbours (on a circle Δk
// points along the tangent, so g is 0 to second order). 5 % margin for what lies between.
void LimitSampler::curve_turn(std::size_t segment, double u0, double u1, Interval& iv) const {
  const auto& c = std::get<toolpath::NurbsCurve>(path_.segments[segment].geometry);
  constexpr int kPoints = 9;
  constexpr double kMinArcMm = 0.02;  // a sliver is sampled over this much of its knot span
  // The knot span that holds the interval (intervals end at breakpoints).
  const std::vector<double>& bp = breakpoints_[segment];
  const auto it = std::upper_bound(bp.begin(), bp.end(), u0);
  const double span_lo = it == bp.begin() ? c.u_begin() : *(it - 1);
  const double span_hi = it == bp.end() ? c.u_end() : *it;
  const auto below = [&](double u) {  // the span's side of a knot
    return u < c.u_end() ? std::max(span_lo, std::nextafter(u, -kInf)) : u;
  };
  double lo = u0, hi = below(std::min(u1, span_hi));
  const double speed = c.derivative(u0).norm();
  if (speed > 0.0 && (hi - lo) * speed < kMinArcMm) {
    // Never onto a span end where the curve rests (a repeated control point: |C'| = 0, and κ
    // grows without bound towards it): the intervals that halve towards it keep their own.
    const auto rests = [&c](double u) { return speed_vanishes(c, c.derivative(u)); };
    const double mid = 0.5 * (lo + hi), half = 0.5 * kMinArcMm / speed;
    lo = std::max(rests(span_lo) ? u0 : span_lo, mid - half);
    hi = below(std::min(rests(span_hi) ? std::min(u1, span_hi) : span_hi, mid + half));
  }
  double kappa = 0.0, turn = 0.0;
  toolpath::CurvePoint prev = c.eval(lo);
  Vec3 k_prev = curvature_vector_per_mm(prev);
  kappa = k_prev.norm();
  double u_prev = lo;
  for (int i = 1; i < kPoints; ++i) {
    const double u = i + 1 == kPoints ? hi : lo + (hi - lo) * i / (kPoints - 1);
    const toolpath::CurvePoint p = c.eval(u);
    const Vec3 k = curvature_vector_per_mm(p);
    kappa = std::max(kappa, k.norm());
    const double ds = 0.5 * (prev.d1.norm() + p.d1.norm()) * (u - u_prev);
    const Vec3 t = unit_or_zero(unit_or_zero(prev.d1) + unit_or_zero(p.d1));
    const Vec3 dk = k - k_prev;
    if (ds > 0.0) turn = std::max(turn, (dk - dk.dot(t) * t).norm() / ds);
    prev = p;
    k_prev = k;
    u_prev = u;
  }
  iv.kappa_per_mm = 1.05 * kappa;
  iv.turn_per_mm2 = 1.05 * turn;
}

// JerkBound::vector: the interval's speed so that the tangential scale it asks for is at least
// kMinTangentialScale times its budget (jerk_vector_feed_mm_per_s), the budget being what a
// jump nearby leaves. An interval raised to the rest speed keeps it (as it keeps it against the
// curve laws).
void LimitSampler::bound_jerk_vector(Interval& iv) const {
  if (limits_.jerk_bound != JerkBound::vector || iv.rest_speed) return;
  const double budget = 1.0 - iv.jump_share;
  const double v = jerk_vector_feed_mm_per_s(limits_, iv.kappa_per_mm, iv.turn_per_mm2, budget);
  if (v < iv.v_mm_per_s) {
    iv.v_mm_per_s = v;
    iv.limit = FeedLimit::JerkVector;
  }
}

// The bottoms of the deep dips of the parametric speed inside each span of c (near-cusps): 16
// samples per span; an interior local minimum below a tenth of the span's largest sample is
// refined by golden section. (Dips at a knot are the knots' own business: rest refinement.)
void LimitSampler::find_dips(const toolpath::NurbsCurve& c, const std::vector<double>& bp,
                             std::vector<double>& out) {
  constexpr int kSamples = 16;
  constexpr double kDeep = 0.1;
  for (std::size_t i = 0; i + 1 < bp.size(); ++i) {
    const double w = bp[i + 1] - bp[i];
    if (!(w > 0.0)) continue;
    std::array<double, kSamples> speed;
    const auto at = [&](int j) { return bp[i] + w * (static_cast<double>(j) + 0.5) / kSamples; };
    double top = 0.0;
    for (int j = 0; j < kSamples; ++j) {
      speed[static_cast<std::size_t>(j)] = c.derivative(at(j)).norm();
      top = std::max(top, speed[static_cast<std::size_t>(j)]);
    }
    for (int j = 1; j + 1 < kSamples; ++j) {
      const auto J = static_cast<std::size_t>(j);
      if (!(speed[J] < speed[J - 1] && speed[J] <= speed[J + 1] && speed[J] < kDeep * top)) {
        continue;
      }
      out.push_back(golden_section_min([&c](double u) { return c.derivative(u).norm(); }, at(j - 1),
                                       at(j + 1), 1e-13 * std::max(1.0, std::abs(at(j + 1)))));
    }
  }
}

// A dip of |C'| to zero (to rounding) inside a span is a cusp: the curve reverses there, and no
// motion passes it but through a stop that the walker cannot place (away from a knot). Refused,
// with the segment, its line and the point named.
void LimitSampler::refuse_cusp(const toolpath::Path& path, std::size_t k,
                               const toolpath::NurbsCurve& c, double u) {
  const toolpath::PathSegment& seg = path.segments[k];
  const toolpath::CurvePoint at = c.eval(u);
  if (!speed_vanishes(c, at.d1)) return;
  throw InputError(
      (path.source.empty() ? "" : path.source + ": ") + "segment " + std::to_string(k + 1) +
      (seg.source_line > 0 ? " (line " + std::to_string(seg.source_line) + ")" : "") +
      ": the curve has a cusp inside a span, at u = " + text::sig(u, 12) + ", (" +
      text::sig(at.p.x(), 9) + ", " + text::sig(at.p.y(), 9) + ", " + text::sig(at.p.z(), 9) +
      ") mm, where its parametric speed vanishes and it turns back; split the curve "
      "there into two segments (a corner the motion stops at)");
}

// Per-axis limits (docs/planner.md §3f): the largest |t_i| of a curve interval from its tangent
// at both ends and the middle, plus θ²/2 for the angle θ the tangent turns between neighbouring
// samples (a component of a unit vector turning smoothly by θ along a great circle exceeds the
// larger of its end values by at most θ²/8: four times that, measured, not proven); 1 on an
// axis where a sample has no tangent (|C'| = 0: a repeated control point).
void LimitSampler::curve_tangent_max(const toolpath::NurbsCurve& c, double u0, double u1,
                                     Interval& iv) const {
  const double u_end = u1 < c.u_end() ? std::max(u0, std::nextafter(u1, -kInf)) : u1;
  const Vec3 t[3] = {unit_or_zero(c.derivative(u0)), unit_or_zero(c.derivative(0.5 * (u0 + u_end))),
                     unit_or_zero(c.derivative(u_end))};
  iv.bends = c.degree() >= 2;
  if (t[0].isZero() || t[1].isZero() || t[2].isZero()) {
    iv.tangent_max = Vec3::Ones();
    return;
  }
  const auto angle = [](const Vec3& a, const Vec3& b) {
    return std::atan2(a.cross(b).norm(), a.dot(b));
  };
  const double turn = std::max(angle(t[0], t[1]), angle(t[1], t[2]));
  const double margin = 0.5 * turn * turn + 1e-9;
  const Vec3 hi = t[0].cwiseAbs().cwiseMax(t[1].cwiseAbs()).cwiseMax(t[2].cwiseAbs());
  iv.tangent_max = (hi + Vec3::Constant(margin)).cwiseMin(1.0);
}

// Per-axis limits: the interval's speed at most min_i vmax_i / max|t_i| (its sampled largest
// tangent components; also where the rest refinement raised it).
void LimitSampler::axis_bound(Interval& iv) const {
  for (std::size_t i = 0; i < 3; ++i) {
    const double ti = iv.tangent_max[static_cast<int>(i)];
    if (!(ti > 0.0)) continue;
    const double v = limits_.axes[i].max_feed_mm_per_min / 60.0 / ti;
    if (v < iv.v_mm_per_s) {
      iv.v_mm_per_s = v;
      iv.limit = FeedLimit::MaxFeed;
    }
  }
}

JerkVectorSpan LimitSampler::jerk_span_of(const Interval& iv) const {
  if (limits_.jerk_bound != JerkBound::vector || iv.rest_speed) return {};
  return {iv.kappa_per_mm, iv.turn_per_mm2, 1.0 - iv.jump_share};
}

bool LimitSampler::is_rest_mm(double s_mm) const {
  const double tol = 1e-7 * std::max(1.0, std::abs(s_mm));
  const double total = starts_mm_.back();
  if (std::abs(s_mm) <= tol || std::abs(s_mm - total) <= tol) return true;
  const auto it = std::lower_bound(stops_mm_.begin(), stops_mm_.end(), s_mm - tol);
  return it != stops_mm_.end() && *it <= s_mm + tol;
}

// The highest speed a motion with |jerk| ≤ J reaches at distance d from rest (or has at
// distance d before coming to rest): full jerk from rest, v = J t²/2 and s = J t³/6, so
// v = (4.5 J d²)^(1/3). The acceleration limit only lowers it.
double LimitSampler::rest_speed_mm_per_s(double distance_mm) const {
  return std::cbrt(4.5 * limits_.max_jerk_mm_per_s3 * distance_mm * distance_mm);
}

// The lowest limit on [u_rest, u_far] (u_far on either side) that the rest speed does not
// cover, +inf if it covers all (docs/planner.md §3, "Rest refinement"). A motion that rests at
// u_rest is no faster than v_rest(x) at distance x from it, so on a piece of the arc whose far
// end lies at x_far a limit of at least v_rest(x_far) holds by itself; a piece whose minimum
// m_i is below that needs the interval's limit at most m_i. The pieces halve in u towards the
// rest, [u_rest + h/2^(i+1), u_rest + h/2^i] for i < kRestPieces, each minimum searched as
// every interval's; the search ends where v_rest(x_far) is at most the interval's minimum
// `floor` (every nearer piece is covered then) or a piece has brought the answer down to it.
// The last 2^-kRestPieces of the interval (nanometres) is the repeated control point's own:
// there the curve laws grow like x^(1/3) and x^(1/4), faster than v_rest ∝ x^(2/3).
double LimitSampler::rest_uncovered_min_mm_per_s(std::size_t segment, double u_rest, double u_far,
                                                 double floor_mm_per_s, bool open_far) const {
  constexpr int kRestPieces = 12;
  const auto& c = std::get<toolpath::NurbsCurve>(path_.segments[segment].geometry);
  double lowest = kInf;
  double h = u_far - u_rest;
  for (int i = 0; i < kRestPieces && lowest > floor_mm_per_s; ++i, h *= 0.5) {
    const double ub = u_rest + h, ua = u_rest + 0.5 * h;
    const double x_far = gauss_arc_mm(c, std::min(u_rest, ub), std::max(u_rest, ub));
    const double v_rest = rest_speed_mm_per_s(x_far);
    if (!(v_rest > floor_mm_per_s)) break;
    const bool open = open_far && i == 0 && ub > ua;
    const double m =
        interval_min_on_curve(segment, std::min(ua, ub), std::max(ua, ub), open).feed_mm_per_s;
    if (m < v_rest) lowest = std::min(lowest, m);
  }
  return lowest;
}

// The travel of the first period from rest at full jerk, J T³ / 6.
double LimitSampler::rest_first_mm() const {
  const double t = limits_.period_s;
  return limits_.max_jerk_mm_per_s3 * t * t * t / 6.0;
}

// A rest point whose limit is below the speed two periods of full jerk give: the limit dips
// towards 0 there (a repeated control point), and the plain 0.2 mm intervals would cap the
// motion near 0 over their whole length.
bool LimitSampler::needs_rest_refinement(std::size_t segment, double u) const {
  return limit_on_curve(segment, u).feed_mm_per_s < rest_speed_mm_per_s(2.0 * rest_first_mm());
}

// The u in [u0, u_hi] at arc length arc_mm from u0 (bisection; [u0, u_hi] holds no knot, so
// the 10-point rule is exact to rounding); u_hi if the arc to it is shorter.
double LimitSampler::u_at_arc(const toolpath::NurbsCurve& c, double u0, double u_hi,
                              double arc_mm) const {
  const auto arc = [&c, u0](double u) { return gauss_arc_mm(c, u0, u); };
  if (arc(u_hi) <= arc_mm) return u_hi;
  double lo = u0, hi = u_hi;
  for (int it = 0; it < 200 && hi > std::nextafter(lo, kInf); ++it) {
    const double mid = 0.5 * (lo + hi);
    (arc(mid) < arc_mm ? lo : hi) = mid;
    if ((hi - lo) <= 1e-12 * (u_hi - u0)) break;
  }
  return hi;
}

void LimitSampler::enter_segment() {
  rest_origin_mm_ = -1.0;
  fine_ = false;
  last_curve_v_ = kInf;
  s_ = starts_mm_[segment_];
  piece_s_ = s_;
  knot_ = 0;
  if (const auto* c = std::get_if<toolpath::NurbsCurve>(&path_.segments[segment_].geometry)) {
    u_ = c->u_begin();
  }
}

bool LimitSampler::next(LimitNode& out) {
  if (finished_) return false;
  if (!started_) {
    started_ = true;
    enter_segment();
    pending_ = {0.0, kInf, FeedLimit::MaxFeed, kInf, kInf, {}};
  }
  Interval iv{};
  while (next_interval(iv)) {
    if (iv.b_mm <= iv.a_mm) continue;  // nothing to limit on a zero-length piece
    if (limits_.has_axis_limits()) axis_bound(iv);
    if (iv.v_mm_per_s < pending_.feed_mm_per_s) {
      pending_.feed_mm_per_s = iv.v_mm_per_s;
      pending_.limit = iv.limit;
    }
    pending_.right_mm_per_s = iv.v_mm_per_s;
    pending_.right_limit = iv.limit;
    pending_.jerk_span = jerk_span_of(iv);
    if (limits_.has_axis_limits()) {
      pending_.axis_scale = axis_scales(limits_, iv.tangent_max, {iv.bends, iv.bends, iv.bends});
    }
    out = pending_;
    pending_ = {iv.b_mm, iv.v_mm_per_s, iv.limit, iv.v_mm_per_s, kInf, {}};
    return true;
  }
  if (!std::isfinite(pending_.feed_mm_per_s)) {  // a path of length 0: no interval at all
    const double cap = limits_.max_feed_mm_per_min / 60.0;
    pending_.feed_mm_per_s = pending_.left_mm_per_s = pending_.right_mm_per_s = cap;
  }
  out = pending_;
  finished_ = true;
  return true;
}

}  // namespace ncd::interpolator
