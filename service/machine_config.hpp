// The machine file of `ncd replay` and `ncd serve` (TOML): period, limits, tolerances, the
// cutting parameters, the DNC link ([link]) and the block encoder ([encoder]). Every key has a
// default and a unit in its name; an unknown key is an error that names it.
// config/machine.example.toml lists them all.
#pragma once

#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <string>

#include "cam/chamfer_ngc.hpp"
#include "core/geometry.hpp"
#include "feed/feed_limits.hpp"
#include "feed/roughness.hpp"
#include "gcode/dialect/dialect.hpp"
#include "gcode/ngc/interpreter.hpp"
#include "link/block_encoder.hpp"
#include "link/line_settings.hpp"

namespace ncd::service {

// [link]: the machine's DNC port and how the sender treats it.
struct LinkConfig {
  comms::LineSettings line;       // device, baud, frame, flow, protocol, eob, percent, nul_leader
  int rx_buffer_bytes = 256;      // the controller's receive buffer
  int max_queued_chars = 16;      // at most this many bytes in the kernel's output queue
  double xoff_timeout_s = 5.0;    // XOFF longer than this holds the motion and is reported
  double reconnect_max_s = 30.0;  // how long the sender tries to reopen a lost port, then gives up
  std::string journal;            // transfer journal file; empty: none
  std::optional<comms::Dialect> dialect;  // the controller's dialect (gcode/dialect/dialect.hpp)
  // The keys the file gave (the rest hold their defaults), for the commands that say where each
  // value came from (service/link_options.hpp, LinkSources).
  std::set<std::string> keys;
  bool has(const std::string& key) const { return keys.count(key) > 0; }
};

// [envelope]: the machine's travel per axis, mm, in the frame of the programs it runs. Every
// point of a path must lie inside before any motion starts (docs/hardening.md). The defaults
// (±2000 mm) are wider than most machining centres: set the machine's own.
struct Envelope {
  static constexpr double kDefaultTravelMm = 2000.0;
  Vec3 min_mm = Vec3::Constant(-kDefaultTravelMm);
  Vec3 max_mm = Vec3::Constant(kDefaultTravelMm);
};

// [tool]: the cutter in the spindle as the programs ncd writes address it (docs/whole-program.md).
struct ToolConfig {
  // What every program ncd writes drives: the ball tip (the tool length set to the tip, the
  // default) or the ball centre. The chamfer NGC, the --blocks program and the whole job agree.
  toolpath::ProgramPoint programmed_point = toolpath::ProgramPoint::Tip;
  int number = 1;                // T word of the tool change and H word of its length offset
  double spindle_dwell_s = 0.0;  // G4 after M3 for the spindle to reach its speed; 0: none
};

struct MachineConfig {
  feed::MachineLimits limits;
  // jerk_bound = "axes": limits hold with_axis_jerk's vector bound (echoed as "axes").
  bool jerk_by_axes = false;
  feed::CuttingParams cutting;
  LinkConfig link;
  Envelope envelope;
  ToolConfig tool;
  // [encoder]; its line and rx_buffer_bytes are copies of [link]'s, set by the parser.
  comms::EncoderSettings encoder;
  // [program]: how RS-274/NGC programs are read (default_units, machine_units, tool_table,
  // parameter_file, subroutine_path); see docs/ngc-interpreter.md.
  // Its machine_tools hold [tool] number (the tool every program ncd writes changes to).
  toolpath::InterpretOptions program = [] {
    toolpath::InterpretOptions o;
    o.machine_tools = {ToolConfig{}.number};
    return o;
  }();
  std::string source = "defaults";  // the file it was read from
  // The keys the file gave, tables' as "table.key" ("program.start_mm"), for the commands that
  // say where each value came from.
  std::set<std::string> keys;
  bool has(const std::string& key) const { return keys.count(key) > 0; }
};

// Reads and validates a machine file; throws InputError naming the file, the key and the value.
MachineConfig load_machine_config(const std::string& path);

// A machine position "X,Y,Z" in mm, as a flag gives it (`what` names the flag in messages).
// Throws InputError naming the text, the form and an example.
Vec3 parse_position_mm(const std::string& text, const std::string& what);

// The same on TOML text already in memory; `name` stands for the file in messages.
MachineConfig parse_machine_config(const std::string& text, const std::string& name);

// Echo of every field, units in the names, for reports.
nlohmann::ordered_json to_json(const MachineConfig& config);

}  // namespace ncd::service
