// Whether this test binary runs under AddressSanitizer. The heaviest random sweeps run a tenth of
// their cases there (the ASan build checks memory, the Release suite runs the sweep in full), so
// that `make test` stays within its time on a 2-core machine.
#pragma once

namespace ncd::test {

#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
inline constexpr bool kSanitized = true;
#else
inline constexpr bool kSanitized = false;
#endif
#else
inline constexpr bool kSanitized = false;
#endif

// `cases` in the Release suite, a tenth of them (at least one) under the sanitizer.
constexpr int sweep_cases(int cases) {
  return kSanitized ? (cases + 9) / 10 : cases;
}

}  // namespace ncd::test
