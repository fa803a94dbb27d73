// The live limit rules of a service job (docs/service.md, "Live limit rules"). `ncd replay`
// accepts a run only when no setpoint exceeds a limit (motion/run_stats.hpp); a live job cannot
// wait for its end, so the service checks every setpoint as it drains it, before the setpoint
// reaches the setpoints file or the block encoder:
//
//   feed    v_k        ≤ F_max · max(1, o) · (1 + r)
//   accel   |a_k|      ≤ a_max · (1 + r)
//   jerk    |j_k|      ≤ j_max · (1 + r)
//   chord   e_k        ≤ ε_c · max(1, o)² · (1 + r)
//
// with r = motion::kViolationRel (replay's relative excess) and o the highest feed override of
// the job so far. The override scales the feed bound and, since a period's chord error grows as
// the square of the distance walked in it (e ≈ κ (vT)² / 8), the chord bound by o²; the planner
// keeps acceleration and jerk within their limits at any override, so those bounds do not move.
// Every violation is counted and reported in the status; a rule whose action is Error ends the
// job in error at the first setpoint that breaks it, and that setpoint is not emitted. The step
// rule (motion/step_guard.hpp) is the cycle's own and always ends the job. A check is a few
// comparisons: no allocation, no exception, a result code.
#pragma once

#include <cstdint>

#include "feed/feed_limits.hpp"
#include "motion/job.hpp"
#include "motion/run_stats.hpp"

namespace ncd::service {

enum class RuleAction : std::uint8_t { Report, Error };
enum class LimitKind : std::uint8_t { None, Feed, Accel, Jerk, Chord };

// "feed", "accel", "jerk", "chord"; "none".
const char* to_string(LimitKind kind);
// "mm/min", "mm/s2", "mm/s3", "mm".
const char* unit(LimitKind kind);

struct LiveLimitRules {
  double max_feed_mm_per_s = 100.0;
  double max_accel_mm_per_s2 = 1000.0;
  double max_jerk_mm_per_s3 = 2e4;
  double chord_tolerance_mm = 0.001;
  RuleAction feed = RuleAction::Error, accel = RuleAction::Error, jerk = RuleAction::Error,
             chord = RuleAction::Error;

  // The machine's own limits, every rule ending the job.
  static LiveLimitRules from(const feed::MachineLimits& limits) {
    LiveLimitRules r;
    r.max_feed_mm_per_s = limits.max_feed_mm_per_min / 60.0;
    r.max_accel_mm_per_s2 = limits.max_accel_mm_per_s2;
    r.max_jerk_mm_per_s3 = limits.max_jerk_mm_per_s3;
    r.chord_tolerance_mm = limits.chord_tolerance_mm;
    return r;
  }
};

// What the checks found so far in one job.
struct LiveViolations {
  std::int64_t feed = 0, accel = 0, jerk = 0, chord = 0;
  std::int64_t total() const { return feed + accel + jerk + chord; }
  // The first violation of a rule whose action is Error (None: the job may go on).
  LimitKind fatal = LimitKind::None;
  double fatal_value = 0.0, fatal_limit = 0.0;  // in the unit of `fatal` (mm/min for feed)
  double fatal_t_s = 0.0, fatal_s_mm = 0.0;
};

class LiveLimitCheck {
 public:
  explicit LiveLimitCheck(const LiveLimitRules& rules) : rules_(rules) {}

  void set_override(double fraction) {
    if (fraction > override_peak_) override_peak_ = fraction;
  }

  // Counts what sp breaks; returns the kind of the first Error rule it breaks (kept in
  // violations().fatal), None when the setpoint may be emitted.
  LimitKind check(const motion::Setpoint& sp) {
    const double k = 1.0 + motion::kViolationRel;
    const double o = override_peak_ > 1.0 ? override_peak_ : 1.0;
    LimitKind worst = LimitKind::None;
    const auto test = [&](LimitKind kind, double value, double allowed, RuleAction action,
                          std::int64_t& count, double shown_scale) {
      if (value <= allowed) return;  // a NaN is never within a bound
      ++count;
      if (action == RuleAction::Error && worst == LimitKind::None) {
        worst = kind;
        if (v_.fatal == LimitKind::None) {
          v_.fatal = kind;
          v_.fatal_value = value * shown_scale;
          v_.fatal_limit = allowed * shown_scale;
          v_.fatal_t_s = sp.t_s;
          v_.fatal_s_mm = sp.s_mm;
        }
      }
    };
    test(LimitKind::Feed, sp.v_mm_per_s, rules_.max_feed_mm_per_s * o * k, rules_.feed, v_.feed,
         60.0);
    test(LimitKind::Accel, sp.a_mm_per_s2 < 0 ? -sp.a_mm_per_s2 : sp.a_mm_per_s2,
         rules_.max_accel_mm_per_s2 * k, rules_.accel, v_.accel, 1.0);
    test(LimitKind::Jerk, sp.j_mm_per_s3 < 0 ? -sp.j_mm_per_s3 : sp.j_mm_per_s3,
         rules_.max_jerk_mm_per_s3 * k, rules_.jerk, v_.jerk, 1.0);
    test(LimitKind::Chord, sp.chord_error_mm, rules_.chord_tolerance_mm * o * o * k, rules_.chord,
         v_.chord, 1.0);
    return worst;
  }

  const LiveViolations& violations() const { return v_; }
  const LiveLimitRules& rules() const { return rules_; }

 private:
  LiveLimitRules rules_;
  double override_peak_ = 1.0;
  LiveViolations v_;
};

}  // namespace ncd::service
