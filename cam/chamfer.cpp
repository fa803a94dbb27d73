// Constant-width chamfer of a drilled hole in a pipe: paper 000 (Sato, Sato, Maekawa, CAD 2016)
// sections 2–4, extended to any drilled hole (inclined, eccentric, cone pipes). Conventions,
// corrections and decisions: docs/chamfer.md.
//
// Geometry. Everything is computed in the drill frame: the drill (radius r) runs along z, the
// pipe axis is the line p0 + s a with a = (0, cos γ, sin γ) and p0 = (−e, 0, 0), γ the
// inclination of the drill from the pipe's normal plane and e the eccentricity (the relative
// position of two lines is their angle and distance; the tilt τ and azimuth φ of ChamferSpec only
// say where this sits in the pipe frame, see DrillPlacement). The pipe surface is the quadric
// f(x) = |w|² − (w·a)² − ρ², w = x − p0, ρ = R_s + (w·a) tan ψ (cylinder for ψ = 0).
//
// Edge curve by numerical intersection. For a hole that pierces the wall every generator
// D(θ, z) = (r cos θ, r sin θ, z) of the drill (eq. 1) meets the surface twice, so the edge is
// a graph over the angle about the drill axis: C(θ) = (r cos θ, r sin θ, z(θ)) with
// g(θ, z) = f(D(θ, z)) = 0, z the upper (larger) or lower root. g is quadratic in z: its stable
// root is the start, polished by Newton on the distance-like |w⊥| − ρ to machine precision.
// The derivatives come from implicit differentiation, with the analytic gradient and the
// constant Hessian 2(I − (1 + tan²ψ) a aᵀ) of f:
//
//     z' = −g_θ / g_z,   z'' = −(g_θθ + 2 g_θz z' + g_zz z'²) / g_z,
//
// so t, b, n, κ and k = κ n (eqs. 6–10) are exact to rounding, not finite differences, and the
// loop closes exactly (C(2π) = C(0)). With γ = e = ψ = 0 this is eq. (4)/(5) itself
// (C(θ) = (r cos θ, r sin θ, σ sqrt(R_s² − r² cos² θ)), σ = +1 upper, −1 lower), which is kept
// (EdgeCurve::ClosedForm) as the reference. The pipe normal N_p is ∇f/|∇f| (eq. 16), which
// points away from the pipe axis. Validation checks the discriminant of g over θ (a trigonometric
// polynomial of degree 2, its minima found by a scan and Newton, chamfer_spec.cpp): a generator
// that misses or grazes a wall surface means the drill does not pierce it completely, and is
// refused with its θ.
//
// Downstream, as in the paper. In the normal plane T at x_p = C(θ) two unit tangents span the
// wedge to be chamfered (N_H = (cos θ, sin θ, 0), eq. 12):
//
//     t1 = s1 (N_H × t)   along the hole surface, into the wall                 eq. (14)
//     t2 = s2 (t × N_p)   along the pipe surface, away from the hole            eq. (15)
//
//           t1 ▲
//              │      wall
//              │   A
//              │  ╱ ╲  ← chamfer of width W = |AB|
//   hole       │ ╱   ╲
//              x_p ───B──────► t2        the ball (centre CL, radius R_B) sits on −e,
//            ╱                           δ deep past x_p:  CL = x_p − (R_B − δ) e   eq. (19)
//        −e ↙  CL
//
// with e = (t1 + α t2)/|t1 + α t2| (eq. 18); α = 1 bisects the wedge. A and B are where the
// sphere |x − CL| = R_B meets the lines x_p + ζ t1 and x_p + η t2 (eqs. 22–25, the + roots).
// δ solves G(δ) = |ζ t1 − η t2|² − W² = 0 (eq. 27) (in closed form at α = 1,
// delta_at_bisector) by Newton from δ = W/4, safeguarded by the
// bracket δ ∈ (0, 2 R_B) on which G(0) = −W² < 0; no root means W is wider than the wedge and
// the ball allow. The width exists only for e·t1 > 0 and e·t2 > 0, i.e. α ∈ (−c, −1/c) with
// c = t1·t2.
//
// Interference (section 4), with the machine's tool axis +z along the drill axis (or the
// spindle direction ChamferSpec::tool_axis gives, for the global check only). Local:
// R_B ≤ 1/|k_e|, k_e = (k·e) e (eqs. 36, 37). Global: the cutter vector −e must not point into
// the hole surface: −e_z ≤ 0 on inner/upper, ≥ 0 on outer/upper, opposite on lower edges
// (eq. 40, with the typo r < R_I corrected), which bounds α as eq. (41) does. Where a check
// fails the θ ranges and the reason are reported (interference_reasons), never clamped. Rod: on an
// inner edge the rod passes through the hole, so the CL must stay within the cylinder of radius R_R
// = min(r − R_B sin β, r − R_od) about the drill axis (eq. 42). Algorithm 1 finds the smallest α ≥
// 1 for which it does. The paper's F(α) of eq. (46) compares |x_p − x_R| with R_B − δ, x_R being
// where the line x_p + u e meets that cylinder; since CL lies on the same line, F has the sign of
// F̃(α) = |CL_xy| − R_R, which we use instead: it is exact (no line–ellipse Newton, no degenerate
// planes c = 0 at θ = 0, π/2, π, 3π/2 to special-case) and it is the very quantity the output is
// checked on. δ is re-solved for every α (from δ at the current α along dδ/dα; the path starts
// at α extrapolated from its two previous points). F̃ is bracketed on α ∈ [1, min(eq. 41, −1/c)] and
// solved by Newton on F̃ + ε_α/2 (dF̃/dα by implicit differentiation of eq. 27, bisection where a
// step leaves the bracket), which stops with F̃ ∈ [−ε_α, 0]: the α returned is on the safe side. A θ
// where no admissible α clears the rod is reported, never hidden.
//
// Segmentation (eqs. 28–34). From θ = 0, N pieces of equal arc length: the speed |C'| is smooth
// and periodic, so its Fourier series (core/periodic_series.hpp, 128 samples for the paper's
// hole) gives the length and, by Halley's iteration on its antiderivative, each θ_k; composite
// Gauss–Legendre with Newton on eq. 31 where the series does not converge (a nearly grazing
// drill) and as the tests' reference. Each piece is split at its parametric midpoint
// while its chordal deviation exceeds ε. Eq. (34) samples the deviation only at the midpoint;
// we measure the true maximum (Newton on d/dθ of the distance to the chord, started at the
// midpoint), so every piece is within ε, not only its midpoint; the split decision stops that
// Newton once it is certain (exceeds_tolerance), with the same points. The cutter locations are
// evaluated at those θ.
#include "cam/chamfer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "cam/chamfer_detail.hpp"
#include "core/error.hpp"
#include "core/number_text.hpp"
#include "core/periodic_series.hpp"
#include "core/quadrature.hpp"

namespace ncd::toolpath {

using namespace chamfer_detail;

namespace {

constexpr int kMaxNewton = 100;
constexpr int kMaxAlphaIterations = 200;
constexpr double kAlphaTolerance = 1e-13;      // relative width of the final α bracket
constexpr double kDeltaNewtonStepMm = 1e-9;    // last Newton step of G(δ) = 0 (quadratic)
constexpr double kRodToleranceMm = 1e-12;      // ε_α of Algorithm 1, on |CL_xy| − R_R
constexpr double kAlphaMargin = 1e-9;          // keep α strictly inside the admissible range
constexpr double kMaxAlphaSearch = 1e6;        // where both bounds are infinite (c = 0)
constexpr int kArcLengthPanels = 64;           // composite GL10 over [0, 2π], doubled until
constexpr int kMaxArcDoublings = 10;           // the total changes by less than kArcTolerance
constexpr double kArcTolerance = 1e-14;        // (relative)
constexpr double kMinSplitTheta = 1e-9;        // a split below this cannot reach ε
constexpr double kSeriesTolerance = 1e-14;     // Fourier series of |C'|: coefficients left out,
constexpr int kSeriesMinSamples = 64;          // relative to the mean speed; samples from 64 to
constexpr int kSeriesMaxSamples = 4096;        // 4096, beyond which quadrature takes over
constexpr double kSeriesNewtonStepRad = 1e-9;  // last Halley step on the series (cubic)
constexpr double kChordNewtonStepRad = 1e-9;   // last Newton step of the chordal deviation

// Positive root of ζ² + 2 q a ζ + δ² − 2 δ R_B = 0 (eqs. 23, 25), q = R_B − δ.
double plus_root(double q, double a, double delta, double ball) {
  const double disc = q * q * a * a - (delta * delta - 2.0 * delta * ball);
  return -q * a + std::sqrt(std::max(disc, 0.0));
}

}  // namespace

ChamferModel::ChamferModel(const ChamferSpec& spec)
    : spec_(spec),
      placement_(drill_placement(spec)),
      surface_(pipe_surface(spec, spec.pipe_radius_mm)) {
  validate(spec_);
  const bool upper = spec_.side == Side::Upper;
  const bool inner = spec_.edge == Edge::Inner;
  sign_z_ = upper ? 1.0 : -1.0;
  sign_t1_ = (inner == upper) ? 1.0 : -1.0;
  sign_t2_ = upper ? 1.0 : -1.0;
  rod_limit_mm_ = rod_limit();
}

ChamferModel::Jet ChamferModel::jet(double theta) const {
  const double r = spec_.drill_radius_mm;
  const double c = std::cos(theta), s = std::sin(theta);
  if (spec_.edge_curve == EdgeCurve::ClosedForm) {  // eqs. (4), (5)
    const double rs = spec_.pipe_radius_mm;
    const double h = std::sqrt(rs * rs - r * r * c * c);
    const double h1 = r * r * c * s / h;                        // dh/dθ
    const double h2 = (r * r * (c * c - s * s) - h1 * h1) / h;  // from (h h')' = r² cos 2θ
    return {
        {r * c, r * s, sign_z_ * h}, {-r * s, r * c, sign_z_ * h1}, {-r * c, -r * s, sign_z_ * h2}};
  }
  // Numerical intersection: the root along the generator, then implicit differentiation.
  const double z = *generator_root(surface_, r, c, s, spec_.side == Side::Upper);
  const Vec3 x(r * c, r * s, z);
  const Vec3 x_theta(-r * s, r * c, 0.0), x_theta2(-r * c, -r * s, 0.0);
  const Vec3 grad = surface_.gradient(x);
  const Vec3& a = surface_.axis_direction;
  const double h = 1.0 + surface_.slope * surface_.slope;  // Hessian 2(I − h a aᵀ)
  const double a_theta = a.dot(x_theta);
  const double g_z = grad.z(), g_t = grad.dot(x_theta);
  const double g_zz = 2.0 * (1.0 - h * a.z() * a.z());
  const double g_tz = -2.0 * h * a_theta * a.z();
  const double g_tt = 2.0 * (x_theta.squaredNorm() - h * a_theta * a_theta) + grad.dot(x_theta2);
  const double z1 = -g_t / g_z;
  const double z2 = -(g_tt + 2.0 * g_tz * z1 + g_zz * z1 * z1) / g_z;
  return {x, {x_theta.x(), x_theta.y(), z1}, {x_theta2.x(), x_theta2.y(), z2}};
}

Vec3 ChamferModel::point(double theta) const {
  return jet(theta).c;
}

Vec3 ChamferModel::derivative(double theta) const {
  return jet(theta).d1;
}

Vec3 ChamferModel::second_derivative(double theta) const {
  return jet(theta).d2;
}

double ChamferModel::speed(double theta) const {
  if (spec_.edge_curve == EdgeCurve::ClosedForm) return derivative(theta).norm();
  // jet()'s first derivative alone (the same operations, so the same value), without C''.
  const double r = spec_.drill_radius_mm;
  const double c = std::cos(theta), s = std::sin(theta);
  const double z = *generator_root(surface_, r, c, s, spec_.side == Side::Upper);
  const Vec3 x_theta(-r * s, r * c, 0.0);
  const Vec3 grad = surface_.gradient(Vec3(r * c, r * s, z));
  const double z1 = -grad.dot(x_theta) / grad.z();
  return Vec3(x_theta.x(), x_theta.y(), z1).norm();
}

EdgeFrame ChamferModel::frame(double theta) const {
  return frame(theta, jet(theta));
}

EdgeFrame ChamferModel::frame(double theta, const Jet& j) const {
  const Vec3 &d1 = j.d1, &d2 = j.d2;
  EdgeFrame f;
  f.theta_rad = theta;
  f.xp = j.c;
  const double v = d1.norm();
  f.t = d1 / v;
  f.k = d1.cross(d2).cross(d1) / (v * v * v * v);  // κ n = (C' × C'') × C' / |C'|⁴
  const Vec3 n_hole(j.c.x() / spec_.drill_radius_mm, j.c.y() / spec_.drill_radius_mm,
                    0.0);  // (cos θ, sin θ, 0), eq. (12)
  const Vec3 n_pipe = spec_.edge_curve == EdgeCurve::ClosedForm
                          ? Vec3(f.xp.x(), 0.0, f.xp.z()) / spec_.pipe_radius_mm  // eq. (17)
                          : surface_.gradient(f.xp).normalized();  // eq. (16), away from the axis
  f.t1 = sign_t1_ * n_hole.cross(f.t);
  f.t2 = sign_t2_ * f.t.cross(n_pipe);
  f.c = f.t1.dot(f.t2);
  return f;
}

AlphaRange ChamferModel::alpha_range(const EdgeFrame& f) const {
  // Width exists: e·t1 ∝ 1 + α c > 0 and e·t2 ∝ c + α > 0.
  AlphaRange range{std::max(0.0, -f.c), f.c < 0.0 ? -1.0 / f.c : kInf};
  // Global check: s1 (t1 + α t2)_z ≥ 0 keeps −e_z on the safe side (eq. 40, 41).
  const double g1 = sign_t1_ * f.t1.z(), g2 = sign_t1_ * f.t2.z();
  if (g2 < 0.0) range.hi = std::min(range.hi, g1 / -g2);
  return range;
}

double ChamferModel::max_width(const EdgeFrame& f, double alpha) const {
  const Vec3 e = (f.t1 + alpha * f.t2).normalized();
  const double a = e.dot(f.t1), b = e.dot(f.t2);
  // At δ = 2 R_B: ζ = 2 R_B a, η = 2 R_B b.
  return 2.0 * spec_.ball_radius_mm * std::sqrt(std::max(0.0, a * a + b * b - 2.0 * a * b * f.c));
}

std::optional<double> ChamferModel::solve_delta(const EdgeFrame& f, double alpha,
                                                std::optional<double> guess_mm) const {
  const double rb = spec_.ball_radius_mm, w = spec_.width_mm;
  const Vec3 e = (f.t1 + alpha * f.t2).normalized();
  const double a = e.dot(f.t1), b = e.dot(f.t2), c = f.c;
  // max_width(f, α), from the same a and b.
  const double widest = 2.0 * rb * std::sqrt(std::max(0.0, a * a + b * b - 2.0 * a * b * c));
  if (!(a > 0.0 && b > 0.0) || widest <= w) return std::nullopt;
  // G(δ) and G'(δ) from eqs. (23), (25), (27); ζ' = (aζ + q)/(ζ + q a), q = R_B − δ.
  auto g_and_slope = [&](double delta, double& slope) {
    const double q = rb - delta;
    const double zeta = plus_root(q, a, delta, rb), eta = plus_root(q, b, delta, rb);
    const double dzeta = (a * zeta + q) / (zeta + q * a);
    const double deta = (b * eta + q) / (eta + q * b);
    slope = 2.0 * (zeta * dzeta + eta * deta - c * (dzeta * eta + zeta * deta));
    return zeta * zeta + eta * eta - 2.0 * c * zeta * eta - w * w;
  };
  double lo = 0.0, hi = 2.0 * rb;
  double delta = guess_mm && *guess_mm > lo && *guess_mm < hi ? *guess_mm : 0.25 * w;
  for (int i = 0; i < kMaxNewton; ++i) {
    double slope = 0.0;
    const double g = g_and_slope(delta, slope);
    if (g == 0.0) return delta;
    (g < 0.0 ? lo : hi) = delta;
    const double newton = delta - g / slope;
    // A Newton step below kDeltaNewtonStepMm leaves an error of about its square: done. (Taken
    // even where it rounds onto the bracket's end δ has just become: bisecting from there
    // would throw away a root known to rounding, then walk back to it in ~30 halvings.)
    if (std::abs(newton - delta) <= kDeltaNewtonStepMm) return newton;
    const double next = newton > lo && newton < hi ? newton : 0.5 * (lo + hi);  // else bisect
    if (std::abs(next - delta) <= 4.0 * std::numeric_limits<double>::epsilon() * next) {
      return next;
    }
    delta = next;
  }
  return delta;  // the bracket has shrunk to rounding level by now
}

std::optional<double> ChamferModel::delta_at_bisector(const EdgeFrame& f) const {
  const double rb = spec_.ball_radius_mm, w = spec_.width_mm, c = f.c;
  const Vec3 e = (f.t1 + f.t2).normalized();
  if (!(e.dot(f.t1) > 0.0 && e.dot(f.t2) > 0.0) || max_width(f, 1.0) <= w) return std::nullopt;
  // a = b = sqrt((1 + c)/2) and ζ = η = W / sqrt(2 − 2c), so ζ²(1 − a²) = W²/4 and eq. (23)
  // gives q = R_B − δ = −aζ + sqrt(R_B² − W²/4), the one root with δ ∈ (0, 2 R_B) (G rises
  // through zero once there); written without the cancellation of R_B − sqrt(…).
  const double half_w = 0.5 * w;
  return half_w * half_w / (rb + std::sqrt(rb * rb - half_w * half_w)) +
         half_w * std::sqrt((1.0 + c) / (1.0 - c));
}

CutterPose ChamferModel::pose(const EdgeFrame& f, double alpha, double delta) const {
  const double rb = spec_.ball_radius_mm, q = rb - delta;
  CutterPose p;
  p.theta_rad = f.theta_rad;
  p.alpha = alpha;
  p.delta_mm = delta;
  p.xp = f.xp;
  p.e = (f.t1 + alpha * f.t2).normalized();
  p.cl = f.xp - q * p.e;
  p.a = f.xp + plus_root(q, p.e.dot(f.t1), delta, rb) * f.t1;
  p.b = f.xp + plus_root(q, p.e.dot(f.t2), delta, rb) * f.t2;
  const Vec3 ab = p.b - p.a;
  p.width_mm = ab.norm();
  p.projected_width_mm = std::hypot(ab.x(), ab.y());
  const double ke = std::abs(f.k.dot(p.e));
  p.inv_ke_mm = ke > 0.0 ? 1.0 / ke : kInf;
  p.minus_ez = -p.e.z();
  p.cl_radius_mm = std::hypot(p.cl.x(), p.cl.y());
  return p;
}

CutterPose ChamferModel::pose_at(double theta, double alpha) const {
  return pose_at(frame(theta), alpha);
}

CutterPose ChamferModel::pose_at(const EdgeFrame& f, double alpha) const {
  const double theta = f.theta_rad;
  const auto delta = alpha == 1.0 ? delta_at_bisector(f) : solve_delta(f, alpha);
  if (!delta) {
    const AlphaRange range = alpha_range(f);
    throw InputError(
        "no chamfer of width W = " + text::sig(spec_.width_mm) + " mm at θ = " + fmt_deg(theta) +
        " with α = " + text::sig(alpha) + ": the widest the wedge and a " +
        "ball of R_B = " + text::sig(spec_.ball_radius_mm) + " mm allow there is " +
        text::sig(max_width(f, alpha)) + " mm (α must also lie in (" + text::sig(range.lo) + ", " +
        text::sig(range.hi) + ")); use a smaller --width or a larger --ball-radius");
  }
  return pose(f, alpha, *delta);
}

std::optional<double> ChamferModel::rod_limit_radius_mm() const {
  return rod_limit_mm_;
}

std::optional<double> ChamferModel::rod_limit() const {
  if (spec_.edge != Edge::Inner) return std::nullopt;
  std::optional<double> limit;
  const double r = spec_.drill_radius_mm;
  if (spec_.rod_radius_mm) limit = r - *spec_.rod_radius_mm;
  if (spec_.non_knife_angle_rad) {
    const double cap = r - spec_.ball_radius_mm * std::sin(0.5 * *spec_.non_knife_angle_rad);
    limit = limit ? std::min(*limit, cap) : cap;
  }
  return limit;
}

double ChamferModel::rod_interference(const EdgeFrame& f, double alpha, double delta) const {
  return pose(f, alpha, delta).cl_radius_mm - *rod_limit_radius_mm();
}

RodInterference ChamferModel::rod_interference_and_slope(const EdgeFrame& f, double alpha,
                                                         double delta) const {
  return rod_terms(f, alpha, delta).f;
}

ChamferModel::RodTerms ChamferModel::rod_terms(const EdgeFrame& f, double alpha,
                                               double delta) const {
  const double rb = spec_.ball_radius_mm, c = f.c, q = rb - delta;
  const Vec3 u = f.t1 + alpha * f.t2;
  const double u_norm = u.norm();
  const Vec3 e = u.normalized();  // as pose() computes it, so the radius is the one checked
  const double a = e.dot(f.t1), b = e.dot(f.t2);
  const double zeta = plus_root(q, a, delta, rb), eta = plus_root(q, b, delta, rb);
  // G_δ as in solve_delta; G_α at fixed δ from ζ_a = −qζ/(ζ + qa), a' = (c − ab)/|u| and
  // η_b = −qη/(η + qb), b' = (1 − b²)/|u| (e' = (t2 − b e)/|u|); then δ' = −G_α / G_δ.
  const double zeta_delta = (a * zeta + q) / (zeta + q * a);
  const double eta_delta = (b * eta + q) / (eta + q * b);
  const double g_delta =
      2.0 * (zeta * zeta_delta + eta * eta_delta - c * (zeta_delta * eta + zeta * eta_delta));
  const double zeta_alpha = -q * zeta / (zeta + q * a) * (c - a * b) / u_norm;
  const double eta_alpha = -q * eta / (eta + q * b) * (1.0 - b * b) / u_norm;
  const double g_alpha = 2.0 * ((zeta - c * eta) * zeta_alpha + (eta - c * zeta) * eta_alpha);
  const double delta_alpha = -g_alpha / g_delta;
  // CL = x_p − q e, so CL' = δ' e − q e'.
  const Vec3 cl = f.xp - q * e;
  const Vec3 cl_alpha = delta_alpha * e - q * (f.t2 - b * e) / u_norm;
  const double radius = std::hypot(cl.x(), cl.y());
  return {
      {radius - *rod_limit_radius_mm(), (cl.x() * cl_alpha.x() + cl.y() * cl_alpha.y()) / radius},
      delta_alpha};
}

RodAvoidance ChamferModel::avoid_rod(const EdgeFrame& f) const {
  return avoid_rod(f, 1.0);
}

RodAvoidance ChamferModel::avoid_rod(const EdgeFrame& f, double alpha_hint) const {
  // δ at α = 1 in closed form; elsewhere Newton from δ at the iteration's current point x
  // carried along its slope dδ/dα (off by about δ'' Δα²/2, so that near the end one step of G
  // suffices).
  double last_delta = 0.0, x_delta = 0.0, x_delta_slope = 0.0;
  double lo = 1.0, hi = 0.0, f_hi = 0.0, x = 1.0, delta_hi = 0.0;
  const auto big_f = [&](double alpha) {
    const std::optional<double> delta =
        alpha == 1.0 ? delta_at_bisector(f)
                     : solve_delta(f, alpha, x_delta + x_delta_slope * (alpha - x));
    if (!delta) (void)pose_at(f, alpha);  // throws the width error, with numbers
    const RodTerms t = rod_terms(f, alpha, *delta);
    last_delta = *delta;
    return t;
  };
  // Evaluates F at the new current point x.
  const auto move_to = [&](double alpha) {
    const RodTerms t = big_f(alpha);
    x = alpha, x_delta = last_delta, x_delta_slope = t.delta_slope_mm;
    return t.f;
  };
  RodInterference at = move_to(1.0);
  if (at.value_mm <= 0.0) return {1.0, last_delta, false, true};
  // Bracket [lo, hi] with F(lo) > 0 ≥ F(hi); hi is inside the admissible and global bounds.
  const AlphaRange range = alpha_range(f);
  const double top = range.hi * (1.0 - kAlphaMargin);  // +inf where both bounds are
  // The hint (the neighbouring point's α) is one end of the bracket, and Newton starts there.
  if (alpha_hint > 1.0 && alpha_hint < std::min(top, kMaxAlphaSearch)) {
    at = move_to(alpha_hint);
    if (at.value_mm > 0.0) {
      lo = x;
    } else {
      hi = x, f_hi = at.value_mm, delta_hi = last_delta;
    }
  }
  if (hi == 0.0 && std::isfinite(top)) {
    hi = top;
    if (hi <= lo || (f_hi = big_f(hi).f.value_mm) > 0.0) return {1.0, 0.0, false, false};
    delta_hi = last_delta;
  } else if (hi == 0.0) {
    for (hi = 2.0 * lo; hi <= kMaxAlphaSearch; hi *= 2.0) {
      const RodTerms at_hi = big_f(hi);
      if ((f_hi = at_hi.f.value_mm) <= 0.0) break;
      lo = x = hi;
      at = at_hi.f;
      x_delta = last_delta, x_delta_slope = at_hi.delta_slope_mm;
    }
    if (f_hi > 0.0) return {1.0, 0.0, false, false};
    delta_hi = last_delta;
  }
  // Newton on F(α) + ε_α/2 = 0 from the current point x (F at the far end does not move it),
  // so that it lands inside
  // [−ε_α, 0], on the safe side; bisection where a step would leave the bracket. The bracket
  // always holds F(lo) > 0 ≥ F(hi); hi is the safe end.
  for (int i = 0;
       i < kMaxAlphaIterations && hi - lo > kAlphaTolerance * hi && f_hi < -kRodToleranceMm; ++i) {
    double next = x - (at.value_mm + 0.5 * kRodToleranceMm) / at.slope_mm;
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    at = move_to(next);
    if (at.value_mm > 0.0) {
      lo = x;
    } else {
      hi = x;
      f_hi = at.value_mm;
      delta_hi = last_delta;
    }
  }
  return {hi, delta_hi, true, true};
}

double ChamferModel::arc_length(double theta0, double theta1) const {
  const auto v = [this](double th) { return speed(th); };
  // The panel count is doubled from half the nominal one until two successive totals agree.
  int panels = std::max(
      1, static_cast<int>(std::ceil(std::abs(theta1 - theta0) / (4.0 * kPi / kArcLengthPanels))));
  double coarse = GaussLegendre10::integrate(v, theta0, theta1, panels);
  for (int i = 0; i < kMaxArcDoublings; ++i) {
    panels *= 2;
    const double fine = GaussLegendre10::integrate(v, theta0, theta1, panels);
    const bool converged = std::abs(fine - coarse) <= kArcTolerance * std::abs(fine);
    coarse = fine;
    if (converged) break;
  }
  return coarse;
}

double ChamferModel::chord_deviation(double theta0, double theta1) const {
  return chord_deviation(theta0, point(theta0), theta1, point(theta1));
}

double ChamferModel::chord_deviation(double theta0, const Vec3& p0, double theta1,
                                     const Vec3& p1) const {
  const Vec3 chord = p1 - p0;
  const double len = chord.norm();
  const double mid = 0.5 * (theta0 + theta1);
  if (len == 0.0) return (point(mid) - p0).norm();
  // The maximum is where C' ⟂ w⊥ (w⊥ = part of C − p0 normal to the chord): Newton on
  // φ(θ) = C'·w⊥, φ' = C''·w⊥ + |C'⊥|², from the midpoint (eq. 34's sample), kept inside the
  // piece; every iterate's distance counts. Near the maximum the distance d is flat: an iterate
  // whose next step is below kChordNewtonStepRad is within ½|d''| step² (< 1e-16 mm) of it, so
  // the iteration stops there.
  const Vec3 u = chord / len;
  double best = 0.0, th = mid;
  for (int i = 0; i < 9; ++i) {
    const Jet j = jet(th);
    const Vec3 w = j.c - p0;
    const Vec3 w_perp = w - w.dot(u) * u;
    best = std::max(best, w_perp.norm());
    const Vec3 d1_perp = j.d1 - j.d1.dot(u) * u;
    const double phi = j.d1.dot(w_perp);
    const double slope = j.d2.dot(w_perp) + d1_perp.squaredNorm();
    if (slope >= 0.0) break;  // not near a maximum: keep the samples we have
    const double next = th - phi / slope;
    if (!(next > theta0 && next < theta1) || std::abs(next - th) <= kChordNewtonStepRad) break;
    th = next;
  }
  return best;
}

std::optional<PeriodicSeries> ChamferModel::speed_series() const {
  return PeriodicSeries::fit([this](double th) { return speed(th); }, kSeriesTolerance,
                             kSeriesMinSamples, kSeriesMaxSamples);
}

std::vector<double> ChamferModel::equal_arc_starts() const {
  const auto series = speed_series();
  if (!series) return equal_arc_starts_by_quadrature();
  // θ_k solves F(θ) = k L / N, F the series' antiderivative of v = |C'|, whose derivatives v and
  // v' are the series' value and slope: Halley's iteration (cubic), from the second-order step
  // Δ = r/v − v' r² / (2 v³) off θ_{k−1}, r = Δs. Once a step is below 1e-9 rad the error left is
  // of the order of its cube, far below the rounding of F (ε L): stop there.
  const int n = spec_.initial_segments;
  const double ds = series->period_integral() / n;
  std::vector<double> start(static_cast<std::size_t>(n) + 1);
  start[0] = 0.0;
  double th = 0.0;
  PeriodicSeries::Sample at = series->at(0.0);
  for (int k = 1; k < n; ++k) {
    const double target = k * ds, rest = target - at.integral;
    th += rest / at.value - 0.5 * at.slope * rest * rest / (at.value * at.value * at.value);
    for (int i = 0; i < kMaxNewton; ++i) {
      at = series->at(th);
      const double f = at.integral - target;
      const double step = 2.0 * f * at.value / (2.0 * at.value * at.value - f * at.slope);
      th -= step;
      at.integral = target;  // F at the new θ, to within the cube of the step (the next start)
      if (std::abs(step) <= kSeriesNewtonStepRad) break;
    }
    start[static_cast<std::size_t>(k)] = th;
  }
  start[static_cast<std::size_t>(n)] = 2.0 * kPi;
  return start;
}

std::vector<double> ChamferModel::equal_arc_starts_by_quadrature() const {
  const int n = spec_.initial_segments;
  const double total = arc_length(0.0, 2.0 * kPi);
  const double ds = total / n;
  // Equal arcs (eqs. 29–33): θ_k from θ_{k−1} by Newton on ∫ v dθ − Δs, v = |C'|.
  std::vector<double> start(static_cast<std::size_t>(n) + 1);
  start[0] = 0.0;
  double prev = 0.0;
  for (int k = 1; k < n; ++k) {
    double th = prev + ds / speed(prev);
    for (int i = 0; i < kMaxNewton; ++i) {
      const double step =
          (GaussLegendre10::integrate([this](double x) { return speed(x); }, prev, th) - ds) /
          speed(th);
      th -= step;
      if (std::abs(step) <= 4.0 * std::numeric_limits<double>::epsilon() * th) break;
    }
    start[static_cast<std::size_t>(k)] = th;
    prev = th;
  }
  start[static_cast<std::size_t>(n)] = 2.0 * kPi;
  return start;
}

bool ChamferModel::exceeds_tolerance(double theta0, const Jet& j0, double theta1, const Jet& j1,
                                     Jet& mid) const {
  // chord_deviation's iteration, with its decision: true once an iterate lies beyond ε (the
  // maximum is at least that), false where chord_deviation would stop below ε. And false as soon
  // as the quadratic model of ψ = |w⊥|²/2 about the iterate, whose maximum exceeds ψ by
  // φ²/(2|φ'|) at a step φ/|φ'| from it, leaves ε with four times that rise and the step within
  // an eighth of the piece: the iterates still to come converge to that maximum, so they would
  // not pass ε either. The decisions, and so the points, are chord_deviation's; most pieces are
  // decided by their midpoint alone.
  const double eps = spec_.tolerance_mm;
  const double mid_theta = 0.5 * (theta0 + theta1);
  mid = jet(mid_theta);
  const Vec3 chord = j1.c - j0.c;
  const double len = chord.norm();
  if (len == 0.0) return (mid.c - j0.c).norm() > eps;
  const Vec3 u = chord / len;
  double th = mid_theta;
  Jet j = mid;
  for (int i = 0; i < 9; ++i) {
    if (i > 0) j = jet(th);
    const Vec3 w = j.c - j0.c;
    const Vec3 w_perp = w - w.dot(u) * u;
    if (w_perp.norm() > eps) return true;
    const Vec3 d1_perp = j.d1 - j.d1.dot(u) * u;
    const double phi = j.d1.dot(w_perp);
    const double slope = j.d2.dot(w_perp) + d1_perp.squaredNorm();
    if (slope >= 0.0) return false;  // not near a maximum: chord_deviation keeps these samples
    const double step = -phi / slope;
    if (std::abs(step) <= 0.125 * (theta1 - theta0) &&
        w_perp.squaredNorm() + 4.0 * phi * step < eps * eps) {
      return false;
    }
    const double next = th + step;
    if (!(next > theta0 && next < theta1) || std::abs(next - th) <= kChordNewtonStepRad) {
      return false;
    }
    th = next;
  }
  return false;
}

std::vector<ChamferModel::Knot> ChamferModel::knots() const {
  const int n = spec_.initial_segments;
  const std::vector<double> start = equal_arc_starts();

  // Midpoint splits (eq. 34), depth first so the output stays in θ order. Each piece carries
  // the jets at its ends, so every point of the curve is evaluated once, and the frames are
  // built from them.
  struct Piece {
    double a, b;
    Jet ja, jb;
  };
  std::vector<Knot> out;
  std::vector<Piece> stack;
  out.reserve(2 * static_cast<std::size_t>(n));  // experiment 3: 120 points from N = 60
  stack.reserve(32);
  Jet j_start = jet(0.0);
  for (int k = 0; k < n; ++k) {
    const double b_k = start[static_cast<std::size_t>(k) + 1];
    const Jet j_end = jet(b_k);
    stack.push_back({start[static_cast<std::size_t>(k)], b_k, j_start, j_end});
    j_start = j_end;
    while (!stack.empty()) {
      const Piece piece = stack.back();
      const double a = piece.a, b = piece.b;
      stack.pop_back();
      Jet mid;
      if (exceeds_tolerance(a, piece.ja, b, piece.jb, mid)) {
        if (b - a < kMinSplitTheta || out.size() + stack.size() > ChamferLimits::kMaxPoints) {
          throw InputError("tolerance ε = " + text::sig(spec_.tolerance_mm) +
                           " mm needs more than " + std::to_string(ChamferLimits::kMaxPoints) +
                           " points; use a larger --tolerance");
        }
        const double m = 0.5 * (a + b);
        stack.push_back({m, b, mid, piece.jb});
        stack.push_back({a, m, piece.ja, mid});
      } else {
        out.push_back({a, piece.ja});
      }
    }
  }
  return out;
}

std::vector<double> ChamferModel::segment() const {
  const std::vector<Knot> k = knots();
  std::vector<double> out(k.size());
  for (std::size_t i = 0; i < k.size(); ++i) out[i] = k[i].theta;
  return out;
}

std::vector<EdgeFrame> ChamferModel::segment_frames() const {
  const std::vector<Knot> k = knots();
  std::vector<EdgeFrame> out(k.size());
  for (std::size_t i = 0; i < k.size(); ++i) out[i] = frame(k[i].theta, k[i].jet);
  return out;
}

namespace {

// Maximal runs of consecutive points (cyclically) where `bad` holds, as θ ranges.
template <class Bad>
std::vector<ThetaRange> fail_ranges(const std::vector<CutterPose>& pts, Bad bad) {
  std::vector<ThetaRange> out;
  const std::size_t n = pts.size();
  std::size_t start = 0;
  while (start < n && bad(pts[start])) ++start;  // a run through θ = 0 is closed at its end
  if (start == n) return n == 0 ? out : std::vector<ThetaRange>{{0.0, 2.0 * kPi}};
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t i = (start + k) % n;
    if (!bad(pts[i])) continue;
    std::size_t j = i;
    while (k + 1 < n && bad(pts[(start + k + 1) % n])) ++k, j = (start + k) % n;
    out.push_back({pts[i].theta_rad, pts[j].theta_rad});
  }
  return out;
}

std::string ranges_text(const std::vector<ThetaRange>& ranges) {
  std::string out;
  for (std::size_t i = 0; i < ranges.size() && i < 4; ++i) {
    out += (i ? ", " : "") + std::string("θ ∈ [") + text::sig(rad_to_deg(ranges[i].from_rad)) +
           "°, " + text::sig(rad_to_deg(ranges[i].to_rad)) + "°]";
  }
  if (ranges.size() > 4) out += " and " + std::to_string(ranges.size() - 4) + " more";
  return out;
}

}  // namespace

std::string interference_reasons(const ChamferPath& path) {
  const auto& ck = path.checks;
  const auto& s = path.spec;
  std::string out;
  if (!ck.local_ok) {
    out += "local: the edge curves more tightly than the ball (1/|k_e| down to " +
           text::sig(ck.min_inv_ke_mm) + " mm < R_B = " + text::sig(s.ball_radius_mm) + " mm) at " +
           ranges_text(ck.local_fail) + "; ";
  }
  if (!ck.global_ok) {
    const std::string down =
        s.tool_axis ? "down the machine's vertical, " +
                          fmt_deg(std::acos(std::min(1.0, std::abs(s.tool_axis->z())))) +
                          " from the drill axis,"
                    : "down +Z along the drill axis";
    out += "global: the cutter vector −e points into the hole surface, so the ball coming " + down +
           " would cut the hole wall, at " + ranges_text(ck.global_fail) + "; ";
  }
  if (!ck.rod_ok) {
    out += "rod: the cutter location leaves the cylinder of radius R_R = " +
           text::sig(*ck.limit_radius_mm) + " mm about the drill axis (up to " +
           text::sig(ck.max_cl_radius_mm) +
           " mm), so the rod or the non-cutting cap touches the hole, "
           "at " +
           ranges_text(ck.rod_fail) + "; ";
  }
  if (!out.empty()) out.resize(out.size() - 2);
  return out;
}

ChamferPath generate_chamfer(const ChamferSpec& spec) {
  const ChamferModel model(spec);
  ChamferPath path;
  path.spec = spec;
  const std::vector<EdgeFrame> frames = model.segment_frames();
  path.points.reserve(frames.size());
  ChamferChecks& ck = path.checks;
  ck.limit_radius_mm = model.rod_limit_radius_mm();
  ck.rod_applies = spec.edge == Edge::Inner;
  ck.min_inv_ke_mm = kInf;
  ck.max_minus_ez = -kInf;
  ck.min_minus_ez = kInf;
  // −e along the tool axis, signed as −e_z (the axis turned with a lower edge): −e_z itself
  // unless a tool axis is given (ChamferSpec::tool_axis).
  const double side_sign = spec.side == Side::Upper ? 1.0 : -1.0;
  const auto tool_minus_ez = [&](const CutterPose& p) {
    return spec.tool_axis ? -p.e.dot(side_sign * *spec.tool_axis) : p.minus_ez;
  };
  // Algorithm 1 starts at α extrapolated from the last two points (where both were adjusted).
  double theta_1 = 0.0, alpha_1 = 1.0, theta_2 = 0.0, alpha_2 = 1.0;
  for (const EdgeFrame& f : frames) {
    const double theta = f.theta_rad;
    std::optional<CutterPose> pose;
    if (ck.limit_radius_mm && spec.avoid) {
      const double hint =
          alpha_1 > 1.0 && alpha_2 > 1.0
              ? alpha_1 + (alpha_1 - alpha_2) * (theta - theta_1) / (theta_1 - theta_2)
              : alpha_1;
      const RodAvoidance rod = model.avoid_rod(f, hint);
      theta_2 = theta_1, alpha_2 = alpha_1;
      theta_1 = theta, alpha_1 = rod.cleared ? rod.alpha : 1.0;
      if (!rod.cleared) ck.uncleared_theta_rad.push_back(theta);
      if (rod.adjusted) ++ck.adjusted_points;
      if (rod.cleared) pose = model.pose(f, rod.alpha, rod.delta_mm);
    }
    const CutterPose p = pose ? *pose : model.pose_at(f, 1.0);
    ck.min_inv_ke_mm = std::min(ck.min_inv_ke_mm, p.inv_ke_mm);
    ck.max_minus_ez = std::max(ck.max_minus_ez, tool_minus_ez(p));
    ck.min_minus_ez = std::min(ck.min_minus_ez, tool_minus_ez(p));
    ck.max_cl_radius_mm = std::max(ck.max_cl_radius_mm, p.cl_radius_mm);
    path.points.push_back(p);
  }
  ck.local_ok = ck.min_inv_ke_mm >= spec.ball_radius_mm;
  // −e_z ≤ 0 on inner/upper and outer/lower, ≥ 0 on outer/upper and inner/lower.
  const bool ez_nonpositive = (spec.edge == Edge::Inner) == (spec.side == Side::Upper);
  ck.global_ok = ez_nonpositive ? ck.max_minus_ez <= 0.0 : ck.min_minus_ez >= 0.0;
  ck.rod_ok = !ck.limit_radius_mm || ck.max_cl_radius_mm <= *ck.limit_radius_mm;
  const auto& pts = path.points;
  ck.local_fail =
      fail_ranges(pts, [&](const CutterPose& p) { return p.inv_ke_mm < spec.ball_radius_mm; });
  ck.global_fail = fail_ranges(pts, [&](const CutterPose& p) {
    return ez_nonpositive ? tool_minus_ez(p) > 0.0 : tool_minus_ez(p) < 0.0;
  });
  if (ck.limit_radius_mm) {
    ck.rod_fail =
        fail_ranges(pts, [&](const CutterPose& p) { return p.cl_radius_mm > *ck.limit_radius_mm; });
  }
  if (spec.avoid && !ck.uncleared_theta_rad.empty()) {
    const double th = ck.uncleared_theta_rad.front();
    const EdgeFrame f = model.frame(th);
    const AlphaRange range = model.alpha_range(f);
    throw InputError("the rod limit R_R = " + text::sig(*ck.limit_radius_mm) +
                     " mm cannot be met at θ = " + fmt_deg(th) + " (and " +
                     std::to_string(ck.uncleared_theta_rad.size() - 1) +
                     " more points): no admissible α in [1, " + text::sig(range.hi) +
                     ") keeps the cutter location that close to the drill axis; use a thinner rod "
                     "(--rod-radius), a smaller non-knife angle, a smaller ball, or --no-avoid to "
                     "report the interference instead");
  }
  return path;
}

}  // namespace ncd::toolpath
