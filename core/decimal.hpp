// One strict reader of decimal numbers for every text format ncd reads by hand (teach points,
// frame points, robot touch points), and one checked conversion of numbers to integers for
// every JSON and TOML integer. docs/input-ranges.md states the grammar and the decisions.
//
// Grammar (the whole token, nothing before or after it):
//   number   = [sign] mantissa [exponent]
//   sign     = "+" | "-"                      (one sign at most: "+-10" is malformed)
//   mantissa = digits ["." [digits]] | "." digits
//   exponent = ("e" | "E") [sign] digits
// No hexadecimal ("0x1p5"), no "inf" or "nan", no spaces, no thousands separators, no locale.
// The value is the nearest double (std::from_chars, chars_format::general). Its magnitude must
// be 0 or within [DBL_MIN, DBL_MAX] = [2.2250738585072014e-308, 1.7976931348623157e+308]:
// a nonzero number that rounds below DBL_MIN (a subnormal such as 1e-310, or 1e-400) is
// refused as too small, a number above DBL_MAX (1e400) as too large. A negative zero reads 0.
#pragma once

#include <charconv>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <system_error>

#include "core/error.hpp"

namespace ncd {

enum class DecimalError { None, Malformed, TooLarge, TooSmall };

struct DecimalResult {
  double value = 0.0;
  DecimalError error = DecimalError::None;
  explicit operator bool() const { return error == DecimalError::None; }
};

namespace detail {
inline bool is_digit(char c) {
  return c >= '0' && c <= '9';
}
}  // namespace detail

// Reads the whole of text as a number of the grammar above.
inline DecimalResult parse_decimal(std::string_view text) {
  using detail::is_digit;
  DecimalResult out;
  std::size_t i = 0;
  const std::size_t n = text.size();
  bool negative = false;
  if (i < n && (text[i] == '+' || text[i] == '-')) negative = text[i++] == '-';
  const std::size_t mantissa_begin = i;
  std::size_t int_digits = 0, frac_digits = 0;
  // Decimal position of the first nonzero digit relative to the point, to tell an underflow
  // from an overflow when from_chars reports result_out_of_range.
  long long lead = 0;
  bool nonzero = false;
  for (; i < n && is_digit(text[i]); ++i, ++int_digits) {
    if (!nonzero && text[i] != '0') {
      nonzero = true;
      lead = 0;
    }
    if (nonzero) ++lead;
  }
  if (i < n && text[i] == '.') {
    ++i;
    for (long long pos = 0; i < n && is_digit(text[i]); ++i, ++frac_digits) {
      --pos;
      if (!nonzero && text[i] != '0') {
        nonzero = true;
        lead = pos + 1;
      }
    }
  }
  if (int_digits + frac_digits == 0) {
    out.error = DecimalError::Malformed;
    return out;
  }
  long long exponent = 0;
  if (i < n && (text[i] == 'e' || text[i] == 'E')) {
    ++i;
    bool exp_negative = false;
    if (i < n && (text[i] == '+' || text[i] == '-')) exp_negative = text[i++] == '-';
    std::size_t exp_digits = 0;
    for (; i < n && is_digit(text[i]); ++i, ++exp_digits) {
      if (exponent < 1'000'000'000) exponent = exponent * 10 + (text[i] - '0');
    }
    if (exp_digits == 0) {
      out.error = DecimalError::Malformed;
      return out;
    }
    if (exp_negative) exponent = -exponent;
  }
  if (i != n) {
    out.error = DecimalError::Malformed;
    return out;
  }
  double v = 0.0;
  const char* first = text.data() + mantissa_begin;
  const auto r = std::from_chars(first, text.data() + n, v, std::chars_format::general);
  if (r.ec == std::errc::result_out_of_range) {
    out.error = lead + exponent > 0 ? DecimalError::TooLarge : DecimalError::TooSmall;
    return out;
  }
  if (r.ec != std::errc() || r.ptr != text.data() + n || !std::isfinite(v)) {
    out.error = DecimalError::Malformed;
    return out;
  }
  if (v != 0.0 && v < std::numeric_limits<double>::min()) {
    out.error = DecimalError::TooSmall;
    return out;
  }
  out.value = v == 0.0 ? 0.0 : (negative ? -v : v);
  return out;
}

// Why a token is not a number, for messages: "is not a decimal number ...", "is too large ...".
inline std::string decimal_error_text(DecimalError e) {
  switch (e) {
    case DecimalError::None:
      return "is a number";
    case DecimalError::Malformed:
      return "is not a number: write a decimal number, digits with an optional sign, point "
             "and exponent, such as -12.5 or 1.5e-3 (no hexadecimal, inf or nan)";
    case DecimalError::TooLarge:
      return "is too large: its magnitude is above 1.8e308, the largest double";
    case DecimalError::TooSmall:
      return "is too small: it is not 0 but its magnitude is below 2.2e-308, the smallest "
             "normal double (write 0 if zero is meant)";
  }
  return "is not a number";
}

// Reads a token as a number of the grammar above, or throws InputError "<where>: '<tok>' <why>".
inline double decimal_or_throw(std::string_view text, const std::string& where) {
  const DecimalResult r = parse_decimal(text);
  if (!r) throw InputError(where + ": '" + std::string(text) + "' " + decimal_error_text(r.error));
  return r.value;
}

// Short text that reads back as v, for messages: whole numbers below 1e15 in digits
// (3000000000), others in the shortest general form (0.0001, 1e-06, 1e+300, inf).
inline std::string number_text(double v) {
  char buf[64];
  const auto r = std::isfinite(v) && v == std::floor(v) && std::abs(v) < 1e15
                     ? std::to_chars(buf, buf + sizeof buf, static_cast<long long>(v))
                     : std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general);
  return std::string(buf, r.ptr);
}

// The one conversion of an input number to an integer: a whole number within [lo, hi], or an
// InputError naming the key, the value and the range. An integral double (3e2) is accepted;
// 4.9, 3e9 for an int, NaN and infinities are not. Never casts out of range.
inline std::int64_t checked_integer(double value, std::int64_t lo, std::int64_t hi,
                                    const std::string& name) {
  const auto range = [&] {
    return "; it must be a whole number from " + std::to_string(lo) + " to " + std::to_string(hi);
  };
  if (!std::isfinite(value) || value != std::floor(value)) {
    throw InputError(name + " = " + number_text(value) + " is not a whole number" + range());
  }
  // lo and hi are exact in double for |x| <= 2^53, and the comparison is done before the cast.
  if (value < static_cast<double>(lo) || value > static_cast<double>(hi)) {
    throw InputError(name + " = " + number_text(value) + " is out of range" + range());
  }
  return static_cast<std::int64_t>(value);
}

inline std::int64_t checked_integer(std::int64_t value, std::int64_t lo, std::int64_t hi,
                                    const std::string& name) {
  if (value < lo || value > hi) {
    throw InputError(name + " = " + std::to_string(value) +
                     " is out of range; it must be a whole number from " + std::to_string(lo) +
                     " to " + std::to_string(hi));
  }
  return value;
}

// A real input value within [lo, hi] (a documented plausible range, docs/input-ranges.md), or an
// InputError naming the value, the range, the unit and a way out.
inline double checked_range(double value, double lo, double hi, const std::string& name,
                            const std::string& unit, const std::string& way_out) {
  if (!std::isfinite(value) || value < lo || value > hi) {
    throw InputError(name + " = " + number_text(value) + " is outside the plausible range [" +
                     number_text(lo) + ", " + number_text(hi) + "]" +
                     (unit.empty() ? "" : " " + unit) + "; " + way_out +
                     " (ranges: docs/input-ranges.md)");
  }
  return value;
}

}  // namespace ncd
