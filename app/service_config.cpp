// The service config (`ncd serve --config FILE.toml`) on toml11, through the text checks of
// app/toml_text.hpp. Kept apart from the service so that the config fuzz harness
// (tests/fuzz/service_config_fuzz.cpp) links without the service.
#include <cstdlib>
#include <string>
#include <toml.hpp>

#include "app/service_config.hpp"
#include "app/toml_text.hpp"
#include "core/error.hpp"

namespace ncd::app {

std::string default_listen() {
  for (const char* var : {"RUNTIME_DIRECTORY", "XDG_RUNTIME_DIR"}) {
    const char* dir = std::getenv(var);
    // RUNTIME_DIRECTORY may list several directories separated by ':'; the first is ours.
    if (dir && *dir == '/')
      return "unix:" + std::string(dir).substr(0, std::string(dir).find(':')) + "/ncd.sock";
  }
  return "unix:/tmp/ncd.sock";
}

ServiceConfig parse_service_config(const std::string& text, const std::string& path) {
  const toml::value root = parse_toml_text(text, path, "service config");
  ServiceConfig c;
  c.source = path;
  for (const auto& [key, v] : root.as_table()) {
    const std::string where = path + ": " + key;
    if (key == "listen" && v.is_string()) {
      c.listen = v.as_string();
    } else if (key == "token" && v.is_string()) {
      c.token = v.as_string().str;
    } else if (key == "machine" && v.is_string()) {
      c.machine_file = v.as_string();
    } else if (key == "clock" && v.is_string() &&
               (v.as_string() == "wall" || v.as_string() == "simulated")) {
      c.clock = v.as_string() == "wall" ? motion::ClockKind::Wall : motion::ClockKind::Simulated;
    } else if (key == "realtime" && v.is_boolean()) {
      c.realtime = v.as_boolean();
    } else if (key == "live_limits" && v.is_table()) {
      for (const auto& [rule, action] : v.as_table()) {
        service::RuleAction* slot = rule == "feed"    ? &c.live_limits.feed
                                    : rule == "accel" ? &c.live_limits.accel
                                    : rule == "jerk"  ? &c.live_limits.jerk
                                    : rule == "chord" ? &c.live_limits.chord
                                                      : nullptr;
        if (!slot) {
          throw InputError("unknown key " + where + "." + rule +
                           "; [live_limits] takes feed, accel, jerk, chord");
        }
        if (!action.is_string() ||
            (action.as_string() != "error" && action.as_string() != "report")) {
          throw InputError(where + "." + rule + " = " + toml::format(action) +
                           " must be \"error\" (the job ends in error) or \"report\" (counted "
                           "in the status only)");
        }
        *slot = action.as_string() == "error" ? service::RuleAction::Error
                                              : service::RuleAction::Report;
      }
    } else if (key == "listen" || key == "token" || key == "machine" || key == "clock" ||
               key == "realtime" || key == "live_limits") {
      throw InputError(where + " has the wrong type or value: " + toml::format(v) +
                       " (listen, token, machine: strings; clock: \"wall\" or \"simulated\"; "
                       "realtime: true or false; live_limits: a table)");
    } else {
      throw InputError("unknown key " + where +
                       "; the service config takes listen, token, machine, clock, realtime, "
                       "[live_limits]");
    }
  }
  if (!c.machine_file.empty()) c.machine = load_machine_config(c.machine_file);
  return c;
}

}  // namespace ncd::app
