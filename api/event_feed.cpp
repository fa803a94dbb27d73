// The service's event feed, drained on the io_context (event_feed.hpp, docs/service.md).
#include "api/event_feed.hpp"

#include <chrono>

#include "api/intake.hpp"

namespace ncd::api {

EventFeed::EventFeed(boost::asio::io_context& io, std::shared_ptr<service::Subscription> feed,
                     double period_s)
    : feed_(std::move(feed)), timer_(io), period_s_(period_s) {}

EventFeed::~EventFeed() {
  timer_.cancel();
  feed_->close();
}

void EventFeed::add_sink(Sink sink) {
  sinks_.push_back(std::move(sink));
}

nlohmann::json EventFeed::to_observer_json(const service::Event& event) {
  nlohmann::json j = to_json(event);
  j.erase("seq");
  j["service_seq"] = event.seq;
  return j;
}

void EventFeed::drain() {
  service::Event e;
  while (feed_->pop(e)) {
    const nlohmann::json j = to_observer_json(e);
    for (const Sink& sink : sinks_) sink(j);
  }
}

void EventFeed::start() {
  arm();
}

void EventFeed::close() {
  if (closed_) return;
  drain();
  closed_ = true;
  timer_.cancel();
}

void EventFeed::arm() {
  if (closed_) return;
  timer_.expires_after(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(period_s_)));
  timer_.async_wait([this](const boost::system::error_code& ec) {
    if (ec) return;
    drain();
    arm();
  });
}

}  // namespace ncd::api
