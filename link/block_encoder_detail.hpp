// What the block encoder's files share (block_encoder.cpp, block_encoder_text.cpp,
// block_encoder_settings.cpp): the bounds on a move and a coordinate, powers of ten, the distance
// to a segment, and the writing of numbers into a block's text. The encoder is explained at the top
// of block_encoder.cpp.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <string>

#include "core/geometry.hpp"

namespace ncd::comms::encoder_detail {

inline constexpr double kTinyMoveMm = 1e-9;  // moves shorter than this carry no direction
inline constexpr double kMaxCoordMm = 1e9;   // beyond this a coordinate is not a machine's

inline double pow10(int n) {
  double s = 1.0;
  for (int i = 0; i < n; ++i) s *= 10.0;
  return s;
}

// Distance from p to the segment [a, b] (to a when the segment is a point).
inline double dist_to_segment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double l2 = ab.squaredNorm();
  if (l2 == 0.0) return (p - a).norm();
  const double t = std::clamp((p - a).dot(ab) / l2, 0.0, 1.0);
  return (a + t * ab - p).norm();
}

// units · 10^-decimals written with a decimal point, no trailing zeros: 10366 → "10.366",
// 10000 → "10.", −500 → "-0.5", 0 → "0.".
inline void append_fixed(std::string& out, std::int64_t units, int decimals) {
  if (units < 0) {
    out.push_back('-');
    units = -units;
  }
  std::int64_t scale = 1;
  for (int i = 0; i < decimals; ++i) scale *= 10;
  const std::int64_t ip = units / scale;
  std::int64_t frac = units % scale;
  char digits[24];
  const int n = std::snprintf(digits, sizeof digits, "%lld", static_cast<long long>(ip));
  out.append(digits, static_cast<std::size_t>(n));
  out.push_back('.');
  if (frac == 0) return;
  int width = decimals;
  while (frac % 10 == 0) {
    frac /= 10;
    --width;
  }
  const int m = std::snprintf(digits, sizeof digits, "%0*lld", width, static_cast<long long>(frac));
  out.append(digits, static_cast<std::size_t>(m));
}

inline void append_number(std::string& out, long n) {
  char digits[24];
  const int k = std::snprintf(digits, sizeof digits, "%ld", n);
  out.append(digits, static_cast<std::size_t>(k));
}

}  // namespace ncd::comms::encoder_detail
