// The simulated controller on its own thread in simulated time, for a live sender in the same
// process (tests/service/live_link_test.cpp, tests/app/serve_whole_job_test.cpp). Its clock is a
// ManualClock that the test moves on. The sender, though, paces its writes by a model of the
// wire on the wall clock (link/dnc_drip.cpp; only its timing of the controller's holds takes
// a clock, SenderSettings::hold_clock), so:
//   - the controller's time is never let fall behind the wall clock: each step moves it on by
//     dt, or to the wall time elapsed if that is later, in increments of dt (a loaded machine
//     makes a step longer, and the line never carries more than the sender's model allows);
//   - drip: before each step the test waits until the sender has read everything the controller
//     wrote (FIONREAD on the controller's port is 0), so a DC3 is seen before time moves on. Not
//     for ack (grbl): its character counting needs no such wait, and the extra descriptor on the
//     port would count as a sender that never leaves (the controller waits for it before it
//     exits at the program end) and, with reset_on_open, reset the controller.
#pragma once

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <thread>

#include "sim/sim_controller.hpp"

namespace ncd::test {

class PacedController {
 public:
  // Creates the controller's pseudo-terminal at config.line.device; config.clock is replaced by
  // the controller's own ManualClock.
  void start(comms::SimControllerConfig config) {
    config.clock = clock_;
    sim_ = std::make_unique<comms::SimController>(config);
    t0_ = clock_->now_s();
    wall0_ = std::chrono::steady_clock::now();
    // A descriptor on the controller's port that never reads: FIONREAD on it is what the sender
    // has not read yet.
    if (config.line.protocol != comms::Protocol::Ack) {
      port_fd_ = ::open(config.line.device.c_str(), O_RDONLY | O_NOCTTY | O_NONBLOCK);
      ASSERT_GE(port_fd_, 0) << config.line.device;
    }
    thread_ = std::thread([this] {
      sim_->run();
      done_ = true;
    });
  }
  ~PacedController() { stop(); }

  // Moves the controller's time on by dt_s, or to the wall time elapsed if that is later. A
  // later wall time is caught up in increments of dt_s, each run by the controller's loop after
  // the sender has read what it wrote, so that a controller's DC3 never outlasts, in its time,
  // the drain that ends it because the test's thread was kept from running.
  void step(double dt_s) {
    const double wall_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0_).count();
    const double to_s = std::max(now_s() + dt_s, wall_s);
    while (!done_ && now_s() < to_s - 1e-12 && !::testing::Test::HasFatalFailure()) {
      increment(std::min(dt_s, to_s - now_s()));
    }
  }

  // Whether the sender still reads the line (it does until it has finished): once it has not,
  // what the controller writes after (a DC1 as its buffer drains) stays unread, and steps no
  // longer wait for it. Unset: the sender reads until the controller is done.
  void while_sender_reads(std::function<bool()> reading) { sender_reading_ = std::move(reading); }

  // run() has returned (exit_at_end: the program end executed and the line quiet).
  bool done() const { return done_; }
  comms::SimController& sim() { return *sim_; }
  // The controller's time, for a sender that times the controller's holds on it
  // (SenderSettings::hold_clock).
  std::shared_ptr<const comms::SimClock> clock() const { return clock_; }
  // Stops the controller and joins its thread; its log is complete after this.
  void stop() {
    if (port_fd_ >= 0) {
      ::close(port_fd_);
      port_fd_ = -1;
    }
    if (thread_.joinable()) {
      sim_->request_stop();
      thread_.join();
    }
  }
  const comms::SimLog& log() const { return sim_->log(); }

 private:
  double now_s() const { return clock_->now_s() - t0_; }

  // One increment: waits until the sender has read everything the controller wrote, moves the
  // controller's time on by dt_s and waits until its loop has run at the new time.
  void increment(double dt_s) {
    using namespace std::chrono_literals;
    const auto until = std::chrono::steady_clock::now() + 60s;
    for (int unread = 1; port_fd_ >= 0 && !done_ && (!sender_reading_ || sender_reading_());) {
      // A link cut (SimFaults) hangs the old pty up: nothing on it is left for the sender.
      if (::ioctl(port_fd_, FIONREAD, &unread) != 0) break;
      if (unread == 0) break;
      ASSERT_LT(std::chrono::steady_clock::now(), until) << "the sender stopped reading";
      std::this_thread::sleep_for(100us);
    }
    clock_->advance(dt_s);
    sim_->wake();  // else the loop sees the new time only when its wait (1 ms of wall time) ends
    const double target = now_s();
    while (!done_ && sim_->progress().t_s < target - 1e-12) {
      ASSERT_LT(std::chrono::steady_clock::now(), until) << "the controller's loop is stuck";
      std::this_thread::sleep_for(100us);
    }
  }

  std::shared_ptr<comms::ManualClock> clock_ = std::make_shared<comms::ManualClock>();
  std::unique_ptr<comms::SimController> sim_;
  std::thread thread_;
  std::atomic<bool> done_{false};
  std::function<bool()> sender_reading_;
  double t0_ = 0.0;
  int port_fd_ = -1;
  std::chrono::steady_clock::time_point wall0_;
};

}  // namespace ncd::test
