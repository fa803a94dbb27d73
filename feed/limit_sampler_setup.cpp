// The limit sampler's set-up, done once in its constructor before the first node (the
// algorithm is explained at the top of limit_sampler.cpp): the roughness law of each segment's
// tool, the corners at joints and inside curves with their jerk shares, the stops, the edges of
// the jumps of the limit at knots and joints, the near-cusp dips of |C'|, and the bounds on |C''|
// per knot span that "Flat intervals" uses. The only allocations of the sampler are here.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

#include "core/error.hpp"
#include "core/number_text.hpp"
#include "feed/corner_blend.hpp"
#include "feed/limit_sampler.hpp"
#include "feed/limit_sampler_detail.hpp"
#include "feed/path_walker.hpp"

namespace ncd::feed {

using namespace sampler_detail;

namespace {

// A jump of the limit by more than this factor gets nodes of its own (edge_speed).
constexpr double kJumpRatio = 1.5;

// The lower of two limits on either side of a point where they differ by more than
// kJumpRatio (the speed that places the nodes beside the jump), +inf where they do not.
double jump_edge(double a, double b) {
  const double lo = std::min(a, b), hi = std::max(a, b);
  return lo > 0.0 && std::isfinite(lo) && hi > kJumpRatio * lo ? lo : kInf;
}

// The angle between two unit directions; 0 where either is missing (a zero-length move).
double turn_rad(const Vec3& a, const Vec3& b) {
  return a.isZero() || b.isZero() ? 0.0 : std::acos(std::clamp(a.dot(b), -1.0, 1.0));
}

// The unit tangent at one end of segment k.
Vec3 end_direction(const toolpath::Path& path, std::size_t k, bool at_end) {
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
}

// The curvature next to a joint: the curve's, or on a polyline the discrete curvature of
// the vertex next to the joint, 2 sin(φ/2) / min(l_in, l_out) (see limit_on_piece).
double end_curvature_per_mm(const toolpath::Path& path, std::size_t k, bool at_end) {
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
}

// The curvature vector next to a joint (JerkBound::vector, per-axis jerk limits): a curve's;
// zero on a polyline.
Vec3 end_curvature_vector(const toolpath::Path& path, std::size_t k, bool at_end,
                          const MachineLimits& limits) {
  const auto* c = std::get_if<toolpath::NurbsCurve>(&path.segments[k].geometry);
  if (c == nullptr || (limits.jerk_bound != JerkBound::vector && !limits.has_axis_jerk())) {
    return Vec3::Zero();
  }
  return curvature_vector_per_mm(c->eval(at_end ? c->u_end() : c->u_begin()));
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
  joint_axis_share_.assign(n + 1, Vec3::Zero());
  inner_corners_.resize(n);
  // Joints (the corner where segment k begins belongs to the move ending there, k − 1) and
  // the interior vertices of polylines, in increasing s; the interior vertices' s is summed
  // exactly as next_interval() sums it, so that every stop is a node of the stream.
  for (std::size_t k = 0; k < n; ++k) {
    if (k > 0) add_joint(k);
    if (const auto* c = std::get_if<toolpath::NurbsCurve>(&path.segments[k].geometry)) {
      add_inner_knots(k, *c);
    }
    if (const auto* line = std::get_if<toolpath::Polyline>(&path.segments[k].geometry)) {
      add_vertex_stops(k, *line);
    }
  }
  const double total = starts_mm_[n];
  while (!stops_mm_.empty() && stops_mm_.back() >= total) stops_mm_.pop_back();
  std::erase_if(stops_mm_, [](double s) { return s <= 0.0; });
  breakpoints_.resize(n);  // here, so that walking the segments later allocates nothing
  knot_edges_.resize(n);
  dips_.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    if (const auto* c = std::get_if<toolpath::NurbsCurve>(&path.segments[k].geometry)) {
      add_knot_edges(k, *c);
    }
  }
  // Flat intervals: the bounds of every span of the curves that qualify (see the top of
  // limit_sampler.cpp).
  span_bounds_.resize(n);
  if (limits_.has_axis_limits()) span_axis_bounds_.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    if (const auto* c = std::get_if<toolpath::NurbsCurve>(&path.segments[k].geometry)) {
      bound_spans(*c, span_bounds_[k], limits_.has_axis_limits() ? &span_axis_bounds_[k] : nullptr);
    }
  }
  add_joint_edges();
}

// The corner at joint k (where segment k begins): a stop, or its corner speed and the share of
// the jerk budget its jump takes.
void LimitSampler::add_joint(std::size_t k) {
  const Vec3 d_in = end_direction(path_, k - 1, true), d_out = end_direction(path_, k, false);
  const Vec3 dk_vec = end_curvature_vector(path_, k, false, limits_) -
                      end_curvature_vector(path_, k - 1, true, limits_);
  const double dk = dk_vec.norm();
  const double kappa =
      std::max(end_curvature_per_mm(path_, k - 1, true), end_curvature_per_mm(path_, k, false));
  FeedLimitResult corner = corner_speed(d_in, d_out, kappa, dk, dk_vec.cwiseAbs());
  const double phi_alone = turn_rad(d_in, d_out);
  const double phi_sum = summed_turn_rad(k, corner.feed_mm_per_s);
  if (phi_sum > phi_alone) {
    const double v =
        polyline_corner_speed_mm_per_s(limits_, std::min(phi_sum, std::numbers::pi), kappa);
    if (v < corner.feed_mm_per_s) corner = {v, FeedLimit::Corner};
  }
  // A summed turn can slow even a tangent joint below the stop threshold: it rests there.
  const bool summed_stop = phi_sum > phi_alone && !(corner.feed_mm_per_s >= stop_below_mm_per_s());
  if (path_.segments[k].stop_before || summed_stop ||
      must_stop(d_in, d_out, corner_mode(path_.segments[k - 1], limits_), corner)) {
    if (stops_mm_.empty() || starts_mm_[k] > stops_mm_.back()) stops_mm_.push_back(starts_mm_[k]);
    return;
  }
  joint_corner_[k] = corner;
  if (!d_in.isZero() && !d_out.isZero()) {
    const double phi = std::acos(std::clamp(d_in.dot(d_out), -1.0, 1.0));
    joint_share_[k] = jump_share(phi, dk, corner.feed_mm_per_s);
    if (limits_.has_axis_jerk()) {
      const Vec3 dd = phi < kMinTurnRad ? Vec3::Zero() : Vec3(d_out - d_in);
      joint_axis_share_[k] = axis_jump_shares(limits_, dd, dk_vec, corner.feed_mm_per_s);
    }
  }
}

// Two joints within one period's step: a segment between them shorter than the step at the
// corner speed puts both in one chord, which deviates by their summed turn (with the short
// segment's own), not by either alone (the corner law with φ the sum, capped at π). The turn at
// joint k, summed so with a short neighbour's.
double LimitSampler::summed_turn_rad(std::size_t k, double corner_mm_per_s) const {
  const std::size_t n = path_.segments.size();
  const double step_mm =
      std::min(corner_mm_per_s, limits_.max_feed_mm_per_min / 60.0) * limits_.period_s;
  const auto length = [&](std::size_t j) { return starts_mm_[j + 1] - starts_mm_[j]; };
  const auto dir = [&](std::size_t j, bool at_end) { return end_direction(path_, j, at_end); };
  double phi_sum = turn_rad(dir(k - 1, true), dir(k, false));
  if (k + 1 < n && length(k) < step_mm) {
    phi_sum += turn_rad(dir(k, false), dir(k, true)) + turn_rad(dir(k, true), dir(k + 1, false));
  }
  if (k >= 2 && length(k - 1) < step_mm) {
    phi_sum += turn_rad(dir(k - 1, false), dir(k - 1, true)) +
               turn_rad(dir(k - 2, true), dir(k - 1, false));
  }
  return phi_sum;
}

// Interior knots of curve k where the tangent turns: a stop, or a corner with its zone (and,
// under JerkBound::vector, a jump of the curvature vector at a smooth knot: a corner of its
// own). Their s is the span lengths summed as the walker sums them (adaptive Gauss–Legendre):
// with four fixed panels a span that nearly reverses (|C'| from 30 down to 1 and back) put a
// stop 7e-4 mm past its knot, and the motion turned the corner at 0.1 mm/s before resting (a
// jerk vector of 36 500 mm/s³: Property.RandomProgramsKeepTheJerkVectorBound, seed 47).
void LimitSampler::add_inner_knots(std::size_t k, const toolpath::NurbsCurve& c) {
  const std::vector<double> bp = c.breakpoints();
  double s = starts_mm_[k];
  for (std::size_t i = 1; i + 1 < bp.size(); ++i) {
    s += arc_length_mm(c, bp[i - 1], bp[i]);
    const toolpath::CurvePoint cl = c.eval(std::nextafter(bp[i], -kInf)), cr = c.eval(bp[i]);
    const Vec3 left = cl.d1, right = cr.d1;
    const Vec3 d_in = unit_or_zero(left), d_out = unit_or_zero(right);
    const bool axis_jerk = limits_.has_axis_jerk();
    const Vec3 dk_vec = limits_.jerk_bound == JerkBound::vector || axis_jerk
                            ? Vec3(curvature_vector_per_mm(cr) - curvature_vector_per_mm(cl))
                            : Vec3::Zero();
    const double dk = limits_.jerk_bound == JerkBound::vector ? dk_vec.norm() : 0.0;
    const double k_scale = std::max(curvature_per_mm(cl), curvature_per_mm(cr));
    const double phi =
        d_in.isZero() || d_out.isZero() ? M_PI : std::acos(std::clamp(d_in.dot(d_out), -1.0, 1.0));
    const bool smooth = phi < kMinTurnRad;
    const FeedLimitResult corner = corner_speed(d_in, d_out, k_scale, dk, dk_vec.cwiseAbs());
    const double share = jump_share(smooth ? 0.0 : phi, dk, corner.feed_mm_per_s);
    const Vec3 axis_share =
        axis_jerk && !d_in.isZero() && !d_out.isZero()
            ? axis_jump_shares(limits_, smooth ? Vec3::Zero() : Vec3(d_out - d_in), dk_vec,
                               corner.feed_mm_per_s)
            : Vec3::Zero();
    if (smooth) {  // a curvature jump: a corner only where it takes a share that counts
      if (share > 1e-6 || axis_share.maxCoeff() > 1e-6) {
        inner_corners_[k].push_back(
            {bp[i], s, left.norm(), right.norm(), corner, share, axis_share});
      }
      continue;
    }
    if (must_stop(d_in, d_out, corner_mode(path_.segments[k], limits_), corner)) {
      if (stops_mm_.empty() || s > stops_mm_.back()) stops_mm_.push_back(s);
    } else {
      inner_corners_[k].push_back({bp[i], s, left.norm(), right.norm(), corner, share, axis_share});
    }
  }
}

// The interior vertices of polyline k where the motion rests.
void LimitSampler::add_vertex_stops(std::size_t k, const toolpath::Polyline& line) {
  double s = starts_mm_[k];
  for (std::size_t v = 1; v + 1 < line.points.size(); ++v) {
    s += (line.points[v] - line.points[v - 1]).norm();
    if (vertex_is_stop(k, v) && (stops_mm_.empty() || s > stops_mm_.back())) {
      stops_mm_.push_back(s);
    }
  }
}

// Curve k's breakpoints, its near-cusp dips (a cusp refused), and at each interior knot where
// the limit jumps (a blend arc meeting its lines) the lower side's speed.
void LimitSampler::add_knot_edges(std::size_t k, const toolpath::NurbsCurve& c) {
  breakpoints_[k] = c.breakpoints();
  find_dips(c, breakpoints_[k], dips_[k]);
  for (const double u : dips_[k]) refuse_cusp(path_, k, c, u);
  for (const double u : breakpoints_[k]) {
    const toolpath::CurvePoint cl = c.eval(std::nextafter(u, -kInf)), cr = c.eval(u);
    const bool interior = u > c.u_begin() && u < c.u_end();
    const double v = interior ? jump_edge(limit_on_curve(k, std::nextafter(u, -kInf)).feed_mm_per_s,
                                          limit_on_curve(k, u).feed_mm_per_s)
                              : kInf;
    knot_edges_[k].push_back({v, cl.d1.norm(), cr.d1.norm()});
  }
}

// "Flat intervals" (top of limit_sampler.cpp): for a non-rational C¹ curve of degree ≥ 2, per
// knot span the largest |C''| (its second hodograph's control points) and the largest |P_i|;
// bounds stays empty for any other curve.
void LimitSampler::bound_spans(const toolpath::NurbsCurve& c, std::vector<SpanBound>& bounds,
                               std::vector<SpanAxisBound>* axis_bounds) {
  if (c.rational() || c.degree() < 2) return;
  const auto p = static_cast<std::size_t>(c.degree());
  const auto& U = c.knots();
  const auto& P = c.points();
  bool c1 = true;  // every interior knot of multiplicity ≤ p − 1: C' is continuous
  for (std::size_t i = p + 1, m = U.size() - p - 1; i < m && c1;) {
    std::size_t j = i;
    while (j + 1 < m && U[j + 1] == U[i]) ++j;
    c1 = j - i + 1 <= p - 1;
    i = j + 1;
  }
  if (!c1) return;
  // First and second hodographs (Piegl and Tiller eq. 3.8): Q_i = p (P_i+1 − P_i) /
  // (u_i+p+1 − u_i+1), R_i = (p − 1)(Q_i+1 − Q_i) / (u_i+p+1 − u_i+2); on span s, C' is a
  // convex combination of Q_s−p … Q_s−1 and C'' of R_s−p … R_s−2 (so per axis too).
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
  if (!finite) return;
  // The third hodograph (degree ≥ 3): T_i = (p − 2)(R_i+1 − R_i) / (u_i+p+1 − u_i+3); on span
  // s, C''' is a convex combination of T_s−p … T_s−3.
  std::vector<Vec3> t3(p >= 3 ? np - 3 : 0);
  for (std::size_t i = 0; i < t3.size(); ++i) {
    t3[i] = static_cast<double>(p - 2) * (r[i + 1] - r[i]) / (U[i + p + 1] - U[i + 3]);
  }
  const Vec3 inf3 = Vec3::Constant(kInf);
  bounds.assign(U.size(), SpanBound{kInf, kInf});
  if (axis_bounds) axis_bounds->assign(U.size(), SpanAxisBound{inf3, inf3, inf3, kInf});
  for (std::size_t sp = p; sp < np; ++sp) {
    double d2 = 0.0, pm = 0.0, d3 = 0.0;
    Vec3 d1_abs = Vec3::Zero(), d2_abs = Vec3::Zero(), d3_abs = Vec3::Zero();
    for (std::size_t i = sp - p; i + 1 <= sp; ++i) d1_abs = d1_abs.cwiseMax(q[i].cwiseAbs());
    for (std::size_t i = sp - p; i + 2 <= sp; ++i) {
      d2 = std::max(d2, r[i].norm());
      d2_abs = d2_abs.cwiseMax(r[i].cwiseAbs());
    }
    for (std::size_t i = sp - p; i + 3 <= sp && p >= 3; ++i) {
      d3 = std::max(d3, t3[i].norm());
      d3_abs = d3_abs.cwiseMax(t3[i].cwiseAbs());
    }
    for (std::size_t i = sp - p; i <= sp; ++i) pm = std::max(pm, P[i].norm());
    bounds[sp] = {d2, pm};
    // (A third hodograph that overflows leaves the span without a jerk bound: +inf.)
    if (!std::isfinite(d3) || !d3_abs.allFinite()) d3 = kInf, d3_abs = inf3;
    if (axis_bounds) (*axis_bounds)[sp] = {d1_abs, d2_abs, d3_abs, d3};
  }
}

// Per joint, the speed that places the nodes around it: a corner's, or where the limit jumps
// across a tangent joint the lower side's (+inf at a stop and where nothing jumps).
void LimitSampler::add_joint_edges() {
  const std::size_t n = path_.segments.size();
  joint_edge_.assign(n + 1, kInf);
  for (std::size_t k = 1; k < n; ++k) {
    if (std::isfinite(joint_corner_[k].feed_mm_per_s)) {
      joint_edge_[k] = joint_corner_[k].feed_mm_per_s;  // a corner: its zone
    } else if (!std::binary_search(stops_mm_.begin(), stops_mm_.end(), starts_mm_[k])) {
      joint_edge_[k] =
          jump_edge(side_limit(k - 1, true).feed_mm_per_s, side_limit(k, false).feed_mm_per_s);
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

}  // namespace ncd::feed
