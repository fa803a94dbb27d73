// RS-274/NGC writer for a chamfer loop (LinuxCNC dialect): a header comment that states every
// parameter, G21 G90 G94, the tool (T n M6, or a header line asking for it where the controller
// has no tool change) and its length (G43 H n before the first move: without it a Fanuc or
// LinuxCNC drives the spindle's gauge line, and the tip runs low by the whole tool length; a
// header line saying how to set it where the controller has no tool table), the spindle (S M3, then
// G4 P for its spin-up when the machine file gives one), an approach, the closed loop of G1 moves,
// a retract, M5, M2: the same sequence as the whole job of the blocks (cam/whole_program.hpp,
// docs/whole-program.md).
//
// Frames (docs/chamfer.md): by default the drill frame, Z along the drill axis, X0 Y0 on it, Z0
// at the foot of the common perpendicular with the pipe axis; the header says how the pipe axis
// then lies, i.e. how to set up the part. The pipe frame (Z0 on the pipe axis, pipe along Y) is
// the same up to a shift by the eccentricity when the drill is not tilted, and refused when it
// is: a 3-axis machine cuts along +Z, and every check assumes that is the drill axis. A lower
// edge is cut with the part turned over, rotated 180° about Y (X → −X, Z → −Z), which maps it
// onto an upper one; the header says so.
// Approach: inner edges are reached down the drill axis and then outwards (the ball only fits
// through the hole near its axis); outer edges by a vertical descent onto the first point.
#include "cam/chamfer_ngc.hpp"

#include <cmath>
#include <iomanip>
#include <sstream>

#include "core/error.hpp"
#include "core/number_text.hpp"

namespace ncd::toolpath {
std::string to_string(ProgramFrame frame) {
  return frame == ProgramFrame::Drill ? "drill" : "pipe";
}

std::string tool_length_text(ProgramPoint point, int tool, bool length_offset) {
  const std::string to = point == ProgramPoint::Tip ? "the ball tip" : "the ball centre";
  const std::string t = std::to_string(tool);
  if (length_offset) return "tool length: G43 H" + t + ", the controller's table, to " + to;
  return "tool length: no tool table; set work Z0 at tool " + t + "'s " +
         (point == ProgramPoint::Tip ? "tip" : "centre") + " or give G43.1 Z";
}

double default_safe_z_mm(const ChamferSpec& spec) {
  ChamferSpec rim = spec;  // the outer surface's edge on the same side
  if (const auto other = companion_radius_mm(spec); other && spec.edge == Edge::Inner) {
    rim.pipe_radius_mm = *other;
    rim.edge = Edge::Outer;
  }
  rim.pipe_thickness_mm.reset();
  rim.rod_radius_mm.reset();
  rim.non_knife_angle_rad.reset();
  const ChamferModel model(rim);
  const double sign = spec.side == Side::Upper ? 1.0 : -1.0;  // lower edges turned over
  double top = -1e300;
  for (int i = 0; i < 720; ++i) top = std::max(top, sign * model.point(i * kPi / 360.0).z());
  return top + 4.0 * spec.ball_radius_mm;
}

Vec3 program_frame_point(const ChamferSpec& spec, const Vec3& q, ProgramFrame frame) {
  Vec3 p = frame == ProgramFrame::Pipe ? drill_placement(spec).to_pipe(q) : q;
  if (spec.side == Side::Lower) p = Vec3(-p.x(), p.y(), -p.z());
  return p;
}

Vec3 program_point(const ChamferSpec& spec, const CutterPose& pose, ProgramPoint point,
                   ProgramFrame frame) {
  Vec3 p = program_frame_point(spec, pose.cl, frame);
  if (point == ProgramPoint::Tip) p.z() -= spec.ball_radius_mm;
  return p;
}

namespace {

bool is_paper_case(const ChamferSpec& s) {
  return s.drill_tilt_rad == 0.0 && s.eccentricity_mm == 0.0;
}

void check_options(const ChamferPath& path, const NgcOptions& o) {
  const ChamferSpec& s = path.spec;
  require_positive("feed (--feed, mm/min)", o.feed_mm_per_min);
  require_positive("spindle speed (--spindle, rpm)", o.spindle_rpm);
  require_finite("safe Z (--safe-z, mm)", o.safe_z_mm);
  if (o.tool < 0) {
    throw InputError("tool number " + std::to_string(o.tool) +
                     " must be 0 or more; set [tool] number in the machine file");
  }
  if (!(o.spindle_dwell_s >= 0.0) || !std::isfinite(o.spindle_dwell_s)) {
    throw InputError("spindle dwell " + text::fixed(o.spindle_dwell_s, 3) +
                     " s must be 0 or more; set [tool] spindle_dwell_s to the spin-up time");
  }
  if (path.points.empty()) throw InputError("the chamfer path has no points");
  if (o.frame == ProgramFrame::Pipe && s.drill_tilt_rad != 0.0) {
    throw InputError("the pipe frame puts the machine's Z at the drill tilt τ = " +
                     text::fixed(rad_to_deg(s.drill_tilt_rad), 3) +
                     " deg to the hole, but a 3-axis machine cuts along +Z and the ball, its cap "
                     "and its rod are checked along the drill axis; use --frame drill and set up "
                     "the part with the drill axis vertical as the program's header says");
  }
}

// The top of the ball along the loop and the loop's length, in the program's frame (mm).
struct LoopExtent {
  double top_mm = -1e300, length_mm = 0.0;
};

LoopExtent loop_extent(const ChamferPath& path, const NgcOptions& o) {
  const ChamferSpec& s = path.spec;
  const auto at = [&](std::size_t i) { return program_point(s, path.points[i], o.point, o.frame); };
  LoopExtent e;
  for (std::size_t i = 0; i < path.points.size(); ++i) {
    const Vec3 p = at(i);
    const Vec3 q = at((i + 1) % path.points.size());
    e.top_mm =
        std::max(e.top_mm, p.z() + (o.point == ProgramPoint::Tip ? 2.0 : 1.0) * s.ball_radius_mm);
    e.length_mm += (q - p).norm();
  }
  return e;
}

// The chamfer's data as comments: edge, pipe, drill, ball, width, tolerance, rod.
void write_spec_comments(std::ostream& g, const ChamferSpec& s) {
  g << "(ncd chamfer: constant-width chamfer of a drilled hole in a pipe, Sato et al. 2016)\n";
  g << "(edge " << to_string(s.edge) << " " << to_string(s.side) << ", pipe surface radius "
    << text::fixed(s.pipe_radius_mm, 4) << " mm, drill radius " << text::fixed(s.drill_radius_mm, 4)
    << " mm)\n";
  g << "(ball radius " << text::fixed(s.ball_radius_mm, 4) << " mm, chamfer width "
    << text::fixed(s.width_mm, 4) << " mm, chordal tolerance " << text::fixed(s.tolerance_mm, 5)
    << " mm, " << s.initial_segments << " initial segments)\n";
  g << "(rod radius " << (s.rod_radius_mm ? text::fixed(*s.rod_radius_mm, 4) + " mm" : "not given")
    << ", non-knife angle "
    << (s.non_knife_angle_rad ? text::fixed(rad_to_deg(*s.non_knife_angle_rad), 3) + " deg"
                              : "not given")
    << ", rod avoidance " << (s.avoid ? "on" : "off (alpha = 1)") << ")\n";
  const bool paper = is_paper_case(s);
  if (!paper || s.pipe_half_angle_rad != 0.0 || s.pipe_thickness_mm) {
    g << "(drill tilt " << text::fixed(rad_to_deg(s.drill_tilt_rad), 3) << " deg, azimuth "
      << text::fixed(rad_to_deg(s.drill_azimuth_rad), 3) << " deg, eccentricity "
      << text::fixed(s.eccentricity_mm, 4) << " mm, pipe half-angle "
      << text::fixed(rad_to_deg(s.pipe_half_angle_rad), 3) << " deg, wall thickness "
      << (s.pipe_thickness_mm ? text::fixed(*s.pipe_thickness_mm, 4) + " mm" : "not given")
      << ")\n";
  }
}

// The program's frame and the part's set-up as comments.
void write_frame_comments(std::ostream& g, const ChamferSpec& s, const NgcOptions& o) {
  const int d = o.decimals;
  const Vec3 axis_xy = program_frame_point(s, Vec3::Zero(), o.frame);  // drill axis at z = 0
  if (is_paper_case(s)) {
    g << "(frame: X0 Y0 on the drill axis, Z0 on the pipe axis, pipe along Y, units mm)\n";
  } else if (o.frame == ProgramFrame::Pipe) {
    g << "(frame: PIPE frame: pipe axis along Y through X0 Z0, drill axis vertical through X"
      << text::fixed(axis_xy.x(), d) << " Y0, units mm)\n";
  } else {
    const PipeSurface surf = pipe_surface(s, s.pipe_radius_mm);
    const Vec3 p0 = program_frame_point(s, surf.axis_point, o.frame);
    Vec3 a = surf.axis_direction;
    if (s.side == Side::Lower) a = Vec3(-a.x(), a.y(), -a.z());
    g << "(frame: DRILL frame: Z along the drill axis, X0 Y0 on it, Z0 where it is closest to the "
         "pipe axis, units mm)\n";
    g << "(set-up: clamp the part with the DRILL AXIS VERTICAL; the pipe axis then passes "
         "through X"
      << text::fixed(p0.x(), d) << " Y" << text::fixed(p0.y(), d) << " Z" << text::fixed(p0.z(), d)
      << " with direction X" << text::fixed(a.x(), 4) << " Y" << text::fixed(a.y(), 4) << " Z"
      << text::fixed(a.z(), 4) << ", rising "
      << text::fixed(rad_to_deg(std::asin(std::abs(a.z()))), 3) << " deg out of the XY plane)\n";
    if (a.z() != 0.0) {
      g << "(safe Z clears the hole's rim; the inclined pipe rises higher away from the hole:"
           " start with the tool above the hole)\n";
    }
  }
  if (s.side == Side::Lower) {
    g << "(LOWER EDGE: written for the part TURNED OVER, rotated 180 deg about the pipe axis Y:"
         " X -> -X, Z -> -Z)\n";
  }
}

}  // namespace

std::string chamfer_program(const ChamferPath& path, const NgcOptions& o) {
  const ChamferSpec& s = path.spec;
  check_options(path, o);
  const auto at = [&](std::size_t i) { return program_point(s, path.points[i], o.point, o.frame); };
  const LoopExtent extent = loop_extent(path, o);
  const double top = extent.top_mm, length = extent.length_mm;
  if (o.safe_z_mm <= top) {
    throw InputError("safe Z = " + text::fixed(o.safe_z_mm, 3) +
                     " mm is not above the top of the ball " + "along the loop (" +
                     text::fixed(top, 3) + " mm); use a larger --safe-z");
  }
  const int d = o.decimals;
  const auto xyz = [d](const Vec3& p) {
    return "X" + text::fixed(p.x(), d) + " Y" + text::fixed(p.y(), d) + " Z" +
           text::fixed(p.z(), d);
  };
  const ChamferChecks& ck = path.checks;
  std::ostringstream g;
  if (o.percent) g << "%\n";
  write_spec_comments(g, s);
  write_frame_comments(g, s, o);
  const Vec3 axis_xy = program_frame_point(s, Vec3::Zero(), o.frame);  // drill axis at z = 0
  g << "(programmed point: "
    << (o.point == ProgramPoint::Tip ? "ball TIP = centre - " + text::fixed(s.ball_radius_mm, 4) +
                                           " mm in Z; tool length set to the tip"
                                     : "ball CENTRE; tool length set to the ball centre")
    << ")\n";
  if (!o.tool_change) {
    g << "(load tool " << o.tool << " before the start: this controller has no tool change, M6)\n";
  }
  g << "(" << tool_length_text(o.point, o.tool, o.length_offset) << ")\n";
  g << "(checks: local " << (ck.local_ok ? "ok" : "INTERFERES") << ", global "
    << (ck.global_ok ? "ok" : "INTERFERES") << ", rod "
    << (!ck.limit_radius_mm ? "not checked"
        : ck.rod_ok         ? "ok"
                            : "INTERFERES")
    << "; alpha adjusted at " << ck.adjusted_points << " points)\n";
  g << "(" << path.points.size() << " points, loop length " << text::fixed(length, 3) << " mm, "
    << text::fixed(60.0 * length / o.feed_mm_per_min, 2) << " s at F"
    << text::fixed(o.feed_mm_per_min, 1) << ", safe Z " << text::fixed(o.safe_z_mm, 3) << " mm)\n";
  g << "G21 G90 G94 G17 G40 G49\n";
  if (o.path_blending) {
    g << "G64 P" << text::fixed(s.tolerance_mm, 4) << "\n";
  } else {
    g << "(no G64 P: this controller has no blending tolerance; its own path mode applies)\n";
  }
  if (o.tool_change) g << "T" << o.tool << " M6\n";
  if (o.length_offset) g << "G43 H" << o.tool << "\n";
  g << "S" << text::fixed(o.spindle_rpm, 0) << " M3\n";
  if (o.spindle_dwell_s > 0.0) g << "G4 P" << text::fixed(o.spindle_dwell_s, 3) << "\n";
  g << "G0 Z" << text::fixed(o.safe_z_mm, d) << "\n";
  const Vec3 first = at(0);
  const std::string axis = "X" + text::fixed(axis_xy.x(), d) + " Y" + text::fixed(axis_xy.y(), d);
  if (s.edge == Edge::Inner) {
    g << "G0 " << axis << "\n";
    g << "G1 Z" << text::fixed(first.z(), d) << " F" << text::fixed(o.feed_mm_per_min, 1) << "\n";
    g << "G1 " << xyz(first) << "\n";
  } else {
    g << "G0 X" << text::fixed(first.x(), d) << " Y" << text::fixed(first.y(), d) << "\n";
    g << "G1 Z" << text::fixed(first.z(), d) << " F" << text::fixed(o.feed_mm_per_min, 1) << "\n";
  }
  for (std::size_t i = 1; i < path.points.size(); ++i) {
    g << "G1 " << xyz(at(i)) << "\n";
  }
  g << "G1 " << xyz(first) << " (loop closed)\n";
  if (s.edge == Edge::Inner) g << "G1 " << axis << "\n";
  g << "G0 Z" << text::fixed(o.safe_z_mm, d) << "\n";
  g << "M5\nM2\n";
  if (o.percent) g << "%\n";
  return g.str();
}

}  // namespace ncd::toolpath
