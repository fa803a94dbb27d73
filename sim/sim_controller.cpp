// The simulated controller: a CNC's DNC port on a pseudo-terminal, one thread, one loop, on the
// wall clock or on a clock the caller injects (SimControllerConfig::clock, a ManualClock in the
// tests), so that pacing, execution and faults can be tested in simulated time. The protocols
// and what each guarantees are described in docs/dnc-link.md.
//
//   sender ─► pty slave ═ kernel ═► master ─► wire ─► receive buffer ─► (ack: planner) ─► executor
//                                  ≤ chars_per_s    buffer_bytes        planner_blocks   real time
//          ◄─ DC1 / DC3, NAK (drip)      ◄─ ok / error:N / ALARM:N (ack)
//
// 1. The wire. A pty has no baud rate, so the master is read no faster than the line would
//    deliver: chars_per_s(line) characters a second, each taken at the end of its frame. A
//    credit grows at chars_per_s while characters wait and drops to zero when the line goes
//    idle, so an idle line banks nothing and the first character after a pause costs a whole
//    character time; while the line is busy the credit is not capped, so a late wake-up of this
//    loop catches up as a UART's FIFO would, and never exceeds the line's rate overall. In drip
//    mode each character of such a burst keeps its own arrival time and the executor and the
//    flow control run between characters, as the controller's receive interrupt would have
//    them. A DC3 that was due more than kLateFlowS before the loop could send it, or before its
//    write reached the pty (the loop's thread kept from running in between) (xoff_late), holds
//    what the sender wrote before it could see it (the rest of the burst and what waits in
//    the kernel, no more than the line could carry meanwhile) until DC1, and those characters obey
//    every DC3 until they have all been read, as the sender's flow control would have had them: the
//    simulation's lateness is never blamed on the sender. A pty carries no framing, no parity and
//    no CTS: parity and stop bits only lengthen the character time, 7-bit frames are emulated by
//    masking the 8th bit, and --flow rtscts cannot stop the sender (there is no CTS line), so it
//    behaves as --flow none and the buffer can overflow.
// 2. The receive buffer holds the line being received and the complete lines not yet taken out,
//    CR and LF included; NULs (leader) are dropped on arrival, as a tape reader skips them. A
//    character that finds the buffer full is an overflow: alarm. A line longer than
//    max_block_chars is an error (ack: error:11) or an alarm (drip).
// 3. Drip: DC3 when the fill reaches xoff_at, DC1 when it falls to xon_at; a sender that
//    connects gets the current state first (DC1, ready, at the start); XOFF storms, holds and
//    alarms also assert DC3.
//    Ack (grbl 1.1): CR and LF each end a line (so CR LF is a line and an empty line, two oks).
//    A line is answered when it leaves the receive buffer: `ok` when a move enters the planner
//    queue (planner_blocks, 15 as grbl's, the executing block included), `ok` for a block
//    without motion once the planner has run empty and the block took effect (grbl
//    synchronises for M codes and G4; it does not for pure setup blocks, which the simulation
//    makes wait as well), `error:N` when it does not parse, `error:11` when more than 79
//    characters are left after removing spaces and comments. A sender counting characters
//    never overflows the buffer; one that does broke the rule: alarm. No DC1/DC3 in ack mode.
//    Real-time bytes are taken out of the stream as they arrive, like grbl's serial interrupt:
//    `?` answers `<State|MPos:x,y,z|Bf:free blocks,free bytes[|Ln:n]|FS:feed,0>` as grbl counts
//    (stepper.c, planner.c, serial.c): a move leaves the planner, and Bf:'s count and Ln:, when
//    its last 10 ms segment is prepared, up to 5 segments before the motion gets there (this
//    also frees its slot for the next line); the byte count is grbl's serial ring, which holds
//    only the bytes behind a line waiting for the planner (docs/dnc-link.md); the status mask
//    ($10, status_mask) chooses MPos or WPos and whether Bf: is there, FS: gives the spindle's
//    speed (0 when stopped), WCO: the work offset on the first report after a reset and every
//    10th (idle) or 30th (busy). `!` decelerates the move at hold_accel (Hold:1; a move that
//    cannot stop within itself runs to its end) and holds it at rest (Hold:0), when grbl's
//    protocol loop is suspended: no line is read until `~` (ignored before Hold:0) or a reset.
//    0x18 resets. A reset (also the injected fault, a power cycle, and with reset_on_open a
//    sender opening the port) aborts the block executing, throws away the planner, the receive
//    buffer and a partial line, stops the spindle and coolant, returns the parser to its
//    power-on modes at the machine's position (which a power-up restarts at 0), and after
//    boot_s (bytes received meanwhile are lost, counted as bytes_before_banner) sends the
//    banner, lost if the port is closed then; a reset in motion (before Hold:0) first says
//    ALARM:3 and locks the controller (error:9 for every g-code line) until `$X`. `$10=N` sets
//    the mask (error:8 unless Idle). N numbers are ignored.
// 4. Lines. LF ends a line; CR and NUL are removed, spaces and tabs trimmed at both ends. Empty
//    lines and `%` lines are framing: a `%` after a block on the current connection ends the
//    program; any other `%` opens it (again, from a sender that reconnected).
//    Every other line is a block, comments included. A repeated block is executed again; only
//    with skip_duplicate_n (drip) is a block whose N is not above the last accepted N
//    discarded, as a controller documented to skip repeated sequence numbers would. Accepted
//    blocks are hashed (SHA-256, each with one LF); M2/M30 end the program too. Lines after the
//    end are counted and ignored (ack: answered ok). Each block executed to its end is logged
//    (`executed`), so a test can compare what ran with the program.
// 5. Execution starts when the buffer is primed (ack: at once, as grbl's auto cycle start): the
//    fill reaches xoff_at, the program end has arrived, or prime_idle_s passed without a
//    character while a block waits. Then each block runs for its time (distance / F for G1, the
//    rapid rate for G0, P seconds for G4, none for the rest) back to back on exact times, so the
//    jitter of this loop does not accumulate. A block's characters leave the buffer when it starts
//    (drip). When the executor is free and the next block arrives later, before the program end
//    has, the tool dwells: an underrun, counted once per dry spell longer than underrun_grace_s.
//    Dry spells before the first move are not counted: the tool is not on the path yet, the
//    controller is reading the program's header (comment lines execute in no time).
//    Once started, execution never waits to be primed again.
// 6. Connections. The slave is watched with inotify. When the last sender closes it, what it
//    wrote is still read at line speed, then its unfinished line is discarded and replies owed
//    to it are dropped; a sender that connects gets a clean input queue and the flow state
//    first. A link drop (fault injection, after N blocks or N characters of lines) does the
//    same at once, and the bytes in flight are lost with the old pty. In ack (grbl) mode the
//    unfinished line is kept instead: grbl's UART knows nothing of the PC's port, and the next
//    characters, from any connection, complete it.
// 7. Dialects (config.dialect, docs/dnc-link.md "Dialects"). grbl: each line's verdict and
//    error number come from comms/dialect's check_grbl_line on the controller's own grbl state
//    (the sender's pre-check runs the same function), and the block executes as grbl would
//    (arcs timed by their helix length, G91, G20, offsets, G28/G30, G93); grbl reads no line
//    while a G4 or an M0 runs. iso/linuxcnc: a refused line is an alarm. Events (S, T, M6,
//    M3/M4/M5, M8/M9, G4 before the motion; M0/M1 after it; the program end) are logged at the
//    controller's times. M0 holds until cycle start (`~`, or cycle_start()); M6 takes
//    tool_change_s. Machine safety: a feed move with the spindle stopped is an alarm when it is
//    received (grbl has no such check).
//
// Where each part lives: this file the loop, construction and the public API; sim_impl.hpp the
// controller's state (SimController::Impl); sim_wire.cpp 1, the DC1/DC3 of 3, and 6;
// sim_receive_buffer.cpp 2 and 4; sim_grbl.cpp the grbl of 3 (planner, serial ring, `$` lines,
// status reports, feed hold, cycle start) and the resets of both protocols; sim_executor.cpp 5;
// sim_block.cpp the reading of a block; sim_faults.cpp the faults on a timer (storms, holds,
// noise); sim_config.cpp the settings' checks; sim_log_json.cpp the log as JSON; sim_port the
// pseudo-terminal and the loop's wake-up (SimPort): every read, write, flush and wait on them,
// so the model in the other files decides when and how many bytes to take and what to send,
// and never touches a descriptor.
#include "sim/sim_controller.hpp"

#include <algorithm>

#include "link/thread_priority.hpp"
#include "sim/sim_impl.hpp"

namespace ncd::comms {

namespace {

constexpr double kLoopPeriodS = 0.001;  // longest wait of the loop

}  // namespace

SimController::Impl::Impl(SimControllerConfig c)
    : cfg(checked(std::move(c))),
      drip(cfg.line.protocol == Protocol::Drip),
      xon_xoff(drip && cfg.line.flow == Flow::XonXoff),
      cps(chars_per_s(cfg.line)),
      xoff_at(*cfg.xoff_at),
      xon_at(*cfg.xon_at),
      max_block(max_block_chars(cfg)),
      rng(cfg.seed),
      port(cfg.line.device) {
  log.config = cfg;
  // The injected clock's zero is taken here, not in run(): a caller that advances the clock
  // right after construction must not race the thread that starts run().
  if (cfg.clock) clock_t0 = cfg.clock->now_s();
}

SimController::Impl::~Impl() = default;

double SimController::Impl::now_s() const {
  if (cfg.clock) return cfg.clock->now_s() - clock_t0;
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

void SimController::Impl::event(const std::string& text) {
  if (cfg.on_event) cfg.on_event(text);
}

void SimController::Impl::link_event(double t, const std::string& what) {
  log.link_events.push_back({t, what, port.device()});
}

void SimController::Impl::run() {
  t0 = Clock::now();
  link_event(0.0, "created");  // DC1 (ready) goes to each sender as it connects
  next_storm = uniform(0.05, 0.5);
  if (cfg.faults.noise_bytes_per_s > 0.0) {
    next_noise = std::exponential_distribution<>(cfg.faults.noise_bytes_per_s)(rng);
  }
  bool readable = false;
  for (;;) {
    double t = now_s();
    if (should_exit(t)) break;
    if (down_until && t >= *down_until) restore_link(t);
    if (booting_until && t >= *booting_until) boot_done();
    if (cycle_start_request.exchange(false)) cycle_start(t);
    if (port.is_open()) on_slave_events(t);
    receive(t, readable);
    flow(t);  // DC3 when the fill reached high water, before a block starting now frees room
    execute(t);
    faults(t);
    flow(t);
    publish();  // before the bytes go out, so a sender reading them sees this state
    flush_out();

    t = now_s();
    readable = port.wait(timeout(t), rx_idle, !out.empty());
  }
  finalize(now_s());
}

// Seconds until something is due, at most kLoopPeriodS.
double SimController::Impl::timeout(double t) const {
  double due = t + kLoopPeriodS;
  if (port.is_open() && !rx_idle) due = std::min(due, credit_t + (1.0 - credit) / cps);
  if (port.is_open() && rx_idle && !backlog.empty()) due = t;
  if (busy && !held) due = std::min(due, busy_end);
  if (booting_until) due = std::min(due, *booting_until);
  const double prime_t = log.last_byte_t_s + cfg.prime_idle_s;
  if (!started && prime_t > t) due = std::min(due, prime_t);
  if (down_until) due = std::min(due, *down_until);
  return std::max(0.0, due - t);
}

bool SimController::Impl::should_exit(double t) const {
  if (stop.load()) return true;
  if (!cfg.exit_at_end) return false;
  if (alarmed || alarm_exit) return t - alarm_t >= cfg.alarm_linger_s;
  // ack: the sender polls status until it has seen the end executed; wait for it to leave
  if (!drip && open_count > 0) return false;
  return log.program_end_executed && t - log.last_byte_t_s >= cfg.exit_quiet_s && out.empty();
}

void SimController::Impl::finalize(double t) {
  if (stop.load()) {
    log.stop_reason = "stop_requested";
  } else {
    log.stop_reason = alarmed || alarm_exit ? "alarm" : "program_end";
  }
  const auto& q = drip ? rx : planner;
  if (moved && !alarmed && !busy && q.empty() && !end_received &&
      t - free_at > cfg.underrun_grace_s) {
    add_underrun(free_at, t);  // still dry when stopped
  }
  log.duration_s = t;
  log.program_sha256 = sha.hex();
  if (log.bytes_received > 0) {
    log.reception_s = log.last_byte_t_s - log.first_byte_t_s;
    log.bytes_per_s = static_cast<double>(log.bytes_received) / log.reception_s;
    log.link_use = log.bytes_per_s / cps;
  }
  port.close();
  publish();
}

void SimController::Impl::publish() {
  live_bytes.store(log.bytes_received, std::memory_order_relaxed);
  live_blocks.store(log.blocks_received, std::memory_order_relaxed);
  live_executed.store(log.blocks_executed, std::memory_order_relaxed);
  live_drops.store(log.link_drops, std::memory_order_relaxed);
  live_alarms.store(static_cast<long>(log.alarms.size()), std::memory_order_relaxed);
  live_fill.store(fill, std::memory_order_relaxed);
  live_end_received.store(end_received, std::memory_order_relaxed);
  live_noise.store(log.noise_bytes_sent, std::memory_order_relaxed);
  live_sent.store(bytes_sent, std::memory_order_relaxed);
  live_t.store(now_s(), std::memory_order_relaxed);
  live_resets.store(static_cast<long>(log.resets.size()), std::memory_order_relaxed);
  const std::array<double, 3> p = position_at(now_s());
  for (std::size_t k = 0; k < 3; ++k) live_position[k].store(p[k], std::memory_order_relaxed);
  live_end_executed.store(log.program_end_executed, std::memory_order_release);
}

SimController::SimController(SimControllerConfig config)
    : impl_(std::make_unique<Impl>(std::move(config))) {}

SimController::~SimController() = default;

const SimControllerConfig& SimController::config() const {
  return impl_->cfg;
}

std::string SimController::device() const {
  return impl_->port.device();
}

void SimController::run() {
  // On a simulated clock (cfg.clock) nothing is late, and the loop, which polls for the time a
  // test's thread moves on, must not take the CPU from that thread: normal scheduling.
  const FifoPriority reception(impl_->cfg.clock ? 0 : impl_->cfg.fifo_priority);
  impl_->run();
}

void SimController::request_stop() noexcept {
  impl_->stop.store(true);
  impl_->port.wake();
}

void SimController::cycle_start() noexcept {
  impl_->cycle_start_request.store(true);
  impl_->port.wake();
}

void SimController::wake() noexcept {
  impl_->port.wake();
}

SimProgress SimController::progress() const noexcept {
  SimProgress p;
  p.program_end_executed = impl_->live_end_executed.load(std::memory_order_acquire);
  p.bytes_received = impl_->live_bytes.load(std::memory_order_relaxed);
  p.blocks_received = impl_->live_blocks.load(std::memory_order_relaxed);
  p.blocks_executed = impl_->live_executed.load(std::memory_order_relaxed);
  p.link_drops = impl_->live_drops.load(std::memory_order_relaxed);
  p.alarms = impl_->live_alarms.load(std::memory_order_relaxed);
  p.buffer_fill = impl_->live_fill.load(std::memory_order_relaxed);
  p.program_end_received = impl_->live_end_received.load(std::memory_order_relaxed);
  p.noise_bytes_sent = impl_->live_noise.load(std::memory_order_relaxed);
  p.bytes_sent = impl_->live_sent.load(std::memory_order_relaxed);
  p.t_s = impl_->live_t.load(std::memory_order_relaxed);
  p.resets = impl_->live_resets.load(std::memory_order_relaxed);
  for (std::size_t k = 0; k < 3; ++k) {
    p.position_mm[k] = impl_->live_position[k].load(std::memory_order_relaxed);
  }
  return p;
}

const SimLog& SimController::log() const {
  return impl_->log;
}

}  // namespace ncd::comms
