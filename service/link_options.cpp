// Line flags: one definition for every subcommand that opens a DNC link.
#include "service/link_options.hpp"

#include <sys/stat.h>
#include <sys/sysmacros.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <system_error>

#include "core/error.hpp"

namespace ncd::app {

void add_link_flags(CLI::App& sub, LinkFlags& flags) {
  sub.add_option("--baud", flags.baud, "line speed in baud (300 … 115200)")->capture_default_str();
  sub.add_option("--frame", flags.frame, "data bits, parity, stop bits: 7E2, 8N1, 8E1, …")
      ->capture_default_str();
  sub.add_option("--flow", flags.flow, "flow control: none | xonxoff | rtscts")
      ->capture_default_str();
  sub.add_option("--protocol", flags.protocol,
                 "drip (DC1/DC3 or CTS pacing) | ack (grbl-type ok / error:N per line)")
      ->capture_default_str();
  sub.add_option("--eob", flags.eob, "end of block: lf | crlf")->capture_default_str();
  sub.add_flag("--no-percent", flags.no_percent, "do not frame the program with % lines");
  sub.add_option("--nul-leader", flags.nul_leader, "NUL characters sent before the program")
      ->capture_default_str();
  sub.add_option("--dialect", flags.dialect,
                 "the controller's dialect: iso | grbl | linuxcnc (docs/dnc-link.md, Dialects); "
                 "a program it cannot take is refused before the first byte");
}

std::optional<comms::Dialect> dialect_of(const LinkFlags& flags) {
  if (flags.dialect.empty()) return std::nullopt;
  try {
    return comms::parse_dialect(flags.dialect);
  } catch (const InputError& e) {
    throw InputError(std::string("--dialect: ") + e.what());
  }
}

comms::LineSettings line_settings(const LinkFlags& flags, const std::string& device) {
  comms::LineSettings line;
  line.device = device;
  comms::check_baud(flags.baud);
  line.baud = flags.baud;
  comms::parse_frame(flags.frame, line);
  line.flow = comms::parse_flow(flags.flow);
  line.protocol = comms::parse_protocol(flags.protocol);
  line.eob = comms::parse_eob(flags.eob);
  line.percent_framing = !flags.no_percent;
  if (flags.nul_leader < 0 || flags.nul_leader > 1000) {
    throw InputError("--nul-leader " + std::to_string(flags.nul_leader) +
                     " is out of range: use 0 to 1000 characters");
  }
  line.nul_leader = flags.nul_leader;
  return line;
}

void require_serial_port(const std::string& device, const std::string& what) {
  const std::string named = device + " (" + what + ")";
  struct stat st {};
  if (::stat(device.c_str(), &st) != 0) {
    throw InputError("no such file: " + named + ": " + std::strerror(errno) +
                     "; give the machine's serial port, such as /dev/ttyS0 or /dev/ttyUSB0");
  }
  if (!S_ISCHR(st.st_mode)) {
    const char* kind = S_ISREG(st.st_mode)    ? "a regular file"
                       : S_ISDIR(st.st_mode)  ? "a directory"
                       : S_ISFIFO(st.st_mode) ? "a FIFO"
                                              : "not a device";
    throw InputError(named + " is " + kind +
                     ", not a serial port; give the machine's serial port, such as /dev/ttyS0");
  }
  // Never open the port to ask isatty(): closing it again hangs up a pseudo-terminal's peer, and
  // opening and closing a real serial port toggles DTR, which resets an Arduino running grbl. The
  // kernel tells without an open: Unix98 pty slaves have majors 136-143 (devices.txt), and every
  // other terminal is in sysfs's tty class.
  const unsigned major_number = major(st.st_rdev);
  const bool pty_slave = major_number >= 136 && major_number <= 143;
  std::error_code ec;
  const std::filesystem::path sysfs_class =
      std::filesystem::canonical("/sys/dev/char/" + std::to_string(major_number) + ":" +
                                     std::to_string(minor(st.st_rdev)) + "/subsystem",
                                 ec);
  if (!pty_slave && (ec || sysfs_class.filename() != "tty")) {
    throw InputError(named +
                     " is a character device but not a terminal (tty): not a serial port; "
                     "give the machine's serial port, such as /dev/ttyS0");
  }
}

}  // namespace ncd::app
