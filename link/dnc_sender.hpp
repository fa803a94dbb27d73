// The DNC sender: takes NC blocks from a source (a program file, or the block encoder live from
// the cycle) and sends them over the serial link with one of two protocols, tracking what the
// controller queued and executed as far as the protocol tells, and keeping a journal of the
// first block not known executed. It resumes after a lost link only where that is provably safe.
// The algorithm is described at the top of dnc_sender.cpp; the rules in docs/dnc-link.md.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "gcode/dialect/dialect.hpp"
#include "link/line_settings.hpp"
#include "link/sim_clock.hpp"

namespace ncd::comms {

class TransferJournal;

struct SenderSettings {
  LineSettings line;
  int max_queued_chars = 16;    // drip: characters allowed ahead of the wire (stop distance)
  int rx_buffer_bytes = 128;    // ack: controller receive buffer (grbl 128, grblHAL 1024)
  double xoff_timeout_s = 5.0;  // a hold longer than this is reported (and holds the motion)
  // A hold the program explains is allowed its wait on top of xoff_timeout_s: the blocks that
  // make the controller wait (M6: tool_change_s; G4 P: its seconds; M0, M1, M60: the operator,
  // no bound) among the last wait_window_chars characters written before the hold
  // (docs/cmd-stream.md, "Holds the program explains").
  double tool_change_s = 30.0;
  int wait_window_chars = 1024;
  // drip: on a stop, the block being written is finished and what was written is let reach the
  // line (so the controller holds whole blocks only), for up to this long.
  double stop_drain_s = 5.0;
  // drip: when the transfer is over and not a byte came back, wait this long for one (a DC1 in
  // flight) before reporting the controller silent.
  double silence_grace_s = 1.0;
  // The clock the controller's holds (XOFF, CTS low) and the reconnect window are timed on;
  // null: the wall clock. A test whose simulated controller runs on a ManualClock gives it here,
  // so that a hold or an outage lasts as long for both ends however the machine's load delays
  // the test's thread.
  std::shared_ptr<const SimClock> hold_clock;
  double reconnect_max_s = 30.0;  // give up reopening a lost port after this long (hold_clock)
  // drip: the clock the wire model runs on (how much the line has carried since a byte was
  // written); null: the wall clock. A test whose simulated controller runs on a ManualClock
  // gives it here too, so that the sender never credits the line with more than the
  // controller's time lets it carry, however the machine's load delays the controller's thread
  // (on the wall clock a delayed controller leaves the bytes the model counts as carried in the
  // kernel, beyond the reach of its DC3).
  std::shared_ptr<const SimClock> wire_clock;
  double progress_period_s = 1.0;
  // drip: after a lost link, blocks within this many characters before the first block the
  // wire model cannot vouch for are sent again; the controller discards repeated N numbers.
  // Negative: max_queued_chars + 0.25 s of line.
  int resend_window_chars = -1;
  double pacing_fraction = 0.98;  // drip: pace at this fraction of the line's capacity
  // The sending thread runs at SCHED_FIFO this priority while run() runs, so that a loaded host
  // does not delay its answer to a DC3 past the controller's headroom (link/thread_priority.hpp);
  // 0: normal scheduling. Refused, it runs on at normal priority and the report says so. Not
  // asked for when hold_clock or wire_clock is set (the line's time is simulated).
  int fifo_priority = 60;
  // drip: the controller's maker documents that it discards a block whose N it already has;
  // only then are blocks resent after a lost link (else the job stops as interrupted).
  bool controller_skips_repeated_n = false;
  // ack (grbl): start-up, status polling and recovery.
  int planner_blocks = 15;          // grbl 1.1: 15
  double status_hz = 5.0;           // `?` polls (out of band); 0: none, "executed" is not known
  double banner_wait_s = 2.5;       // wait this long for the banner before waking with an LF
  double startup_timeout_s = 10.0;  // no banner and no answer to the wake by then: give up
  // On error:N or ALARM, and when a lost link cannot be resumed: bring grbl to a safe halt
  // (DncSender::request_halt) so that nothing queued after the failure runs.
  bool reset_on_error = true;
  // ack: when `stop` is set, bring grbl to a safe halt before run() returns (the same as
  // request_halt); off, a stop leaves grbl running the blocks it has queued.
  bool halt_on_stop = false;
  double halt_timeout_s = 30.0;  // ack: the longest wait for a hold to come to rest (Hold:0)
  // ack: at start-up, clear grbl's alarm lock with `$X` (the operator has checked the machine;
  // after ALARM:3 its position may be lost). Off, a locked controller ends the job before any
  // line is sent.
  bool unlock = false;
  // Lines sent before the first block (a restart's modal state and re-entry), without N.
  std::vector<std::string> preamble;
  // The controller's dialect: each block is checked (comms/dialect) before it is written; the
  // first one the dialect refuses ends the job with the block and word named. A program file
  // is checked whole before the first byte with check_program_file.
  std::optional<Dialect> dialect;
};

// The blocks of a program file (as ProgramFile gives them: `%` and empty lines are framing)
// checked against the dialect before anything is sent: the first violation, its `line` the
// file's line (1-based), or nullopt. linuxcnc: the interpreter reads the whole file. Throws
// InputError if the file cannot be read.
std::optional<Violation> check_program_file(const std::string& path, Dialect dialect);

// A grbl 1.1 status report, `<Run|MPos:1.000,2.000,0.000|Bf:14,120|Ln:40|FS:500,0>`.
struct GrblStatus {
  std::string state;  // Idle, Run, Hold:0, Hold:1, Alarm, …
  std::optional<std::array<double, 3>> mpos, wpos, wco;
  std::optional<int> free_blocks, free_bytes;  // Bf:
  std::optional<long> line_number;             // Ln:
  std::optional<double> feed;                  // FS: (or F:), mm/min
  std::optional<double> spindle_rpm;           // FS:'s second value: 0 when the spindle is off
};
// Parses one status line (without CR LF); nullopt if it is not one.
std::optional<GrblStatus> parse_grbl_status(std::string_view line);

// The end of grbl's safe halt (DncSender::request_halt, docs/dnc-link.md "A safe halt"): a feed
// hold, a wait until the status says the motion is at rest (Hold:0, or Idle), then the soft
// reset, which throws the queue away without an alarm, and a status to confirm the state.
struct HaltReport {
  bool attempted = false;
  bool at_rest = false;  // the status said Hold:0, Idle or Alarm before the reset
  bool reset = false;    // the soft reset was sent and grbl's banner came back
  bool alarm = false;    // grbl is in alarm (locked until $X) after it
  double rest_s = 0.0;   // from the hold to the status at rest
  std::string state;     // grbl's state after the halt (Idle, Alarm), or when it gave up
  std::string detail;    // why it did not complete; empty when it did
  bool ok() const { return at_rest && reset && !alarm && detail.empty(); }
};

// What grbl says of itself when asked with `?` only (no line sent): for advice on where to
// restart after ncd was killed (docs/dnc-link.md "After ncd was killed").
struct GrblProbe {
  bool spoke = false;   // it answered a status report
  bool banner = false;  // it reset when the port opened: its position restarted, tells nothing
  std::string state;    // Idle, Run, Hold:0, Alarm, … (the last report, after waiting)
  std::optional<std::array<double, 3>> position;  // work coordinates; none without WPos or WCO
  std::optional<int> free_blocks;                 // Bf:, when reported
  std::string failure;                            // why it could not be asked
};
// Opens the port, waits for the banner up to banner_wait_s, asks `?` and, while grbl runs the
// blocks it has queued (Run), asks again up to settle_s; writes nothing but `?`.
GrblProbe probe_grbl(const SenderSettings& settings, double settle_s);

// Where a program stands at a controller's reported position (work coordinates): of the moves
// among blocks [first, end) (0-based), and the last move before `first`, the one that ends at
// `position` (then the block after it is the first not done) or that `position` lies on, past
// its start (then that move is), within 0.002 mm. It must be the only one.
struct PositionMatch {
  std::optional<std::int64_t> first_not_done;  // 0-based; nullopt: no unique match (see why)
  std::int64_t move = -1;                      // the move matched (0-based)
  bool at_end = false;                         // at its end point (else inside it)
  std::string why;                             // when there is no unique match
};
PositionMatch match_position(const std::string& program_path, std::int64_t first, std::int64_t end,
                             const std::array<double, 3>& position);

enum class BlockStatus { Ready, NotYet, End };

// Where blocks come from. next() fills `text` (no end of block) and returns Ready, NotYet when
// a live producer has nothing yet, or End when the program is over.
class BlockSource {
 public:
  virtual ~BlockSource() = default;
  virtual BlockStatus next(std::string& text) = 0;
};

struct SenderEvent {
  enum class Kind { Opened, LinkLost, Reopened, XoffLong, XoffEnd, Noise, Alarm, Progress, Ending };
  Kind kind = Kind::Progress;
  double t_s = 0.0;        // since the sender started
  std::int64_t block = 0;  // the block concerned (0-based), or blocks sent for Progress
  std::string text;        // what happened, for the log
};

// How an ack (grbl) stream ended early (DncSender::end_with; docs/dnc-link.md, "Ending early").
struct EndingReport {
  bool requested = false;   // end_with() was acted on
  bool not_needed = false;  // no motion block had been written: the controller never moved
  bool held = false;        // after `!` the controller reported Hold:0
  bool reset = false;       // then it was reset (0x18) and sent its banner
  bool sent = false;        // every ending line was answered ok
  bool executed = false;    // ... and the controller then reported Idle
  std::optional<std::array<double, 3>> held_at_mm;  // where the hold left the tool (work)
  double request_t_s = -1.0;  // since the sender started: the request seen, `!` written
  double held_t_s = -1.0;     // Hold:0 seen
  // Why the held position was not trusted (empty: it was): it lay on none of the moves the
  // controller was sent and not where the last one known done ended, so the controller has
  // reset or been moved meanwhile (a power-up counts from 0). The ending then moves nothing.
  std::string position_doubt;
  std::vector<std::string> lines;
  std::string failure;  // why the ending was not sent
};

struct SenderReport {
  bool completed = false;    // drip: all delivered; ack: all executed (or queued without status)
  bool stopped = false;      // stopped on request before the end
  bool interrupted = false;  // a reset, an alarm, an error or a lost link stopped the job
  std::string failure;       // alarm or link given up; empty otherwise
  std::int64_t first_block = 0;       // resumed from this block (journal)
  std::int64_t blocks = 0;            // program blocks taken from the source
  std::int64_t blocks_confirmed = 0;  // resume point at the end: the first block not known
                                      // executed (ack) or sent (drip), 0-based
  std::int64_t blocks_sent = 0;       // program blocks written in full at least once
  std::int64_t blocks_queued = 0;     // ack: answered ok (queued by the controller)
  std::int64_t blocks_executed = -1;  // ack with status: known executed; -1 not known (drip)
  std::string execution_basis;        // how `executed` is known: Ln, Bf, position, or not
  std::string dropped;                // what a reset threw away (queued, not executed)
  std::int64_t rejected_block = -1;   // ack: the block grbl answered error:N (0-based)
  // ack: grbl's state when the job ended, from its last status report (Idle, Alarm, Hold:0…);
  // empty when not known.
  std::string controller_state;
  bool position_may_be_lost = false;      // ack: ALARM:3 (a reset in motion) or a restart was seen
  HaltReport halt;                        // ack: the safe halt, when one was made
  int link_losses = 0;                    // the port failed or hung up
  std::uint64_t bytes_before_banner = 0;  // ack: always 0 (nothing is sent before it)
  std::string startup;                    // ack: banner | woken | none
  long status_reports = 0;
  std::vector<std::string> notes;  // what the report cannot vouch for
  std::int64_t blocks_resent = 0;  // sent again after a lost link
  std::int64_t bytes_written = 0;  // everything written, framing and resends included
  std::int64_t program_bytes = 0;  // the blocks with their end of block, once each
  // Written but not known to have left on the line when the transfer ended: drip, what the
  // kernel's queue and the wire model say the line has not carried yet; ack, the lines not
  // answered. 0 for a completed transfer.
  std::int64_t bytes_in_flight = 0;
  double duration_s = 0.0;
  // (bytes_written − bytes_in_flight) / (duration · line capacity): the share of the time the
  // line carried ncd's bytes. Above 1 only on a port that ignores the baud rate (USB, virtual);
  // a note then says so.
  double link_use = 0.0;
  // Not a byte came back from the controller during the whole transfer (no DC1/DC3, no reply,
  // and with RTS/CTS the CTS line never seen asserted): the blocks may not have arrived.
  bool controller_silent = false;
  // drip: a stop cut a block and could not finish it: the controller holds part of it.
  std::int64_t cut_block = -1;
  int holds_explained = 0;  // holds longer than xoff_timeout_s within their explained wait
  int xoff_count = 0;
  double xoff_total_s = 0.0;    // on SenderSettings::hold_clock
  double xoff_longest_s = 0.0;  // on SenderSettings::hold_clock
  int xoff_timeouts = 0;
  int reconnects = 0;  // reopened and resumed
  std::int64_t noise_bytes = 0;
  std::vector<std::string> alarms;
  int max_output_queue = 0;     // largest TIOCOUTQ seen
  int max_queued_estimate = 0;  // largest characters ahead of the wire, model or kernel
  int max_unacked_bytes = 0;    // ack: largest sum of unanswered lines
  std::string program_sha256;   // of the blocks, each ended by one LF
  std::string scheduling;       // the sending thread's: "SCHED_FIFO 60", or why it was normal
  EndingReport ending;          // ack: end_with()
};

// What the sender has done so far, published while it runs (docs/dnc-link.md, "Live counters"):
// the sender's thread stores them once per pass of its loop and when it ends, with relaxed
// atomic stores (no lock, no allocation); any thread reads them with load(). Each counter only
// grows during a transfer, and once run() has returned they equal its SenderReport's.
struct SenderCounts {
  std::int64_t bytes_written = 0;     // SenderReport::bytes_written
  std::int64_t blocks_taken = 0;      // program blocks taken from the source (report.blocks)
  std::int64_t blocks_written = 0;    // written in full at least once (report.blocks_sent)
  std::int64_t blocks_acked = -1;     // ack: answered ok, queued (report.blocks_queued); -1 drip
  std::int64_t blocks_executed = -1;  // ack with status: known executed; -1 not known
  int xoff_count = 0;                 // the controller's holds (DC3) seen (report.xoff_count)
  bool xoff_held = false;             // the controller holds the line now (DC3, or CTS low)
  // The controller's receive buffer as the sender knows it, bytes (characters): ack, the sum
  // of the lines written and not yet answered (character counting) against rx_buffer_bytes;
  // drip, the characters written and not yet carried by the line (the larger of the wire
  // model and the kernel's output queue) against max_queued_chars, the sender's own bound.
  int buffer_bytes = 0;
  int buffer_limit_bytes = 0;
  // Times the sender had nothing to write while the program was not over, the link was up and
  // the controller was not holding, after the first block went out: the controller could
  // starve. Counted once per dry spell (when it begins), not per pass of the loop.
  std::int64_t underruns = 0;
  int reconnects = 0;   // report.reconnects
  int link_losses = 0;  // report.link_losses
};

class SenderCounters {
 public:
  SenderCounts load() const;
  void store(const SenderCounts& c);

 private:
  std::atomic<std::int64_t> bytes_written_{0}, blocks_taken_{0}, blocks_written_{0},
      blocks_acked_{-1}, blocks_executed_{-1}, underruns_{0};
  std::atomic<int> xoff_count_{0}, buffer_bytes_{0}, buffer_limit_bytes_{0}, reconnects_{0},
      link_losses_{0};
  std::atomic<bool> xoff_held_{false};
};

// The controller's last status report as the sender received it (ack with status polling;
// docs/dnc-link.md, "The controller's own state"): the report as parsed, the work position the
// sender derives from it (WPos, or MPos less the last WCO: seen, or less nothing when none came:
// wco_known false), and when it arrived (steady clock). The sender's thread publishes each
// report; any other thread takes a copy under a short mutex (neither side is the 4 ms cycle).
struct ControllerReport {
  GrblStatus status;
  std::array<double, 3> work_mm{};
  bool wco_known = false;  // a WCO: (or WPos) was reported: work_mm is the controller's own
  std::chrono::steady_clock::time_point received;
  long reports = 0;  // status reports received in this run so far
};

class ControllerReportBox {
 public:
  void publish(const ControllerReport& r);
  std::optional<ControllerReport> last() const;

 private:
  mutable std::mutex mutex_;
  std::optional<ControllerReport> last_;
};

class DncSender {
 public:
  using EventFn = std::function<void(const SenderEvent&)>;
  using HoldFn = std::function<void(bool hold)>;
  // Told each time a program block becomes known executed (ack with status): how many are known
  // executed, and the last one's index (0-based). On the sender's thread.
  using ExecutedFn = std::function<void(std::int64_t executed, std::int64_t last_index)>;

  DncSender(const SenderSettings& settings, BlockSource& source, EventFn on_event = {});
  // Resume after a restart: skip (but checksum) the first `first_block` blocks, send no opening
  // framing, and keep `journal` (may be null) up to date.
  void resume_from(std::int64_t first_block);
  void set_journal(TransferJournal* journal) { journal_ = journal; }
  // Called when the link holds the motion (a long XOFF, CTS low, a lost port) and frees it.
  void on_hold(HoldFn fn) { on_hold_ = std::move(fn); }
  void on_executed(ExecutedFn fn) { on_executed_ = std::move(fn); }
  // The lines that end a job early, given where the controller stopped (work coordinates, mm;
  // none when not known): comms::ending_blocks of the job's toolpath::SafeRetract.
  using EndingFn =
      std::function<std::vector<std::string>(const std::optional<std::array<double, 3>>& at_mm)>;
  // ack (grbl) with status polling: end the stream now, safely (docs/dnc-link.md, "Ending
  // early"). No more program blocks are taken; once the link is ready the controller is held
  // (`!`), and when its status says Hold:0 (at rest: a reset then raises no ALARM:3) it is reset
  // (0x18: grbl drops what it queued, stops the spindle and coolant, keeps the position); after
  // its banner the lines ending(where the hold left the tool) are sent and their execution
  // followed to Idle. report.ending says how far it went. Callable from any thread, once (later
  // calls are ignored); drip ignores it (the caller appends its ending to the source).
  void end_with(EndingFn ending);
  // The motion that feeds the source is held (an operator's hold): a dry spell then, and its
  // continuation until the next block, is no underrun (the tool is at rest, nothing starves).
  // Callable from any thread.
  void set_source_held(bool held) { source_held_.store(held, std::memory_order_relaxed); }
  // Sends until the program is confirmed, an alarm, the link is given up, or stop is set.
  SenderReport run(const std::atomic<bool>& stop);
  // Brings grbl to a safe halt and ends run() as stopped: a feed hold `!`, a wait until the
  // status says the motion is at rest (Hold:0, or Idle; up to halt_timeout_s), then the soft
  // reset 0x18, which throws away every queued block without ALARM:3 (grbl raises it for a
  // reset in motion), and a status to confirm there is no alarm. SenderReport::halt says how it
  // went. Drip (no such commands): run() just stops. Callable from any thread (an atomic flag),
  // before or during run(); async-signal-safe.
  void request_halt() noexcept { halt_request_.store(true); }
  // The live counters of the run under way (or the last one); readable from any thread.
  const SenderCounters& counters() const { return counters_; }
  // The controller's last status report (ack with status polling); none before the first, and
  // in drip feed, which has none.
  std::optional<ControllerReport> controller_report() const { return reports_.last(); }

 private:
  SenderSettings settings_;
  BlockSource& source_;
  EventFn on_event_;
  HoldFn on_hold_;
  ExecutedFn on_executed_;
  TransferJournal* journal_ = nullptr;
  std::int64_t first_block_ = 0;
  SenderCounters counters_;
  ControllerReportBox reports_;
  std::atomic<bool> halt_request_{false};
  std::atomic<bool> ending_claimed_{false};  // end_with() was called
  EndingFn ending_;                          // then written, before end_requested_ is set
  std::atomic<bool> end_requested_{false};
  std::atomic<bool> source_held_{false};
};

}  // namespace ncd::comms
