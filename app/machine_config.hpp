// The machine file of `ncd replay` and `ncd serve` (TOML): period, limits, tolerances and the
// cutting parameters. Every key has a default and a unit in its name; an unknown key is an
// error that names it. config/machine.example.toml lists them all.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "interpolator/feed_limits.hpp"
#include "interpolator/roughness.hpp"

namespace ncd::app {

struct MachineConfig {
  interpolator::MachineLimits limits;
  interpolator::CuttingParams cutting;
  std::string source = "defaults";  // the file it was read from
};

// Reads and validates a machine file; throws InputError naming the file, the key and the value.
MachineConfig load_machine_config(const std::string& path);

// The same on TOML text already in memory; `name` stands for the file in messages.
MachineConfig parse_machine_config(const std::string& text, const std::string& name);

// Echo of every field, units in the names, for reports.
nlohmann::ordered_json to_json(const MachineConfig& config);

}  // namespace ncd::app
