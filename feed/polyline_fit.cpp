// Smoothing of dense polylines under G64 P and G64 P Q (docs/planner.md §3d).
//
// CAM systems write curves as runs of short G1 moves (chords within their own tolerance,
// often with coordinates rounded to 1 µm). Walked as a polyline, each vertex is a small corner
// and the limit sampler's discrete-curvature law (§2) sees the rounding noise as curvature:
// a 0.01 mm piece whose ends are rounded to 1 µm turns by up to ~0.2 rad, a "radius" of
// 0.05 mm. Under G64 Q > 0 (LinuxCNC's naive-CAM tolerance; here the smoothing tolerance) such
// runs are replaced by one C² cubic B-spline that lies within Q of the programmed polyline.
//
// 0. Tolerance q: G64 Q > 0 gives q = Q. Without Q (G64 P, or a plain G64 taking the machine's
//    blend_tolerance_mm as P) q = P − ε_c, unless the machine file says fit_dense_runs =
//    false: setpoints lie on the curve (within q of the polyline), a chord between two of them
//    within ε_c of the curve, so every programmed point is passed within P by a chord. G61,
//    G61.1 and an explicit Q0 fit nothing; nor does the default under P ≤ ε_c or G64 P0 (a G64
//    P0 Q > 0 fits to Q, as before the default existed). Q stands for q below.
// 1. Runs (inside one segment: a segment is one feed, spindle and mode; the readers merge
//    consecutive G1 moves of the same feed into one polyline segment). A piece is short when
//    l ≤ max(√(8 R_ref Q), v_cap T), R_ref = 50 mm: a chord of a circle of radius R within a
//    CAM tolerance Q is √(8 R Q) long, so this takes the pieces CAM writes for radii up to
//    50 mm, and every piece shorter than one period's travel (where several vertices fall
//    into one period). Longer moves are the programmer's straight lines and stay exact. A
//    vertex is a real corner when it turns by more than φ_c = 30° both between its own pieces
//    and between the chords to the points λ = 20 Q back and ahead along the polyline: noise of
//    amplitude ≤ Q turns a 0.01 mm piece by up to 2Q/l but the λ-chords by at most 2Q/λ = 0.1
//    rad, while a programmed corner turns both. A vertex turning by more than 90° (a
//    reversal: a curve within Q would need a cusp there) is always a corner. A run is a
//    maximal stretch of at least three
//    short pieces with no corner inside; corners and long moves are left to G64 P (§3a).
// 2. Fit: the run's distinct points P_k at chord-length parameters t_k (so that u is close to
//    arc length, mm) are approximated by a clamped cubic B-spline C(u) = Σ N_{i,3}(u) C_i
//    (Piegl and Tiller, eq. 2.5/3.1) with C_0 = P_first, C_n = P_last (the run ends exactly
//    where the polyline does), uniform knots of about 4 mm to start. The inner control points
//    minimise the discrete least squares (P&T §9.4.1, eq. 9.63)
//        Σ w_j |C(t_j) − Q_j|² + μ Σ_i |C_{i−1} − 2 C_i + C_{i+1}|²
//    over samples Q_j of the polyline (its vertices and points on long pieces, weights w_j =
//    the polyline length they stand for), μ = 1e-6 h_min a regulariser that keeps the banded
//    normal equations (half-bandwidth 3) positive definite when a span holds few samples.
//    They are solved by banded Cholesky: O(samples + spans).
// 3. Proof: d_H(C, polyline) ≤ Q, both ways, from samples and Lipschitz bounds:
//    - curve → polyline: on each span, |C'| ≤ M1 = max |3 (C_{i+1} − C_i) / (u_{i+4} − u_{i+1})|
//      (the first hodograph's control points: C' is their convex combination, P&T eq. 3.4).
//      The span is sampled at steps Δu ≤ 0.2 Q / M1; at each sample d = an upper bound of the
//      distance to the polyline (the distance to nearby pieces: a minimum over fewer pieces
//      can only be larger). The distance to a set is 1-Lipschitz, so between samples a and b
//      every point of C is within (d_a + d_b + M1 Δu) / 2 of the polyline.
//    - polyline → curve: the polyline is sampled at steps δ ≤ 0.2 Q along each piece (vertices
//      included); e = the distance to the nearest curve sample (an upper bound of the distance
//      to C); between two samples every point is within (e_a + e_b + δ) / 2 of C. The search
//      for that sample steps over samples the triangle inequality rules out (their chords to
//      one at distance d add up to less than d − the best so far): the same minimum, faster.
//    Each refit moves every control point (one least-squares system), so every round proves
//    the whole run again; most of the work is the first round's, whose curve is far off.
//    The largest of these bounds is the proven deviation. Spans where a bound exceeds Q get a
//    knot in their middle and the run is refitted (up to 16 rounds, spans not below Q wide).
//    A curve whose parametric speed |C'| falls below 0.5 of its mean at a sample (the mean is
//    the curve's length over the run's chord length: ≈ 1 for clean points, lower when noise
//    lengthens the chords; a dip far below it means the fit folds towards a cusp, which the
//    walker's arc-length correction should not be given) is refused without refinement. A
//    run that still fails is split at the vertex nearest its worst point (or its slowest
//    sample) and each half is fitted on its own; pieces that cannot be fitted stay a polyline.
// 4. Segments: a segment with fitted runs is split into its polyline parts and one NURBS
//    segment per run, in order; each keeps the program segment's feed, mode, tolerances and
//    source line (stop_before only on the first), so that the source line the service reports
//    is the program's. FitReport::source_segment maps the new segments to the program's.
//
// Where: feed moves (G1, not G0) under G64 (PathControl::blend, P > 0) with q > 0, plain polylines
// (no contact normals: the chamfer's roughness law needs them at the vertices). It runs before
// corner blending (corner_blend.cpp), which then rounds the corners left between the polyline
// parts.
#include "feed/polyline_fit.hpp"

#include "feed/limit_sampler_detail.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>

namespace ncd::feed {
namespace {

using toolpath::NurbsCurve;
using toolpath::PathControl;
using toolpath::PathSegment;
using toolpath::Polyline;

constexpr double kRefRadiusMm = 50.0;       // R_ref of the short-piece rule
constexpr double kCornerTurnRad = kPi / 6;  // φ_c, 30°
constexpr double kCoarseChordPerQ = 20.0;   // λ = 20 Q
constexpr std::size_t kMinRunPieces = 3;
constexpr double kInitialSpanMm = 4.0;
constexpr int kMaxRounds = 16;
constexpr int kMaxSplitDepth = 12;
constexpr double kSampleStepPerQ = 0.2;   // Δu M1 ≤ 0.2 Q and δ ≤ 0.2 Q
constexpr double kRoundingMm = 1e-12;     // added to every bound for the rounding of the distances
constexpr double kSkipMarginMm = 1e-9;    // the rounding of the chord sums, many times over
constexpr double kReversalRad = kPi / 2;  // a vertex turning more is always a corner
constexpr double kMinSpeed = 0.5;         // smallest |C'| accepted, over the mean |C'|

double point_piece_mm(const Vec3& x, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double l2 = ab.squaredNorm();
  const double t = l2 > 0.0 ? std::clamp((x - a).dot(ab) / l2, 0.0, 1.0) : 0.0;
  return (x - (a + t * ab)).norm();
}

// The four non-zero cubic basis functions at t on span s (U[s] ≤ t < U[s+1]), P&T A2.2.
std::array<double, 4> basis(const std::vector<double>& U, std::size_t s, double t) {
  std::array<double, 4> n{1.0, 0.0, 0.0, 0.0};
  std::array<double, 4> left{}, right{};
  for (std::size_t j = 1; j <= 3; ++j) {
    left[j] = t - U[s + 1 - j];
    right[j] = U[s + j] - t;
    double saved = 0.0;
    for (std::size_t r = 0; r < j; ++r) {
      const double tmp = n[r] / (right[r + 1] + left[j - r]);
      n[r] = saved + right[r + 1] * tmp;
      saved = left[j - r] * tmp;
    }
    n[j] = saved;
  }
  return n;
}

// Normal equations of the least squares for the inner control points 1 … n−1 (banded,
// half-bandwidth 3), with the end points C_0 and C_n fixed.
struct Normal {
  std::size_t n;  // index of the last control point
  const Vec3 &first, &last;
  std::vector<std::array<double, 4>> a;  // a[i][d] = A(i, i + d), unknown i = control i + 1
  std::vector<Vec3> rhs;

  Normal(std::size_t n_last, const Vec3& c0, const Vec3& cn)
      : n(n_last),
        first(c0),
        last(cn),
        a(n_last - 1, {0, 0, 0, 0}),
        rhs(n_last - 1, Vec3::Zero()) {}

  // Adds w |Σ c_k C_{i_k} − y|².
  void add(const std::size_t* idx, const double* c, std::size_t count, const Vec3& y, double w) {
    Vec3 known = Vec3::Zero();
    for (std::size_t k = 0; k < count; ++k) {
      if (idx[k] == 0) known += c[k] * first;
      if (idx[k] == n) known += c[k] * last;
    }
    const Vec3 target = y - known;
    for (std::size_t k = 0; k < count; ++k) {
      if (idx[k] == 0 || idx[k] == n || c[k] == 0.0) continue;
      const std::size_t i = idx[k] - 1;
      rhs[i] += w * c[k] * target;
      for (std::size_t l = 0; l < count; ++l) {
        if (idx[l] == 0 || idx[l] == n || idx[l] < idx[k]) continue;
        const std::size_t d = idx[l] - idx[k];  // ≤ 3: the indices are consecutive
        if (d < 4) a[i][d] += w * c[k] * c[l];
      }
    }
  }

  // Banded Cholesky A = L Lᵀ, then the two triangular solves; false if A is not positive
  // definite (it always is with μ > 0; kept as a guard).
  bool solve(std::vector<Vec3>& x) {
    const std::size_t m = a.size();
    std::vector<std::array<double, 4>> l(m, {0, 0, 0, 0});  // l[i][d] = L(i, i − d)
    for (std::size_t i = 0; i < m; ++i) {
      for (std::size_t j = i >= 3 ? i - 3 : 0; j <= i; ++j) {
        double s = a[j][i - j];
        for (std::size_t k = (i >= 3 ? i - 3 : 0); k < j; ++k) s -= l[i][i - k] * l[j][j - k];
        if (j == i) {
          if (!(s > 0.0)) return false;
          l[i][0] = std::sqrt(s);
        } else {
          l[i][i - j] = s / l[j][0];
        }
      }
    }
    x.assign(m, Vec3::Zero());
    for (std::size_t i = 0; i < m; ++i) {
      Vec3 s = rhs[i];
      for (std::size_t k = (i >= 3 ? i - 3 : 0); k < i; ++k) s -= l[i][i - k] * x[k];
      x[i] = s / l[i][0];
    }
    for (std::size_t i = m; i-- > 0;) {
      Vec3 s = x[i];
      for (std::size_t k = i + 1; k < std::min(m, i + 4); ++k) s -= l[k][k - i] * x[k];
      x[i] = s / l[i][0];
    }
    return true;
  }
};

struct Run {
  std::vector<Vec3> p;    // distinct points
  std::vector<double> t;  // chord length at each, mm
};

// Least-squares control points for the breakpoints `breaks` (0 … L); empty on failure.
std::vector<Vec3> least_squares(const Run& run, const std::vector<double>& breaks) {
  const std::size_t spans = breaks.size() - 1;
  std::vector<double> U(4, breaks.front());
  U.insert(U.end(), breaks.begin() + 1, breaks.end() - 1);
  U.insert(U.end(), 4, breaks.back());
  const std::size_t n = spans + 2;  // control points 0 … spans + 2
  double h_min = breaks.back();
  for (std::size_t j = 0; j < spans; ++j) h_min = std::min(h_min, breaks[j + 1] - breaks[j]);
  Normal ne(n, run.p.front(), run.p.back());
  // Samples of the polyline at spacing ≤ h_min / 8 (vertices included), weighted by the length
  // each stands for.
  const double spacing = h_min / 8.0;
  std::vector<std::pair<double, Vec3>> samples;
  for (std::size_t k = 0; k + 1 < run.p.size(); ++k) {
    const double len = run.t[k + 1] - run.t[k];
    const auto m = static_cast<std::size_t>(std::max(1.0, std::ceil(len / spacing)));
    for (std::size_t q = 0; q < m; ++q) {
      const double f = static_cast<double>(q) / static_cast<double>(m);
      samples.emplace_back(run.t[k] + f * len, run.p[k] + f * (run.p[k + 1] - run.p[k]));
    }
  }
  samples.emplace_back(run.t.back(), run.p.back());
  std::size_t s = 3;
  for (std::size_t j = 0; j < samples.size(); ++j) {
    const double t = samples[j].first;
    const double prev = j > 0 ? samples[j - 1].first : t;
    const double next = j + 1 < samples.size() ? samples[j + 1].first : t;
    const double w = 0.5 * (next - prev);
    while (s < n && t >= U[s + 1]) ++s;
    const auto b = basis(U, s, t);
    const std::size_t idx[4] = {s - 3, s - 2, s - 1, s};
    ne.add(idx, b.data(), 4, samples[j].second, w);
  }
  const double mu = 1e-6 * h_min;
  const double c[3] = {1.0, -2.0, 1.0};
  for (std::size_t i = 1; i < n; ++i) {
    const std::size_t idx[3] = {i - 1, i, i + 1};
    ne.add(idx, c, 3, Vec3::Zero(), mu);
  }
  std::vector<Vec3> inner;
  if (!ne.solve(inner)) return {};
  std::vector<Vec3> cp{run.p.front()};
  cp.insert(cp.end(), inner.begin(), inner.end());
  cp.push_back(run.p.back());
  return cp;
}

std::vector<double> knots_of(const std::vector<double>& breaks) {
  std::vector<double> U(4, breaks.front());
  U.insert(U.end(), breaks.begin() + 1, breaks.end() - 1);
  U.insert(U.end(), 4, breaks.back());
  return U;
}

struct Check {
  double bound_mm = 0.0;  // the proven two-sided deviation
  // The smallest |C'| at the samples, and the mean: the curve's length (through its samples)
  // over the run's chord length.
  double min_speed = std::numeric_limits<double>::infinity();
  double mean_speed = 1.0;
  double min_speed_at_mm = 0.0;
  std::vector<char> span_fail;  // spans where a bound exceeds the tolerance
  double worst_at_mm = 0.0;     // chord-length position of the largest bound
};

// The proof of step 3 (see the top of the file).
Check check(const NurbsCurve& c, const std::vector<double>& breaks, const Run& run, double tol) {
  Check out;
  const std::size_t spans = breaks.size() - 1;
  out.span_fail.assign(spans, 0);
  const auto& cp = c.points();
  const auto& U = c.knots();
  const auto note = [&](double bound, std::size_t span, double at) {
    bound += kRoundingMm;
    if (bound > tol) out.span_fail[span] = 1;
    if (bound > out.bound_mm) {
      out.bound_mm = bound;
      out.worst_at_mm = at;
    }
  };
  const std::size_t pieces = run.p.size() - 1;
  // Distance (upper bound) from x at parameter u to the polyline: the piece holding u and its
  // neighbours as long as they can still be nearer (by chord-length parameter), with a margin.
  std::size_t k0 = 0;
  const auto to_polyline = [&](const Vec3& x, double u) {
    while (k0 + 1 < pieces && run.t[k0 + 1] <= u) ++k0;
    double best = point_piece_mm(x, run.p[k0], run.p[k0 + 1]);
    for (std::size_t k = k0 + 1; k < pieces && run.t[k] - u <= best + 2.0 * tol; ++k) {
      best = std::min(best, point_piece_mm(x, run.p[k], run.p[k + 1]));
    }
    for (std::size_t k = k0; k-- > 0 && u - run.t[k + 1] <= best + 2.0 * tol;) {
      best = std::min(best, point_piece_mm(x, run.p[k], run.p[k + 1]));
    }
    return best;
  };
  struct Sample {
    double u;
    Vec3 p;
    std::size_t span;
  };
  std::vector<Sample> cs;
  for (std::size_t j = 0; j < spans; ++j) {
    double m1 = 0.0;  // first hodograph's control points of span j: C_j … C_{j+3}
    for (std::size_t i = j; i < j + 3; ++i) {
      m1 = std::max(m1, 3.0 * (cp[i + 1] - cp[i]).norm() / (U[i + 4] - U[i + 1]));
    }
    const double width = breaks[j + 1] - breaks[j];
    const double steps = std::max(1.0, std::ceil(width * m1 / (kSampleStepPerQ * tol)));
    const auto n = static_cast<std::size_t>(steps);
    const double du = width / steps;
    double d_prev = 0.0;
    for (std::size_t q = 0; q <= n; ++q) {
      const double u = q == n ? breaks[j + 1] : breaks[j] + du * static_cast<double>(q);
      const toolpath::CurvePoint e = c.eval(u);
      const Vec3& x = e.p;
      if (e.d1.norm() < out.min_speed) {
        out.min_speed = e.d1.norm();
        out.min_speed_at_mm = u;
      }
      const double d = to_polyline(x, u);
      if (q > 0) note(0.5 * (d_prev + d + m1 * du), j, u);
      if (q > 0 || j == 0) cs.push_back({u, x, j});
      d_prev = d;
    }
  }
  // along[i]: the length of the chords from the first curve sample to sample i.
  std::vector<double> along(cs.size(), 0.0);
  double curve_mm = 0.0;
  for (std::size_t i = 1; i < cs.size(); ++i) {
    curve_mm += (cs[i].p - cs[i - 1].p).norm();
    along[i] = curve_mm;
  }
  out.mean_speed = curve_mm / (breaks.back() - breaks.front());
  // Polyline → curve: distance to the nearest curve sample around the parameter. A sample whose
  // chords to one at distance d add up to at most d − best (less a margin for the rounding of
  // the sums) is no nearer than best (triangle inequality): the scan steps over it, which leaves
  // the minimum, its span and where the scan stops as they were (it stops at the first sample
  // too far in parameter, and parameters only grow away from y's).
  std::size_t i0 = 0;
  const auto to_curve = [&](const Vec3& y, double t, std::size_t& span) {
    while (i0 + 1 < cs.size() && cs[i0 + 1].u <= t) ++i0;
    double best = (y - cs[i0].p).norm();
    span = cs[i0].span;
    for (std::size_t i = i0 + 1; i < cs.size() && cs[i].u - t <= best + tol; ++i) {
      const double d = (y - cs[i].p).norm();
      if (d < best) best = d, span = cs[i].span;
      const double reach = along[i] + (d - best - kSkipMarginMm);
      while (i + 1 < cs.size() && along[i + 1] <= reach) ++i;
    }
    for (std::size_t i = i0; i-- > 0 && t - cs[i].u <= best + tol;) {
      const double d = (y - cs[i].p).norm();
      if (d < best) best = d, span = cs[i].span;
      const double reach = along[i] - (d - best - kSkipMarginMm);
      while (i > 0 && along[i - 1] >= reach) --i;
    }
    return best;
  };
  for (std::size_t k = 0; k < pieces; ++k) {
    const double len = run.t[k + 1] - run.t[k];
    const double steps = std::max(1.0, std::ceil(len / (kSampleStepPerQ * tol)));
    const auto n = static_cast<std::size_t>(steps);
    double e_prev = 0.0;
    std::size_t span_prev = 0;
    for (std::size_t q = 0; q <= n; ++q) {
      const double f = q == n ? 1.0 : static_cast<double>(q) / steps;
      const Vec3 y = q == n ? run.p[k + 1] : run.p[k] + f * (run.p[k + 1] - run.p[k]);
      std::size_t span = 0;
      const double e = to_curve(y, run.t[k] + f * len, span);
      if (q > 0) {
        const double b = 0.5 * (e_prev + e + len / steps);
        note(b, e > e_prev ? span : span_prev, run.t[k] + f * len);
      }
      e_prev = e;
      span_prev = span;
    }
  }
  return out;
}

struct Attempt {
  std::optional<FittedRun> run;
  double worst_at_mm = 0.0;  // where the last check failed worst
};

Attempt fit_run(const std::vector<Vec3>& points, double tol) {
  Attempt out;
  Run run;
  for (const Vec3& p : points) {
    if (!p.allFinite()) return out;
    if (run.p.empty() || (p - run.p.back()).norm() > 0.0) {
      run.t.push_back(run.p.empty() ? 0.0 : run.t.back() + (p - run.p.back()).norm());
      run.p.push_back(p);
    }
  }
  if (run.p.size() < 2 || !(tol > 0.0) || !std::isfinite(tol)) return out;
  const double length = run.t.back();
  const double h_min = std::max(tol, 1e-9 * length);
  const double spans0 = std::max(1.0, std::ceil(length / kInitialSpanMm));
  std::vector<double> breaks;
  for (double j = 0.0; j <= spans0; j += 1.0)
    breaks.push_back(j == spans0 ? length : length * j / spans0);
  for (int round = 0; round < kMaxRounds; ++round) {
    std::vector<Vec3> cp = least_squares(run, breaks);
    if (cp.empty()) return out;
    NurbsCurve curve(3, knots_of(breaks), std::move(cp));
    const Check c = check(curve, breaks, run, tol);
    out.worst_at_mm = c.worst_at_mm;
    // A near-cusp: not refined (it would follow it closer).
    if (c.min_speed < kMinSpeed * c.mean_speed) {
      out.worst_at_mm = c.min_speed_at_mm;
      return out;
    }
    if (c.bound_mm <= tol) {
      out.run = FittedRun{std::move(curve), c.bound_mm};
      return out;
    }
    std::vector<double> refined{breaks.front()};
    bool inserted = false;
    for (std::size_t j = 0; j + 1 < breaks.size(); ++j) {
      const double w = breaks[j + 1] - breaks[j];
      if (c.span_fail[j] && w >= 2.0 * h_min) {
        refined.push_back(breaks[j] + 0.5 * w);
        inserted = true;
      }
      refined.push_back(breaks[j + 1]);
    }
    if (!inserted) return out;
    breaks = std::move(refined);
  }
  return out;
}

// The fit's tolerance for segment s (step 0 at the top of the file); 0: nothing is fitted.
double smoothing_mm(const PathSegment& s, const MachineLimits& l) {
  if (s.path_control != PathControl::blend) return 0.0;  // G61, G61.1
  if (s.smoothing_tolerance_mm) {  // G64 Q: the program's own tolerance (Q0: no fit), any P
    const double q = *s.smoothing_tolerance_mm;
    return std::isfinite(q) && q > 0.0 ? q : 0.0;
  }
  // The machine's default fit, within P less the chord tolerance; none under G64 P0.
  if (!l.fit_dense_runs || sampler_detail::corner_mode(s, l) != PathControl::blend) return 0.0;
  const double q = s.blend_tolerance_mm.value_or(l.blend_tolerance_mm) - l.chord_tolerance_mm;
  return std::isfinite(q) && q > 0.0 ? q : 0.0;
}

bool eligible(const PathSegment& s, const MachineLimits& l) {
  const auto* line = std::get_if<Polyline>(&s.geometry);
  return line && line->normals.empty() && line->points.size() >= kMinRunPieces + 1 && !s.rapid &&
         smoothing_mm(s, l) > 0.0;
}

double angle_between_rad(const Vec3& a, const Vec3& b) {
  const double na = a.norm(), nb = b.norm();
  if (!(na > 0.0 && nb > 0.0)) return 0.0;
  return std::acos(std::clamp(a.dot(b) / (na * nb), -1.0, 1.0));
}

struct Block {
  std::size_t a, b;  // distinct-point indices
  std::optional<FittedRun> fit;
};

// Fits distinct points a … b, splitting where the fit is refused (step 3).
void fit_or_split(const std::vector<Vec3>& p, const std::vector<double>& t, std::size_t a,
                  std::size_t b, double tol, int depth, std::vector<Block>& out, FitReport& rep) {
  if (b - a < kMinRunPieces) {
    out.push_back({a, b, std::nullopt});
    return;
  }
  Attempt at = fit_run(std::vector<Vec3>(p.begin() + static_cast<std::ptrdiff_t>(a),
                                         p.begin() + static_cast<std::ptrdiff_t>(b) + 1),
                       tol);
  if (at.run) {
    out.push_back({a, b, std::move(at.run)});
    return;
  }
  if (depth >= kMaxSplitDepth) {
    ++rep.refused;
    out.push_back({a, b, std::nullopt});
    return;
  }
  const double where = t[a] + at.worst_at_mm;
  std::size_t v = a + 1;
  for (std::size_t k = a + 1; k < b; ++k) {
    if (std::abs(t[k] - where) < std::abs(t[v] - where)) v = k;
  }
  fit_or_split(p, t, a, v, tol, depth + 1, out, rep);
  fit_or_split(p, t, v, b, tol, depth + 1, out, rep);
}

// A run's distinct points (a zero-length move is skipped), their indices in the polyline, and
// their arc length from its start.
struct Distinct {
  std::vector<Vec3> p;
  std::vector<std::size_t> orig;
  std::vector<double> t;
};

Distinct distinct_points(const std::vector<Vec3>& pts) {
  Distinct d;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (d.p.empty() || (pts[i] - d.p.back()).norm() > 0.0) {
      d.t.push_back(d.p.empty() ? 0.0 : d.t.back() + (pts[i] - d.p.back()).norm());
      d.p.push_back(pts[i]);
      d.orig.push_back(i);
    }
  }
  return d;
}

// corner[v]: a real corner at distinct vertex v (1 … m − 1): a reversal, or a turn above
// kCornerTurnRad both at the vertex and over the chord of λ on each side.
std::vector<char> find_corners(const Distinct& d, double lambda) {
  const std::vector<Vec3>& p = d.p;
  const std::vector<double>& t = d.t;
  const std::size_t m = p.size() - 1;
  std::vector<char> corner(m + 1, 0);
  std::size_t back = 0, ahead = 1;
  for (std::size_t v = 1; v < m; ++v) {
    const double fine = angle_between_rad(p[v] - p[v - 1], p[v + 1] - p[v]);
    if (fine <= kCornerTurnRad) continue;
    while (back + 1 < v && t[v] - t[back + 1] >= lambda) ++back;
    ahead = std::max(ahead, v + 1);
    while (ahead < m && t[ahead] - t[v] < lambda) ++ahead;
    corner[v] =
        fine > kReversalRad || angle_between_rad(p[v] - p[back], p[ahead] - p[v]) > kCornerTurnRad
            ? 1
            : 0;
  }
  return corner;
}

// The blocks of the run: each long piece alone, each stretch of short pieces between long
// pieces and real corners fitted (or split where the fit is refused).
std::vector<Block> fit_blocks(const Distinct& d, const std::vector<char>& corner, double short_mm,
                              double q, FitReport& rep) {
  const std::size_t m = d.p.size() - 1;
  std::vector<Block> blocks;
  std::size_t a = 0;  // start of the current stretch of short pieces
  const auto flush = [&](std::size_t b) {
    if (b > a) fit_or_split(d.p, d.t, a, b, q, 0, blocks, rep);
  };
  for (std::size_t i = 0; i < m; ++i) {
    const bool is_short = d.t[i + 1] - d.t[i] <= short_mm;
    if (!is_short) {
      flush(i);
      blocks.push_back({i, i + 1, std::nullopt});
      a = i + 1;
    } else if (i > a && corner[i]) {
      flush(i);
      a = i;
    }
  }
  flush(m);
  return blocks;
}

// Output of segment k's blocks: polyline parts (original points, duplicates kept) and one
// NURBS per fitted run; the segment's stop_before (and rotary indexes) stay with the first.
void emit_blocks(const PathSegment& seg, std::size_t k, const Distinct& d,
                 std::vector<Block>& blocks, toolpath::Path& out, FitReport& rep) {
  const auto& pts = std::get<Polyline>(seg.geometry).points;
  const std::size_t m = d.p.size() - 1;
  bool first = true;
  std::vector<Vec3> part;
  const auto emit = [&](decltype(PathSegment::geometry) g) {
    PathSegment s = seg;
    s.geometry = std::move(g);
    s.stop_before = first && seg.stop_before;
    if (!first) s.indexes_before.clear();  // the rotary indexes too (docs/planner.md §3g)
    first = false;
    out.segments.push_back(std::move(s));
    rep.source_segment.push_back(k);
  };
  const auto flush_part = [&] {
    if (part.size() >= 2) emit(Polyline{std::move(part), {}});
    part.clear();
  };
  for (std::size_t j = 0; j < blocks.size(); ++j) {
    Block& b = blocks[j];
    if (b.fit) {
      flush_part();
      ++rep.runs;
      rep.spans += b.fit->curve.breakpoints().size() - 1;
      rep.points += b.b - b.a + 1;
      rep.max_deviation_mm = std::max(rep.max_deviation_mm, b.fit->deviation_mm);
      emit(std::move(b.fit->curve));
      continue;
    }
    const std::size_t from = part.empty() ? d.orig[b.a] : d.orig[b.a] + 1;
    const std::size_t to = b.b == m ? pts.size() - 1 : d.orig[b.b];
    for (std::size_t i = from; i <= to; ++i) part.push_back(pts[i]);
  }
  flush_part();
}

}  // namespace

std::optional<FittedRun> fit_polyline_run(const std::vector<Vec3>& points, double tolerance_mm) {
  return fit_run(points, tolerance_mm).run;
}

toolpath::Path fit_polylines(const toolpath::Path& path, const MachineLimits& limits,
                             FitReport* report) {
  toolpath::Path out;
  out.source = path.source;
  out.chamfer = path.chamfer;
  out.rotary_axis = path.rotary_axis;
  out.rotary_start_deg = path.rotary_start_deg;
  out.indexes_at_end = path.indexes_at_end;
  FitReport rep;
  for (std::size_t k = 0; k < path.segments.size(); ++k) {
    const PathSegment& seg = path.segments[k];
    const auto keep = [&] {
      out.segments.push_back(seg);
      rep.source_segment.push_back(k);
    };
    if (!eligible(seg, limits)) {
      keep();
      continue;
    }
    const double q = smoothing_mm(seg, limits);
    const Distinct d = distinct_points(std::get<Polyline>(seg.geometry).points);
    const std::size_t m = d.p.size() - 1;  // pieces
    if (m < kMinRunPieces) {
      keep();
      continue;
    }
    const double short_mm = std::max(std::sqrt(8.0 * kRefRadiusMm * q),
                                     segment_cap_mm_per_s(seg, limits) * limits.period_s);
    const std::vector<char> corner = find_corners(d, kCoarseChordPerQ * q);
    std::vector<Block> blocks = fit_blocks(d, corner, short_mm, q, rep);
    if (std::none_of(blocks.begin(), blocks.end(),
                     [](const Block& b) { return b.fit.has_value(); })) {
      keep();
      continue;
    }
    emit_blocks(seg, k, d, blocks, out, rep);
  }
  if (report) *report = std::move(rep);
  return out;
}

}  // namespace ncd::feed
