// Corner blending under G64 P (docs/planner.md §3a).
//
// A corner between two straight pieces turning by φ (the angle between the directions d_in
// and d_out) is replaced by the circular arc tangent to both pieces whose midpoint passes the
// vertex V, the programmed end point, at P − ε_c (P: the move's G64 P, or blend_tolerance_mm
// under a plain G64; ε_c the chord tolerance; below):
//
//            V                     R = (P − ε_c) cos(φ/2) / (1 − cos(φ/2))
//      ─────●─────                 L = R tan(φ/2)
//     d_in ╱ ╲                     (the midpoint lies R (1/cos(φ/2) − 1) = P − ε_c from V and
//         ●‿‿‿●                     R (1 − cos(φ/2)) = (P − ε_c) cos(φ/2) off both pieces)
//       tangent points   arc: rational quadratic Bézier V − L d_in, V, V + L d_out with
//                        weights 1, cos(φ/2), 1 (a circle)
//
// The midpoint is the arc's point nearest V, and a chord between two setpoints on the arc lies
// at most ε_c farther inside: the walked path passes every programmed end point within P
// (issue 32; LinuxCNC's circular blends are within P of the vertex too). A point of the arc that
// has turned by α from its tangent point lies R (1 − cos α) off that piece, less than P: the arc
// stays within P of the programmed path. (Sized to lie P off the pieces, as before issue 32, it
// passed V at P / cos(φ/2): 1.41 P at 90°.) The tangent length is capped at half of each
// neighbouring piece, so that the arcs of consecutive corners never overlap; R shrinks with it
// (R = L / tan(φ/2)).
//
// Among the curves tangent to both pieces that pass within a distance of the vertex, the arc has
// the smallest largest curvature, so its curve laws (centripetal acceleration √(a/κ), centripetal
// jerk (j/κ²)^(1/3), chord error) give the highest constant speed through the corner.
// LinuxCNC's tp rounds corners with arcs within P of the vertex too; grbl keeps the sharp
// corner and bounds the speed by its junction deviation (the sampler's rule at unblended
// corners, §2).
//
// Whether to blend: the arc is walked at its constant speed v_arc; the sharp corner is passed
// at the sampler's corner speed v_c, or with a full stop where v_c < a_max T. Each choice
// costs, on each side, the jerk-limited S-curve time from the speed V reachable there (the
// cap, or less on a leg too short to reach it) down to the corner speed, less the time that
// distance takes at V, plus the time through the slow zone (the arc and one period of travel
// on each side, or 4 v_c T). The arc is taken only where it costs less: at 1 µm chord
// tolerance and the default limits a 90° corner at P0.01 mm allows 2.1 mm/s through its arc
// (R 0.022 mm, the centripetal jerk law), slower than stopping, so it stops; at P0.5 mm it is
// rounded. Under the jerk-vector bound (docs/planner.md §3c) the arc's ends are curvature jumps,
// and the whole arc is estimated at their jump speed.
//
// Where: corners between straight pieces of moves under G64 with P > 0, inside a polyline
// and at the joint with the next move, when both are plain polylines (no contact normals,
// the chamfer's, which the roughness law needs at the vertices), the next move needs no rest
// before it, and no piece is shorter than one period's travel at its feed (dense CAM runs
// keep the discrete-curvature laws of the sampler, §2). Reversals (cos(φ/2) < 0.05) and
// corners under G61/G61.1 are never blended.
//
// Representation: a segment that receives an arc becomes a degree-2 rational NURBS with one
// Bézier span per line (middle control point at the midpoint: constant parametric speed) or
// arc, knots of multiplicity 2 between spans (tangent-continuous, so the sampler sees no
// corner there), each span as wide in u as it is long. The next segment starts at the arc's
// end. Segment count, order, feeds and modes are unchanged.
#include "feed/corner_blend.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace ncd::feed {
namespace {

using toolpath::NurbsCurve;
using toolpath::PathControl;
using toolpath::PathSegment;
using toolpath::Polyline;

constexpr double kMinHalfCos = 0.05;    // cos(φ/2) below it (φ > 174°): a reversal, not blended
constexpr double kMinSpanMm = 1e-9;     // shorter line spans are dropped (their knots would merge)
constexpr double kMinTangentMm = 1e-6;  // an arc shorter than this is not worth a span

// G64 P gives the tolerance; a plain G64 (no P) takes the machine file's blend_tolerance_mm
// (the "without G64 P the machine file's blend_tolerance_mm applies"; LinuxCNC's plain
// G64 has no bound at all). G64 P0 keeps the corners sharp.
double tolerance_mm(const PathSegment& s, const MachineLimits& limits) {
  const double p = s.blend_tolerance_mm.value_or(limits.blend_tolerance_mm);
  return std::isfinite(p) && p > 0.0 ? p : 0.0;
}

// A polyline whose every corner may be rounded: plain, under G64 with P > 0, no piece shorter
// than one period's travel at its feed.
bool blendable_body(const PathSegment& s, const MachineLimits& l) {
  const auto* line = std::get_if<Polyline>(&s.geometry);
  if (!line || !line->normals.empty() || line->points.size() < 2) return false;
  if (s.path_control != PathControl::blend || !(tolerance_mm(s, l) > 0.0)) return false;
  const double shortest = segment_cap_mm_per_s(s, l) * l.period_s;
  for (std::size_t i = 0; i + 1 < line->points.size(); ++i) {
    if (!((line->points[i + 1] - line->points[i]).norm() >= shortest)) return false;
  }
  return true;
}

// One side of a corner approached at speed V (cruise) and passed at v: the jerk-limited
// S-curve time from V to v, less the time the same distance, plus `saved_mm` of path that
// the slow zone or the arc skips, would take at V: the time the corner costs on that side.
double side_cost_s(double cruise, double v, double saved_mm, const MachineLimits& l) {
  const double a = l.max_accel_mm_per_s2, j = l.max_jerk_mm_per_s3;
  const double dv = std::max(cruise - v, 0.0);
  const double t = dv >= a * a / j ? dv / a + a / j : 2.0 * std::sqrt(dv / j);
  return t - (0.5 * (cruise + v) * t + saved_mm) / cruise;
}

// The highest speed a jerk-limited S-curve from rest reaches within d (and comes back to
// a = 0): d = w t(w) / 2 with t(w) = 2 sqrt(w / j) below a²/j, w/a + a/j above.
double reachable_mm_per_s(double d_mm, const MachineLimits& l) {
  const double a = l.max_accel_mm_per_s2, j = l.max_jerk_mm_per_s3;
  const double w = std::cbrt(d_mm * d_mm * j);
  if (w <= a * a / j) return w;
  return 0.5 * a * (-a / j + std::sqrt(a * a / (j * j) + 8.0 * d_mm / a));
}

struct Corner {
  bool blended = false;
  Vec3 v, d_in, d_out;
  double tangent_mm = 0.0, radius_mm = 0.0, half_cos = 1.0, phi_rad = 0.0;
  bool eligible = false;  // a turn that is neither straight nor a reversal, P > 0
  double tolerance_mm = 0.0, in_mm = 0.0, out_mm = 0.0;
};

// The arc at vertex v between pieces of lengths l_in and l_out, for tolerance p and the
// feed cap of the move that ends at v; blended only if faster than the sharp corner.
Corner plan_corner(const Vec3& a, const Vec3& v, const Vec3& b, double p_mm, double cap_in,
                   double cap, const MachineLimits& l) {
  Corner c;
  c.v = v;
  const Vec3 in = v - a, out = b - v;
  const double l_in = in.norm(), l_out = out.norm();
  if (!(l_in > 0.0 && l_out > 0.0)) return c;
  c.d_in = in / l_in;
  c.d_out = out / l_out;
  c.phi_rad = std::acos(std::clamp(c.d_in.dot(c.d_out), -1.0, 1.0));
  c.half_cos = std::cos(0.5 * c.phi_rad);
  if (c.phi_rad < kMinTurnRad || c.half_cos < kMinHalfCos) return c;
  const double one_minus = 2.0 * std::pow(std::sin(0.25 * c.phi_rad), 2);  // 1 − cos(φ/2), exact
  const double tan_half = std::tan(0.5 * c.phi_rad);
  // The arc's midpoint lies R (1 − cos(φ/2)) / cos(φ/2) from the vertex (the programmed end
  // point) and R (1 − cos(φ/2)) off both legs: P bounds the first, which is the larger, less
  // the chord tolerance, by which a chord between two setpoints on the arc lies farther.
  const double r_p = std::max(p_mm - l.chord_tolerance_mm, 0.0) * c.half_cos / one_minus;
  c.tangent_mm = std::min({r_p * tan_half, 0.5 * l_in, 0.5 * l_out});
  c.radius_mm = c.tangent_mm / tan_half;
  if (!(c.tangent_mm >= kMinTangentMm) || !std::isfinite(c.radius_mm)) return c;
  const double T = l.period_s;
  const double kappa = 1.0 / c.radius_mm;
  const double v_arc =
      std::min({cap_in, cap, chord_feed_mm_per_s(kappa, l.chord_tolerance_mm, l.period_s),
                centripetal_accel_feed_mm_per_s(kappa, l.max_accel_mm_per_s2),
                centripetal_jerk_feed_mm_per_s(kappa, l.max_jerk_mm_per_s3)});
  // Under the jerk-vector bound the arc's ends are curvature jumps, passed at the jump speed;
  // the estimate takes the whole arc at it. (An arc walked at its own speed between the two
  // jumps, reached with a_max, was tried: it chose the arcs of the 30° zig-zag at P0.5, which
  // then took 3.60 s against 3.12 s with stops, since the ramps between the jumps are
  // jerk-limited and at the scaled tangential limits of docs/planner.md §3c.)
  // Under per-axis jerk limits the same ends take each axis's jump law (the curvature vector
  // jumps by κ along the arc's normal there: d_out's part normal to d_in at the start, −d_in's
  // normal to d_out at the end), and the sharp corner its velocity jump's.
  double v_end = l.jerk_bound == JerkBound::vector
                     ? std::min(v_arc, jump_feed_mm_per_s(l, 0.0, kappa))
                     : v_arc;
  double v_sharp = std::min(cap, polyline_corner_speed_mm_per_s(l, c.phi_rad));
  if (l.has_axis_jerk()) {
    const Vec3 dd = c.d_out - c.d_in;
    const double cos_phi = c.d_in.dot(c.d_out);
    const Vec3 n_start = (c.d_out - cos_phi * c.d_in).normalized();
    const Vec3 n_end = (cos_phi * c.d_out - c.d_in).normalized();
    const Vec3 dk = kappa * n_start.cwiseAbs().cwiseMax(n_end.cwiseAbs());
    v_end = std::min(v_end, axis_jump_feed_mm_per_s(l, Vec3::Zero(), dk));
    v_sharp = std::min(v_sharp, axis_jump_feed_mm_per_s(l, dd, Vec3::Zero()));
  }
  const double t_arc = (c.radius_mm * c.phi_rad + 2.0 * v_end * T) / v_end;
  if (v_sharp < l.max_accel_mm_per_s2 * l.period_s) v_sharp = 0.0;  // the sampler stops there
  // The time each way costs near the corner, from cruising at the caps on both sides (see the
  // top of the file): blend if the arc is faster than the sharp corner or the stop.
  // The speed each side can reach: the cap, or less on a short leg (rest at its midpoint).
  cap_in = std::min(cap_in, reachable_mm_per_s(0.5 * l_in, l));
  cap = std::min(cap, reachable_mm_per_s(0.5 * l_out, l));
  const double blend = side_cost_s(cap_in, v_end, c.tangent_mm + v_end * T, l) +
                       side_cost_s(cap, v_end, c.tangent_mm + v_end * T, l) + t_arc;
  const double sharp = v_sharp > 0.0
                           ? side_cost_s(cap_in, v_sharp, 2.0 * v_sharp * T, l) +
                                 side_cost_s(cap, v_sharp, 2.0 * v_sharp * T, l) + 4.0 * T
                           : side_cost_s(cap_in, 0.0, 0.0, l) + side_cost_s(cap, 0.0, 0.0, l);
  c.blended = v_end > v_sharp && blend < sharp;
  c.eligible = true;
  c.tolerance_mm = p_mm;
  c.in_mm = l_in;
  c.out_mm = l_out;
  return c;
}

struct Span {
  Vec3 mid;        // middle control point
  Vec3 end;        // end point
  double w = 1.0;  // middle weight
  double len_mm = 0.0;
};

// The corner at the joint after each segment k, where its arc may be (it belongs to segment k):
// a blendable polyline followed by one whose first piece is long enough at its cap.
std::vector<Corner> plan_joints(const toolpath::Path& path, const MachineLimits& limits,
                                const std::vector<char>& body) {
  const std::size_t n = path.segments.size();
  std::vector<Corner> joint(n);
  for (std::size_t k = 0; k + 1 < n; ++k) {
    const PathSegment &s = path.segments[k], &t = path.segments[k + 1];
    const auto* next = std::get_if<Polyline>(&t.geometry);
    if (!body[k] || t.stop_before || !next || !next->normals.empty() || next->points.size() < 2) {
      continue;
    }
    if (!((next->points[1] - next->points[0]).norm() >=
          segment_cap_mm_per_s(t, limits) * limits.period_s)) {
      continue;
    }
    const auto& pts = std::get<Polyline>(s.geometry).points;
    // The joint's pieces: the last of k and the first of k + 1 (their other ends may be
    // trimmed by other arcs, each by at most half of the piece).
    joint[k] =
        plan_corner(pts[pts.size() - 2], pts.back(), next->points[1], tolerance_mm(s, limits),
                    segment_cap_mm_per_s(s, limits), segment_cap_mm_per_s(t, limits), limits);
  }
  return joint;
}

// The corners kept sharp, in path order. The straight length on each side is what is left of
// the piece after its other end's arc (at most half of the piece).
// Not where a rapid begins or ends: a G0 positions, and the approach and the retract are
// written to the machine as their programmed points (link/program_blocks.cpp).
void keep_sharp(BlendReport& rep, const toolpath::Path& path, std::size_t k, const Corner& c,
                bool joint_corner) {
  if (!c.eligible || c.blended || path.segments[k].rapid) return;
  if (joint_corner && path.segments[k + 1].rapid) return;
  rep.sharp.push_back({c.v, c.d_in, c.d_out, c.tolerance_mm, 0.5 * c.in_mm, 0.5 * c.out_mm, k});
}

// The corners at the interior vertices of polyline k (none where its body is not blendable);
// whether any of them, or the joint after it, is blended.
bool plan_inner_corners(const toolpath::Path& path, const MachineLimits& limits, std::size_t k,
                        bool body, bool joint_blended, std::vector<Corner>& inner) {
  const auto& pts = std::get<Polyline>(path.segments[k].geometry).points;
  inner.clear();
  bool any = joint_blended;
  if (body) {
    for (std::size_t v = 1; v + 1 < pts.size(); ++v) {
      inner.push_back(plan_corner(pts[v - 1], pts[v], pts[v + 1],
                                  tolerance_mm(path.segments[k], limits),
                                  segment_cap_mm_per_s(path.segments[k], limits),
                                  segment_cap_mm_per_s(path.segments[k], limits), limits));
      any = any || inner.back().blended;
    }
  }
  return any;
}

// The lines and arcs of a polyline whose corners are blended, span by span from `at`.
struct SpanBuilder {
  std::vector<Span>& spans;
  BlendReport& rep;
  Vec3 at;

  void line_to(const Vec3& q) {
    // Two arcs that each take half of a piece meet (to rounding): no line between them.
    const double len = (q - at).norm();
    if (!(len > kMinSpanMm)) return;
    spans.push_back({0.5 * (at + q), q, 1.0, len});
    at = q;
  }

  void arc(const Corner& c) {
    line_to(c.v - c.tangent_mm * c.d_in);
    const Vec3 end = c.v + c.tangent_mm * c.d_out;
    spans.push_back({c.v, end, c.half_cos, c.radius_mm * c.phi_rad});
    at = end;
    ++rep.corners;
    rep.max_deviation_mm =
        std::max(rep.max_deviation_mm, c.radius_mm * (1.0 - c.half_cos) / c.half_cos);
  }
};

// The spans from start as one rational quadratic B-spline: each span a middle control point of
// weight w and its end, double knots between spans at the arc length so far.
NurbsCurve spans_curve(const Vec3& start, const std::vector<Span>& spans) {
  std::vector<Vec3> cp{start};
  std::vector<double> w{1.0};
  std::vector<double> knots{0.0, 0.0, 0.0};
  double u = 0.0;
  for (std::size_t i = 0; i < spans.size(); ++i) {
    cp.push_back(spans[i].mid);
    cp.push_back(spans[i].end);
    w.push_back(spans[i].w);
    w.push_back(1.0);
    u += spans[i].len_mm;
    knots.insert(knots.end(), i + 1 < spans.size() ? 2 : 3, u);
  }
  return NurbsCurve(2, std::move(knots), std::move(cp), std::move(w));
}

}  // namespace

double polyline_corner_speed_mm_per_s(const MachineLimits& limits, double phi_rad,
                                      double curvature_per_mm) {
  if (phi_rad < kMinTurnRad) return std::numeric_limits<double>::infinity();
  const double eps = limits.chord_tolerance_mm, t = limits.period_s;
  const double b = 0.5 * std::sin(0.5 * phi_rad), qa = 0.125 * curvature_per_mm;
  const double step =
      qa > 0.0 && std::isfinite(qa) ? 2.0 * eps / (b + std::sqrt(b * b + 4.0 * qa * eps)) : eps / b;
  const double c = std::cos(0.5 * phi_rad);
  const double junction = c < 1.0 ? std::sqrt(limits.max_accel_mm_per_s2 * eps * c / (1.0 - c))
                                  : std::numeric_limits<double>::infinity();
  const double v = std::min(step / t, junction);
  if (limits.jerk_bound != JerkBound::vector) return v;
  return std::min(v, jump_feed_mm_per_s(limits, phi_rad, 0.0));
}

toolpath::Path blend_corners(const toolpath::Path& path, const MachineLimits& limits,
                             BlendReport* report) {
  toolpath::Path out = path;
  BlendReport rep;
  const std::size_t n = path.segments.size();
  std::vector<char> body(n);
  for (std::size_t k = 0; k < n; ++k) body[k] = blendable_body(path.segments[k], limits) ? 1 : 0;
  const std::vector<Corner> joint = plan_joints(path, limits, body);
  std::vector<Span> spans;
  std::vector<Corner> inner;
  for (std::size_t k = 0; k < n; ++k) {
    if (!std::holds_alternative<Polyline>(path.segments[k].geometry)) continue;
    const auto& pts = std::get<Polyline>(path.segments[k].geometry).points;
    Vec3 start = pts.front();
    if (k > 0 && joint[k - 1].blended) {
      start = joint[k - 1].v + joint[k - 1].tangent_mm * joint[k - 1].d_out;
    }
    const bool any = plan_inner_corners(path, limits, k, body[k] != 0, joint[k].blended, inner);
    auto& geometry = out.segments[k].geometry;
    if (!any) {
      for (const Corner& c : inner) keep_sharp(rep, path, k, c, false);
      keep_sharp(rep, path, k, joint[k], true);
      std::get<Polyline>(geometry).points.front() = start;
      continue;
    }
    spans.clear();
    SpanBuilder build{spans, rep, start};
    for (std::size_t v = 1; v < pts.size(); ++v) {
      const Corner* c = v + 1 < pts.size() ? &inner[v - 1] : &joint[k];
      keep_sharp(rep, path, k, *c, v + 1 == pts.size());
      if (c->blended) {
        build.arc(*c);
      } else {
        build.line_to(pts[v]);
      }
    }
    geometry = spans_curve(start, spans);
  }
  if (report) *report = rep;
  return out;
}

}  // namespace ncd::feed
