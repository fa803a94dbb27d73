// `ncd simulate`: the surface a ball-end mill leaves, on a Z-map (surface/, see
// docs/surface-simulation.md), against the roughness model ncd plans its feed with
// (interpolator/roughness, paper 004 eqs. 2–4).
//
//   --case fig13|fig14|fig15   the paper's surfaces (Figs. 13–15), with the paper's R_max beside
//   --case raster              a raster of passes with --alpha-deg, --ft-mm, --pick-feed-mm
//   --case fig6                the model-vs-simulation error map over α × f_t/f_p (Fig. 6)
//   --setpoints FILE           the setpoints of `ncd replay --setpoints` over --patch
//
// Writes a JSON report (stdout by default), and on request SVG pictures: the height map and the
// R_max map with colour scales, and the cross-sections through the highest peak.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "app/commands.hpp"
#include "app/heatmap_svg.hpp"
#include "app/svg_plot.hpp"
#include "core/error.hpp"
#include "core/output_file.hpp"
#include "feed/roughness.hpp"
#include "service/machine_config.hpp"
#include "surface/cutter.hpp"
#include "surface/measure.hpp"
#include "surface/raster.hpp"
#include "surface/zmap.hpp"

namespace ncd::app {
namespace {

using surface::BallEndMill;
using surface::Plane;
using surface::ZMap;

struct SimulateArgs {
  std::string case_name, setpoints, machine;
  std::vector<double> patch;  // x0 y0 x1 y1
  std::optional<double> surface_z_mm, nominal_z_mm, cell_um, stock_mm, phase_step_deg, radius_mm,
      rpm, helix_deg, pick_feed_mm, ft_mm, alpha_deg, window_x_mm, window_y_mm;
  double slope_deg = 0.0;
  std::optional<int> teeth;
  int threads = 0;
  bool zigzag = false, ccw = false, quiet = false;
  std::string report = "-", heightmap, rmax_map, profile, plot;
};

struct PaperCase {
  const char* name;
  const char* figure;
  double alpha_deg, ft_over_fp, paper_um, tolerance_um;
};

constexpr PaperCase kPaper[] = {
    {"fig13", "Fig. 13", 10.0, 1.0, 10.7, 1.0},
    {"fig14", "Fig. 14", 0.0, 1.0, 24.9, 1.5},
    {"fig15", "Fig. 15", 0.0, 0.65, 10.2, 1.0},
};

double r4(double v) {
  return std::isfinite(v) ? std::round(v * 1e4) / 1e4 : std::numeric_limits<double>::quiet_NaN();
}

nlohmann::ordered_json num_or_null(double v) {
  return std::isfinite(v) ? nlohmann::ordered_json(r4(v)) : nlohmann::ordered_json(nullptr);
}

struct Setup {
  BallEndMill tool;
  double pick_feed_mm = 0.5;
};

Setup setup_of(const SimulateArgs& a) {
  Setup s;
  if (!a.machine.empty()) {
    const service::MachineConfig m = service::load_machine_config(a.machine);
    s.tool.radius_mm = m.cutting.ball_radius_mm;
    s.tool.teeth = m.cutting.teeth;
    s.tool.spindle_rpm = m.cutting.spindle_rpm;
    s.pick_feed_mm = m.cutting.pick_feed_mm;
  }
  if (a.radius_mm) s.tool.radius_mm = *a.radius_mm;
  if (a.teeth) s.tool.teeth = *a.teeth;
  if (a.rpm) s.tool.spindle_rpm = *a.rpm;
  if (a.helix_deg) s.tool.helix_deg = *a.helix_deg;
  s.tool.clockwise = !a.ccw;
  if (a.pick_feed_mm) s.pick_feed_mm = *a.pick_feed_mm;
  surface::validate(s.tool);
  return s;
}

nlohmann::ordered_json tool_json(const BallEndMill& t) {
  nlohmann::ordered_json j;
  j["ball_radius_mm"] = t.radius_mm;
  j["teeth"] = t.teeth;
  j["spindle_rpm"] = t.spindle_rpm;
  j["helix_deg"] = t.helix_deg;
  j["rotation"] = t.clockwise ? "clockwise (M3)" : "counter-clockwise (M4)";
  j["edges"] = t.helix_deg == 0.0 ? "straight, in axial planes, meeting at the tip"
                                  : "helical, lag tan(helix)(1 - cos phi)";
  return j;
}

nlohmann::ordered_json sim_json(const surface::SimStats& st, const ZMap& map) {
  nlohmann::ordered_json j;
  j["cells"] = map.cells();
  j["cell_updates"] = st.cell_updates;
  j["time_steps"] = st.time_steps;
  j["threads"] = st.threads;
  j["tiles"] = st.tiles;
  j["seconds"] = r4(st.seconds);
  j["cells_updated_per_s"] = std::round(st.updates_per_s());
  return j;
}

nlohmann::ordered_json roughness_json(const surface::Roughness& r) {
  nlohmann::ordered_json j;
  j["areal"] = r4(r.rmax_um);
  j["along_feed"] = r4(r.along_um);
  j["across_feed"] = r4(r.across_um);
  j["peak"] = r4(r.peak_um);
  j["valley"] = r4(r.valley_um);
  j["peak_at_mm"] = {r4(r.peak_x_mm), r4(r.peak_y_mm)};
  j["uncut_cells"] = r.uncut_cells;
  return j;
}

// Residual heights (µm, normal to the reference) of the whole map, row-major.
std::vector<double> residual_um(const ZMap& map, const Plane& ref) {
  const double norm = std::sqrt(1.0 + ref.grad_x * ref.grad_x + ref.grad_y * ref.grad_y);
  std::vector<double> v(static_cast<std::size_t>(map.cells()));
  for (int j = 0; j < map.ny(); ++j) {
    for (int i = 0; i < map.nx(); ++i) {
      v[static_cast<std::size_t>(j) * static_cast<std::size_t>(map.nx()) +
        static_cast<std::size_t>(i)] =
          (map.z_mm(i, j) - ref.at_mm(map.x_mm(i), map.y_mm(j))) / norm * 1e3;
    }
  }
  return v;
}

struct Pictures {
  std::string title;
  std::vector<std::string> notes;
  double model_um = std::numeric_limits<double>::quiet_NaN();
  std::string window_reference = "the nominal surface";
};

void write_pictures(const SimulateArgs& a, const ZMap& map, const Plane& ref,
                    const surface::Roughness& r, const surface::RmaxMap& rm, const Pictures& p) {
  if (!a.heightmap.empty()) {
    HeatMap h;
    h.title = p.title + ": surface height above the nominal surface";
    h.value_label = "height (um)";
    h.notes = p.notes;
    h.nx = map.nx();
    h.ny = map.ny();
    h.values = residual_um(map, ref);
    h.x_min_mm = map.x0_mm();
    h.x_max_mm = map.x0_mm() + map.nx() * map.cell_mm();
    h.y_min_mm = map.y0_mm();
    h.y_max_mm = map.y0_mm() + map.ny() * map.cell_mm();
    h.x_label = "x (mm), the feed direction";
    write_output(a.heightmap, render_heatmap_svg(h));
  }
  if (!a.rmax_map.empty()) {
    HeatMap h;
    h.title = p.title + ": R_max per window";
    h.value_label = "R_max (um)";
    h.notes = p.notes;
    char line[200];
    std::snprintf(line, sizeof line, "windows of %.3f x %.3f mm, peak to valley from %s",
                  rm.window_x_mm, rm.window_y_mm, p.window_reference.c_str());
    h.notes.emplace_back(line);
    double lo = std::numeric_limits<double>::infinity(), hi = -lo, mlo = lo, mhi = -lo;
    for (const auto& w : rm.windows) {
      lo = std::min(lo, w.rmax_um);
      hi = std::max(hi, w.rmax_um);
      if (std::isfinite(w.model_um)) {
        mlo = std::min(mlo, w.model_um);
        mhi = std::max(mhi, w.model_um);
      }
    }
    std::snprintf(line, sizeof line, "simulated %.2f .. %.2f um; model %.2f .. %.2f um", lo, hi,
                  mlo, mhi);
    h.notes.emplace_back(line);
    h.nx = rm.nx;
    h.ny = rm.ny;
    for (const auto& w : rm.windows) h.values.push_back(w.cut ? w.rmax_um : std::nan(""));
    h.x_min_mm = map.x0_mm();
    h.x_max_mm = map.x0_mm() + rm.nx * rm.window_x_mm;
    h.y_min_mm = map.y0_mm();
    h.y_max_mm = map.y0_mm() + rm.ny * rm.window_y_mm;
    write_output(a.rmax_map, render_heatmap_svg(h));
  }
  if (!a.profile.empty()) {
    const double norm = std::sqrt(1.0 + ref.grad_x * ref.grad_x + ref.grad_y * ref.grad_y);
    const int pi =
        std::clamp(static_cast<int>((r.peak_x_mm - map.x0_mm()) / map.cell_mm()), 0, map.nx() - 1);
    const int pj =
        std::clamp(static_cast<int>((r.peak_y_mm - map.y0_mm()) / map.cell_mm()), 0, map.ny() - 1);
    Series across{"across the feed, through the highest peak", {}, {}, "#1f77b4"};
    for (int j = 0; j < map.ny(); ++j) {
      across.x.push_back(map.y_mm(j));
      across.y.push_back((map.z_mm(pi, j) - ref.at_mm(map.x_mm(pi), map.y_mm(j))) / norm * 1e3);
    }
    Series along{"along the feed, through the highest peak", {}, {}, "#ff7f0e"};
    for (int i = 0; i < map.nx(); ++i) {
      along.x.push_back(map.x_mm(i));
      along.y.push_back((map.z_mm(i, pj) - ref.at_mm(map.x_mm(i), map.y_mm(pj))) / norm * 1e3);
    }
    std::vector<RefLine> lines{{r.valley_um + r.rmax_um, "simulated R_max", "#2ca02c"}};
    if (std::isfinite(p.model_um)) lines.push_back({r.valley_um + p.model_um, "model R_max"});
    Figure f;
    f.title = p.title + ": cross-sections";
    f.x_label = "position (mm): y for the first panel, x for the second";
    char t1[96], t2[96];
    std::snprintf(t1, sizeof t1, "across the feed at x = %.4f mm", map.x_mm(pi));
    std::snprintf(t2, sizeof t2, "along the feed at y = %.4f mm", map.y_mm(pj));
    f.panels = {Panel{t1, "height (um)", {across}, lines, {}},
                Panel{t2, "height (um)", {along}, lines, {}}};
    write_output(a.profile, render_svg(f));
  }
}

surface::RasterSpec raster_spec(const SimulateArgs& a, const Setup& s, double alpha_deg,
                                double ft_mm) {
  surface::RasterSpec spec;
  spec.pick_feed_mm = s.pick_feed_mm;
  spec.feed_per_tooth_mm = ft_mm;
  spec.inclination_deg = alpha_deg;
  if (a.stock_mm) spec.stock_mm = *a.stock_mm;
  if (a.cell_um) spec.cell_mm = *a.cell_um * 1e-3;
  spec.zigzag = a.zigzag;
  if (a.phase_step_deg) spec.phase_step_deg = *a.phase_step_deg;
  return spec;
}

struct CaseResult {
  surface::Roughness rough;
  double model_um = 0.0;
  surface::SimStats stats;
};

// The raster of a --case run: the paper's inclination and f_t/f_p, or --alpha-deg and --ft-mm.
struct CaseRaster {
  const PaperCase* paper = nullptr;  // null for --case raster
  double alpha_deg = 0.0, ft_mm = 0.0;
};

CaseRaster case_raster(const SimulateArgs& a, const Setup& s) {
  CaseRaster c;
  for (const auto& p : kPaper) {
    if (a.case_name == p.name) c.paper = &p;
  }
  if (c.paper) {
    if (a.alpha_deg || a.ft_mm) {
      throw InputError(
          "--case " + a.case_name + " fixes the inclination and the feed per " +
          "tooth of the paper's figure: drop --alpha-deg/--ft-mm, or use --case raster");
    }
    c.alpha_deg = c.paper->alpha_deg;
    c.ft_mm = c.paper->ft_over_fp * s.pick_feed_mm;
  } else {
    if (!a.alpha_deg || !a.ft_mm) {
      throw InputError("--case raster needs --alpha-deg and --ft-mm (the inclination and the " +
                       std::string("feed per tooth)"));
    }
    c.alpha_deg = *a.alpha_deg;
    c.ft_mm = *a.ft_mm;
  }
  return c;
}

// The model's R_max for the raster (paper 004 eqs. 2-4), the outside branch's and the critical
// inclination between the two.
struct CaseModel {
  double model_um = 0.0, out_um = 0.0;
  std::optional<double> alpha_c;
};

CaseModel case_model(const Setup& s, const CaseRaster& c) {
  const double alpha = deg_to_rad(c.alpha_deg);
  const double r_mm = s.tool.radius_mm, fp = s.pick_feed_mm;
  CaseModel m;
  m.model_um = feed::roughness_mm(r_mm, fp, c.ft_mm, alpha) * 1e3;
  m.out_um = feed::roughness_outside_mm(r_mm, fp, c.ft_mm) * 1e3;
  m.alpha_c = feed::critical_angle_rad(r_mm, fp, c.ft_mm);
  return m;
}

nlohmann::ordered_json raster_json(const Setup& s, const CaseRaster& c,
                                   const surface::RasterSpec& spec, const surface::RasterRun& run) {
  const double fp = s.pick_feed_mm;
  return {{"pick_feed_mm", fp},
          {"feed_per_tooth_mm", c.ft_mm},
          {"ft_over_fp", r4(c.ft_mm / fp)},
          {"inclination_deg", c.alpha_deg},
          {"milling", c.alpha_deg > 0   ? "up (climbing)"
                      : c.alpha_deg < 0 ? "down"
                                        : "level"},
          {"stock_mm", spec.stock_mm},
          {"zigzag", spec.zigzag},
          {"phase_step_deg", spec.phase_step_deg},
          {"passes", run.passes},
          {"feed_mm_per_min", r4(run.feed_mm_per_min)}};
}

nlohmann::ordered_json difference_json(const surface::Roughness& r, const CaseModel& m,
                                       const PaperCase* paper) {
  nlohmann::ordered_json diff;
  diff["simulation_minus_model"] = r4(r.rmax_um - m.model_um);
  if (paper) {
    diff["simulation_minus_paper"] = r4(r.rmax_um - paper->paper_um);
    diff["model_minus_paper"] = r4(m.model_um - paper->paper_um);
    diff["within_issue_tolerance"] = std::abs(r.rmax_um - paper->paper_um) <= paper->tolerance_um;
  }
  return diff;
}

nlohmann::ordered_json window_range_json(const surface::RmaxMap& rm, double model_um) {
  double wmax = 0.0, wmin = std::numeric_limits<double>::infinity();
  for (const auto& w : rm.windows) {
    wmax = std::max(wmax, w.rmax_um);
    wmin = std::min(wmin, w.rmax_um);
  }
  return {{"window_mm", {r4(rm.window_x_mm), r4(rm.window_y_mm)}},
          {"windows", rm.windows.size()},
          {"max_um", r4(wmax)},
          {"min_um", r4(wmin)},
          {"model_um", r4(model_um)}};
}

// ", paper 10.7 um" for a paper's case; "" for a raster.
std::string paper_note(const PaperCase* paper) {
  return paper ? ", paper " + std::to_string(paper->paper_um).substr(0, 4) + " um" : "";
}

Pictures case_pictures(const SimulateArgs& a, const Setup& s, const CaseRaster& c,
                       const surface::Roughness& r, double model_um) {
  Pictures p;
  char title[160];
  std::snprintf(
      title, sizeof title, "%s%s: alpha = %g deg, f_t = %g mm, f_p = %g mm, r = %g mm, %d teeth",
      a.case_name.c_str(), c.paper ? (std::string(" (paper ") + c.paper->figure + ")").c_str() : "",
      c.alpha_deg, c.ft_mm, s.pick_feed_mm, s.tool.radius_mm, s.tool.teeth);
  p.title = title;
  char note[200];
  std::snprintf(note, sizeof note, "R_max simulated %.2f um, model %.2f um%s", r.rmax_um, model_um,
                paper_note(c.paper).c_str());
  p.notes.emplace_back(note);
  p.model_um = model_um;
  return p;
}

int run_case(const SimulateArgs& a) {
  const Setup s = setup_of(a);
  const CaseRaster c = case_raster(a, s);
  const surface::RasterSpec spec = raster_spec(a, s, c.alpha_deg, c.ft_mm);
  const surface::RasterRun run = surface::make_raster(spec, s.tool);
  ZMap map(run.grid, run.initial);
  surface::SimOptions opt;
  opt.threads = a.threads;
  const surface::SimStats st = surface::simulate(map, s.tool, run.moves, opt);
  const surface::Roughness r = surface::measure(map, run.nominal, {0, map.nx(), 0, map.ny()});
  if (r.uncut_cells > 0) {
    throw InputError("the stock of " + std::to_string(spec.stock_mm) + " mm left " +
                     std::to_string(r.uncut_cells) +
                     " cells of the patch uncut: raise --stock-mm above the expected R_max");
  }
  const CaseModel m = case_model(s, c);
  const std::vector<double> model_by_move(run.moves.size(), m.model_um);
  const double wx = a.window_x_mm.value_or(s.tool.teeth * c.ft_mm);
  const double wy = a.window_y_mm.value_or(s.pick_feed_mm);
  const surface::RmaxMap rm = surface::rmax_map(map, wx, wy, model_by_move, &run.nominal);

  nlohmann::ordered_json j;
  j["case"] = a.case_name;
  if (c.paper) {
    j["paper"] = {{"figure", c.paper->figure},
                  {"rmax_um", c.paper->paper_um},
                  {"issue_tolerance_um", c.paper->tolerance_um}};
  }
  j["tool"] = tool_json(s.tool);
  j["raster"] = raster_json(s, c, spec, run);
  j["grid"] = {{"cell_um", r4(map.cell_mm() * 1e3)},
               {"nx", map.nx()},
               {"ny", map.ny()},
               {"x_mm", {map.x0_mm(), r4(map.x0_mm() + map.nx() * map.cell_mm())}},
               {"y_mm", {map.y0_mm(), r4(map.y0_mm() + map.ny() * map.cell_mm())}}};
  j["simulation"] = sim_json(st, map);
  j["rmax_um"] = roughness_json(r);
  j["model"] = {{"rmax_um", r4(m.model_um)},
                {"branch", m.model_um > m.out_um ? "eq. 3 (dead centre)" : "eq. 2 (outside)"},
                {"critical_angle_deg",
                 m.alpha_c ? nlohmann::ordered_json(r4(rad_to_deg(*m.alpha_c))) : nullptr}};
  j["difference_um"] = difference_json(r, m, c.paper);
  j["rmax_map"] = window_range_json(rm, m.model_um);
  write_output(a.report, j.dump(2) + "\n");

  write_pictures(a, map, run.nominal, r, rm, case_pictures(a, s, c, r, m.model_um));
  if (!a.quiet) {
    std::fprintf(stderr,
                 "ncd simulate %s: R_max %.2f um (along %.2f, across %.2f), model %.2f um%s; "
                 "%lld cells, %.3g cell updates in %.2f s on %d threads (%.3g /s)\n",
                 a.case_name.c_str(), r.rmax_um, r.along_um, r.across_um, m.model_um,
                 paper_note(c.paper).c_str(), static_cast<long long>(map.cells()),
                 static_cast<double>(st.cell_updates), st.seconds, st.threads, st.updates_per_s());
  }
  return 0;
}

// One point of Fig. 6: the raster at inclination alpha and f_t = ratio f_p, simulated, against
// the model.
struct Fig6Point {
  double simulated_um = 0.0, model_um = 0.0, cell_um = 0.0, seconds = 0.0;
  std::int64_t updates = 0;
};

Fig6Point fig6_point(const SimulateArgs& a, const Setup& s, double alpha_deg, double ratio) {
  const double fp = s.pick_feed_mm;
  const double ft = ratio * fp;
  surface::RasterSpec spec = raster_spec(a, s, alpha_deg, ft);
  if (!a.cell_um) spec.cell_mm = ft / 50.0;
  const surface::RasterRun run = surface::make_raster(spec, s.tool);
  ZMap map(run.grid, run.initial);
  surface::SimOptions opt;
  opt.threads = a.threads;
  const surface::SimStats st = surface::simulate(map, s.tool, run.moves, opt);
  Fig6Point p;
  p.seconds = st.seconds;
  p.updates = st.cell_updates;
  const surface::Roughness r = surface::measure(map, run.nominal, {0, map.nx(), 0, map.ny()});
  if (r.uncut_cells > 0) {
    throw InputError("the stock left cells uncut at alpha = " + std::to_string(alpha_deg) +
                     " deg: raise --stock-mm");
  }
  p.simulated_um = r.rmax_um;
  p.model_um = feed::roughness_mm(s.tool.radius_mm, fp, ft, deg_to_rad(alpha_deg)) * 1e3;
  p.cell_um = map.cell_mm() * 1e3;
  return p;
}

// The whole sweep of Fig. 6 (α 0..30° by 2.5°, f_t/f_p 0.2..1.0 by 0.1): the error map, the
// points, the curves of four inclinations and the largest difference.
struct Fig6 {
  std::vector<double> alphas, ratios;
  nlohmann::ordered_json points = nlohmann::ordered_json::array();
  HeatMap err;
  std::vector<Series> curves;
  double worst = 0.0, worst_alpha = 0.0, worst_ratio = 0.0, seconds = 0.0;
  std::int64_t updates = 0;
};

Fig6 sweep_fig6(const SimulateArgs& a, const Setup& s) {
  Fig6 f;
  for (int k = 0; k <= 12; ++k) f.alphas.push_back(2.5 * k);
  for (int k = 2; k <= 10; ++k) f.ratios.push_back(0.1 * k);
  f.err.nx = static_cast<int>(f.ratios.size());
  f.err.ny = static_cast<int>(f.alphas.size());
  f.err.values.assign(static_cast<std::size_t>(f.err.nx * f.err.ny), 0.0);
  for (std::size_t ia = 0; ia < f.alphas.size(); ++ia) {
    Series sim{"", {}, {}, "#1f77b4"}, model{"", {}, {}, "#d62728", true};
    for (std::size_t ir = 0; ir < f.ratios.size(); ++ir) {
      const Fig6Point p = fig6_point(a, s, f.alphas[ia], f.ratios[ir]);
      f.seconds += p.seconds;
      f.updates += p.updates;
      const double d = p.simulated_um - p.model_um;
      f.err.values[ia * f.ratios.size() + ir] = d;
      if (std::abs(d) > std::abs(f.worst)) {
        f.worst = d;
        f.worst_alpha = f.alphas[ia];
        f.worst_ratio = f.ratios[ir];
      }
      f.points.push_back({{"alpha_deg", f.alphas[ia]},
                          {"ft_over_fp", r4(f.ratios[ir])},
                          {"cell_um", r4(p.cell_um)},
                          {"simulated_um", r4(p.simulated_um)},
                          {"model_um", r4(p.model_um)},
                          {"difference_um", r4(d)}});
      sim.x.push_back(f.ratios[ir]);
      sim.y.push_back(p.simulated_um);
      model.x.push_back(f.ratios[ir]);
      model.y.push_back(p.model_um);
      if (!a.quiet) {
        std::fprintf(stderr, "alpha %4.1f deg, f_t/f_p %.1f: simulated %6.2f um, model %6.2f um\n",
                     f.alphas[ia], f.ratios[ir], p.simulated_um, p.model_um);
      }
    }
    if (ia % 4 == 0) {  // 0, 10, 20, 30 degrees on the curves' plot
      char name[64];
      std::snprintf(name, sizeof name, "simulated, alpha = %g deg", f.alphas[ia]);
      sim.name = name;
      std::snprintf(name, sizeof name, "model, alpha = %g deg", f.alphas[ia]);
      model.name = name;
      static const char* colors[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd"};
      sim.color = model.color = colors[(ia / 4) % 4];
      f.curves.push_back(sim);
      f.curves.push_back(model);
    }
  }
  return f;
}

nlohmann::ordered_json fig6_json(const Setup& s, const Fig6& f) {
  nlohmann::ordered_json j;
  j["case"] = "fig6";
  j["tool"] = tool_json(s.tool);
  j["pick_feed_mm"] = s.pick_feed_mm;
  j["grid"] = {{"alpha_deg", f.alphas},
               {"ft_over_fp", {0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0}}};
  j["max_abs_difference_um"] = r4(std::abs(f.worst));
  j["at"] = {{"alpha_deg", f.worst_alpha},
             {"ft_over_fp", r4(f.worst_ratio)},
             {"difference_um", r4(f.worst)}};
  j["paper_max_error_um"] = 1.8;
  j["simulation"] = {
      {"cell_updates", f.updates},
      {"seconds", r4(f.seconds)},
      {"cells_updated_per_s",
       f.seconds > 0.0 ? std::round(static_cast<double>(f.updates) / f.seconds) : 0.0}};
  j["points"] = f.points;
  return j;
}

// --plot: the map of simulated minus model R_max.
void write_fig6_plot(const std::string& file, const Setup& s, const Fig6& f) {
  HeatMap err = f.err;
  err.title = "Fig. 6 redone: simulated minus model R_max";
  err.value_label = "difference (um)";
  char note[160];
  std::snprintf(note, sizeof note,
                "largest |difference| %.2f um at alpha = %g deg, f_t/f_p = %.1f (paper: 1.8 um); "
                "r = %g mm, f_p = %g mm, %d teeth",
                std::abs(f.worst), f.worst_alpha, f.worst_ratio, s.tool.radius_mm, s.pick_feed_mm,
                s.tool.teeth);
  err.notes = {note};
  err.x_min_mm = 0.15;
  err.x_max_mm = 1.05;
  err.y_min_mm = -1.25;
  err.y_max_mm = 31.25;
  err.x_label = "f_t / f_p";
  err.y_label = "alpha (deg)";
  write_output(file, render_heatmap_svg(err));
}

int run_fig6(const SimulateArgs& a) {
  const Setup s = setup_of(a);
  const Fig6 f = sweep_fig6(a, s);
  write_output(a.report, fig6_json(s, f).dump(2) + "\n");
  if (!a.plot.empty()) write_fig6_plot(a.plot, s, f);
  if (!a.profile.empty()) {
    Figure fig;
    fig.title = "Fig. 6 redone: R_max against f_t/f_p, simulated (solid) and model (dashed)";
    fig.x_label = "f_t / f_p";
    fig.panels = {Panel{"R_max", "R_max (um)", f.curves, {}, {}}};
    fig.panel_height_px = 420;
    write_output(a.profile, render_svg(fig));
  }
  if (!a.quiet) {
    std::fprintf(stderr,
                 "ncd simulate fig6: largest |simulated - model| %.2f um at alpha = %g deg, "
                 "f_t/f_p = %.1f (paper: 1.8 um)\n",
                 std::abs(f.worst), f.worst_alpha, f.worst_ratio);
  }
  return 0;
}

// The setpoints of --setpoints as moves of the tool, after the flags that go with them.
std::vector<surface::Move> read_moves(const SimulateArgs& a, const Setup& s) {
  if (a.patch.size() != 4) {
    throw InputError(
        "--setpoints needs --patch X0 Y0 X1 Y1 (mm): the part of the work to simulate");
  }
  if (!a.surface_z_mm) {
    throw InputError(
        "--setpoints needs --surface-z Z (mm): the height of the initial surface at "
        "x = 0, y = 0 (a plane, sloped by --slope-deg along x)");
  }
  std::ifstream in(a.setpoints);
  if (!in) throw InputError("cannot open --setpoints " + a.setpoints + ": check the path");
  std::vector<surface::Move> moves = surface::read_setpoints_csv(in, a.setpoints, s.tool);
  if (!(std::abs(a.slope_deg) < 60.0)) {
    throw InputError("--slope-deg " + std::to_string(a.slope_deg) + " is outside (-60, 60)");
  }
  return moves;
}

// The model for each move: its feed per tooth and inclination. The default cell follows the
// feed per tooth that most of the path's length was cut at (the median over length), not the
// slow setpoints of corners and starts.
struct MoveModels {
  std::vector<double> model_um;  // per move
  double ft_median = 0.0;        // mm, over length
};

MoveModels move_models(const SimulateArgs& a, const Setup& s,
                       const std::vector<surface::Move>& moves) {
  MoveModels out;
  out.model_um.resize(moves.size());
  std::vector<std::pair<double, double>> ft_len;  // (f_t, length)
  const double zn = s.tool.teeth * s.tool.spindle_rpm;
  double total_len = 0.0;
  for (std::size_t k = 0; k < moves.size(); ++k) {
    const auto& m = moves[k];
    const Vec3 d = m.to_mm - m.from_mm;
    const double dt = m.t1_s - m.t0_s;
    const double ft = dt > 0.0 ? d.norm() / dt * 60.0 / zn : 0.0;
    if (ft > 0.0) {
      ft_len.emplace_back(ft, d.norm());
      total_len += d.norm();
    }
    out.model_um[k] =
        feed::roughness_mm(s.tool.radius_mm, s.pick_feed_mm, ft,
                           d.norm() > 0.0 ? feed::inclination_from_tangent_rad(d) : 0.0) *
        1e3;
  }
  if (ft_len.empty()) throw InputError(a.setpoints + ": the tool never moves");
  std::sort(ft_len.begin(), ft_len.end());
  double run_len = 0.0;
  out.ft_median = ft_len.back().first;
  for (const auto& [ft, len] : ft_len) {
    run_len += len;
    if (run_len >= 0.5 * total_len) {
      out.ft_median = ft;
      break;
    }
  }
  return out;
}

// Refuses a patch the tool never cut; says how much of it was not cut.
void check_cut(const SimulateArgs& a, const ZMap& map) {
  std::int64_t uncut = 0;
  for (int j = 0; j < map.ny(); ++j) {
    for (int i = 0; i < map.nx(); ++i) uncut += map.cut_by(i, j) < 0;
  }
  if (uncut == map.cells()) {
    throw InputError("the tool never cuts below --surface-z " + std::to_string(*a.surface_z_mm) +
                     " mm inside --patch: put the patch where the setpoints pass and the surface "
                     "above the tool tip there");
  }
  if (uncut > 0 && !a.quiet) {
    std::fprintf(stderr,
                 "ncd simulate: %lld of %lld cells of the patch are not cut; the R_max "
                 "map counts only windows cut wholly\n",
                 static_cast<long long>(uncut), static_cast<long long>(map.cells()));
  }
}

// The windows cut wholly: the worst one's R_max and the model there, the model's largest.
struct WindowSummary {
  double worst = 0.0, worst_model = std::nan(""), model_max = 0.0;
  std::size_t cut_windows = 0;
};

WindowSummary summarise_windows(const surface::RmaxMap& rm) {
  WindowSummary w;
  for (const auto& win : rm.windows) {
    if (!win.cut) continue;
    ++w.cut_windows;
    if (win.rmax_um > w.worst) {
      w.worst = win.rmax_um;
      w.worst_model = win.model_um;
    }
    if (std::isfinite(win.model_um)) w.model_max = std::max(w.model_max, win.model_um);
  }
  return w;
}

int run_setpoints(const SimulateArgs& a) {
  const Setup s = setup_of(a);
  const std::vector<surface::Move> moves = read_moves(a, s);
  const MoveModels models = move_models(a, s, moves);
  const double ft_median = models.ft_median;
  surface::GridSpec g{a.patch[0], a.patch[2], a.patch[1], a.patch[3],
                      a.cell_um ? *a.cell_um * 1e-3 : ft_median / 100.0};
  surface::InitialSurface init;
  init.z0_mm = *a.surface_z_mm;
  init.grad_x = std::tan(deg_to_rad(a.slope_deg));
  ZMap map(g, init);
  surface::SimOptions opt;
  opt.threads = a.threads;
  const surface::SimStats st = surface::simulate(map, s.tool, moves, opt);
  const surface::CellRegion all{0, map.nx(), 0, map.ny()};
  check_cut(a, map);
  const Plane ref =
      a.nominal_z_mm ? Plane{*a.nominal_z_mm, init.grad_x, 0.0} : surface::fit_plane(map, all);
  const surface::Roughness r = surface::measure(map, ref, all);
  const double w = std::max(s.pick_feed_mm, s.tool.teeth * ft_median);
  const surface::RmaxMap rm =
      surface::rmax_map(map, a.window_x_mm.value_or(w), a.window_y_mm.value_or(w), models.model_um,
                        a.nominal_z_mm ? &ref : nullptr);
  const WindowSummary ws = summarise_windows(rm);
  nlohmann::ordered_json j;
  j["setpoints"] = a.setpoints;
  j["moves"] = moves.size();
  j["tool"] = tool_json(s.tool);
  j["pick_feed_mm"] = s.pick_feed_mm;
  j["feed_per_tooth_median_by_length_mm"] = r4(ft_median);
  j["grid"] = {{"cell_um", r4(map.cell_mm() * 1e3)}, {"nx", map.nx()}, {"ny", map.ny()}};
  j["simulation"] = sim_json(st, map);
  j["rmax_um"] = roughness_json(r);
  j["rmax_um"]["reference"] = a.nominal_z_mm ? "the plane of --nominal-z and --slope-deg"
                                             : "least-squares plane of the patch";
  j["rmax_map"] = {{"window_mm", {r4(rm.window_x_mm), r4(rm.window_y_mm)}},
                   {"windows", rm.windows.size()},
                   {"windows_wholly_cut", ws.cut_windows},
                   {"max_um", r4(ws.worst)},
                   {"model_at_max_um", num_or_null(ws.worst_model)},
                   {"model_max_um", r4(ws.model_max)}};
  write_output(a.report, j.dump(2) + "\n");
  Pictures p;
  p.title = "ncd simulate " + a.setpoints;
  char note[160];
  std::snprintf(note, sizeof note,
                "%zu moves, f_t median %.4f mm, f_p %.3g mm; worst window R_max %.2f um",
                moves.size(), ft_median, s.pick_feed_mm, ws.worst);
  p.notes.emplace_back(note);
  if (!a.nominal_z_mm) p.window_reference = "each window's best plane";
  write_pictures(a, map, ref, r, rm, p);
  if (!a.quiet) {
    std::fprintf(stderr,
                 "ncd simulate: %zu moves over %lld cells, %.3g cell updates in %.2f s on "
                 "%d threads (%.3g /s); worst window R_max %.2f um\n",
                 moves.size(), static_cast<long long>(map.cells()),
                 static_cast<double>(st.cell_updates), st.seconds, st.threads, st.updates_per_s(),
                 ws.worst);
  }
  return 0;
}

int run_simulate(const SimulateArgs& a) {
  if (a.case_name.empty() == a.setpoints.empty()) {
    throw InputError("give either --case fig13|fig14|fig15|fig6|raster or --setpoints FILE");
  }
  if (a.cell_um) require_positive("--cell-um", *a.cell_um);
  if (a.threads < 0) throw InputError("--threads " + std::to_string(a.threads) + " is negative");
  if (!a.setpoints.empty()) return run_setpoints(a);
  if (a.case_name == "fig6") return run_fig6(a);
  return run_case(a);
}

}  // namespace

void register_simulate(CLI::App& app, Runner& run) {
  auto a = std::make_shared<SimulateArgs>();
  CLI::App* c = app.add_subcommand(
      "simulate",
      "Simulate the surface a ball-end mill leaves on a Z-map (rotating edges, min-z) and compare "
      "its R_max with the roughness model of paper 004; see docs/surface-simulation.md.");
  c->add_option("--case", a->case_name,
                "fig13 | fig14 | fig15 (the paper's surfaces), fig6 (the error map), raster")
      ->check(CLI::IsMember({"fig13", "fig14", "fig15", "fig6", "raster"}));
  c->add_option("--setpoints", a->setpoints,
                "CSV of `ncd replay --setpoints` (tool tip positions)");
  c->add_option("--patch", a->patch, "with --setpoints: X0 Y0 X1 Y1 of the patch, mm")->expected(4);
  c->add_option("--surface-z", a->surface_z_mm, "with --setpoints: initial surface height, mm");
  c->add_option(
      "--nominal-z", a->nominal_z_mm,
      "with --setpoints: height at x = 0, y = 0 of the surface meant to be left (parallel "
      "to the initial one); R_max is measured from it (default: the patch's best plane)");
  c->add_option("--slope-deg", a->slope_deg, "with --setpoints: initial surface slope along x");
  c->add_option("--machine", a->machine,
                "machine file: [cutting] radius, teeth, spindle, pick feed");
  c->add_option("--radius-mm", a->radius_mm, "ball radius r (default 5 or the machine file's)");
  c->add_option("--teeth", a->teeth, "cutting edges z (default 2)");
  c->add_option("--rpm", a->rpm, "spindle speed N (default 10000)");
  c->add_option("--helix-deg", a->helix_deg, "edge lead angle; 0: straight edges (default)");
  c->add_flag("--ccw", a->ccw, "spindle counter-clockwise (M4); default clockwise (M3)");
  c->add_option("--pick-feed-mm", a->pick_feed_mm, "pick feed f_p (default 0.5)");
  c->add_option("--ft-mm", a->ft_mm, "--case raster: feed per tooth f_t");
  c->add_option("--alpha-deg", a->alpha_deg,
                "--case raster: inclination; > 0 climbs along the feed (up-milling)");
  c->add_option("--cell-um", a->cell_um, "Z-map cell (default f_t/100; fig6: f_t/50)");
  c->add_option("--stock-mm", a->stock_mm, "material above the final surface (default 0.05)");
  c->add_option("--phase-step-deg", a->phase_step_deg,
                "spindle angle added at the start of each pass (default 0: passes in phase)");
  c->add_flag("--zigzag", a->zigzag, "alternate the pass direction");
  c->add_option("--threads", a->threads, "threads (default 0: every core)");
  c->add_option("--window-x-mm", a->window_x_mm, "R_max map window along x");
  c->add_option("--window-y-mm", a->window_y_mm, "R_max map window along y");
  c->add_option("--report", a->report, "JSON report (default: standard output)");
  c->add_option("--heightmap", a->heightmap, "SVG height map with a colour scale");
  c->add_option("--rmax-map", a->rmax_map, "SVG map of R_max per window");
  c->add_option("--profile", a->profile,
                "SVG cross-sections through the highest peak (fig6: R_max curves)");
  c->add_option("--plot", a->plot, "--case fig6: SVG map of simulated minus model R_max");
  c->add_flag("-q,--quiet", a->quiet, "no summary on standard error");
  c->callback([a, &run] { run = [a] { return run_simulate(*a); }; });
}

}  // namespace ncd::app
