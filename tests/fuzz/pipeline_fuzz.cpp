// libFuzzer harness of the whole motion pipeline (issue 30 §1): an input is a machine and an
// RS-274/NGC program (a text starting with "(fuzz", or bytes a generator turns into one; see
// pipeline.hpp), interpreted, made a Path and a motion::Job, and walked period by period with
// every period checked: the feed, the limit curve and the F word, the tangential acceleration
// and jerk, the chord tolerance, the envelope of the program's geometry, progress within a
// bound of periods, rest at the programmed end, no StepFault, no NaN, and no allocation in any
// period after the first prepare() (counted by a sanitizer malloc hook on this thread). A
// violation prints the input as a text reproducer and the violation to stderr, and aborts.
//
// NCD_FUZZ_PRINT=1 prints every input as text and its outcome (to turn corpus files into
// readable programs); a refused input is not a finding.
#include <sanitizer/allocator_interface.h>

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "tests/fuzz/pipeline.hpp"

namespace {

// Allocations made on the fuzzing thread while counting is on.
thread_local bool t_counting = false;
thread_local long t_allocations = 0;

void on_malloc(const volatile void*, std::size_t) {
  if (t_counting) ++t_allocations;
}
void on_free(const volatile void*) {}

long allocations() {
  return t_allocations;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  __sanitizer_install_malloc_and_free_hooks(on_malloc, on_free);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace p = ncd::fuzz::pipeline;
  if (size > 65536) return 0;  // a program of that size is not what this harness is for
  const p::Input in = p::decode(data, size);
  t_counting = true;
  const p::Outcome out = p::run(in, allocations);
  t_counting = false;
  static const bool print = std::getenv("NCD_FUZZ_PRINT") != nullptr;
  if (print) {
    std::fprintf(stderr, "%s--- %s after %lld periods (bound %.0f): %s\n", p::as_text(in).c_str(),
                 out.kind == p::Outcome::Walked    ? "walked"
                 : out.kind == p::Outcome::Refused ? "refused"
                                                   : "VIOLATION",
                 static_cast<long long>(out.periods), out.bound, out.message.c_str());
  }
  if (out.kind == p::Outcome::Violation) {
    std::fprintf(stderr,
                 "=== pipeline violation: %s\n=== reproducer (save as a .ngc; "
                 "tests/motion/fuzz_findings_test.cpp walks it):\n%s=== end\n",
                 out.message.c_str(), p::as_text(in).c_str());
    std::abort();
  }
  return 0;
}
