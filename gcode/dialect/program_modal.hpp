// The modal state of an NC program, block by block, as far as the DNC link needs it: where each
// block ends (to recognise a controller's reported position) and which modes are in force at a
// block (to restart a program from it). See docs/dnc-link.md, "Tracking executed blocks" and
// "Restart from block N".
#pragma once

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "gcode/dialect/dialect.hpp"

namespace ncd::comms {

struct ModalState {
  bool inch = false;                 // G20 / G21
  bool absolute = true;              // G90 / G91
  int work_offset = 54;              // G54 … G59
  std::optional<int> tool;           // T of the last M6 (or the last T when no M6 was seen)
  bool tool_changed = false;         // an M6 was seen
  std::optional<int> length_offset;  // G43 H; none after G49
  int spindle = 5;                   // 3, 4 or 5
  std::optional<double> speed_rpm;   // S
  bool mist = false, flood = false;  // M7, M8 (M9 clears both)
  std::optional<double> feed;        // F, in program units per minute
  int motion = 0;                    // 0, 1, 2, 3 (G80: -1)
  std::array<double, 3> position_mm{0.0, 0.0, 0.0};  // work coordinates, mm
  bool position_known = false;  // every axis has been given once (absolute) or the start
};

// What one block does to the machine, for tracking.
struct BlockMotion {
  bool motion = false;  // moves the tool (G0 G1 G2 G3 with an axis word)
  bool dwell = false;   // G4
  bool known = true;    // false: a word the tracker cannot follow (G28, G92, G53, …)
  std::array<double, 3> from_mm{}, to_mm{};  // work coordinates
};

class ProgramModal {
 public:
  // Applies one block (comments and N are allowed) and says what it does.
  BlockMotion apply(std::string_view block);
  const ModalState& state() const { return state_; }

 private:
  ModalState state_;
};

// The blocks that bring a controller into the state `at` (the modes in force before block N)
// and re-enter the cut safely: up to clearance_z_mm at the rapid rate, over `start_mm` (block
// N's start point), down at the program's feed, then the distance mode and motion of block N.
// Throws InputError when the state cannot be written (no feed in force, unknown position), or,
// given the controller's dialect, when a line of it is one that dialect refuses (checked as the
// controller would receive them, from its power-on state).
std::vector<std::string> restart_blocks(const ModalState& at, double clearance_z_mm,
                                        std::optional<Dialect> dialect = std::nullopt);

}  // namespace ncd::comms
