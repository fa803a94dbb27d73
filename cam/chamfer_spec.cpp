// The chamfer's hole and its checks (docs/chamfer.md): the pipe surface (a cylinder or cone,
// its implicit function and gradient), where the drill sits in the pipe frame, the wall's other
// surface, and validate(): every value's range, and a drill that pierces each wall surface it
// must (the discriminant scan of "Edge curve by numerical intersection", top of chamfer.cpp).
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

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

// Refuses a surface the drill does not pierce completely: a generator that misses or grazes it,
// or meets the far nappe of a cone.
void check_pierces(const ChamferSpec& spec, const PipeSurface& surf, const std::string& which) {
  const double r = spec.drill_radius_mm;
  const std::string drill = "the drill (r = " + text::sig(r) + " mm, tilt " +
                            fmt_deg(spec.drill_tilt_rad) + ", eccentricity " +
                            text::sig(spec.eccentricity_mm) + " mm)";
  const std::string pipe = "the " + which + " pipe surface (radius " + text::sig(surf.radius_mm) +
                           " mm at the reference point, half-angle " +
                           fmt_deg(spec.pipe_half_angle_rad) + ")";
  const double az = surf.axis_direction.z();
  if (!(generator_quadratic(surf, r, 0.0).qa > 1e-9)) {
    throw InputError(drill + " runs at " + fmt_deg(std::acos(std::min(1.0, std::abs(az)))) +
                     " to the pipe axis, which must exceed the half-angle " +
                     fmt_deg(std::abs(spec.pipe_half_angle_rad)) + " of " + pipe +
                     " for a hole through the wall; reduce --drill-tilt-deg");
  }
  const auto half_gap = [](const Quadratic& q) {
    const double d = q.discriminant();
    return d > 0.0 ? std::sqrt(d) / (2.0 * q.qa) : -std::sqrt(-d) / (2.0 * q.qa);
  };
  const auto half_gap_at = [&](double th) { return half_gap(generator_quadratic(surf, r, th)); };
  int worst = 0;
  double worst_gap = kInf;
  for (int i = 0; i < kPierceScan; ++i) {
    const double th = 2.0 * kPi * i / kPierceScan;
    const double cos_t = std::cos(th), sin_t = std::sin(th);
    const Quadratic q = generator_quadratic(surf, r, cos_t, sin_t);
    const double g = half_gap(q);
    if (g < worst_gap) worst_gap = g, worst = i;
    for (const bool upper : {true, false}) {
      if (surf.slope == 0.0) break;  // a cylinder has no far nappe
      const auto z = quadratic_root(q, upper);
      if (z && !(surf.axial_radius(Vec3(r * cos_t, r * sin_t, *z)) > 0.0)) {
        throw InputError(drill + " meets " + pipe +
                         " beyond the cone's apex at θ = " + fmt_deg(th) +
                         "; move the hole away from the apex (a larger --pipe-radius"
                         " or a smaller --pipe-half-angle-deg)");
      }
    }
  }
  // Golden-section refinement of the smallest gap between the neighbouring samples.
  double lo = 2.0 * kPi * (worst - 1) / kPierceScan, hi = 2.0 * kPi * (worst + 1) / kPierceScan;
  const double gr = 0.5 * (std::sqrt(5.0) - 1.0);
  double x1 = hi - gr * (hi - lo), x2 = lo + gr * (hi - lo);
  double g1 = half_gap_at(x1), g2 = half_gap_at(x2);
  for (int i = 0; i < 50; ++i) {  // one new evaluation per step: the other point is kept
    if (g1 < g2) {
      hi = x2;
      x2 = x1, g2 = g1;
      x1 = hi - gr * (hi - lo), g1 = half_gap_at(x1);
    } else {
      lo = x1;
      x1 = x2, g1 = g2;
      x2 = lo + gr * (hi - lo), g2 = half_gap_at(x2);
    }
  }
  const double th = 0.5 * (lo + hi);
  worst_gap = std::min(worst_gap, half_gap_at(th));
  if (!(worst_gap > kMinHalfGapMm)) {
    // θ to 0.01°, in [0°, 360°).
    const double deg = std::round(rad_to_deg(std::fmod(th + 2.0 * kPi, 2.0 * kPi)) * 100.0) / 100.0;
    throw InputError(drill + " does not pierce " + pipe + " completely: the drill's generator at " +
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
  if (!paper_geometry) {
    check_pierces(s, pipe_surface(s, s.pipe_radius_mm), to_string(s.edge));
  }
  if (const auto other = companion_radius_mm(s)) {
    check_pierces(s, pipe_surface(s, *other),
                  to_string(s.edge == Edge::Inner ? Edge::Outer : Edge::Inner));
  }
}

}  // namespace ncd::toolpath
