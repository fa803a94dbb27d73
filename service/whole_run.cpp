// The whole program of a job (whole_run.hpp, docs/whole-program.md).
#include "service/whole_run.hpp"

#include <algorithm>
#include <cstdio>

#include "cam/whole_program.hpp"
#include "core/input_file.hpp"
#include "gcode/dialect/dialect.hpp"
#include "gcode/ngc/interpreter.hpp"
#include "gcode/ngc/tool_table.hpp"

namespace ncd::service {
namespace {

// The path's own motions as a program without events.
toolpath::Program bare_program(const toolpath::Path& input) {
  toolpath::Program p;
  for (const toolpath::PathSegment& seg : input.segments) {
    toolpath::Motion mo;
    mo.rapid = seg.rapid;
    mo.feed = seg.feed_mm_per_min.value_or(0.0);
    if (const auto* pl = std::get_if<toolpath::Polyline>(&seg.geometry)) {
      mo.start = pl->points.front();
      mo.geometry = toolpath::PolylineMove{*pl};
    } else {
      const auto& c = std::get<toolpath::NurbsCurve>(seg.geometry);
      mo.start = c.points().front();
      mo.geometry = toolpath::NurbsMove{c};
    }
    p.steps.push_back({std::move(mo), {}});
  }
  return p;
}

// A generated job (a chamfer, a path file) is cut by [tool] number, a ball end: the tool table
// must not declare that tool another kind.
void check_generated_tool(const MachineConfig& m) {
  const auto tools = toolpath::tool_catalogue(m.program);
  const auto it = tools.find(m.tool.number);
  if (it == tools.end() || it->second.kind == toolpath::ToolKind::ball ||
      it->second.kind == toolpath::ToolKind::unknown) {
    return;
  }
  throw InputError(it->second.where + ": tool T" + std::to_string(m.tool.number) + " is a " +
                   toolpath::to_string(it->second.kind) +
                   ", but the machine file's [tool] number = " + std::to_string(m.tool.number) +
                   " is the ball end this job is cut with; give [tool] number the ball end's "
                   "tool, or correct its kind");
}

}  // namespace

WholeRun whole_ngc_run(const std::string& who, const std::string& name, const std::string& text,
                       const MachineConfig& m) {
  WholeRun w;
  w.program = toolpath::interpret_ngc(text, name, m.program);
  w.header.push_back(who + " of " + name + " (programmed point: as in that program)");
  w.path = toolpath::to_path(w.program);
  if (!w.path.segments.empty()) w.retract = toolpath::program_retract(w.program, w.path);
  return w;
}

WholeRun whole_run(const std::string& who, const std::string& file, const toolpath::Path& input,
                   const MachineConfig& m, bool path_only) {
  WholeRun w;
  const std::string name = file.empty() ? "the chamfer job" : file;
  if (path_only) {
    w.path = input;  // its own tools (a JSON path: the ball end of [cutting])
    w.program = bare_program(input);
    w.header.push_back(who + " --path-only of " + name +
                       ": the path alone, no preamble, "
                       "spindle or program end");
    return w;
  }
  bool ngc = false;
  std::string text;
  if (!file.empty() && !input.chamfer) {
    text = read_input_file(file, "path file");
    const std::size_t first = text.find_first_not_of(" \t\r\n");
    ngc = first == std::string::npos || text[first] != '{';
  }
  const bool tip = m.tool.programmed_point == toolpath::ProgramPoint::Tip;
  const double r_mm = m.cutting.ball_radius_mm;
  if (ngc) {
    w = whole_ngc_run(who, file, text, m);
  } else {
    check_generated_tool(m);
    toolpath::JobFrame f;
    f.spindle_rpm = m.cutting.spindle_rpm;
    f.spindle_dwell_s = m.tool.spindle_dwell_s;
    f.tool = m.tool.number;
    f.tool_change = !m.link.dialect || comms::rules(*m.link.dialect).tool_change;
    f.length_offset = !m.link.dialect || comms::rules(*m.link.dialect).length_offsets;
    f.feed_mm_per_min = input.segments.front().feed_mm_per_min.value_or(300.0);
    toolpath::Path cut = input;
    double top = -1e300;
    if (input.chamfer) {
      const toolpath::ChamferOrigin& c = *input.chamfer;
      for (toolpath::PathSegment& seg : cut.segments) {
        auto& pl = std::get<toolpath::Polyline>(seg.geometry);
        for (Vec3& p : pl.points) {
          if (c.lower_side) p = Vec3(-p.x(), p.y(), -p.z());  // the part turned over
          if (tip) p.z() -= r_mm;
          top = std::max(top, p.z());
        }
        if (c.lower_side) {
          for (Vec3& n : pl.normals) n = Vec3(-n.x(), n.y(), -n.z());
        }
      }
      // The chamfer's own clearance (for the point its NGC program drives), else 4 R_B above
      // the loop; both in the machine's programmed point.
      double clear = top + 4.0 * r_mm;
      if (c.safe_z_mm) {
        clear = *c.safe_z_mm + (c.safe_z_for_tip == tip ? 0.0 : tip ? -r_mm : r_mm);
      }
      f.clearance_z_mm = clear;
      if (c.inner_edge) f.axis_xy = Vec3::Zero();
      w.header.push_back(
          who + " of the chamfer " + (file.empty() ? "job" : file) + ", " +
          (c.inner_edge ? "inner" : "outer") + " " +
          (c.lower_side ? "lower edge: the part TURNED OVER (X -> -X, Z -> -Z)" : "upper edge") +
          ", drill frame");
      w.header.push_back(toolpath::programmed_point_text(m.tool.programmed_point, r_mm));
    } else {
      for (const auto& seg : cut.segments) {
        if (const auto* pl = std::get_if<toolpath::Polyline>(&seg.geometry)) {
          for (const Vec3& p : pl->points) top = std::max(top, p.z());
        } else {
          for (const Vec3& p : std::get<toolpath::NurbsCurve>(seg.geometry).points()) {
            top = std::max(top, p.z());
          }
        }
      }
      f.clearance_z_mm = top + 2.0 * r_mm + 5.0;
      w.header.push_back(who + " of " + name + " (programmed point: as in that path)");
    }
    char line[96];
    std::snprintf(line, sizeof line, "clearance plane Z %.3f mm, spindle %.0f rpm",
                  f.clearance_z_mm, f.spindle_rpm);
    if (!f.tool_change) {
      w.header.push_back("load tool " + std::to_string(f.tool) + " before the start: the " +
                         comms::to_string(*m.link.dialect) + " dialect has no tool change (M6)");
    }
    w.header.push_back(
        toolpath::tool_length_text(m.tool.programmed_point, f.tool, f.length_offset));
    w.header.push_back(line);
    // Header lines short enough for a drip controller's buffer (program_blocks.cpp).
    w.header.push_back("approach: G0 Z plane, G0 X Y over the " +
                       std::string(f.axis_xy ? "axis" : "start") + ", G0 to 1 mm above, G1 down" +
                       (f.axis_xy ? ", out" : ""));
    w.header.push_back(std::string("retract: ") + (f.axis_xy ? "G1 to the axis, " : "") +
                       "G0 up to the plane");
    w.program = toolpath::whole_job(cut, f);
    w.retract = toolpath::job_retract(cut, f);
    w.path = toolpath::to_path(w.program);
  }
  w.path.source = input.source;
  w.path.chamfer = input.chamfer;
  return w;
}

}  // namespace ncd::service
