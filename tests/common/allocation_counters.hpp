// The counters of tests/common/count_allocations.hpp, for the other files of a test binary that
// includes it once (that file replaces operator new; these only read what it counts).
#pragma once

#include <atomic>

namespace ncd::test {
inline std::atomic<long> g_allocations{0};
inline std::atomic<long> g_allocated_bytes{0};  // requested, summed (frees not subtracted)
}  // namespace ncd::test
