// The service's job state machine and its live pipeline (docs/service.md).
//
//              submit            start                 hold(operator | link)
//   idle ─────────────► ready ─────────► running ───────────────────────► holding
//    │                  ▲  │ submit       │   ▲   resume(by the holder)      │
//    │                  │  └──(replaces)  │   └──────────────────────────────┘
//    │                  │                 │ the motion ends: done; stop: stopped (a jerk-limited
//    │                  │                 │ stop on the path, from running or holding); the step
//    │                  │                 │ rule, a live limit rule or a fault: error
//    │                  │                 ▼
//    │                  │        a link? ──yes──► streaming ──the sender ends──┐
//    │                  │                 │ no     (motion over, blocks still  │
//    │                  │                 ▼         going to the controller)   │
//    └──── submit ──── done / stopped / error ◄───────────────────────────────┘
//
// `ncd replay` (the cycle on the owner's thread, below) goes idle → ready → running → done or
// error, with no link and no hold.
//
// submit is refused while running, holding or streaming. A hold has one holder: the operator
// (a client's hold) or the link (the sender saw XOFF or CTS held longer than xoff_timeout_s, or
// lost its port). Only the holder releases it: the link's release does not resume a motion the
// operator holds, and an operator's hold during a link hold takes it over (the operator must
// resume). A resume by anyone else is refused naming the holder. `stopped` is kept apart from
// `done` (a job that did not reach its end) and tells why and where it stopped.
//
// Without a cycle thread (ServiceOptions::cycle_thread false, the simulated clock: `ncd replay`),
// poll() runs the periods itself (motion::Cycle::run_here), each setpoint drained at once, so that
// a sink sees the job as that setpoint left it; the states and transitions are the same.
//
// Threads: the commands, poll() and status() run on the owner's thread; the service's own state
// needs no lock. The cycle thread is reached only through its atomic commands, its setpoint ring
// and its seqlocked status; the sender's thread through the live block queue, one atomic for its
// holds, its live counters (relaxed atomics) and a mutex-guarded list of its events (neither
// side is the cycle). poll() drains the
// setpoints in order into: the live limit check (service/live_limits.hpp; a setpoint breaking an
// Error rule is not emitted and the job ends in error), the statistics, the setpoint sink, the
// block encoder, whose closed blocks queue for the sender. Observers get events through their
// own bounded rings (service/events.hpp).
//
// Ending early (a stop, a shutdown, a job error, a refused block, an exception, a lost link):
// service_ending.cpp says how the machine is left. The streamed job's link: service_stream.cpp;
// the names and events: service_events.cpp.
#include "service/service.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <thread>

#include "core/error.hpp"
#include "core/number_text.hpp"
#include "gcode/dialect/dialect.hpp"
#include "link/live_blocks.hpp"
#include "link/program_blocks.hpp"
#include "link/transfer_journal.hpp"
#include "service/service_live.hpp"

namespace ncd::service {

// How far into a queued block its move is looked up, mm (Service::controller_view).
constexpr double kBlockStartProbeMm = 1e-4;

Service::Service(const ServiceOptions& options) : options_(options) {
  if (!options_.cycle_thread && options_.clock != motion::ClockKind::Simulated) {
    throw InputError("service: only the simulated clock runs without a cycle thread");
  }
}

Service::~Service() {
  if (cycle_) {
    cycle_->stop();
    cycle_.reset();  // joins
  }
  if (live_) {
    live_->blocks.close();
    live_.reset();  // stops and joins the sender
  }
}

void Service::set_state(State s, HoldHolder holder, const std::string& why) {
  if (s == state_ && holder == holder_) return;
  state_ = s;
  holder_ = holder;
  emit(EventKind::State, why);
}

void Service::require_active(const char* cmd) const {
  if (state_ != State::Running && state_ != State::Holding) {
    throw InputError(std::string(cmd) + ": no job is running (state " + to_string(state_) + ")");
  }
}

bool Service::busy() const {
  return state_ == State::Running || state_ == State::Holding || state_ == State::Streaming;
}

void Service::submit(JobSpec job) {
  if (busy()) throw InputError("submit: a job is running; stop it first");
  if (!job.path) throw InputError("submit: the job has no path");
  // Build the job now, so that a path the machine cannot run is refused at submit; start() runs
  // this one (a long path is not built twice).
  auto built = std::make_unique<motion::Job>(*job.path, job.motion);
  CommandedTable modal;
  if (job.program) modal = CommandedTable(*job.program);
  cycle_.reset();
  live_.reset();
  job_ = std::move(job);
  built_ = std::move(built);
  modal_ = std::move(modal);
  error_.clear();
  set_state(State::Ready, HoldHolder::None, "submitted");
  emit(EventKind::Job, "submitted " + job_.name);
}

const std::string& Service::start() {
  if (state_ != State::Ready) {
    throw InputError(std::string("start: nothing to start (state ") + to_string(state_) +
                     "); submit a job first");
  }
  // A start that threw (the first look-ahead window) leaves the state ready: build it again.
  std::unique_ptr<motion::Job> job =
      built_ ? std::move(built_) : std::make_unique<motion::Job>(*job_.path, job_.motion);
  live_.reset();
  start_mm_ = job->walker().position();
  stop_why_.clear();
  moving_s_ = 0.0;
  held_time_left_s_.reset();
  setpoints_ = 0;
  accel_max_ = jerk_max_ = feed_max_ = 0.0;
  override_percent_ = preset_override_percent_;  // 100 % unless preset
  overruns_seen_ = 0;
  ending_ = {};
  append_pending_ = false;
  alarmed_ = false;
  last_ = {};
  last_.p = start_mm_;
  limits_.emplace(job_.rules);
  if (job_.link) start_stream(*job);
  motion::CycleOptions o;
  o.clock = options_.clock;
  o.realtime = options_.realtime;
  o.ring_capacity = options_.ring_capacity;
  o.own_thread = options_.cycle_thread;
  cycle_ = std::make_unique<motion::Cycle>(std::move(job), o);
  cycle_->set_override(override_percent_ / 100.0);  // a preset: from the first period on
  limits_->set_override(override_percent_ / 100.0);
  realtime_ = cycle_->start().message;
  log("job " + job_.name + " started; " + realtime_);
  preset_override_percent_ = 100.0;  // used: the next job starts at 100 % unless preset again
  set_state(State::Running, HoldHolder::None, "started");
  emit(EventKind::Job,
       job_.restart ? "started " + job_.name + " from line " + std::to_string(job_.restart->line)
                    : "started " + job_.name);
  return realtime_;
}

void Service::hold(HoldHolder by) {
  require_active("hold");
  if (by == HoldHolder::None) throw InputError("hold: a hold needs a holder");
  if (state_ != State::Holding) held_time_left_s_ = time_left_s();
  cycle_->hold();
  if (live_) live_->sender->set_source_held(true);  // the controller waits: no underrun
  set_state(State::Holding, by, std::string("held by the ") + to_string(by));
}

void Service::resume(HoldHolder by) {
  require_active("resume");
  if (state_ == State::Holding && holder_ != by) {
    throw InputError(std::string("resume: the motion is held by the ") + to_string(holder_) +
                     (holder_ == HoldHolder::Link ? "; it resumes when the link is free again"
                                                  : "; only the operator resumes it"));
  }
  cycle_->resume();
  if (live_) live_->sender->set_source_held(false);
  held_time_left_s_.reset();
  set_state(State::Running, HoldHolder::None, std::string("resumed by the ") + to_string(by));
}

void Service::stop(const std::string& why) {
  if (state_ == State::Streaming && live_) {
    // The motion is over; the controller still has blocks. grbl: hold it and end the job now.
    if (live_->hold_and_reset && ending_.state == EndingStatus::State::None &&
        !live_->done.load(std::memory_order_acquire)) {
      stop_why_ = why;
      final_state_ = State::Stopped;
      request_ending(why, true);
      return;
    }
    throw InputError(
        "stop: the motion has ended and the controller is taking the last blocks, which end the "
        "job safely" +
        std::string(live_->hold_and_reset ? "" : " (a drip link cannot take back what it sent)"));
  }
  require_active("stop");
  stop_why_ = why;
  cycle_->stop();
  request_ending(why, true);
}

void Service::set_override(double percent) {
  if (!(percent >= 0.0 && percent <= 200.0)) {
    throw InputError("override: \"percent\" = " + text::sig(percent) + " is outside 0..200 %");
  }
  if (state_ == State::Streaming) {
    throw InputError(
        "override: the motion has ended and the controller is taking the last blocks; set it "
        "again for the next job once this one has ended");
  }
  if (state_ != State::Running && state_ != State::Holding) {
    const double previous = preset_override_percent_;
    preset_override_percent_ = percent;
    emit(EventKind::Override, "override " + text::sig(percent) + " % for the next start", percent,
         previous);
    return;
  }
  cycle_->set_override(percent / 100.0);
  if (limits_) limits_->set_override(percent / 100.0);
  const double previous = override_percent_;
  override_percent_ = percent;
  emit(EventKind::Override, "override " + text::sig(percent) + " %", percent, previous);
}

void Service::shutdown(const std::string& why) {
  if (state_ == State::Streaming && live_) {
    if (live_->hold_and_reset && ending_.state == EndingStatus::State::None) {
      // The controller may still run seconds of queued blocks: hold it and end the job now.
      request_ending(why, true);
      final_state_ = State::Stopped;
      stop_why_ = why;
    } else {
      log("the controller is taking the last blocks, which end the job safely; waiting for "
          "them (a second signal gives the transfer up)");
    }
  } else if (cycle_ && !cycle_->finished() &&
             (state_ == State::Running || state_ == State::Holding)) {
    log("stopping the running job (a jerk-limited stop on the path), then ending it safely");
    stop_why_ = why;
    cycle_->stop();
    request_ending(why, true);
  }
}

bool Service::poll() {
  try {
    step();
  } catch (const std::exception& e) {
    if (options_.cycle_thread) {
      fail_job(std::string("internal error: ") + e.what());
    } else {
      fail_job(e.what());
      throw;  // the owner's: an input error of the look-ahead, a sink's refusal
    }
  }
  return busy();
}

void Service::step() {
  if (live_) {
    // The sender's events and holds, in the order it gave them.
    std::vector<std::string> events;
    {
      std::lock_guard lock(live_->mutex);
      events.swap(live_->events);
    }
    for (const std::string& e : events) emit(EventKind::Link, e);
    if ((state_ == State::Running || state_ == State::Holding) &&
        live_->done.load(std::memory_order_acquire)) {
      const comms::SenderReport& r = live_->report;
      if (!(r.ending.sent || r.ending.not_needed)) {
        link_failed();
        return;
      }
    }
    const int request = live_->hold_request.exchange(-1);
    if (request >= 0 && cycle_ && !cycle_->finished()) {
      if (request == 1 && state_ == State::Running) {
        log("the link holds: bringing the motion to a stop");
        hold(HoldHolder::Link);
      } else if (request == 0 && state_ == State::Holding && holder_ == HoldHolder::Link) {
        log("the link is free again: resuming the motion");
        resume(HoldHolder::Link);
      }
    }
  }
  if (cycle_ && (state_ == State::Running || state_ == State::Holding)) {
    if (options_.cycle_thread) {
      drain();
    } else {
      run_here();
    }
    if (!cycle_ || (state_ != State::Running && state_ != State::Holding)) return;
    const motion::CycleStatus c = cycle_->status();
    if (c.overruns > overruns_seen_) {
      overruns_seen_ = c.overruns;
      emit(EventKind::Overrun, "the cycle overran its period", static_cast<double>(c.late_wakeups),
           0.0, c.overruns);
    }
    if (cycle_->finished()) {
      drain();
      if (!cycle_ || (state_ != State::Running && state_ != State::Holding)) return;
      finish_motion();
    }
  }
  if (state_ == State::Streaming) follow_stream();
}

void Service::run_here() {
  for (std::int64_t k = 0; k < options_.periods_per_poll && cycle_->run_here(); ++k) {
    drain();
    if (!cycle_ || (state_ != State::Running && state_ != State::Holding)) return;
  }
}

// At most a ring's worth a call: on the simulated clock the cycle's thread refills the ring as
// fast as it is drained, and a poll must come back to its owner (status, holds, the link).
void Service::drain() {
  motion::Setpoint sp;
  const double period_s = job_.motion.limits.period_s;
  for (std::size_t n = 0; n < options_.ring_capacity && cycle_->pop(sp); ++n) {
    if (limits_->check(sp) != LimitKind::None) {
      const LiveViolations& v = limits_->violations();
      const std::string what =
          std::string(to_string(v.fatal)) + " " + text::sig(v.fatal_value) + " " + unit(v.fatal) +
          " against at most " + text::sig(v.fatal_limit) + " " + unit(v.fatal) +
          " at t = " + text::sig(v.fatal_t_s) + " s, s = " + text::sig(v.fatal_s_mm) + " mm";
      emit(EventKind::Violation, what, v.fatal_value, v.fatal_limit);
      fail_job("live limit rule (" + what + "); the setpoint was not emitted");
      return;
    }
    ++setpoints_;
    if (sp.v_mm_per_s > 0.0) moving_s_ += period_s;
    last_ = sp;
    accel_max_ = std::max(accel_max_, std::abs(sp.a_mm_per_s2));
    jerk_max_ = std::max(jerk_max_, std::abs(sp.j_mm_per_s3));
    feed_max_ = std::max(feed_max_, sp.v_mm_per_s);
    if (job_.sink) {
      if (options_.cycle_thread) {
        job_.sink->write(sp);
      } else {
        job_.sink->write_period(sp, cycle_->job(), cycle_->last_times());
      }
    }
    if (live_) {
      if (live_->program) {
        live_->program->push(sp);
      } else {
        live_->encoder->push(sp);
      }
      if (!live_->refused.empty()) {
        fail_job(live_->refused);
        return;
      }
    }
  }
}

void Service::finish_motion() {
  cycle_->join();
  const motion::CycleState end = cycle_->status().state;
  State s = State::Done;
  std::string why = "the motion ended";
  if (end == motion::CycleState::Error) {
    s = State::Error;
    error_ = cycle_->error();
    why = error_;
  } else if (end == motion::CycleState::Stopped) {
    s = State::Stopped;
    why = stop_why_.empty() ? "stopped" : stop_why_;
  }
  try {
    if (s == State::Error) {
      job_.sink.reset();  // a job in error keeps no setpoints file
    } else if (job_.sink) {
      job_.sink->commit();
    }
  } catch (const std::exception& e) {
    s = State::Error;
    error_ = e.what();
    why = error_;
  }
  const motion::CycleStats& st = cycle_->stats();
  log("job " + job_.name + " motion ended after " + std::to_string(setpoints_) + " setpoints; " +
      std::to_string(st.late_wakeups) + " late wake-ups, " + std::to_string(st.overruns) +
      " overruns, " + std::to_string(st.setpoints_lost) + " setpoints lost");
  if (live_) {
    // A job that reached its end: what follows its last planned move (the retract's rapid, M5,
    // M2). A restarted one has no program events after its line: its ending follows the last
    // block (a bare path, a test's, has none to follow). Any other end is early: the ending from
    // where the blocks leave the tool (in the blocks after the planned stop, or sent by the sender
    // after its hold and reset).
    if (s == State::Done && live_->program) {
      live_->program->end();
    } else if (s == State::Done && !job_.restart) {
      live_->encoder->finish();  // a bare path: no program, nothing started that must stop
    } else {
      if (s == State::Done) {
        request_ending("the restarted program reached its end", false);
        ending_.how.replace(0, ending_.how.find(';'),
                            "after the restarted program's last block: the retract, M5, M9, the "
                            "program end");
      } else {
        request_ending(why, true);
      }
      if (append_pending_) {
        append_ending();
      } else {
        live_->encoder->finish();
      }
    }
    live_->blocks.close();
    final_state_ = s;
    if (s == State::Error) {
      emit(EventKind::Alarm, error_);
      alarmed_ = true;
    }
    set_state(State::Streaming, HoldHolder::None,
              s == State::Done ? "the motion ended; blocks still to send"
                               : "the motion ended early; ending the job safely");
    return;
  }
  if (s == State::Error) emit(EventKind::Alarm, error_);
  set_state(s, HoldHolder::None, why);
  end_job();
}

void Service::fail_job(const std::string& why) {
  log("job " + job_.name + " failed: " + why);
  cycle_.reset();  // leaves at once (even blocked on a full ring) and joins the cycle thread
  if (live_ && state_ != State::Streaming && !live_->done.load(std::memory_order_acquire)) {
    // The link still carries: end the job safely after the last block queued (ack: hold, reset,
    // then the ending), then end in error once the controller has it.
    job_.sink.reset();
    error_ = why;
    try {
      request_ending(why, true);
      if (append_pending_) {
        append_ending();
      } else {
        live_->encoder->finish();
      }
    } catch (const std::exception& e) {
      ending_.state = EndingStatus::State::NotSent;
      ending_.note =
          std::string("the ending could not be written (") + e.what() + "); " + ending_advice();
      error_ += "; " + ending_.note;
    }
    live_->blocks.close();
    final_state_ = State::Error;
    emit(EventKind::Alarm, error_);
    alarmed_ = true;
    set_state(State::Streaming, HoldHolder::None, "the job failed; ending it safely");
    return;
  }
  error_ = why;
  if (live_) {  // streaming already, or the link gone: nothing more reaches the controller
    live_->blocks.close();
    live_->stop = true;
    if (live_->thread.joinable()) live_->thread.join();
    live_->done.store(true);
    if (ending_.state != EndingStatus::State::Sent &&
        ending_.state != EndingStatus::State::NotNeeded) {
      ending_.state = EndingStatus::State::NotSent;
      ending_.note =
          "the safe ending could NOT be sent: the transfer was given up; " + ending_advice();
      error_ += "; " + ending_.note;
    }
  }
  job_.sink.reset();  // removes the setpoints' temporary file
  emit(EventKind::Alarm, error_);
  set_state(State::Error, HoldHolder::None, error_);
  end_job();
}

// The source line of the segment of the job's path (corners blended: the same segments as the
// program's) at arc length s_mm. The walker's segment starts are fixed when the job is built, so
// this reads nothing the cycle thread writes.
int Service::line_at(double s_mm) const {
  const std::vector<toolpath::PathSegment>& segs = cycle_->job().path().segments;
  return segs.empty() ? 0 : segs[segment_at(s_mm)].source_line;
}

// The segment of the job's path at arc length s_mm: the last one starting at or before it.
std::size_t Service::segment_at(double s_mm) const {
  const motion::Job& job = cycle_->job();
  std::size_t lo = 0, hi = job.path().segments.size();
  while (hi - lo > 1) {
    const std::size_t mid = (lo + hi) / 2;
    if (job.walker().segment_start_mm(mid) <= s_mm) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  return lo;
}

// The program's modal state at arc length s_mm; none when the job has no program, or when the
// planner split the program's segments (G64 Q fitting), so that they no longer match.
std::optional<CommandedModal> Service::modal_at(double s_mm) const {
  if (!cycle_ || modal_.empty() || cycle_->job().path().segments.size() != modal_.segments()) {
    return std::nullopt;
  }
  const std::size_t segment = segment_at(s_mm);
  return modal_.at(segment, s_mm - cycle_->job().walker().segment_start_mm(segment));
}

// The controller's own state in a streamed job: its last status report (ack), and which block
// it executes, or was last sent (drip), against ncd's commanded motion (service.hpp,
// ControllerProgress).
void Service::controller_view(Status& s) const {
  const comms::SenderCounts& c = s.link->counts;
  s.controller = live_->sender->controller_report();
  if (s.controller) {
    s.controller_age_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - s.controller->received)
            .count();
  }
  const BlockTrace& trace = live_->trace;
  std::optional<std::size_t> at;
  ControllerProgress p;
  if (s.controller && s.controller->status.line_number) {
    at = trace.with_number(*s.controller->status.line_number);
    p.source = "controller (Ln:)";
  }
  if (!at && c.blocks_executed >= 0 && trace.size() > 0) {
    at = std::min<std::size_t>(static_cast<std::size_t>(c.blocks_executed), trace.size() - 1);
    p.source = "controller (executed blocks)";
  }
  if (!at && c.blocks_acked < 0) {
    const std::size_t carried = trace.carried(c.blocks_written, c.buffer_bytes);
    if (carried > 0) at = carried - 1;
    p.source = "last sent";
  }
  if (!at || !cycle_) return;
  const QueuedBlock& b = trace[*at];
  p.block = *at;
  p.number = b.number;
  // The move the block begins in: a hair past its start (a block that starts at a corner
  // belongs to the move after it).
  const double into_mm =
      b.start_s_mm + std::min(kBlockStartProbeMm, 0.5 * (b.end_s_mm - b.start_s_mm));
  p.modal = modal_at(into_mm);
  p.line = p.modal && p.modal->line > 0 ? p.modal->line : line_at(into_mm);
  p.blocks_behind = static_cast<std::int64_t>(trace.size() - 1 - *at);
  const double reached_t_s = p.source == "last sent" ? b.end_t_s : b.start_t_s;
  p.seconds_behind = std::max(0.0, s.t_s - reached_t_s);
  if (s.controller) {
    const auto& w = s.controller->work_mm;
    Vec3 at_mm(w[0], w[1], w[2]);
    if (live_->length_offsets && p.modal) at_mm += p.modal->tool_length_mm;
    s.controller_position_mm = at_mm;
  }
  s.progress_at_controller = std::move(p);
}

void Service::end_job() {
  log("job " + job_.name + " " + to_string(state_));
  emit(EventKind::Job, std::string("ended ") + job_.name + " " + to_string(state_));
}

// The time the job still needs: what is left of the path at the mean feed of the time spent
// moving so far (a hold adds neither time nor path, so the estimate does not grow while held);
// frozen at its value when the hold was asked for. None until the tool has moved.
std::optional<double> Service::time_left_s() const {
  if (state_ == State::Holding && held_time_left_s_) return held_time_left_s_;
  if (!cycle_) return std::nullopt;
  const motion::CycleStatus c = cycle_->status();
  if (!(moving_s_ > 0.0) || !(c.s_mm > 0.0)) return std::nullopt;
  const double mean_mm_per_s = c.s_mm / moving_s_;
  return std::max(0.0, cycle_->length_mm() - c.s_mm) / mean_mm_per_s;
}

Status Service::status() const {
  Status s;
  s.state = state_;
  s.holder = holder_;
  s.job = job_.name;
  s.error = error_;
  s.realtime = realtime_;
  if (cycle_) {
    const motion::CycleStatus c = cycle_->status();
    s.has_job_run = true;
    s.length_mm = cycle_->length_mm();
    // Before the first period the cycle has published nothing: the path's start.
    s.position_mm = c.periods == 0 ? start_mm_ : Vec3(c.x_mm, c.y_mm, c.z_mm);
    s.feed_mm_per_min = c.v_mm_per_s * 60.0;
    s.progress = s.length_mm > 0.0 ? c.s_mm / s.length_mm : 1.0;
    if (state_ == State::Done || state_ == State::Stopped || state_ == State::Streaming) {
      s.time_left_s = 0.0;
    } else {
      s.time_left_s = time_left_s();
    }
    s.t_s = c.t_s;
    s.commanded = modal_at(last_.s_mm);
    if (setpoints_ > 0) {
      s.line = line_at(last_.s_mm);
      s.binding_limit = motion::limit_name(last_.limit_id);
      s.feed_limit_mm_per_min = last_.feed_limit_mm_per_s * 60.0;
    }
    s.overruns = c.overruns;
    s.late_wakeups = c.late_wakeups;
    s.lateness_bins_ns = cycle_->lateness_bins();
  }
  s.override_percent = busy() ? override_percent_ : preset_override_percent_;
  s.setpoints = setpoints_;
  s.accel_max_mm_per_s2 = accel_max_;
  s.jerk_max_mm_per_s3 = jerk_max_;
  s.feed_max_mm_per_min = feed_max_ * 60.0;
  s.interference_allowed = job_.interference_allowed;
  if (limits_) s.violations = limits_->violations();
  if (job_.restart) s.restart_line = job_.restart->line;
  s.ending = ending_;
  if (state_ == State::Stopped && cycle_) {
    StopReport r;
    r.why = stop_why_.empty() ? "stopped" : stop_why_;
    r.position_mm = last_.p;
    r.s_mm = last_.s_mm;
    r.length_mm = cycle_->length_mm();
    const std::size_t seg = last_.segment;  // the walker may be ahead (docs/planner.md §3b)
    // The job's own path: fitted dense runs (G64 Q) split a program segment, each part keeps
    // its source line.
    const auto& segs = cycle_->job().path().segments;
    if (seg < segs.size()) r.line = segs[seg].source_line;
    s.stopped = r;
  }
  if (live_) {
    LinkStatus l;
    l.port = live_->line.device;
    l.settings = comms::describe(live_->line);
    l.blocks_encoded = live_->blocks_encoded;
    l.chars_encoded = live_->chars_encoded;
    l.blocks_waiting = live_->blocks.waiting();
    {
      std::lock_guard lock(live_->mutex);
      l.last_event = live_->last_event;
    }
    l.link_holds = live_->link_holds.load();
    l.done = live_->done.load(std::memory_order_acquire);
    l.counts = live_->sender->counters().load();
    if (l.done) l.report = live_->report;
    s.link = std::move(l);
    controller_view(s);
  }
  for (const auto& sub : subscribers_) s.events_dropped += sub->dropped();
  return s;
}

}  // namespace ncd::service
