// Choi's ball-end roughness model (paper 004, docs/feedrate.md §1): the peak-to-valley
// roughness R_max left by a ball-end mill as a function of pick feed, feed per tooth and the
// inclination of the surface, its inverse (the feed per tooth that meets a roughness target)
// and the feed that follows. The model is explained once, in roughness.cpp.
#pragma once

#include <optional>

#include "core/geometry.hpp"

namespace ncd::feed {

// The cutting process of one finishing job. Lengths in mm, roughness in µm (an edge unit).
struct CuttingParams {
  double ball_radius_mm = 5.0;        // r
  double pick_feed_mm = 0.5;          // f_p, step-over between passes; 0 for a single pass
  int teeth = 2;                      // z
  double spindle_rpm = 10000.0;       // N
  double roughness_target_um = 10.0;  // R_max wanted on the surface
};

// Throws InputError naming the value, the limit and a way out: non-positive or non-finite
// values (f_p may be 0), f_p ≥ 2r, R ≥ r, and 8 r R < f_p² (the pick feed alone leaves cusps
// higher than the target).
void validate(const CuttingParams& params);

// R_max outside the dead-centre zone, |α| > α_c (eq. 2), mm; f_p = 0 gives f_t² / (8r).
double roughness_outside_mm(double ball_radius_mm, double pick_feed_mm, double feed_per_tooth_mm);
// R_max inside the dead-centre zone, |α| ≤ α_c (eq. 3), mm; needs f_t ≤ r.
double roughness_dead_centre_mm(double ball_radius_mm, double feed_per_tooth_mm,
                                double inclination_rad);
// R_max = max(eq. 2, eq. 3), mm: the model at any α without a branch test.
double roughness_mm(double ball_radius_mm, double pick_feed_mm, double feed_per_tooth_mm,
                    double inclination_rad);
// α_c where the branches meet (eq. 4), in [0, π/2]; nullopt below f_t ≈ 0.53 f_p, where eq. 2
// governs at every α.
std::optional<double> critical_angle_rad(double ball_radius_mm, double pick_feed_mm,
                                         double feed_per_tooth_mm);

// Feed per tooth for target R outside the dead-centre zone (eq. 5), mm; needs 8 r R ≥ f_p².
double feed_per_tooth_outside_mm(double ball_radius_mm, double pick_feed_mm, double roughness_mm);
// Feed per tooth for target R inside the dead-centre zone (eq. 6), mm.
double feed_per_tooth_dead_centre_mm(double ball_radius_mm, double roughness_mm,
                                     double inclination_rad);
// f_t(R, α) = min(eq. 5, eq. 6), mm: the inverse of roughness_mm, continuous in α.
double feed_per_tooth_mm(double ball_radius_mm, double pick_feed_mm, double roughness_mm,
                         double inclination_rad);

// F = f_t z N (§1.2), mm/min.
double feed_mm_per_min(double feed_per_tooth_mm, int teeth, double spindle_rpm);
// The feed that keeps R_max at the target at inclination α, mm/s; params must be validated.
double roughness_feed_mm_per_s(const CuttingParams& params, double inclination_rad);

// Sign convention of α (only |α| enters the model): positive when the tool climbs along the
// feed direction (up-milling a slope), negative descending, in [−π/2, π/2].
//
// α of a 3-axis path from its tangent (any length): asin(t_z) of the unit tangent (§1.4).
double inclination_from_tangent_rad(const Vec3& tangent);
// α from the contact normal n (from the surface towards the tool), the feed direction t and
// the tool axis a (from the tip towards the spindle), none need be unit: the tilt of n away
// from a in the plane of a and t. Equals inclination_from_tangent_rad for a surface whose
// normal lies in that plane. Where t is parallel to a (a plunge) there is no feed direction
// and the whole angle between n and a is returned.
double inclination_from_normal_rad(const Vec3& contact_normal, const Vec3& feed_direction,
                                   const Vec3& tool_axis = Vec3::UnitZ());

}  // namespace ncd::feed
