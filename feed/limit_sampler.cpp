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
// that on a curve after an interval whose limit is below the cap and changing; a curve step
// that came out longer than 1.25 spacings is cut back), with a node on every knot and vertex. The
// minimum over a curve interval: five samples, then Brent's method around the lowest (the minimum
// may sit just inside an end).
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
// min(roughness(0), chord(κ_max), accel(κ_max), jerk(κ_max)), and with per-axis limits the axis
// laws at |t_i| ≤ max|C'_i| / min|C'| and |k_i| ≤ (max|C''_i| + |t_i| M2) / min|C'|² (the
// hodographs' hulls per axis). The interval is flat if that exceeds the cap by 1e-6
// (relative). Rational curves and corners at knots always search. Under per-axis jerk the
// same tables spare an interval curve_turn's nine points where they prove the axes' curve-jerk
// law idle (axis_curve_jerk_holds, limit_sampler_laws.cpp).
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
#include <cmath>
#include <limits>

#include "feed/limit_sampler_detail.hpp"

namespace ncd::feed {

using namespace sampler_detail;

namespace {

// Half intervals follow one whose limit is below the cap (by 0.1 %) and changed from the one
// before by more than kFineStep of itself (a slope of the limit; docs/planner.md §2).
constexpr double kFineBelowCap = 0.999;
constexpr double kFineStep = 0.005;
// Where the limit jumps at a smooth knot, the nodes beside it lie this many periods of travel
// (at the lower speed) from it: the slow stretch is the arc and these two guards. One whole
// period held the arc's speed two periods longer at each corner (gentle zig-zag under G64
// P0.01: 3.040 s; a quarter: 2.960 s, and a tenth the same; docs/planner.md §3a).
constexpr double kGuardPeriods = 0.25;
// A curve interval longer than this many spacings is cut back (curve_interval).
constexpr double kOverlong = 1.25;

}  // namespace

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

void LimitSampler::apply_zones(Interval& iv) const {
  const auto zone = [&](double center_mm, FeedLimitResult corner, double share,
                        const Vec3& axis_share) {
    if (!std::isfinite(corner.feed_mm_per_s)) return;
    const double half = corner.feed_mm_per_s * limits_.period_s;
    // The third difference of the setpoints spans three periods: the jump's share of the
    // jerk budget holds within two periods' travel of it (of each axis's, per-axis jerk).
    if (iv.a_mm < center_mm + 2.0 * half && iv.b_mm > center_mm - 2.0 * half) {
      if (share > 0.0) iv.jump_share = std::max(iv.jump_share, share);
      iv.axis_jump_share = iv.axis_jump_share.cwiseMax(axis_share);
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
      Vec3 axis_share = Vec3::Zero();
      if (v == 0 || v + 1 == line->points.size()) {
        share = joint_share_[v == 0 ? segment_ : segment_ + 1];
        axis_share = joint_axis_share_[v == 0 ? segment_ : segment_ + 1];
      } else if (std::isfinite(corner.feed_mm_per_s)) {
        const Vec3 d_in = unit_or_zero(line->points[v] - line->points[v - 1]);
        const Vec3 d_out = unit_or_zero(line->points[v + 1] - line->points[v]);
        const double phi = std::acos(std::clamp(d_in.dot(d_out), -1.0, 1.0));
        share = jump_share(phi, vertex_curvature_jump_per_mm(segment_, v), corner.feed_mm_per_s);
        if (limits_.has_axis_jerk()) {
          axis_share =
              axis_jump_shares(limits_, phi < kMinTurnRad ? Vec3::Zero() : Vec3(d_out - d_in),
                               vertex_axis_curvature_jump(segment_, v), corner.feed_mm_per_s);
        }
      }
      zone(s, corner, share, axis_share);
      if (v + 1 < line->points.size()) s += (line->points[v + 1] - line->points[v]).norm();
    }
  } else {
    zone(starts_mm_[segment_], joint_corner_[segment_], joint_share_[segment_],
         joint_axis_share_[segment_]);
    zone(starts_mm_[segment_ + 1], joint_corner_[segment_ + 1], joint_share_[segment_ + 1],
         joint_axis_share_[segment_ + 1]);
    const auto& inner = inner_corners_[segment_];
    const double reach = 2.0 * limits_.max_feed_mm_per_min / 60.0 * limits_.period_s;
    auto it = std::lower_bound(inner.begin(), inner.end(), iv.a_mm - reach,
                               [](const InnerCorner& c, double s) { return c.s_mm < s; });
    for (; it != inner.end() && it->s_mm <= iv.b_mm + reach; ++it) {
      zone(it->s_mm, it->corner, it->share, it->axis_share);
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
        next_segment();
        continue;
      }
      piece_interval(*line, iv);
      return true;
    }
    const auto& c = std::get<toolpath::NurbsCurve>(g);
    if (u_ >= c.u_end()) {
      next_segment();
      continue;
    }
    curve_interval(c, iv);
    return true;
  }
  return false;
}

void LimitSampler::next_segment() {
  ++segment_, piece_ = 0, sub_ = 0;
  if (segment_ < path_.segments.size()) enter_segment();
}

// One interval of polyline piece piece_ from s_: at most spacing_mm long, ending on the corner
// zones' edges; the piece's limit, lowered in the zones.
void LimitSampler::piece_interval(const toolpath::Polyline& line, Interval& iv) {
  const double len = (line.points[piece_ + 1] - line.points[piece_]).norm();
  const bool last_piece = piece_ + 2 == line.points.size();
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
  iv.kappa_per_mm = limits_.jerk_bound == JerkBound::vector || limits_.has_axis_jerk()
                        ? piece_curvature_per_mm(segment_, piece_)
                        : 0.0;
  iv.turn_per_mm2 = 0.0;
  iv.jump_share = 0.0;
  iv.axis_jump_share = Vec3::Zero();
  iv.k_axis = iv.kappa_per_mm * Vec3::Ones();
  iv.g_axis = iv.kappa_per_mm * iv.kappa_per_mm * Vec3::Ones();  // as a circle's −κ² T
  iv.axis_accel_factor = 1.0;
  iv.rest_speed = false;
  iv.tangent_max = (line.points[piece_ + 1] - line.points[piece_]).normalized().cwiseAbs();
  iv.bends = piece_curvature_per_mm(segment_, piece_) > 0.0;
  apply_zones(iv);
  bound_jerk_vector(iv);
  bound_axis_curve_jerk(iv);
  s_ = b;
  if (b >= end) {
    ++piece_, sub_ = 0;
    piece_s_ = end;
  }
}

// One interval of curve c from u_: where it ends (curve_step_end_u, then the refinements
// towards a rest and a near-cusp), its limit (curve_interval_limit), raised to the rest speed
// where it is the innermost one at a rest, then its curvature, tangents, corner zones and
// jerk-vector bound.
void LimitSampler::curve_interval(const toolpath::NurbsCurve& c, Interval& iv) {
  const Vec3 d1_u0 = c.derivative(u_);
  const double speed = d1_u0.norm();
  double u1 = curve_step_end_u(c, speed);
  RestEnds rest{};
  refine_towards_rest_start(c, u1, rest);
  refine_near_dips(c, u1);
  bool end_rest = refine_towards_rest_end(c, u1, rest);
  double arc = gauss_arc_mm(c, u_, u1);
  // The step is sized by |C'(u_)|: where |C'| grows fast past u_ (a curve leaving a point of
  // high curvature slowly), the interval came out several spacings long, all of it at the limit
  // of its slow end. Rescaled until it is at most kOverlong spacings (|C'| growing, a rescaled
  // step is shorter still); its end is then no knot and no rest.
  const double spacing_mm = fine_ ? 0.5 * config_.spacing_mm : config_.spacing_mm;
  while (arc > kOverlong * spacing_mm) {
    u1 = u_ + (u1 - u_) * (spacing_mm / arc);
    arc = gauss_arc_mm(c, u_, u1);
    end_rest = false;
  }
  const std::vector<double>& knots = breakpoints_[segment_];
  const bool open_end = (knot_ < knots.size() && u1 == knots[knot_] &&
                         std::isfinite(knot_edges_[segment_][knot_].v_mm_per_s)) ||
                        (end_rest && u1 < c.u_end());
  FeedLimitResult v = curve_interval_limit(u1, speed, open_end);
  const bool raised = rest.innermost && raise_to_rest_speed(rest, u1, open_end, v);
  iv.a_mm = s_;
  iv.b_mm = u1 >= c.u_end() ? starts_mm_[segment_ + 1] : s_ + arc;
  iv.v_mm_per_s = v.feed_mm_per_s;
  iv.limit = v.limit;
  iv.kappa_per_mm = iv.turn_per_mm2 = 0.0;
  iv.jump_share = 0.0;
  iv.axis_jump_share = iv.k_axis = iv.g_axis = Vec3::Zero();
  iv.axis_accel_factor = 1.0;
  iv.rest_speed = raised;
  if (limits_.has_axis_limits()) curve_tangent_max(c, u_, u1, d1_u0, iv);
  const bool vector = limits_.jerk_bound == JerkBound::vector;
  if (vector) curve_turn(segment_, u_, u1, speed, iv);
  apply_zones(iv);
  bound_jerk_vector(iv);
  // Per-axis jerk alone reads curve_turn's figures only in bound_axis_curve_jerk, which leaves
  // an interval raised to the rest speed, or one the span's bounds prove within every axis's
  // budget, as it is (axis_curve_jerk_holds): those skip its nine evaluations.
  if (!vector && limits_.has_axis_jerk() && !iv.rest_speed) {
    if (config_.skip_flat_intervals && axis_curve_jerk_holds(segment_, u_, u1, speed, iv)) {
      ++axis_turn_skips_;
    } else {
      curve_turn(segment_, u_, u1, speed, iv);
    }
  }
  bound_axis_curve_jerk(iv);
  s_ = iv.b_mm;
  u_ = u1;
}

// The end of the next curve interval before the rest and near-cusp refinements: one spacing
// (half of it where fine_) at the parametric speed at u_, no further than the next breakpoint,
// with no sliver left before a rest, and ending on the first zone edge of a joint's corner, a
// corner inside the curve, or a jump of the limit at a smooth knot.
double LimitSampler::curve_step_end_u(const toolpath::NurbsCurve& c, double speed) {
  const double spacing_mm = fine_ ? 0.5 * config_.spacing_mm : config_.spacing_mm;
  double u1 = speed > 0.0 ? u_ + spacing_mm / speed : c.u_end();
  const std::vector<double>& knots = breakpoints_[segment_];
  while (knot_ < knots.size() && knots[knot_] <= u_) ++knot_;
  if (knot_ < knots.size()) u1 = std::min(u1, knots[knot_]);
  u1 = std::min(u1, c.u_end());
  u1 = no_sliver_before_rest(c, u1);
  u1 = joint_zone_edge_u(c, u1);
  u1 = inner_corner_edge_u(u1);
  return knot_guard_edge_u(u1);
}

// No sliver before a rest point: where the step leaves less than another step's worth of
// parameter to the next breakpoint and the motion rests there, the arc up to it becomes one
// interval or two equal ones, so that the rest refinement sees an interval that ends on the
// rest point. (Near a repeated end point the parametric speed falls to 0, the step u + d/|C'|
// stopped 2 µm short of the end, and that sliver took the rest speed of its length, 0.008
// mm/s; the planner takes the smaller limit of an interval's two nodes, so the whole 0.1 mm
// interval before it crawled: seed 7414150 of Property.RandomDegenerateNurbs*.)
double LimitSampler::no_sliver_before_rest(const toolpath::NurbsCurve& c, double u1) const {
  const std::vector<double>& knots = breakpoints_[segment_];
  const double u_next = knot_ < knots.size() ? std::min(knots[knot_], c.u_end()) : c.u_end();
  if (!(u1 < u_next && u_next - u1 < u1 - u_)) return u1;
  const double to_next = gauss_arc_mm(c, u_, u_next);
  const double s_next = u_next >= c.u_end() ? starts_mm_[segment_ + 1] : s_ + to_next;
  if (!is_rest_mm(s_next)) return u1;
  if (to_next <= config_.spacing_mm) return u_next;
  if (to_next <= 2.0 * config_.spacing_mm) return u_at_arc(c, u_, u_next, 0.5 * to_next);
  return u1;
}

// The corner zones at the joints get intervals of their own (their edges mapped to u at the
// joint's parametric speed), so that a slow corner does not slow a whole interval.
double LimitSampler::joint_zone_edge_u(const toolpath::NurbsCurve& c, double u1) const {
  const double s0 = starts_mm_[segment_], s1 = starts_mm_[segment_ + 1];
  const double edge = next_zone_edge_mm(s0, joint_edge_[segment_], s1, joint_edge_[segment_ + 1]);
  if (!std::isfinite(edge)) return u1;
  const bool near_start = edge - s0 < s1 - edge;
  const double speed_joint = c.eval(near_start ? c.u_begin() : c.u_end()).d1.norm();
  if (!(speed_joint > 0.0)) return u1;
  const double ue =
      near_start ? c.u_begin() + (edge - s0) / speed_joint : c.u_end() - (s1 - edge) / speed_joint;
  return ue > u_ ? std::min(u1, ue) : u1;
}

// A jump of the limit at a smooth knot (a blend arc meeting its lines): a node a quarter of a
// period's travel at the lower speed before and after it (kGuardPeriods).
double LimitSampler::knot_guard_edge_u(double u1) const {
  const std::vector<double>& knots = breakpoints_[segment_];
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
    consider(knots[knot_] - edges[knot_].v_mm_per_s * kGuardPeriods * T / edges[knot_].speed_in);
  }
  return u1;
}

// Rest refinement, leaving a rest: where the motion rests at a knot whose limit dips towards
// 0 (a repeated control point), the first interval is d₁ long and the ones after it double.
void LimitSampler::refine_towards_rest_start(const toolpath::NurbsCurve& c, double& u1,
                                             RestEnds& rest) {
  const double d1 = rest_first_mm();
  const std::vector<double>& knots = breakpoints_[segment_];
  const bool at_knot = u_ == c.u_begin() || (knot_ > 0 && knots[knot_ - 1] == u_);
  if (rest_origin_mm_ < 0.0 && at_knot && is_rest_mm(s_) && needs_rest_refinement(segment_, u_)) {
    rest_origin_mm_ = s_;
    rest.innermost = rest.at_start = true;
    rest.d_mm = d1;
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
}

// Near-cusps (docs/planner.md §2): intervals halve towards the bottom u* of a deep dip of |C'|
// inside a span and double away from it, from kDipFirstMm, and one ends on u*: only a few µm
// around it take the speed of its curvature peak, not two whole intervals.
void LimitSampler::refine_near_dips(const toolpath::NurbsCurve& c, double& u1) const {
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

// Rest refinement, coming to rest: an interval that ends on a knot where the motion rests and
// the limit dips is halved until it is at most 2 d₁ long, the last one the innermost. Whether
// the interval ends where the motion rests (its far side is not its own).
bool LimitSampler::refine_towards_rest_end(const toolpath::NurbsCurve& c, double& u1,
                                           RestEnds& rest) {
  const std::vector<double>& knots = breakpoints_[segment_];
  const bool end_knot = u1 >= c.u_end() || (knot_ < knots.size() && u1 == knots[knot_]);
  if (!end_knot) return false;
  const double d_mm = gauss_arc_mm(c, u_, u1);
  const double s_end = u1 >= c.u_end() ? starts_mm_[segment_ + 1] : s_ + d_mm;
  bool end_rest = is_rest_mm(s_end);
  if (end_rest && needs_rest_refinement(segment_, std::nextafter(u1, -kInf))) {
    if (d_mm > 2.0 * rest_first_mm()) {
      u1 = u_at_arc(c, u_, u1, 0.5 * d_mm);
      end_rest = false;
      rest_origin_mm_ = -1.0;
    } else {
      rest.innermost = rest.at_end = true;
      rest.d_mm = std::max(rest.d_mm, d_mm);
    }
  }
  return end_rest;
}

// The limit of the curve interval [u_, u1]: the cap where it is flat, else the searched
// minimum. Sets fine_ for the next interval.
FeedLimitResult LimitSampler::curve_interval_limit(double u1, double speed, bool open_end) {
  // A flat interval: every point the search would evaluate gives the cap, and ties keep the
  // first, so its result is the limit at any one point with every law above the cap.
  // (JerkBound::vector needs the curvature of every interval: no skip.)
  const bool flat = config_.skip_flat_intervals && limits_.jerk_bound != JerkBound::vector &&
                    interval_is_flat(segment_, u_, u1, speed);
  const FeedLimitResult v =
      flat ? min_of({limits_.max_feed_mm_per_min / 60.0, FeedLimit::MaxFeed}, segment_cap(segment_))
           : interval_min_on_curve(segment_, u_, u1, open_end);
  ++curve_intervals_;
  if (flat) ++flat_intervals_;
  // Where the limit is below the cap and changes fast along the curve, shorter intervals
  // follow it closer (the planner holds each interval's minimum over the whole interval).
  fine_ = v.feed_mm_per_s < kFineBelowCap * segment_cap(segment_).feed_mm_per_s &&
          std::abs(v.feed_mm_per_s - last_curve_v_) > kFineStep * v.feed_mm_per_s;
  last_curve_v_ = v.feed_mm_per_s;
  return v;
}

// The innermost interval at a rest: the first (last) period's travel from (to) rest: no
// jerk-limited motion is faster there than the rest speed, so the limit's dip to 0 at the
// point itself is not a cap. The segment's own caps (its programmed feed, the machine's
// maximum) are, whatever the speed reachable: a move programmed slower than the rest speed (G93
// F0.5 over 8 mm is 3.9 mm/min) keeps its feed up to the rest. Nor is a limit the rest speed
// does not cover: where the limit is below the rest speed at some distance from the rest (a
// tiny helix, whose chord law is low all along, not a dip at the point), the raise stops at it
// (rest_uncovered_min_mm_per_s). Whether v was raised.
bool LimitSampler::raise_to_rest_speed(const RestEnds& rest, double u1, bool open_end,
                                       FeedLimitResult& v) const {
  const FeedLimitResult cap = segment_cap(segment_);
  double raise = std::min(rest_speed_mm_per_s(rest.d_mm), cap.feed_mm_per_s);
  const double u_mid = rest.at_start && rest.at_end ? 0.5 * (u_ + u1) : (rest.at_start ? u1 : u_);
  if (rest.at_start && raise > v.feed_mm_per_s) {
    raise = std::min(raise, rest_uncovered_min_mm_per_s(segment_, u_, u_mid, v.feed_mm_per_s,
                                                        open_end && u_mid == u1));
  }
  if (rest.at_end && raise > v.feed_mm_per_s) {
    raise =
        std::min(raise, rest_uncovered_min_mm_per_s(segment_, u1, u_mid, v.feed_mm_per_s, false));
  }
  if (!(raise > v.feed_mm_per_s)) return false;
  if (raise >= cap.feed_mm_per_s) {
    v = cap;
  } else {
    v.feed_mm_per_s = raise;
  }
  return true;
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

// The u in [u0, u_hi] at arc length arc_mm from u0 (bisection; [u0, u_hi] holds no knot, and
// gauss_arc_mm checks the 10-point rule where |C'| varies); u_hi if the arc to it is shorter.
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
      pending_.axis_scale = axis_scales(limits_, iv.tangent_max, {iv.bends, iv.bends, iv.bends},
                                        Vec3::Ones() - iv.axis_jump_share);
      pending_.axis_scale.accel *= iv.axis_accel_factor;
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

}  // namespace ncd::feed
