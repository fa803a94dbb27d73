// Machine file reader on toml11. Integers are accepted where a real number is expected
// (`period_s = 1` is 1.0 s); anything else of the wrong type, an unknown key or table, and a
// value out of range are InputErrors naming the file and the key. The [link] spellings are
// those of the line flags (link/line_settings.hpp); [encoder] is checked by the encoder's own
// validate().
#include "service/machine_config.hpp"

#include <filesystem>

#include <charconv>
#include <cmath>
#include <cstdint>
#include <toml.hpp>

#include "core/decimal.hpp"
#include "core/error.hpp"
#include "core/input_file.hpp"
#include "core/input_ranges.hpp"
#include "core/toml_text.hpp"

namespace ncd::service {
namespace {

double as_real(const toml::value& v, const std::string& where) {
  if (v.is_floating()) return v.as_floating();
  if (v.is_integer()) return static_cast<double>(v.as_integer());
  throw InputError(where + " must be a number, not " + toml::format(v));
}

// Every TOML integer goes through checked_integer (core/decimal.hpp): in range, or an error
// naming the key, the value and the range.
std::int64_t as_int_in(const toml::value& v, const std::string& where, std::int64_t lo,
                       std::int64_t hi) {
  if (!v.is_integer()) {
    throw InputError(where + " must be a whole number from " + std::to_string(lo) + " to " +
                     std::to_string(hi) + ", not " + toml::format(v));
  }
  return checked_integer(v.as_integer(), lo, hi, where);
}

int as_int(const toml::value& v, const std::string& where) {
  return static_cast<int>(as_int_in(v, where, 1, 1000));
}

// A value within its documented range (core/input_ranges.hpp, docs/input-ranges.md).
void check(double value, const ranges::Range& r, const std::string& where) {
  checked_range(value, r.lo, r.hi, where, r.unit,
                "give a value in the range, or leave the key out for the default (see "
                "config/machine.example.toml)");
}

// The plausible ranges of the machine file; the interpolator's, the cutting law's and the
// encoder's own validate() then check the relations between values.
void check_ranges(const MachineConfig& c, const std::string& name) {
  const auto& l = c.limits;
  const auto& k = c.cutting;
  check(l.period_s, ranges::kPeriodS, name + ": period_s");
  check(l.max_feed_mm_per_min, ranges::kMaxFeedMmPerMin, name + ": max_feed_mm_per_min");
  check(l.max_accel_mm_per_s2, ranges::kMaxAccelMmPerS2, name + ": max_accel_mm_per_s2");
  check(l.max_jerk_mm_per_s3, ranges::kMaxJerkMmPerS3, name + ": max_jerk_mm_per_s3");
  check(l.chord_tolerance_mm, ranges::kChordToleranceMm, name + ": chord_tolerance_mm");
  check(k.ball_radius_mm, ranges::kBallRadiusMm, name + ": cutting.ball_radius_mm");
  check(k.pick_feed_mm, ranges::kPickFeedMm, name + ": cutting.pick_feed_mm");
  check(k.spindle_rpm, ranges::kSpindleRpm, name + ": cutting.spindle_rpm");
  check(k.roughness_target_um, ranges::kRoughnessTargetUm, name + ": cutting.roughness_target_um");
  check(c.link.xoff_timeout_s, ranges::kXoffTimeoutS, name + ": link.xoff_timeout_s");
  check(c.link.reconnect_max_s, ranges::kReconnectMaxS, name + ": link.reconnect_max_s");
  const auto& e = c.encoder;
  check(e.chord_tolerance_mm, ranges::kEncoderChordToleranceMm,
        name + ": encoder.chord_tolerance_mm");
  check(e.time_tolerance_s, ranges::kTimeToleranceS, name + ": encoder.time_tolerance_s");
  check(e.max_block_s, ranges::kMaxBlockS, name + ": encoder.max_block_s");
}

double as_positive(const toml::value& v, const std::string& where) {
  const double x = as_real(v, where);
  if (!std::isfinite(x) || x <= 0.0) {
    throw InputError(where + " = " + toml::format(v) + " must be a number greater than 0");
  }
  return x;
}

std::string as_text(const toml::value& v, const std::string& where) {
  if (!v.is_string()) throw InputError(where + " must be a string, not " + toml::format(v));
  return v.as_string().str;
}

bool as_bool(const toml::value& v, const std::string& where) {
  if (!v.is_boolean()) throw InputError(where + " must be true or false, not " + toml::format(v));
  return v.as_boolean();
}

// Runs a parser of link/line_settings.hpp, its message prefixed with the file and key.
template <typename F>
auto with_where(const std::string& where, F&& parse) {
  try {
    return parse();
  } catch (const InputError& e) {
    throw InputError(where + ": " + e.what());
  }
}

void parse_link(const toml::value& table, const std::string& name, LinkConfig& l) {
  for (const auto& [key, v] : table.as_table()) {
    const std::string where = name + ": link." + key;
    comms::LineSettings& line = l.line;
    l.keys.insert(key);
    if (key == "device") {
      line.device = as_text(v, where);
    } else if (key == "baud") {
      line.baud = static_cast<int>(as_int_in(v, where, 1, 10000000));
      with_where(where, [&] {
        comms::check_baud(line.baud);
        return 0;
      });
    } else if (key == "frame") {
      const std::string text = as_text(v, where);
      with_where(where, [&] {
        comms::parse_frame(text, line);
        return 0;
      });
    } else if (key == "flow") {
      const std::string text = as_text(v, where);
      line.flow = with_where(where, [&] { return comms::parse_flow(text); });
    } else if (key == "protocol") {
      const std::string text = as_text(v, where);
      line.protocol = with_where(where, [&] { return comms::parse_protocol(text); });
    } else if (key == "eob") {
      const std::string text = as_text(v, where);
      line.eob = with_where(where, [&] { return comms::parse_eob(text); });
    } else if (key == "percent") {
      line.percent_framing = as_bool(v, where);
    } else if (key == "nul_leader") {
      line.nul_leader = static_cast<int>(as_int_in(v, where, 0, 1000));
    } else if (key == "rx_buffer_bytes") {
      l.rx_buffer_bytes = static_cast<int>(as_int_in(v, where, 1, 1 << 20));
    } else if (key == "max_queued_chars") {
      l.max_queued_chars = static_cast<int>(as_int_in(v, where, 1, 65536));
    } else if (key == "xoff_timeout_s") {
      l.xoff_timeout_s = as_positive(v, where);
    } else if (key == "reconnect_max_s") {
      l.reconnect_max_s = as_positive(v, where);
    } else if (key == "journal") {
      l.journal = as_text(v, where);
    } else if (key == "dialect") {
      const std::string text = as_text(v, where);
      l.dialect = with_where(where, [&] { return comms::parse_dialect(text); });
    } else {
      throw InputError("unknown key " + where +
                       "; [link] takes device, baud, frame, flow, protocol, eob, percent, "
                       "nul_leader, rx_buffer_bytes, max_queued_chars, xoff_timeout_s, "
                       "reconnect_max_s, journal, dialect");
    }
  }
}

void parse_encoder(const toml::value& table, const std::string& name, comms::EncoderSettings& e) {
  for (const auto& [key, v] : table.as_table()) {
    const std::string where = name + ": encoder." + key;
    if (key == "chord_tolerance_mm") {
      e.chord_tolerance_mm = as_real(v, where);
    } else if (key == "feed_band") {
      e.feed_band = as_real(v, where);
    } else if (key == "link_margin") {
      e.link_margin = as_real(v, where);
    } else if (key == "decimals") {
      e.decimals = static_cast<int>(as_int_in(v, where, 0, 6));
    } else if (key == "feed_decimals") {
      e.feed_decimals = static_cast<int>(as_int_in(v, where, 0, 3));
    } else if (key == "time_tolerance_s") {
      e.time_tolerance_s = as_real(v, where);
    } else if (key == "number_start") {
      e.number_start = static_cast<long>(as_int_in(v, where, 0, 99999999));
    } else if (key == "number_step") {
      e.number_step = static_cast<long>(as_int_in(v, where, 1, 1000));
    } else if (key == "max_block_s") {
      e.max_block_s = as_real(v, where);
    } else if (key == "numbers") {
      if (!v.is_boolean()) throw InputError(where + " must be true or false");
      e.numbers_wanted = v.as_boolean();
      e.numbers = v.as_boolean();
    } else if (key == "max_setpoints_per_block") {
      e.max_setpoints_per_block = static_cast<std::size_t>(as_int_in(v, where, 2, 1 << 20));
    } else {
      throw InputError("unknown key " + where +
                       "; [encoder] takes chord_tolerance_mm, feed_band, link_margin, decimals, "
                       "feed_decimals, time_tolerance_s, number_start, number_step, numbers, "
                       "max_setpoints_per_block, max_block_s");
    }
  }
}

// [program]: the RS-274/NGC interpreter's setting (docs/ngc-interpreter.md).
void parse_program(const toml::value& table, const std::string& name,
                   toolpath::InterpretOptions& p) {
  const auto units = [&](const toml::value& v, const std::string& where) {
    const std::string u = as_text(v, where);
    if (u == "mm") return toolpath::Units::mm;
    if (u == "inch") return toolpath::Units::inch;
    throw InputError(where + " = \"" + u + "\" must be \"mm\" or \"inch\"");
  };
  for (const auto& [key, v] : table.as_table()) {
    const std::string where = name + ": program." + key;
    if (key == "default_units") {
      p.default_units = units(v, where);
    } else if (key == "machine_units") {
      p.machine_units = units(v, where);
    } else if (key == "tool_table") {
      p.tool_table = as_text(v, where);
    } else if (key == "parameter_file") {
      p.parameter_file = as_text(v, where);
    } else if (key == "start_mm") {
      // Where the machine stands when a program starts (machine coordinates, mm).
      if (!v.is_array() || v.as_array().size() != 3) {
        throw InputError(where +
                         " must be three numbers, the machine position in mm: "
                         "start_mm = [0.0, 0.0, 50.0]");
      }
      Vec3 at;
      for (std::size_t a = 0; a < 3; ++a) {
        at[static_cast<Eigen::Index>(a)] = as_real(v.as_array()[a], where);
        if (!std::isfinite(at[static_cast<Eigen::Index>(a)]) ||
            std::abs(at[static_cast<Eigen::Index>(a)]) > 1e6) {
          throw InputError(where + " = " + toml::format(v) +
                           " must hold finite positions within ±1e6 mm (1 km)");
        }
      }
      p.start_machine_mm = at;
    } else if (key == "subroutine_path") {
      if (!v.is_array()) throw InputError(where + " must be a list of folders: [\"subs\"]");
      p.subroutine_path.clear();
      for (const auto& d : v.as_array()) p.subroutine_path.push_back(as_text(d, where));
    } else {
      throw InputError("unknown key " + where +
                       "; [program] takes default_units, machine_units, tool_table, "
                       "parameter_file, subroutine_path, start_mm");
    }
  }
}

// [envelope]: x_min_mm … z_max_mm, finite, min < max on every axis.
void parse_envelope(const toml::value& table, const std::string& name, Envelope& e) {
  static const char* const kAxes = "xyz";
  for (const auto& [key, v] : table.as_table()) {
    const std::string where = name + ": envelope." + key;
    bool known = false;
    for (int a = 0; a < 3 && !known; ++a) {
      const std::string axis(1, kAxes[a]);
      for (const bool is_min : {true, false}) {
        if (key != axis + (is_min ? "_min_mm" : "_max_mm")) continue;
        const double x = as_real(v, where);
        if (!std::isfinite(x) || std::abs(x) > 1e6) {
          throw InputError(where + " = " + toml::format(v) +
                           " must be a finite travel within ±1e6 mm (1 km)");
        }
        (is_min ? e.min_mm : e.max_mm)[a] = x;
        known = true;
      }
    }
    if (!known) {
      throw InputError("unknown key " + where +
                       "; [envelope] takes x_min_mm, x_max_mm, y_min_mm, y_max_mm, z_min_mm, "
                       "z_max_mm");
    }
  }
  for (int a = 0; a < 3; ++a) {
    if (!(e.min_mm[a] < e.max_mm[a])) {
      throw InputError(name + ": envelope." + std::string(1, kAxes[a]) +
                       "_min_mm = " + std::to_string(e.min_mm[a]) + " must be below " +
                       std::string(1, kAxes[a]) + "_max_mm = " + std::to_string(e.max_mm[a]));
    }
  }
}

void parse_tool(const toml::value& table, const std::string& name, ToolConfig& t) {
  for (const auto& [key, v] : table.as_table()) {
    const std::string where = name + ": tool." + key;
    if (key == "programmed_point") {
      const std::string p = as_text(v, where);
      if (p == "tip") {
        t.programmed_point = toolpath::ProgramPoint::Tip;
      } else if (p == "centre") {
        t.programmed_point = toolpath::ProgramPoint::Centre;
      } else {
        throw InputError(where + " = \"" + p +
                         "\" is neither \"tip\" (the tool length set to the ball tip) nor "
                         "\"centre\" (set to the ball centre)");
      }
    } else if (key == "number") {
      t.number = static_cast<int>(as_int_in(v, where, 0, 99999));
    } else if (key == "spindle_dwell_s") {
      t.spindle_dwell_s = as_real(v, where);
      checked_range(t.spindle_dwell_s, 0.0, 600.0, where, "s",
                    "give the spin-up time of the spindle, or 0 for no dwell");
    } else {
      throw InputError("unknown key " + where +
                       "; [tool] takes programmed_point, number, spindle_dwell_s");
    }
  }
}

// [tools.N] (docs/feedrate.md §1.5): what the machine file knows of tool N, kind (required),
// teeth and radius_mm; merged with the tool table's comments by toolpath::tool_catalogue.
void parse_tools(const toml::value& table, const std::string& name,
                 std::map<int, toolpath::ToolSpec>& tools) {
  for (const auto& [number, value] : table.as_table()) {
    const std::string where = name + ": tools." + number;
    int n = -1;
    const auto r = std::from_chars(number.data(), number.data() + number.size(), n);
    if (r.ec != std::errc() || r.ptr != number.data() + number.size() || n < 0 || n > 99999) {
      throw InputError(where + ": \"" + number +
                       "\" is not a tool number; write [tools.N] with N the tool's T number "
                       "from 0 to 99999, e.g. [tools.1]");
    }
    if (!value.is_table()) {
      throw InputError(where + " must be a table: [tools." + number + "] kind = \"flat\"");
    }
    toolpath::ToolSpec t;
    t.where = name + " [tools." + number + "]";
    for (const auto& [key, v] : value.as_table()) {
      const std::string kwhere = where + "." + key;
      if (key == "kind") {
        const std::string k = as_text(v, kwhere);
        const auto kind = toolpath::tool_kind_from_text(k);
        if (!kind) {
          throw InputError(kwhere + " = \"" + k + "\" is not a tool kind; use one of " +
                           toolpath::kToolKindsText +
                           " (the roughness law caps ball ends only; docs/feedrate.md 1.5)");
        }
        t.kind = *kind;
      } else if (key == "teeth") {
        t.teeth = as_int(v, kwhere);
      } else if (key == "radius_mm") {
        t.radius_mm = as_real(v, kwhere);
        check(t.radius_mm, ranges::kBallRadiusMm, kwhere);
      } else {
        throw InputError("unknown key " + kwhere + "; [tools.N] takes kind, teeth, radius_mm");
      }
    }
    if (t.kind == toolpath::ToolKind::unknown) {
      throw InputError(where + " has no kind; give kind = one of " + toolpath::kToolKindsText +
                       ", or leave the table out (a tool of no stated kind runs at its "
                       "programmed feed)");
    }
    tools[n] = t;
  }
}

// [axis.a] or [axis.b] (docs/planner.md §3g): the rotary index axis; the table's presence
// declares it, its keys (each with a default) bound its index moves.
void parse_rotary(const std::string& axis, const toml::value& value, const std::string& name,
                  feed::RotaryLimits& r) {
  const std::string table_name = "axis." + axis;
  if (!value.is_table()) {
    throw InputError(name + ": " + table_name + " must be a table: [" + table_name + "]");
  }
  if (r.present()) {
    throw InputError(name +
                     ": [axis.a] and [axis.b] are both given, but ncd drives one rotary index "
                     "axis; keep the table of the axis the machine has (a: about X, b: about Y)");
  }
  r.axis = axis[0];
  for (const auto& entry : value.as_table()) {
    const std::string& key = entry.first;
    const toml::value& v = entry.second;
    const std::string where = name + ": " + table_name + "." + key;
    const auto in_range = [&](const ranges::Range& range) {
      const double x = as_real(v, where);
      checked_range(x, range.lo, range.hi, where, range.unit,
                    "give the rotary axis's limit in that range, or leave the key out for its "
                    "default (config/machine.example.toml)");
      return x;
    };
    if (key == "max_feed_deg_per_min")
      r.max_feed_deg_per_min = in_range(ranges::kRotaryFeedDegPerMin);
    else if (key == "max_accel_deg_per_s2")
      r.max_accel_deg_per_s2 = in_range(ranges::kRotaryAccelDegPerS2);
    else if (key == "max_jerk_deg_per_s3")
      r.max_jerk_deg_per_s3 = in_range(ranges::kRotaryJerkDegPerS3);
    else {
      throw InputError("unknown key " + where + "; [" + table_name +
                       "] takes max_feed_deg_per_min, max_accel_deg_per_s2, max_jerk_deg_per_s3");
    }
  }
}

// [axis.x], [axis.y], [axis.z] (docs/planner.md §3f): each axis's own limits, in the ranges of
// the path's; a key left out leaves the axis bounded by the path limit only. [axis.a] and
// [axis.b]: the rotary index axis (parse_rotary).
void parse_axes(const toml::value& table, const std::string& name, feed::MachineLimits& limits) {
  static constexpr const char* kNames[3] = {"x", "y", "z"};
  std::array<feed::AxisLimits, 3>& axes = limits.axes;
  for (const auto& [axis, value] : table.as_table()) {
    if (axis == "a" || axis == "b") {
      parse_rotary(axis, value, name, limits.rotary);
      continue;
    }
    std::size_t i = 0;
    while (i < 3 && axis != kNames[i]) ++i;
    if (i == 3) {
      throw InputError("unknown table " + name + ": [axis." + axis +
                       "]; the machine file takes [axis.x], [axis.y], [axis.z] and one rotary "
                       "index axis, [axis.a] (about X) or [axis.b] (about Y)");
    }
    const std::string table_name = "axis." + axis;
    if (!value.is_table()) {
      throw InputError(name + ": " + table_name + " must be a table: [" + table_name + "]");
    }
    feed::AxisLimits& ax = axes[i];
    for (const auto& entry : value.as_table()) {
      // (named copies, not a structured binding: clang 14, the fuzz build's, cannot capture one)
      const std::string& key = entry.first;
      const toml::value& v = entry.second;
      const std::string where = name + ": " + table_name + "." + key;
      const auto in_range = [&](const ranges::Range& r) {
        const double x = as_real(v, where);
        checked_range(x, r.lo, r.hi, where, r.unit,
                      "give the axis's limit in that range, or leave the key out: the axis is then "
                      "bounded by the path's " +
                          key + " (the file's top level) only");
        return x;
      };
      if (key == "max_feed_mm_per_min")
        ax.max_feed_mm_per_min = in_range(ranges::kMaxFeedMmPerMin);
      else if (key == "max_accel_mm_per_s2")
        ax.max_accel_mm_per_s2 = in_range(ranges::kMaxAccelMmPerS2);
      else if (key == "max_jerk_mm_per_s3")
        ax.max_jerk_mm_per_s3 = in_range(ranges::kMaxJerkMmPerS3);
      else {
        throw InputError("unknown key " + where + "; [" + table_name +
                         "] takes max_feed_mm_per_min, max_accel_mm_per_s2, max_jerk_mm_per_s3");
      }
    }
  }
}

// A top-level limit of the machine file (period_s, max_feed_mm_per_min, …) into l; false if key
// is not one.
bool parse_top_limit(const std::string& key, const toml::value& value, const std::string& where,
                     feed::MachineLimits& l) {
  double* slot = key == "period_s"              ? &l.period_s
                 : key == "max_feed_mm_per_min" ? &l.max_feed_mm_per_min
                 : key == "max_accel_mm_per_s2" ? &l.max_accel_mm_per_s2
                 : key == "max_jerk_mm_per_s3"  ? &l.max_jerk_mm_per_s3
                 : key == "chord_tolerance_mm"  ? &l.chord_tolerance_mm
                 : key == "feed_tolerance_rel"  ? &l.feed_tolerance_rel
                 : key == "blend_tolerance_mm"  ? &l.blend_tolerance_mm
                 : key == "stall_timeout_s"     ? &l.stall_timeout_s
                                                : nullptr;
  if (slot == nullptr) return false;
  *slot = as_real(value, where);
  return true;
}

// jerk_bound = "tangential", "vector" or "axes" into l; whether it is "axes" (the vector bound
// at the smallest axis jerk, set once the [axis.*] tables are read).
bool parse_jerk_bound(const toml::value& value, const std::string& where, feed::MachineLimits& l) {
  const std::string b = as_text(value, where);
  if (b != "tangential" && b != "vector" && b != "axes") {
    throw InputError(where + " = \"" + b +
                     "\" is not a jerk bound; use \"tangential\" (|j_t| and v^3 kappa^2 "
                     "each <= max_jerk, the default), \"vector\" (the jerk vector <= "
                     "max_jerk; docs/planner.md section 3c) or \"axes\" (the jerk vector <= "
                     "the smallest [axis.*] max_jerk_mm_per_s3: every axis within its jerk; "
                     "section 3f)");
  }
  l.jerk_bound = b == "tangential" ? feed::JerkBound::tangential : feed::JerkBound::vector;
  return b == "axes";
}

// [cutting]: the roughness law's parameters.
void parse_cutting(const toml::value& value, const std::string& name, feed::CuttingParams& k) {
  for (const auto& [ck, cv] : value.as_table()) {
    const std::string cwhere = name + ": cutting." + ck;
    if (ck == "ball_radius_mm")
      k.ball_radius_mm = as_real(cv, cwhere);
    else if (ck == "pick_feed_mm")
      k.pick_feed_mm = as_real(cv, cwhere);
    else if (ck == "teeth")
      k.teeth = as_int(cv, cwhere);
    else if (ck == "spindle_rpm")
      k.spindle_rpm = as_real(cv, cwhere);
    else if (ck == "roughness_target_um")
      k.roughness_target_um = as_real(cv, cwhere);
    else {
      throw InputError("unknown key " + cwhere +
                       "; [cutting] takes ball_radius_mm, pick_feed_mm, teeth, spindle_rpm, "
                       "roughness_target_um");
    }
  }
}

// A table of the machine file other than [cutting] ([link], [program], [encoder], [envelope],
// [axis.*], [tool], [tools.N]) into c; false if key names none.
bool parse_table(const std::string& key, const toml::value& value, const std::string& where,
                 const std::string& name, MachineConfig& c) {
  const auto table = [&](const char* form) {
    if (!value.is_table()) throw InputError(where + " must be " + form);
  };
  if (key == "link") {
    table("a table: [link]");
    parse_link(value, name, c.link);
  } else if (key == "program") {
    table("a table: [program]");
    parse_program(value, name, c.program);
  } else if (key == "encoder") {
    table("a table: [encoder]");
    parse_encoder(value, name, c.encoder);
  } else if (key == "envelope") {
    table("a table: [envelope]");
    parse_envelope(value, name, c.envelope);
  } else if (key == "axis") {
    table("tables: [axis.x], [axis.y], [axis.z], [axis.a] or [axis.b]");
    parse_axes(value, name, c.limits);
  } else if (key == "tool") {
    table("a table: [tool]");
    parse_tool(value, name, c.tool);
  } else if (key == "tools") {
    table("tables: [tools.1], [tools.2], …");
    parse_tools(value, name, c.program.declared_tools);
  } else {
    return false;
  }
  return true;
}

// jerk_bound = "axes": the vector bound at the smallest axis jerk (docs/planner.md §3f), which
// needs an axis jerk.
void apply_jerk_by_axes(MachineConfig& c, const std::string& name) {
  const auto& ax = c.limits.axes;
  if (!std::isfinite(ax[0].max_jerk_mm_per_s3) && !std::isfinite(ax[1].max_jerk_mm_per_s3) &&
      !std::isfinite(ax[2].max_jerk_mm_per_s3)) {
    throw InputError(name +
                     ": jerk_bound = \"axes\" needs max_jerk_mm_per_s3 in an [axis.x], "
                     "[axis.y] or [axis.z] table; give the axes' jerk, or use \"vector\"");
  }
  c.limits = feed::with_axis_jerk(c.limits);
  c.jerk_by_axes = true;
}

// What the file's values imply (the encoder's line and buffer, the machine's tool), then the
// ranges and the libraries' own checks, each error naming the file.
void finish_config(MachineConfig& c, const std::string& name) {
  c.encoder.line = c.link.line;
  c.encoder.rx_buffer_bytes = c.link.rx_buffer_bytes;
  c.program.machine_tools = {c.tool.number};     // the tool the programs ncd writes change to
  c.program.rotary_axis = c.limits.rotary.axis;  // the A or B words the programs may hold
  c.encoder.rotary_axis = c.limits.rotary.axis;
  check_ranges(c, name);
  try {
    feed::validate(c.limits);
    feed::validate(c.cutting);
    comms::validate(c.encoder);
  } catch (const InputError& e) {
    throw InputError(name + ": " + e.what());
  }
}

}  // namespace

MachineConfig parse_machine_config(const std::string& text, const std::string& name) {
  const toml::value root = parse_toml_text(text, name, "machine file");
  MachineConfig c;
  c.source = name;
  bool jerk_by_axes = false;
  for (const auto& [key, value] : root.as_table()) {
    const std::string where = name + ": " + key;
    c.keys.insert(key);
    if (value.is_table()) {
      for (const auto& [sub, v] : value.as_table()) c.keys.insert(key + "." + sub);
    }
    if (parse_top_limit(key, value, where, c.limits)) continue;
    if (key == "jerk_bound") {
      jerk_by_axes = parse_jerk_bound(value, where, c.limits);
    } else if (key == "fit_dense_runs") {
      c.limits.fit_dense_runs = as_bool(value, where);
    } else if (key == "cutting") {
      if (!value.is_table()) throw InputError(where + " must be a table: [cutting]");
      parse_cutting(value, name, c.cutting);
    } else if (!parse_table(key, value, where, name, c)) {
      throw InputError(
          "unknown key " + where +
          "; the machine file takes period_s, max_feed_mm_per_min, "
          "max_accel_mm_per_s2, max_jerk_mm_per_s3, chord_tolerance_mm, "
          "feed_tolerance_rel, blend_tolerance_mm, stall_timeout_s, jerk_bound, fit_dense_runs and "
          "the tables "
          "[cutting], [link], [encoder], [envelope], [program], [tool], [tools.N], [axis.x], "
          "[axis.y], [axis.z], [axis.a] or [axis.b]");
    }
  }
  if (jerk_by_axes) apply_jerk_by_axes(c, name);
  finish_config(c, name);
  return c;
}

namespace {

// A path the machine file names, taken relative to the file's folder (as LinuxCNC takes an INI
// file's TOOL_TABLE), not to the folder the command runs in.
void relative_to(const std::filesystem::path& folder, std::string& path) {
  if (path.empty() || std::filesystem::path(path).is_absolute()) return;
  path = (folder / path).lexically_normal().string();
}

}  // namespace

Vec3 parse_position_mm(const std::string& text, const std::string& what) {
  Vec3 at;
  std::size_t from = 0;
  for (int a = 0; a < 3; ++a) {
    const std::size_t comma = a < 2 ? text.find(',', from) : text.size();
    const std::string part =
        comma == std::string::npos ? std::string() : text.substr(from, comma - from);
    double v = 0.0;
    const char* first = part.data();
    const char* last = part.data() + part.size();
    const auto r = std::from_chars(first, last, v);
    if (comma == std::string::npos || part.empty() || r.ec != std::errc() || r.ptr != last ||
        !std::isfinite(v) || std::abs(v) > 1e6) {
      throw InputError(what + " \"" + text +
                       "\" is not a position: give X,Y,Z in machine mm within ±1e6, e.g. " + what +
                       " 0,0,50");
    }
    at[a] = v;
    from = comma + 1;
  }
  return at;
}

MachineConfig load_machine_config(const std::string& path) {
  MachineConfig c = parse_machine_config(read_input_file(path, "machine file, --machine"), path);
  const std::filesystem::path folder = std::filesystem::path(path).parent_path();
  relative_to(folder, c.program.tool_table);
  relative_to(folder, c.program.parameter_file);
  for (std::string& d : c.program.subroutine_path) relative_to(folder, d);
  return c;
}

nlohmann::ordered_json to_json(const MachineConfig& c) {
  nlohmann::ordered_json j;
  j["source"] = c.source;
  j["period_s"] = c.limits.period_s;
  j["max_feed_mm_per_min"] = c.limits.max_feed_mm_per_min;
  j["max_accel_mm_per_s2"] = c.limits.max_accel_mm_per_s2;
  j["max_jerk_mm_per_s3"] = c.limits.max_jerk_mm_per_s3;
  j["chord_tolerance_mm"] = c.limits.chord_tolerance_mm;
  j["feed_tolerance_rel"] = c.limits.feed_tolerance_rel;
  j["blend_tolerance_mm"] = c.limits.blend_tolerance_mm;
  j["stall_timeout_s"] = c.limits.stall_timeout_s;
  j["jerk_bound"] = c.jerk_by_axes ? "axes" : feed::to_string(c.limits.jerk_bound);
  j["fit_dense_runs"] = c.limits.fit_dense_runs;
  if (c.limits.has_axis_limits()) {  // only when given: without them the JSON is as before
    static constexpr const char* kNames[3] = {"x", "y", "z"};
    nlohmann::ordered_json axes = nlohmann::ordered_json::object();
    for (std::size_t i = 0; i < 3; ++i) {
      const feed::AxisLimits& ax = c.limits.axes[i];
      const auto limit = [](double x) {
        return std::isfinite(x) ? nlohmann::ordered_json(x) : nlohmann::ordered_json(nullptr);
      };
      axes[kNames[i]] = {{"max_feed_mm_per_min", limit(ax.max_feed_mm_per_min)},
                         {"max_accel_mm_per_s2", limit(ax.max_accel_mm_per_s2)},
                         {"max_jerk_mm_per_s3", limit(ax.max_jerk_mm_per_s3)}};
    }
    j["axis"] = axes;
  }
  if (c.limits.rotary.present()) {  // only when declared: without it the JSON is as before
    const feed::RotaryLimits& r = c.limits.rotary;
    j["rotary_axis"] = {{"axis", std::string(1, r.axis)},
                        {"max_feed_deg_per_min", r.max_feed_deg_per_min},
                        {"max_accel_deg_per_s2", r.max_accel_deg_per_s2},
                        {"max_jerk_deg_per_s3", r.max_jerk_deg_per_s3}};
  }
  j["cutting"] = {{"ball_radius_mm", c.cutting.ball_radius_mm},
                  {"pick_feed_mm", c.cutting.pick_feed_mm},
                  {"teeth", c.cutting.teeth},
                  {"spindle_rpm", c.cutting.spindle_rpm},
                  {"roughness_target_um", c.cutting.roughness_target_um}};
  const comms::LineSettings& line = c.link.line;
  j["link"] = {{"device", line.device},
               {"baud", line.baud},
               {"frame", comms::frame_text(line)},
               {"flow", comms::to_string(line.flow)},
               {"protocol", comms::to_string(line.protocol)},
               {"eob", line.eob == comms::EndOfBlock::CrLf ? "crlf" : "lf"},
               {"percent", line.percent_framing},
               {"nul_leader", line.nul_leader},
               {"rx_buffer_bytes", c.link.rx_buffer_bytes},
               {"max_queued_chars", c.link.max_queued_chars},
               {"xoff_timeout_s", c.link.xoff_timeout_s},
               {"reconnect_max_s", c.link.reconnect_max_s},
               {"journal", c.link.journal},
               {"dialect", c.link.dialect ? nlohmann::json(comms::to_string(*c.link.dialect))
                                          : nlohmann::json(nullptr)}};
  j["envelope"] = {{"x_min_mm", c.envelope.min_mm.x()}, {"x_max_mm", c.envelope.max_mm.x()},
                   {"y_min_mm", c.envelope.min_mm.y()}, {"y_max_mm", c.envelope.max_mm.y()},
                   {"z_min_mm", c.envelope.min_mm.z()}, {"z_max_mm", c.envelope.max_mm.z()}};
  const comms::EncoderSettings& e = c.encoder;
  j["encoder"] = {{"chord_tolerance_mm", e.chord_tolerance_mm},
                  {"feed_band", e.feed_band},
                  {"link_margin", e.link_margin},
                  {"decimals", e.decimals},
                  {"feed_decimals", e.feed_decimals},
                  {"time_tolerance_s", e.time_tolerance_s},
                  {"number_start", e.number_start},
                  {"number_step", e.number_step},
                  {"max_setpoints_per_block", e.max_setpoints_per_block},
                  {"max_block_s", e.max_block_s}};
  j["tool"] = {{"programmed_point",
                c.tool.programmed_point == toolpath::ProgramPoint::Tip ? "tip" : "centre"},
               {"number", c.tool.number},
               {"spindle_dwell_s", c.tool.spindle_dwell_s}};
  if (!c.program.declared_tools.empty()) {  // [tools.N], only where the file has any
    nlohmann::ordered_json tools = nlohmann::ordered_json::object();
    for (const auto& [n, t] : c.program.declared_tools) {
      nlohmann::ordered_json entry = {{"kind", toolpath::to_string(t.kind)}};
      if (t.teeth > 0) entry["teeth"] = t.teeth;
      if (t.radius_mm > 0.0) entry["radius_mm"] = t.radius_mm;
      tools[std::to_string(n)] = std::move(entry);
    }
    j["tools"] = std::move(tools);
  }
  const toolpath::InterpretOptions& p = c.program;
  j["program"] = {{"default_units", p.default_units == toolpath::Units::inch ? "inch" : "mm"},
                  {"machine_units", p.machine_units == toolpath::Units::inch ? "inch" : "mm"},
                  {"tool_table", p.tool_table},
                  {"parameter_file", p.parameter_file},
                  {"subroutine_path", p.subroutine_path}};
  if (p.start_machine_mm) {
    const Vec3& at = *p.start_machine_mm;
    j["program"]["start_mm"] = {at.x(), at.y(), at.z()};
  }
  return j;
}

}  // namespace ncd::service
