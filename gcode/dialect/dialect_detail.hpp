// What dialect.cpp and grbl.cpp share: the violation maker and grbl's line buffer size.
// Private to gcode/dialect.
#pragma once

#include <string>

#include "gcode/dialect/dialect.hpp"

namespace ncd::comms::dialect_detail {

constexpr int kGrblKeptChars = 79;  // LINE_BUFFER_SIZE 80, less the terminator

inline Violation violation(int column, std::string word, int grbl_error, std::string reason,
                           std::string way_out) {
  Violation v;
  v.column = column;
  v.word = std::move(word);
  v.grbl_error = grbl_error;
  v.reason = std::move(reason);
  v.way_out = std::move(way_out);
  return v;
}

}  // namespace ncd::comms::dialect_detail
