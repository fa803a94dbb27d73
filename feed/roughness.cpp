// Choi, Jung, Hong, Yang, "NURBS interpolator for controlling the surface roughness" (paper
// 004), section 2, as reconstructed in docs/feedrate.md §1.
//
// A ball of radius r, stepping over by the pick feed f_p between passes and advancing by the
// feed per tooth f_t along each pass, leaves two kinds of marks. Away from the tool tip
// (|α| > α_c, α the inclination of the surface in the feed direction) each tooth cuts a
// spherical scallop, and the peak of the superposed scallops is (eq. 2)
//
//     R_out = f_p² / (8r) · [1 + ((f_t − p) / f_p)²] = A / (8r),   A = f_p² + (f_t − p)²,
//     p = f_p / (2π),
//
// which is also the f_p = 0 single-pass value f_t² / (8r), with no branch. Near the tip
// (|α| ≤ α_c) the tip, where the cutting speed is zero, rubs the surface: the mark is the ball
// itself seen at a distance f_t from the previous tooth, tilted by α (eq. 3):
//
//     R_dc = r · [1 − sqrt(1 − (f_t / r)² + sin²α)]
//
//          tool axis
//              │  ╲ α                       ┌─ R_dc: the tip's own track,
//          ╭───┼───╮ ╲ surface normal       │  deepest at α = 0
//          │   │   │                        │
//          ╰─╮ ● ╭─╯  ← tip, v = 0          └─ R_out: the scallops of the pick feed
//   ─────────╲___╱──────────── surface, sloped by α in the feed direction
//
// The branches meet at the critical angle α_c (eq. 4); R_max = max(R_out, R_dc) is the same
// law without the branch test and stays right below f_t ≈ 0.53 f_p, where the radicand of
// eq. 4 is negative, α_c does not exist and R_out governs at every α.
//
// Inverse (eqs. 5, 6). Both branches increase with f_t (R_out for f_t ≥ p), so the feed per
// tooth for a target R is the smaller of the two branch inverses:
//
//     f_t,out = p + sqrt(8 r R − f_p²),   f_t,dc = sqrt((r sin α)² + 2 r R − R²),
//
// equal at α = α_c(f_t,out), hence continuous in α. 8 r R < f_p² means the pick feed alone
// leaves cusps above the target: an input error, never clamped. The feed is F = f_t z N.
#include "feed/roughness.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include "core/error.hpp"
#include "core/number_text.hpp"

namespace ncd::feed {
namespace {

double p_of(double pick_feed_mm) {
  return pick_feed_mm / (2.0 * kPi);
}

}  // namespace

void validate(const CuttingParams& params) {
  require_positive("ball_radius_mm", params.ball_radius_mm);
  require_positive("spindle_rpm", params.spindle_rpm);
  require_positive("roughness_target_um", params.roughness_target_um);
  if (params.teeth <= 0) {
    throw InputError("teeth = " + std::to_string(params.teeth) +
                     " is invalid: a cutter has at least 1 tooth");
  }
  const double r = params.ball_radius_mm;
  const double fp = params.pick_feed_mm;
  if (!std::isfinite(fp) || fp < 0.0) {
    throw InputError("pick_feed_mm = " + text::sig(fp) +
                     " is invalid: it must be finite and at least 0 (0 for a single pass)");
  }
  if (fp >= 2.0 * r) {
    throw InputError("pick_feed_mm = " + text::sig(fp) + " is not below the ball diameter 2 * " +
                     "ball_radius_mm = " + text::sig(2.0 * r) +
                     " mm: the passes would leave uncut ribs; reduce the pick feed");
  }
  const double target_mm = params.roughness_target_um * 1e-3;
  if (target_mm >= r) {
    throw InputError("roughness_target_um = " + text::sig(params.roughness_target_um) +
                     " is not below ball_radius_mm = " + text::sig(r) +
                     " mm: the model holds for marks much smaller than the ball");
  }
  if (8.0 * r * target_mm < fp * fp) {
    const double cusp_um = fp * fp / (8.0 * r) * 1e3;
    throw InputError("roughness_target_um = " + text::sig(params.roughness_target_um) +
                     " cannot be met: pick_feed_mm = " + text::sig(fp) + " with ball_radius_mm = " +
                     text::sig(r) + " alone leaves cusps of f_p^2/(8r) = " + text::sig(cusp_um) +
                     " um; reduce the pick feed to at most sqrt(8 r R) = " +
                     text::sig(std::sqrt(8.0 * r * target_mm)) +
                     " mm or raise the target to at least " + text::sig(cusp_um) + " um");
  }
}

double roughness_outside_mm(double ball_radius_mm, double pick_feed_mm, double feed_per_tooth_mm) {
  const double d = feed_per_tooth_mm - p_of(pick_feed_mm);
  return (pick_feed_mm * pick_feed_mm + d * d) / (8.0 * ball_radius_mm);
}

double roughness_dead_centre_mm(double ball_radius_mm, double feed_per_tooth_mm,
                                double inclination_rad) {
  const double q = feed_per_tooth_mm / ball_radius_mm;
  const double s = std::sin(inclination_rad);
  return ball_radius_mm * (1.0 - std::sqrt(1.0 - q * q + s * s));
}

double roughness_mm(double ball_radius_mm, double pick_feed_mm, double feed_per_tooth_mm,
                    double inclination_rad) {
  return std::max(roughness_outside_mm(ball_radius_mm, pick_feed_mm, feed_per_tooth_mm),
                  roughness_dead_centre_mm(ball_radius_mm, feed_per_tooth_mm, inclination_rad));
}

std::optional<double> critical_angle_rad(double ball_radius_mm, double pick_feed_mm,
                                         double feed_per_tooth_mm) {
  const double r = ball_radius_mm;
  const double d = feed_per_tooth_mm - p_of(pick_feed_mm);
  const double a = pick_feed_mm * pick_feed_mm + d * d;
  const double b = a / (8.0 * r);
  const double radicand = b * b - a / 4.0 + feed_per_tooth_mm * feed_per_tooth_mm;
  if (radicand < 0.0) return std::nullopt;
  const double sin_c = std::sqrt(radicand) / r;
  return sin_c >= 1.0 ? kPi / 2.0 : std::asin(sin_c);
}

double feed_per_tooth_outside_mm(double ball_radius_mm, double pick_feed_mm, double roughness_mm) {
  return p_of(pick_feed_mm) +
         std::sqrt(8.0 * ball_radius_mm * roughness_mm - pick_feed_mm * pick_feed_mm);
}

double feed_per_tooth_dead_centre_mm(double ball_radius_mm, double roughness_mm,
                                     double inclination_rad) {
  const double rs = ball_radius_mm * std::sin(inclination_rad);
  return std::sqrt(rs * rs + 2.0 * ball_radius_mm * roughness_mm - roughness_mm * roughness_mm);
}

double feed_per_tooth_mm(double ball_radius_mm, double pick_feed_mm, double roughness_mm,
                         double inclination_rad) {
  return std::min(feed_per_tooth_outside_mm(ball_radius_mm, pick_feed_mm, roughness_mm),
                  feed_per_tooth_dead_centre_mm(ball_radius_mm, roughness_mm, inclination_rad));
}

double feed_mm_per_min(double feed_per_tooth_mm, int teeth, double spindle_rpm) {
  return feed_per_tooth_mm * teeth * spindle_rpm;
}

double roughness_feed_mm_per_s(const CuttingParams& params, double inclination_rad) {
  const double ft = feed_per_tooth_mm(params.ball_radius_mm, params.pick_feed_mm,
                                      params.roughness_target_um * 1e-3, inclination_rad);
  return feed_mm_per_min(ft, params.teeth, params.spindle_rpm) / 60.0;
}

double inclination_from_tangent_rad(const Vec3& tangent) {
  return std::atan2(tangent.z(), tangent.head<2>().norm());
}

double inclination_from_normal_rad(const Vec3& contact_normal, const Vec3& feed_direction,
                                   const Vec3& tool_axis) {
  const Vec3 a = tool_axis.normalized();
  const Vec3 across = feed_direction - feed_direction.dot(a) * a;  // feed ⟂ tool axis
  const double across_norm = across.norm();
  if (!(across_norm > 1e-12 * feed_direction.norm())) {
    return std::atan2(contact_normal.cross(a).norm(), contact_normal.dot(a));
  }
  // A surface climbing along the feed tilts its normal against the feed direction.
  return std::atan2(-contact_normal.dot(across) / across_norm, contact_normal.dot(a));
}

}  // namespace ncd::feed
