// A part, not a hole (docs/part.md): every hole of a pipe chamfered in one program on a machine
// whose pipe lies on a rotary table (A about X, or B about Y) under a vertical spindle.
//
// Frames. Part coordinates (s, v, w): s along the pipe axis (the rotary axis), from the pipe's
// station 0; v, w across it, w up when the table is at 0. A hole at angle θ around has the
// radial direction n(θ) = (0, sin θ, cos θ), so that turning the part by θ right-handed about
// +s, R(θ), brings n up: R(θ) n(θ) = w. Its single-hole pipe frame (cam/chamfer.hpp: the pipe
// along Y, Z towards the drill's entry side, origin at the station where the drill axis passes
// nearest the pipe axis) sits at (station, 0, 0) with Y = s, Z = n(θ), X = Y × Z; its drill
// frame follows from the hole's tilt, azimuth and eccentricity (DrillPlacement). So a point p of
// the hole's model (drill frame) is the part point q = O + M·placement(p), and at the table's
// turn α the machine point R(α) q, written as X Y Z (A: X = s, Y = v, Z = w; B: Y = s,
// X = −v, Z = w): the rotary axis's centreline is the program's Y0 Z0 (A) or X0 Z0 (B), and
// station 0 its X0 (Y0).
//
// Index. Each hole is turned so that the spindle side of its drill axis (+z of the drill frame
// for an upper edge, −z for a lower one: the part turned over) is as vertical as it can be: the
// direction's (v, w) part rotated onto w, α = atan2(d_v, d_w). A drill axis perpendicular to
// the rotary axis is then vertical and the hole is the single-hole set-up exactly. One that is
// not (a lateral, tilted along the pipe) keeps the angle asin |d_s| from the vertical: its outer
// edge is accepted when the single hole's global check passes with the machine's vertical as the
// tool axis (ChamferSpec::tool_axis; the cutter locations do not depend on it), its inner edge
// refused (the rod check and the approach down the drill axis assume the rod along that axis).
// The written rotary word is the machine's A (B) = sense · α, each hole's taken the shortest way
// from the previous one (continuous, not wrapped), starting from [rotary] start_deg (0 unless
// given), where the axis stands when the program starts.
//
// Clearance. The pipe is a body of revolution about the rotary axis: at every index it lies
// within its largest outer radius of the axis. The clearance plane is that radius plus a margin
// (default 4 R_B, as the single hole's), for the ball tip; every index happens there, the tool
// reaching it straight up from the previous hole's retract (or from where it stands at the
// start) before the rotary word, and leaving it only over the next hole.
//
// Order. The air moves between holes are the index (from hole i's turn to hole j's, the shortest
// way) followed by the rapid across at the clearance plane (from i's exit to j's entry). Their
// time model: each is a rest-to-rest trapezoid (accelerate at a, cruise at v, brake at a; a
// triangle when the distance is too short to reach v); a rapid takes the slowest of its path's
// trapezoid (the machine's rapid rate and acceleration) and each axis's own (its distance on that
// axis under the axis's limits); the index under the rotary axis's rate and acceleration. The
// descent, the cut and the rise of each hole do not depend on the order. The start is the first
// index from start_deg (the tool's place is unknown). Holes are ordered by nearest neighbour, then
// 2-opt (reversing any stretch of the order that shortens it); the file's order is improved by
// 2-opt too, and the shortest is taken, so the order is never longer than the file's. The nearest
// neighbour is started from every hole in turn (n tours; the first index from the start counts in
// each), which costs n times one and keeps 2-opt out of most of its traps.
#include "cam/part.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <optional>
#include <sstream>
#include <toml.hpp>
#include <tuple>

#include "cam/chamfer_detail.hpp"
#include "cam/whole_program.hpp"
#include "core/decimal.hpp"
#include "core/error.hpp"
#include "core/input_file.hpp"
#include "core/number_text.hpp"
#include "core/toml_text.hpp"

namespace ncd::toolpath {

namespace {

constexpr double kPerpendicular = 1e-12;  // |d_s| below this: the drill axis ⟂ the rotary axis
constexpr double kPartMaxHalfAngleRad = kPi / 3.0;

// ---- reading the part file ----

struct Reader {
  std::string file;
  std::string where(const std::string& table, const std::string& key) const {
    return file + ": " + table + "." + key;
  }
};

double as_real(const toml::value& v, const std::string& where) {
  if (v.is_floating()) return v.as_floating();
  if (v.is_integer()) return static_cast<double>(v.as_integer());
  throw InputError(where + " must be a number, not " + toml::format(v));
}

std::string as_text(const toml::value& v, const std::string& where) {
  if (!v.is_string()) throw InputError(where + " must be a string, not " + toml::format(v));
  return v.as_string().str;
}

int as_int(const toml::value& v, const std::string& where, int lo, int hi) {
  if (!v.is_integer()) {
    throw InputError(where + " must be a whole number from " + std::to_string(lo) + " to " +
                     std::to_string(hi) + ", not " + toml::format(v));
  }
  return static_cast<int>(checked_integer(v.as_integer(), lo, hi, where));
}

double positive(const toml::value& v, const std::string& where, const std::string& way_out) {
  const double x = as_real(v, where);
  if (!std::isfinite(x) || x <= 0.0) {
    throw InputError(where + " = " + text::sig(x) + " must be greater than 0; " + way_out);
  }
  return x;
}

double finite(const toml::value& v, const std::string& where) {
  const double x = as_real(v, where);
  if (!std::isfinite(x)) throw InputError(where + " = " + text::sig(x) + " must be finite");
  return x;
}

const toml::table& table_of(const toml::value& v, const std::string& where) {
  if (!v.is_table()) throw InputError(where + " must be a table");
  return v.as_table();
}

void parse_pipe(const toml::value& v, const Reader& r, PartPipe& p, bool& seen_length) {
  bool radius = false, wall = false;
  for (const auto& [key, value] : table_of(v, r.file + ": [pipe]")) {
    const std::string w = r.where("pipe", key);
    if (key == "outer_radius_mm") {
      p.outer_radius_mm = positive(value, w, "give the pipe's outer radius at station 0");
      radius = true;
    } else if (key == "wall_mm") {
      p.wall_mm = positive(value, w, "give the wall's thickness");
      wall = true;
    } else if (key == "half_angle_deg") {
      p.half_angle_rad = deg_to_rad(finite(value, w));
      if (std::abs(p.half_angle_rad) >= kPartMaxHalfAngleRad) {
        throw InputError(w + " = " + text::sig(rad_to_deg(p.half_angle_rad)) +
                         " must lie in (-60, 60) degrees; 0 for a cylinder");
      }
    } else if (key == "length_mm") {
      p.length_mm = positive(value, w, "give the pipe's length from station 0");
      if (p.length_mm > PartLimits::kMaxLengthMm) {
        throw InputError(w + " = " + text::sig(p.length_mm) + " is above " +
                         text::sig(PartLimits::kMaxLengthMm) + " mm; check the units (mm)");
      }
      seen_length = true;
    } else {
      throw InputError("unknown key " + w +
                       "; [pipe] takes outer_radius_mm, wall_mm, half_angle_deg, length_mm");
    }
  }
  if (!radius || !wall) {
    throw InputError(r.file + ": [pipe] needs outer_radius_mm and wall_mm");
  }
}

void parse_tool(const toml::value& v, const Reader& r, PartTool& t, bool& seen_h) {
  bool ball = false;
  for (const auto& [key, value] : table_of(v, r.file + ": [tool]")) {
    const std::string w = r.where("tool", key);
    if (key == "ball_radius_mm") {
      t.ball_radius_mm = positive(value, w, "give the ball's radius R_B");
      ball = true;
    } else if (key == "rod_radius_mm") {
      t.rod_radius_mm = positive(value, w, "give the rod's radius, or leave the key out");
    } else if (key == "non_knife_angle_deg") {
      const double deg = finite(value, w);
      if (!(deg > 0.0 && deg < 180.0)) {
        throw InputError(w + " = " + text::sig(deg) +
                         " must lie in (0, 180) degrees (2 beta, the non-cutting cap)");
      }
      t.non_knife_angle_rad = deg_to_rad(deg);
    } else if (key == "number") {
      t.number = as_int(value, w, 0, 99999);
    } else if (key == "length_offset") {
      t.length_offset = as_int(value, w, 0, 99999);
      seen_h = true;
    } else {
      throw InputError("unknown key " + w +
                       "; [tool] takes ball_radius_mm, rod_radius_mm, non_knife_angle_deg, "
                       "number, length_offset");
    }
  }
  if (!ball) throw InputError(r.file + ": [tool] needs ball_radius_mm");
}

void parse_cut(const toml::value& v, const Reader& r, PartCut& c) {
  for (const auto& [key, value] : table_of(v, r.file + ": [cut]")) {
    const std::string w = r.where("cut", key);
    if (key == "feed_mm_per_min") {
      c.feed_mm_per_min = positive(value, w, "give the cutting feed");
    } else if (key == "spindle_rpm") {
      c.spindle_rpm = positive(value, w, "give the spindle speed");
    } else if (key == "spindle_dwell_s") {
      c.spindle_dwell_s = finite(value, w);
      if (c.spindle_dwell_s < 0.0) throw InputError(w + " must be 0 or more (0: no dwell)");
    } else if (key == "tolerance_mm") {
      c.tolerance_mm = positive(value, w, "0.01 mm is typical");
    } else if (key == "clearance_margin_mm") {
      c.clearance_margin_mm = positive(value, w, "give the tip's height above the pipe's top");
    } else if (key == "approach_gap_mm") {
      c.approach_gap_mm = positive(value, w, "1 mm is typical");
    } else {
      throw InputError("unknown key " + w +
                       "; [cut] takes feed_mm_per_min, spindle_rpm, spindle_dwell_s, "
                       "tolerance_mm, clearance_margin_mm, approach_gap_mm");
    }
  }
}

void parse_rotary(const toml::value& v, const Reader& r, PartRotary& t) {
  for (const auto& [key, value] : table_of(v, r.file + ": [rotary]")) {
    const std::string w = r.where("rotary", key);
    if (key == "axis") {
      const std::string a = as_text(value, w);
      if (a != "a" && a != "b" && a != "A" && a != "B") {
        throw InputError(
            w + " = \"" + a +
            "\" is not a rotary axis; use \"a\" (the pipe along X) or \"b\" (along Y)");
      }
      t.axis = (a == "a" || a == "A") ? RotaryAxis::A : RotaryAxis::B;
      t.axis_given = true;
    } else if (key == "sense") {
      const int s = as_int(value, w, -1, 1);
      if (s == 0) throw InputError(w + " = 0 must be 1 or -1");
      t.sense = s;
    } else if (key == "max_feed_deg_per_min") {
      t.max_feed_deg_per_min = positive(value, w, "give the rotary axis's rapid rate");
    } else if (key == "max_accel_deg_per_s2") {
      t.max_accel_deg_per_s2 = positive(value, w, "give the rotary axis's acceleration");
    } else if (key == "start_deg") {
      t.start_deg = finite(value, w);
      if (std::abs(t.start_deg) > PartLimits::kMaxStartDeg) {
        throw InputError(w + " = " + text::sig(t.start_deg) + " is beyond ±" +
                         text::sig(PartLimits::kMaxStartDeg) +
                         " deg; give where the rotary axis stands at the start, in degrees");
      }
    } else {
      throw InputError("unknown key " + w +
                       "; [rotary] takes axis, sense, max_feed_deg_per_min, max_accel_deg_per_s2, "
                       "start_deg");
    }
  }
}

std::string label_of(std::size_t index, const std::string& name) {
  return "hole " + std::to_string(index + 1) + (name.empty() ? "" : " (\"" + name + "\")");
}

PartHole parse_hole(const toml::value& v, const std::string& file, std::size_t index) {
  PartHole h;
  const std::string table = file + ": [[hole]] " + std::to_string(index + 1);
  const toml::table& t = table_of(v, table);
  if (const auto it = t.find("name"); it != t.end()) {
    h.name = as_text(it->second, table + ".name");
    if (h.name.size() > 60) {
      throw InputError(table + ".name is " + std::to_string(h.name.size()) +
                       " characters long; give at most 60 (it goes into the program's comments)");
    }
  }
  const std::string label = file + ": " + label_of(index, h.name);
  bool station = false, angle = false, drill = false, width = false, edge = false;
  for (const auto& [key, value] : t) {
    const std::string w = label + ": " + key;
    if (key == "name") {
      continue;
    } else if (key == "position_mm") {
      h.station_mm = finite(value, w);
      station = true;
    } else if (key == "angle_deg") {
      h.angle_rad = deg_to_rad(finite(value, w));
      angle = true;
    } else if (key == "drill_radius_mm") {
      h.drill_radius_mm = positive(value, w, "give the drilled hole's radius");
      drill = true;
    } else if (key == "tilt_deg") {
      const double deg = finite(value, w);
      if (!(deg >= 0.0 && deg < 90.0)) {
        throw InputError(w + " = " + text::sig(deg) +
                         " must lie in [0, 90) degrees; give its direction with azimuth_deg");
      }
      h.tilt_rad = deg_to_rad(deg);
    } else if (key == "azimuth_deg") {
      h.azimuth_rad = deg_to_rad(finite(value, w));
    } else if (key == "eccentricity_mm") {
      h.eccentricity_mm = finite(value, w);
    } else if (key == "width_mm") {
      h.width_mm = positive(value, w, "give the chamfer's width W");
      width = true;
    } else if (key == "edge") {
      const std::string e = as_text(value, w);
      if (e != "inner" && e != "outer") {
        throw InputError(w + " = \"" + e + "\" must be \"inner\" or \"outer\"");
      }
      h.edge = e == "inner" ? Edge::Inner : Edge::Outer;
      edge = true;
    } else if (key == "side") {
      const std::string s = as_text(value, w);
      if (s != "upper" && s != "lower") {
        throw InputError(w + " = \"" + s +
                         "\" must be \"upper\" (the drill's entry side) or \"lower\"");
      }
      h.side = s == "upper" ? Side::Upper : Side::Lower;
    } else {
      throw InputError("unknown key " + w +
                       "; [[hole]] takes name, position_mm, angle_deg, drill_radius_mm, tilt_deg, "
                       "azimuth_deg, eccentricity_mm, edge, side, width_mm");
    }
  }
  const auto need = [&](bool seen, const char* key, const char* what) {
    if (!seen) throw InputError(label + " has no " + key + "; give " + what);
  };
  need(station, "position_mm", "its station along the pipe, mm from station 0");
  need(angle, "angle_deg", "its angle around the pipe (the index that brings it up), degrees");
  need(drill, "drill_radius_mm", "the drilled hole's radius, mm");
  need(width, "width_mm", "the chamfer's width, mm");
  need(edge, "edge", "edge = \"outer\" or \"inner\"");
  return h;
}

void check_part(const Part& p) {
  const std::string& f = p.source;
  if (p.pipe.length_mm <= 0.0) throw InputError(f + ": [pipe] needs length_mm");
  for (const double station : {0.0, p.pipe.length_mm}) {
    const double outer = p.pipe.outer_radius_at(station);
    const double inner = outer - p.pipe.wall_mm / std::cos(p.pipe.half_angle_rad);
    if (!(inner > 0.0)) {
      throw InputError(f + ": pipe.wall_mm = " + text::sig(p.pipe.wall_mm) +
                       " leaves no bore at station " + text::sig(station) + " mm (outer radius " +
                       text::sig(outer) +
                       " mm); give a thinner wall, a larger radius or a "
                       "smaller cone half-angle");
    }
  }
  if (p.holes.empty()) throw InputError(f + ": no [[hole]]; give at least one");
  for (std::size_t i = 0; i < p.holes.size(); ++i) {
    const PartHole& h = p.holes[i];
    if (h.station_mm < 0.0 || h.station_mm > p.pipe.length_mm) {
      throw InputError(f + ": " + label_of(i, h.name) +
                       ": position_mm = " + text::sig(h.station_mm) + " is off the pipe [0, " +
                       text::sig(p.pipe.length_mm) + "] mm; give its station along the pipe");
    }
  }
}

Vec3 rotate_about_s(const Vec3& q, double turn_rad) {
  const double c = std::cos(turn_rad), s = std::sin(turn_rad);
  return {q.x(), q.y() * c - q.z() * s, q.y() * s + q.z() * c};
}

}  // namespace

std::string to_string(RotaryAxis axis) {
  return axis == RotaryAxis::A ? "A" : "B";
}

double PartPipe::outer_radius_at(double station_mm) const {
  return outer_radius_mm + station_mm * std::tan(half_angle_rad);
}

double PartPipe::max_outer_radius_mm() const {
  return std::max(outer_radius_at(0.0), outer_radius_at(length_mm));
}

Part parse_part(const std::string& text, const std::string& name) {
  const toml::value root = ncd::parse_toml_text(text, name, "part file");
  Part p;
  p.source = name;
  const Reader r{name};
  bool seen_pipe = false, seen_tool = false, seen_length = false, seen_h = false;
  for (const auto& [key, value] : table_of(root, name)) {
    if (key == "pipe") {
      parse_pipe(value, r, p.pipe, seen_length);
      seen_pipe = true;
    } else if (key == "tool") {
      parse_tool(value, r, p.tool, seen_h);
      seen_tool = true;
    } else if (key == "cut") {
      parse_cut(value, r, p.cut);
    } else if (key == "rotary") {
      parse_rotary(value, r, p.rotary);
    } else if (key == "hole") {
      if (!value.is_array()) {
        throw InputError(name + ": hole must be an array of tables: [[hole]]");
      }
      const auto& holes = value.as_array();
      if (holes.size() > PartLimits::kMaxHoles) {
        throw InputError(name + ": " + std::to_string(holes.size()) + " holes, more than " +
                         std::to_string(PartLimits::kMaxHoles) + "; split the part");
      }
      for (std::size_t i = 0; i < holes.size(); ++i)
        p.holes.push_back(parse_hole(holes[i], name, i));
    } else {
      throw InputError("unknown table or key " + name + ": " + key +
                       "; a part file takes [pipe], [tool], [cut], [rotary] and [[hole]]");
    }
  }
  if (!seen_pipe) throw InputError(name + ": no [pipe]; give outer_radius_mm, wall_mm, length_mm");
  if (!seen_tool) throw InputError(name + ": no [tool]; give ball_radius_mm at least");
  if (!seen_length) throw InputError(name + ": [pipe] needs length_mm");
  if (!seen_h) p.tool.length_offset = p.tool.number;
  check_part(p);
  return p;
}

Part load_part(const std::string& path) {
  return parse_part(read_input_file(path, "part file, --part"), path);
}

std::string hole_label(const Part& part, std::size_t index) {
  return label_of(index, part.holes.at(index).name);
}

Vec3 HoleSetup::pipe_to_part(const Vec3& p) const {
  return origin + p.x() * axes[0] + p.y() * axes[1] + p.z() * axes[2];
}

Vec3 part_to_machine(RotaryAxis axis, const Vec3& part, double turn_rad) {
  const Vec3 q = rotate_about_s(part, turn_rad);
  return axis == RotaryAxis::A ? q : Vec3(-q.y(), q.x(), q.z());
}

HoleSetup hole_setup(const Part& part, std::size_t index) {
  const PartHole& h = part.holes.at(index);
  const PartPipe& pipe = part.pipe;
  const std::string label = part.source + ": " + hole_label(part, index);
  HoleSetup s;
  ChamferSpec& c = s.spec;
  const double outer = pipe.outer_radius_at(h.station_mm);
  const double radial_wall = pipe.wall_mm / std::cos(pipe.half_angle_rad);
  c.pipe_radius_mm = h.edge == Edge::Outer ? outer : outer - radial_wall;
  c.pipe_thickness_mm = pipe.wall_mm;
  c.pipe_half_angle_rad = pipe.half_angle_rad;
  c.drill_radius_mm = h.drill_radius_mm;
  c.ball_radius_mm = part.tool.ball_radius_mm;
  c.width_mm = h.width_mm;
  c.tolerance_mm = part.cut.tolerance_mm;
  c.edge = h.edge;
  c.side = h.side;
  c.rod_radius_mm = part.tool.rod_radius_mm;
  c.non_knife_angle_rad = part.tool.non_knife_angle_rad;
  c.drill_tilt_rad = h.tilt_rad;
  c.drill_azimuth_rad = h.azimuth_rad;
  c.eccentricity_mm = h.eccentricity_mm;
  const double th = h.angle_rad;
  s.origin = Vec3(h.station_mm, 0.0, 0.0);
  s.axes = {Vec3(0.0, -std::cos(th), std::sin(th)), Vec3(1.0, 0.0, 0.0),
            Vec3(0.0, std::sin(th), std::cos(th))};
  const DrillPlacement place = drill_placement(c);
  const Vec3 spindle_drill(0.0, 0.0, h.side == Side::Upper ? 1.0 : -1.0);
  const Vec3 d_pipe = place.direction_to_pipe(spindle_drill);
  const Vec3 d = d_pipe.x() * s.axes[0] + d_pipe.y() * s.axes[1] + d_pipe.z() * s.axes[2];
  s.index_rad = std::atan2(d.y(), d.z());
  s.perpendicular = std::abs(d.x()) <= kPerpendicular;
  s.tilt_left_rad = std::asin(std::min(1.0, std::abs(d.x())));
  if (!s.perpendicular) {
    if (h.edge == Edge::Inner) {
      throw InputError(
          label + ": its drill axis is " + chamfer_detail::fmt_deg(s.tilt_left_rad) +
          " out of the plane the " + to_string(part.rotary.axis) +
          " axis turns, so no index makes it vertical, and an inner edge needs the tool down the "
          "drill axis (the rod check and the approach through the hole assume it); this machine "
          "lacks that tilt: cut the hole on a machine with a tilting axis, or chamfer its outer "
          "edge");
    }
    // The machine's vertical in part coordinates at this index, then in the drill frame.
    const Vec3 up(0.0, std::sin(s.index_rad), std::cos(s.index_rad));
    const Vec3 up_pipe(s.axes[0].dot(up), s.axes[1].dot(up), s.axes[2].dot(up));
    c.tool_axis =
        Vec3(place.x.dot(up_pipe), place.y.dot(up_pipe), place.z.dot(up_pipe)).normalized();
  }
  try {
    validate(c);
  } catch (const InputError& e) {
    throw InputError(label + ": " + e.what() +
                     " (the part file's keys: drill_radius_mm, tilt_deg, azimuth_deg, "
                     "eccentricity_mm, width_mm, [pipe], [tool])");
  }
  return s;
}

double trapezoid_time_s(double distance, double rate, double accel) {
  const double d = std::abs(distance);
  if (d == 0.0) return 0.0;
  if (d >= rate * rate / accel) return d / rate + rate / accel;
  return 2.0 * std::sqrt(d / accel);
}

double rapid_time_s(const AirModel& m, const Vec3& from, const Vec3& to) {
  const Vec3 delta = to - from;
  double t = trapezoid_time_s(delta.norm(), m.rapid_mm_per_s, m.rapid_accel_mm_per_s2);
  for (int i = 0; i < 3; ++i) {
    const double v = std::min(m.axis_mm_per_s[static_cast<std::size_t>(i)], m.rapid_mm_per_s);
    const double a =
        std::min(m.axis_accel_mm_per_s2[static_cast<std::size_t>(i)], m.rapid_accel_mm_per_s2);
    t = std::max(t, trapezoid_time_s(delta[i], v, a));
  }
  return t;
}

double index_time_s(const AirModel& m, double delta_deg) {
  return trapezoid_time_s(delta_deg, m.index_deg_per_s, m.index_accel_deg_per_s2);
}

double shortest_turn_deg(double from_deg, double to_deg) {
  double d = std::fmod(to_deg - from_deg, 360.0);
  if (d >= 180.0) d -= 360.0;
  if (d < -180.0) d += 360.0;
  return d;
}

double AirCosts::tour_s(const std::vector<std::size_t>& order) const {
  if (order.empty()) return 0.0;
  double t = from_start[order.front()];
  for (std::size_t k = 1; k < order.size(); ++k) t += between[order[k - 1]][order[k]];
  return t;
}

namespace {

// 2-opt on an open path from the start: reversing order[i..j] changes only the two links at
// its ends (the costs between holes are symmetric); taken while it shortens the tour.
void two_opt(const AirCosts& c, std::vector<std::size_t>& order) {
  const std::size_t n = order.size();
  const auto link = [&](std::size_t pos_before, std::size_t hole) {  // pos_before n: the start
    return pos_before == n ? c.from_start[hole] : c.between[order[pos_before]][hole];
  };
  for (bool improved = true; improved;) {
    improved = false;
    for (std::size_t i = 0; i + 1 < n; ++i) {
      for (std::size_t j = i + 1; j < n; ++j) {
        const std::size_t before = i == 0 ? n : i - 1;
        const double tail_old = j + 1 < n ? c.between[order[j]][order[j + 1]] : 0.0;
        const double tail_new = j + 1 < n ? c.between[order[i]][order[j + 1]] : 0.0;
        const double old_cost = link(before, order[i]) + tail_old;
        const double new_cost = link(before, order[j]) + tail_new;
        if (new_cost < old_cost - 1e-12 * (1.0 + old_cost)) {
          std::reverse(order.begin() + static_cast<std::ptrdiff_t>(i),
                       order.begin() + static_cast<std::ptrdiff_t>(j) + 1);
          improved = true;
        }
      }
    }
  }
}

}  // namespace

std::vector<std::size_t> order_holes(const AirCosts& c) {
  const std::size_t n = c.from_start.size();
  std::vector<std::size_t> best(n);
  for (std::size_t i = 0; i < n; ++i) best[i] = i;
  if (n < 2) return best;
  two_opt(c, best);  // the file's order, improved
  // Nearest neighbour from each first hole, each improved by 2-opt.
  for (std::size_t first = 0; first < n; ++first) {
    std::vector<std::size_t> nn{first};
    std::vector<bool> used(n, false);
    used[first] = true;
    while (nn.size() < n) {
      std::size_t next = n;
      double next_t = std::numeric_limits<double>::infinity();
      for (std::size_t j = 0; j < n; ++j) {
        if (!used[j] && c.between[nn.back()][j] < next_t)
          next_t = c.between[nn.back()][j], next = j;
      }
      used[next] = true;
      nn.push_back(next);
    }
    two_opt(c, nn);
    if (c.tour_s(nn) < c.tour_s(best)) best = nn;
  }
  return best;
}

namespace {

// The loop of a hole in machine coordinates at its index, programmed point.
std::vector<Vec3> machine_loop(const Part& part, const HoleSetup& s, const ChamferPath& path,
                               ProgramPoint point) {
  const DrillPlacement place = drill_placement(s.spec);
  std::vector<Vec3> out;
  out.reserve(path.points.size());
  for (const CutterPose& pose : path.points) {
    Vec3 m = part_to_machine(part.rotary.axis, s.pipe_to_part(place.to_pipe(pose.cl)), s.index_rad);
    if (point == ProgramPoint::Tip) m.z() -= s.spec.ball_radius_mm;
    out.push_back(m);
  }
  return out;
}

void check_hole_path(const Part& part, std::size_t index, const HoleSetup& s,
                     const ChamferPath& path) {
  const std::string label = part.source + ": " + hole_label(part, index);
  const ChamferChecks& ck = path.checks;
  if (!ck.local_ok || !ck.global_ok || !ck.rod_ok) {
    std::string why = interference_reasons(path);
    if (!s.perpendicular && !ck.global_ok) {
      why += ". After its index the drill axis stays " + chamfer_detail::fmt_deg(s.tilt_left_rad) +
             " from the vertical: this machine lacks that tilt (a tilting axis would give it)";
    }
    throw InputError(label + " cannot be chamfered on this machine: " + why +
                     ". No program written. Use a smaller ball (tool.ball_radius_mm), another "
                     "edge, or leave the hole out");
  }
  const DrillPlacement place = drill_placement(s.spec);
  for (const CutterPose& pose : path.points) {
    const double station = s.pipe_to_part(place.to_pipe(pose.xp)).x();
    if (station < 0.0 || station > part.pipe.length_mm) {
      throw InputError(label + ": its edge reaches station " + text::sig(station) +
                       " mm, off the pipe [0, " + text::sig(part.pipe.length_mm) +
                       "] mm; move the hole (position_mm) or give the pipe's length");
    }
  }
}

// The closest approach of segments p0p1 and q0q1 (Ericson, Real-Time Collision Detection,
// 5.1.9): the parameters clamped to [0, 1] in turn.
double part_segment_distance(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1) {
  const Vec3 d1 = p1 - p0, d2 = q1 - q0, r = p0 - q0;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  double s = 0.0, t = 0.0;
  if (a <= 1e-300 && e <= 1e-300) return r.norm();
  if (a <= 1e-300) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= 1e-300) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2), denom = a * e - b * b;
      s = denom > 0.0 ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0.0) {
        t = 0.0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1.0) {
        t = 1.0;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  return ((p0 + s * d1) - (q0 + t * d2)).norm();
}

// A hole's chamfered edge and drilled hole in part coordinates, for the overlap check.
struct PartEdgeRing {
  std::vector<Vec3> edge;  // closed loop (the last point joins the first)
  Vec3 centre;             // of the edge's bounding sphere
  double radius = 0.0;
  Vec3 axis_point, axis;  // the drill axis: its point nearest the pipe axis, unit direction
  double drill_radius_mm = 0.0;
  double side = 1.0;  // the sign of (edge − axis_point)·axis: the wall the edge is on
  double width_mm = 0.0;
};

PartEdgeRing edge_ring(const HoleCut& h) {
  PartEdgeRing g;
  g.edge = edge_in_part(h, PartLimits::kOverlapSagMm);
  g.centre = Vec3::Zero();
  for (const Vec3& p : g.edge) g.centre += p;
  g.centre /= static_cast<double>(g.edge.size());
  for (const Vec3& p : g.edge) g.radius = std::max(g.radius, (p - g.centre).norm());
  const DrillPlacement place = drill_placement(h.setup.spec);
  g.axis_point = h.setup.pipe_to_part(place.origin);
  g.axis = (h.setup.pipe_to_part(place.to_pipe(Vec3(0, 0, 1))) - g.axis_point).normalized();
  g.drill_radius_mm = h.setup.spec.drill_radius_mm;
  g.side = (g.centre - g.axis_point).dot(g.axis) >= 0.0 ? 1.0 : -1.0;
  g.width_mm = h.setup.spec.width_mm;
  return g;
}

// The first point of `b`'s edge inside `a`'s drilled hole (nearer a's drill axis than its radius,
// on the wall a's edge is on), if any.
std::optional<Vec3> edge_inside_hole(const PartEdgeRing& a, const PartEdgeRing& b) {
  for (const Vec3& p : b.edge) {
    const Vec3 w = p - a.axis_point;
    const double along = w.dot(a.axis);
    if (along * a.side > 0.0 && (w - along * a.axis).norm() < a.drill_radius_mm) return p;
  }
  return std::nullopt;
}

double ring_distance_mm(const PartEdgeRing& a, const PartEdgeRing& b, double stop_below) {
  double best = kInf;
  const std::size_t na = a.edge.size(), nb = b.edge.size();
  for (std::size_t i = 0; i < na; ++i) {
    const Vec3& p0 = a.edge[i];
    const Vec3& p1 = a.edge[(i + 1) % na];
    for (std::size_t j = 0; j < nb; ++j) {
      best = std::min(best, part_segment_distance(p0, p1, b.edge[j], b.edge[(j + 1) % nb]));
    }
    if (best < stop_below) return best;
  }
  return best;
}

// Overlapping holes (docs/part.md, "Overlapping holes"): refused naming both.
void check_overlaps(const Part& part, const std::vector<HoleCut>& cuts) {
  std::vector<PartEdgeRing> rings;
  rings.reserve(cuts.size());
  for (const HoleCut& h : cuts) rings.push_back(edge_ring(h));
  const auto refuse = [&](std::size_t i, std::size_t j, const std::string& how) {
    throw InputError(part.source + ": " + hole_label(part, i) + " and " + hole_label(part, j) +
                     " overlap: " + how +
                     "; move one of them (position_mm, angle_deg), narrow the chamfers "
                     "(width_mm) or leave one out. No program written");
  };
  for (std::size_t i = 0; i < cuts.size(); ++i) {
    for (std::size_t j = i + 1; j < cuts.size(); ++j) {
      const PartEdgeRing &a = rings[i], &b = rings[j];
      const double limit = a.width_mm + b.width_mm;
      for (const auto& [x, y, xi, yi] : {std::tuple{&a, &b, i, j}, std::tuple{&b, &a, j, i}}) {
        if (const auto p = edge_inside_hole(*x, *y)) {
          refuse(i, j,
                 "the edge of " + hole_label(part, yi) + " enters the drilled hole of " +
                     hole_label(part, xi) + " (at station " + text::fixed(p->x(), 3) +
                     " mm, nearer its drill axis than its radius " + text::sig(x->drill_radius_mm) +
                     " mm)");
        }
      }
      if ((a.centre - b.centre).norm() - a.radius - b.radius > limit) continue;
      // Stops at the first approach within the limit; then the closest, for the message.
      if (ring_distance_mm(a, b, limit) <= limit) {
        const double d = ring_distance_mm(a, b, 0.0);
        refuse(i, j,
               "their edges come within " + text::fixed(d, 3) +
                   " mm of each other, not more than the sum of their chamfer widths " +
                   text::sig(limit) + " mm (" + text::sig(a.width_mm) + " + " +
                   text::sig(b.width_mm) + ")");
      }
    }
  }
}

}  // namespace

std::vector<Vec3> edge_in_part(const HoleCut& h, double sag_mm) {
  const ChamferModel model(h.setup.spec);
  // The chord of a step Δθ leaves the curve by at most max|C''| Δθ² / 8: the largest second
  // derivative over 64 samples, with half again for what falls between them.
  double c2 = 0.0;
  for (int k = 0; k < 64; ++k)
    c2 = std::max(c2, model.second_derivative(2.0 * kPi * k / 64).norm());
  const double step = std::sqrt(8.0 * sag_mm / (1.5 * c2));
  const std::size_t n =
      std::clamp<std::size_t>(static_cast<std::size_t>(std::ceil(2.0 * kPi / step)), 64, 100000);
  const DrillPlacement place = drill_placement(h.setup.spec);
  std::vector<Vec3> out;
  out.reserve(n);
  for (std::size_t k = 0; k < n; ++k) {
    const double theta = 2.0 * kPi * static_cast<double>(k) / static_cast<double>(n);
    out.push_back(h.setup.pipe_to_part(place.to_pipe(model.point(theta))));
  }
  return out;
}

PartProgram plan_part(const Part& part, const AirModel& air, NgcOptions o) {
  PartProgram prog;
  prog.part = part;
  o.feed_mm_per_min = part.cut.feed_mm_per_min;
  o.spindle_rpm = part.cut.spindle_rpm;
  o.spindle_dwell_s = part.cut.spindle_dwell_s;
  o.tool = part.tool.number;
  const double rb = part.tool.ball_radius_mm;
  const double margin = part.cut.clearance_margin_mm.value_or(4.0 * rb);
  prog.clearance_tip_z_mm = part.pipe.max_outer_radius_mm() + margin;
  prog.clearance_z_mm = prog.clearance_tip_z_mm + (o.point == ProgramPoint::Centre ? rb : 0.0);
  o.safe_z_mm = prog.clearance_z_mm;
  prog.options = o;

  const std::size_t n = part.holes.size();
  std::vector<HoleCut> cuts(n);
  for (std::size_t i = 0; i < n; ++i) {
    HoleCut& h = cuts[i];
    h.hole = i;
    h.setup = hole_setup(part, i);
    try {
      h.path = generate_chamfer(h.setup.spec);
    } catch (const InputError& e) {
      throw InputError(part.source + ": " + hole_label(part, i) + ": " + e.what());
    }
    check_hole_path(part, i, h.setup, h.path);
    h.points = machine_loop(part, h.setup, h.path, o.point);
    double top = -kInf;  // the top of the ball along the loop
    for (const Vec3& p : h.points)
      top = std::max(top, p.z() + (o.point == ProgramPoint::Tip ? 2.0 : 1.0) * rb);
    if (!(prog.clearance_z_mm > top)) {
      throw InputError(part.source + ": " + hole_label(part, i) + ": the clearance plane Z " +
                       text::fixed(prog.clearance_z_mm, 3) +
                       " mm is not above the top of the ball along its loop (" +
                       text::fixed(top, 3) + " mm); raise cut.clearance_margin_mm");
    }
    Vec3 entry = h.points.front();
    if (h.setup.spec.edge == Edge::Inner) {
      const DrillPlacement place = drill_placement(h.setup.spec);
      entry =
          part_to_machine(part.rotary.axis, h.setup.pipe_to_part(place.origin), h.setup.index_rad);
    }
    h.over = Vec3(entry.x(), entry.y(), prog.clearance_z_mm);
  }
  check_overlaps(part, cuts);

  AirCosts costs;
  costs.from_start.resize(n);
  costs.between.assign(n, std::vector<double>(n, 0.0));
  const double sense = part.rotary.sense;
  for (std::size_t i = 0; i < n; ++i) {
    const double ai = sense * rad_to_deg(cuts[i].setup.index_rad);
    costs.from_start[i] = index_time_s(air, shortest_turn_deg(part.rotary.start_deg, ai));
    for (std::size_t j = 0; j < n; ++j) {
      if (i == j) continue;
      const double aj = sense * rad_to_deg(cuts[j].setup.index_rad);
      costs.between[i][j] = index_time_s(air, shortest_turn_deg(ai, aj)) +
                            rapid_time_s(air, cuts[i].over, cuts[j].over);
    }
  }
  std::vector<std::size_t> file(n);
  for (std::size_t i = 0; i < n; ++i) file[i] = i;
  prog.order = order_holes(costs);
  prog.air_ordered_s = costs.tour_s(prog.order);
  prog.air_file_order_s = costs.tour_s(file);
  double a = part.rotary.start_deg;
  for (const std::size_t i : prog.order) {
    HoleCut h = cuts[i];
    a += shortest_turn_deg(a, sense * rad_to_deg(h.setup.index_rad));
    h.a_deg = a;
    for (std::size_t k = 0; k < h.points.size(); ++k) {
      prog.cut_length_mm += (h.points[(k + 1) % h.points.size()] - h.points[k]).norm();
    }
    prog.cuts.push_back(std::move(h));
  }
  return prog;
}

namespace {

std::string xyz(const Vec3& p, int d) {
  return "X" + text::fixed(p.x(), d) + " Y" + text::fixed(p.y(), d) + " Z" + text::fixed(p.z(), d);
}

void write_header(std::ostream& g, const PartProgram& prog) {
  const Part& p = prog.part;
  const NgcOptions& o = prog.options;
  const std::string ax = to_string(p.rotary.axis);
  const std::string along = p.rotary.axis == RotaryAxis::A ? "X" : "Y";
  g << "(ncd chamfer --part " << std::filesystem::path(p.source).filename().string() << ": "
    << p.holes.size() << " holes of one pipe, each indexed under the spindle on " << ax << ")\n";
  g << "(pipe: outer radius " << text::fixed(p.pipe.outer_radius_mm, 4) << " mm at station 0, wall "
    << text::fixed(p.pipe.wall_mm, 4) << " mm, half-angle "
    << text::fixed(rad_to_deg(p.pipe.half_angle_rad), 3) << " deg, length "
    << text::fixed(p.pipe.length_mm, 3) << " mm)\n";
  g << "(set-up: the pipe's axis on the " << ax << " axis's centreline, " << along
    << " = the station (" << along << "0 at station 0), "
    << (p.rotary.axis == RotaryAxis::A ? "Y0 Z0" : "X0 Z0") << " on the centreline; at " << ax
    << "0 the hole angle 0 points up; " << ax << "+ turns the part "
    << (p.rotary.sense > 0 ? "right-handed" : "left-handed") << " about +" << along << ")\n";
  g << "(the " << ax << " axis stands at " << ax << text::fixed(p.rotary.start_deg, 4)
    << " at the start: the first index leaves from there)\n";
  g << "(tool: ball radius " << text::fixed(p.tool.ball_radius_mm, 4) << " mm, rod "
    << (p.tool.rod_radius_mm ? text::fixed(*p.tool.rod_radius_mm, 4) + " mm" : "not given")
    << ", non-knife angle "
    << (p.tool.non_knife_angle_rad
            ? text::fixed(rad_to_deg(*p.tool.non_knife_angle_rad), 3) + " deg"
            : "not given")
    << ")\n";
  g << "(" << programmed_point_text(o.point, p.tool.ball_radius_mm) << ")\n";
  if (!o.tool_change) {
    g << "(load tool " << o.tool << " before the start: this controller has no tool change, M6)\n";
  }
  g << "(" << tool_length_text(o.point, p.tool.length_offset, o.length_offset) << ")\n";
  g << "(clearance: Z" << text::fixed(prog.clearance_z_mm, 4) << ", the ball tip "
    << text::fixed(prog.clearance_tip_z_mm - p.pipe.max_outer_radius_mm(), 3)
    << " mm above the pipe's largest radius " << text::fixed(p.pipe.max_outer_radius_mm(), 3)
    << " mm: above the part at every index; every " << ax << " move is made there)\n";
  g << "(order:";
  for (const HoleCut& h : prog.cuts) g << " " << h.hole + 1;
  g << "; air time " << text::fixed(prog.air_ordered_s, 2) << " s against "
    << text::fixed(prog.air_file_order_s, 2) << " s in the file's order)\n";
  for (const HoleCut& h : prog.cuts) {
    const ChamferChecks& ck = h.path.checks;
    g << "(" << hole_label(p, h.hole) << ": station " << text::fixed(p.holes[h.hole].station_mm, 3)
      << " mm, angle " << text::fixed(rad_to_deg(p.holes[h.hole].angle_rad), 3) << " deg, "
      << to_string(h.setup.spec.edge) << " " << to_string(h.setup.spec.side) << " edge, drill r "
      << text::fixed(h.setup.spec.drill_radius_mm, 4) << ", width "
      << text::fixed(h.setup.spec.width_mm, 4) << ")\n(  " << ax << text::fixed(h.a_deg, 4)
      << (h.setup.perpendicular
              ? ", drill axis vertical"
              : ", drill axis " + text::fixed(rad_to_deg(h.setup.tilt_left_rad), 3) +
                    " deg from the vertical")
      << "; checks local ok, global ok, rod " << (!ck.limit_radius_mm ? "not checked" : "ok")
      << "; " << h.points.size() << " points)\n";
  }
}

// A comment's text as RS-274/NGC takes it: no parenthesis inside (LinuxCNC refuses a nested
// comment), so a hole's name or a note in brackets instead.
std::string comment(std::string text) {
  for (char& ch : text) {
    if (ch == '(') ch = '[';
    if (ch == ')') ch = ']';
  }
  return "(" + text + ")\n";
}

}  // namespace

std::string part_program_text(const PartProgram& prog) {
  const NgcOptions& o = prog.options;
  const int d = o.decimals;
  const std::string ax = to_string(prog.part.rotary.axis);
  const std::string clear = "G0 Z" + text::fixed(prog.clearance_z_mm, d);
  std::ostringstream g;
  if (o.percent) g << "%\n";
  std::ostringstream header;  // written as "(…)" lines, then made comment-safe
  write_header(header, prog);
  std::istringstream lines(header.str());
  for (std::string line; std::getline(lines, line);) {
    g << comment(line.substr(1, line.size() - 2));
  }
  g << "G21 G90 G94 G17 G40 G49\n";
  if (o.path_blending) {
    g << "G64 P" << text::fixed(prog.part.cut.tolerance_mm, 4) << "\n";
  } else {
    g << "(no G64 P: this controller has no blending tolerance; its own path mode applies)\n";
  }
  if (o.tool_change) g << "T" << o.tool << " M6\n";
  if (o.length_offset) g << "G43 H" << prog.part.tool.length_offset << "\n";
  g << "S" << text::fixed(o.spindle_rpm, 0) << " M3\n";
  if (o.spindle_dwell_s > 0.0) g << "G4 P" << text::fixed(o.spindle_dwell_s, 3) << "\n";
  g << clear << "\n";
  const std::string feed = " F" + text::fixed(o.feed_mm_per_min, 1);
  for (std::size_t k = 0; k < prog.cuts.size(); ++k) {
    const HoleCut& h = prog.cuts[k];
    const bool inner = h.setup.spec.edge == Edge::Inner;
    const Vec3& first = h.points.front();
    g << comment(std::to_string(k + 1) + " of " + std::to_string(prog.cuts.size()) + ": " +
                 hole_label(prog.part, h.hole));
    g << "G0 " << ax << text::fixed(h.a_deg, d) << "\n";
    g << "G0 X" << text::fixed(h.over.x(), d) << " Y" << text::fixed(h.over.y(), d) << "\n";
    const double gap_z = first.z() + prog.part.cut.approach_gap_mm;
    if (gap_z < prog.clearance_z_mm) g << "G0 Z" << text::fixed(gap_z, d) << "\n";
    g << "G1 Z" << text::fixed(first.z(), d) << feed << "\n";
    if (inner) g << "G1 " << xyz(first, d) << "\n";
    for (std::size_t i = 1; i < h.points.size(); ++i) g << "G1 " << xyz(h.points[i], d) << "\n";
    g << "G1 " << xyz(first, d) << " (loop closed)\n";
    if (inner) {
      g << "G1 X" << text::fixed(h.over.x(), d) << " Y" << text::fixed(h.over.y(), d) << "\n";
    }
    g << clear << "\n";
  }
  g << "M5\nM2\n";
  if (o.percent) g << "%\n";
  return g.str();
}

}  // namespace ncd::toolpath
