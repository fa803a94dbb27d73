// The line flags shared by `ncd stream` and `ncd sim-controller`: --baud, --frame, --flow,
// --protocol, --eob, --no-percent, --nul-leader.
#pragma once

#include <CLI/CLI.hpp>
#include <optional>
#include <string>

#include "gcode/dialect/dialect.hpp"
#include "link/line_settings.hpp"

namespace ncd::app {

struct LinkFlags {
  int baud = 19200;
  std::string frame = "7E2";
  std::string flow = "xonxoff";
  std::string protocol = "drip";
  std::string eob = "lf";
  bool no_percent = false;
  int nul_leader = 0;
  std::string dialect;  // iso | grbl | linuxcnc; empty: none (no dialect check)
};

// Adds the line flags to a subcommand, with the defaults above.
void add_link_flags(CLI::App& sub, LinkFlags& flags);
// Checks the flags and turns them into line settings for `device`; throws InputError.
comms::LineSettings line_settings(const LinkFlags& flags, const std::string& device);
// The controller's dialect given by --dialect (gcode/dialect/dialect.hpp); nullopt when not given.
std::optional<comms::Dialect> dialect_of(const LinkFlags& flags);
// Checks, before any transfer, that device is a terminal (a serial port or a pseudo-terminal):
// a missing file is "no such file" at once (no reconnect attempts), anything else that is not
// a tty (a regular file, /dev/full, a FIFO) is refused. Throws InputError naming the device and
// `what` (the flag or key that gave it).
void require_serial_port(const std::string& device, const std::string& what);

}  // namespace ncd::app
