// The service config (`ncd serve --config FILE.toml`): every key optional. One parser reads the
// whole file, the dashboard's [http] and the fleet's [mqtt] tables included; every error names
// the file, the key (table.key), the value, the limit and a way out (docs/service.md,
// "Configuration").
#pragma once

#include <optional>
#include <string>

#include "api/http_config.hpp"
#include "api/mqtt_config.hpp"
#include "motion/cycle.hpp"
#include "service/live_limits.hpp"
#include "service/machine_config.hpp"

namespace ncd::api {

// The default control endpoint: unix:DIR/ncd.sock in the runtime directory, DIR =
// $RUNTIME_DIRECTORY (systemd's RuntimeDirectory=), else $XDG_RUNTIME_DIR, else /tmp. The socket
// is made with mode 0660: its owner and group may drive the machine, nobody else.
std::string default_listen();

// What the live limit rules do when broken (service/live_limits.hpp): [live_limits] feed,
// accel, jerk, chord = "error" (the default: the job ends in error) or "report" (counted in the
// status only).
struct LiveLimitActions {
  service::RuleAction feed = service::RuleAction::Error, accel = service::RuleAction::Error,
                      jerk = service::RuleAction::Error, chord = service::RuleAction::Error;
};

struct ServiceConfig {
  std::string listen = default_listen();  // TCP on loopback by config; elsewhere a token
  std::optional<std::string> token;       // required on every request when set
  std::string machine_file;               // machine TOML; empty: the documented defaults
  service::MachineConfig machine;         // loaded from machine_file
  motion::ClockKind clock = motion::ClockKind::Wall;  // "simulated": run jobs without sleeping
  bool realtime = true;                               // ask for SCHED_FIFO and locked memory
  LiveLimitActions live_limits;
  HttpConfig http;                 // [http]: the web dashboard (docs/web-dashboard.md)
  std::optional<MqttConfig> mqtt;  // [mqtt]: the fleet's broker (docs/fleet-mqtt.md)
  std::string source = "defaults";
};

// Throws InputError naming the file, the key and the value.
ServiceConfig load_service_config(const std::string& path);
// The same on TOML text already in memory; `name` stands for the file in messages.
ServiceConfig parse_service_config(const std::string& text, const std::string& name);

}  // namespace ncd::api
