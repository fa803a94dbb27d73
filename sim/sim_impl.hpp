// The simulated controller's inside (SimController::Impl), shared by the files of sim/ that
// implement it, one concern each; the model is explained at the top of sim_controller.cpp.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <deque>
#include <optional>
#include <random>
#include <string>
#include <string_view>

#include "link/sha256.hpp"
#include "sim/sim_controller.hpp"
#include "sim/sim_port.hpp"

namespace ncd::comms {

// The straight distance between two points, mm.
inline double distance(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
}

struct SimController::Impl {
  using Clock = std::chrono::steady_clock;

  enum class Kind { Block, End, Framing, Duplicate, AfterEnd, Error, System };
  struct Line {
    Kind kind = Kind::Block;
    int size = 0;             // characters it holds in the receive buffer
    std::uint64_t epoch = 0;  // the connection it came on
    double ready_t = 0.0;     // when the executor may have it
    SimBlock block;
    int error = 0;
    std::string text;  // the block, for the executed log
    long seq = 0;      // blocks accepted when it was (1-based)
  };

  // ---- sim_controller.cpp: construction, time and the loop
  explicit Impl(SimControllerConfig c);
  ~Impl();
  double now_s() const;
  void event(const std::string& text);
  void link_event(double t, const std::string& what);
  void run();
  double timeout(double t) const;
  bool should_exit(double t) const;
  void finalize(double t);
  void publish();

  // ---- sim_wire.cpp: bytes out and flow control, connections, reception at the line's rate
  void send(std::string_view bytes);
  void send_flow(bool xoff);
  void reply(const Line& line, std::string_view text);
  void flush_out();
  void xoff_written(double t);
  void hold_late_written(double late_s);
  void flow(double t);
  void on_slave_events(double t);
  void sender_connected(double t);
  void sender_disconnected(double t);
  void apply_marker();
  void discard_partial();
  void drop_link(double t);
  void restore_link(double t);
  void receive(double t, bool readable);

  // ---- sim_receive_buffer.cpp: characters into lines, each line judged and queued
  void on_byte(char c, double t);
  void complete_line(double t);
  SimParse parse_grbl(const std::string& text, GrblState& st) const;
  void accept(const std::string& text, const SimBlock& b, double t);
  void receive_end(double t);
  void queue_line(Line line, double t);
  void raise_alarm(double t, const std::string& code, const std::string& detail);

  // ---- sim_grbl.cpp: grbl's planner, serial ring, `$` lines, status reports, hold, resume; resets
  std::size_t planner_count() const;
  std::size_t prepared(double t) const;
  std::size_t planner_held(double t) const;
  int ring_used() const;
  int ring_available() const;
  void pump_planner(double t);
  std::string system_command(const std::string& text, double t);
  std::array<double, 3> wco() const;
  std::string status_report(double t);
  void feed_hold(double t);
  void cycle_start(double t);
  void reset(double t, const std::string& cause);
  void boot_done();

  // ---- sim_executor.cpp: blocks executed on exact times; the position
  bool primed(double t) const;
  void execute(double t);
  void start_block(const Line& line, double start);
  bool pauses(const SimBlock& b) const;
  void block_events(const Line& line, double t);
  void finish(double t);
  void end_executed(double t);
  void add_underrun(double from, double to);
  std::array<double, 3> along(double s) const;
  std::array<double, 3> position_at(double t) const;
  bool hold_complete(double t) const;
  bool moving(double t) const;

  // ---- sim_faults.cpp: faults on a timer, noise
  double uniform(double lo, double hi);
  void faults(double t);
  std::string noise_bytes(std::size_t n);
  std::string noise_line(std::size_t n);

  // ---- the state
  const SimControllerConfig cfg;
  const bool drip, xon_xoff;
  const double cps;
  const int xoff_at, xon_at, max_block;
  std::mt19937_64 rng;
  SimPort port;  // the pty and the loop's wake-up: every byte in and out goes through it
  std::atomic<bool> stop{false};
  std::atomic<bool> cycle_start_request{false};
  Clock::time_point t0 = Clock::now();
  double clock_t0 = 0.0;
  SimLog log;
  std::uint64_t bytes_sent = 0;
  Sha256 sha;
  std::string out;

  // connection
  int open_count = 0;
  std::uint64_t rx_epoch = 0, reply_epoch = 0;
  std::optional<std::uint64_t> marker;  // bytes taken when the last sender's bytes are all read
  std::optional<double> down_until;
  bool drop_pending = false, alarm_pending = false, reset_pending = false;
  bool restart_pending = false, restarted = false;

  // wire
  std::array<char, 4096> buf{};
  bool rx_idle = true;
  double credit = 0.0, credit_t = 0.0;
  std::uint64_t taken = 0;
  std::string backlog;  // read off the pty ahead of the wire (a sender that left), taken first

  // receive buffer and parser
  std::string partial;
  int partial_chars = 0;  // without CR
  bool discarding_long = false;
  int fill = 0;
  std::uint64_t ring_in = 0;  // ack: characters put into grbl's serial ring, ever
  std::deque<Line> rx, planner;
  SimModal modal;
  GrblState grbl_state;
  bool end_received = false;
  double end_received_t = 0.0;
  long blocks_in_epoch = 0;

  // flow and faults
  bool fill_xoff = false, told_xoff = false;
  // Drip: the end (in bytes taken) of what the sender wrote before it could see a DC3 the loop
  // sent late; up to there the wire obeys DC3 as the sender would have.
  std::uint64_t late_written_end = 0;
  // Drip: where in `out` the last DC3 waits to be written, and when it was due.
  std::optional<std::size_t> xoff_at_out;
  double xoff_due_t = 0.0;
  std::optional<double> storm_until, hold_until;
  double next_storm = 0.0, next_noise = 0.0;
  bool alarmed = false;
  bool alarm_exit = false;  // with exit_at_end: an alarm was raised and not unlocked since
  double alarm_t = 0.0;
  std::optional<long> executed_at_last_report;  // blocks executed when the last report was sent

  // executor
  bool started = false, busy = false, moved = false;  // moved: a move has started
  double busy_end = 0.0, free_at = 0.0;
  SimBlock current;
  std::array<double, 3> position{0.0, 0.0, 0.0};
  std::optional<long> last_exec_n;
  std::string current_text;
  long current_seq = 0;
  std::array<double, 3> cur_from{}, hold_pos{};  // the move executing: from, and where held
  double cur_t0 = 0.0, cur_t1 = 0.0, remaining_s = 0.0;
  bool sync_busy = false;    // ack: the executor runs a dwell outside the planner
  bool held = false;         // ack: feed hold (!), decelerating or at rest
  bool hold_to_end = false;  // the held move cannot stop before its end: it runs to it
  double hold_t = 0.0, hold_done_t = 0.0;  // the `!`, and when the motion is at rest
  bool pausing = false;                    // a program stop (M0) waits for cycle start
  int exec_spindle = 5;                    // the spindle as executed: 3, 4 or 5
  bool exec_coolant = false;
  double exec_rpm = 0.0;
  bool grbl_locked = false;           // ack: alarm state after a reset in motion, until $X
  int status_mask = cfg.status_mask;  // grbl's $10
  int wco_countdown = 0;              // status reports until the next WCO: field
  std::optional<double> booting_until;

  // live view
  std::atomic<std::uint64_t> live_bytes{0};
  std::atomic<long> live_blocks{0}, live_executed{0}, live_drops{0}, live_alarms{0};
  std::atomic<int> live_fill{0};
  std::atomic<bool> live_end_received{false}, live_end_executed{false};
  std::atomic<std::uint64_t> live_noise{0}, live_sent{0};
  std::atomic<double> live_t{0.0};
  std::atomic<long> live_resets{0};
  std::array<std::atomic<double>, 3> live_position{};
};

}  // namespace ncd::comms
