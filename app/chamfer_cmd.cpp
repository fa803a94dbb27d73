// `ncd chamfer`: the constant-width chamfer generator from the command line.
#include <chrono>
#include <iostream>
#include <memory>
#include <optional>

#include "app/chamfer_part.hpp"
#include "app/chamfer_report.hpp"
#include "app/commands.hpp"
#include "core/error.hpp"
#include "core/output_file.hpp"
#include "gcode/dialect/dialect.hpp"
#include "service/machine_config.hpp"

namespace ncd::app {
namespace {

struct ChamferArgs {
  toolpath::ChamferSpec spec;
  std::string edge = "inner", side = "upper", format = "json", frame = "drill";
  std::optional<std::string> point;  // --program-point; default: the machine file's, else tip
  std::string machine;
  std::optional<double> rod_radius_mm, non_knife_angle_deg, safe_z_mm, pipe_thickness_mm;
  double tilt_deg = 0.0, azimuth_deg = 0.0, half_angle_deg = 0.0;
  bool no_avoid = false, quiet = false;
  double feed_mm_per_min = 300.0, spindle_rpm = 3000.0;
  std::string output, plot;
  std::string part;  // --part FILE: every hole of a part file (app/chamfer_part.hpp)
  std::vector<CLI::Option*> hole_required;  // required for one hole, refused with --part
  CLI::Option* format_option = nullptr;
};

// One programmed point (docs/whole-program.md): the machine file's [tool] programmed_point,
// unless --program-point says otherwise; both given and different is a contradiction.
toolpath::ProgramPoint programmed_point(const ChamferArgs& a) {
  const auto parse = [](const std::string& p) {
    return p == "centre" ? toolpath::ProgramPoint::Centre : toolpath::ProgramPoint::Tip;
  };
  if (a.machine.empty()) return parse(a.point.value_or("tip"));
  const service::MachineConfig m = service::load_machine_config(a.machine);
  if (a.point && parse(*a.point) != m.tool.programmed_point) {
    throw InputError("--program-point " + *a.point + " contradicts the machine file " + a.machine +
                     ", whose [tool] programmed_point is " +
                     (m.tool.programmed_point == toolpath::ProgramPoint::Tip ? "tip" : "centre") +
                     ": every program for that machine drives one point; drop --program-point "
                     "or change the machine file");
  }
  return m.tool.programmed_point;
}

// `ncd chamfer --part FILE`: every hole of a part (app/chamfer_part.cpp).
int run_part(const ChamferArgs& a) {
  PartArgs p;
  p.part = a.part;
  p.machine = a.machine;
  p.point = a.point;
  if (a.format_option->count() > 0) p.format = a.format;
  p.output = a.output;
  p.plot = a.plot;
  p.quiet = a.quiet;
  return run_chamfer_part(p);
}

int run_chamfer(const ChamferArgs& a) {
  if (!a.part.empty()) return run_part(a);
  for (const CLI::Option* o : a.hole_required) {
    if (o->count() == 0) {
      throw InputError(o->get_name() +
                       " is required for one hole (or give --part FILE for every hole of a part)");
    }
  }
  toolpath::ChamferSpec spec = a.spec;
  spec.edge = a.edge == "inner" ? toolpath::Edge::Inner : toolpath::Edge::Outer;
  spec.side = a.side == "upper" ? toolpath::Side::Upper : toolpath::Side::Lower;
  spec.rod_radius_mm = a.rod_radius_mm;
  if (a.non_knife_angle_deg) {
    require_finite("non-knife angle (--non-knife-angle, deg)", *a.non_knife_angle_deg);
    spec.non_knife_angle_rad = deg_to_rad(*a.non_knife_angle_deg);
  }
  spec.avoid = !a.no_avoid;
  require_finite("drill tilt (--drill-tilt-deg)", a.tilt_deg);
  require_finite("drill azimuth (--drill-azimuth-deg)", a.azimuth_deg);
  require_finite("pipe half-angle (--pipe-half-angle-deg)", a.half_angle_deg);
  spec.drill_tilt_rad = deg_to_rad(a.tilt_deg);
  spec.drill_azimuth_rad = deg_to_rad(a.azimuth_deg);
  spec.pipe_half_angle_rad = deg_to_rad(a.half_angle_deg);
  spec.pipe_thickness_mm = a.pipe_thickness_mm;
  toolpath::validate(spec);
  toolpath::NgcOptions ngc;
  ngc.frame = a.frame == "drill" ? toolpath::ProgramFrame::Drill : toolpath::ProgramFrame::Pipe;
  ngc.feed_mm_per_min = a.feed_mm_per_min;
  ngc.spindle_rpm = a.spindle_rpm;
  ngc.point = programmed_point(a);
  // The controller's dialect ([link] dialect of --machine): what it cannot take is left out
  // where a choice exists (G64 P, M6), and the written program is checked against its rules.
  // The tool and the spindle's spin-up ([tool] number, spindle_dwell_s) as the whole job of the
  // blocks writes them (docs/whole-program.md).
  std::optional<comms::Dialect> dialect;
  if (!a.machine.empty()) {
    const service::MachineConfig m = service::load_machine_config(a.machine);
    dialect = m.link.dialect;
    ngc.tool = m.tool.number;
    ngc.spindle_dwell_s = m.tool.spindle_dwell_s;
  }
  if (dialect) {
    ngc.path_blending = comms::rules(*dialect).path_blending;
    ngc.percent = comms::rules(*dialect).percent_framing;
    ngc.tool_change = comms::rules(*dialect).tool_change;
    ngc.length_offset = comms::rules(*dialect).length_offsets;
  }
  ngc.safe_z_mm = a.safe_z_mm.value_or(toolpath::default_safe_z_mm(spec));
  require_positive("feed (--feed, mm/min)", ngc.feed_mm_per_min);
  require_positive("spindle speed (--spindle, rpm)", ngc.spindle_rpm);

  check_output(a.output, "-o");
  check_output(a.plot, "--plot");
  const auto t0 = std::chrono::steady_clock::now();
  const toolpath::ChamferPath path = toolpath::generate_chamfer(spec);
  const double elapsed_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();

  const auto& ck = path.checks;
  const bool interferes = !ck.local_ok || !ck.global_ok || !ck.rod_ok;
  std::string text;
  if (a.format == "json") {
    text = chamfer_json(path, ngc, a.non_knife_angle_deg, elapsed_ms).dump(1) + "\n";
  } else if (a.format == "csv") {
    text = chamfer_csv(path);
  } else {
    if (interferes && spec.avoid) {
      throw InputError(
          "the path interferes with the part: " + toolpath::interference_reasons(path) +
          ". No NC program written. Use a smaller --ball-radius (or another edge, "
          "tilt or set-up), or --no-avoid to write it anyway for a deliberate test "
          "cut");
    }
    text = toolpath::chamfer_program(path, ngc);
    if (dialect) {
      if (const auto v = comms::check_program(*dialect, text)) {
        throw InputError("the chamfer program breaks the machine's controller dialect: " +
                         comms::describe(*v, *dialect) + ". No NC program written.");
      }
    }
  }
  if (!a.plot.empty()) write_output(a.plot, render_svg(chamfer_figure(path)), "--plot");
  write_output(a.output, text);
  if (!a.quiet) {
    std::cerr << chamfer_summary(path, elapsed_ms);
    if (interferes) std::cerr << "warning: the path interferes with the part (see the checks)\n";
    if (!a.output.empty() && a.output != "-")
      std::cerr << "  wrote             " << a.output << "\n";
    if (!a.plot.empty()) std::cerr << "  wrote             " << a.plot << "\n";
  }
  return 0;
}

}  // namespace

void register_chamfer(CLI::App& app, Runner& run) {
  auto a = std::make_shared<ChamferArgs>();
  CLI::App* c = app.add_subcommand(
      "chamfer",
      "Tool path for a constant-width chamfer of a drilled hole in a pipe (paper 000). "
      "Drill frame: Z along the drill axis; with no tilt and no eccentricity the pipe axis is Y "
      "and the origin is where the axes cross; lengths in mm.");
  a->hole_required = {
      c->add_option("--pipe-radius", a->spec.pipe_radius_mm,
                    "radius of the pipe surface carrying the edge (R outside, R_I inside), mm "
                    "(required without --part)"),
      c->add_option("--drill-radius", a->spec.drill_radius_mm,
                    "drill (hole) radius r, mm (required without --part)"),
      c->add_option("--ball-radius", a->spec.ball_radius_mm,
                    "ball-end cutter radius R_B, mm (required without --part)"),
      c->add_option("--width", a->spec.width_mm,
                    "chamfer width W = |AB|, mm (required without --part)")};
  c->add_option("--tolerance", a->spec.tolerance_mm, "chordal tolerance ε, mm")
      ->capture_default_str();
  c->add_option("--edge", a->edge, "edge on the inner or outer pipe surface")
      ->check(CLI::IsMember({"inner", "outer"}))
      ->capture_default_str();
  c->add_option("--side", a->side,
                "upper (drill entry side) or lower edge; lower edges are "
                "written for the part turned over")
      ->check(CLI::IsMember({"upper", "lower"}))
      ->capture_default_str();
  c->add_option("--rod-radius", a->rod_radius_mm, "cutter rod radius R_od, mm (rod check)");
  c->add_option("--non-knife-angle", a->non_knife_angle_deg,
                "non-cutting cap angle 2β of the ball, degrees (rod check)");
  c->add_option("--drill-tilt-deg", a->tilt_deg,
                "angle τ of the drill axis from the pipe's radial Z direction, degrees, [0, 90)")
      ->capture_default_str();
  c->add_option("--drill-azimuth-deg", a->azimuth_deg,
                "direction of the tilt about Z, degrees: 0 along the pipe axis (a lateral), "
                "90 across it")
      ->capture_default_str();
  c->add_option("--eccentricity", a->spec.eccentricity_mm,
                "distance of the drill axis from the pipe axis (signed, along pipe Y × drill), mm")
      ->capture_default_str();
  c->add_option("--pipe-half-angle-deg", a->half_angle_deg,
                "half-angle ψ of a cone pipe (radius growing along +Y; --pipe-radius is taken "
                "where the drill axis passes nearest), degrees; 0 = cylinder")
      ->capture_default_str();
  c->add_option("--pipe-thickness", a->pipe_thickness_mm,
                "wall thickness, mm: the drill must then pierce the other wall surface too");
  c->add_option("--frame", a->frame,
                "frame of the NC program: drill (Z along the drill axis, part set up with the "
                "hole vertical) or pipe (only for an untilted drill)")
      ->check(CLI::IsMember({"drill", "pipe"}))
      ->capture_default_str();
  c->add_flag("--no-avoid", a->no_avoid,
              "keep α = 1 and report interference instead of avoiding it (Algorithm 1 off)");
  c->add_option("--initial-segments", a->spec.initial_segments,
                "N equal-arc-length pieces before chordal refinement")
      ->capture_default_str();
  a->format_option =
      c->add_option("--format", a->format, "output format (with --part: ngc, the default, or json)")
          ->check(CLI::IsMember({"json", "csv", "ngc"}))
          ->capture_default_str();
  c->add_option("-o,--output", a->output, "output file (default: standard output)");
  c->add_option("--plot", a->plot, "also write the checks of Fig. 14 as an SVG plot");
  c->add_option("--feed", a->feed_mm_per_min, "feed for the NC program, mm/min")
      ->capture_default_str();
  c->add_option("--spindle", a->spindle_rpm, "spindle speed for the NC program, rpm")
      ->capture_default_str();
  c->add_option("--program-point", a->point,
                "what the NC program drives: the ball tip (tool length to the tip) or centre "
                "(default: the --machine file's [tool] programmed_point, else tip)")
      ->check(CLI::IsMember({"tip", "centre"}));
  c->add_option("--machine", a->machine,
                "machine file whose [tool] programmed_point the NC program follows");
  c->add_option("--safe-z", a->safe_z_mm,
                "clearance height of the NC program, mm (default: pipe radius + 4 R_B; for an "
                "inner edge it must clear the outer surface too)");
  c->add_flag("-q,--quiet", a->quiet, "no summary on standard error");
  CLI::Option* part =
      c->add_option("--part", a->part,
                    "part file (TOML, docs/part.md): every hole of a pipe on a rotary axis in one "
                    "program; takes --machine, --program-point, --format, -o, --plot");
  for (CLI::Option* o : c->get_options()) {
    const std::string name = o->get_name();
    if (o == part || name == "--machine" || name == "--program-point" || name == "--format" ||
        name == "-o" || name == "--output" || name == "--plot" || name == "-q" ||
        name == "--quiet" || name == "--help" || name == "-h" || o->get_lnames().empty()) {
      continue;
    }
    part->excludes(o);
  }
  c->callback([a, &run] { run = [a] { return run_chamfer(*a); }; });
}

}  // namespace ncd::app
