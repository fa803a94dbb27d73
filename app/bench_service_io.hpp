// `ncd bench latency --with-service-io` (docs/web-dashboard.md, "What the page and MQTT cost the
// cycle"): the cycle's wake-up lateness in the service, without and with its observers (the
// dashboard's WebSocket and the MQTT bridge), in one run. The design is at the top of
// bench_service_io.cpp.
#pragma once

#include <string>

namespace ncd::app {

struct ServiceIoBenchArgs {
  int seconds = 0;          // each phase
  int rounds = 2;           // each round is one phase without and one with the observers
  double period_ms = 4.0;   // the cycle's period
  double status_hz = 50.0;  // the page's status rate and the MQTT status rate
  std::string broker;       // an MQTT broker URL; empty: the bench starts mosquitto
  std::string json;         // the report as JSON to this file; empty: none
};

// The p99 of the phases with the observers over the p99 of those without may be at most this.
inline constexpr double kServiceIoP99RatioLimit = 1.1;

// Runs the phases, prints the report, writes the JSON. Returns 0, or 1 when setpoints were lost.
// Throws InputError for bad arguments or a broker that cannot be reached or started.
int run_bench_service_io(const ServiceIoBenchArgs& args);

}  // namespace ncd::app
