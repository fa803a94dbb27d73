// What `ncd replay` and `ncd serve` walk and write for a job: a whole program
// (docs/whole-program.md). A chamfer (its JSON, or `ncd serve`'s chamfer job made from
// parameters) holds the ball centre in the drill frame; its loop becomes the machine file's
// programmed point (the tip is the centre less R_B in Z), turned over for a lower edge as the
// chamfer's NGC program is, wrapped by toolpath::whole_job: preamble, tool, spindle, clearance
// plane, the approach down the drill axis for an inner edge, the cut, the retract, M5, M2. A JSON
// path file is wrapped the same way (straight down onto its start, the clearance plane
// 2 R_B + 5 mm above its highest point). RS-274/NGC is the program as interpreted, its events in
// place. One function for both commands, so that a served job streams the blocks a replay
// writes for it.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "cam/whole_program.hpp"
#include "gcode/program.hpp"
#include "geometry/path.hpp"
#include "service/machine_config.hpp"

namespace ncd::service {

struct WholeRun {
  toolpath::Program program;        // the events and motions, in order
  toolpath::Path path;              // what the planner walks: to_path(program)
  std::vector<std::string> header;  // comment lines (without parentheses) opening the blocks
  // How the job leaves the part when it ends early (docs/whole-program.md, "Ending early"): a
  // generated job's clearance plane and drill axis, an NC program's highest Z. None for
  // path_only.
  std::optional<toolpath::SafeRetract> retract;
};

// `who` names the command in the header ("ncd replay", "ncd serve"); `file` is the path file the
// job came from (`input` read from it), or empty for a chamfer made from parameters, whose edge,
// side and clearance plane are in input.chamfer. path_only: the path's own motions, no events
// (`ncd replay --path-only`). Throws InputError when the job cannot be wrapped (a clearance plane
// not above the cut, an NGC program that does not interpret).
WholeRun whole_run(const std::string& who, const std::string& file, const toolpath::Path& input,
                   const MachineConfig& machine, bool path_only = false);

// The same for RS-274/NGC text already in memory (a part's program, service/part_job.hpp);
// `name` stands for the file in the header and in messages.
WholeRun whole_ngc_run(const std::string& who, const std::string& name, const std::string& text,
                       const MachineConfig& machine);

}  // namespace ncd::service
