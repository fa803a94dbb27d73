// motion/sliding_min.hpp, the planner's running minimum of its window's axis scales: against a
// scan of the window (the slow reference it replaced) after every push and drop, on random
// sequences with many ties and plateaus, the window filled to its capacity and emptied, and
// cleared between runs (as Planner::restart does). The seed is printed.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <deque>
#include <random>

#include "motion/sliding_min.hpp"
#include "tests/common/seed.hpp"

namespace ncd::motion {
namespace {

TEST(SlidingMin, EmptyGivesTheDefault) {
  SlidingMin m;
  m.reserve(4);
  EXPECT_EQ(m.min_or(1.0), 1.0);
  m.push(0, 0.25);
  EXPECT_EQ(m.min_or(1.0), 0.25);
  m.drop(0);
  EXPECT_EQ(m.min_or(1.0), 1.0);
  m.push(1, 0.5);
  m.clear();
  EXPECT_EQ(m.min_or(1.0), 1.0);
}

TEST(SlidingMin, MatchesAScanOfTheWindow) {
  const std::uint64_t seed = test::seed();
  std::mt19937_64 rng(seed);
  constexpr std::size_t kCapacity = 64;
  SlidingMin m;
  m.reserve(kCapacity);
  std::deque<double> window;  // the reference: the window itself, scanned
  std::uint64_t front = 0;    // the sequence number of window.front()
  std::uniform_int_distribution<int> op(0, 99), level(0, 7);
  std::uniform_real_distribution<double> value(0.01, 1.0);
  long checks = 0;
  for (int step = 0; step < 200000; ++step) {
    const int o = op(rng);
    if (o < 2) {  // restart: the planner clears the window
      m.clear();
      front += window.size();
      window.clear();
    } else if ((o < 52 && window.size() < kCapacity) || window.empty()) {
      // Few distinct levels (ties and plateaus, as the planner's scales have), or any value.
      const double v = o % 2 == 0 ? 0.125 * level(rng) + 0.125 : value(rng);
      m.push(front + window.size(), v);
      window.push_back(v);
    } else {
      m.drop(front);
      window.pop_front();
      ++front;
    }
    const double scan =
        window.empty() ? 1.0 : std::min(1.0, *std::min_element(window.begin(), window.end()));
    ASSERT_EQ(m.min_or(1.0), scan) << "step " << step << ", seed " << seed;
    ASSERT_LE(m.size(), window.size()) << "step " << step << ", seed " << seed;
    ++checks;
  }
  EXPECT_EQ(checks, 200000);
}

}  // namespace
}  // namespace ncd::motion
