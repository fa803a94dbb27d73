// A clock for the parts of the link that tests run in simulated time: the simulated controller
// (sim/sim_controller.hpp) and the sender's measure of how long the controller holds the line
// (SenderSettings::hold_clock). Null where one is taken: the wall clock (steady_clock).
#pragma once

#include <atomic>

namespace ncd::comms {

class SimClock {
 public:
  virtual ~SimClock() = default;
  virtual double now_s() const = 0;
};

// The time a test moves on by hand; readable from any thread.
class ManualClock : public SimClock {
 public:
  double now_s() const override { return t_s_.load(std::memory_order_acquire); }
  void advance(double dt_s) { t_s_.store(now_s() + dt_s, std::memory_order_release); }

 private:
  std::atomic<double> t_s_{0.0};
};

}  // namespace ncd::comms
