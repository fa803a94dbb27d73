// Numbers as text: the one set of number formatters of the project, on the fmt library, for
// messages, reports, plots and the programs ncd writes. None depends on the locale, and none
// writes a negative zero ("-0", "-0.000"): a value that prints as zero prints without a sign.
#pragma once

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <string>

namespace ncd::text {

namespace detail {
// "-0.000" → "0.000", "-0" → "0": a negative value that rounded to zero.
inline std::string unsigned_zero(std::string s) {
  if (s.size() > 1 && s[0] == '-' && s.find_first_not_of("0.", 1) == std::string::npos) {
    s.erase(0, 1);
  }
  return s;
}

__extension__ using Uint128 = unsigned __int128;

// v with `decimals` decimals as printf's "%.Nf" writes it: the exact binary value rounded half to
// even. A double is m·2^e exactly (m < 2^53), so v·10^d = m·10^d·2^e is an integer of at most 113
// bits shifted right by −e, and the bits shifted out decide the rounding. For |v|·10^d < 2^63
// (9.2e18: the rounded value fits in 64 bits) and d ≤ 18; returns nullptr outside that range
// (and for NaN and the infinities), where std::to_chars takes over.
inline char* fixed_exact(char* out, double v, int decimals) {
  if (decimals < 0 || decimals > 18) return nullptr;
  std::uint64_t scale = 1;  // 10^d
  for (int i = 0; i < decimals; ++i) scale *= 10;
  if (!(std::abs(v) < 9.2e18 / static_cast<double>(scale))) return nullptr;
  // The fields of the IEEE 754 double: 52 bits of fraction, 11 of exponent.
  const auto bits = std::bit_cast<std::uint64_t>(v);
  const int biased = static_cast<int>((bits >> 52) & 0x7ff);
  const std::uint64_t fraction = bits & ((std::uint64_t{1} << 52) - 1);
  const std::uint64_t m = biased == 0 ? fraction : fraction | (std::uint64_t{1} << 52);
  const int e = (biased == 0 ? 1 : biased) - 1075;  // |v| = m·2^e
  const Uint128 x = static_cast<Uint128>(m) * scale;
  std::uint64_t q = 0;
  if (e >= 0) {
    q = static_cast<std::uint64_t>(x << e);
  } else if (e > -128) {
    const int k = -e;
    q = static_cast<std::uint64_t>(x >> k);
    const Uint128 rest = x & ((static_cast<Uint128>(1) << k) - 1);
    const Uint128 half = static_cast<Uint128>(1) << (k - 1);
    if (rest > half || (rest == half && (q & 1) != 0)) ++q;
  }  // else x < 2^113 is below half of 2^128: 0
  if (std::signbit(v)) *out++ = '-';
  out = std::to_chars(out, out + 20, q / scale).ptr;
  if (decimals > 0) {
    *out++ = '.';
    std::uint64_t frac = q % scale;
    for (int i = decimals - 1; i >= 0; --i) {
      out[i] = static_cast<char>('0' + frac % 10);
      frac /= 10;
    }
    out += decimals;
  }
  return out;
}
}  // namespace detail

// `digits` significant digits, as printf's %.Ng (6: as %g and an iostream's default), for
// messages: 1.5, 0.000123, 1.23457e+06.
inline std::string sig(double v, int digits = 6) {
  return detail::unsigned_zero(fmt::format("{:.{}g}", v, digits));
}

// `decimals` decimals, as printf's %.Nf: 8.3920, 0.0000.
inline std::string fixed(double v, int decimals) {
  return detail::unsigned_zero(fmt::format("{:.{}f}", v, decimals));
}

// `decimals` decimals, then the trailing zeros removed down to `min_decimals` (and the point
// with them when that is 0): G-code words X1.5 Z0, or 1.0 with min_decimals 1.
// append_trimmed writes the same text at the end of a buffer, without an allocation (for long
// listings such as the canonical program of `ncd check`). Its digits are printf's "%.Nf": from
// fixed_exact above for the numbers of programs (a third of std::to_chars' instructions, a
// tenth of fmt's "{:.Nf}", which in fmt 9 often takes its slow exact path), else from
// std::to_chars in fixed notation.
template <typename Buffer>
void append_trimmed(Buffer& out, double v, int decimals, int min_decimals = 0) {
  // 309 integer digits at most (DBL_MAX), a sign, a point, the decimals: on the stack up to
  // 30 decimals, else on the heap.
  decimals = std::max(decimals, 0);
  const std::size_t size = 320 + static_cast<std::size_t>(decimals);
  char local[350];
  std::string heap;
  if (size > sizeof local) heap.resize(size);
  char* const buf = heap.empty() ? local : heap.data();
  const char* end = detail::fixed_exact(buf, v, decimals);
  if (!end) end = std::to_chars(buf, buf + size, v, std::chars_format::fixed, decimals).ptr;
  const char* point = std::find(static_cast<const char*>(buf), end, '.');
  if (point != end) {
    const char* keep = point + min_decimals + 1;
    while (end > keep && end[-1] == '0') --end;
    if (end[-1] == '.') --end;
  }
  // "-0", "-0.0": a negative value that rounded to zero is written without its sign.
  const char* begin = buf;
  if (*begin == '-' && std::all_of(begin + 1, end, [](char c) { return c == '0' || c == '.'; }))
    ++begin;
  out.append(begin, static_cast<std::size_t>(end - begin));
}

inline std::string trimmed(double v, int decimals, int min_decimals = 0) {
  std::string s;
  append_trimmed(s, v, decimals, min_decimals);
  return s;
}

// A plot's tick label at v, ticks `step` apart: `digits` significant digits, and the tick that
// the accumulated steps put a rounding error away from zero (1.4e-17) written 0.
inline std::string tick(double v, double step, int digits = 6) {
  return sig(std::abs(v) <= 1e-9 * std::abs(step) ? 0.0 : v, digits);
}

// The shortest text that reads back as exactly v (fmt's default, as std::to_chars).
inline std::string shortest(double v) {
  return detail::unsigned_zero(fmt::format("{}", v));
}

// A point as "(x, y, z)", each coordinate shortest: the points error messages name.
template <typename Point>
std::string point(const Point& p) {
  return "(" + shortest(p.x()) + ", " + shortest(p.y()) + ", " + shortest(p.z()) + ")";
}

}  // namespace ncd::text
