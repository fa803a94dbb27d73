// core/number_text.hpp: the project's number formatters against printf's own digits (the
// reference: "%.*f" and "%.*g" in the C library), and their two rules of their own: trailing
// zeros trimmed down to a minimum, and no negative zero.
#include "core/number_text.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>

#include "tests/common/seed.hpp"

namespace ncd::text {
namespace {

std::string printf_fixed(double v, int decimals) {
  char b[400];
  std::snprintf(b, sizeof b, "%.*f", decimals, v);
  return b;
}

TEST(NumberText, TrimmedKeepsTheMinimumDecimalsAndWritesNoNegativeZero) {
  EXPECT_EQ(trimmed(1.5, 3), "1.5");
  EXPECT_EQ(trimmed(2.0, 3), "2");
  EXPECT_EQ(trimmed(2.0, 3, 1), "2.0");
  EXPECT_EQ(trimmed(-0.0000001, 6, 1), "0.0");
  EXPECT_EQ(trimmed(-0.0, 3), "0");
  EXPECT_EQ(trimmed(-1.25, 6, 1), "-1.25");
  EXPECT_EQ(trimmed(1234567.0, 0), "1234567");
  EXPECT_EQ(fixed(-0.0004, 3), "0.000");
}

// append_trimmed appends exactly trimmed()'s text, and trimmed() is printf's "%.*f" with the
// zeros taken off: random values of every magnitude and sign (seed printed).
TEST(NumberText, AppendTrimmedIsTrimmedIsPrintfWithoutTheZeros) {
  std::mt19937_64 rng(test::seed());
  std::uniform_real_distribution<double> mantissa(-1.0, 1.0);
  std::uniform_int_distribution<int> exponent(-9, 9), decimals(0, 8), min_dec(0, 2);
  std::string buffer = "prefix ";
  for (int i = 0; i < 20000; ++i) {
    const double v = mantissa(rng) * std::pow(10.0, exponent(rng));
    const int d = decimals(rng), m = std::min(min_dec(rng), d);
    std::string want = printf_fixed(v, d);
    if (want.find('.') != std::string::npos) {
      const std::size_t keep = want.find('.') + static_cast<std::size_t>(m) + 1;
      while (want.size() > keep && want.back() == '0') want.pop_back();
      if (want.back() == '.') want.pop_back();
    }
    if (want[0] == '-' && want.find_first_not_of("0.", 1) == std::string::npos) want.erase(0, 1);
    ASSERT_EQ(trimmed(v, d, m), want) << v << " " << d << " " << m;
    const std::size_t before = buffer.size();
    append_trimmed(buffer, v, d, m);
    ASSERT_EQ(buffer.substr(before), want) << v;
    ASSERT_EQ(buffer.rfind("prefix ", 0), 0u);
    buffer.resize(before);
  }
}

// detail::fixed_exact (append_trimmed's digits) is printf's "%.*f" exactly where it answers, and
// answers for the numbers programs hold: values read from short decimal text, exact ties of
// round-half-to-even (odd multiples of 2^-k), random bit patterns (subnormals, huge values:
// outside its range it declines), with 0 to 18 decimals (seed printed).
TEST(NumberText, FixedExactIsPrintfDigitForDigit) {
  std::mt19937_64 rng(test::seed());
  std::uniform_int_distribution<int> decimals(0, 18), short_decimals(0, 7), exponent(0, 9);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  long answered = 0, declined = 0;
  const auto check = [&](double v, int d) {
    char mine[400];
    const char* end = detail::fixed_exact(mine, v, d);
    if (!end) {
      ++declined;
      // Declined only outside |v|·10^d < 9.2e18 (or beyond 18 decimals).
      ASSERT_FALSE(std::abs(v) * std::pow(10.0, d) < 9.0e18 && d <= 18) << v << " " << d;
      return;
    }
    ++answered;
    ASSERT_EQ(std::string(static_cast<const char*>(mine), end), printf_fixed(v, d))
        << v << " with " << d << " decimals";
  };
  for (int i = 0; i < 200000; ++i) {
    const int d = decimals(rng);
    char text[64];
    std::snprintf(text, sizeof text, "%.*f", short_decimals(rng),
                  unit(rng) * std::pow(10.0, exponent(rng)));
    check(std::strtod(text, nullptr), d);
    check(
        std::ldexp(static_cast<double>(rng() % 2000001) - 1000000.0, -static_cast<int>(rng() % 40)),
        d);
    const std::uint64_t bits = rng();
    double any = 0.0;
    std::memcpy(&any, &bits, sizeof any);
    if (std::isfinite(any)) check(any, d);
  }
  for (const double v : {0.0, -0.0, 0.5, 1.5, 2.5, -2.5, 0.0078125, 5e-7, -5e-7, 4.9e-324,
                         999999.9999995, 9.1e12, 9.3e12, 1e300}) {
    for (int d = 0; d <= 18; ++d) check(v, d);
  }
  EXPECT_GT(answered, 200000);
  EXPECT_GT(declined, 0);
}

}  // namespace
}  // namespace ncd::text
