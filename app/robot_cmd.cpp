// `ncd robot`: the chamfer of a hole through a cylinder for a 6-axis robot holding a rotary bar
// (paper 002): poses with W, P, R attitudes in the robot frame, as JSON or as a plain text
// program whose header documents it. The geometry is in cam/robot.cpp.
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "app/commands.hpp"
#include "cam/robot.hpp"
#include "core/error.hpp"
#include "core/input_file.hpp"
#include "core/number_text.hpp"
#include "core/output_file.hpp"

namespace ncd::app {
namespace {

using nlohmann::ordered_json;
using toolpath::AttitudeStats;
using toolpath::RobotPath;
using toolpath::RobotProgram;
using toolpath::TouchFit;

constexpr int kTextDecimals = 4;  // 0.1 µm and 0.0001° in the text program

struct RobotArgs {
  toolpath::RobotSpec spec;
  toolpath::RobotProgramOptions program;
  std::string rule = "paper", format = "json", output, touch_points;
  std::optional<double> depth_mm, chamfer_width_mm;
  double start_angle_deg = 0.0;
  double max_touch_residual_mm = 0.5;
  bool quiet = false;
};

// The touch-point file (--touch-points), read as toolpath::parse_touch_points() describes.
std::vector<toolpath::TouchPoint> read_touch_points(const std::string& path) {
  return toolpath::parse_touch_points(read_input_file(path, "touch-point file, --touch-points"),
                                      path);
}

ordered_json vec(const Vec3& v) {
  return ordered_json::array({v.x(), v.y(), v.z()});
}

ordered_json deg3(double a, double b, double c) {
  return ordered_json::array({rad_to_deg(a), rad_to_deg(b), rad_to_deg(c)});
}

ordered_json attitude_json(const RobotPath& path) {
  const AttitudeStats& c = path.chosen();
  ordered_json j;
  j["rule"] = toolpath::to_string(path.spec.rule);
  j["total"] = rad_to_deg(c.total_rad);
  j["max"] = rad_to_deg(c.max_rad);
  j["naive_total"] = rad_to_deg(path.naive.total_rad);
  j["naive_max"] = rad_to_deg(path.naive.max_rad);
  j["paper_total"] = rad_to_deg(path.paper.total_rad);
  j["paper_max"] = rad_to_deg(path.paper.max_rad);
  j["min_change_total"] = rad_to_deg(path.min_change.total_rad);
  j["min_change_max"] = rad_to_deg(path.min_change.max_rad);
  j["excursion_max"] = rad_to_deg(c.excursion_max_rad);
  j["naive_excursion_max"] = rad_to_deg(path.naive.excursion_max_rad);
  j["paper_excursion_max"] = rad_to_deg(path.paper.excursion_max_rad);
  j["min_change_excursion_max"] = rad_to_deg(path.min_change.excursion_max_rad);
  return j;
}

ordered_json robot_json(const RobotArgs& a, const RobotPath& path, const RobotProgram& prog,
                        const std::optional<TouchFit>& fit) {
  const auto& s = path.spec;
  const auto& o = prog.options;
  ordered_json in;
  in["cylinder_radius_mm"] = s.cylinder_radius_mm;
  in["hole_radius_mm"] = s.hole_radius_mm;
  in["points"] = s.points;
  in["start_angle_deg"] = a.start_angle_deg;
  in["depth_mm"] = s.depth_mm;
  in["passes"] = s.passes;
  in["chamfer_width_mm"] = 2.0 * s.depth_mm * s.passes;
  in["bar_radius_mm"] = s.bar_radius_mm;
  in["rule"] = toolpath::to_string(s.rule);
  in["speed_mm_per_s"] = o.speed_mm_per_s;
  in["move_speed_mm_per_s"] = o.move_speed_mm_per_s;
  in["spindle_rpm"] = o.spindle_rpm;
  in["approach_distance_mm"] = o.approach_distance_mm;
  in["touch_points"] = a.touch_points.empty() ? ordered_json() : ordered_json(a.touch_points);
  in["max_touch_residual_mm"] = a.max_touch_residual_mm;

  ordered_json tr;
  const toolpath::RigidTransform t = fit ? fit->transform : toolpath::RigidTransform{};
  tr["source"] = fit ? "touch points" : "identity (no --touch-points)";
  tr["rotation"] = ordered_json::array();
  for (int i = 0; i < 3; ++i) tr["rotation"].push_back(vec(t.rotation.row(i).transpose()));
  tr["translation_mm"] = vec(t.translation_mm);
  const toolpath::Wpr twpr = toolpath::matrix_to_wpr(t.rotation);
  tr["wpr_deg"] = deg3(twpr.w_rad, twpr.p_rad, twpr.r_rad);
  if (fit) {
    tr["touches"] = fit->residual_mm.size();
    tr["residual_rms_mm"] = fit->rms_mm;
    tr["residual_max_mm"] = fit->max_mm;
    tr["residual_mm"] = fit->residual_mm;
  }

  ordered_json poses = ordered_json::array();
  for (std::size_t i = 0; i < prog.moves.size(); ++i) {
    const auto& mv = prog.moves[i];
    const auto& p = mv.pose;
    ordered_json j;
    j["n"] = i + 1;
    j["mode"] = toolpath::to_string(mv.mode);
    j["pass"] = p.pass;
    j["theta_deg"] = rad_to_deg(p.theta_rad);
    j["p"] = vec(p.p_mm);
    j["edge"] = vec(p.edge_mm);
    j["F"] = vec(p.f);
    j["D"] = vec(p.d);
    j["Tf"] = vec(p.tf);
    j["Tg"] = vec(p.tg);
    j["wpr_deg"] = deg3(mv.wpr.w_rad, mv.wpr.p_rad, mv.wpr.r_rad);
    j["speed_mm_per_s"] = mv.speed_mm_per_s;
    j["attitude_change_deg"] = rad_to_deg(mv.attitude_change_rad);
    poses.push_back(std::move(j));
  }

  const auto& ck = path.checks;
  ordered_json checks;
  checks["surface_residual_mm"] = ck.surface_residual_mm;
  checks["wall_angle_deg"] = {rad_to_deg(ck.wall_angle_min_rad), rad_to_deg(ck.wall_angle_max_rad)};
  checks["tf_cylinder_angle_deg"] = {rad_to_deg(ck.tf_cylinder_angle_min_rad),
                                     rad_to_deg(ck.tf_cylinder_angle_max_rad)};
  checks["frame_error"] = ck.frame_error;
  checks["wpr_roundtrip_error"] = prog.wpr_roundtrip_error;
  checks["chord_deviation_mm"] = ck.chord_deviation_mm;

  ordered_json out;
  out["format"] = "ncd-robot 1";
  out["input"] = std::move(in);
  out["transform"] = std::move(tr);
  out["attitude_change_deg"] = attitude_json(path);
  out["checks"] = std::move(checks);
  out["cut_length_mm"] = prog.cut_length_mm;
  out["move_length_mm"] = prog.move_length_mm;
  out["duration_s"] = prog.duration_s;
  out["poses"] = std::move(poses);
  return out;
}

std::string attitude_line(const char* name, const AttitudeStats& s) {
  return std::string(name) + "total " + text::fixed(rad_to_deg(s.total_rad), 3) +
         ", largest step " + text::fixed(rad_to_deg(s.max_rad), 3) +
         ", largest from the first pose " + text::fixed(rad_to_deg(s.excursion_max_rad), 3);
}

std::string robot_text(const RobotPath& path, const RobotProgram& prog,
                       const std::optional<TouchFit>& fit) {
  const auto& s = path.spec;
  const auto& o = prog.options;
  const auto& ck = path.checks;
  std::ostringstream t;
  t << "# ncd robot: chamfer of a hole through a cylinder, 6-axis robot with a rotary bar "
       "(paper 002)\n"
    << "# format: ncd-robot-text 1\n"
    << "# cylinder radius R " << text::sig(s.cylinder_radius_mm) << " mm, hole radius r "
    << text::sig(s.hole_radius_mm) << " mm, " << s.points << " points per loop (step "
    << text::sig(360.0 / s.points) << " deg), start angle "
    << text::sig(rad_to_deg(s.start_angle_rad))
    << " deg, travel clockwise seen from outside the hole\n"
    << "# depth of cut " << text::sig(s.depth_mm) << " mm per pass, " << s.passes
    << " pass(es), chamfer width " << text::sig(2.0 * s.depth_mm * s.passes)
    << " mm (45 deg to the "
    << "hole wall), TCP "
    << (s.bar_radius_mm > 0.0
            ? "on the bar's axis, bar radius " + text::sig(s.bar_radius_mm) + " mm"
            : std::string("on the bar's side"))
    << "\n"
    << "# spindle " << text::sig(o.spindle_rpm)
    << " rpm on before the first line, off after the last; "
    << "chamfering speed " << text::sig(o.speed_mm_per_s) << " mm/s, moving speed "
    << text::sig(o.move_speed_mm_per_s) << " mm/s\n"
    << "# T_g rule: " << toolpath::to_string(s.rule) << "; attitude change (deg), "
    << "rotation angle of R_prev^T R_next:\n"
    << "#   " << attitude_line("paper       ", path.paper) << "\n"
    << "#   " << attitude_line("min-change  ", path.min_change) << "\n"
    << "#   " << attitude_line("naive T_g=T_f ", path.naive) << "\n";
  if (fit) {
    const toolpath::Wpr w = toolpath::matrix_to_wpr(fit->transform.rotation);
    t << "# workpiece to robot: " << fit->residual_mm.size() << " touch points, residual rms "
      << text::fixed(fit->rms_mm, 4) << " mm, max " << text::fixed(fit->max_mm, 4)
      << " mm; translation " << text::fixed(fit->transform.translation_mm.x(), 4) << " "
      << text::fixed(fit->transform.translation_mm.y(), 4) << " "
      << text::fixed(fit->transform.translation_mm.z(), 4) << " mm, rotation W P R "
      << text::fixed(rad_to_deg(w.w_rad), 4) << " " << text::fixed(rad_to_deg(w.p_rad), 4) << " "
      << text::fixed(rad_to_deg(w.r_rad), 4) << " deg\n";
  } else {
    t << "# workpiece to robot: identity (no touch points): the robot frame is the workpiece "
         "frame (hole axis z, cylinder axis y, origin where they cross)\n";
  }
  t << "# checks: edge on both surfaces to " << text::sig(ck.surface_residual_mm)
    << " mm; D and T_f to the hole wall " << text::fixed(rad_to_deg(ck.wall_angle_min_rad), 6)
    << ".." << text::fixed(rad_to_deg(ck.wall_angle_max_rad), 6)
    << " deg; T_f to the cylinder surface "
    << text::fixed(rad_to_deg(ck.tf_cylinder_angle_min_rad), 3) << ".."
    << text::fixed(rad_to_deg(ck.tf_cylinder_angle_max_rad), 3) << " deg; frames orthonormal to "
    << text::sig(ck.frame_error) << "; W,P,R round trip to " << text::sig(prog.wpr_roundtrip_error)
    << "; chord deviation " << text::fixed(ck.chord_deviation_mm, 4) << " mm\n"
    << "# cut length " << text::fixed(prog.cut_length_mm, 3) << " mm, duration "
    << text::fixed(prog.duration_s, 1) << " s from the approach pose\n"
    << "# tool frame: +z along the bar's axis towards its tip (D), +x along T_g (the arm's "
       "last axis, away from the wrist)\n"
    << "# W P R: rotations about the fixed robot x, y, z axes in that order, "
       "R = Rz(R) Ry(P) Rx(W), degrees\n"
    << "# each line is one move, ending at its pose: move = positioning, cut = chamfering\n"
    << "# columns: n mode x_mm y_mm z_mm w_deg p_deg r_deg speed_mm_per_s\n";
  const int d = kTextDecimals;
  for (std::size_t i = 0; i < prog.moves.size(); ++i) {
    const auto& mv = prog.moves[i];
    const Vec3& p = mv.pose.p_mm;
    t << (i + 1) << ' ' << toolpath::to_string(mv.mode) << ' ' << text::fixed(p.x(), d) << ' '
      << text::fixed(p.y(), d) << ' ' << text::fixed(p.z(), d) << ' '
      << text::fixed(rad_to_deg(mv.wpr.w_rad), d) << ' ' << text::fixed(rad_to_deg(mv.wpr.p_rad), d)
      << ' ' << text::fixed(rad_to_deg(mv.wpr.r_rad), d) << ' ' << text::sig(mv.speed_mm_per_s)
      << '\n';
  }
  return t.str();
}

std::string robot_summary(const RobotPath& path, const RobotProgram& prog,
                          const std::optional<TouchFit>& fit) {
  const auto& s = path.spec;
  std::ostringstream o;
  o << "robot: R " << text::sig(s.cylinder_radius_mm) << " mm, r " << text::sig(s.hole_radius_mm)
    << " mm, " << s.points << " points x " << s.passes << " pass(es), rule "
    << toolpath::to_string(s.rule) << "\n";
  o << "  attitude change (deg):\n";
  o << "    " << attitude_line("paper       ", path.paper) << "\n";
  o << "    " << attitude_line("min-change  ", path.min_change) << "\n";
  o << "    " << attitude_line("naive       ", path.naive) << "\n";
  if (fit) {
    o << "  touch fit         " << fit->residual_mm.size() << " points, residual rms "
      << text::fixed(fit->rms_mm, 4) << " mm, max " << text::fixed(fit->max_mm, 4) << " mm\n";
  }
  o << "  T_f to cylinder   " << text::fixed(rad_to_deg(path.checks.tf_cylinder_angle_min_rad), 3)
    << " .. " << text::fixed(rad_to_deg(path.checks.tf_cylinder_angle_max_rad), 3)
    << " deg (45 deg to the hole wall)\n";
  o << "  moves             " << prog.moves.size() << ", cut " << text::fixed(prog.cut_length_mm, 3)
    << " mm, " << text::fixed(prog.duration_s, 1) << " s\n";
  return o.str();
}

int run_robot(const RobotArgs& a) {
  toolpath::RobotSpec spec = a.spec;
  require_finite("start angle (--start-angle, deg)", a.start_angle_deg);
  spec.start_angle_rad = deg_to_rad(a.start_angle_deg);
  spec.rule = a.rule == "paper"        ? toolpath::TgRule::Paper
              : a.rule == "min-change" ? toolpath::TgRule::MinChange
                                       : toolpath::TgRule::Naive;
  if (a.chamfer_width_mm) {
    require_positive("chamfer width (--chamfer-width, mm)", *a.chamfer_width_mm);
    spec.depth_mm = *a.chamfer_width_mm / (2.0 * spec.passes);
  } else if (a.depth_mm) {
    spec.depth_mm = *a.depth_mm;
  }
  require_positive("largest touch residual (--max-touch-residual, mm)", a.max_touch_residual_mm);

  std::optional<TouchFit> fit;
  if (!a.touch_points.empty()) {
    fit = toolpath::fit_touch_points(read_touch_points(a.touch_points));
    if (fit->max_mm > a.max_touch_residual_mm) {
      std::size_t worst = 0;
      for (std::size_t i = 0; i < fit->residual_mm.size(); ++i) {
        if (fit->residual_mm[i] > fit->residual_mm[worst]) worst = i;
      }
      throw InputError("the touch points do not fit one rigid motion: touch " +
                       std::to_string(worst + 1) + " is " + text::sig(fit->max_mm) +
                       " mm off the best fit (rms " + text::sig(fit->rms_mm) + " mm), more than " +
                       text::sig(a.max_touch_residual_mm) + " mm; check that line of " +
                       a.touch_points + ", touch again, or raise --max-touch-residual");
    }
  }
  const RobotPath path = toolpath::generate_robot_path(spec);
  const RobotProgram prog = toolpath::make_robot_program(
      path, fit ? fit->transform : toolpath::RigidTransform{}, a.program);
  const std::string text = a.format == "json" ? robot_json(a, path, prog, fit).dump(1) + "\n"
                                              : robot_text(path, prog, fit);
  write_output(a.output, text);
  if (!a.quiet) {
    std::cerr << robot_summary(path, prog, fit);
    if (!a.output.empty() && a.output != "-")
      std::cerr << "  wrote             " << a.output << "\n";
  }
  return 0;
}

}  // namespace

void register_robot(CLI::App& app, Runner& run) {
  auto a = std::make_shared<RobotArgs>();
  CLI::App* c = app.add_subcommand(
      "robot",
      "Chamfer of a hole through a cylinder by a 6-axis robot holding a rotary bar (paper 002): "
      "poses (position, tool axis D, pushing direction T_f, holder direction T_g) as W, P, R. "
      "Workpiece frame: hole axis = Z, cylinder axis = Y, origin where they cross; mm, degrees.");
  c->add_option("--cylinder-radius", a->spec.cylinder_radius_mm, "cylinder radius R, mm")
      ->required();
  c->add_option("--hole-radius", a->spec.hole_radius_mm, "hole radius r < R, mm")->required();
  c->add_option("--points", a->spec.points, "chamfering points per loop N (equal steps 360/N)")
      ->capture_default_str();
  c->add_option("--start-angle", a->start_angle_deg,
                "angle of the first point about the hole axis, from +X towards +Y, degrees")
      ->capture_default_str();
  auto* depth = c->add_option("--depth", a->depth_mm,
                              "depth of cut per pass along T_f, mm (default 0.1, the paper's)");
  auto* width = c->add_option("--chamfer-width", a->chamfer_width_mm,
                              "final chamfer width 2 x depth x passes, mm (instead of --depth)");
  depth->excludes(width);
  c->add_option("--passes", a->spec.passes, "loops, each one depth deeper")->capture_default_str();
  c->add_option("--bar-radius", a->spec.bar_radius_mm,
                "bar radius, mm, when the TCP is taught on the bar's axis (0: on its side)")
      ->capture_default_str();
  c->add_option("--rule", a->rule,
                "T_g about D: paper (turn by -(n-1) x step), min-change (smallest attitude "
                "change from the previous pose), naive (T_g = T_f)")
      ->check(CLI::IsMember({"paper", "min-change", "naive"}))
      ->capture_default_str();
  c->add_option("--speed", a->program.speed_mm_per_s, "chamfering speed, mm/s")
      ->capture_default_str();
  c->add_option("--move-speed", a->program.move_speed_mm_per_s,
                "positioning speed of the approach and retract moves, mm/s")
      ->capture_default_str();
  c->add_option("--spindle", a->program.spindle_rpm, "rotary bar speed, rpm")
      ->capture_default_str();
  c->add_option("--approach-distance", a->program.approach_distance_mm,
                "approach and retract distance along the chamfer normal N, mm")
      ->capture_default_str();
  c->add_option("--touch-points", a->touch_points,
                "file of touches 'x_w y_w z_w x_r y_r z_r' (workpiece, robot frame; mm), three "
                "or more: the workpiece-to-robot transform (least squares beyond three)");
  c->add_option("--max-touch-residual", a->max_touch_residual_mm,
                "largest residual of a touch against the fitted transform, mm")
      ->capture_default_str();
  c->add_option("--format", a->format, "output format")
      ->check(CLI::IsMember({"json", "text"}))
      ->capture_default_str();
  c->add_option("-o,--output", a->output, "output file (default: standard output)");
  c->add_flag("-q,--quiet", a->quiet, "no summary on standard error");
  c->callback([a, &run] { run = [a] { return run_robot(*a); }; });
}

}  // namespace ncd::app
