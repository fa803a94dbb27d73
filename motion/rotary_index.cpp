// The double-S index profile (rotary_index.hpp explains it).
#include "motion/rotary_index.hpp"

#include <algorithm>
#include <cmath>

namespace ncd::motion {

IndexLimits index_limits(const feed::RotaryLimits& axis, std::optional<double> feed_deg_per_min) {
  IndexLimits l{axis.max_feed_deg_per_min / 60.0, axis.max_accel_deg_per_s2,
                axis.max_jerk_deg_per_s3};
  if (feed_deg_per_min)
    l.max_speed_deg_per_s = std::min(l.max_speed_deg_per_s, *feed_deg_per_min / 60.0);
  return l;
}

IndexProfile::IndexProfile(double from_deg, double to_deg, const IndexLimits& limits)
    : from_(from_deg), to_(to_deg) {
  const double v = limits.max_speed_deg_per_s, a = limits.max_accel_deg_per_s2;
  j_ = limits.max_jerk_deg_per_s3;
  h_ = std::abs(to_deg - from_deg);
  sign_ = to_deg >= from_deg ? 1.0 : -1.0;
  if (!(h_ > 0.0)) return;  // nothing to turn: duration 0
  if (v * j_ >= a * a) {
    tj_ = a / j_;
    ta_ = tj_ + v / a;
  } else {
    tj_ = std::sqrt(v / j_);
    ta_ = 2.0 * tj_;
  }
  tv_ = h_ / v - ta_;
  if (tv_ < 0.0) {
    tv_ = 0.0;
    if (h_ >= 2.0 * a * a * a / (j_ * j_)) {
      tj_ = a / j_;
      ta_ = 0.5 * tj_ + std::sqrt(0.25 * tj_ * tj_ + h_ / a);
    } else {
      tj_ = std::cbrt(h_ / (2.0 * j_));
      ta_ = 2.0 * tj_;
    }
  }
  v_peak_ = (ta_ - tj_) * j_ * tj_;
}

// The travel t into the acceleration phase (0 ≤ t ≤ Ta): jerk +j for Tj, the peak acceleration
// held, jerk −j for the last Tj.
double IndexProfile::displacement(double t) const {
  const double a_peak = j_ * tj_;
  if (t < tj_) return j_ * t * t * t / 6.0;
  if (t < ta_ - tj_) return a_peak / 6.0 * (3.0 * t * t - 3.0 * tj_ * t + tj_ * tj_);
  const double r = ta_ - t;
  return v_peak_ * ta_ / 2.0 - v_peak_ * r + j_ * r * r * r / 6.0;
}

double IndexProfile::position_deg(double t_s) const {
  const double total = duration_s();
  if (!(t_s > 0.0)) return from_;
  if (t_s >= total) return to_;
  double q = 0.0;
  if (t_s <= ta_) {
    q = displacement(t_s);
  } else if (t_s <= ta_ + tv_) {
    q = v_peak_ * ta_ / 2.0 + v_peak_ * (t_s - ta_);
  } else {
    q = h_ - displacement(total - t_s);  // the deceleration mirrors the acceleration
  }
  return from_ + sign_ * q;
}

}  // namespace ncd::motion
