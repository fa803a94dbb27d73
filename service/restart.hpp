// Restart a job from a line of its NC program, the way `ncd stream --restart-from N` does for a
// program file (docs/service.md, "Restart from a line"; docs/dnc-link.md, "Restart from block
// N"). The job's motion is the program from the first motion of line N on (the motions before
// it are dropped from the interpreted program before it becomes a path, so a run of lines
// merged into one polyline is cut at N's own vertex). A streamed job first sends the modes in
// force at N and a safe re-entry (up to the clearance plane, over N's start point, down at
// feed: comms::restart_blocks), then the live blocks from N on. Nothing before N runs, and
// everything from N runs once.
#pragma once

#include <optional>
#include <string_view>

#include "gcode/program.hpp"
#include "service/service.hpp"

namespace ncd::service {

// Cuts job.path to the program from `line` on and sets job.restart. `program` is the
// interpretation of `program_text` (toolpath::interpret_ngc). The clearance plane is
// clearance_z_mm (work coordinates), else the highest Z the program reached before the line.
// Throws InputError naming the line when:
//   - no motion starts on the line or after it;
//   - the program loops or calls subroutines before it (the modal state read line by line would
//     not be the one in force);
//   - it moves before the line in a way the modal reader does not follow (G28, G30, G53, G92);
//   - no clearance is known, or it lies below the line's start, or no feed is in force;
//   - the modal reader's position at the line is not the interpreter's.
void restart_job(JobSpec& job, const toolpath::Program& program, std::string_view program_text,
                 int line, std::optional<double> clearance_z_mm,
                 const toolpath::ToPathOptions& options = {});

}  // namespace ncd::service
