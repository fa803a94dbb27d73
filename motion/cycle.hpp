// The cycle: one thread per running job that wakes every period and runs one period of the
// job, against the wall clock (the service) or a simulated clock (tests, a simulated service);
// on the simulated clock it may also run on its owner's thread, one period per run_here()
// (`ncd replay`). The algorithm is explained in cycle.cpp.
#pragma once

#include <array>
#include <atomic>
#include <boost/lockfree/spsc_queue.hpp>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>

#include "core/histogram.hpp"
#include "motion/job.hpp"

namespace ncd::motion {

enum class ClockKind { Wall, Simulated };

struct CycleOptions {
  ClockKind clock = ClockKind::Wall;
  bool realtime = true;              // ask for SCHED_FIFO and locked memory (logged if refused)
  int fifo_priority = 80;            // SCHED_FIFO priority when granted
  std::size_t ring_capacity = 8192;  // setpoints the consumer may lag behind (32 s at 4 ms)
  bool block_when_full = true;       // simulated clock only: wait for the consumer, never drop
  // false (simulated clock only): start() starts no thread; the owner runs each period with
  // run_here() and pops its setpoint before the next (a full ring then loses, never waits).
  bool own_thread = true;
};

// What one period cost, ns: the look-ahead sampling (Job::prepare) and the planner step and
// path walk (Job::step). Measured only on the owner's thread (CycleOptions::own_thread false).
struct PeriodTimes {
  std::int64_t prepare_ns = 0, step_ns = 0;
};

// What the cycle measured; read it after the thread has stopped, or as a snapshot.
struct CycleStats {
  LogHistogram lateness_ns;          // wake-up time minus its deadline, every wake-up
  LogHistogram compute_ns;           // work per period
  std::int64_t periods = 0;          // periods run (each gives one setpoint)
  std::int64_t late_wakeups = 0;     // wake-ups more than one period late
  std::int64_t caught_up = 0;        // periods run back to back to catch up
  std::int64_t overruns = 0;         // periods whose work alone took longer than a period
  std::int64_t setpoints_lost = 0;   // setpoint ring full on the wall clock (must stay 0)
  std::int64_t first_window_ns = 0;  // the constructor's filling of the first look-ahead window
};

// What the cycle got from the operating system when it started.
struct RealtimeGrant {
  bool fifo = false;
  bool memory_locked = false;
  bool cpu_latency_held = false;  // /dev/cpu_dma_latency held at 0 µs (no deep C-states)
  std::string message;  // one line for the log: what was asked, what was granted, and why not
};

enum class CycleState : int { Running, Holding, Done, Stopped, Error };

// Published by the cycle once per period for status readers (lock-free snapshot).
struct CycleStatus {
  CycleState state = CycleState::Running;
  double t_s = 0.0, s_mm = 0.0, v_mm_per_s = 0.0;
  double x_mm = 0.0, y_mm = 0.0, z_mm = 0.0;
  double override_fraction = 1.0;
  std::int64_t periods = 0, overruns = 0, late_wakeups = 0;
};

class Cycle {
 public:
  // Takes the job (already constructed); fills the planner's first look-ahead window here,
  // outside the cycle. Does not start the thread.
  Cycle(std::unique_ptr<Job> job, const CycleOptions& options);
  ~Cycle();  // requests stop and joins
  Cycle(const Cycle&) = delete;
  Cycle& operator=(const Cycle&) = delete;

  // Starts the cycle thread (none without own_thread); returns what real-time scheduling it
  // got. Throws InputError for own_thread false on the wall clock.
  RealtimeGrant start();
  // Without own_thread, after start(): runs the next period here, exactly as the thread would
  // (commands, look-ahead, step, ring, status, watchdog, statistics). Returns false once the
  // job has ended (finished(); that period's setpoint, if any, is in the ring). An exception of
  // the job's (an InputError of the look-ahead) ends the cycle in Error and is rethrown.
  bool run_here();
  // The last period's times (run_here() only).
  const PeriodTimes& last_times() const { return times_; }
  // Commands, read by the cycle at its next period (atomic flags, no locks).
  void hold();
  void resume();
  // 0..2, applied through the planner at the next period; throws InputError outside that.
  void set_override(double fraction);
  void stop();  // a jerk-limited stop on the path, then the end
  // Blocks until the job is done or stopped (the thread has ended).
  void join();
  bool finished() const { return finished_.load(std::memory_order_acquire); }

  // The consumer side of the setpoint ring (one consumer thread only).
  bool pop(Setpoint& out) { return ring_.pop(out); }
  CycleStatus status() const;
  // The wake-up lateness histogram so far, in ns, on LogHistogram's coarse buckets
  // (LogHistogram::coarse_from); read while the cycle runs (relaxed atomics, one writer), it
  // lags by at most the wake-up being counted. After join() it equals stats().lateness_ns
  // regrouped.
  using LatenessBins = std::array<std::int64_t, LogHistogram::kCoarseBuckets>;
  LatenessBins lateness_bins() const;
  // Valid after join().
  const CycleStats& stats() const { return stats_; }
  // Why the run ended in error, in words (empty if it did not); read after finished().
  std::string error() const;
  double length_mm() const { return job_->length_mm(); }
  const Job& job() const { return *job_; }

 private:
  void run();
  void publish(const Setpoint& sp, CycleState state);
  bool run_period(CycleState& state);
  void count_wakeup(std::int64_t late_ns);
  void count_work(std::int64_t work_ns, std::int64_t ran);
  void end_run();
  void fail_run(const char* what, CycleState& state);

  std::unique_ptr<Job> job_;
  CycleOptions options_;
  boost::lockfree::spsc_queue<Setpoint> ring_;  // one producer, one consumer, no allocation
  std::thread thread_;
  CycleStats stats_;
  std::string error_;  // an exception that escaped a period (none should)
  struct Stall {
    bool seen = false;
    Setpoint at;  // the setpoint where no progress was seen for stall_timeout_s
  } stall_;
  RealtimeGrant grant_;
  // Commands.
  std::atomic<bool> hold_req_{false}, resume_req_{false}, stop_req_{false};
  std::atomic<double> override_req_{-1.0};
  std::atomic<bool> finished_{false};
  std::atomic<bool> abort_{false};  // the destructor: leave at once, even mid-hold
  int cpu_latency_fd_ = -1;         // held open while the cycle lives (PM QoS request)
  bool stopping_ = false;
  double override_applied_ = 1.0;
  std::int64_t period_ns_ = 0;
  CycleState here_state_ = CycleState::Running;  // run_here()'s state between periods
  PeriodTimes times_;
  // No-progress watchdog: s at the last progress, and the periods since.
  double watch_s_mm_ = 0.0;
  std::int64_t watch_periods_ = 0;
  // Status snapshot (seqlock: odd while written).
  mutable std::atomic<std::uint64_t> seq_{0};
  std::atomic<double> st_t_{0}, st_s_{0}, st_v_{0}, st_x_{0}, st_y_{0}, st_z_{0}, st_ovr_{1};
  std::atomic<int> st_state_{0};
  std::atomic<std::int64_t> st_periods_{0}, st_overruns_{0}, st_late_{0};
  std::array<std::atomic<std::int64_t>, LogHistogram::kCoarseBuckets> late_bins_{};
};

}  // namespace ncd::motion
