// A simulated CNC controller on a pseudo-terminal: the other end of `ncd stream`. It paces
// reception at the line's baud and frame, holds a receive buffer with DC1/DC3 flow control (drip)
// or models grbl 1.1 (ack: ok when queued, a 15-block planner, a 128-byte receive ring, 79
// characters a line, status reports, feed hold, cycle start and soft reset, a banner on reset),
// parses the blocks, executes them in (simulated or wall) time at their feed and records each
// block it executed. Faults (link cuts with the controller running, controller resets, XOFF
// storms and holds, noise, alarms) can be injected for the sender's tests. The model is
// explained at the top of sim_controller.cpp; the protocols in docs/dnc-link.md.
//
//   SimController sim(config);   // creates the pty and links it at config.line.device
//   std::thread t([&] { sim.run(); });
//   ... a sender opens config.line.device and streams ...
//   sim.request_stop(); t.join();
//   nlohmann::json log = to_json(sim.log());
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "gcode/dialect/dialect.hpp"
#include "link/line_settings.hpp"
#include "link/program_file.hpp"
#include "link/sim_clock.hpp"

namespace ncd::comms {

// Faults injected into the link, for the sender's tests. Block counts are accepted blocks
// (`blocks_received`); 0 turns a fault off. Each count-triggered fault happens once.
struct SimFaults {
  // Link cut, the controller keeps running: close the pty, unlink the path, relink a new pty.
  long drop_link_after_blocks = 0;
  double down_s = 1.0;  // ... after this long
  // The same cut after this many characters of lines (not real-time bytes, not NULs): it can
  // land in the middle of a block, leaving a half line (grbl keeps it; docs/dnc-link.md).
  long drop_link_after_chars = 0;
  bool xoff_storm = false;     // random DC3, held 20–300 ms, DC1, while receiving
  long hold_after_blocks = 0;  // then assert DC3 once for hold_s
  double hold_s = 10.0;
  double noise_bytes_per_s = 0.0;  // random bytes (drip) or garbage lines (ack) to the sender
  long alarm_after_blocks = 0;     // then raise an alarm and stop executing
  // Controller reset (watchdog, reset button): the block executing is aborted, the receive
  // buffer and the planner are lost, the position is kept, the banner is sent again (ack; after
  // ALARM:3 when it was moving, as grbl's reset during motion does).
  long reset_after_blocks = 0;
  // Ack: the controller restarts as at power-up while its USB link goes away (an Arduino's
  // serial port disappears when the board loses power): the link is cut as by
  // drop_link_after_blocks for down_s, the block executing is aborted, the planner, the receive
  // buffer and the parser state are lost, grbl's position restarts at 0 (a power-up clears it),
  // and its banner goes out while the port is closed, so a sender never sees it.
  long restart_after_blocks = 0;
};

struct SimControllerConfig {
  LineSettings line;     // line.device is the path of the link to create (a symbolic link)
  int buffer_bytes = 0;  // 0: 256 (drip) or grbl's 128 (ack)
  // High-water mark (DC3 when the fill reaches it); default buffer − min(64, buffer/4), which
  // leaves room for a sender that stops within 16 characters.
  std::optional<int> xoff_at;
  // Low-water mark (DC1 when the fill falls to it); default xoff_at / 2.
  std::optional<int> xon_at;
  int planner_blocks = 15;           // ack: grbl 1.1's planner (16 slots, 15 usable)
  double rapid_mm_per_min = 5000.0;  // G0
  double prime_idle_s = 0.5;         // execution starts after this long without a character
  double underrun_grace_s = 0.002;   // dry spells shorter than this are timer jitter, not counted
  bool exit_at_end = false;          // run() returns once the program end has been executed
  // run() runs at SCHED_FIFO this priority (a UART's reception is hard real time; above the
  // DNC sender's 60, below the cycle's 80), back to the thread's former scheduling after; 0:
  // normal scheduling. Refused, it runs at normal priority (link/thread_priority.hpp). Not
  // asked for on a simulated clock (`clock` set).
  int fifo_priority = 70;
  double exit_quiet_s = 0.2;    // ... and the line has been quiet this long
  double alarm_linger_s = 1.0;  // with exit_at_end: run() returns this long after an alarm
  std::uint64_t seed = 0;       // for the storm and noise faults
  // Drip: discard a block whose N is not above the last accepted N (a controller documented to
  // skip repeated sequence numbers). Off, a repeated block is executed again, as most do.
  bool skip_duplicate_n = false;
  // Ack: a sender opening the port resets the controller (an Arduino's DTR auto-reset), which
  // then boots for boot_s, losing what it receives meanwhile, and sends its banner.
  bool reset_on_open = false;
  double boot_s = 0.0;
  bool report_line_numbers = false;  // ack: status reports carry Ln: (grbl's USE_LINE_NUMBERS)
  // Ack: grbl's $10, the status report mask: bit 0 MPos (else WPos), bit 1 the Bf: field. grbl's
  // factory default is 1 (MPos, no Bf:); ncd's tracking wants 3. A `$10=N` line changes it.
  int status_mask = 3;
  // Ack: the deceleration of a feed hold (grbl's $120–$122 acceleration), mm/s². After `!` a
  // move slows down along its path (Hold:1) and stops (Hold:0), or, when it would not stop within
  // the block, runs to the block's end and stops there; a reset before then is in motion.
  double hold_accel_mm_per_s2 = 100.0;
  // The controller's dialect (gcode/dialect/dialect.hpp). grbl (ack only): every line gets
  // grbl 1.1's verdict and error number from check_grbl_line, and is executed as grbl would (arcs,
  // G91, G20, offsets, G28/G30, G4, M0, M2/M30). iso or linuxcnc (drip): a line the dialect refuses
  // is an alarm. Unset: the transport-test parser (G0/G1/G4, absolute mm, parse_sim_block).
  std::optional<Dialect> dialect;
  // With a dialect, machine safety: a feed move (G1 G2 G3) with the spindle stopped raises the
  // alarm spindle_stopped, as a machine's interlock would. grbl itself does not check this.
  bool machine_safety = true;
  double tool_change_s = 5.0;  // M6 (drip dialects; grbl refuses M6): the change takes this long
  bool optional_stop = false;  // M1 stops as M0 does (the operator's optional-stop switch)
  // The controller's time (link/sim_clock.hpp); null: the wall clock. A test gives a ManualClock
  // and moves it on, so that the controller runs in simulated time whatever the load.
  std::shared_ptr<const SimClock> clock;
  SimFaults faults;
  // Told of link events and alarms as they happen (on the thread of run()); may be empty.
  std::function<void(const std::string&)> on_event;
};

// Fills in the defaults and checks the ranges; throws InputError naming the value, the limit
// and the way out.
SimControllerConfig checked(SimControllerConfig config);
// The longest block (characters before CR/LF) the controller takes: 255, or less when the
// buffer could not otherwise hold a whole block below its high-water mark. In ack (grbl) mode
// this is the raw line the receive buffer can hold; grbl's own limit is kGrblLineChars.
int max_block_chars(const SimControllerConfig& config);

// grbl 1.1h's start-up line (report.c), without its leading CR LF.
inline constexpr const char* kGrblBanner = "Grbl 1.1h ['$' for help]";
// grbl's real-time commands, taken out of the stream as they arrive.
inline constexpr char kGrblStatus = '?', kGrblHold = '!', kGrblResume = '~', kGrblReset = 0x18;

// ---- Block parsing (one pure function, also used by the tests) ----

// grbl 1.1 error codes used in `error:N` replies.
enum SimError : int {
  kErrExpectedLetter = 1,  // a character that is not a word letter
  kErrBadNumber = 2,       // a letter without a number, or a malformed number
  kErrNegative = 4,        // negative F, S, T or P
  kErrIdle = 8,            // a $ command that needs Idle (or Alarm), e.g. $10= while moving
  kErrAlarmLock = 9,       // a line received while in alarm
  kErrLineOverflow = 11,   // more than 79 characters kept (grbl's line buffer)
  kErrUnsupported = 20,    // G91, G20, G2/G3, unknown G or M codes, unsupported letters
  kErrModalGroup = 21,     // two motion codes in one block
  kErrUndefinedFeed = 22,  // G1 with no F so far
  kErrNotInteger = 23,     // N, M or T with a fraction
  kErrRepeatedWord = 25,   // the same letter twice (G and M may repeat)
  kErrBadLineNumber = 27,  // N out of 0 … 99 999 999
  kErrMissingValue = 28,   // G4 without P
};

// Modal state a block is read against: G90 absolute mm only.
struct SimModal {
  std::array<double, 3> position{0.0, 0.0, 0.0};  // mm
  int motion = 0;                                 // 0 (G0), 1 (G1) or 80 (G80: none)
  double feed_mm_per_min = 0.0;                   // 0: not yet set
  int spindle = 5;                                // 3, 4 (turning) or 5 (stopped)
  // The rotary index axis ('A' or 'B', the first of the two a block names; 0: none yet) and its
  // angle, degrees (0 at power-up, as LinuxCNC's and ncd's interpreters start).
  char rotary_axis = 0;
  double rotary_deg = 0.0;
};

struct SimBlock {
  std::optional<long> n;         // the sequence number, when the block has one
  bool move = false;             // G0/G1 with an axis word
  bool dwell = false;            // G4
  int g = 0;                     // 0 or 1, for a move
  std::array<double, 3> to{};    // end point, mm
  double feed_mm_per_min = 0.0;  // feed of the move (the rapid rate for G0)
  double duration_s = 0.0;       // move or dwell (G4) time
  bool program_end = false;      // M2 or M30
  // Events, in the order a controller executes them: before the motion (S, T, M6, M3/M4/M5,
  // M8/M9, G4), then the motion, then the stops (M0, M1, M2/M30).
  std::optional<double> spindle_rpm;  // S
  std::optional<int> spindle;         // 3, 4 or 5
  std::optional<bool> coolant;        // M8 on, M9 off
  std::optional<int> tool;            // T
  bool tool_change = false;           // M6: takes tool_change_s (in duration_s)
  bool pause = false;                 // M0 (or M1 with optional_stop): waits for cycle start
  bool optional_stop = false;         // M1
  bool feed_move = false;             // G1 G2 G3: the spindle must turn (not probes)
  bool probe_must_touch = false;      // grbl G38.2/G38.4: no contact in a simulation, ALARM:5
  double path_mm = 0.0;               // length of the move (arcs: the helix)
  // An index of the rotary axis (A or B alone, X, Y, Z standing still): its axis and end angle;
  // it turns at the feed (degrees per minute) or, for G0, at the rapid rate taken as deg/min.
  char rotary_axis = 0;
  std::optional<double> rotary_to_deg;
};

struct SimParse {
  int error = 0;        // 0, or a SimError code
  std::string message;  // what was wrong, for the log
  SimBlock block;
};

// Reads one block (a line without its end of block; CR and NUL already removed) against
// `modal`, which is updated only when the block parses. Comments in parentheses and after `;`
// are ignored; letters may be lower case.
SimParse parse_sim_block(std::string_view text, SimModal& modal, double rapid_mm_per_min);

// ---- What a run did ----

struct SimMove {
  std::array<double, 3> p{};  // end point, mm
  double feed_mm_per_min = 0.0;
  int g = 1;
  std::optional<long> n;
  double t_s = 0.0;      // when the move ended, seconds since the controller started
  long seq = 0;          // the block (1-based, blocks accepted), as in SimExecuted and SimEvent
  char rotary_axis = 0;  // an index: 'A' or 'B'
  std::optional<double> rotary_deg;  // and the angle it ended at, degrees
};

struct SimAlarm {
  double t_s = 0.0;
  std::string code;       // overflow | injected | bad_block | block_too_long
  long block = 0;         // blocks received when it was raised
  std::optional<long> n;  // the last accepted sequence number
  std::string detail;
};

struct SimUnderrun {
  double t_s = 0.0;       // when the executor ran dry
  long block = 0;         // blocks executed by then
  std::optional<long> n;  // the sequence number of the last executed block
  double dwell_s = 0.0;
};

struct SimErrorReply {  // ack protocol: a line answered error:N
  double t_s = 0.0;
  long line = 0;  // lines received, this one included
  int code = 0;
  std::string text, message;
};

// A block the controller executed to its end (a move reached its end point, a dwell elapsed,
// a setup block took effect), in the order it did so.
struct SimExecuted {
  long seq = 0;  // blocks accepted by then, this one included (1-based)
  std::optional<long> n;
  std::string text;
  double t_s = 0.0;
};

// A controller reset: what it interrupted and what it threw away.
struct SimReset {
  double t_s = 0.0;
  // injected | soft_reset (0x18) | port_opened | power_cycle (restart_after_blocks)
  std::string cause;
  bool in_motion = false;              // grbl then raises ALARM:3 and locks until $X
  std::optional<std::string> aborted;  // the block executing, left unfinished
  std::array<double, 3> position{};    // where the motion stopped (grbl keeps it, except at
                                       // a power-up, after which it counts from 0)
  long blocks_lost = 0;                // in the planner and the receive buffer
  // The blocks executed when the last status report before the reset was sent (the most a
  // sender reading every report can know executed); none if no report was sent.
  std::optional<long> executed_at_last_report;
};

// An event the controller executed (spindle, coolant, tool, dwell, stops, program end), at its
// simulated time: spindle_cw | spindle_ccw | spindle_stop | speed | coolant_on | coolant_off |
// tool | tool_change | dwell | pause | resume | optional_stop_skipped | program_end, and
// feed_hold (ack: a `!` that stopped the motion, at the time and place it stopped).
struct SimEvent {
  double t_s = 0.0;
  long seq = 0;  // the block (1-based, blocks accepted)
  std::optional<long> n;
  std::string kind;
  double value = 0.0;  // rpm, tool number or seconds
};

struct SimLinkEvent {
  double t_s = 0.0;
  std::string event;  // created | sender_connected | sender_disconnected | down | up
  std::string device;
};

struct SimLog {
  SimControllerConfig config;  // as checked, defaults filled in
  std::string stop_reason;     // stop_requested | program_end | alarm
  double duration_s = 0.0;
  long lines_received = 0, blocks_received = 0, blocks_executed = 0, framing_lines = 0;
  long duplicates_discarded = 0, blocks_rejected = 0, lines_after_end = 0;
  long partial_lines_discarded = 0;
  std::string program_sha256;
  bool program_end_received = false, program_end_executed = false;
  std::optional<long> first_n, last_n;
  std::uint64_t bytes_received = 0, nul_received = 0, bytes_after_alarm = 0;
  double first_byte_t_s = 0.0;  // when the first character started on the line
  double last_byte_t_s = 0.0;   // when the last one was taken (the end of its frame)
  double reception_s = 0.0;     // last_byte_t_s − first_byte_t_s
  double bytes_per_s = 0.0, link_use = 0.0;
  int max_buffer_fill = 0;
  long max_planner_blocks = 0;
  double execution_start_t_s = -1.0, execution_end_t_s = -1.0;
  long underruns = 0;
  double dwell_s = 0.0;
  std::vector<SimUnderrun> underrun_events;
  std::vector<SimAlarm> alarms;
  std::vector<SimErrorReply> errors;
  long xoff_sent = 0, xon_sent = 0, xoff_storms = 0, holds = 0;
  long xoff_late = 0;  // DC3s the loop sent late, with the wire paused till then (drip)
  std::uint64_t noise_bytes_sent = 0;
  long link_drops = 0, sender_connects = 0, sender_disconnects = 0;
  std::vector<SimLinkEvent> link_events;
  std::vector<SimMove> moves;
  double path_length_mm = 0.0;
  std::vector<SimExecuted> executed;
  std::vector<SimEvent> events;
  std::vector<SimReset> resets;
  long status_reports = 0, feed_holds = 0, cycle_starts = 0;
  long unlocks = 0;                       // ack: `$X` lines that cleared an alarm lock
  std::uint64_t bytes_before_banner = 0;  // ack: received while booting, before the banner
  long banners_sent = 0;
  long banners_lost = 0;  // sent while the port was closed or no sender had it open
};

// The log as the JSON `--log` writes (field names in docs/cmd-sim-controller.md).
nlohmann::json to_json(const SimLog& log);
// The settings part of it.
nlohmann::json settings_json(const SimControllerConfig& config);

// A live view of a run, readable from any thread.
struct SimProgress {
  std::uint64_t bytes_received = 0;
  long blocks_received = 0, blocks_executed = 0, link_drops = 0, alarms = 0;
  int buffer_fill = 0;
  bool program_end_received = false, program_end_executed = false;
  std::uint64_t noise_bytes_sent = 0, bytes_sent = 0;  // bytes_sent: written to the pty
  double t_s = 0.0;                                    // the controller's time
  long resets = 0;
  // The machine position at t_s (MPos): where the move executing (or its hold) has got to.
  std::array<double, 3> position_mm{};
};

class SimController {
 public:
  // Checks the config (InputError), creates the pty and links it at config.line.device.
  explicit SimController(SimControllerConfig config);
  ~SimController();
  SimController(const SimController&) = delete;
  SimController& operator=(const SimController&) = delete;

  // The checked config (defaults filled in).
  const SimControllerConfig& config() const;
  // The slave the link points at now. Call before run() or after it returns.
  std::string device() const;

  // Runs until request_stop(), or with exit_at_end until the program end has been executed (or
  // an alarm stopped the controller). Closes the pty and removes the link before returning.
  // Call once.
  void run();
  // Makes run() return soon. Async-signal-safe; callable from any thread.
  void request_stop() noexcept;
  // The cycle-start button: resumes a program stopped by M0 (and M1 with optional_stop), as `~`
  // does on the grbl link. Async-signal-safe; callable from any thread.
  void cycle_start() noexcept;
  // Runs the loop now instead of at its next wait's end (at most kLoopPeriodS of wall time): for
  // a test that has moved the controller's ManualClock on (tests/common/paced_controller.hpp).
  // Async-signal-safe; callable from any thread.
  void wake() noexcept;
  SimProgress progress() const noexcept;
  // What the run did; complete once run() has returned.
  const SimLog& log() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace ncd::comms
