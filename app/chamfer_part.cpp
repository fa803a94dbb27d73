// `ncd chamfer --part FILE` (docs/part.md): reads the part file and the machine file, plans the
// part (cam/part.hpp: every hole computed and checked alone, placed at its index, ordered), and
// writes the program (or the JSON report) and the unrolled plot; nothing is written when a hole
// is refused.
#include "app/chamfer_part.hpp"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <optional>
#include <sstream>

#include "core/error.hpp"
#include "core/number_text.hpp"
#include "core/output_file.hpp"
#include "service/machine_config.hpp"
#include "service/part_job.hpp"

namespace ncd::app {

namespace {

// The machine file and --program-point as the planner's machine (service/part_job.hpp).
struct LoadedMachine {
  std::optional<service::MachineConfig> config;
  service::PartMachine part_machine(const PartArgs& a) const {
    service::PartMachine m;
    if (config) m.machine = &*config;
    m.name = a.machine;
    if (a.point) {
      m.point = *a.point == "centre" ? toolpath::ProgramPoint::Centre : toolpath::ProgramPoint::Tip;
      m.point_text = *a.point;
    }
    return m;
  }
};

}  // namespace

int run_chamfer_part(const PartArgs& a) {
  if (a.format != "ngc" && a.format != "json") {
    throw InputError("--format " + a.format +
                     " is not one of a part's formats; use ngc (the program) or json (the report)");
  }
  const toolpath::Part file_part = toolpath::load_part(a.part);
  LoadedMachine loaded;
  if (!a.machine.empty()) loaded.config = service::load_machine_config(a.machine);
  const service::PartMachine machine = loaded.part_machine(a);
  const toolpath::Part part = service::with_machine_axis(file_part, machine);
  const toolpath::NgcOptions options = service::part_writer_options(machine, part);
  const toolpath::AirModel air = service::part_air_model(machine, part);
  check_output(a.output, "-o");
  check_output(a.plot, "--plot");
  const auto t0 = std::chrono::steady_clock::now();
  const toolpath::PartProgram program = toolpath::plan_part(part, air, options);
  const double elapsed_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  const std::string text = a.format == "json" ? part_json(program, elapsed_ms).dump(1) + "\n"
                                              : toolpath::part_program_text(program);
  if (!a.plot.empty()) write_output(a.plot, part_svg(program), "--plot");
  write_output(a.output, text);
  if (!a.quiet) {
    std::cerr << part_summary(program, elapsed_ms);
    if (!a.output.empty() && a.output != "-")
      std::cerr << "  wrote             " << a.output << "\n";
    if (!a.plot.empty()) std::cerr << "  wrote             " << a.plot << "\n";
  }
  return 0;
}

nlohmann::ordered_json part_json(const toolpath::PartProgram& p, double elapsed_ms) {
  nlohmann::ordered_json j;
  j["part"] = p.part.source;
  j["rotary_axis"] = toolpath::to_string(p.part.rotary.axis);
  j["clearance_z_mm"] = p.clearance_z_mm;
  j["air_time_ordered_s"] = p.air_ordered_s;
  j["air_time_file_order_s"] = p.air_file_order_s;
  j["cut_length_mm"] = p.cut_length_mm;
  nlohmann::ordered_json order = nlohmann::ordered_json::array();
  for (const std::size_t i : p.order) order.push_back(i + 1);
  j["order"] = order;
  nlohmann::ordered_json holes = nlohmann::ordered_json::array();
  for (const toolpath::HoleCut& h : p.cuts) {
    nlohmann::ordered_json o;
    o["hole"] = h.hole + 1;
    o["name"] = p.part.holes[h.hole].name;
    o["index_deg"] = h.a_deg;
    o["perpendicular"] = h.setup.perpendicular;
    o["tilt_left_deg"] = rad_to_deg(h.setup.tilt_left_rad);
    o["edge"] = toolpath::to_string(h.setup.spec.edge);
    o["side"] = toolpath::to_string(h.setup.spec.side);
    o["points"] = h.points.size();
    o["checks"] = {
        {"local", h.path.checks.local_ok},
        {"global", h.path.checks.global_ok},
        {"rod", h.path.checks.limit_radius_mm ? nlohmann::ordered_json(h.path.checks.rod_ok)
                                              : nlohmann::ordered_json(nullptr)},
        {"alpha_adjusted_points", h.path.checks.adjusted_points}};
    o["entry_mm"] = {h.over.x(), h.over.y(), h.over.z()};
    holes.push_back(o);
  }
  j["holes"] = holes;
  j["elapsed_ms"] = elapsed_ms;
  return j;
}

std::string part_summary(const toolpath::PartProgram& p, double elapsed_ms) {
  std::ostringstream s;
  std::size_t points = 0;
  for (const toolpath::HoleCut& h : p.cuts) points += h.points.size();
  s << "ncd chamfer --part " << p.part.source << "\n";
  s << "  holes             " << p.cuts.size() << " on " << toolpath::to_string(p.part.rotary.axis)
    << ", " << points << " points, cut length " << text::fixed(p.cut_length_mm, 1) << " mm\n";
  s << "  order            ";
  for (const toolpath::HoleCut& h : p.cuts) s << " " << h.hole + 1;
  s << "\n";
  s << "  air time          " << text::fixed(p.air_ordered_s, 2) << " s ordered, "
    << text::fixed(p.air_file_order_s, 2) << " s in the file's order (index and rapids between "
    << "holes, trapezoids)\n";
  s << "  clearance         Z " << text::fixed(p.clearance_z_mm, 3) << " mm at every index\n";
  s << "  computed in       " << text::fixed(elapsed_ms, 1) << " ms\n";
  return s.str();
}

std::string part_svg(const toolpath::PartProgram& p) {
  const double length = p.part.pipe.length_mm;
  const double w = 900.0, h = 480.0, left = 60.0, right = 20.0, top = 40.0, bottom = 50.0;
  const auto sx = [&](double station) { return left + (w - left - right) * station / length; };
  const auto sy = [&](double deg) { return h - bottom - (h - top - bottom) * deg / 360.0; };
  const auto num = [](double v) { return text::fixed(v, 2); };
  std::ostringstream g;
  g << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << w << "\" height=\"" << h
    << "\" font-family=\"sans-serif\" font-size=\"12\">\n";
  g << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  g << "<text x=\"" << left << "\" y=\"20\" font-size=\"14\">"
    << std::filesystem::path(p.part.source).filename().string()
    << ": the pipe unrolled, holes numbered in cutting order; air "
    << text::fixed(p.air_ordered_s, 2) << " s (file order " << text::fixed(p.air_file_order_s, 2)
    << " s)</text>\n";
  g << "<rect x=\"" << num(sx(0)) << "\" y=\"" << num(sy(360)) << "\" width=\""
    << num(sx(length) - sx(0)) << "\" height=\"" << num(sy(0) - sy(360))
    << "\" fill=\"#f4f4f4\" stroke=\"#888\"/>\n";
  for (int deg = 0; deg <= 360; deg += 60) {
    g << "<text x=\"" << num(left - 8) << "\" y=\"" << num(sy(deg) + 4) << "\" text-anchor=\"end\">"
      << deg << "°</text>\n";
  }
  for (int k = 0; k <= 4; ++k) {
    const double st = length * k / 4.0;
    g << "<text x=\"" << num(sx(st)) << "\" y=\"" << num(h - bottom + 16)
      << "\" text-anchor=\"middle\">" << text::sig(st, 4) << "</text>\n";
  }
  g << "<text x=\"" << num(0.5 * (left + w - right)) << "\" y=\"" << num(h - 10)
    << "\" text-anchor=\"middle\">station along the pipe, mm (angle around: the index that "
       "brings the point up)</text>\n";
  std::vector<std::pair<double, double>> centres;
  for (const toolpath::HoleCut& c : p.cuts) {
    const toolpath::DrillPlacement place = toolpath::drill_placement(c.setup.spec);
    const double centre_deg = std::fmod(rad_to_deg(p.part.holes[c.hole].angle_rad) + 720.0, 360.0);
    std::string pts;
    double ms = 0.0, md = 0.0;
    for (const toolpath::CutterPose& pose : c.path.points) {
      const Vec3 q = c.setup.pipe_to_part(place.to_pipe(pose.xp));
      double deg = rad_to_deg(std::atan2(q.y(), q.z()));
      deg = centre_deg + std::remainder(deg - centre_deg, 360.0);
      pts += num(sx(q.x())) + "," + num(sy(deg)) + " ";
      ms += q.x();
      md += deg;
    }
    const double n = static_cast<double>(c.path.points.size());
    centres.emplace_back(ms / n, md / n);
    const bool inner = c.setup.spec.edge == toolpath::Edge::Inner;
    g << "<polygon points=\"" << pts << "\" fill=\"none\" stroke=\""
      << (inner ? "#1f77b4" : "#d62728") << "\" stroke-width=\"1.5\"/>\n";
  }
  std::string path;
  for (const auto& [st, deg] : centres) path += num(sx(st)) + "," + num(sy(deg)) + " ";
  g << "<polyline points=\"" << path
    << "\" fill=\"none\" stroke=\"#2ca02c\" stroke-dasharray=\"6,4\" stroke-width=\"1.5\"/>\n";
  for (std::size_t k = 0; k < centres.size(); ++k) {
    g << "<text x=\"" << num(sx(centres[k].first) + 10) << "\" y=\""
      << num(sy(centres[k].second) - 10) << "\" font-weight=\"bold\">" << k + 1 << " (hole "
      << p.cuts[k].hole + 1 << ")</text>\n";
  }
  g << "<text x=\"" << left << "\" y=\"" << num(top - 4)
    << "\" fill=\"#555\">red: outer edge, blue: inner edge, green dashes: the order</text>\n";
  g << "</svg>\n";
  return g.str();
}

}  // namespace ncd::app
