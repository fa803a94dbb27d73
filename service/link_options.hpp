// The line flags shared by `ncd stream` and `ncd sim-controller`: --baud, --frame, --flow,
// --protocol, --eob, --no-percent, --nul-leader, --dialect, and --machine FILE, whose [link]
// gives every one of them (docs/cmd-stream.md, "One machine file").
//
// Each value is taken from the first of: its flag, when given on the command line; the machine
// file's [link] key, when the file has it; the command's default. LinkSources makes that choice
// value by value and keeps, for the command to print, which values came from where, and each
// flag that overrode a different value of the file ("--baud 19200 overrides baud = 115200 of
// m.toml [link]"). A [link] key the command has no use for is named, never silently dropped.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <initializer_list>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "gcode/dialect/dialect.hpp"
#include "link/line_settings.hpp"

namespace ncd::service {

struct LinkFlags {
  int baud = 19200;
  std::string frame = "7E2";
  std::string flow = "xonxoff";
  std::string protocol = "drip";
  std::string eob = "lf";
  bool no_percent = false;
  int nul_leader = 0;
  std::string dialect;  // iso | grbl | linuxcnc; empty: none (no dialect check)
  std::string machine;  // --machine FILE: its [link] gives the values no flag gives; empty: none
  std::set<std::string> given;  // the flags given on the command line ("--baud", …)
};

struct MachineConfig;

// Adds the line flags and --machine to a subcommand, with the defaults above.
void add_link_flags(CLI::App& sub, LinkFlags& flags);
// After parsing: records in flags.given which of the line flags and of `more` (the command's
// own flags that a [link] key also gives, e.g. "--port") were on the command line.
void note_given_flags(const CLI::App& sub, LinkFlags& flags,
                      std::initializer_list<const char*> more = {});

// The values of a command's link, chosen flag > machine file [link] > default, and where each
// came from.
class LinkSources {
 public:
  // `machine` null: no --machine (each value from its flag or the default).
  LinkSources(const LinkFlags& flags, const MachineConfig* machine);

  // The value of [link] `key`, given on the command line by `flag` as `flag_value` (its default
  // when not given), in the file as `file_value`; `text` writes a value for the report.
  template <typename T>
  T pick(const std::string& flag, const std::string& key, const T& flag_value, const T& file_value,
         const std::function<std::string(const T&)>& text) {
    const bool by_flag = given(flag);
    const bool in_file = file_has(key);
    if (by_flag && in_file && !(flag_value == file_value)) {
      overrides_.push_back(flag + " " + text(flag_value) + " overrides " + key + " = " +
                           text(file_value) + " of " + file_name() + " [link]");
    }
    const T& v = by_flag ? flag_value : in_file ? file_value : flag_value;
    record(by_flag ? Origin::Flag : in_file ? Origin::File : Origin::Default, key, text(v), flag);
    return v;
  }
  // The line settings (device left empty) and the dialect, each value chosen as above.
  comms::LineSettings line();
  std::optional<comms::Dialect> dialect();
  // A [link] key in the file that this command does not use, and why (e.g. "the sender's").
  void unused(const std::string& key, const std::string& why);

  // The report, a few lines: the values of each origin on one line ("baud 115200, frame 8N1
  // (machine file m.toml [link])", "eob crlf (--eob)", "nul_leader 0 (default)"), then each
  // override, then the keys not used.
  std::vector<std::string> report() const;

 private:
  enum class Origin { Flag, File, Default };
  bool given(const std::string& flag) const;
  bool file_has(const std::string& key) const;
  std::string file_name() const;
  void record(Origin o, const std::string& key, const std::string& value, const std::string& flag);

  const LinkFlags& flags_;
  const MachineConfig* machine_;
  std::vector<std::string> from_file_, from_default_, from_flags_, overrides_, unused_;
};

// Checks the flags and turns them into line settings for `device`; throws InputError.
comms::LineSettings line_settings(const LinkFlags& flags, const std::string& device);
// The controller's dialect given by --dialect (gcode/dialect/dialect.hpp); nullopt when not given.
std::optional<comms::Dialect> dialect_of(const LinkFlags& flags);
// Checks, before any transfer, that device is a terminal (a serial port or a pseudo-terminal):
// a missing file is "no such file" at once (no reconnect attempts), anything else that is not
// a tty (a regular file, /dev/full, a FIFO) is refused. Throws InputError naming the device and
// `what` (the flag or key that gave it).
void require_serial_port(const std::string& device, const std::string& what);

}  // namespace ncd::service
