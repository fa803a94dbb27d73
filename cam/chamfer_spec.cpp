// The chamfer's hole and its checks (docs/chamfer.md): the pipe surface (a cylinder or cone,
// its implicit function and gradient), where the drill sits in the pipe frame, the wall's other
// surface, and validate(): every value's range, and a drill that pierces each wall surface it
// must (the discriminant scan of "Edge curve by numerical intersection", top of chamfer.cpp).
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "cam/chamfer.hpp"
#include "cam/chamfer_detail.hpp"
#include "core/error.hpp"
#include "core/number_text.hpp"

namespace ncd::toolpath {

using namespace chamfer_detail;

namespace {

constexpr int kPierceScan = 360;        // samples of θ in the piercing check
constexpr double kMinHalfGapMm = 1e-6;  // upper and lower roots at least 2 µm apart
constexpr double kMaxHalfAngleRad = kPi / 3.0;
constexpr int kMaxMinimumSteps = 60;      // safeguarded Newton on a trig polynomial's slope,
constexpr double kMinimumStepRad = 1e-9;  // until its step is below this

// l0 + l1 cos θ + l2 sin θ.
struct Trig1 {
  double k0 = 0.0, c1 = 0.0, s1 = 0.0;
};

// k0 + c1 cos θ + s1 sin θ + c2 cos 2θ + s2 sin 2θ, with its first two derivatives.
struct Trig2 {
  double k0 = 0.0, c1 = 0.0, s1 = 0.0, c2 = 0.0, s2 = 0.0;
  double at(double c, double s) const {  // at (cos θ, sin θ)
    return k0 + c1 * c + s1 * s + c2 * (c * c - s * s) + s2 * (2.0 * s * c);
  }
  double slope(double c, double s) const {
    return -c1 * s + s1 * c + 2.0 * (-c2 * (2.0 * s * c) + s2 * (c * c - s * s));
  }
  double curvature(double c, double s) const {
    return -c1 * c - s1 * s - 4.0 * (c2 * (c * c - s * s) + s2 * (2.0 * s * c));
  }
};

Trig1 operator*(double x, const Trig1& l) {
  return {x * l.k0, x * l.c1, x * l.s1};
}
Trig1 operator+(const Trig1& l, const Trig1& m) {
  return {l.k0 + m.k0, l.c1 + m.c1, l.s1 + m.s1};
}
// With cos² = (1 + cos 2θ)/2, sin² = (1 − cos 2θ)/2, cos sin = sin 2θ / 2.
Trig2 operator*(const Trig1& l, const Trig1& m) {
  const double cc = l.c1 * m.c1, ss = l.s1 * m.s1, cs = l.c1 * m.s1 + l.s1 * m.c1;
  return {l.k0 * m.k0 + 0.5 * (cc + ss), l.k0 * m.c1 + l.c1 * m.k0, l.k0 * m.s1 + l.s1 * m.k0,
          0.5 * (cc - ss), 0.5 * cs};
}
Trig2 operator+(const Trig2& p, const Trig2& q) {
  return {p.k0 + q.k0, p.c1 + q.c1, p.s1 + q.s1, p.c2 + q.c2, p.s2 + q.s2};
}
Trig2 operator*(double x, const Trig2& p) {
  return {x * p.k0, x * p.c1, x * p.s1, x * p.c2, x * p.s2};
}

// generator_quadratic's coefficients as functions of θ: qa constant, qb ∈ Trig1, qc ∈ Trig2;
// and the discriminant qb² − 4 qa qc, a trigonometric polynomial of degree 2.
struct GeneratorCoefficients {
  double qa = 0.0;
  Trig1 qb, rho_mid;  // ρ at the roots' midpoint z = −qb / (2 qa), where ρ is linear in z
  Trig2 discriminant;
};

GeneratorCoefficients generator_coefficients(const PipeSurface& s, double r) {
  const Vec3 &a = s.axis_direction, &p = s.axis_point;
  const double k = s.slope, az = a.z();
  const Trig1 aw{-a.dot(p), r * a.x(), r * a.y()};  // a·w0, w0 = (r cos θ, r sin θ, 0) − p0
  const Trig1 rho0 = Trig1{s.radius_mm, 0.0, 0.0} + k * aw;
  GeneratorCoefficients g;
  g.qa = 1.0 - (1.0 + k * k) * az * az;
  g.qb = 2.0 * (Trig1{-p.z(), 0.0, 0.0} + (-az) * aw + (-k * az) * rho0);
  const Trig2 w0_squared{r * r + p.squaredNorm(), -2.0 * r * p.x(), -2.0 * r * p.y(), 0.0, 0.0};
  const Trig2 qc = w0_squared + (-1.0) * (aw * aw) + (-1.0) * (rho0 * rho0);
  g.discriminant = g.qb * g.qb + (-4.0 * g.qa) * qc;
  g.rho_mid = rho0 + (-k * az / (2.0 * g.qa)) * g.qb;
  return g;
}

// cos θ_i and sin θ_i at the kPierceScan angles θ_i = 2π i / kPierceScan, by four interleaved
// rotations (one would be a chain of 360 dependent steps; no trigonometric call per angle).
struct ScanCircle {
  static constexpr double kStepRad = 2.0 * kPi / kPierceScan;
  std::array<double, kPierceScan> c{}, s{};
  ScanCircle() {
    constexpr std::size_t kChains = 4;
    static_assert(kPierceScan % kChains == 0);
    const double ch = std::cos(kChains * kStepRad), sh = std::sin(kChains * kStepRad);
    for (std::size_t j = 0; j < kChains; ++j) {
      c[j] = std::cos(static_cast<double>(j) * kStepRad);
      s[j] = std::sin(static_cast<double>(j) * kStepRad);
    }
    for (std::size_t i = kChains; i < kPierceScan; ++i) {
      c[i] = c[i - kChains] * ch - s[i - kChains] * sh;
      s[i] = s[i - kChains] * ch + c[i - kChains] * sh;
    }
  }
};

// The θ of every local minimum of p over [0, 2π): the local minima of its samples on the scan
// circle, each refined by Newton on p' = 0 kept inside its two neighbouring samples, bisecting
// by the sign of p' where a step would leave them. A degree-2 polynomial has at most two; a
// constant one gives θ = 0.
std::vector<double> local_minima(const Trig2& p, const ScanCircle& circle) {
  std::array<double, kPierceScan> v{};
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = p.at(circle.c[i], circle.s[i]);
  const double h = ScanCircle::kStepRad;
  std::vector<double> out;
  for (int i = 0; i < kPierceScan; ++i) {
    const std::size_t k = static_cast<std::size_t>(i);
    const double prev = v[i == 0 ? v.size() - 1 : k - 1];
    const double next = v[k + 1 == v.size() ? 0 : k + 1];
    if (!(v[k] <= prev && v[k] < next)) continue;
    double lo = h * (i - 1), hi = h * (i + 1), th = h * i;
    for (int it = 0; it < kMaxMinimumSteps && hi - lo > kMinimumStepRad; ++it) {
      const double ct = std::cos(th), st = std::sin(th);
      const double d1 = p.slope(ct, st), d2 = p.curvature(ct, st);
      const double step = d1 / d2;
      // Quadratic convergence: the error after a step this small is far below rounding.
      if (d2 > 0.0 && std::abs(step) <= kMinimumStepRad) {
        th -= step;
        break;
      }
      (d1 < 0.0 ? lo : hi) = th;
      const bool inside = d2 > 0.0 && th - step > lo && th - step < hi;
      th = inside ? th - step : 0.5 * (lo + hi);
    }
    out.push_back(th);
  }
  if (out.empty()) {  // constant (no strict minimum among the samples): its first sample
    out.push_back(0.0);
  }
  return out;
}

// Refuses a surface the drill does not pierce completely: a generator that misses or grazes it,
// or meets the far nappe of a cone. g's discriminant and ρ at the roots' midpoint are
// trigonometric polynomials in θ (generator_coefficients), so the scan costs a few
// multiplications per angle; each decision is then taken on g itself (generator_quadratic,
// quadratic_root) at the θ the polynomials point to.
//
// Far nappe (cones), checked first as a scan of the kPierceScan angles: along a generator ρ is
// linear in z, so both roots have ρ > 0 iff ρ_mid > |k a_z| · half-gap, i.e. ρ_mid > 0 and
// H = ρ_mid² − (k a_z / (2 qa))² disc > 0. (A generator that pierces a cone meets one nappe
// only, and the drill axis never enters the far one, so every hole refused here also fails the
// check below; this one names the cause.) Piercing: the smallest half-gap is at a local minimum
// of the discriminant (qa is constant), found by local_minima.
void check_pierces(const ChamferSpec& spec, const PipeSurface& surf, const std::string& which) {
  const double r = spec.drill_radius_mm;
  // The messages are only composed for a refusal (formatting numbers costs microseconds).
  const auto drill = [&] {
    return "the drill (r = " + text::sig(r) + " mm, tilt " + fmt_deg(spec.drill_tilt_rad) +
           ", eccentricity " + text::sig(spec.eccentricity_mm) + " mm)";
  };
  const auto pipe = [&] {
    return "the " + which + " pipe surface (radius " + text::sig(surf.radius_mm) +
           " mm at the reference point, half-angle " + fmt_deg(spec.pipe_half_angle_rad) + ")";
  };
  const double az = surf.axis_direction.z();
  const GeneratorCoefficients g = generator_coefficients(surf, r);
  if (!(g.qa > 1e-9)) {
    throw InputError(drill() + " runs at " + fmt_deg(std::acos(std::min(1.0, std::abs(az)))) +
                     " to the pipe axis, which must exceed the half-angle " +
                     fmt_deg(std::abs(spec.pipe_half_angle_rad)) + " of " + pipe() +
                     " for a hole through the wall; reduce --drill-tilt-deg");
  }
  const ScanCircle circle;
  if (surf.slope != 0.0) {  // a cylinder has no far nappe
    const double kz = surf.slope * az / (2.0 * g.qa);
    for (std::size_t i = 0; i < circle.c.size(); ++i) {
      const double cos_t = circle.c[i], sin_t = circle.s[i];
      const double disc = g.discriminant.at(cos_t, sin_t);
      const double m = g.rho_mid.k0 + g.rho_mid.c1 * cos_t + g.rho_mid.s1 * sin_t;
      if (disc < 0.0 || (m > 0.0 && m * m - kz * kz * disc > 1e-9 * m * m)) continue;
      const double th = ScanCircle::kStepRad * static_cast<double>(i);
      const Quadratic q = generator_quadratic(surf, r, th);
      for (const bool upper : {true, false}) {
        const auto z = quadratic_root(q, upper);
        if (z && !(surf.axial_radius(Vec3(r * std::cos(th), r * std::sin(th), *z)) > 0.0)) {
          throw InputError(drill() + " meets " + pipe() +
                           " beyond the cone's apex at θ = " + fmt_deg(th) +
                           "; move the hole away from the apex (a larger --pipe-radius"
                           " or a smaller --pipe-half-angle-deg)");
        }
      }
    }
  }
  const auto half_gap_at = [&](double th) {
    const double d = generator_quadratic(surf, r, th).discriminant();
    return d > 0.0 ? std::sqrt(d) / (2.0 * g.qa) : -std::sqrt(-d) / (2.0 * g.qa);
  };
  double worst_gap = kInf, th = 0.0;
  for (const double m : local_minima(g.discriminant, circle)) {
    const double gap = half_gap_at(m);
    if (gap < worst_gap) worst_gap = gap, th = m;
  }
  if (!(worst_gap > kMinHalfGapMm)) {
    // θ to 0.01°, in [0°, 360°).
    const double deg = std::round(rad_to_deg(std::fmod(th + 2.0 * kPi, 2.0 * kPi)) * 100.0) / 100.0;
    throw InputError(drill() + " does not pierce " + pipe() +
                     " completely: the drill's generator at " +
                     "θ = " + text::sig(deg >= 360.0 ? 0.0 : deg + 0.0) + "°" +
                     (worst_gap > -kMinHalfGapMm ? " only grazes it" : " misses it") +
                     ", so the edge is not a closed loop around the hole (for a cylinder pipe and "
                     "no tilt: r + |eccentricity| must stay below the radius); reduce "
                     "--eccentricity, --drill-radius or --drill-tilt-deg");
  }
}

}  // namespace

double PipeSurface::implicit(const Vec3& x) const {
  const Vec3 w = x - axis_point;
  const double aw = axis_direction.dot(w), rho = radius_mm + slope * aw;
  return w.squaredNorm() - aw * aw - rho * rho;
}

Vec3 PipeSurface::gradient(const Vec3& x) const {
  const Vec3 w = x - axis_point;
  const double aw = axis_direction.dot(w), rho = radius_mm + slope * aw;
  return 2.0 * (w - (aw + slope * rho) * axis_direction);
}

double PipeSurface::axial_radius(const Vec3& x) const {
  return radius_mm + slope * axis_direction.dot(x - axis_point);
}

Vec3 DrillPlacement::to_drill(const Vec3& p) const {
  const Vec3 w = p - origin;
  return {w.dot(x), w.dot(y), w.dot(z)};
}

DrillPlacement drill_placement(const ChamferSpec& spec) {
  const double tau = spec.drill_tilt_rad, phi = spec.drill_azimuth_rad;
  const Vec3 d(std::sin(tau) * std::sin(phi), std::sin(tau) * std::cos(phi), std::cos(tau));
  const Vec3 pipe_axis(0.0, 1.0, 0.0);
  DrillPlacement p;
  p.z = d;
  p.y = (pipe_axis - pipe_axis.dot(d) * d).normalized();
  p.x = p.y.cross(p.z);
  p.origin = spec.eccentricity_mm * p.x;  // x = Y × d / |Y × d| = n̂
  return p;
}

PipeSurface pipe_surface(const ChamferSpec& spec, double radius_mm) {
  const DrillPlacement p = drill_placement(spec);
  PipeSurface s;
  s.axis_point = p.to_drill(Vec3::Zero());
  s.axis_direction = Vec3(p.x.y(), p.y.y(), p.z.y());  // +Y in drill coordinates
  s.radius_mm = radius_mm;
  s.slope = std::tan(spec.pipe_half_angle_rad);
  return s;
}

std::optional<double> companion_radius_mm(const ChamferSpec& spec) {
  if (!spec.pipe_thickness_mm) return std::nullopt;
  const double radial = *spec.pipe_thickness_mm / std::cos(spec.pipe_half_angle_rad);
  return spec.edge == Edge::Inner ? spec.pipe_radius_mm + radial : spec.pipe_radius_mm - radial;
}

std::string to_string(Edge edge) {
  return edge == Edge::Inner ? "inner" : "outer";
}
std::string to_string(Side side) {
  return side == Side::Upper ? "upper" : "lower";
}

namespace {

// The cutter's own limits: the rod and the non-knife cap within the hole, the tool axis.
void validate_tool(const ChamferSpec& s) {
  if (s.rod_radius_mm) {
    require_positive("rod radius R_od (--rod-radius)", *s.rod_radius_mm);
    if (*s.rod_radius_mm >= s.drill_radius_mm) {
      throw InputError("rod radius R_od = " + text::sig(*s.rod_radius_mm) +
                       " mm must be smaller than the drill radius r = " +
                       text::sig(s.drill_radius_mm) + " mm, or the rod cannot enter the hole");
    }
  }
  if (s.non_knife_angle_rad) {
    const double two_beta = *s.non_knife_angle_rad;
    if (!std::isfinite(two_beta) || two_beta <= 0.0 || two_beta >= kPi) {
      throw InputError("non-knife angle 2β = " + fmt_deg(two_beta) +
                       " must lie in (0°, 180°) (--non-knife-angle, degrees)");
    }
    if (s.ball_radius_mm * std::sin(0.5 * two_beta) >= s.drill_radius_mm) {
      throw InputError("non-knife cap radius R_B sin β = " +
                       text::sig(s.ball_radius_mm * std::sin(0.5 * two_beta)) +
                       " mm reaches the drill radius r = " + text::sig(s.drill_radius_mm) + " mm");
    }
  }
  if (s.tool_axis) {
    const Vec3& a = *s.tool_axis;
    if (!a.allFinite() || std::abs(a.norm() - 1.0) > 1e-9) {
      throw InputError("the tool axis (" + text::sig(a.x()) + ", " + text::sig(a.y()) + ", " +
                       text::sig(a.z()) + ") must be a finite unit vector in the drill frame");
    }
    if (s.edge == Edge::Inner && std::hypot(a.x(), a.y()) > 1e-12) {
      throw InputError(
          "an inner edge needs the tool along the drill axis (the rod check and the "
          "approach through the hole assume it), but the tool axis is " +
          fmt_deg(std::acos(std::min(1.0, std::abs(a.z())))) +
          " from it; cut the hole with its drill axis vertical");
    }
  }
}

}  // namespace

void validate(const ChamferSpec& s) {
  require_positive("pipe radius (--pipe-radius) " + text::sig(s.pipe_radius_mm) + " mm",
                   s.pipe_radius_mm);
  require_positive("drill radius (--drill-radius)", s.drill_radius_mm);
  require_positive("ball radius R_B (--ball-radius)", s.ball_radius_mm);
  require_positive("chamfer width W (--width)", s.width_mm);
  require_positive("tolerance ε (--tolerance)", s.tolerance_mm);
  require_finite("drill tilt τ (--drill-tilt-deg)", s.drill_tilt_rad);
  require_finite("drill azimuth φ (--drill-azimuth-deg)", s.drill_azimuth_rad);
  require_finite("eccentricity (--eccentricity, mm)", s.eccentricity_mm);
  require_finite("pipe half-angle ψ (--pipe-half-angle-deg)", s.pipe_half_angle_rad);
  if (s.drill_tilt_rad < 0.0 || s.drill_tilt_rad >= 0.5 * kPi) {
    throw InputError("drill tilt τ = " + fmt_deg(s.drill_tilt_rad) +
                     " must lie in [0°, 90°) (--drill-tilt-deg; the direction of the tilt is "
                     "--drill-azimuth-deg)");
  }
  if (std::abs(s.pipe_half_angle_rad) >= kMaxHalfAngleRad) {
    throw InputError("pipe half-angle ψ = " + fmt_deg(s.pipe_half_angle_rad) +
                     " must lie in (−60°, 60°) (--pipe-half-angle-deg; 0 for a cylinder)");
  }
  const bool paper_geometry =
      s.drill_tilt_rad == 0.0 && s.eccentricity_mm == 0.0 && s.pipe_half_angle_rad == 0.0;
  if (s.edge_curve == EdgeCurve::ClosedForm && !paper_geometry) {
    throw InputError(
        "the closed-form edge curve (eq. 4) holds only without tilt, eccentricity "
        "and cone angle; use the numerical edge curve");
  }
  if (s.pipe_thickness_mm) {
    require_positive("pipe wall thickness (--pipe-thickness)", *s.pipe_thickness_mm);
    const double other = *companion_radius_mm(s);
    if (!(other > 0.0)) {
      throw InputError("pipe wall thickness " + text::sig(*s.pipe_thickness_mm) +
                       " mm leaves no bore inside the outer radius " + text::sig(s.pipe_radius_mm) +
                       " mm; use a smaller --pipe-thickness");
    }
  }
  if (s.pipe_half_angle_rad == 0.0 && s.drill_radius_mm >= s.pipe_radius_mm) {
    throw InputError("drill radius r = " + text::sig(s.drill_radius_mm) +
                     " mm must be smaller than the pipe radius " + text::sig(s.pipe_radius_mm) +
                     " mm (a drill as wide as the pipe cuts it in two, and the edge is not a "
                     "closed curve); use a smaller --drill-radius or the right --pipe-radius");
  }
  if (s.tolerance_mm < ChamferLimits::kMinToleranceMm ||
      s.tolerance_mm > ChamferLimits::kMaxToleranceMm) {
    throw InputError("tolerance ε = " + text::sig(s.tolerance_mm) + " mm is outside [" +
                     text::sig(ChamferLimits::kMinToleranceMm) + ", " +
                     text::sig(ChamferLimits::kMaxToleranceMm) +
                     "] mm; 0.01 mm is typical (--tolerance)");
  }
  if (s.initial_segments < ChamferLimits::kMinInitialSegments ||
      s.initial_segments > ChamferLimits::kMaxInitialSegments) {
    throw InputError("initial segments N = " + std::to_string(s.initial_segments) +
                     " is outside [" + std::to_string(ChamferLimits::kMinInitialSegments) + ", " +
                     std::to_string(ChamferLimits::kMaxInitialSegments) + "]; the paper uses 60");
  }
  if (s.edge == Edge::Inner && s.ball_radius_mm >= s.drill_radius_mm) {
    throw InputError(
        "ball radius R_B = " + text::sig(s.ball_radius_mm) +
        " mm must be smaller than the drill radius r = " + text::sig(s.drill_radius_mm) +
        " mm to reach an inner edge through the hole; use a smaller --ball-radius");
  }
  validate_tool(s);
  if (!paper_geometry) {
    check_pierces(s, pipe_surface(s, s.pipe_radius_mm), to_string(s.edge));
  }
  if (const auto other = companion_radius_mm(s)) {
    check_pierces(s, pipe_surface(s, *other),
                  to_string(s.edge == Edge::Inner ? Edge::Outer : Edge::Inner));
  }
}

}  // namespace ncd::toolpath
