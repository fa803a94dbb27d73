// Shared by the libFuzzer harnesses: the input as text, and the one rule every parser keeps:
// bad input is an InputError (a clear message, exit 2); anything else that escapes (another
// exception, a sanitizer report, a crash, a hang) is a finding that fails the run.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "core/error.hpp"

namespace ncd::fuzz {

inline std::string text_of(const std::uint8_t* data, std::size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

// Runs parse(); an InputError is the expected refusal and its message must not be empty.
template <typename F>
void expect_input_error_or_value(F&& parse) {
  try {
    parse();
  } catch (const InputError& e) {
    if (std::string(e.what()).empty()) __builtin_trap();
  }
}

}  // namespace ncd::fuzz
