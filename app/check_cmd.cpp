// `ncd check FILE`: reads an RS-274/NGC program with the interpreter (docs/ngc-interpreter.md)
// and prints what a person checks before running it: the canonical program (one move or event
// a line, each with its source file:line, in the program's units) and a summary in mm: extents
// per axis (machine coordinates, arcs and NURBS sampled), cut and rapid lengths, an estimate of
// the time (each move at its feed, capped at the machine's maximum feed; rapids at the
// machine's maximum feed; dwells; each index of the rotary axis the double S the planner turns it
// by, motion/rotary_index.hpp, under the machine file's [axis.a] or [axis.b]), the tools,
// spindle speeds and feeds. --json for tools.
// Rapids made before X, Y and Z are all known (the machine comes from wherever it stands)
// count with their end point only.
// --save-parameters writes the parameter file back after a program read whole, as LinuxCNC's
// interpreter does at its exit (docs/ngc-interpreter.md, "Persistent parameters"): checked
// writable before reading, written to a temporary file renamed over it (core/output_file.hpp), so a
// refused program or a failed write leaves the old file as it was.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "app/commands.hpp"
#include "core/error.hpp"
#include "core/number_text.hpp"
#include "core/output_file.hpp"
#include "gcode/ngc/interpreter.hpp"
#include "gcode/program.hpp"
#include "motion/rotary_index.hpp"
#include "service/machine_config.hpp"

namespace ncd::app {
namespace {

using toolpath::Motion;
using toolpath::Program;

struct CheckArgs {
  std::string file, machine, tool_table, parameter_file, start;
  bool json = false;
  bool summary_only = false;
  bool save_parameters = false;
  bool quiet = false;
};

// With --machine: where the values the reading and the estimate use came from, to stderr (a
// line per origin, then each flag that overrode the file's value): the flag, the machine file,
// or the default.
void print_sources(const CheckArgs& a, const service::MachineConfig& m,
                   const toolpath::InterpretOptions& o) {
  std::vector<std::string> file, flags, defaults, overrides;
  const auto one = [&](const std::string& key, const std::string& value, const std::string& flag,
                       const std::string& flag_text, const std::string& file_value) {
    if (!flag_text.empty()) {
      flags.push_back(key + " " + value + " (" + flag + ")");
      if (m.has(key) && file_value != value) {
        overrides.push_back(flag + " " + flag_text + " overrides " + key + " = " + file_value +
                            " of " + m.source);
      }
    } else {
      (m.has(key) ? file : defaults).push_back(key + " " + value);
    }
  };
  const auto position = [](const std::optional<Vec3>& at) {
    return at ? "[" + text::sig(at->x()) + ", " + text::sig(at->y()) + ", " + text::sig(at->z()) +
                    "]"
              : std::string("unknown");
  };
  const auto none = [](const std::string& s) { return s.empty() ? std::string("none") : s; };
  one("max_feed_mm_per_min", text::sig(m.limits.max_feed_mm_per_min) + " (feed cap, rapid rate)",
      "", "", "");
  one("program.start_mm", position(o.start_machine_mm), "--start", a.start,
      position(m.program.start_machine_mm));
  one("program.tool_table", none(o.tool_table), "--tool-table", a.tool_table,
      none(m.program.tool_table));
  one("program.parameter_file", none(o.parameter_file), "--parameter-file", a.parameter_file,
      none(m.program.parameter_file));
  one("program.default_units", o.default_units == toolpath::Units::inch ? "inch" : "mm", "", "",
      "");
  const auto join = [](const std::vector<std::string>& v) {
    std::string s;
    for (const std::string& x : v) s += (s.empty() ? "" : ", ") + x;
    return s;
  };
  if (!file.empty())
    std::cerr << "ncd check: " << join(file) << " (machine file " << m.source << ")\n";
  if (!flags.empty()) std::cerr << "ncd check: " << join(flags) << "\n";
  if (!defaults.empty()) {
    std::cerr << "ncd check: " << join(defaults) << " (default: not in " << m.source
              << " nor given as a flag)\n";
  }
  for (const std::string& line : overrides) std::cerr << "ncd check: " << line << "\n";
}

struct Summary {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 hi = Vec3::Constant(-std::numeric_limits<double>::infinity());
  double cut_mm = 0.0, rapid_mm = 0.0, time_s = 0.0, dwell_s = 0.0;
  std::size_t moves = 0, events = 0;
  std::size_t indexes = 0;  // rotary index moves (a turn of A or B alone)
  double index_deg = 0.0, index_s = 0.0;
  std::set<int> tools;
  std::set<double> spindle_rpm;
  double feed_min = std::numeric_limits<double>::infinity(), feed_max = 0.0;
  bool capped = false;  // some feed was above the machine's maximum
};

// Points along a motion in machine mm, for the extents.
void sample(const Motion& m, Summary& s) {
  const double k = toolpath::mm_per_unit(m.units);
  const auto add = [&](const Vec3& p_prog) {
    const Vec3 p = (p_prog + m.offset) * k;
    s.lo = s.lo.cwiseMin(p);
    s.hi = s.hi.cwiseMax(p);
  };
  if (m.start_known) add(m.start);  // else the machine comes from wherever it stands
  if (const auto* arc = std::get_if<toolpath::ArcMove>(&m.geometry)) {
    const toolpath::ArcGeometry g = toolpath::arc_geometry(m.start, *arc);
    const toolpath::PlaneAxes ax = toolpath::plane_axes(arc->plane);
    const double a0 = std::atan2(m.start[ax.second] - arc->centre[ax.second],
                                 m.start[ax.first] - arc->centre[ax.first]);
    // The extremes of a circle are where the angle is a multiple of 90°: those inside the
    // sweep, plus the ends (the axis coordinate moves linearly, its extremes are the ends).
    const double lo = std::min(a0, a0 + g.sweep_rad), hi = std::max(a0, a0 + g.sweep_rad);
    for (double q = std::ceil(lo / (kPi / 2)); q * (kPi / 2) <= hi; q += 1.0) {
      const double ang = q * (kPi / 2);
      const double f = (ang - a0) / g.sweep_rad;
      const long quarter = static_cast<long>(q) % 4;
      const long qm = quarter < 0 ? quarter + 4 : quarter;
      Vec3 p;
      p[ax.first] = arc->centre[ax.first] + g.radius * (qm == 0 ? 1.0 : qm == 2 ? -1.0 : 0.0);
      p[ax.second] = arc->centre[ax.second] + g.radius * (qm == 1 ? 1.0 : qm == 3 ? -1.0 : 0.0);
      p[ax.axis] = m.start[ax.axis] + g.rise * f;
      add(p);
    }
  } else if (const auto* nm = std::get_if<toolpath::NurbsMove>(&m.geometry)) {
    const auto& c = nm->curve;
    for (int i = 0; i <= 256; ++i)
      add(c.eval(c.u_begin() + (c.u_end() - c.u_begin()) * i / 256.0).p);
  } else if (const auto* pl = std::get_if<toolpath::PolylineMove>(&m.geometry)) {
    for (const Vec3& p : pl->polyline.points) add(p);
  }
  add(toolpath::motion_end(m));
}

Summary summarise(const Program& p, const service::MachineConfig& machine) {
  Summary s;
  const double rapid_mm_per_min = machine.limits.max_feed_mm_per_min;
  for (const toolpath::Step& st : p.steps) {
    if (const auto* m = std::get_if<Motion>(&st.item)) {
      ++s.moves;
      sample(*m, s);
      const double k = toolpath::mm_per_unit(m->units);
      const double len = toolpath::motion_length(*m) * k;
      if (m->rapid && !m->start_known) {
        // Positions the machine from an unknown place: no length, no time.
      } else if (m->rapid) {
        s.rapid_mm += len;
        s.time_s += len / rapid_mm_per_min * 60.0;
      } else {
        s.cut_mm += len;
        double feed = m->feed_mode == toolpath::FeedMode::per_minute ? m->feed * k : m->feed * len;
        s.feed_min = std::min(s.feed_min, feed);
        s.feed_max = std::max(s.feed_max, feed);
        if (feed > machine.limits.max_feed_mm_per_min) {
          s.capped = true;
          feed = machine.limits.max_feed_mm_per_min;
        }
        if (feed > 0.0) s.time_s += len / feed * 60.0;
      }
      if (m->tool != 0) s.tools.insert(m->tool);
      if (m->spindle != toolpath::SpindleDir::off) s.spindle_rpm.insert(m->spindle_rpm);
      continue;
    }
    ++s.events;
    const auto& e = std::get<toolpath::Event>(st.item);
    if (const auto* d = std::get_if<toolpath::DwellEvent>(&e)) {
      s.dwell_s += d->seconds;
      s.time_s += d->seconds;
    }
    if (const auto* t = std::get_if<toolpath::ToolChangeEvent>(&e)) s.tools.insert(t->tool);
    if (const auto* r = std::get_if<toolpath::RotaryIndexMove>(&e)) {
      if (r->from_deg == r->to_deg) continue;
      // As the planner turns it (motion/job.cpp): rest to rest, a G1's feed capping the speed.
      const std::optional<double> feed = !r->rapid && r->feed_deg_per_min > 0.0
                                             ? std::optional<double>(r->feed_deg_per_min)
                                             : std::nullopt;
      const motion::IndexLimits il = motion::index_limits(machine.limits.rotary, feed);
      const double t = motion::IndexProfile(r->from_deg, r->to_deg, il).duration_s();
      ++s.indexes;
      s.index_deg += std::abs(r->to_deg - r->from_deg);
      s.index_s += t;
      s.time_s += t;
    }
  }
  return s;
}

int run_check(const CheckArgs& a) {
  service::MachineConfig machine;
  if (!a.machine.empty()) machine = service::load_machine_config(a.machine);
  toolpath::InterpretOptions opt = machine.program;
  if (!a.tool_table.empty()) opt.tool_table = a.tool_table;
  if (!a.start.empty()) opt.start_machine_mm = service::parse_position_mm(a.start, "--start");
  if (!a.parameter_file.empty()) opt.parameter_file = a.parameter_file;
  if (!a.machine.empty() && !a.quiet) print_sources(a, machine, opt);
  if (a.save_parameters) {
    if (opt.parameter_file.empty()) {
      throw InputError(
          "--save-parameters needs a parameter file; give --parameter-file FILE or "
          "parameter_file in the machine file's [program] table");
    }
    check_output(opt.parameter_file, "parameter file");
  }
  const Program p = toolpath::interpret_ngc_file(a.file, opt);
  if (a.save_parameters) write_output(opt.parameter_file, p.parameter_file_text, "parameter file");
  const Summary s = summarise(p, machine);
  const bool any = s.moves > 0;
  if (a.json) {
    std::ostringstream canonical;
    if (!a.summary_only) toolpath::write_canonical(canonical, p);
    nlohmann::ordered_json j;
    j["program"] = a.file;
    j["files"] = p.files;
    nlohmann::ordered_json lines = nlohmann::ordered_json::array();
    std::istringstream in(canonical.str());
    for (std::string line; std::getline(in, line);) lines.push_back(line);
    j["canonical"] = lines;
    nlohmann::ordered_json sum;
    sum["moves"] = s.moves;
    sum["events"] = s.events;
    if (any) {
      sum["extents_mm"] = {
          {"x", {s.lo.x(), s.hi.x()}}, {"y", {s.lo.y(), s.hi.y()}}, {"z", {s.lo.z(), s.hi.z()}}};
    }
    sum["cut_length_mm"] = s.cut_mm;
    sum["rapid_length_mm"] = s.rapid_mm;
    sum["dwell_s"] = s.dwell_s;
    sum["index_moves"] = s.indexes;
    sum["index_deg"] = s.index_deg;
    sum["index_time_s"] = s.index_s;
    sum["estimated_time_s"] = s.time_s;
    sum["rapid_rate_mm_per_min"] = machine.limits.max_feed_mm_per_min;
    sum["feed_capped_at_machine_maximum"] = s.capped;
    sum["tools"] = std::vector<int>(s.tools.begin(), s.tools.end());
    sum["spindle_rpm"] = std::vector<double>(s.spindle_rpm.begin(), s.spindle_rpm.end());
    if (s.feed_max > 0.0) sum["feed_mm_per_min"] = {{"min", s.feed_min}, {"max", s.feed_max}};
    j["summary"] = sum;
    std::cout << j.dump(2) << "\n";
    return 0;
  }
  if (!a.summary_only) toolpath::write_canonical(std::cout, p);  // straight out, no copy
  std::cout << "summary of " << a.file << " (mm, machine coordinates)\n";
  std::cout << "  moves " << s.moves << ", events " << s.events << "\n";
  if (any) {
    for (int i = 0; i < 3; ++i) {
      std::cout << "  "
                << "XYZ"[i] << " from " << text::fixed(s.lo[i], 4) << " to "
                << text::fixed(s.hi[i], 4) << "\n";
    }
  }
  std::cout << "  cut length " << text::fixed(s.cut_mm, 3) << " mm, rapid length "
            << text::fixed(s.rapid_mm, 3) << " mm\n";
  std::cout << "  estimated time " << text::fixed(s.time_s, 1) << " s (feeds capped at "
            << text::fixed(machine.limits.max_feed_mm_per_min, 0)
            << " mm/min, rapids at that rate, " << text::fixed(s.dwell_s, 1) << " s of dwell)"
            << (s.capped ? "; some feeds were capped" : "") << "\n";
  if (s.indexes > 0) {
    const char axis = static_cast<char>(machine.limits.rotary.axis - 'a' + 'A');
    std::cout << "  rotary " << axis << " " << s.indexes << " index moves, "
              << text::fixed(s.index_deg, 1) << " deg, " << text::fixed(s.index_s, 3)
              << " s of the estimate (rest to rest, double S at [axis."
              << machine.limits.rotary.axis << "]'s "
              << text::fixed(machine.limits.rotary.max_feed_deg_per_min, 0) << " deg/min, "
              << text::fixed(machine.limits.rotary.max_accel_deg_per_s2, 0) << " deg/s2, "
              << text::fixed(machine.limits.rotary.max_jerk_deg_per_s3, 0) << " deg/s3)\n";
  }
  std::cout << "  tools";
  if (s.tools.empty()) std::cout << " none";
  for (int t : s.tools) std::cout << " T" << t;
  std::cout << "\n  spindle";
  if (s.spindle_rpm.empty()) std::cout << " never on";
  for (double r : s.spindle_rpm) std::cout << " " << text::fixed(r, 0) << " rpm";
  std::cout << "\n  feeds";
  if (s.feed_max > 0.0) {
    std::cout << " " << text::fixed(s.feed_min, 1) << " to " << text::fixed(s.feed_max, 1)
              << " mm/min\n";
  } else {
    std::cout << " none\n";
  }
  return 0;
}

}  // namespace

void register_check(CLI::App& app, Runner& run) {
  auto a = std::make_shared<CheckArgs>();
  CLI::App* c = app.add_subcommand(
      "check",
      "read an RS-274/NGC program (LinuxCNC's dialect) and print its canonical moves and "
      "events with their source lines, then extents, lengths, time, tools, speeds and feeds");
  c->add_option("FILE", a->file, "the NC program")->required();
  c->add_option("--machine", a->machine,
                "machine file (TOML): limits for the time estimate, [program] for the reader; "
                "prints where each value came from (a flag wins over the file and says so)");
  c->add_option("--tool-table", a->tool_table, "LinuxCNC tool table (overrides [program])");
  c->add_option("--start", a->start,
                "X,Y,Z: where the machine stands when the program starts, machine mm (overrides "
                "[program] start_mm)");
  c->add_option("--parameter-file", a->parameter_file,
                "LinuxCNC parameter file, .var (overrides [program]); read, and written back "
                "with --save-parameters");
  c->add_flag("--save-parameters", a->save_parameters,
              "after a program read whole, write the persistent parameters (work offsets, "
              "G28/G30 homes, G92) back to the parameter file, as LinuxCNC does at exit");
  c->add_flag("--json", a->json, "print JSON instead of text");
  c->add_flag("--summary", a->summary_only, "print the summary only, not the canonical program");
  c->add_flag("-q,--quiet", a->quiet,
              "with --machine: do not print where the values came from (stderr)");
  c->callback([a, &run] { run = [a] { return run_check(*a); }; });
}

}  // namespace ncd::app
