// The service config (`ncd serve --config FILE.toml`) on toml11, through the text checks of
// core/toml_text.hpp: the service's keys here, [http] in http_config.cpp, [mqtt] in
// api/mqtt_config.cpp, all from this one parse. Kept apart from the service so that the config
// fuzz harness (tests/fuzz/service_config_fuzz.cpp) links without the service.
#include <cstdlib>
#include <string>
#include <toml.hpp>

#include "api/control_server.hpp"
#include "api/service_config.hpp"
#include "core/error.hpp"
#include "core/toml_text.hpp"

namespace ncd::api {

std::string default_listen() {
  for (const char* var : {"RUNTIME_DIRECTORY", "XDG_RUNTIME_DIR"}) {
    const char* dir = std::getenv(var);
    // RUNTIME_DIRECTORY may list several directories separated by ':'; the first is ours.
    if (dir && *dir == '/')
      return "unix:" + std::string(dir).substr(0, std::string(dir).find(':')) + "/ncd.sock";
  }
  return "unix:/tmp/ncd.sock";
}

namespace {

const char* kKeys = "listen, token, machine, clock, realtime, [live_limits], [http], [mqtt]";

std::string need_string(const toml::value& v, const std::string& at, const char* what) {
  if (!v.is_string() || v.as_string().str.empty()) {
    throw InputError(at + " = " + toml::format(v) + " must be a non-empty string (" + what +
                     "); quote it, or remove the key");
  }
  return v.as_string().str;
}

}  // namespace

ServiceConfig parse_service_config(const std::string& text, const std::string& path) {
  const toml::value root = parse_toml_text(text, path, "service config");
  ServiceConfig c;
  c.source = path;
  for (const auto& [key, v] : root.as_table()) {
    const std::string at = path + ": " + key;
    if (key == "listen") {
      c.listen = need_string(v, at, "tcp:HOST:PORT or unix:PATH");
      try {
        (void)comms::ListenAddress::parse(c.listen);
      } catch (const InputError& e) {
        throw InputError(at + ": " + e.what());
      }
    } else if (key == "token") {
      c.token = need_string(v, at, "the secret every request must carry");
    } else if (key == "machine") {
      c.machine_file = need_string(v, at, "the machine file");
    } else if (key == "clock") {
      if (!v.is_string() || (v.as_string() != "wall" && v.as_string() != "simulated")) {
        throw InputError(at + " = " + toml::format(v) +
                         " must be \"wall\" (real time) or \"simulated\" (jobs run without "
                         "sleeping); write one of them, or remove the key for \"wall\"");
      }
      c.clock = v.as_string() == "wall" ? motion::ClockKind::Wall : motion::ClockKind::Simulated;
    } else if (key == "realtime") {
      if (!v.is_boolean()) {
        throw InputError(at + " = " + toml::format(v) +
                         " must be true (ask for SCHED_FIFO and locked memory) or false; write "
                         "one of them without quotes");
      }
      c.realtime = v.as_boolean();
    } else if (key == "live_limits") {
      if (!v.is_table()) {
        throw InputError(at + " = " + toml::format(v) +
                         " must be a table, such as [live_limits] feed = \"error\"");
      }
      for (const auto& [rule, action] : v.as_table()) {
        service::RuleAction* slot = rule == "feed"    ? &c.live_limits.feed
                                    : rule == "accel" ? &c.live_limits.accel
                                    : rule == "jerk"  ? &c.live_limits.jerk
                                    : rule == "chord" ? &c.live_limits.chord
                                                      : nullptr;
        if (!slot) {
          throw InputError("unknown key " + at + "." + rule +
                           "; [live_limits] takes feed, accel, jerk, chord");
        }
        if (!action.is_string() ||
            (action.as_string() != "error" && action.as_string() != "report")) {
          throw InputError(at + "." + rule + " = " + toml::format(action) +
                           " must be \"error\" (the job ends in error) or \"report\" (counted "
                           "in the status only)");
        }
        *slot = action.as_string() == "error" ? service::RuleAction::Error
                                              : service::RuleAction::Report;
      }
    } else if (key == "http") {
      c.http = parse_http_config(v, at);
    } else if (key == "mqtt") {
      c.mqtt = api::parse_mqtt_config(v, at);
    } else {
      throw InputError("unknown key " + at + "; the service config takes " + kKeys);
    }
  }
  if (!c.machine_file.empty()) c.machine = service::load_machine_config(c.machine_file);
  return c;
}

}  // namespace ncd::api
