// What grbl's steps share (grbl.cpp steps 1 and 4, grbl_read.cpp step 2, grbl_check.cpp step 3;
// the model is at the top of grbl.cpp): the kept line, the words of a block, what step 3 settles
// for step 4, grbl's modal groups and value words, and the steps themselves. Private to
// gcode/dialect.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "gcode/dialect/dialect.hpp"
#include "gcode/dialect/dialect_detail.hpp"

namespace ncd::comms::grbl_detail {

using dialect_detail::kGrblKeptChars;
using dialect_detail::violation;

inline constexpr double kMmPerInch = 25.4;
inline constexpr double kGrblMaxLineNumber = 10000000.0;
inline constexpr double kGrblMaxTool = 255.0;

struct Kept {
  std::string text;         // the characters grbl keeps, upper case
  std::vector<int> column;  // their 1-based columns in the raw line
  int overflow_column = 0;  // the first character beyond 79, 0 if none
};

inline int bit(int b) {
  return 1 << b;
}

// Modal groups (word_bit of gcode.c) and value words.
enum Group { kG0, kG1, kG2, kG3, kG4, kG5, kG6, kG7, kG8, kG12, kG13, kM4, kM7, kM8 };
enum Word { kF, kI, kJ, kK, kL, kN, kP, kR, kS, kT, kX, kY, kZ };
enum AxisCommand { kNone, kNonModal, kMotion, kToolLength };

inline double dist3(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
}

// The words of a block as step 2 reads them: gc_block before its checks.
struct Words {
  int command_words = 0, value_words = 0, axis_words = 0, ijk_words = 0;
  AxisCommand axis_command = kNone;
  GrblState blk;       // gc_block.modal, copied from the state
  int non_modal = -1;  // G code × 10: 40, 100, 280, 281, 300, 301, 530, 920, 921
  std::array<double, 3> xyz{}, ijk{};
  double f = 0.0, l = 0.0, n = 0.0, p = 0.0, r = 0.0, sv = 0.0, t = 0.0;
  int word_col[13] = {};
  int motion_col = 0;
  bool g49 = false;
  int non_modal_col = 0;
};

// What step 3 settles for step 4: the plane's axes, the tool length, offsets, the target.
struct Settled {
  int a0 = 0, a1 = 1, alin = 2;  // the plane's axes and the linear one
  bool set_tlo = false;
  double tlo = 0.0;
  std::array<double, 3> home{}, target{}, center{};
  std::optional<std::pair<int, std::array<double, 3>>> set_cs;
  std::optional<std::array<double, 3>> set_g92;
};

// Step 1 (grbl.cpp): the kept characters of a line.
Kept grbl_keep(std::string_view raw);
// Step 2 (grbl_read.cpp): grbl's read_float, and the words of the kept line.
bool grbl_read_float(std::string_view s, std::size_t& i, double& value);
std::optional<Violation> read_words(const Kept& k, Words& w, GrblBlock& b);
// Step 3 (grbl_check.cpp), in gcode.c's order.
std::optional<Violation> check_modes(const Kept& k, const GrblState& state, Words& w, Settled& z);
std::optional<Violation> check_offsets(const Kept& k, const GrblState& state, Words& w, Settled& z);
std::optional<Violation> check_motion(const Kept& k, const GrblState& state, Words& w, Settled& z);
std::optional<Violation> check_unused(Words& w);
// Step 4 (grbl.cpp).
GrblState apply_block(const GrblState& state, const Words& w, const Settled& z, GrblBlock& b);

}  // namespace ncd::comms::grbl_detail
