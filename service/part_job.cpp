// A part's whole program for a machine: see part_job.hpp. The planning is cam/part.cpp's; this
// file reads the machine's side of it (rotary axis, air model, dialect, programmed point).
#include "service/part_job.hpp"

#include <cmath>

#include "core/error.hpp"
#include "gcode/dialect/dialect.hpp"

namespace ncd::service {

toolpath::Part with_machine_axis(toolpath::Part part, const PartMachine& m) {
  if (!m.machine) return part;
  const feed::RotaryLimits r = m.machine->limits.rotary;
  if (!r.present()) return part;
  const toolpath::RotaryAxis axis =
      r.axis == 'a' ? toolpath::RotaryAxis::A : toolpath::RotaryAxis::B;
  if (part.rotary.axis_given && part.rotary.axis != axis) {
    throw InputError("the part file " + part.source + " lies on the " +
                     toolpath::to_string(part.rotary.axis) +
                     " axis ([rotary] axis) but the machine file " + m.name + " has [axis." +
                     std::string(1, r.axis) + "]; make them agree or leave [rotary] axis out");
  }
  part.rotary.axis = axis;
  return part;
}

toolpath::AirModel part_air_model(const PartMachine& pm, const toolpath::Part& part) {
  toolpath::AirModel m;
  const feed::MachineLimits defaults;
  const feed::MachineLimits& limits = pm.machine ? pm.machine->limits : defaults;
  m.rapid_mm_per_s = limits.max_feed_mm_per_min / 60.0;
  m.rapid_accel_mm_per_s2 = limits.max_accel_mm_per_s2;
  for (std::size_t i = 0; i < 3; ++i) {
    const auto& ax = limits.axes[i];
    if (std::isfinite(ax.max_feed_mm_per_min)) m.axis_mm_per_s[i] = ax.max_feed_mm_per_min / 60.0;
    if (std::isfinite(ax.max_accel_mm_per_s2)) m.axis_accel_mm_per_s2[i] = ax.max_accel_mm_per_s2;
  }
  // The index under the machine file's [axis.a] or [axis.b] where it has one, else [rotary].
  m.index_deg_per_s = (limits.rotary.present() ? limits.rotary.max_feed_deg_per_min
                                               : part.rotary.max_feed_deg_per_min) /
                      60.0;
  m.index_accel_deg_per_s2 = limits.rotary.present() ? limits.rotary.max_accel_deg_per_s2
                                                     : part.rotary.max_accel_deg_per_s2;
  return m;
}

toolpath::NgcOptions part_writer_options(const PartMachine& pm, const toolpath::Part& part) {
  toolpath::NgcOptions o;
  o.point = pm.point.value_or(toolpath::ProgramPoint::Tip);
  if (!pm.machine) return o;
  const MachineConfig& m = *pm.machine;
  if (pm.point && *pm.point != m.tool.programmed_point) {
    throw InputError("--program-point " + pm.point_text + " contradicts the machine file " +
                     pm.name + ", whose [tool] programmed_point is " +
                     (m.tool.programmed_point == toolpath::ProgramPoint::Tip ? "tip" : "centre") +
                     "; drop --program-point or change the machine file");
  }
  o.point = m.tool.programmed_point;
  if (m.has("tool.number") && m.tool.number != part.tool.number) {
    throw InputError("the part file " + part.source + " cuts with tool " +
                     std::to_string(part.tool.number) + " (tool.number) but the machine file " +
                     pm.name + " says [tool] number = " + std::to_string(m.tool.number) +
                     "; make them agree");
  }
  if (m.link.dialect) {
    const auto r = comms::rules(*m.link.dialect);
    o.path_blending = r.path_blending;
    o.percent = r.percent_framing;
    o.tool_change = r.tool_change;
    o.length_offset = r.length_offsets;
  }
  return o;
}

toolpath::PartProgram plan_part_for(const toolpath::Part& file_part, const PartMachine& m) {
  const toolpath::Part part = with_machine_axis(file_part, m);
  const toolpath::NgcOptions options = part_writer_options(m, part);
  const toolpath::AirModel air = part_air_model(m, part);
  return toolpath::plan_part(part, air, options);
}

}  // namespace ncd::service
