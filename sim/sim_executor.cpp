// The simulated controller's executor (the model: sim_controller.cpp, 5): blocks run back to back
// on exact times, their events and underruns logged; the position along the move executing.

#include "sim/sim_impl.hpp"

#include <algorithm>

namespace ncd::comms {

bool SimController::Impl::primed(double t) const {
  const auto& q = drip ? rx : planner;
  const bool has_block = std::any_of(q.begin(), q.end(), [](const Line& l) {
    return l.kind == Kind::Block || l.kind == Kind::End;
  });
  if (!has_block) return false;
  if (!drip) return true;  // grbl starts a cycle as soon as a move is planned
  if (end_received || fill >= xoff_at) return true;
  if (!drip && planner.size() >= static_cast<std::size_t>(cfg.planner_blocks)) return true;
  return t - log.last_byte_t_s >= cfg.prime_idle_s;
}

void SimController::Impl::execute(double t) {
  if (alarmed) return;
  if (!started) {
    if (!primed(t)) return;
    started = true;
    free_at = t;
    log.execution_start_t_s = t;
  }
  if (!drip) pump_planner(t);
  for (;;) {
    if (busy) {
      // held: at rest mid-move; a hold that runs to the block's end lets the block finish
      if ((held && !hold_to_end) || busy_end > t || pausing) return;
      const bool answer = sync_busy;
      finish(busy_end);
      if (answer) send("ok\r\n");  // a dwell is answered when it is over
      if (!drip) pump_planner(busy_end);
      if (busy) continue;
    }
    if (held) return;
    auto& q = drip ? rx : planner;
    if (q.empty()) return;
    Line line = std::move(q.front());
    q.pop_front();
    if (drip) fill -= line.size;
    const double start = std::max(free_at, line.ready_t);
    if (moved && start - free_at > cfg.underrun_grace_s &&
        (!end_received || free_at < end_received_t)) {
      add_underrun(free_at, start);
    }
    free_at = start;
    if (line.kind == Kind::Block) {
      start_block(line, start);
    } else if (line.kind == Kind::End) {
      end_executed(start);
    }
  }
}

void SimController::Impl::start_block(const Line& line, double start) {
  busy = true;
  sync_busy = false;
  moved = moved || line.block.move;
  busy_end = start + line.block.duration_s;
  current = line.block;
  current_text = line.text;
  current_seq = line.seq;
  cur_from = position;
  cur_t0 = start;
  cur_t1 = busy_end;
  block_events(line, start);
}

// M0, or M1 with the optional-stop switch on (grbl ignores M1: "not supported" in gcode.c).
bool SimController::Impl::pauses(const SimBlock& b) const {
  return b.pause || (b.optional_stop && cfg.optional_stop && cfg.dialect != Dialect::grbl);
}

// The events a block executes before its motion (and, for a stop, after it).
void SimController::Impl::block_events(const Line& line, double t) {
  const SimBlock& b = line.block;
  const auto add = [&](const char* kind, double value, double at) {
    log.events.push_back({at, line.seq, b.n, kind, value});
  };
  if (b.spindle_rpm) {
    exec_rpm = *b.spindle_rpm;
    add("speed", exec_rpm, t);
  }
  if (b.tool) add("tool", *b.tool, t);
  if (b.tool_change) add("tool_change", cfg.tool_change_s, t);
  if (b.spindle && *b.spindle != exec_spindle) {
    exec_spindle = *b.spindle;
    add(exec_spindle == 3   ? "spindle_cw"
        : exec_spindle == 4 ? "spindle_ccw"
                            : "spindle_stop",
        exec_rpm, t);
  }
  if (b.coolant) {
    exec_coolant = *b.coolant;
    add(*b.coolant ? "coolant_on" : "coolant_off", 0.0, t);
  }
  if (b.dwell) add("dwell", b.duration_s, t);
  if (pauses(b)) {
    pausing = true;
    add("pause", 0.0, busy_end);
    event("program stop (M" + std::string(b.pause ? "0" : "1") + "): waiting for cycle start");
  } else if (b.optional_stop) {
    add("optional_stop_skipped", 0.0, busy_end);
  }
}

void SimController::Impl::finish(double t) {
  busy = false;
  sync_busy = false;
  free_at = t;
  ++log.blocks_executed;
  log.executed.push_back({current_seq, current.n, current_text, t});
  if (current.n) last_exec_n = current.n;
  if (current.program_end) {
    if (exec_spindle != 5) log.events.push_back({t, current_seq, current.n, "spindle_stop", 0.0});
    exec_spindle = 5;
    log.events.push_back({t, current_seq, current.n, "program_end", 0.0});
  }
  if (current.move) {
    log.path_length_mm += current.path_mm > 0.0 ? current.path_mm : distance(position, current.to);
    position = current.to;
    log.moves.push_back({current.to, current.feed_mm_per_min, current.g, current.n, t, current_seq,
                         current.rotary_axis, current.rotary_to_deg});
  }
  if (current.program_end) end_executed(t);
}

void SimController::Impl::end_executed(double t) {
  if (log.program_end_executed) return;
  log.program_end_executed = true;
  log.execution_end_t_s = t;
  event("program end executed");
}

void SimController::Impl::add_underrun(double from, double to) {
  ++log.underruns;
  log.dwell_s += to - from;
  log.underrun_events.push_back({from, log.blocks_executed, last_exec_n, to - from});
}

// The position of the move executing at time s, at full speed.
std::array<double, 3> SimController::Impl::along(double s) const {
  const double span = cur_t1 - cur_t0;
  const double f = span > 0.0 ? std::clamp((s - cur_t0) / span, 0.0, 1.0) : 1.0;
  std::array<double, 3> p{};
  for (std::size_t k = 0; k < 3; ++k) p[k] = cur_from[k] + f * (current.to[k] - cur_from[k]);
  return p;
}

std::array<double, 3> SimController::Impl::position_at(double t) const {
  if (!busy || !current.move) return position;
  if (held && !hold_to_end) {
    if (t >= hold_done_t) return hold_pos;
    // Decelerating at a = v/τ: after σ the move has covered v·(σ − σ²/2τ), what full speed
    // covers in σ − σ²/2τ.
    const double sigma = std::max(0.0, t - hold_t), tau = hold_done_t - hold_t;
    return along(hold_t + sigma - sigma * sigma / (2.0 * tau));
  }
  return along(t);
}

// A hold has brought the motion to rest (grbl's SUSPEND_HOLD_COMPLETE): Hold:0.
bool SimController::Impl::hold_complete(double t) const {
  return held && t >= hold_done_t;
}

// The machine moves at t: a move executing, not yet at rest in a hold. A reset now is a reset
// in motion (grbl's mc_reset: ALARM:3).
bool SimController::Impl::moving(double t) const {
  return busy && current.move && !sync_busy && t < busy_end && !hold_complete(t);
}

}  // namespace ncd::comms
