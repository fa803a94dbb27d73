// Where a feed hold can leave the tool, and so whether a position a controller reports at
// Hold:0 can be trusted to write a retract from (the ending of an ack job: dnc_ending.cpp).
//
// A hold stops the motion along the move executing, or at the end of the last one done. The
// moves the controller may be executing are those it was sent and that are not known done; the
// last known done ended at last_end. So a trusted position lies within tol_mm of one of those
// moves (a straight segment from its start to its end: the block encoder writes only G0 and
// G1; a G2/G3 would be taken as its chord, so a hold far inside an arc is doubted, the safe
// side), or of last_end. Anywhere else the controller has reset or been moved since: a power-up
// counts from 0 again, a jog moves it. A block the modal tracker cannot follow (G28, G53, G92)
// among them makes every position untrusted.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "gcode/dialect/program_modal.hpp"

namespace ncd::comms {

struct HeldCandidate {
  BlockMotion geo;
  std::string_view text;  // the block, to name it
};

// Empty: trusted. Else why not, as a clause ("it lies on none of ...").
std::string held_position_doubt(const std::array<double, 3>& pos_mm,
                                const std::optional<std::array<double, 3>>& last_end_mm,
                                const std::vector<HeldCandidate>& moves, double tol_mm);

}  // namespace ncd::comms
