// The limit sampler's laws (the algorithm is explained at the top of limit_sampler.cpp): the
// feed limit at a point of a curve or a polyline piece, the corner speed at a vertex, joint or
// knot, and the limit over a whole curve interval: its minimum (five samples, then Brent's
// method; "Flat intervals" skips it where a bound proves the cap), its largest curvature and
// curvature turn under JerkBound::vector, and its largest tangent components under per-axis
// limits. All const: nothing here moves the sampler's cursor.
#include <algorithm>
#include <cmath>
#include <limits>

#include "feed/corner_blend.hpp"
#include "feed/limit_sampler.hpp"
#include "feed/limit_sampler_detail.hpp"

namespace ncd::feed {

using namespace sampler_detail;

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
                                           double curvature_per_mm, double curvature_jump_per_mm,
                                           const Vec3& axis_curvature_jump) const {
  if (d_in.isZero() || d_out.isZero()) return {0.0, FeedLimit::Corner};
  const double phi = std::acos(std::clamp(d_in.dot(d_out), -1.0, 1.0));
  FeedLimitResult r{polyline_corner_speed_mm_per_s(limits_, phi, curvature_per_mm),
                    FeedLimit::Corner};
  if (limits_.jerk_bound == JerkBound::vector && curvature_jump_per_mm > 0.0) {
    const double v =
        jump_feed_mm_per_s(limits_, phi < kMinTurnRad ? 0.0 : phi, curvature_jump_per_mm);
    if (v < r.feed_mm_per_s) r = {v, FeedLimit::JerkVector};
  }
  if (limits_.has_axis_jerk()) {  // each axis's jump law (docs/planner.md §3f)
    const Vec3 dd = phi < kMinTurnRad ? Vec3::Zero() : Vec3(d_out - d_in);
    const double v = axis_jump_feed_mm_per_s(limits_, dd, axis_curvature_jump);
    if (v < r.feed_mm_per_s) r = {v, FeedLimit::Corner};
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

Vec3 LimitSampler::vertex_axis_curvature_jump(std::size_t segment, std::size_t vertex) const {
  if (!limits_.has_axis_jerk()) return Vec3::Zero();
  const auto& pts = std::get<toolpath::Polyline>(path_.segments[segment].geometry).points;
  const Vec3 here = vertex_curvature_vector(segment, vertex);
  const Vec3 before = vertex > 0 ? vertex_curvature_vector(segment, vertex - 1) : Vec3::Zero();
  const Vec3 after =
      vertex + 1 < pts.size() ? vertex_curvature_vector(segment, vertex + 1) : Vec3::Zero();
  return (here - before).cwiseAbs().cwiseMax((after - here).cwiseAbs());
}

FeedLimitResult LimitSampler::corner_limit(std::size_t segment, std::size_t vertex) const {
  const auto& line = std::get<toolpath::Polyline>(path_.segments[segment].geometry);
  if (vertex == 0) return joint_corner_[segment];
  if (vertex + 1 == line.points.size()) return joint_corner_[segment + 1];
  if (vertex_is_stop(segment, vertex)) return {kInf, FeedLimit::Corner};  // at rest there
  return corner_speed(unit_or_zero(line.points[vertex] - line.points[vertex - 1]),
                      unit_or_zero(line.points[vertex + 1] - line.points[vertex]), 0.0,
                      vertex_curvature_jump_per_mm(segment, vertex),
                      vertex_axis_curvature_jump(segment, vertex));
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
  const auto span = [&c](double u) { return knot_span_of(c, u); };
  double d2 = 0.0, e1 = 0.0, e2 = 0.0;
  Vec3 d1_abs = Vec3::Zero(), d2_abs = Vec3::Zero();
  for (std::size_t s = span(lo), last = span(hi); s <= last; ++s) {
    const double h = U[s + 1] - U[s];
    if (!(h > 0.0)) continue;
    // Rounding of eval(): |N'| ≤ 2p / h and |N''| ≤ 4p(p − 1) / h² on the span, p + 1 terms,
    // each off by far less than 1e-12 of its size.
    const double pp = static_cast<double>(p), terms = pp + 1.0;
    e1 = std::max(e1, 1e-12 * terms * 2.0 * pp / h * bounds[s].p_max);
    e2 = std::max(e2, 1e-12 * terms * 4.0 * pp * (pp - 1.0) / (h * h) * bounds[s].p_max);
    d2 = std::max(d2, bounds[s].d2_max);
    if (!span_axis_bounds_.empty()) {
      d1_abs = d1_abs.cwiseMax(span_axis_bounds_[segment][s].d1_abs);
      d2_abs = d2_abs.cwiseMax(span_axis_bounds_[segment][s].d2_abs);
    }
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
  const double threshold = segment_cap(segment).feed_mm_per_s * (1.0 + 1e-6);
  if (limits_.has_axis_limits()) {
    // The axis laws at bounds of |t_i| and |k_i|: t = C' / |C'|, and k = (C'' − (t·C'') t) / |C'|²
    // (the curvature vector), so |t_i| ≤ max|C'_i| / min|C'| and |k_i| ≤ (max|C''_i| + |t_i|
    // max|C''|) / min|C'|², each at most 1 and κ. (|t_i| ≤ 1 alone kept a slow axis from ever
    // finding an interval flat: Z at 1500 mm/min under an F6000 cap.)
    const double grow = 1.0 + 1e-9;
    const Vec3 t_abs = ((d1_abs + Vec3::Constant(e1)) * (grow / d1_min)).cwiseMin(1.0);
    const Vec3 k_abs =
        ((d2_abs + Vec3::Constant(e2) + (d2 + e2) * t_abs) * (grow / (d1_min * d1_min)))
            .cwiseMin(kappa);
    if (!axis_laws_above(limits_, t_abs, k_abs, kappa, threshold)) return false;
  }
  return floor_mm_per_s > threshold;
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

double LimitSampler::jump_share(double phi, double dk, double v_corner) const {
  if (limits_.jerk_bound != JerkBound::vector) return 0.0;
  const double v = std::min(v_corner, limits_.max_feed_mm_per_min / 60.0);
  const double j = jump_jerk_mm_per_s3(limits_, phi < kMinTurnRad ? 0.0 : phi, dk, v);
  return std::min(kJumpJerkShare, j / limits_.max_jerk_mm_per_s3);
}

// The parameter range curve_turn samples: the interval, or a sliver's surroundings within its
// knot span (never onto a span end where the curve rests).
std::pair<double, double> LimitSampler::turn_range(std::size_t segment, double u0, double u1,
                                                   double speed) const {
  const auto& c = std::get<toolpath::NurbsCurve>(path_.segments[segment].geometry);
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
  if (speed > 0.0 && (hi - lo) * speed < kMinArcMm) {
    // Never onto a span end where the curve rests (a repeated control point: |C'| = 0, and κ
    // grows without bound towards it): the intervals that halve towards it keep their own.
    const auto rests = [&c](double u) { return speed_vanishes(c, c.derivative(u)); };
    const double mid = 0.5 * (lo + hi), half = 0.5 * kMinArcMm / speed;
    lo = std::max(rests(span_lo) ? u0 : span_lo, mid - half);
    hi = below(std::min(rests(span_hi) ? std::min(u1, span_hi) : span_hi, mid + half));
  }
  return {lo, hi};
}

// JerkBound::vector (docs/planner.md §3c): the largest curvature κ and curvature turn
// g = |κ' N + κ τ B| on [u0, u1], from nine points: κ from the curvature vector k = κ N, g
// from the part of Δk / Δs normal to the mid tangent between neighbours (on a circle Δk
// points along the tangent, so g is 0 to second order). 5 % margin for what lies between.
void LimitSampler::curve_turn(std::size_t segment, double u0, double u1, double speed_u0,
                              Interval& iv) const {
  const auto& c = std::get<toolpath::NurbsCurve>(path_.segments[segment].geometry);
  constexpr int kPoints = kTurnPoints;
  const auto [lo, hi] = turn_range(segment, u0, u1, speed_u0);
  double kappa = 0.0, turn = 0.0;
  toolpath::CurvePoint prev = c.eval(lo);
  Vec3 k_prev = curvature_vector_per_mm(prev);
  kappa = k_prev.norm();
  Vec3 k_axis = k_prev.cwiseAbs(), g_axis = Vec3::Zero();  // g_axis: |dk/ds| per axis
  double u_prev = lo;
  for (int i = 1; i < kPoints; ++i) {
    const double u = i + 1 == kPoints ? hi : lo + (hi - lo) * i / (kPoints - 1);
    const toolpath::CurvePoint p = c.eval(u);
    const Vec3 k = curvature_vector_per_mm(p);
    kappa = std::max(kappa, k.norm());
    k_axis = k_axis.cwiseMax(k.cwiseAbs());
    const double ds = 0.5 * (prev.d1.norm() + p.d1.norm()) * (u - u_prev);
    const Vec3 t = unit_or_zero(unit_or_zero(prev.d1) + unit_or_zero(p.d1));
    const Vec3 dk = k - k_prev;
    if (ds > 0.0) {
      turn = std::max(turn, (dk - dk.dot(t) * t).norm() / ds);
      g_axis = g_axis.cwiseMax(dk.cwiseAbs() / ds);
    }
    prev = p;
    k_prev = k;
    u_prev = u;
  }
  iv.kappa_per_mm = 1.05 * kappa;
  iv.turn_per_mm2 = 1.05 * turn;
  iv.k_axis = 1.05 * k_axis;
  iv.g_axis = 1.05 * g_axis;
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

// Per-axis jerk limits on a curve (docs/planner.md §3f). Axis i's jerk is
// j t_i + 3 v a k_i + v³ (dk/ds)_i (dk/ds = −κ² T + κ' N + κ τ B, the curvature vector's
// derivative; on a helix its Z part is 0, the −κ² T_z and κ τ B_z cancelling): the planner holds
// |j t_i| to kAxisTangentialShare of the axis's budget (axis_scales()), and the curve's terms
// are held to the rest, with the interval's largest |k_i| and |(dk/ds)_i| (curve_turn()):
//     v³ |(dk/ds)_i| + 3 v λ A |k_i| ≤ R_i = (1 − kAxisTangentialShare)(1 − q_i) j_i,
// A the largest |a| the axes allow on the interval (axis_scales()), q_i the share a jump within
// two periods' travel takes (0 elsewhere). As the jerk-vector bound does with σ (§3c), the
// acceleration gives way first: at the interval's speed limit v the largest λ ≤ 1 that holds
// is the fraction of its acceleration scale the interval asks of the planner; where it would
// fall below kMinAxisAccelFactor, λ is that and the speed is lowered to the root of the left
// side (it grows with v: one real root). An interval raised to the rest speed keeps it.
void LimitSampler::bound_axis_curve_jerk(Interval& iv) const {
  if (iv.rest_speed || !limits_.has_axis_jerk() || !(iv.kappa_per_mm > 0.0)) return;
  const double A = axis_scales(limits_, iv.tangent_max, {iv.bends, iv.bends, iv.bends}).accel *
                   limits_.max_accel_mm_per_s2;
  for (std::size_t i = 0; i < 3; ++i) {
    const auto I = static_cast<int>(i);
    if (!std::isfinite(limits_.axes[i].max_jerk_mm_per_s3)) continue;
    const double cubic = iv.g_axis[I];
    const double rhs = (1.0 - kAxisTangentialShare) * (1.0 - iv.axis_jump_share[I]) *
                       axis_jerk_for_planner(limits_, i);
    const double v = iv.v_mm_per_s, linear = 3.0 * A * iv.k_axis[I];
    const double room = rhs - cubic * v * v * v;  // what the cross term may take at v
    if (linear * v <= room) continue;
    if (linear > 0.0 && room >= kMinAxisAccelFactor * linear * v) {
      iv.axis_accel_factor = std::min(iv.axis_accel_factor, room / (linear * v));
      continue;
    }
    // v³ + p v = q (p = λ_min linear / cubic, q = rhs / cubic), in the hyperbolic form, free of
    // Cardano's cancellation where p³ dwarfs q².
    const double lin = kMinAxisAccelFactor * linear;
    double root = kInf;
    if (cubic > 0.0) {
      const double p = lin / cubic, q = rhs / cubic;
      root = p > 0.0 ? 2.0 * std::sqrt(p / 3.0) *
                           std::sinh(std::asinh(1.5 * q / p * std::sqrt(3.0 / p)) / 3.0)
                     : std::cbrt(q);
    } else if (lin > 0.0) {
      root = rhs / lin;
    }
    iv.axis_accel_factor = std::min(iv.axis_accel_factor, kMinAxisAccelFactor);
    if (root < iv.v_mm_per_s) {
      iv.v_mm_per_s = root;
      iv.limit = FeedLimit::CentripetalJerk;
    }
  }
}

// Whether bound_axis_curve_jerk would leave the interval as it is whatever curve_turn samples
// (docs/planner.md §3f, "Replay speed with per-axis limits"): then curve_turn's nine
// evaluations are not needed. On the knot span that holds curve_turn's points (one polynomial
// piece; no rational curves: span_bounds_), with S ≤ |C'| there (from |C'(u0)| and max|C''|,
// less eval()'s rounding e1, e2 as in interval_is_flat) and the hodographs' hulls A1..A3
// (per axis), M2, M3 (norms):
//     |t_i| ≤ A1_i / S,   |k_i| ≤ (A2_i + |t_i| M2) / S² (and ≤ κ ≤ M2 / S²),
//     |dk_i/du| ≤ (A3_i + |t_i| M3) / S² + (3 A2_i M2 + 5 |t_i| M2²) / S³
// (k = C''/|C'|² − C'(C'·C'')/|C'|⁴ differentiated term by term), so curve_turn's difference
// quotient |Δk_i| / Δs is at most |dk_i/du| / S plus twice k's rounding over the shortest
// step. If, with these in place of k_axis and g_axis (and their 5 %), every axis's
// 3 A |k_i| v + |(dk/ds)_i| v³ stays below its budget by 1e-9, the law changes nothing; else
// curve_turn runs as before.
bool LimitSampler::axis_curve_jerk_holds(std::size_t segment, double u0, double u1, double speed_u0,
                                         const Interval& iv) const {
  const auto& bounds = span_bounds_[segment];
  if (bounds.empty() || span_axis_bounds_.empty() || !(speed_u0 > 0.0)) return false;
  const auto& c = std::get<toolpath::NurbsCurve>(path_.segments[segment].geometry);
  const auto [lo, hi] = turn_range(segment, u0, u1, speed_u0);
  if (!(hi > lo)) return false;
  const std::size_t sp = knot_span_of(c, lo);
  if (knot_span_of(c, hi) != sp) return false;
  const auto& U = c.knots();
  const double h = U[sp + 1] - U[sp];
  if (!(h > 0.0)) return false;
  const SpanBound& b0 = bounds[sp];
  const SpanAxisBound& b = span_axis_bounds_[segment][sp];
  const double pp = static_cast<double>(c.degree()), terms = pp + 1.0;
  const double e1 = 1e-12 * terms * 2.0 * pp / h * b0.p_max;
  const double e2 = 1e-12 * terms * 4.0 * pp * (pp - 1.0) / (h * h) * b0.p_max;
  const double m2 = b0.d2_max + e2;
  const double S = speed_u0 - m2 * std::max(u0 - lo, hi - u0) - 2.0 * e1;
  if (!(S > 0.0)) return false;
  const double grow = 1.0 + 1e-9;
  const Vec3 t_abs = ((b.d1_abs + Vec3::Constant(e1)) * (grow / S)).cwiseMin(1.0);
  const double kappa = m2 / (S * S) * grow;
  const double err_k = (e2 + 4.0 * m2 * e1 / S) / (S * S) + 1e-12 * kappa;  // rounding of k
  const Vec3 k_abs =
      ((b.d2_abs + Vec3::Constant(e2) + m2 * t_abs) * (grow / (S * S))).cwiseMin(kappa) +
      Vec3::Constant(err_k);
  const Vec3 dk_du = ((b.d3_abs + b.d3_max * t_abs) / (S * S) +
                      (3.0 * m2 * b.d2_abs + 5.0 * m2 * m2 * t_abs) / (S * S * S)) *
                     grow;
  const double du_min = 0.999 * (hi - lo) / (kTurnPoints - 1);
  const Vec3 g_abs = (dk_du / S + Vec3::Constant(2.0 * err_k / (S * du_min))) * grow;
  const double A = axis_scales(limits_, iv.tangent_max, {iv.bends, iv.bends, iv.bends}).accel *
                   limits_.max_accel_mm_per_s2;
  const double v = iv.v_mm_per_s;
  for (std::size_t i = 0; i < 3; ++i) {
    const auto I = static_cast<int>(i);
    if (!std::isfinite(limits_.axes[i].max_jerk_mm_per_s3)) continue;
    const double rhs = (1.0 - kAxisTangentialShare) * (1.0 - iv.axis_jump_share[I]) *
                       axis_jerk_for_planner(limits_, i);
    const double need = 3.0 * A * 1.05 * k_abs[I] * v + 1.05 * g_abs[I] * v * v * v;
    if (!(need <= rhs * (1.0 - 1e-9))) return false;
  }
  return true;
}

// Per-axis limits (docs/planner.md §3f): the largest |t_i| of a curve interval from its tangent
// at both ends and the middle, plus θ²/2 for the angle θ the tangent turns between neighbouring
// samples (a component of a unit vector turning smoothly by θ along a great circle exceeds the
// larger of its end values by at most θ²/8: four times that, measured, not proven); 1 on an
// axis where a sample has no tangent (|C'| = 0: a repeated control point).
void LimitSampler::curve_tangent_max(const toolpath::NurbsCurve& c, double u0, double u1,
                                     const Vec3& d1_u0, Interval& iv) const {
  const double u_end = u1 < c.u_end() ? std::max(u0, std::nextafter(u1, -kInf)) : u1;
  const Vec3 t[3] = {unit_or_zero(d1_u0), unit_or_zero(c.derivative(0.5 * (u0 + u_end))),
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

}  // namespace ncd::feed
