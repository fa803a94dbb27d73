// Replaces the global operator new and delete with a malloc/free pair that counts every heap
// allocation of the test binary, to prove that a hot path (NURBS eval, a walker step, a cycle
// period) makes none. Include it from exactly one file of a test binary; other files read the
// counters through tests/common/allocation_counters.hpp.
#pragma once

#include <cstdlib>
#include <new>

#include "tests/common/allocation_counters.hpp"

void* operator new(std::size_t size) {
  ncd::test::g_allocations.fetch_add(1, std::memory_order_relaxed);
  ncd::test::g_allocated_bytes.fetch_add(static_cast<long>(size), std::memory_order_relaxed);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
// A malloc/free pair; GCC cannot see that through inlining.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}
#pragma GCC diagnostic pop
