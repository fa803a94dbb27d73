// A part's whole program from its part file and the machine (docs/part.md): what `ncd chamfer
// --part` writes and what `ncd serve` runs for a job that names a part ({"part": FILE} or
// {"part_toml": TEXT}, docs/service.md "Jobs"). One function for both, so that a served part is
// the program the command writes: same order, same checks, same refusals.
#pragma once

#include <optional>
#include <string>

#include "cam/part.hpp"
#include "service/machine_config.hpp"

namespace ncd::service {

// The machine a part is planned for: none (the documented defaults, no dialect, the programmed
// point of `point` or the tip), or a machine file's. `name` names it in messages.
struct PartMachine {
  const MachineConfig* machine = nullptr;
  std::string name;
  std::optional<toolpath::ProgramPoint> point;  // `--program-point`; must agree with the machine's
  std::string point_text;                       // how it was given, for the message
};

// The rotary axis: the machine file's [axis.a] or [axis.b] where it has one (the part file's
// [rotary] axis, if given, must agree), else the part file's.
toolpath::Part with_machine_axis(toolpath::Part part, const PartMachine& m);

// The time model of the air moves from the machine's limits (the path's rapid rate and
// acceleration, [axis.x..z]; the index under [axis.a]/[axis.b] where it has one, else the part's
// [rotary]).
toolpath::AirModel part_air_model(const PartMachine& m, const toolpath::Part& part);

// The writer's options: the programmed point and what the machine's dialect leaves out. Throws
// InputError where the machine and the part (or --program-point) disagree.
toolpath::NgcOptions part_writer_options(const PartMachine& m, const toolpath::Part& part);

// All of the above, then toolpath::plan_part: every hole computed and checked (a refusal names
// the hole and the key), placed, ordered.
toolpath::PartProgram plan_part_for(const toolpath::Part& part, const PartMachine& m);

}  // namespace ncd::service
