// The argument guide's distance (app/cli_guide.hpp) against a slow reference written from its
// definition (the optimal string alignment distance as a recursion over the last letters), on
// exact cases and random short words; and what `nearest` suggests.
#include "app/cli_guide.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <string>

#include "tests/common/seed.hpp"

namespace {

using ncd::app::edit_distance;
using ncd::app::nearest;

// d(i, j) of a[0..i), b[0..j): delete, insert, substitute, or swap the last two letters.
std::size_t osa_reference(const std::string& a, const std::string& b, std::size_t i,
                          std::size_t j) {
  if (i == 0) return j;
  if (j == 0) return i;
  std::size_t d = std::min({osa_reference(a, b, i - 1, j) + 1, osa_reference(a, b, i, j - 1) + 1,
                            osa_reference(a, b, i - 1, j - 1) + (a[i - 1] == b[j - 1] ? 0 : 1)});
  if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) {
    d = std::min(d, osa_reference(a, b, i - 2, j - 2) + 1);
  }
  return d;
}

TEST(CliGuide, DistanceOfKnownPairs) {
  EXPECT_EQ(edit_distance("", ""), 0U);
  EXPECT_EQ(edit_distance("", "abc"), 3U);
  EXPECT_EQ(edit_distance("chamfr", "chamfer"), 1U);
  EXPECT_EQ(edit_distance("pipe-raduis", "pipe-radius"), 1U);  // one transposition
  EXPECT_EQ(edit_distance("kitten", "sitting"), 3U);
  EXPECT_EQ(edit_distance("ca", "abc"), 3U);  // OSA, not the unrestricted distance (2)
}

TEST(CliGuide, DistanceAgreesWithTheRecursionOnRandomWords) {
  std::mt19937_64 rng(ncd::test::seed());
  std::uniform_int_distribution<int> len(0, 7), letter(0, 3);  // few letters: many swaps
  for (int k = 0; k < 3000; ++k) {
    std::string a, b;
    for (int n = len(rng); n > 0; --n) a += static_cast<char>('a' + letter(rng));
    for (int n = len(rng); n > 0; --n) b += static_cast<char>('a' + letter(rng));
    ASSERT_EQ(edit_distance(a, b), osa_reference(a, b, a.size(), b.size())) << a << " / " << b;
    ASSERT_EQ(edit_distance(a, b), edit_distance(b, a)) << a << " / " << b;
  }
}

TEST(CliGuide, NearestSuggestsOnlyWhatIsNear) {
  const std::vector<std::string> commands{"chamfer", "replay", "check", "stream", "serve"};
  EXPECT_EQ(nearest("chamfr", commands), "chamfer");
  EXPECT_EQ(nearest("chek", commands), "check");
  EXPECT_EQ(nearest("strem", commands), "stream");
  EXPECT_EQ(nearest("frobnicate", commands), std::nullopt);
  EXPECT_EQ(nearest("z", {"h", "o", "q"}), std::nullopt);  // a letter is near every letter
}

}  // namespace
