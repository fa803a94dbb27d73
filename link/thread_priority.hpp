// Real-time scheduling for the calling thread while an object lives (docs/dnc-link.md,
// "Priority"). A drip-feed controller sends DC3 with a few tens of milliseconds of buffer left:
// a sender a loaded host keeps off the CPU for longer writes into a full buffer. SCHED_FIFO
// (below the simulated controller's 70 and the cycle's 80) keeps the wake-up on a DC3 prompt.
// Refused (no CAP_SYS_NICE, no RLIMIT_RTPRIO), the thread stays as it was and the description
// says why. The former policy is restored when the object goes.
#pragma once

#include <pthread.h>
#include <sched.h>

#include <string>

namespace ncd::comms {

class FifoPriority {
 public:
  // priority 1..99; 0 leaves the thread's scheduling as it is.
  explicit FifoPriority(int priority);
  ~FifoPriority();
  FifoPriority(const FifoPriority&) = delete;
  FifoPriority& operator=(const FifoPriority&) = delete;

  bool raised() const { return raised_; }
  // "SCHED_FIFO 60", "normal scheduling (SCHED_FIFO 60 refused: Operation not permitted)" or
  // "normal scheduling (not requested)".
  const std::string& description() const { return description_; }

 private:
  bool raised_ = false;
  int old_policy_ = SCHED_OTHER;
  sched_param old_param_{};
  std::string description_;
};

}  // namespace ncd::comms
