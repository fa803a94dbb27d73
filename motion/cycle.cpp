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
// On the owner's thread (CycleOptions::own_thread false, simulated clock only: `ncd replay`
// through the service library), run_here() is one wake-up of the same loop with one period due:
// the same period, counted the same way, with the look-ahead and the step timed apart for the
// owner's report. The owner pops each setpoint before the next period, while the job stands
// where that setpoint left it (Job::limit_here is then that setpoint's).
//
// No-progress watchdog: while the job runs (not held, not stopping, override above 0 %), its
// arc length must advance by more than kProgressMm within the machine's stall_timeout_s.
// A period of a rotary index (Setpoint::indexing) is progress too, of the rotary axis.
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

#include "core/error.hpp"

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
  const std::int64_t t0 = now_ns();
  // The first look-ahead window, outside the cycle: a path the look-ahead cannot take is
  // refused here, at the job's start.
  if (!job_->prepare()) throw InputError(job_->fault_message());
  stats_.first_window_ns = now_ns() - t0;
  period_ns_ = static_cast<std::int64_t>(std::llround(job_->config().limits.period_s * 1e9));
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
  if (!options_.own_thread) {
    if (options_.clock != ClockKind::Simulated) {
      throw InputError("cycle: only the simulated clock runs on its owner's thread");
    }
    g.message = "cycle on the simulated clock, on the owner's thread (no sleeping)";
    grant_ = g;
    return g;
  }
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
  if (!(fraction >= 0.0 && fraction <= 2.0)) {  // checked here: the period takes it as it is
    throw InputError("feed override = " + std::to_string(fraction) +
                     " is invalid: it must be between 0 (0 %) and 2 (200 %)");
  }
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
  if (ovr >= 0.0 && job_->set_override(ovr)) override_applied_ = ovr;
  Setpoint sp;
  if (options_.own_thread) {
    job_->prepare();
    sp = job_->step();
  } else {
    const std::int64_t t0 = now_ns();
    job_->prepare();
    const std::int64_t t1 = now_ns();
    sp = job_->step();
    times_ = {t1 - t0, now_ns() - t1};
  }
  if (sp.fault != StepFault::None) {
    state = CycleState::Error;  // the step rule: not emitted; run() reports it
    return false;
  }
  ++stats_.periods;
  if (options_.clock == ClockKind::Simulated && options_.block_when_full && options_.own_thread) {
    while (!ring_.push(sp)) {
      if (abort_.load(std::memory_order_acquire)) return false;
      std::this_thread::yield();  // the consumer is behind: simulated time can wait
    }
  } else if (!ring_.push(sp)) {
    ++stats_.setpoints_lost;
  }
  // A rotary index is not at rest until it lands (a stop waits for it, as for any move).
  const bool at_rest = sp.v_mm_per_s == 0.0 && sp.a_mm_per_s2 == 0.0 && !sp.indexing;
  if (sp.done) state = CycleState::Done;
  if (stopping_ && at_rest) state = CycleState::Stopped;
  if (state == CycleState::Running && !stopping_ && override_applied_ > 0.0 &&
      sp.s_mm <= watch_s_mm_ + kProgressMm && !sp.indexing) {
    const auto& limits = job_->config().limits;
    if (static_cast<double>(++watch_periods_) * limits.period_s >= limits.stall_timeout_s) {
      stall_ = Stall{true, sp};  // worded by error(), outside the period
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

void Cycle::count_wakeup(std::int64_t late_ns) {
  stats_.lateness_ns.add(static_cast<double>(late_ns));
  // The status's histogram: one writer (the cycle), so a relaxed load and store.
  std::atomic<std::int64_t>& bin = late_bins_[static_cast<std::size_t>(
      LogHistogram::coarse_of(LogHistogram::bucket_of(static_cast<double>(late_ns))))];
  bin.store(bin.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
}

// Every period run is counted once: at its wake-up, or as caught up (periods = wake-ups +
// caught_up, exactly, also when the job ends in the middle of a catch-up).
void Cycle::count_work(std::int64_t work_ns, std::int64_t ran) {
  stats_.caught_up += ran - 1;
  stats_.compute_ns.add(static_cast<double>(work_ns) / static_cast<double>(ran));
  if (work_ns > ran * period_ns_) ++stats_.overruns;
}

void Cycle::end_run() {
  if (job_->fault().fault != StepFault::None) {
    st_state_.store(static_cast<int>(CycleState::Error), std::memory_order_release);
  }
}

// The words for what ended the run in error, made here (by the owner, after the run), not in
// the period that found it: a stall, the job's fault, or an exception that escaped a period.
std::string Cycle::error() const {
  if (stall_.seen) {
    const Setpoint& sp = stall_.at;
    const auto& limits = job_->config().limits;
    const feed::FeedLimitResult here = job_->limit_here();
    return "no progress for " + std::to_string(limits.stall_timeout_s) +
           " s (stall_timeout_s) at s = " + std::to_string(sp.s_mm) + " of " +
           std::to_string(job_->length_mm()) + " mm, X" + std::to_string(sp.p.x()) + " Y" +
           std::to_string(sp.p.y()) + " Z" + std::to_string(sp.p.z()) +
           ", v = " + std::to_string(sp.v_mm_per_s) +
           " mm/s; limit in force: " + limit_name(sp.limit_id) + " (" +
           feed::to_string(here.limit) + " " + std::to_string(here.feed_mm_per_s) +
           " mm/s here): the motion was stopped (an internal error; please report it with the "
           "program)";
  }
  if (job_->fault().fault != StepFault::None) return job_->fault_message();
  return error_;
}

void Cycle::fail_run(const char* what, CycleState& state) {
  error_ = what;
  state = CycleState::Error;
  st_state_.store(static_cast<int>(state), std::memory_order_release);
}

void Cycle::run() {
  CycleState state = CycleState::Running;
  try {
    const bool wall = options_.clock == ClockKind::Wall;
    std::int64_t deadline = now_ns() + period_ns_;
    bool running = true;
    while (running && !abort_.load(std::memory_order_acquire)) {
      if (wall) sleep_until_ns(deadline);
      const std::int64_t woke = wall ? now_ns() : deadline;
      const std::int64_t late = std::max<std::int64_t>(0, woke - deadline);
      count_wakeup(late);
      const std::int64_t due = 1 + late / period_ns_;
      if (due > 1) ++stats_.late_wakeups;
      const std::int64_t t0 = now_ns();
      std::int64_t ran = 0;  // fewer than due when the job ends during a catch-up
      for (; ran < due && running; ++ran) running = run_period(state);
      count_work(now_ns() - t0, ran);
      deadline += due * period_ns_;
    }
    end_run();
  } catch (const std::exception& e) {
    fail_run(e.what(), state);
  } catch (...) {  // nothing may leave the thread
    fail_run("unknown exception in the cycle", state);
  }
  finished_.store(true, std::memory_order_release);
}

bool Cycle::run_here() {
  if (options_.own_thread) throw InputError("cycle: run_here() needs own_thread = false");
  if (finished()) return false;
  bool running = false;
  try {
    count_wakeup(0);  // the simulated clock: every wake-up on time, one period due
    running = run_period(here_state_);
    count_work(times_.prepare_ns + times_.step_ns, 1);
    if (!running) end_run();
  } catch (const std::exception& e) {
    fail_run(e.what(), here_state_);
    finished_.store(true, std::memory_order_release);
    throw;
  }
  if (!running) finished_.store(true, std::memory_order_release);
  return running;
}

}  // namespace ncd::motion
