// `ncd teach`: digitized burr points → NC program (paper 003) from the command line.
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>

#include "app/commands.hpp"
#include "cam/teach.hpp"
#include "core/error.hpp"
#include "core/input_file.hpp"
#include "core/output_file.hpp"

namespace ncd::app {
namespace {

struct TeachArgs {
  std::string points, frame_points, side = "left", output;
  toolpath::TeachSpec spec;
  toolpath::TeachProgramOptions program;
  bool truncate = false, quiet = false, no_length_offset = false;
};

// The whole file (a regular file, core/input_file.hpp), or an InputError naming it and the flag
// that gave it.
std::string read_text(const std::string& path, const std::string& flag) {
  return read_input_file(path, flag);
}

// --frame-points: "x,y,z;x,y,z;x,y,z" inline, or a file of exactly three points.
std::array<Vec3, 3> frame_points(const std::string& arg) {
  if (arg.find(';') != std::string::npos) {
    return toolpath::parse_frame_points(arg, "--frame-points");
  }
  const auto pts = toolpath::parse_points(read_text(arg, "--frame-points"), arg);
  if (pts.size() != 3) {
    throw InputError(arg + " (--frame-points) has " + std::to_string(pts.size()) +
                     " point(s); it must hold exactly three, P1 P2 P3 in that order");
  }
  return {pts[0].p_mm, pts[1].p_mm, pts[2].p_mm};
}

int run_teach(const TeachArgs& a) {
  toolpath::TeachSpec spec = a.spec;
  spec.side = a.side == "left" ? toolpath::TravelSide::Left : toolpath::TravelSide::Right;
  toolpath::TeachProgramOptions program = a.program;
  program.rounding = a.truncate ? toolpath::Rounding::Truncate : toolpath::Rounding::Nearest;
  program.length_offset = !a.no_length_offset;
  toolpath::validate(spec);  // flags before files: the cheaper mistake is reported first
  toolpath::validate(program);

  const toolpath::TeachFrame frame =
      toolpath::make_frame(frame_points(a.frame_points), "--frame-points");
  const auto points = toolpath::parse_points(read_text(a.points, "POINTS"), a.points);
  toolpath::TeachPath path;
  try {
    path = toolpath::teach(points, frame, spec);
  } catch (const InputError& e) {
    throw InputError(a.points + ": " + e.what());  // the points' file, then point and line
  }
  write_output(a.output, toolpath::teach_program(path, program));

  if (!a.quiet) {
    const auto paper = std::count_if(path.points.begin(), path.points.end(), [](const auto& p) {
      return p.fit == toolpath::TangentFit::PaperParabola;
    });
    std::cerr << "ncd teach: " << path.points.size() << " points, "
              << (spec.closed ? "closed loop" : "open path") << ", tool centre " << path.offset_mm
              << " mm " << to_string(spec.side) << " of travel\n"
              << "  tangent           paper parabola at " << paper << ", chord-length quadratic at "
              << std::ssize(path.points) - paper << "\n";
    if (!std::isinf(path.min_tool_side_radius_mm)) {
      std::cerr << "  tightest bend     radius " << path.min_tool_side_radius_mm
                << " mm towards the tool at point " << path.min_tool_side_radius_at + 1 << "\n";
      if (path.min_tool_side_radius_mm < path.offset_mm) {
        std::cerr << "warning: the path bends towards the tool tighter than D/2 - l = "
                  << path.offset_mm << " mm; the tool cuts deeper than l there\n";
      }
    }
    if (!a.output.empty() && a.output != "-") {
      std::cerr << "  wrote             " << a.output << "\n";
    }
  }
  return 0;
}

}  // namespace

void register_teach(CLI::App& app, Runner& run) {
  auto a = std::make_shared<TeachArgs>();
  CLI::App* c = app.add_subcommand(
      "teach",
      "NC program from digitized deburring points (paper 003): three-point frame, tool-radius "
      "offset on one side of travel, one G01 per point. Lengths in mm.");
  c->add_option("POINTS", a->points,
                "digitized points: CSV with x,y,z columns, or 'name x y z' / 'x y z' lines")
      ->required();
  c->add_option("--frame-points", a->frame_points,
                "P1 (origin), P2 (on +X), P3 (in the XY plane): a file of three points, or "
                "x,y,z;x,y,z;x,y,z")
      ->required();
  c->add_option("--tool-diameter", a->spec.tool_diameter_mm, "tool diameter D, mm")->required();
  c->add_option("--depth", a->spec.depth_mm, "deburring depth l, mm (tool centre at D/2 - l)")
      ->required();
  c->add_option("--feed", a->program.feed_mm_per_min, "feed, mm/min")->required();
  c->add_option("--spindle", a->program.spindle_rpm, "spindle speed, rpm")->required();
  c->add_option("--side", a->side,
                "side of the direction of travel the tool lies on, away from the material")
      ->check(CLI::IsMember({"left", "right"}))
      ->capture_default_str();
  c->add_flag("--closed", a->spec.closed,
              "the points form a loop: the last joins the first, neighbours wrap around");
  c->add_flag("--truncate", a->truncate,
              "truncate coordinates toward zero, as the paper does (default: round)");
  c->add_option("--decimals", a->program.decimals, "digits after the point in coordinates")
      ->capture_default_str();
  c->add_option("--clearance", a->program.clearance_mm,
                "approach and retract plane above the highest point (+Z), mm")
      ->capture_default_str();
  c->add_option("--tool", a->program.tool,
                "the tool in the spindle (the program changes none): G43 H<tool> before the "
                "first move takes its length from the controller's tool table")
      ->capture_default_str();
  c->add_flag("--no-length-offset", a->no_length_offset,
              "no G43 H, for a controller without a tool table (grbl): set the work offset Z "
              "for the tool instead");
  c->add_option("-o,--output", a->output, "NC program file (default: standard output)");
  c->add_flag("-q,--quiet", a->quiet, "no summary on standard error");
  c->callback([a, &run] { run = [a] { return run_teach(*a); }; });
}

}  // namespace ncd::app
