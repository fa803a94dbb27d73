// The service on the shop's MQTT broker: status at a set rate, the state on change, events in
// order with sequence numbers, a last will that marks the machine offline, and commands from a
// command topic through the control socket's own checks (the token). Eclipse Paho C++ is the
// client. Topics, payloads and bounds: docs/fleet-mqtt.md.
//
// Threads. Everything but push_event() runs on the io_context given (the service's I/O
// thread): the status and pump timers, the reconnection timer, the status and command
// callbacks. Paho's own threads only post to that io_context. push_event() is for one producer
// thread (the service's event feed); it never blocks, never waits for the broker: a full queue
// drops the event and counts it.
//
// Bounds. At most queue_bound events wait in the push queue, and at most queue_bound more are
// in flight (published, not yet acknowledged by the broker, kept to be sent again after a
// reconnection). While the broker is away the push queue fills; past its bound events are
// dropped (the newest) and counted: subscribers see the gap in "seq".
#pragma once

#include <boost/asio/io_context.hpp>
#include <cstdint>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "api/mqtt_config.hpp"

namespace ncd::api {

struct BridgeCounters {
  std::uint64_t events_pushed = 0;     // push_event() calls
  std::uint64_t events_dropped = 0;    // refused because the queue was full
  std::uint64_t events_published = 0;  // acknowledged by the broker (QoS 1)
  std::uint64_t events_resent = 0;     // published again after a lost connection
  std::uint64_t status_published = 0;
  std::uint64_t state_published = 0;
  std::uint64_t commands = 0;          // command messages answered
  std::uint64_t connects = 0;          // successful connections
  std::uint64_t connect_failures = 0;  // attempts the broker or the TLS handshake refused
  std::uint64_t connection_losses = 0;
};

class MqttBridge {
 public:
  // The status snapshot (Intake::status()) and the command handler (Intake::handle()), both
  // called on the io_context's thread.
  using StatusFn = std::function<nlohmann::json()>;
  using CommandFn = std::function<nlohmann::json(const nlohmann::json&)>;

  // `token`: the control socket's token; when set, every command must carry it.
  MqttBridge(boost::asio::io_context& io, const MqttConfig& config, StatusFn status,
             CommandFn command, std::optional<std::string> token = {});
  // stop()s.
  ~MqttBridge();
  MqttBridge(const MqttBridge&) = delete;
  MqttBridge& operator=(const MqttBridge&) = delete;

  // Starts connecting (without waiting) and the timers. Call on the io_context's thread or
  // before it runs.
  void start();
  // Publishes the machine offline, disconnects, stops the timers. Waits at most timeout_s for
  // the broker (a shutdown only). Idempotent.
  void stop(double timeout_s = 2.0);

  // Queues one event (a JSON object; "seq" is added, counting from 1 for every call, so a drop
  // leaves a gap). Never blocks; false when the queue is full (the event is dropped, counted).
  bool push_event(nlohmann::json event);

  BridgeCounters counters() const;
  bool connected() const;
  // Why the last connection attempt failed ("" before any failure): Paho's return code and,
  // with TLS, the TLS library's last error of that attempt (an unknown CA, a certificate the
  // broker requires and did not get, ...). Also written to the log (standard error).
  std::string last_failure() const;

  struct Core;

 private:
  std::shared_ptr<Core> core_;
};

}  // namespace ncd::api
