// The seed of a random test sweep: NCD_TEST_SEED when set, else `fixed` if the suite pins one,
// else a fresh random one. Printed and recorded in the test's XML, so a failure can be replayed
// with NCD_TEST_SEED=<seed>.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <iostream>
#include <optional>
#include <random>
#include <string>

namespace ncd::test {

inline std::uint64_t seed(std::optional<std::uint64_t> fixed = std::nullopt) {
  std::uint64_t s = fixed ? *fixed : std::random_device{}();
  if (const char* env = std::getenv("NCD_TEST_SEED")) s = std::strtoull(env, nullptr, 10);
  std::cout << "[ seed     ] NCD_TEST_SEED=" << s << "\n";
  ::testing::Test::RecordProperty("seed", std::to_string(s));
  return s;
}

}  // namespace ncd::test
