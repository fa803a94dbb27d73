// The motion of one rotary index (docs/planner.md §3g): the rotary axis turned from rest to rest
// while X, Y and Z stand still, in the shortest time its speed, acceleration and jerk limits
// allow. The profile is the closed-form double S of Biagiotti and Melchiorri (Trajectory
// Planning for Automatic Machines and Robots, 2008, §3.4) for zero end speeds, symmetric:
//
//     jerk  +j ▁▁        ▁▁ ... (cruise) ...        ▁▁
//              0  ‾‾‾‾‾‾‾  -j                  -j  ‾‾‾‾‾‾‾  +j
//           |Tj|  Ta−2Tj |Tj|       Tv        |Tj|  Ta−2Tj |Tj|
//
// With h = |to − from|, v, a, j the limits:
//   - the acceleration phase lasts Ta: Tj = a/j, Ta = Tj + v/a when v·j ≥ a² (a is reached),
//     else Tj = √(v/j), Ta = 2 Tj; it covers v·Ta/2, the deceleration the same;
//   - if h ≥ v·Ta the speed v is held for Tv = h/v − Ta;
//   - else no cruise (Tv = 0) and a lower peak: with a reached when h ≥ 2a³/j², Tj = a/j and
//     Ta = Tj/2 + √((Tj/2)² + h/a); else Tj = (h/(2j))^(1/3), Ta = 2 Tj.
// The peak speed is then (Ta − Tj)·j·Tj, the peak acceleration j·Tj, the duration 2 Ta + Tv, and
// h = peak speed × (Ta + Tv) in each case. position_deg() evaluates the profile in closed form:
// no allocation, no iteration; the cycle calls it once a period.
#pragma once

#include <optional>

#include "feed/feed_limits.hpp"

namespace ncd::motion {

struct IndexLimits {
  double max_speed_deg_per_s = 60.0;
  double max_accel_deg_per_s2 = 1800.0;
  double max_jerk_deg_per_s3 = 36000.0;
};

// The limits an index turns under: the machine's rotary axis ([axis.a] or [axis.b]), its speed
// capped by a G1's feed where the index has one (none: a rapid). The planner (job.cpp) and the
// estimate of `ncd check` both take them from here.
IndexLimits index_limits(const feed::RotaryLimits& axis, std::optional<double> feed_deg_per_min);

class IndexProfile {
 public:
  IndexProfile() = default;
  // Limits must be finite and > 0 (the machine file's ranges); from and to finite.
  IndexProfile(double from_deg, double to_deg, const IndexLimits& limits);

  double from_deg() const { return from_; }
  double to_deg() const { return to_; }
  double duration_s() const { return 2.0 * ta_ + tv_; }
  double peak_speed_deg_per_s() const { return v_peak_; }
  double peak_accel_deg_per_s2() const { return j_ * tj_; }
  double cruise_s() const { return tv_; }
  // The axis's position t seconds after the index began: from_deg before 0, to_deg from the
  // duration on, the double S between.
  double position_deg(double t_s) const;

 private:
  double displacement(double t_s) const;  // |travel| at t within the acceleration phase
  double from_ = 0.0, to_ = 0.0, sign_ = 1.0, h_ = 0.0;
  double j_ = 0.0, tj_ = 0.0, ta_ = 0.0, tv_ = 0.0, v_peak_ = 0.0;
};

}  // namespace ncd::motion
