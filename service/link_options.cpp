// Line flags: one definition for every subcommand that opens a DNC link.
#include "service/link_options.hpp"

#include <sys/stat.h>
#include <sys/sysmacros.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <system_error>

#include "core/error.hpp"
#include "service/machine_config.hpp"

namespace ncd::service {

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
  sub.add_option("--machine", flags.machine,
                 "machine file (TOML): its [link] gives the port and every line setting no flag "
                 "gives (a flag wins over the file and says so)");
}

void note_given_flags(const CLI::App& sub, LinkFlags& flags,
                      std::initializer_list<const char*> more) {
  static const char* const kLineFlags[] = {"--baud", "--frame",      "--flow",       "--protocol",
                                           "--eob",  "--no-percent", "--nul-leader", "--dialect"};
  flags.given.clear();
  for (const char* f : kLineFlags) {
    if (sub.count(f) > 0) flags.given.insert(f);
  }
  for (const char* f : more) {
    if (sub.count(f) > 0) flags.given.insert(f);
  }
}

LinkSources::LinkSources(const LinkFlags& flags, const MachineConfig* machine)
    : flags_(flags), machine_(machine) {}

bool LinkSources::given(const std::string& flag) const {
  return flags_.given.count(flag) > 0;
}

bool LinkSources::file_has(const std::string& key) const {
  return machine_ != nullptr && machine_->link.has(key);
}

std::string LinkSources::file_name() const {
  return machine_ ? machine_->source : "";
}

void LinkSources::record(Origin o, const std::string& key, const std::string& value,
                         const std::string& flag) {
  switch (o) {
    case Origin::Flag:
      from_flags_.push_back(key + " " + value + " (" + flag + ")");
      break;
    case Origin::File:
      from_file_.push_back(key + " " + value);
      break;
    case Origin::Default:
      from_default_.push_back(key + " " + value);
      break;
  }
}

void LinkSources::unused(const std::string& key, const std::string& why) {
  if (file_has(key)) unused_.push_back("link." + key + " (" + why + ")");
}

namespace {

std::string join(const std::vector<std::string>& parts) {
  std::string out;
  for (const std::string& p : parts) out += (out.empty() ? "" : ", ") + p;
  return out;
}

std::string eob_name(comms::EndOfBlock e) {
  return e == comms::EndOfBlock::CrLf ? "crlf" : "lf";
}

}  // namespace

comms::LineSettings LinkSources::line() {
  // The flags' own line, checked as before; the file's was checked when it was read.
  const comms::LineSettings by_flags = line_settings(flags_, "");
  const comms::LineSettings in_file = machine_ ? machine_->link.line : comms::LineSettings{};
  comms::LineSettings line = by_flags;
  const auto number = [](const int& v) { return std::to_string(v); };
  const auto word = [](const std::string& v) { return v; };
  line.baud = pick<int>("--baud", "baud", by_flags.baud, in_file.baud, number);
  const std::string frame = pick<std::string>("--frame", "frame", comms::frame_text(by_flags),
                                              comms::frame_text(in_file), word);
  comms::parse_frame(frame, line);
  line.flow = comms::parse_flow(pick<std::string>("--flow", "flow", comms::to_string(by_flags.flow),
                                                  comms::to_string(in_file.flow), word));
  line.protocol = comms::parse_protocol(
      pick<std::string>("--protocol", "protocol", comms::to_string(by_flags.protocol),
                        comms::to_string(in_file.protocol), word));
  line.eob = comms::parse_eob(
      pick<std::string>("--eob", "eob", eob_name(by_flags.eob), eob_name(in_file.eob), word));
  line.percent_framing =
      pick<bool>("--no-percent", "percent", by_flags.percent_framing, in_file.percent_framing,
                 [](const bool& v) { return std::string(v ? "true" : "false"); });
  line.nul_leader =
      pick<int>("--nul-leader", "nul_leader", by_flags.nul_leader, in_file.nul_leader, number);
  return line;
}

std::optional<comms::Dialect> LinkSources::dialect() {
  const std::optional<comms::Dialect> by_flag = dialect_of(flags_);
  const std::optional<comms::Dialect> in_file =
      machine_ ? machine_->link.dialect : std::optional<comms::Dialect>{};
  return pick<std::optional<comms::Dialect>>(
      "--dialect", "dialect", by_flag, in_file, [](const std::optional<comms::Dialect>& d) {
        return d ? comms::to_string(*d) : std::string("none");
      });
}

std::vector<std::string> LinkSources::report() const {
  std::vector<std::string> out;
  if (!from_file_.empty()) {
    out.push_back(join(from_file_) + " (machine file " + file_name() + " [link])");
  }
  if (!from_flags_.empty()) out.push_back(join(from_flags_));
  if (!from_default_.empty()) {
    out.push_back(join(from_default_) + " (default" +
                  (machine_ ? ": not in " + file_name() + " [link] nor given as a flag)" : ")"));
  }
  for (const std::string& o : overrides_) out.push_back(o);
  if (!unused_.empty()) {
    out.push_back("not used by this command: " + join(unused_));
  }
  return out;
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

}  // namespace ncd::service
