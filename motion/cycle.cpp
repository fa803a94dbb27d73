// The cycle thread (docs/architecture.md, "Threads of the service", thread 2; docs/planner.md §5
// for its watchdog).
//
//   deadline d_k = d_0 + k T (absolute CLOCK_MONOTONIC)
//
//   ──┬──────────┬──────────┬──────────┬───────────────┬──────────┬──► wall time
//    d_1        d_2        d_3        d_4             d_5        d_6
//     ▲ wake     ▲ wake     ▲ wake       ▲ late wake    ▲ wake
//     step       step       step         step d_4, d_5  step d_6     (catch up: back to back)
//
// Each wake-up sleeps with clock_nanosleep(TIMER_ABSTIME) until the next deadline, measures how
// late it woke (the lateness histogram; also kept bin by bin in relaxed atomics, the status's
// live view), and runs every period that is due by then, one job
// step each. A late wake-up therefore runs the periods it missed back to back: the time base
// never stretches and no setpoint is skipped (each period is one setpoint, its t_s = k T). On
// the simulated clock there is no sleeping at all; otherwise the code is the same.
//
// Inside a period: read the command flags (hold, resume, override, stop: atomics written by the
// I/O thread), step the job (look-ahead sampling incrementally, planner, walker), push the
// setpoint into the lock-free ring, publish the status through a seqlock. No locks, no I/O;
// the planner's first look-ahead window is filled before the thread starts, so the sampling
// inside the cycle is a few intervals per period. Stop is a feed hold followed by the end of
// the job once the motion is at rest.
//
// No-progress watchdog: while the job runs (not held, not stopping, override above 0 %), its
// arc length must advance by more than kProgressMm within the machine's stall_timeout_s.
// Otherwise the cycle ends in state Error with a message naming the position and the limit in
// force. It guards against defects of the planner and is never expected to fire (docs/planner.md).
#include "motion/cycle.hpp"

#include <fcntl.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>

namespace ncd::motion {
namespace {

std::int64_t now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// Progress the watchdog asks for within stall_timeout_s: 0.1 µm (a feed below 3e-3 mm/min).
constexpr double kProgressMm = 1e-4;

void sleep_until_ns(std::int64_t deadline_ns) {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(deadline_ns / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(deadline_ns % 1'000'000'000);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

}  // namespace

Cycle::Cycle(std::unique_ptr<Job> job, const CycleOptions& options)
    : job_(std::move(job)), options_(options), ring_(options.ring_capacity) {
  job_->prepare();  // the first look-ahead window, outside the cycle
  // Until the first period, the status shows where the path starts (not the origin).
  const Vec3 start = job_->walker().position();
  st_x_.store(start.x(), std::memory_order_relaxed);
  st_y_.store(start.y(), std::memory_order_relaxed);
  st_z_.store(start.z(), std::memory_order_relaxed);
}

Cycle::~Cycle() {
  stop_req_.store(true, std::memory_order_release);
  abort_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
  if (cpu_latency_fd_ >= 0) close(cpu_latency_fd_);  // ends the PM QoS request
}

RealtimeGrant Cycle::start() {
  RealtimeGrant g;
  std::string why;
  if (options_.realtime && options_.clock == ClockKind::Wall) {
    if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) {
      g.memory_locked = true;
    } else {
      why += std::string(" mlockall: ") + std::strerror(errno) + ";";
    }
    // Keep the CPUs out of deep idle states while the cycle lives, as cyclictest does: a
    // wake-up from C6 costs tens of microseconds (the kernel's PM QoS interface).
    cpu_latency_fd_ = open("/dev/cpu_dma_latency", O_WRONLY | O_CLOEXEC);
    const std::int32_t zero_us = 0;
    if (cpu_latency_fd_ >= 0 &&
        write(cpu_latency_fd_, &zero_us, sizeof zero_us) == sizeof zero_us) {
      g.cpu_latency_held = true;
    } else {
      why += std::string(" /dev/cpu_dma_latency: ") + std::strerror(errno) + ";";
    }
  }
  thread_ = std::thread(&Cycle::run, this);
  if (options_.realtime && options_.clock == ClockKind::Wall) {
    sched_param p{};
    p.sched_priority = options_.fifo_priority;
    const int rc = pthread_setschedparam(thread_.native_handle(), SCHED_FIFO, &p);
    if (rc == 0) {
      g.fifo = true;
    } else {
      why += std::string(" SCHED_FIFO: ") + std::strerror(rc) + ";";
    }
  }
  if (options_.clock == ClockKind::Simulated) {
    g.message = "cycle on the simulated clock (no sleeping, no real-time scheduling needed)";
  } else if (!options_.realtime) {
    g.message = "cycle on the wall clock, real-time scheduling not requested";
  } else {
    g.message =
        std::string("cycle on the wall clock: SCHED_FIFO ") +
        (g.fifo ? "granted (priority " + std::to_string(options_.fifo_priority) + ")" : "refused") +
        ", memory " + (g.memory_locked ? "locked" : "not locked") + ", CPU idle latency " +
        (g.cpu_latency_held ? "held at 0 us" : "not held") +
        (why.empty() ? ""
                     : " (" + why.substr(1) +
                           " run as root or give the process "
                           "CAP_SYS_NICE and CAP_IPC_LOCK)");
  }
  grant_ = g;
  return g;
}

void Cycle::hold() {
  hold_req_.store(true, std::memory_order_release);
}
void Cycle::resume() {
  resume_req_.store(true, std::memory_order_release);
}
void Cycle::stop() {
  stop_req_.store(true, std::memory_order_release);
}
void Cycle::set_override(double fraction) {
  override_req_.store(fraction, std::memory_order_release);
}

void Cycle::join() {
  if (thread_.joinable()) thread_.join();
}

// Seqlock without fences: the fields are atomics stored with release and loaded with acquire,
// so a reader that sees any field of a newer write also sees the odd sequence number of that
// write when it reads seq_ again, and retries (Boehm, "Can seqlocks get along with programming
// language memory models?", 2012). On x86 these are plain moves.
void Cycle::publish(const Setpoint& sp, CycleState state) {
  constexpr auto rel = std::memory_order_release;
  const std::uint64_t s = seq_.load(std::memory_order_relaxed);
  seq_.store(s + 1, std::memory_order_relaxed);
  st_t_.store(sp.t_s, rel);
  st_s_.store(sp.s_mm, rel);
  st_v_.store(sp.v_mm_per_s, rel);
  st_x_.store(sp.p.x(), rel);
  st_y_.store(sp.p.y(), rel);
  st_z_.store(sp.p.z(), rel);
  st_ovr_.store(override_applied_, rel);
  st_state_.store(static_cast<int>(state), rel);
  st_periods_.store(stats_.periods, rel);
  st_overruns_.store(stats_.overruns, rel);
  st_late_.store(stats_.late_wakeups, rel);
  seq_.store(s + 2, rel);
}

Cycle::LatenessBins Cycle::lateness_bins() const {
  LatenessBins out{};
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i] = late_bins_[i].load(std::memory_order_relaxed);
  }
  return out;
}

CycleStatus Cycle::status() const {
  constexpr auto acq = std::memory_order_acquire;
  CycleStatus c;
  for (;;) {
    const std::uint64_t s0 = seq_.load(acq);
    if (s0 & 1U) continue;
    c.t_s = st_t_.load(acq);
    c.s_mm = st_s_.load(acq);
    c.v_mm_per_s = st_v_.load(acq);
    c.x_mm = st_x_.load(acq);
    c.y_mm = st_y_.load(acq);
    c.z_mm = st_z_.load(acq);
    c.override_fraction = st_ovr_.load(acq);
    c.state = static_cast<CycleState>(st_state_.load(acq));
    c.periods = st_periods_.load(acq);
    c.overruns = st_overruns_.load(acq);
    c.late_wakeups = st_late_.load(acq);
    if (seq_.load(std::memory_order_relaxed) == s0) return c;
  }
}

bool Cycle::run_period(CycleState& state) {
  Planner& planner = job_->planner();
  if (stop_req_.exchange(false, std::memory_order_acq_rel) && !stopping_) {
    planner.hold();
    stopping_ = true;
  }
  if (hold_req_.exchange(false, std::memory_order_acq_rel) && !stopping_) {
    planner.hold();
    state = CycleState::Holding;
  }
  if (resume_req_.exchange(false, std::memory_order_acq_rel) && !stopping_) {
    planner.resume();
    state = CycleState::Running;
  }
  const double ovr = override_req_.exchange(-1.0, std::memory_order_acq_rel);
  if (ovr >= 0.0) {
    job_->set_override(ovr);
    override_applied_ = ovr;
  }
  job_->prepare();
  const Setpoint sp = job_->step();
  if (sp.fault != StepFault::None) {
    state = CycleState::Error;  // the step rule: not emitted; run() reports it
    return false;
  }
  ++stats_.periods;
  if (options_.clock == ClockKind::Simulated && options_.block_when_full) {
    while (!ring_.push(sp)) {
      if (abort_.load(std::memory_order_acquire)) return false;
      std::this_thread::yield();  // the consumer is behind: simulated time can wait
    }
  } else if (!ring_.push(sp)) {
    ++stats_.setpoints_lost;
  }
  const bool at_rest = sp.v_mm_per_s == 0.0 && sp.a_mm_per_s2 == 0.0;
  if (sp.done) state = CycleState::Done;
  if (stopping_ && at_rest) state = CycleState::Stopped;
  if (state == CycleState::Running && !stopping_ && override_applied_ > 0.0 &&
      sp.s_mm <= watch_s_mm_ + kProgressMm) {
    const auto& limits = job_->config().limits;
    if (static_cast<double>(++watch_periods_) * limits.period_s >= limits.stall_timeout_s) {
      const interpolator::FeedLimitResult here = job_->limit_here();
      error_ = "no progress for " + std::to_string(limits.stall_timeout_s) +
               " s (stall_timeout_s) at s = " + std::to_string(sp.s_mm) + " of " +
               std::to_string(job_->length_mm()) + " mm, X" + std::to_string(sp.p.x()) + " Y" +
               std::to_string(sp.p.y()) + " Z" + std::to_string(sp.p.z()) +
               ", v = " + std::to_string(sp.v_mm_per_s) +
               " mm/s; limit in force: " + limit_name(sp.limit_id) + " (" +
               interpolator::to_string(here.limit) + " " + std::to_string(here.feed_mm_per_s) +
               " mm/s here): the motion was stopped (an internal error; please report it with "
               "the program)";
      publish(sp, CycleState::Error);
      return false;
    }
  } else {
    watch_s_mm_ = sp.s_mm;
    watch_periods_ = 0;
  }
  publish(sp, state);
  return state != CycleState::Done && state != CycleState::Stopped;
}

void Cycle::run() {
  CycleState state = CycleState::Running;
  try {
    const bool wall = options_.clock == ClockKind::Wall;
    const auto period_ns =
        static_cast<std::int64_t>(std::llround(job_->config().limits.period_s * 1e9));
    std::int64_t deadline = now_ns() + period_ns;
    bool running = true;
    while (running && !abort_.load(std::memory_order_acquire)) {
      if (wall) sleep_until_ns(deadline);
      const std::int64_t woke = wall ? now_ns() : deadline;
      const std::int64_t late = std::max<std::int64_t>(0, woke - deadline);
      stats_.lateness_ns.add(static_cast<double>(late));
      {  // the status's histogram: one writer (this thread), so a relaxed load and store
        std::atomic<std::int64_t>& bin = late_bins_[static_cast<std::size_t>(
            LogHistogram::coarse_of(LogHistogram::bucket_of(static_cast<double>(late))))];
        bin.store(bin.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
      }
      const std::int64_t due = 1 + late / period_ns;
      if (due > 1) ++stats_.late_wakeups;
      const std::int64_t t0 = now_ns();
      std::int64_t ran = 0;  // fewer than due when the job ends during a catch-up
      for (; ran < due && running; ++ran) running = run_period(state);
      // Every period run is counted once: at its wake-up, or as caught up (periods = wake-ups +
      // caught_up, exactly, also when the job ends in the middle of a catch-up).
      stats_.caught_up += ran - 1;
      const std::int64_t work = now_ns() - t0;
      stats_.compute_ns.add(static_cast<double>(work) / static_cast<double>(ran));
      if (work > ran * period_ns) ++stats_.overruns;
      deadline += due * period_ns;
    }
    if (job_->fault().fault != StepFault::None) {
      error_ = job_->fault_message();
      st_state_.store(static_cast<int>(state), std::memory_order_release);
    }
  } catch (const std::exception& e) {
    error_ = e.what();
    state = CycleState::Error;
    st_state_.store(static_cast<int>(state), std::memory_order_release);
  } catch (...) {  // nothing may leave the thread
    error_ = "unknown exception in the cycle";
    state = CycleState::Error;
    st_state_.store(static_cast<int>(state), std::memory_order_release);
  }
  finished_.store(true, std::memory_order_release);
}

}  // namespace ncd::motion
