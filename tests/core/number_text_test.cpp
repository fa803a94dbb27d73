// core/number_text.hpp: the project's number formatters against printf's own digits (the
// reference: "%.*f" and "%.*g" in the C library), and their two rules of their own: trailing
// zeros trimmed down to a minimum, and no negative zero.
#include "core/number_text.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "tests/common/seed.hpp"

namespace ncd::text {
namespace {

std::string printf_fixed(double v, int decimals) {
  char b[64];
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

}  // namespace
}  // namespace ncd::text
