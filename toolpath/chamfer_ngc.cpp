// RS-274/NGC writer for a chamfer loop (LinuxCNC dialect): a header comment that states every
// parameter, G21 G90 G94, an approach, the closed loop of G1 moves, a retract, M2.
//
// Frame: X0 Y0 on the drill axis, Z0 on the pipe axis, pipe along Y. A 3-axis machine works
// from +Z, so a lower edge is cut with the part turned over, rotated 180° about the pipe axis
// (X → −X, Z → −Z), which maps the lower edge onto an upper one; the header says so.
// Approach: inner edges are reached down the drill axis and then outwards (the ball only fits
// through the hole near its axis); outer edges by a vertical descent onto the first point.
#include "toolpath/chamfer_ngc.hpp"

#include <cmath>
#include <iomanip>
#include <sstream>

#include "core/error.hpp"

namespace ncd::toolpath {
namespace {

std::string num(double v, int decimals) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(decimals)
    << (std::abs(v) < 0.5 * std::pow(10.0, -decimals) ? 0.0 : v);
  return s.str();
}

}  // namespace

double default_safe_z_mm(const ChamferSpec& spec) {
  return spec.pipe_radius_mm + 4.0 * spec.ball_radius_mm;
}

Vec3 program_point(const ChamferSpec& spec, const CutterPose& pose, ProgramPoint point) {
  Vec3 p = pose.cl;
  if (spec.side == Side::Lower) p = Vec3(-p.x(), p.y(), -p.z());
  if (point == ProgramPoint::Tip) p.z() -= spec.ball_radius_mm;
  return p;
}

std::string chamfer_program(const ChamferPath& path, const NgcOptions& o) {
  const ChamferSpec& s = path.spec;
  require_positive("feed (--feed, mm/min)", o.feed_mm_per_min);
  require_positive("spindle speed (--spindle, rpm)", o.spindle_rpm);
  require_finite("safe Z (--safe-z, mm)", o.safe_z_mm);
  if (path.points.empty()) throw InputError("the chamfer path has no points");
  double top = -1e300, length = 0.0;
  for (std::size_t i = 0; i < path.points.size(); ++i) {
    const Vec3 p = program_point(s, path.points[i], o.point);
    const Vec3 q = program_point(s, path.points[(i + 1) % path.points.size()], o.point);
    top = std::max(top, p.z() + (o.point == ProgramPoint::Tip ? 2.0 : 1.0) * s.ball_radius_mm);
    length += (q - p).norm();
  }
  if (o.safe_z_mm <= top) {
    throw InputError("safe Z = " + num(o.safe_z_mm, 3) + " mm is not above the top of the ball " +
                     "along the loop (" + num(top, 3) + " mm); use a larger --safe-z");
  }
  const int d = o.decimals;
  const auto xyz = [d](const Vec3& p) {
    return "X" + num(p.x(), d) + " Y" + num(p.y(), d) + " Z" + num(p.z(), d);
  };
  const ChamferChecks& ck = path.checks;
  std::ostringstream g;
  g << "%\n";
  g << "(ncd chamfer: constant-width chamfer of a drilled hole in a pipe, Sato et al. 2016)\n";
  g << "(edge " << to_string(s.edge) << " " << to_string(s.side) << ", pipe surface radius "
    << num(s.pipe_radius_mm, 4) << " mm, drill radius " << num(s.drill_radius_mm, 4) << " mm)\n";
  g << "(ball radius " << num(s.ball_radius_mm, 4) << " mm, chamfer width " << num(s.width_mm, 4)
    << " mm, chordal tolerance " << num(s.tolerance_mm, 5) << " mm, " << s.initial_segments
    << " initial segments)\n";
  g << "(rod radius " << (s.rod_radius_mm ? num(*s.rod_radius_mm, 4) + " mm" : "not given")
    << ", non-knife angle "
    << (s.non_knife_angle_rad ? num(rad_to_deg(*s.non_knife_angle_rad), 3) + " deg" : "not given")
    << ", rod avoidance " << (s.avoid ? "on" : "off (alpha = 1)") << ")\n";
  g << "(frame: X0 Y0 on the drill axis, Z0 on the pipe axis, pipe along Y, units mm)\n";
  if (s.side == Side::Lower) {
    g << "(LOWER EDGE: written for the part TURNED OVER, rotated 180 deg about the pipe axis Y:"
         " X -> -X, Z -> -Z)\n";
  }
  g << "(programmed point: "
    << (o.point == ProgramPoint::Tip ? "ball TIP = centre - " + num(s.ball_radius_mm, 4) +
                                           " mm in Z; tool length set to the tip"
                                     : "ball CENTRE; tool length set to the ball centre")
    << ")\n";
  g << "(checks: local " << (ck.local_ok ? "ok" : "INTERFERES") << ", global "
    << (ck.global_ok ? "ok" : "INTERFERES") << ", rod "
    << (!ck.limit_radius_mm ? "not checked"
        : ck.rod_ok         ? "ok"
                            : "INTERFERES")
    << "; alpha adjusted at " << ck.adjusted_points << " points)\n";
  g << "(" << path.points.size() << " points, loop length " << num(length, 3) << " mm, "
    << num(60.0 * length / o.feed_mm_per_min, 2) << " s at F" << num(o.feed_mm_per_min, 1)
    << ", safe Z " << num(o.safe_z_mm, 3) << " mm)\n";
  g << "G21 G90 G94 G17 G40 G49\n";
  g << "G64 P" << num(s.tolerance_mm, 4) << "\n";
  g << "S" << num(o.spindle_rpm, 0) << " M3\n";
  g << "G0 Z" << num(o.safe_z_mm, d) << "\n";
  const Vec3 first = program_point(s, path.points.front(), o.point);
  if (s.edge == Edge::Inner) {
    g << "G0 X0 Y0\n";
    g << "G1 Z" << num(first.z(), d) << " F" << num(o.feed_mm_per_min, 1) << "\n";
    g << "G1 " << xyz(first) << "\n";
  } else {
    g << "G0 X" << num(first.x(), d) << " Y" << num(first.y(), d) << "\n";
    g << "G1 Z" << num(first.z(), d) << " F" << num(o.feed_mm_per_min, 1) << "\n";
  }
  for (std::size_t i = 1; i < path.points.size(); ++i) {
    g << "G1 " << xyz(program_point(s, path.points[i], o.point)) << "\n";
  }
  g << "G1 " << xyz(first) << " (loop closed)\n";
  if (s.edge == Edge::Inner) g << "G1 X0 Y0\n";
  g << "G0 Z" << num(o.safe_z_mm, d) << "\n";
  g << "M5\nM2\n%\n";
  return g.str();
}

}  // namespace ncd::toolpath
