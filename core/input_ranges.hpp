// The plausible range of every number a user gives ncd: the machine file, the service config,
// path files and control requests. A value outside is refused at the edge with its name, the
// range and a way out (checked_range() in core/decimal.hpp), so that nothing behind the edge
// (planner buffers sized from v/a, walk lengths from the chord tolerance) is ever asked to work
// with 1e12 mm/min or a 1e-9 mm tolerance. The ranges are wide (every real machine fits) but
// finite; docs/input-ranges.md lists them with their reasons. Keep the two in step.
#pragma once

namespace ncd::ranges {

struct Range {
  double lo;
  double hi;
  const char* unit;
};

// Machine file, top level.
inline constexpr Range kPeriodS{1e-4, 0.1, "s"};  // 0.1 ms to 100 ms interpolation period
inline constexpr Range kMaxFeedMmPerMin{1.0, 120000.0, "mm/min"};   // 120 m/min: linear motors
inline constexpr Range kMaxAccelMmPerS2{10.0, 100000.0, "mm/s^2"};  // 0.001 g to 10 g
inline constexpr Range kMaxJerkMmPerS3{100.0, 1e7, "mm/s^3"};       // 0.1 to 10 000 m/s^3
inline constexpr Range kChordToleranceMm{1e-4, 1.0, "mm"};          // 0.1 um to 1 mm
// [axis.a] / [axis.b]: the rotary index axis (degrees).
inline constexpr Range kRotaryFeedDegPerMin{1.0, 360000.0, "deg/min"};  // up to 1000 rev/min
inline constexpr Range kRotaryAccelDegPerS2{1.0, 1e6, "deg/s^2"};
inline constexpr Range kRotaryJerkDegPerS3{10.0, 1e8, "deg/s^3"};
// [cutting]
inline constexpr Range kBallRadiusMm{0.01, 100.0, "mm"};
inline constexpr Range kPickFeedMm{0.0, 100.0, "mm"};
inline constexpr Range kSpindleRpm{1.0, 200000.0, "rpm"};
inline constexpr Range kRoughnessTargetUm{0.01, 1000.0, "um"};
// [link]
inline constexpr Range kXoffTimeoutS{0.01, 3600.0, "s"};
inline constexpr Range kReconnectMaxS{0.1, 3600.0, "s"};
// [encoder]
inline constexpr Range kEncoderChordToleranceMm{1e-4, 10.0, "mm"};
inline constexpr Range kTimeToleranceS{0.0, 10.0, "s"};
inline constexpr Range kMaxBlockS{0.0, 3600.0, "s"};
// Programs (path files, chamfer jobs): the programmed feed and spindle speed, coordinates.
inline constexpr Range kProgramFeedMmPerMin{0.1, 120000.0, "mm/min"};
inline constexpr Range kProgramSpindleRpm{1.0, 200000.0, "rpm"};
inline constexpr Range kCoordinateMm{-100000.0, 100000.0, "mm"};  // 100 m either way
// Control requests.
inline constexpr double kMinSubscribeHz = 0.1;  // one status line every 10 s at the slowest

}  // namespace ncd::ranges
