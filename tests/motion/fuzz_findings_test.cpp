// The whole-pipeline fuzzer's inputs as regular tests: tests/fuzz/pipeline.hpp decodes each one
// into a machine and an RS-274/NGC program, interprets it, builds the motion::Job and walks every
// period through the same checks as the libFuzzer harness (feed, limit curve and F word,
// tangential acceleration and jerk, chord tolerance, envelope, progress within a bound, rest at
// the programmed end, no StepFault, no NaN), with the allocations of the periods counted by the
// operator new that no_alloc_test.cpp replaces in this binary.
//   - Every seed of tests/fuzz/corpus/pipeline/ (tests/ngc and LinuxCNC's samples on four
//     machines, random programs of the generator; a tenth of them under ASan, where the fuzz
//     stage of `make test` walks them all) is walked or refused, never a violation.
//   - Each finding of the fuzzer is a reproducer there, finding_<name>.ngc, and a test of its
//     own below that must walk it to its end (a refusal fails it too: the reproducer would no
//     longer reach the code it was found in).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "tests/common/allocation_counters.hpp"
#include "tests/common/sanitized.hpp"
#include "tests/fuzz/pipeline.hpp"

namespace ncd::fuzz::pipeline {
namespace {

namespace fs = std::filesystem;

const fs::path kCorpus = fs::path(NCD_SOURCE_DIR) / "tests" / "fuzz" / "corpus" / "pipeline";

long allocations() {
  return ncd::test::g_allocations.load();
}

Outcome run_file(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto* data = reinterpret_cast<const std::uint8_t*>(bytes.data());
  return run(decode(data, bytes.size()), allocations);
}

std::string kind(const Outcome& o) {
  return o.kind == Outcome::Walked    ? "walked"
         : o.kind == Outcome::Refused ? "refused"
                                      : "violation";
}

// A finding's reproducer walks to its end within every check.
void expect_walked(const std::string& name) {
  const Outcome o = run_file(kCorpus / ("finding_" + name + ".ngc"));
  EXPECT_EQ(kind(o), "walked") << o.message;
}

// The allocation check is not vacuous: the counter of this binary moves.
TEST(PipelineFuzz, AllocationsAreCounted) {
  const long before = allocations();
  auto* p = new std::vector<int>(3);
  EXPECT_GE(allocations() - before, 2);
  delete p;
}

// Finding: a G1 into a G2 of 2 um (a near-full circle ending 1 um from its start, taken the
// short way) and a G1 straight up, on a slow machine (F149, T 4.35 ms, chord 2.7 um): both
// joints fell in one period's step, and the chord across them deviated 3.32 um, 22 % over the
// tolerance, as each joint was bounded on its own. The corner law now sums the turns of joints
// around a segment shorter than the step (feed/limit_sampler.cpp).
TEST(PipelineFuzz, TwoJointsAroundAShortArcInOnePeriodKeepTheChordTolerance) {
  expect_walked("chord_two_joints_in_one_period");
}

TEST(PipelineFuzz, EverySeedIsWalkedOrRefusedNeverAViolation) {
  std::vector<fs::path> seeds;
  for (const auto& e : fs::directory_iterator(kCorpus)) seeds.push_back(e.path());
  std::sort(seeds.begin(), seeds.end());
  ASSERT_GE(seeds.size(), 100u);
  const std::size_t every = test::kSanitized ? 10 : 1;
  int walked = 0, refused = 0;
  for (std::size_t i = 0; i < seeds.size(); i += every) {
    const Outcome o = run_file(seeds[i]);
    EXPECT_NE(o.kind, Outcome::Violation) << seeds[i].filename() << ": " << o.message;
    (o.kind == Outcome::Walked ? walked : refused) += 1;
  }
  std::printf("%d seeds walked, %d refused\n", walked, refused);
  // Most seeds walk: the corpus tests the walk, not the interpreter's refusals.
  EXPECT_GE(walked, 8 * (walked + refused) / 10);
}

}  // namespace
}  // namespace ncd::fuzz::pipeline
