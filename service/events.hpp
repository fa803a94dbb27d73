// The observers' view of the service (docs/service.md, "Observers"): a bounded event feed and
// the status snapshot (service.hpp). The web dashboard and the MQTT publisher each subscribe and
// read their feed on their own thread; the service's loop writes it. A push never blocks and
// never allocates: when a subscriber lags and its ring is full, the event is dropped and
// counted, and the subscriber sees the count (dropped()) and the gap in the sequence numbers.
#pragma once

#include <array>
#include <atomic>
#include <boost/lockfree/spsc_queue.hpp>
#include <cstdint>
#include <memory>
#include <string_view>

namespace ncd::service {

// The states of a job (service.cpp has the picture of their transitions).
enum class State : std::uint8_t { Idle, Ready, Running, Holding, Streaming, Done, Stopped, Error };
// Who holds the motion. Only the holder's release resumes it (service.cpp).
enum class HoldHolder : std::uint8_t { None, Operator, Link };

// "idle", "ready", …; "none", "operator", "link".
const char* to_string(State state);
const char* to_string(HoldHolder holder);

enum class EventKind : std::uint8_t {
  State,      // the state changed: state, holder; text: why (hold, stop, error)
  Job,        // a job event: text "submitted", "started", "ended", "restart from line N"
  Alarm,      // the job ended in error: text is the reason
  Overrun,    // the cycle overran: count = overruns so far, value = late wake-ups so far
  Link,       // a sender event (port opened, lost, XOFF, …): text
  Violation,  // a live limit was exceeded: text names it, value = measured, limit = allowed
  Override,   // the operator set the feed override: value = the new percent, limit = the old
};
const char* to_string(EventKind kind);

// One event: plain data, copied through the ring (no allocation).
struct Event {
  std::uint64_t seq = 0;  // 1, 2, 3 … per service; a gap means dropped events
  EventKind kind = EventKind::State;
  State state = State::Idle;  // the state after the event
  HoldHolder holder = HoldHolder::None;
  double job_t_s = 0.0;          // the job's motion time at the event, s (0 before it starts)
  double time_unix_s = 0.0;      // the wall clock at the event (system clock), s since 1970
  std::int64_t count = 0;        // Overrun: overruns so far
  double value = 0.0;            // Overrun: late wake-ups so far; Violation: the measured value
  double limit = 0.0;            // Violation: what the rule allows
  std::array<char, 200> text{};  // NUL-terminated, truncated to fit

  std::string_view message() const { return std::string_view(text.data()); }
  void set_text(std::string_view s);
};

// One subscriber's feed: the service pushes (its loop's thread), the subscriber pops (its own).
class Subscription {
 public:
  explicit Subscription(std::size_t capacity) : ring_(capacity) {}
  // Subscriber side.
  bool pop(Event& out) { return ring_.pop(out); }
  std::uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }
  // The subscriber leaves; the service forgets it at its next push.
  void close() { closed_.store(true, std::memory_order_release); }
  bool closed() const { return closed_.load(std::memory_order_acquire); }
  // Service side: never blocks; a full ring drops the event and counts it.
  void push(const Event& e) {
    if (!ring_.push(e)) dropped_.fetch_add(1, std::memory_order_relaxed);
  }

 private:
  boost::lockfree::spsc_queue<Event> ring_;  // one producer, one consumer, no allocation
  std::atomic<std::uint64_t> dropped_{0};
  std::atomic<bool> closed_{false};
};

}  // namespace ncd::service
