// The service's observer events to `ncd serve`'s observers (docs/service.md, "Observers"): one
// subscription to the service library's event feed, drained on the io_context by a timer every
// period_s, each event turned into JSON (api::to_json(Event), units in the names) and handed to
// every sink in order: the MQTT bridge's push_event (docs/fleet-mqtt.md) and the web dashboard
// (docs/web-dashboard.md). The service's loop writes the feed on the same io_context thread,
// never waiting: a feed that is not drained fills and drops (counted, "events_dropped" in the
// status; a gap in "service_seq").
#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <vector>

#include "service/events.hpp"

namespace ncd::api {

class EventFeed {
 public:
  using Sink = std::function<void(const nlohmann::json&)>;
  // The subscription's ring: events that may wait between two drains (a power of two).
  static constexpr std::size_t kCapacity = 1024;

  EventFeed(boost::asio::io_context& io, std::shared_ptr<service::Subscription> feed,
            double period_s = 0.02);
  ~EventFeed();  // closes the subscription
  EventFeed(const EventFeed&) = delete;
  EventFeed& operator=(const EventFeed&) = delete;

  void add_sink(Sink sink);
  // Arms the timer (on the io_context's thread, or before it runs).
  void start();
  // Hands every event waiting to the sinks now.
  void drain();
  // Drains once more, then stops the timer. Idempotent.
  void close();

  // An event as the observers see it: api::to_json(Event) with the service's own sequence
  // number as "service_seq" ("seq" is the bridge's, docs/fleet-mqtt.md).
  static nlohmann::json to_observer_json(const service::Event& event);

 private:
  void arm();

  std::shared_ptr<service::Subscription> feed_;
  boost::asio::steady_timer timer_;
  double period_s_;
  std::vector<Sink> sinks_;
  bool closed_ = false;
};

}  // namespace ncd::api
