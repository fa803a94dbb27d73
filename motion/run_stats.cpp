// Run statistics: feed error against the true arc length, chord error, tangential
// acceleration and jerk, the jerk vector from the setpoints (third difference), limit
// violations beyond kViolationRel, roughness, binding limits.
#include "motion/run_stats.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace ncd::motion {

double RunStats::feed_error_rms_rel() const {
  return feed_error_steps > 0 ? std::sqrt(feed_error_sum_sq / static_cast<double>(feed_error_steps))
                              : 0.0;
}

std::int64_t RunStats::limit_violations() const {
  return violations_feed + violations_accel + violations_jerk + violations_chord +
         violations_rotary;
}

namespace {

// The per-axis differences of the setpoints (the first three periods only have fewer).
void record_axes(RunStats& st, double T, const Vec3& p) {
  const auto& q = st.last_p_mm;
  for (int i = 0; i < 3; ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (st.cycles >= 2) {
      st.axis_feed_max_mm_per_s[k] =
          std::max(st.axis_feed_max_mm_per_s[k], std::abs(p[i] - q[2][i]) / T);
    }
    if (st.cycles >= 3) {
      st.axis_accel_max_mm_per_s2[k] = std::max(st.axis_accel_max_mm_per_s2[k],
                                                std::abs(p[i] - 2.0 * q[2][i] + q[1][i]) / (T * T));
    }
    if (st.cycles >= 4) {
      st.axis_jerk_max_mm_per_s3[k] =
          std::max(st.axis_jerk_max_mm_per_s3[k],
                   std::abs(p[i] - 3.0 * q[2][i] + 3.0 * q[1][i] - q[0][i]) / (T * T * T));
    }
  }
}

// The rotary axis's differences, as for X, Y, Z, and each against its limit. An index's time
// counts its periods; an index is counted as it lands (the first period at rest after it).
void record_rotary(RunStats& st, const feed::MachineLimits& l, const Setpoint& sp,
                   bool was_indexing) {
  if (!l.rotary.present()) return;
  const double T = l.period_s, r = sp.rotary_deg;
  const auto& q = st.last_rotary_deg;
  if (!st.rotary_started) st.last_rotary_deg = {r, r, r};  // at rest where the first one stands
  st.rotary_started = true;
  const double v = std::abs(r - q[2]) / T;
  const double a = std::abs(r - 2.0 * q[2] + q[1]) / (T * T);
  const double j = std::abs(r - 3.0 * q[2] + 3.0 * q[1] - q[0]) / (T * T * T);
  st.rotary_speed_max_deg_per_s = std::max(st.rotary_speed_max_deg_per_s, v);
  st.rotary_accel_max_deg_per_s2 = std::max(st.rotary_accel_max_deg_per_s2, a);
  st.rotary_jerk_max_deg_per_s3 = std::max(st.rotary_jerk_max_deg_per_s3, j);
  const double k = 1.0 + kViolationRel;
  if (v > l.rotary.max_feed_deg_per_min / 60.0 * k || a > l.rotary.max_accel_deg_per_s2 * k ||
      j > l.rotary.max_jerk_deg_per_s3 * k) {
    ++st.violations_rotary;
  }
  if (sp.indexing || was_indexing) st.index_time_s += T;
  if (was_indexing && !sp.indexing) ++st.index_moves;
  st.last_rotary_deg = {q[1], q[2], r};
}

}  // namespace

std::string rotary_text(const RunStats& st, const feed::MachineLimits& l) {
  if (!l.rotary.present()) return {};
  const auto& r = l.rotary;
  char line[400];
  std::snprintf(line, sizeof line,
                "  rotary %c          %lld index moves in %.3f s; speed %.1f deg/min (limit %.6g), "
                "accel %.1f deg/s2 (limit %.6g), jerk %.0f deg/s3 (limit %.6g); %lld violations\n",
                static_cast<char>(r.axis - 'a' + 'A'), static_cast<long long>(st.index_moves),
                st.index_time_s, st.rotary_speed_max_deg_per_s * 60.0, r.max_feed_deg_per_min,
                st.rotary_accel_max_deg_per_s2, r.max_accel_deg_per_s2,
                st.rotary_jerk_max_deg_per_s3, r.max_jerk_deg_per_s3,
                static_cast<long long>(st.violations_rotary));
  return line;
}

nlohmann::ordered_json rotary_json(const RunStats& st, const feed::MachineLimits& l) {
  const auto& r = l.rotary;
  return {{"axis", std::string(1, r.axis)},
          {"index_moves", st.index_moves},
          {"index_time_s", st.index_time_s},
          {"speed_max_deg_per_min", st.rotary_speed_max_deg_per_s * 60.0},
          {"speed_limit_deg_per_min", r.max_feed_deg_per_min},
          {"accel_max_deg_per_s2", st.rotary_accel_max_deg_per_s2},
          {"accel_limit_deg_per_s2", r.max_accel_deg_per_s2},
          {"jerk_max_deg_per_s3", st.rotary_jerk_max_deg_per_s3},
          {"jerk_limit_deg_per_s3", r.max_jerk_deg_per_s3},
          {"violations", st.violations_rotary}};
}

std::array<AxisPeak, 3> axis_peaks(const RunStats& st, const feed::MachineLimits& l) {
  std::array<AxisPeak, 3> out{};
  for (std::size_t i = 0; i < 3; ++i) {
    const feed::AxisLimits& ax = l.axes[i];
    out[i] = {static_cast<char>('X' + i),     st.axis_feed_max_mm_per_s[i] * 60.0,
              st.axis_accel_max_mm_per_s2[i], st.axis_jerk_max_mm_per_s3[i],
              ax.max_feed_mm_per_min,         ax.max_accel_mm_per_s2,
              ax.max_jerk_mm_per_s3};
  }
  return out;
}

nlohmann::ordered_json axis_peaks_json(const RunStats& st, const feed::MachineLimits& l) {
  const auto lim = [](double x) {
    return std::isfinite(x) ? nlohmann::ordered_json(x) : nlohmann::ordered_json(nullptr);
  };
  nlohmann::ordered_json j = nlohmann::ordered_json::object();
  for (const AxisPeak& a : axis_peaks(st, l)) {
    j[std::string(1, static_cast<char>(a.axis - 'X' + 'x'))] = {
        {"feed_max_mm_per_min", a.feed_mm_per_min},
        {"feed_limit_mm_per_min", lim(a.feed_limit_mm_per_min)},
        {"accel_max_mm_per_s2", a.accel_mm_per_s2},
        {"accel_limit_mm_per_s2", lim(a.accel_limit_mm_per_s2)},
        {"jerk_max_mm_per_s3", a.jerk_mm_per_s3},
        {"jerk_limit_mm_per_s3", lim(a.jerk_limit_mm_per_s3)}};
  }
  return j;
}

std::string axis_peaks_text(const RunStats& st, const feed::MachineLimits& l) {
  if (!l.has_axis_limits()) return {};
  std::string text;
  for (const AxisPeak& a : axis_peaks(st, l)) {
    char line[240];
    const auto lim = [](double x, char* buf, std::size_t n) {
      if (std::isfinite(x)) {
        std::snprintf(buf, n, "%.6g", x);
      } else {
        std::snprintf(buf, n, "none");
      }
      return buf;
    };
    char f[32], ac[32], jk[32];
    std::snprintf(line, sizeof line,
                  "  axis %c            feed %.1f mm/min (limit %s), accel %.1f mm/s2 (limit %s), "
                  "jerk %.0f mm/s3 (limit %s)\n",
                  a.axis, a.feed_mm_per_min, lim(a.feed_limit_mm_per_min, f, sizeof f),
                  a.accel_mm_per_s2, lim(a.accel_limit_mm_per_s2, ac, sizeof ac), a.jerk_mm_per_s3,
                  lim(a.jerk_limit_mm_per_s3, jk, sizeof jk));
    text += line;
  }
  return text;
}

void record(RunStats& st, const JobConfig& config, const Setpoint& sp, double limit_mm_per_s,
            double roughness_um, double step_time_ns) {
  const auto& l = config.limits;
  ++st.cycles;
  st.duration_s = sp.t_s;
  record_rotary(st, l, sp, st.was_indexing);
  st.was_indexing = sp.indexing;
  const double sum = st.travelled_mm + sp.travelled_mm;  // Neumaier summation
  st.travelled_carry_mm += std::abs(st.travelled_mm) >= std::abs(sp.travelled_mm)
                               ? (st.travelled_mm - sum) + sp.travelled_mm
                               : (sp.travelled_mm - sum) + st.travelled_mm;
  st.travelled_mm = sum;
  const double abs_err = std::abs(sp.travelled_mm - sp.planned_ds_mm);
  st.feed_error_max_abs_mm = std::max(st.feed_error_max_abs_mm, abs_err);
  if (sp.planned_ds_mm >= kFeedErrorMinStepMm) {
    const double e = abs_err / sp.planned_ds_mm;
    st.feed_error_max_rel = std::max(st.feed_error_max_rel, e);
    st.feed_error_sum_sq += e * e;
    ++st.feed_error_steps;
  }
  st.chord_error_max_mm = std::max(st.chord_error_max_mm, sp.chord_error_mm);
  st.accel_max_mm_per_s2 = std::max(st.accel_max_mm_per_s2, std::abs(sp.a_mm_per_s2));
  st.jerk_max_mm_per_s3 = std::max(st.jerk_max_mm_per_s3, std::abs(sp.j_mm_per_s3));
  if (st.cycles >= 4) {
    const double t3 = l.period_s * l.period_s * l.period_s;
    const Vec3 d3 = sp.p - 3.0 * st.last_p_mm[2] + 3.0 * st.last_p_mm[1] - st.last_p_mm[0];
    st.jerk_vector_max_mm_per_s3 = std::max(st.jerk_vector_max_mm_per_s3, d3.norm() / t3);
  }
  record_axes(st, l.period_s, sp.p);
  st.last_p_mm = {st.last_p_mm[1], st.last_p_mm[2], sp.p};
  st.feed_max_mm_per_s = std::max(st.feed_max_mm_per_s, sp.v_mm_per_s);
  st.roughness_max_um = std::max(st.roughness_max_um, roughness_um);
  const double k = 1.0 + kViolationRel;
  if (sp.v_mm_per_s > limit_mm_per_s * k) ++st.violations_feed;
  if (std::abs(sp.a_mm_per_s2) > l.max_accel_mm_per_s2 * k) ++st.violations_accel;
  if (std::abs(sp.j_mm_per_s3) > l.max_jerk_mm_per_s3 * k) ++st.violations_jerk;
  if (sp.chord_error_mm > l.chord_tolerance_mm * k) ++st.violations_chord;
  if (!sp.converged) ++st.not_converged;
  ++st.cycles_by_limit[sp.limit_id];
  st.step_time_ns.add(step_time_ns);
}

std::string refusal(const RunStats& st, const JobConfig& config) {
  std::string why;
  const auto add = [&why](const std::string& part) { why += (why.empty() ? "" : "; ") + part; };
  if (st.limit_violations() > 0) {
    add(std::to_string(st.limit_violations()) + " limit violation(s) (feed " +
        std::to_string(st.violations_feed) + ", accel " + std::to_string(st.violations_accel) +
        ", jerk " + std::to_string(st.violations_jerk) + ", chord " +
        std::to_string(st.violations_chord) + ", rotary axis " +
        std::to_string(st.violations_rotary) + ")");
  }
  const double drift_allowed_mm =
      kDriftToleranceMm + config.limits.feed_tolerance_rel * st.path_length_mm;
  if (!(std::abs(st.drift_mm()) <= drift_allowed_mm)) {
    char text[160];
    std::snprintf(text, sizeof text, "arc-length drift %.6g mm (allowed %.6g mm)", st.drift_mm(),
                  drift_allowed_mm);
    add(text);
  }
  return why;
}

}  // namespace ncd::motion
