// The DNC sender's session, private to link/: one DncSender::run(), its state and its steps.
// The algorithm is explained once, at the top of dnc_sender.cpp (and in docs/dnc-link.md). The
// steps are defined by concern: dnc_sender.cpp (the run loop, taking blocks, the report),
// dnc_drip.cpp (drip feed: the wire model, DC1/DC3 and CTS), dnc_ack.cpp (grbl: character
// counting, ok/error, status reports and what they say is executed), dnc_startup.cpp (grbl:
// nothing before the controller has spoken), dnc_resume.cpp (a lost link, resuming, the
// journal), dnc_ending.cpp (ending early, the safe halt, the ways a job stops).
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/number_text.hpp"
#include "gcode/dialect/dialect.hpp"
#include "gcode/dialect/program_modal.hpp"
#include "link/dnc_sender.hpp"
#include "link/serial_link.hpp"
#include "link/sha256.hpp"

namespace ncd::comms::dnc_detail {

using Clock = std::chrono::steady_clock;
using text::fixed;
using Xyz = std::array<double, 3>;  // a position as grbl reports it (MPos, WPos), mm

constexpr std::int64_t kFraming = -1;        // % and NUL leader
constexpr std::int64_t kPreamble = -2;       // restart lines
constexpr std::int64_t kFlush = -3;          // ack: the line grbl must refuse (error:11)
constexpr std::int64_t kEnding = -4;         // ack: a line of the ending after a reset
constexpr double kEndingHoldTimeoutS = 5.0;  // `!` to Hold:0 at most
constexpr double kPositionTolMm = 0.002;     // grbl reports 3 decimals
// grbl 1.1's step segment buffer holds 5 segments (stepper.c, SEGMENT_BUFFER_SIZE − 1), each of
// one block: up to 5 moves that left the planner (Bf:, Ln:) may still be running.
constexpr std::size_t kGrblSegments = 5;
// The line that ends a half line an earlier connection may have left in grbl's line buffer
// without letting it run: grbl stores `)` as a character (after closing an open `(` comment),
// and a block holding `)` is refused whole (error:1, or error:2 after a letter, error:11 at the
// limit), so nothing of the half line runs. Only a half line inside a `;` comment, whose code
// arrived whole, swallows it and is queued (ok). docs/dnc-link.md, "A half line".
constexpr const char* kFlushText = "))";
constexpr char kResetByte = 0x18;  // grbl's soft reset (real-time)

// The program's spindle turns after a block: M3 or M4 with a speed above 0.
inline bool spins(const ModalState& m) {
  return m.spindle != 5 && m.speed_rpm.value_or(0.0) > 0.0;
}

struct Item {
  std::int64_t index = kFraming;  // program block, or one of the negative kinds
  bool closing = false;           // the closing `%`
  std::string bytes;              // with end of block
  double end_mark = -1.0;         // bytes written on this connection when its last byte went out
  BlockMotion geo;                // what the block does
  std::optional<long> n;          // its N
  bool spindle_on = false;        // the program's spindle turns (M3/M4 at S > 0) after it
  double wait_s = 0.0;            // the controller waits this long for it (wait_of_block)
};

inline double dist(const Xyz& a, const Xyz& b) {
  return std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
}

// Distance from p to the segment a–b, and where along it (0 at a, 1 at b).
inline double to_segment(const Xyz& p, const Xyz& a, const Xyz& b, double& u) {
  Xyz d{b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double len2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  u = len2 > 0.0 ? ((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1] + (p[2] - a[2]) * d[2]) / len2
                 : 0.0;
  u = std::clamp(u, 0.0, 1.0);
  const Xyz q{a[0] + u * d[0], a[1] + u * d[1], a[2] + u * d[2]};
  return dist(p, q);
}

// One run() of DncSender: the connection, the blocks in flight, what the controller has, and the
// report. Its steps are defined in the files named at the top of this header.
class Session {
 public:
  Session(const SenderSettings& s, BlockSource& source, const DncSender::EventFn& on_event,
          const DncSender::HoldFn& on_hold, TransferJournal* journal, std::int64_t first_block,
          SenderCounters& counters, ControllerReportBox& reports,
          const std::atomic<bool>& halt_request, const std::atomic<bool>& end_requested,
          const DncSender::EndingFn& ending, const std::atomic<bool>& source_held);

  void on_executed(DncSender::ExecutedFn fn) { on_executed_ = std::move(fn); }
  SenderReport run(const std::atomic<bool>& stop);

 private:
  enum class Phase { Startup, Ready, Recovering };
  enum class Ending { None, NotNeeded, Holding, Resetting, Sending };
  // After a lost link (decide_resume): the blocks the controller may hold, oldest first: the
  // queued ones (answered ok), then the lines written on the lost connection.
  struct ResumeCandidates {
    std::vector<const Item*> items;
    std::size_t queued = 0;   // the first `queued` of items were answered ok
    std::size_t written = 0;  // lines written on the lost connection (a partial one too)
  };

  double now_s() const { return std::chrono::duration<double>(Clock::now() - t0_).count(); }
  double hold_now_s() const { return s_.hold_clock ? s_.hold_clock->now_s() : now_s(); }
  double wire_now_s() const { return s_.wire_clock ? s_.wire_clock->now_s() : now_s(); }
  bool over() const { return !report_.failure.empty(); }
  bool status_known() const { return s_.status_hz > 0.0 && status_.supported; }

  // dnc_sender.cpp: the run loop, taking blocks, the report
  void publish();
  void watch_underrun();
  void emit(SenderEvent::Kind kind, std::int64_t block, std::string text);
  void set_hold(bool hold);
  bool step();
  int wait_ms() const;
  bool done() const;
  void read_input();
  void interrupt(const std::string& why);
  void noise(std::size_t bytes, char c);
  static std::string hex_byte(char c);
  bool pull();
  void written(const Item& it);
  bool reopen(const std::atomic<bool>& stop);
  void progress();
  void finish();

  // dnc_drip.cpp: drip feed (the wire model, DC1/DC3, CTS)
  double delivered() const;
  void advance_model();
  void drip_byte(char c);
  void end_xoff();
  void alarm(const std::string& text);
  void watch_hold();
  double explained_wait_s();
  void write_drip();
  void confirm_drip();
  void drain_on_stop();
  void wait_for_a_word();
  std::int64_t bytes_in_flight() const;

  // dnc_ack.cpp: acknowledged streaming (grbl): lines, answers, status tracking
  void ack_byte(char c);
  static bool is_banner(const std::string& line);
  void ack_line(const std::string& line);
  void half_line_queued();
  static std::string trim_eob(std::string s);
  void take_ok();
  void queue_item(Item it);
  void executed(const Item& it);
  void pop_done(std::size_t moves);
  std::size_t queued_moves() const;
  Xyz work_position(const GrblStatus& st);
  void on_status(const GrblStatus& st);
  void track(const GrblStatus& st, const Xyz& pos);
  void basis(const char* how);
  void poll_status();
  void write_raw(std::string_view bytes);
  void write_ack();

  // dnc_startup.cpp: grbl start-up
  void startup_line(const std::string& line);
  void startup();
  void wake();
  void start_state(std::string state);

  // dnc_resume.cpp: a lost link, resuming, the journal
  void recovering();
  void decide_resume(const GrblStatus& st, const Xyz& pos);
  bool buffers_countable(const GrblStatus& st, const std::string& where);
  ResumeCandidates resume_candidates() const;
  bool restarted_unseen(const ResumeCandidates& c, const GrblStatus& st, const std::string& where);
  std::optional<long> last_received(const ResumeCandidates& c, std::size_t held, const Xyz& pos,
                                    const std::string& where);
  std::optional<long> last_received_at_rest(const ResumeCandidates& c, const Xyz& pos,
                                            const std::string& where);
  std::optional<long> last_received_in_motion(const ResumeCandidates& c, std::size_t held,
                                              const Xyz& pos, const std::string& where);
  bool holds_what_was_queued(const ResumeCandidates& c, long last, const std::string& where);
  void resume_after(const ResumeCandidates& c, long last, std::size_t held, const GrblStatus& st,
                    const std::string& where);
  std::int64_t resume_point() const;
  std::int64_t first_unexecuted() const;
  void confirm_journal();
  void lost_link(const std::string& why);

  // dnc_ending.cpp: ending early, the safe halt, stopping
  void begin_ending();
  void ending_step();
  void reset_for_ending();
  void ending_line(const std::string& line);
  void send_ending();
  std::string held_position_doubt(const Xyz& pos) const;
  void fail_ending(const std::string& why);
  void controller_reset(const std::string& why);
  void stop_controller(const std::string& why);
  void give_up(const std::string& why);
  void halt_on_request();
  static bool at_rest(const std::string& state);
  static std::string halt_text(const HaltReport& h);
  HaltReport safe_halt();
  void read_state();
  void dropped_note(std::int64_t first);

  const SenderSettings& s_;
  BlockSource& source_;
  const DncSender::EventFn& on_event_;
  const DncSender::HoldFn& on_hold_;
  DncSender::ExecutedFn on_executed_;
  TransferJournal* journal_;
  SenderCounters& counters_;
  ControllerReportBox& reports_;
  const std::atomic<bool>& halt_request_;
  const std::atomic<bool>& end_requested_;
  const DncSender::EndingFn& ending_fn_;
  const std::atomic<bool>& source_held_;
  // ack: ending early (end_with; dnc_ending.cpp).
  struct EndingState {
    Ending step = Ending::None;
    double t0_s = 0.0;                   // the step began (now_s)
    std::int64_t first_unexecuted = -1;  // at the reset for the ending
  } end_;
  bool motion_written_ = false;  // a line with motion went out
  const bool ack_;
  const double cps_;
  const int window_;

  std::unique_ptr<SerialLink> link_;
  std::deque<Item> items_;      // not yet answered (ack) or delivered (drip), oldest first
  std::deque<Item> queued_;     // ack: answered ok, not known executed
  std::size_t sent_items_ = 0;  // items at the front fully written on this connection
  std::size_t cur_off_ = 0;     // bytes of items_[sent_items_] written
  std::int64_t conn_written_ = 0;
  double model_delivered_ = 0.0;
  int outq_ = 0;
  int unacked_bytes_ = 0;
  std::string line_;
  std::int64_t next_index_ = 0;
  std::int64_t skip_until_ = 0;
  std::int64_t sent_high_ = 0;
  std::int64_t executed_count_ = 0, last_executed_ = -1;
  ProgramModal modal_;
  bool source_done_ = false;
  bool source_waiting_ = false;
  bool dry_ = false;  // in an underrun (watch_underrun)
  std::int64_t underruns_ = 0;
  std::int64_t noise_events_ = 0;
  bool xon_ = true;
  bool heard_ = false;
  bool draining_ = false;  // drip: stopping, only the block begun is finished  // a byte came from
                           // the controller (or CTS was seen asserted)
  // Blocks that make the controller wait, written lately: bytes_written after them, their wait.
  struct WaitMark {
    std::int64_t at_byte = 0;
    double wait_s = 0.0;
  };
  std::deque<WaitMark> waits_;
  double xoff_since_s_ = 0.0;
  bool xoff_reported_ = false;
  bool cts_low_ = false;
  double cts_low_since_s_ = 0.0;
  bool holding_ = false;
  bool opened_once_ = false;
  bool opened_once_before_ = false;  // ack: a connection carried blocks before this one
  Phase phase_ = Phase::Startup;
  double phase_t0_ = 0.0;
  // ack start-up (dnc_startup.cpp): the wake-up line was sent; the controller spoke (banner,
  // status, answer); `?` asked; the wake-up line and `$X` await their answers; `$X` was sent; a
  // hold met at start-up was halted; status polls.
  struct AckStartup {
    bool woke = false;
    bool spoke = false, asked = false, wake_pending = false, unlock_pending = false;
    bool unlock_tried = false, halted = false;
    int polls = 0;
  } start_;
  // A line (anything but real-time bytes) was written on the first connection.
  bool wrote_line_ = false;
  std::string rejected_reply_;    // the error:N of the rejected block
  bool last_spindle_on_ = false;  // after the last block known executed
  std::optional<Xyz> last_end_;   // where the last move known executed ended
  bool stopping_ = false, reset_seen_ = false, track_ok_ = true;
  // ack: grbl's status reports (dnc_ack.cpp): it answers `?`; a report came since asked; polls
  // sent; the next poll; the last report, its work position and the last work offset (WCO:).
  struct StatusReports {
    bool supported = true, have = false, wco_known = false;
    long polls = 0;
    double next_poll_s = 0.0;
    std::optional<GrblStatus> last;
    Xyz position{}, wco{};
  } status_;
  std::int64_t journaled_ = -1;
  double journal_at_s_ = -1.0;
  double next_progress_s_ = 1.0;
  Clock::time_point t0_;
  double last_tick_s_ = 0.0;  // wire_now_s() at the wire model's last advance
  Sha256 sha_;
  DialectState dialect_state_;
  SenderReport report_;
};

}  // namespace ncd::comms::dnc_detail
