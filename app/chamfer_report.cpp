// Reports of a chamfer path. Infinite 1/|k_e| (curvature normal to the cutter vector) is
// written as JSON null and as "inf" in CSV; every other number is finite by construction.
#include "app/chamfer_report.hpp"

#include <cmath>
#include <iomanip>
#include <sstream>

namespace ncd::app {
namespace {

using nlohmann::ordered_json;
using toolpath::ChamferPath;

ordered_json vec(const Vec3& v) {
  return ordered_json::array({v.x(), v.y(), v.z()});
}
ordered_json finite_or_null(double v) {
  return std::isfinite(v) ? ordered_json(v) : ordered_json();
}
template <class T>
ordered_json opt(const std::optional<T>& v) {
  return v ? ordered_json(*v) : ordered_json();
}
// θ ranges where a check fails, in degrees: [[from, to], ...].
ordered_json ranges_deg(const std::vector<toolpath::ThetaRange>& ranges) {
  ordered_json out = ordered_json::array();
  for (const auto& r : ranges) {
    out.push_back(ordered_json::array({rad_to_deg(r.from_rad), rad_to_deg(r.to_rad)}));
  }
  return out;
}

}  // namespace

ordered_json chamfer_json(const ChamferPath& path, const toolpath::NgcOptions& ngc,
                          std::optional<double> non_knife_angle_deg, double elapsed_ms) {
  const auto& s = path.spec;
  const auto& ck = path.checks;
  ordered_json in;
  in["pipe_radius_mm"] = s.pipe_radius_mm;
  in["drill_radius_mm"] = s.drill_radius_mm;
  in["ball_radius_mm"] = s.ball_radius_mm;
  in["width_mm"] = s.width_mm;
  in["tolerance_mm"] = s.tolerance_mm;
  in["edge"] = toolpath::to_string(s.edge);
  in["side"] = toolpath::to_string(s.side);
  in["rod_radius_mm"] = opt(s.rod_radius_mm);
  in["non_knife_angle_deg"] = opt(non_knife_angle_deg);
  in["avoid"] = s.avoid;
  in["initial_segments"] = s.initial_segments;
  in["drill_tilt_deg"] = rad_to_deg(s.drill_tilt_rad);
  in["drill_azimuth_deg"] = rad_to_deg(s.drill_azimuth_rad);
  in["eccentricity_mm"] = s.eccentricity_mm;
  in["pipe_half_angle_deg"] = rad_to_deg(s.pipe_half_angle_rad);
  in["pipe_thickness_mm"] = opt(s.pipe_thickness_mm);
  in["frame"] = "drill";  // points are in the drill frame, z along the drill axis
  in["feed_mm_per_min"] = ngc.feed_mm_per_min;
  in["spindle_rpm"] = ngc.spindle_rpm;
  in["program_point"] = ngc.point == toolpath::ProgramPoint::Tip ? "tip" : "centre";
  in["safe_z_mm"] = ngc.safe_z_mm;
  ordered_json pts = ordered_json::array();
  for (const auto& p : path.points) {
    ordered_json j;
    j["theta"] = p.theta_rad;
    j["xp"] = vec(p.xp);
    j["cl"] = vec(p.cl);
    j["e"] = vec(p.e);
    j["alpha"] = p.alpha;
    j["delta"] = p.delta_mm;
    j["width"] = p.width_mm;
    j["projected_width"] = p.projected_width_mm;
    j["inv_ke"] = finite_or_null(p.inv_ke_mm);
    j["minus_ez"] = p.minus_ez;
    j["cl_radius"] = p.cl_radius_mm;
    pts.push_back(std::move(j));
  }
  ordered_json out;
  out["input"] = std::move(in);
  out["segments"] = path.points.size();
  out["points"] = std::move(pts);
  ordered_json rod;
  rod["ok"] = ck.rod_ok;
  rod["applies"] = ck.rod_applies;
  rod["limit_radius"] = opt(ck.limit_radius_mm);
  rod["max_cl_radius"] = ck.max_cl_radius_mm;
  rod["adjusted_points"] = ck.adjusted_points;
  rod["fail_theta_deg"] = ranges_deg(ck.rod_fail);
  out["checks"] = {{"local",
                    {{"ok", ck.local_ok},
                     {"min_inv_ke", finite_or_null(ck.min_inv_ke_mm)},
                     {"fail_theta_deg", ranges_deg(ck.local_fail)}}},
                   {"global",
                    {{"ok", ck.global_ok},
                     {"max_minus_ez", ck.max_minus_ez},
                     {"min_minus_ez", ck.min_minus_ez},
                     {"fail_theta_deg", ranges_deg(ck.global_fail)}}},
                   {"rod", std::move(rod)}};
  out["elapsed_ms"] = elapsed_ms;
  return out;
}

std::string chamfer_csv(const ChamferPath& path) {
  std::ostringstream o;
  o << std::setprecision(17);
  o << "theta_rad,xp_x_mm,xp_y_mm,xp_z_mm,cl_x_mm,cl_y_mm,cl_z_mm,e_x,e_y,e_z,alpha,delta_mm,"
       "width_mm,projected_width_mm,inv_ke_mm,minus_ez,cl_radius_mm\n";
  for (const auto& p : path.points) {
    o << p.theta_rad << ',' << p.xp.x() << ',' << p.xp.y() << ',' << p.xp.z() << ',' << p.cl.x()
      << ',' << p.cl.y() << ',' << p.cl.z() << ',' << p.e.x() << ',' << p.e.y() << ',' << p.e.z()
      << ',' << p.alpha << ',' << p.delta_mm << ',' << p.width_mm << ',' << p.projected_width_mm
      << ',' << (std::isfinite(p.inv_ke_mm) ? std::to_string(p.inv_ke_mm) : "inf") << ','
      << p.minus_ez << ',' << p.cl_radius_mm << '\n';
  }
  return o.str();
}

std::string chamfer_summary(const ChamferPath& path, double elapsed_ms) {
  const auto& s = path.spec;
  const auto& ck = path.checks;
  double a_min = 1e300, a_max = -1e300, w_min = 1e300, w_max = -1e300, pw_min = 1e300,
         pw_max = -1e300, length = 0.0;
  for (std::size_t i = 0; i < path.points.size(); ++i) {
    const auto& p = path.points[i];
    a_min = std::min(a_min, p.alpha);
    a_max = std::max(a_max, p.alpha);
    w_min = std::min(w_min, p.width_mm);
    w_max = std::max(w_max, p.width_mm);
    pw_min = std::min(pw_min, p.projected_width_mm);
    pw_max = std::max(pw_max, p.projected_width_mm);
    length += (path.points[(i + 1) % path.points.size()].cl - p.cl).norm();
  }
  std::ostringstream o;
  o << std::fixed << std::setprecision(4);
  o << "chamfer: " << toolpath::to_string(s.edge) << " " << toolpath::to_string(s.side)
    << " edge, pipe radius " << s.pipe_radius_mm << " mm, drill radius " << s.drill_radius_mm
    << " mm, ball radius " << s.ball_radius_mm << " mm, width " << s.width_mm << " mm\n";
  if (s.drill_tilt_rad != 0.0 || s.eccentricity_mm != 0.0 || s.pipe_half_angle_rad != 0.0) {
    o << "  geometry          drill tilt " << rad_to_deg(s.drill_tilt_rad) << " deg (azimuth "
      << rad_to_deg(s.drill_azimuth_rad) << " deg), eccentricity " << s.eccentricity_mm
      << " mm, pipe half-angle " << rad_to_deg(s.pipe_half_angle_rad)
      << " deg; points in the drill frame\n";
  }
  o << "  points            " << path.points.size() << " (closed loop, tolerance " << s.tolerance_mm
    << " mm), CL loop length " << length << " mm\n";
  o << "  width |AB|        " << w_min << " .. " << w_max << " mm (top view " << pw_min << " .. "
    << pw_max << " mm)\n";
  o << "  alpha             " << a_min << " .. " << a_max << " (" << ck.adjusted_points
    << " points adjusted by Algorithm 1)\n";
  o << "  local check       " << (ck.local_ok ? "ok" : "INTERFERES") << ": min 1/|k_e| "
    << ck.min_inv_ke_mm << " mm against R_B " << s.ball_radius_mm << " mm\n";
  o << "  global check      " << (ck.global_ok ? "ok" : "INTERFERES") << ": -e_z in ["
    << ck.min_minus_ez << ", " << ck.max_minus_ez << "]\n";
  if (!ck.rod_applies) {
    o << "  rod check         not applicable (outer edge: the rod stays above the part)\n";
  } else if (!ck.limit_radius_mm) {
    o << "  rod check         not asked (give --rod-radius and/or --non-knife-angle)\n";
  } else {
    o << "  rod check         " << (ck.rod_ok ? "ok" : "INTERFERES") << ": max CL radius "
      << ck.max_cl_radius_mm << " mm against R_R " << *ck.limit_radius_mm << " mm\n";
  }
  o << "  computed in       " << std::setprecision(3) << elapsed_ms << " ms\n";
  return o.str();
}

Figure chamfer_figure(const ChamferPath& path) {
  const auto& s = path.spec;
  const auto& ck = path.checks;
  Series alpha{"alpha", {}, {}, "#1f77b4"}, inv_ke{"1/|k_e|", {}, {}, "#9467bd"},
      ez{"-e_z", {}, {}, "#8c564b"}, clr{"CL radius", {}, {}, "#ff7f0e"},
      pw{"top-view width", {}, {}, "#2ca02c"};
  for (const auto& p : path.points) {
    const double deg = rad_to_deg(p.theta_rad);
    for (Series* ser : {&alpha, &inv_ke, &ez, &clr, &pw}) ser->x.push_back(deg);
    alpha.y.push_back(p.alpha);
    inv_ke.y.push_back(p.inv_ke_mm);
    ez.y.push_back(p.minus_ez);
    clr.y.push_back(p.cl_radius_mm);
    pw.y.push_back(p.projected_width_mm);
  }
  Figure fig;
  fig.title = "Chamfer of the " + toolpath::to_string(s.edge) + " " + toolpath::to_string(s.side) +
              " edge (paper 000, Fig. 14)";
  if (s.drill_tilt_rad != 0.0 || s.eccentricity_mm != 0.0 || s.pipe_half_angle_rad != 0.0) {
    std::ostringstream g;
    g << std::setprecision(4) << ": tilt " << rad_to_deg(s.drill_tilt_rad) << " deg, eccentricity "
      << s.eccentricity_mm << " mm, cone " << rad_to_deg(s.pipe_half_angle_rad) << " deg";
    fig.title += g.str();
  }
  fig.x_label = "theta (deg)";
  fig.panels.push_back({"alpha distribution (Algorithm 1)", "alpha", {alpha}, {}, {}});
  fig.panels.push_back({"local interference check",
                        "1/|k_e| (mm)",
                        {inv_ke},
                        {{s.ball_radius_mm, "R_B (must stay below 1/|k_e|)"}},
                        {}});
  fig.panels.push_back(
      {"global interference check", "-e_z", {ez}, {{0.0, "0 (sign must not change)"}}, {}});
  Panel rod{"cutter location distance from the drill axis", "CL radius (mm)", {clr}, {}, {}};
  if (ck.limit_radius_mm) rod.lines.push_back({*ck.limit_radius_mm, "R_R (CL must stay below)"});
  fig.panels.push_back(rod);
  fig.panels.push_back({"projected (top-view) chamfer width", "width (mm)", {pw}, {}, {}});
  return fig;
}

}  // namespace ncd::app
