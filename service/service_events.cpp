// The service's names and events: the words of its states, holders, event kinds, ending states
// and limit kinds (as the socket and the logs show them), and the events it logs and pushes to
// each subscriber's bounded ring (service/events.hpp). The service is explained at the top of
// service.cpp.
#include <algorithm>
#include <chrono>
#include <memory>
#include <string>

#include "service/service.hpp"

namespace ncd::service {

const char* to_string(State s) {
  switch (s) {
    case State::Idle:
      return "idle";
    case State::Ready:
      return "ready";
    case State::Running:
      return "running";
    case State::Holding:
      return "holding";
    case State::Streaming:
      return "streaming";
    case State::Done:
      return "done";
    case State::Stopped:
      return "stopped";
    case State::Error:
      return "error";
  }
  return "error";
}

const char* to_string(HoldHolder h) {
  switch (h) {
    case HoldHolder::None:
      return "none";
    case HoldHolder::Operator:
      return "operator";
    case HoldHolder::Link:
      return "link";
  }
  return "none";
}

const char* to_string(EventKind k) {
  switch (k) {
    case EventKind::State:
      return "state";
    case EventKind::Job:
      return "job";
    case EventKind::Alarm:
      return "alarm";
    case EventKind::Overrun:
      return "overrun";
    case EventKind::Link:
      return "link";
    case EventKind::Violation:
      return "violation";
    case EventKind::Override:
      return "override";
  }
  return "state";
}

const char* to_string(EndingStatus::State s) {
  switch (s) {
    case EndingStatus::State::None:
      return "none";
    case EndingStatus::State::Pending:
      return "pending";
    case EndingStatus::State::Sent:
      return "sent";
    case EndingStatus::State::NotSent:
      return "not_sent";
    case EndingStatus::State::NotNeeded:
      return "not_needed";
  }
  return "none";
}

const char* to_string(LimitKind k) {
  switch (k) {
    case LimitKind::None:
      return "none";
    case LimitKind::Feed:
      return "feed";
    case LimitKind::Accel:
      return "accel";
    case LimitKind::Jerk:
      return "jerk";
    case LimitKind::Chord:
      return "chord";
  }
  return "none";
}

const char* unit(LimitKind k) {
  switch (k) {
    case LimitKind::Feed:
      return "mm/min";
    case LimitKind::Accel:
      return "mm/s2";
    case LimitKind::Jerk:
      return "mm/s3";
    case LimitKind::Chord:
    case LimitKind::None:
      return "mm";
  }
  return "mm";
}

void Event::set_text(std::string_view s) {
  const std::size_t n = std::min(s.size(), text.size() - 1);
  std::copy_n(s.data(), n, text.data());
  text[n] = '\0';
}

void Service::log(const std::string& line) const {
  if (options_.log) options_.log(line);
}

std::shared_ptr<Subscription> Service::subscribe(std::size_t capacity) {
  std::size_t pow2 = 2;
  while (pow2 < capacity) pow2 *= 2;
  auto s = std::make_shared<Subscription>(pow2);
  subscribers_.push_back(s);
  return s;
}

void Service::emit(EventKind kind, const std::string& text, double value, double limit,
                   std::int64_t count) {
  Event e;
  e.seq = ++event_seq_;
  e.kind = kind;
  e.state = state_;
  e.holder = holder_;
  e.job_t_s = last_.t_s;
  e.time_unix_s =
      std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  e.value = value;
  e.limit = limit;
  e.count = count;
  e.set_text(text);
  std::erase_if(subscribers_, [](const auto& s) { return s->closed(); });
  for (const auto& s : subscribers_) s->push(e);
}

}  // namespace ncd::service
