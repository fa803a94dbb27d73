// The sending thread's real-time scheduling: link/thread_priority.hpp.
#include "link/thread_priority.hpp"

#include <cstring>

namespace ncd::comms {

FifoPriority::FifoPriority(int priority) {
  if (priority <= 0) {
    description_ = "normal scheduling (not requested)";
    return;
  }
  const std::string wanted = "SCHED_FIFO " + std::to_string(priority);
  if (const int rc = pthread_getschedparam(pthread_self(), &old_policy_, &old_param_); rc != 0) {
    description_ = "normal scheduling (" + wanted + " not tried: " + std::strerror(rc) + ")";
    return;
  }
  sched_param p{};
  p.sched_priority = priority;
  if (const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p); rc != 0) {
    description_ = "normal scheduling (" + wanted + " refused: " + std::strerror(rc) + ")";
    return;
  }
  raised_ = true;
  description_ = wanted;
}

FifoPriority::~FifoPriority() {
  if (raised_) pthread_setschedparam(pthread_self(), old_policy_, &old_param_);
}

}  // namespace ncd::comms
