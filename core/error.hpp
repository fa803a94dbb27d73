// Errors at the edges of ncd. Invalid input (geometry that cannot be cut, a flag out of range)
// is an InputError: its message names the value, the limit and a way out, and the executable
// exits with status 2. A run that would break a machine limit is a LimitError (status 3: the
// motion was refused, nothing was streamed). A failed read or write of a file or of standard
// output is an IoError (status 1, "I/O error"). Anything else that escapes is an internal
// failure (status 1).
#pragma once

#include <cmath>
#include <stdexcept>
#include <string>

namespace ncd {

class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A program that moves nothing (only modes, comments, M2): an InputError to a command that
// needs motion; `ncd replay` reports it as "no motion" and exits 0.
class NoMotionError : public InputError {
 public:
  using InputError::InputError;
};

class LimitError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class IoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Throws InputError unless value is finite and strictly positive; name carries the unit.
inline void require_positive(const std::string& name, double value) {
  if (!std::isfinite(value) || value <= 0.0) {
    throw InputError(name + " = " + std::to_string(value) +
                     " is invalid: it must be a finite number greater than 0");
  }
}

// Throws InputError unless value is finite.
inline void require_finite(const std::string& name, double value) {
  if (!std::isfinite(value)) {
    throw InputError(name + " = " + std::to_string(value) + " is invalid: it must be finite");
  }
}

}  // namespace ncd
