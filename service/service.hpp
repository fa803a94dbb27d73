// The ncd service as a library (docs/service.md): a job's lifecycle and its live pipeline,
// without JSON, without a socket and without an event loop of its own. The owner (`ncd serve`'s
// JSON mapping in api/intake.cpp, `ncd replay` in app/replay_cmd.cpp, or a test) calls the
// commands and poll() from one thread; poll() is the one loop that drains the cycle's setpoints
// into the sinks, the block encoder, the live block queue and the sender. The state machine is
// drawn at the top of service.cpp.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cam/whole_program.hpp"
#include "core/geometry.hpp"
#include "gcode/program.hpp"
#include "geometry/path.hpp"
#include "link/block_encoder.hpp"
#include "link/dnc_sender.hpp"
#include "link/line_settings.hpp"
#include "motion/cycle.hpp"
#include "service/commanded_state.hpp"
#include "service/events.hpp"
#include "service/live_limits.hpp"

namespace ncd::service {

// Where a job's setpoints go besides the encoder (the setpoints file, a test's capture, replay's
// statistics). write() runs on the owner's thread in poll(); commit() when the job ends done or
// stopped; a job in error destroys its sink without commit().
class SetpointSink {
 public:
  virtual ~SetpointSink() = default;
  virtual void write(const motion::Setpoint& sp) = 0;
  // With the cycle on the owner's thread (ServiceOptions::cycle_thread false), called instead
  // of write(), right after sp's period: the job stands where sp left it (Job::limit_here and
  // Job::roughness_here_um are sp's), and times is what that period cost.
  virtual void write_period(const motion::Setpoint& sp, const motion::Job& job,
                            const motion::PeriodTimes& times) {
    (void)job;
    (void)times;
    write(sp);
  }
  virtual void commit() = 0;
};

// The DNC link of a job that streams live.
struct LinkSpec {
  comms::EncoderSettings encoder;  // its line is replaced by sender.line
  comms::SenderSettings sender;    // sender.line.device is the port
  std::string journal;             // transfer journal file; empty: none
};

// Restart a job from a program line (docs/service.md, "Restart from a line").
struct RestartSpec {
  int line = 0;  // the job's path starts at the first segment opened on this source line
  // Sent before the first live block: the modes in force at the line and the safe re-entry
  // through the clearance plane (comms::restart_blocks).
  std::vector<std::string> preamble;
  // The tool length in force at the line (the program's last G43 H before it, from ncd's tool
  // table), mm: the planned path holds it, the controller adds its own after the preamble's
  // G43 H, so the blocks leave it out (comms::BlockEncoder::set_offset). Zero after G49/G43.1.
  Vec3 length_offset_mm = Vec3::Zero();
};

// A job, checked and ready to run: what the owner made of a request.
struct JobSpec {
  std::string name;
  std::shared_ptr<const toolpath::Path> path;
  // The whole program the path was planned from (toolpath::to_path of it; docs/whole-program.md),
  // and the comment lines that open its blocks. Set, a streamed job's blocks carry its events and
  // rapids at their place (comms::ProgramBlocks, as `ncd replay --blocks` writes them): preamble,
  // tool, spindle, the rapids as G0, M5, M2. None: the blocks of the path alone.
  std::shared_ptr<const toolpath::Program> program;
  std::vector<std::string> header;
  motion::JobConfig motion;
  LiveLimitRules rules;                // LiveLimitRules::from(motion.limits) unless configured
  std::optional<LinkSpec> link;        // none: no streaming
  std::unique_ptr<SetpointSink> sink;  // may be null
  bool interference_allowed = false;   // a chamfer whose checks failed, allowed by the user
  std::optional<RestartSpec> restart;
  // How a streamed job leaves the part when it ends early (docs/service.md, "Ending early"):
  // its clearance plane and, for an inner edge, the way back to the drill axis. None: the
  // ending stops the spindle and the coolant and ends the program, and moves nothing.
  std::optional<toolpath::SafeRetract> retract;
};

struct ServiceOptions {
  motion::ClockKind clock = motion::ClockKind::Wall;
  bool realtime = true;
  // false (the simulated clock only; `ncd replay`): no cycle thread. poll() runs the periods
  // itself, up to periods_per_poll at a time, each drained before the next (the sinks'
  // write_period), and an exception of a period or a sink ends the job in error and leaves
  // poll() to the owner instead of becoming "internal error".
  bool cycle_thread = true;
  std::int64_t periods_per_poll = 1024;
  std::size_t ring_capacity = 8192;  // the cycle's setpoint ring
  // The block encoder's longest block when streaming live, s, when the encoder settings give
  // none: a block reaches the controller only when it closes.
  double live_max_block_s = 0.5;
  std::function<void(const std::string&)> log;  // one line for the log; may be empty
};

// A stopped job: why and where.
struct StopReport {
  std::string why;
  Vec3 position_mm = Vec3::Zero();
  double s_mm = 0.0, length_mm = 0.0;
  int line = 0;  // source line of the segment it stopped in; 0 if none
};

// How a streamed job that did not reach its end left the machine (docs/service.md, "Ending
// early"): stopped, shut down, failed, or its link failed. The ending is the retract from where
// the blocks left the tool, M5, M9 and the program end.
struct EndingStatus {
  enum class State {
    None,       // the job has not ended early (or has no link)
    Pending,    // asked for: on its way to the controller
    Sent,       // the controller has it (drip: delivered; ack: executed, Idle after it)
    NotSent,    // it could not be sent: `note` says why and what to do at the machine
    NotNeeded,  // no move had reached the controller
  };
  State state = State::None;
  std::string how;                  // the sequence this link uses
  std::vector<std::string> blocks;  // as sent (drip with N numbers; ack after its reset)
  std::string note;                 // what is known of it, or why not and what to do
};
const char* to_string(EndingStatus::State s);

// The link of a streaming job.
struct LinkStatus {
  std::string port, settings, last_event;
  std::int64_t blocks_encoded = 0, chars_encoded = 0;
  std::size_t blocks_waiting = 0;
  bool link_holds = false;     // the sender's last word: the controller holds the line
  bool done = false;           // the sender has finished; report is valid
  comms::SenderReport report;  // valid when done
  // The sender's live counters (comms::SenderCounts: bytes, blocks, XOFF, the controller's
  // buffer, underruns, reconnects), read without a lock while it runs; equal to the report's
  // once done.
  comms::SenderCounts counts;
};

// Where the controller stands in a streamed job (docs/web-dashboard.md, "The machine state"):
// the block it executes as its status report says (grbl's Ln:, or the blocks known executed),
// or, where nothing says so (drip feed), the last block the line has carried in full; that
// block's source line, and how far ncd's commanded motion runs ahead of it.
struct ControllerProgress {
  // "controller (Ln:)", "controller (executed blocks)" or "last sent" (drip: the line carried
  // it; the controller's own progress is not reported).
  std::string source;
  std::size_t block = 0;           // the block (0-based, in the order queued)
  long number = 0;                 // its N word (0: none)
  int line = 0;                    // the source line of the move it begins in (else its segment's)
  std::int64_t blocks_behind = 0;  // blocks ncd has queued after it
  // The commanded motion time less the block's planned start (ack) or end (drip: the controller
  // cannot be further than the end of what it received): how far it runs behind, s, ≥ 0.
  double seconds_behind = 0.0;
  std::optional<CommandedModal> modal;  // the program's state at that block
};

// The status snapshot (owner's thread; allocates, never touches the cycle's thread).
struct Status {
  State state = State::Idle;
  HoldHolder holder = HoldHolder::None;
  std::string job, error, realtime;
  bool has_job_run = false;  // a cycle exists: the motion fields below are valid
  Vec3 position_mm = Vec3::Zero();
  double feed_mm_per_min = 0.0, progress = 0.0, t_s = 0.0, length_mm = 0.0;
  std::optional<double> time_left_s;
  // Of the last setpoint drained (none before the first): the source line of the segment it
  // lies in (0: the path has no lines), the feed limit that bound it (motion::limit_name:
  // "roughness", …, "program", "tangential_accel", "hold", …) and the feed laws' limit there at
  // 100 % override, whichever binds (motion::Setpoint::feed_limit_mm_per_s; 0 before the first).
  int line = 0;
  std::string binding_limit;
  double feed_limit_mm_per_min = 0.0;
  std::int64_t overruns = 0, late_wakeups = 0, setpoints = 0;
  // The cycle's wake-up lateness so far, ns on LogHistogram's coarse buckets
  // (motion::Cycle::lateness_bins; bucket g from LogHistogram::coarse_from(g)); all zero before
  // a job has run.
  motion::Cycle::LatenessBins lateness_bins_ns{};
  double accel_max_mm_per_s2 = 0.0, jerk_max_mm_per_s3 = 0.0, feed_max_mm_per_min = 0.0;
  double override_percent = 100.0;
  bool interference_allowed = false;
  LiveViolations violations;
  std::optional<StopReport> stopped;
  std::optional<LinkStatus> link;
  EndingStatus ending;
  int restart_line = 0;
  std::uint64_t events_dropped = 0;  // summed over the subscribers
  // The program's modal state where ncd's commanded motion stands (none without a program, or
  // before the first setpoint when the path is empty).
  std::optional<CommandedModal> commanded;
  // ack with status polling: the controller's last status report and its age (s); none in
  // drip feed and before the first report.
  std::optional<comms::ControllerReport> controller;
  double controller_age_s = 0.0;
  // The controller's work position in the path's frame (mm, the blocks' coordinates plus the
  // tool length when the blocks leave it to the controller's G43 H); none without a report.
  std::optional<Vec3> controller_position_mm;
  std::optional<ControllerProgress> progress_at_controller;
};

class Service {
 public:
  explicit Service(const ServiceOptions& options);
  ~Service();  // stops any cycle and sender, joins their threads
  Service(const Service&) = delete;
  Service& operator=(const Service&) = delete;

  // Commands. Each throws InputError naming the state when it does not apply there.
  void submit(JobSpec job);    // idle, ready, done, stopped, error → ready
  const std::string& start();  // ready → running; returns the real-time grant
  void hold(HoldHolder by);    // running → holding (or a new holder while holding)
  void resume(HoldHolder by);  // holding → running, by the holder only
  // running, holding → a jerk-limited stop, then the ending (service.cpp), then stopped;
  // streaming on an ack link with status → the controller held and the ending sent now.
  void stop(const std::string& why);
  // 0..200 %. Running or holding: at once. Idle, ready, done, stopped, error: a preset that the
  // next start() applies before the first period (without one a job starts at 100 %); the
  // status shows it. Streaming (the motion is over): refused.
  void set_override(double percent);
  // Stops any motion (a jerk-limited stop) and ends a streamed job safely, as stop() does; a
  // transfer already ending goes on to its end. poll() until !busy().
  void shutdown(const std::string& why);
  // Gives the transfer up at once (a second shutdown signal): the ending is not sent, and the
  // job's error says so and what to do at the machine.
  void abort_transfer(const std::string& why);
  // When the link is down now, what that means for the ending (for a stop's reply); else "".
  std::string link_down_note() const;

  // The loop: drains the setpoints, applies the link's holds, follows the sender, ends the job.
  // Returns busy(). Never throws: an exception ends the job in error.
  bool poll();
  // A cycle or a sender is under way: poll again (1 ms while running, less often streaming).
  bool busy() const;
  State state() const { return state_; }
  Status status() const;
  // The statistics of the last job's cycle (every wake-up's lateness, compute time, overruns)
  // once the cycle has ended; null before a job has run and while its cycle runs. Valid until
  // the next submit or start.
  const motion::CycleStats* cycle_stats() const {
    return cycle_ && state_ != State::Running && state_ != State::Holding ? &cycle_->stats()
                                                                          : nullptr;
  }
  // The job of the last start (its path as walked, its planner's high-water marks): null before
  // a start and after a job failed on an exception. With a cycle thread, only once the cycle
  // has ended (as cycle_stats()); without one, at any time between polls.
  // The job submit() built, until start() takes it (null otherwise): where its segments start
  // on the path it will walk, for a caller that places program events on it before the start.
  const motion::Job* submitted_job() const { return built_.get(); }
  const motion::Job* job() const {
    if (!cycle_ ||
        (options_.cycle_thread && (state_ == State::Running || state_ == State::Holding)))
      return nullptr;
    return &cycle_->job();
  }
  // A new subscriber's event feed (capacity rounded up to a power of two, at least 2).
  std::shared_ptr<Subscription> subscribe(std::size_t capacity);

 private:
  struct Live;  // the encoder, the queue and the sender thread (service.cpp)

  void step();
  void run_here();
  void drain();
  void finish_motion();
  void start_stream(const motion::Job& job);
  void follow_stream();
  void fail_job(const std::string& why);
  // Ending early (service.cpp, "Ending early"): ask for it (now: cut the controller's queue
  // where the link can, ack; else the ending follows the blocks up to the stop), and write it
  // into the block stream after the planned stop.
  void request_ending(const std::string& why, bool now);
  bool ends_by_hold_and_reset() const;
  void append_ending();
  void resolve_ending(const comms::SenderReport& r);
  void link_failed();
  std::string ending_advice() const;
  void end_job();
  void set_state(State s, HoldHolder holder, const std::string& why);
  void emit(EventKind kind, const std::string& text, double value = 0.0, double limit = 0.0,
            std::int64_t count = 0);
  void log(const std::string& line) const;
  std::optional<double> time_left_s() const;
  int line_at(double s_mm) const;
  std::size_t segment_at(double s_mm) const;
  std::optional<CommandedModal> modal_at(double s_mm) const;
  void controller_view(Status& s) const;
  void require_active(const char* cmd) const;

  ServiceOptions options_;
  State state_ = State::Idle;
  HoldHolder holder_ = HoldHolder::None;
  JobSpec job_;
  std::unique_ptr<motion::Job> built_;  // submit()'s, for start()
  CommandedTable modal_;                // the job's program, move by move (commanded_state.hpp)
  std::string error_, stop_why_, realtime_;
  Vec3 start_mm_ = Vec3::Zero();
  double moving_s_ = 0.0;
  std::optional<double> held_time_left_s_;
  std::unique_ptr<Live> live_;
  State final_state_ = State::Done;
  std::unique_ptr<motion::Cycle> cycle_;
  std::optional<LiveLimitCheck> limits_;
  std::int64_t setpoints_ = 0;
  motion::Setpoint last_{};
  double accel_max_ = 0.0, jerk_max_ = 0.0, feed_max_ = 0.0;
  double override_percent_ = 100.0;
  double preset_override_percent_ = 100.0;  // for the next start (set_override while not moving)
  std::int64_t overruns_seen_ = 0;
  EndingStatus ending_;
  bool append_pending_ = false;  // the ending goes into the blocks after the planned stop
  bool alarmed_ = false;         // the job's alarm event has gone out
  std::uint64_t event_seq_ = 0;
  std::vector<std::shared_ptr<Subscription>> subscribers_;
};

}  // namespace ncd::service
