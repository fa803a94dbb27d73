// grbl's step 3 (the model at the top of grbl.cpp): a block's checks in gcode.c's order, each
// refusal at the word concerned with grbl's error code: the modes, the offsets, the motion, and
// the words left unused.
#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "gcode/dialect/dialect.hpp"
#include "gcode/dialect/grbl_detail.hpp"

namespace ncd::comms::grbl_detail {
namespace {

// The word (letter and number as kept) that starts at a column.
std::string word_at(const Kept& k, int col) {
  const std::string& s = k.text;
  const auto it = std::find(k.column.begin(), k.column.end(), col);
  std::size_t i = static_cast<std::size_t>(it - k.column.begin());
  std::size_t j = i + 1;
  double ignored = 0.0;
  if (i < s.size()) grbl_read_float(s, j, ignored);
  return i < s.size() ? s.substr(i, j - i) : std::string();
}

// A step 3 violation at the word concerned, else at column 1.
Violation fail_at(const Kept& k, int code, int col, std::string why, std::string way_out) {
  if (col <= 0) col = k.column[0];
  return violation(col, word_at(k, col), code, std::move(why), std::move(way_out));
}

}  // namespace

// Step 3, first part: N, F and S, G4, the plane, inches, G43.1.
std::optional<Violation> check_modes(const Kept& k, const GrblState& state, Words& w, Settled& z) {
  if (w.axis_words && w.axis_command == kNone) w.axis_command = kMotion;
  if ((w.value_words & bit(kN)) && w.n > kGrblMaxLineNumber) {
    return fail_at(k, kGrblLineNumber, w.word_col[kN], "N is above grbl's 10000000",
                   "number the blocks from 0 to 10000000, or leave N out");
  }
  if (w.blk.inverse_time) {
    if (w.axis_command == kMotion && w.blk.motion != 800 && w.blk.motion != 0 &&
        !(w.value_words & bit(kF))) {
      return fail_at(k, kGrblUndefinedFeed, w.motion_col, "a G93 (inverse time) motion without F",
                     "give F on every G93 motion");
    }
  } else if (!state.inverse_time) {
    if (w.value_words & bit(kF)) {
      if (w.blk.inches) w.f *= kMmPerInch;
    } else {
      w.f = state.feed;
    }
  }
  if (!(w.value_words & bit(kS))) w.sv = state.spindle_rpm;
  if (w.non_modal == 40) {
    if (!(w.value_words & bit(kP))) {
      return fail_at(k, kGrblValueMissing, w.non_modal_col, "G4 without P, the dwell in seconds",
                     "write G4 P0.5");
    }
    w.value_words &= ~bit(kP);
  }
  z.a0 = w.blk.plane == 0 ? 0 : w.blk.plane == 1 ? 2 : 1;
  z.a1 = w.blk.plane == 0 ? 1 : w.blk.plane == 1 ? 0 : 2;
  z.alin = w.blk.plane == 0 ? 2 : w.blk.plane == 1 ? 1 : 0;
  if (w.blk.inches) {
    for (int q = 0; q < 3; ++q) {
      if (w.axis_words & (1 << q)) w.xyz[static_cast<std::size_t>(q)] *= kMmPerInch;
    }
  }
  z.tlo = state.tool_length_mm;
  if (w.axis_command == kToolLength) {
    if (!w.g49 && w.axis_words != 4) {
      return fail_at(k, kGrblG43Axis, 0, "G43.1 needs a Z word and no other axis word",
                     "write G43.1 Z<length>");
    }
    z.set_tlo = true;
    z.tlo = w.g49 ? 0.0 : w.xyz[2];
  }
  return std::nullopt;
}

// Step 3: G10, G92, the target in machine coordinates, G28/G30, G53.
std::optional<Violation> check_offsets(const Kept& k, const GrblState& state, Words& w,
                                       Settled& z) {
  std::array<double, 3> block_cs = state.coord_system[static_cast<std::size_t>(w.blk.coord_select)];
  z.target = state.position;
  if (w.non_modal == 100) {
    if (!w.axis_words)
      return fail_at(k, kGrblNoAxisWords, w.non_modal_col, "G10 without axis words",
                     "give X, Y or Z");
    if (!(w.value_words & (bit(kP) | bit(kL)))) {
      return fail_at(k, kGrblValueMissing, w.non_modal_col, "G10 without P and L",
                     "write G10 L2 P1 X… or G10 L20");
    }
    const double pv = std::trunc(w.p);
    if (pv > 6.0) {
      return fail_at(k, kGrblCoordSystem, w.word_col[kP], "G10 P above 6 (grbl has G54 to G59)",
                     "use P0 to P6");
    }
    if (w.l != 20.0) {
      if (w.l != 2.0 || (w.value_words & bit(kR))) {
        return fail_at(k, kGrblUnsupported, w.word_col[kL],
                       w.l == 2.0 ? "G10 L2 with R (rotation) is not supported"
                                  : "G10 with an L other than 2 or 20",
                       "use G10 L2 or G10 L20 without R");
      }
    }
    w.value_words &= ~(bit(kL) | bit(kP));
    const int idx = pv > 0.0 ? static_cast<int>(pv) - 1 : w.blk.coord_select;
    std::array<double, 3> data = state.coord_system[static_cast<std::size_t>(idx)];
    for (std::size_t q = 0; q < 3; ++q) {
      if (!(w.axis_words & (1 << q))) continue;
      data[q] = w.l == 20.0 ? state.position[q] - state.g92[q] - w.xyz[q] -
                                  (q == 2 ? state.tool_length_mm : 0.0)
                            : w.xyz[q];
    }
    z.set_cs = std::make_pair(idx, data);
  } else if (w.non_modal == 920) {
    if (!w.axis_words)
      return fail_at(k, kGrblNoAxisWords, w.non_modal_col, "G92 without axis words",
                     "give X, Y or Z");
    std::array<double, 3> off{};
    for (std::size_t q = 0; q < 3; ++q) {
      off[q] = (w.axis_words & (1 << q)) ? state.position[q] - block_cs[q] - w.xyz[q] -
                                               (q == 2 ? state.tool_length_mm : 0.0)
                                         : state.g92[q];
    }
    z.set_g92 = off;
  } else {
    if (w.axis_command != kToolLength && w.axis_words) {
      for (std::size_t q = 0; q < 3; ++q) {
        if (!(w.axis_words & (1 << q))) {
          z.target[q] = state.position[q];
        } else if (w.non_modal == 530) {
          z.target[q] = w.xyz[q];
        } else if (!w.blk.incremental) {
          z.target[q] =
              w.xyz[q] + block_cs[q] + state.g92[q] + (q == 2 ? state.tool_length_mm : 0.0);
        } else {
          z.target[q] = w.xyz[q] + state.position[q];
        }
      }
    }
    if (w.non_modal == 280 || w.non_modal == 300) {
      z.home = w.non_modal == 280 ? state.g28 : state.g30;
      if (!w.axis_words) w.axis_command = kNone;
    } else if (w.non_modal == 530) {
      if (w.blk.motion != 0 && w.blk.motion != 10) {
        return fail_at(k, kGrblG53Motion, w.non_modal_col, "G53 outside G0 or G1",
                       "use G53 with G0 or G1");
      }
    }
  }
  return std::nullopt;
}

// Step 3: the motion: G80, a feed, arcs (R or I J K, their end on the circle), probes.
std::optional<Violation> check_motion(const Kept& k, const GrblState& state, Words& w, Settled& z) {
  if (w.blk.motion == 800) {
    if (w.axis_words) {
      return fail_at(k, kGrblAxisWordsExist, 0, "axis words with G80 (no motion mode) active",
                     "give G0 or G1 before the axis words");
    }
  } else if (w.axis_command == kMotion) {
    if (w.blk.motion == 0) {
      if (!w.axis_words) w.axis_command = kNone;
    } else {
      if (w.f == 0.0) {
        return fail_at(k, kGrblUndefinedFeed, w.motion_col, "a feed motion without a feed rate",
                       "give F (mm/min) on or before the first G1, G2 or G3");
      }
      if (w.blk.motion == 10) {
        if (!w.axis_words) w.axis_command = kNone;
      } else if (w.blk.motion == 20 || w.blk.motion == 30) {
        if (!w.axis_words)
          return fail_at(k, kGrblNoAxisWords, w.motion_col, "an arc without axis words",
                         "give its end point");
        if (!(w.axis_words & ((1 << z.a0) | (1 << z.a1)))) {
          return fail_at(k, kGrblNoAxisInPlane, w.motion_col,
                         "an arc without an axis word in its plane",
                         "give the end point in the plane (G17: X Y)");
        }
        const auto ua0 = static_cast<std::size_t>(z.a0), ua1 = static_cast<std::size_t>(z.a1);
        const double x = z.target[ua0] - state.position[ua0];
        const double y = z.target[ua1] - state.position[ua1];
        double ci = 0.0, cj = 0.0;
        if (w.value_words & bit(kR)) {
          w.value_words &= ~bit(kR);
          if (z.target == state.position) {
            return fail_at(k, kGrblInvalidTarget, w.word_col[kR], "an R arc ending where it starts",
                           "program a full circle with I J K");
          }
          double rr = w.blk.inches ? w.r * kMmPerInch : w.r;
          double h = 4.0 * rr * rr - x * x - y * y;
          if (h < 0.0) {
            return fail_at(k, kGrblArcRadius, w.word_col[kR],
                           "the arc's radius is shorter than half its chord",
                           "check R against the end point");
          }
          h = -std::sqrt(h) / std::hypot(x, y);
          if (w.blk.motion == 30) h = -h;
          if (rr < 0.0) h = -h;
          ci = 0.5 * (x - y * h);
          cj = 0.5 * (y + x * h);
        } else {
          if (!(w.ijk_words & ((1 << z.a0) | (1 << z.a1)))) {
            return fail_at(k, kGrblNoOffsetsInPlane, w.motion_col,
                           "an arc without a centre offset in its plane",
                           "give I J (G17), I K (G18) or J K (G19), or R");
          }
          w.value_words &= ~(bit(kI) | bit(kJ) | bit(kK));
          if (w.blk.inches) {
            for (auto& v : w.ijk) v *= kMmPerInch;
          }
          ci = w.ijk[ua0];
          cj = w.ijk[ua1];
          const double target_r = std::hypot(x - ci, y - cj);
          const double radius = std::hypot(ci, cj);
          const double dr = std::fabs(target_r - radius);
          if (dr > 0.005 && (dr > 0.5 || dr > 0.001 * radius)) {
            return fail_at(
                k, kGrblInvalidTarget, w.motion_col,
                "the arc's end is not on its circle (off by " + std::to_string(dr) + " mm)",
                "check I J K against the end point");
          }
        }
        z.center = state.position;
        z.center[ua0] += ci;
        z.center[ua1] += cj;
      } else {  // probes
        if (!w.axis_words)
          return fail_at(k, kGrblNoAxisWords, w.motion_col, "a probe without axis words",
                         "give its end point");
        if (z.target == state.position) {
          return fail_at(k, kGrblInvalidTarget, w.motion_col, "a probe to where the tool stands",
                         "give a probe target away from the tool");
        }
      }
    }
  }
  return std::nullopt;
}

// Step 3, last: a word no command of the block used.
std::optional<Violation> check_unused(Words& w) {
  w.value_words &= ~(bit(kN) | bit(kF) | bit(kS) | bit(kT));
  if (w.axis_command != kNone) w.value_words &= ~(bit(kX) | bit(kY) | bit(kZ));
  if (w.value_words) {
    int word_id = 0;
    while (!(w.value_words & bit(word_id))) ++word_id;
    static constexpr char kLetters[] = "FIJKLNPRSTXYZ";
    return violation(
        w.word_col[word_id], std::string(1, kLetters[word_id]), kGrblUnusedWords,
        std::string("the word ") + kLetters[word_id] + " is not used by any command of the block",
        "remove it (grbl takes P only with G4 and G10, R and I J K only with arcs)");
  }
  return std::nullopt;
}

}  // namespace ncd::comms::grbl_detail
