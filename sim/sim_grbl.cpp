// The simulated grbl (ack; the model: sim_controller.cpp, 3): its planner and serial ring, `$`
// commands, status reports, feed hold and cycle start; and the controller reset of both protocols.

#include "sim/sim_impl.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>

namespace ncd::comms {

namespace {

// grbl 1.1's step segment buffer (stepper.c): SEGMENT_BUFFER_SIZE 6, of which 5 hold segments,
// each at most DT_SEGMENT = 1/(ACCELERATION_TICKS_PER_SECOND·60) min = 10 ms of motion.
constexpr int kGrblSegments = 5;
constexpr double kGrblSegmentS = 0.01;

}  // namespace

// Blocks in grbl's planner: the queue and the move executing.
std::size_t SimController::Impl::planner_count() const {
  return planner.size() + (busy && !sync_busy ? 1 : 0);
}

// grbl's stepper prepares up to kGrblSegments segments of kGrblSegmentS ahead of the motion
// and discards a planner block once its last segment is prepared (st_prep_buffer): the blocks
// counted here (the executing one first, then the queue) have left the planner while their
// motion still runs. None while held (grbl re-plans a hold's remainder) or idle.
std::size_t SimController::Impl::prepared(double t) const {
  if (!busy || sync_busy || held || !current.move) return 0;
  const auto segments = [](double s) {
    return std::max(1, static_cast<int>(std::ceil(s / kGrblSegmentS - 1e-9)));
  };
  int used = segments(busy_end - t);
  if (used > kGrblSegments) return 0;
  std::size_t n = 1;
  for (const Line& l : planner) {
    used += l.block.move ? segments(l.block.duration_s) : 0;
    if (used > kGrblSegments) break;
    ++n;
  }
  return n;
}

// Blocks in grbl's planner ring (what Bf: counts and what bounds it): not yet prepared.
std::size_t SimController::Impl::planner_held(double t) const {
  return planner_count() - prepared(t);
}

// grbl's serial ring (serial.c): the protocol loop takes characters out as they come, into its
// line buffer, except while a complete line waits for room in the planner (or for it to run
// empty): the bytes behind that line stay in the ring. A line being assembled is not in it.
int SimController::Impl::ring_used() const {
  return rx.empty() ? 0 : std::max(0, fill - rx.front().size);
}

// serial_get_rx_buffer_available(): RX_BUFFER_SIZE − used with the head at or past the tail,
// one less once the head has wrapped behind it.
int SimController::Impl::ring_available() const {
  const int size = cfg.buffer_bytes;
  const auto head = static_cast<int>(ring_in % static_cast<std::uint64_t>(size));
  const auto tail = static_cast<int>((ring_in - static_cast<std::uint64_t>(ring_used())) %
                                     static_cast<std::uint64_t>(size));
  return head >= tail ? size - (head - tail) : tail - head - 1;
}

// Ack: answers the lines at the head of the receive buffer, moving blocks into the planner.
void SimController::Impl::pump_planner(double t) {
  // grbl executes G4 and M0 inside gc_execute_line (mc_dwell, the suspend loop): it reads no
  // further line until they are over.
  // A complete hold suspends grbl's protocol loop (protocol_exec_rt_suspend): no line is read
  // until cycle start or a reset.
  if (hold_complete(t)) return;
  while (!rx.empty() && !alarmed && !(busy && sync_busy)) {
    Line& line = rx.front();
    if (line.kind == Kind::Block && !line.block.move) {
      // grbl synchronises: the block waits for the planner to run empty, then takes effect.
      if (!planner.empty() || busy || held || pausing) return;
      if (!started) {
        started = true;
        log.execution_start_t_s = t;
      }
      fill -= line.size;
      if (line.block.dwell || pauses(line.block) || line.block.tool_change) {
        // answered once the dwell, the stop or the tool change is over
        start_block(line, t);
        sync_busy = true;
        rx.pop_front();
        return;
      }
      current = line.block;
      current_text = line.text;
      current_seq = line.seq;
      block_events(line, t);
      finish(t);
      reply(line, "ok\r\n");
      rx.pop_front();
      continue;
    }
    if (line.kind == Kind::Block || line.kind == Kind::End) {
      if (planner_held(t) >= static_cast<std::size_t>(cfg.planner_blocks)) return;
      line.ready_t = t;
      reply(line, "ok\r\n");
      fill -= line.size;
      planner.push_back(std::move(line));
      log.max_planner_blocks = std::max(log.max_planner_blocks, static_cast<long>(planner_held(t)));
    } else if (line.kind == Kind::System) {
      reply(line, system_command(line.text, t));
      fill -= line.size;
    } else {
      reply(line, line.kind == Kind::Error ? "error:" + std::to_string(line.error) + "\r\n"
                                           : std::string("ok\r\n"));
      fill -= line.size;
    }
    rx.pop_front();
  }
}

// A grbl `$` line as system.c executes it, when the protocol loop reads it: `$X` clears an
// alarm lock (and does nothing otherwise), `$10=N` sets the status report mask (Idle or Alarm
// only: error:8 while the machine runs or holds). Others are not modelled: error:1.
std::string SimController::Impl::system_command(const std::string& text, double t) {
  std::string up = text;
  for (char& c : up) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  const auto fail = [&](int code, const std::string& why) {
    log.errors.push_back({t, log.lines_received, code, text, why});
    ++log.blocks_rejected;
    return "error:" + std::to_string(code) + "\r\n";
  };
  if (up == "$X") {
    if (grbl_locked) {
      grbl_locked = false;
      alarm_exit = false;
      ++log.unlocks;
      send("[MSG:Caution: Unlocked]\r\n");
      event("unlocked ($X)");
    }
    return "ok\r\n";
  }
  if (up.rfind("$10=", 0) == 0) {
    int mask = -1;
    const auto r = std::from_chars(up.data() + 4, up.data() + up.size(), mask);
    if (r.ec != std::errc() || r.ptr != up.data() + up.size() || mask < 0 || mask > 255) {
      return fail(3, "$10 takes a number from 0 to 255");
    }
    if (busy || !planner.empty() || held || pausing) {
      return fail(kErrIdle, "$10= while the machine runs or holds (grbl wants Idle)");
    }
    status_mask = mask;
    return "ok\r\n";
  }
  return fail(kErrExpectedLetter, "not a block (only $X and $10= are modelled)");
}

// grbl's work coordinate offset (report.c): the coordinate system in use, G92 and the tool
// length offset on Z. Zero without the grbl dialect (the transport parser has no offsets).
std::array<double, 3> SimController::Impl::wco() const {
  std::array<double, 3> w{};
  if (cfg.dialect != Dialect::grbl) return w;
  const auto& cs = grbl_state.coord_system[static_cast<std::size_t>(grbl_state.coord_select)];
  for (std::size_t k = 0; k < 3; ++k) w[k] = cs[k] + grbl_state.g92[k];
  w[2] += grbl_state.tool_length_mm;
  return w;
}

std::string SimController::Impl::status_report(double t) {
  std::string s = "<";
  if (alarmed || grbl_locked) {
    s += "Alarm";
  } else if (held) {
    s += hold_complete(t) ? "Hold:0" : "Hold:1";  // 1: decelerating; 0: at rest, can resume
  } else if (busy && pausing && busy_end <= t) {
    s += "Hold:0";
  } else {
    s += busy || !planner.empty() ? "Run" : "Idle";
  }
  // $10 bit 0: MPos, else WPos (the machine position less the work offset); bit 1: Bf:.
  auto p = position_at(t);
  const auto w = wco();
  const bool mpos = (status_mask & 1) != 0;
  if (!mpos) {
    for (std::size_t k = 0; k < 3; ++k) p[k] -= w[k];
  }
  std::array<char, 96> text{};
  std::snprintf(text.data(), text.size(), "|%s:%.3f,%.3f,%.3f", mpos ? "MPos" : "WPos", p[0], p[1],
                p[2]);
  s += text.data();
  if ((status_mask & 2) != 0) {
    std::snprintf(text.data(), text.size(), "|Bf:%d,%d",
                  cfg.planner_blocks - static_cast<int>(planner_held(t)), ring_available());
    s += text.data();
  }
  // grbl reports the line number of the planner's current block: the first not prepared.
  if (cfg.report_line_numbers && planner_held(t) > 0) {
    const std::size_t k = prepared(t);
    const bool executing = busy && !sync_busy;
    const SimBlock& b = k == 0 && executing ? current : planner[k - (executing ? 1 : 0)].block;
    if (b.n && *b.n > 0) s += "|Ln:" + std::to_string(*b.n);
  }
  // FS: the feed now (falling during a hold's deceleration) and the spindle's speed (0 when
  // stopped: sys.spindle_speed).
  double feed = 0.0;
  if (busy && current.move && !sync_busy && t < busy_end && !held) {
    feed = current.feed_mm_per_min;
  } else if (held && !hold_complete(t) && busy && current.move) {
    feed = hold_to_end ? current.feed_mm_per_min
                       : current.feed_mm_per_min * (1.0 - (t - hold_t) / (hold_done_t - hold_t));
  }
  std::snprintf(text.data(), text.size(), "|FS:%.0f,%.0f", feed,
                exec_spindle != 5 ? exec_rpm : 0.0);
  s += text.data();
  // WCO: on the first report after a reset, then every 10th (idle) or 30th (busy), as grbl.
  if (wco_countdown > 0) {
    --wco_countdown;
  } else {
    wco_countdown = busy || held ? 29 : 9;
    std::snprintf(text.data(), text.size(), "|WCO:%.3f,%.3f,%.3f", w[0], w[1], w[2]);
    s += text.data();
  }
  return s + ">\r\n";
}

// `!`: grbl decelerates a move along its path (Hold:1) and holds at rest (Hold:0); idle, or
// in a dwell, the hold is complete at once. This model slows down within the move executing:
// a move that cannot stop before its end runs to its end at its feed and holds there (grbl
// would decelerate through the next blocks, a difference that only moves where it stops).
void SimController::Impl::feed_hold(double t) {
  ++log.feed_holds;
  if (held || alarmed || grbl_locked) return;  // grbl ignores a hold in alarm
  const bool was_moving = moving(t);
  // Where the machine is, taken before `held` is set: position_at() of a held machine answers
  // the hold's position, not yet known here.
  const std::array<double, 3> now_pos = position_at(t);
  held = true;
  hold_t = t;
  hold_to_end = false;
  hold_done_t = t;
  if (was_moving) {
    const double v_mm_per_s = current.feed_mm_per_min / 60.0;
    const double tau = v_mm_per_s / cfg.hold_accel_mm_per_s2;  // time to stop
    const double left_s = busy_end - t;                        // at full speed
    if (tau / 2.0 >= left_s) {
      hold_to_end = true;
      hold_done_t = busy_end;
    } else {
      hold_done_t = t + tau;
      hold_pos = along(t + tau / 2.0);  // stopping covers what full speed covers in τ/2
      remaining_s = left_s - tau / 2.0;
    }
  } else {
    hold_pos = now_pos;
    remaining_s = busy ? std::max(0.0, busy_end - t) : 0.0;
  }
  log.events.push_back({t, current_seq, current.n, "feed_hold", 0.0});  // the hold begins
  event("feed hold");
}

void SimController::Impl::cycle_start(double t) {
  if (pausing && !held) {  // M0: the program goes on
    ++log.cycle_starts;
    pausing = false;
    busy_end = cur_t1 = std::max(busy_end, t);
    log.events.push_back({t, current_seq, current.n, "resume", 0.0});
    event("cycle start: resumed after the program stop");
    return;
  }
  if (!hold_complete(t)) return;  // grbl resumes a hold only once it is complete
  ++log.cycle_starts;
  held = false;
  if (busy && !hold_to_end) {
    cur_from = hold_pos;
    cur_t0 = t;
    busy_end = cur_t1 = t + remaining_s;
  } else if (!busy) {
    free_at = std::max(free_at, t);
  }
  hold_to_end = false;
  event("cycle start");
  pump_planner(t);
}

// A controller reset (soft reset 0x18, the injected fault, the port opened with reset_on_open,
// a power cycle): the motion stops where it is, the queue is lost, the spindle and coolant
// stop (grbl's mc_reset), the parser returns to its power-on modes (gc_init: the coordinate
// systems are kept, G92 and the tool length offset are not) at the machine's position, which
// a power-up (power_cycle, port_opened: a hardware reset) restarts at 0.
void SimController::Impl::reset(double t, const std::string& cause) {
  const bool power_up = cause == "power_cycle" || cause == "port_opened";
  SimReset r;
  r.t_s = t;
  r.cause = cause;
  r.in_motion = moving(t) && !power_up;
  if (busy) {
    position = position_at(t);
    r.aborted = current_text;
  }
  r.position = position;
  for (const Line& l : planner) r.blocks_lost += l.kind == Kind::Block ? 1 : 0;
  for (const Line& l : rx) r.blocks_lost += l.kind == Kind::Block ? 1 : 0;
  r.executed_at_last_report = executed_at_last_report;
  const long seq = current_seq;
  busy = sync_busy = held = pausing = hold_to_end = false;
  rx.clear();
  planner.clear();
  partial.clear();
  partial_chars = 0;
  discarding_long = false;
  fill = 0;
  free_at = t;
  if (exec_spindle != 5) log.events.push_back({t, seq, std::nullopt, "spindle_stop", 0.0});
  if (exec_coolant) log.events.push_back({t, seq, std::nullopt, "coolant_off", 0.0});
  exec_spindle = 5;
  exec_coolant = false;
  log.resets.push_back(r);
  event("reset (" + cause + ")" + (r.aborted ? ": aborted '" + *r.aborted + "'" : "") + ", " +
        std::to_string(r.blocks_lost) + " queued blocks lost, " +
        (power_up ? "position restarts at 0" : "position kept") +
        (r.in_motion && !drip ? "; in motion: ALARM:3, locked until $X" : ""));
  if (drip) {  // a Fanuc-type control: DC3 then SYN, ready again at low water
    send_flow(true);
    send(std::string(1, kSyn));
    return;
  }
  if (power_up) position = {0.0, 0.0, 0.0};
  GrblState fresh;  // gc_init, then gc_sync_position
  fresh.coord_system = grbl_state.coord_system;
  fresh.position = position;
  grbl_state = fresh;
  modal = SimModal{};
  modal.position = position;
  end_received = false;
  blocks_in_epoch = 0;
  wco_countdown = 0;
  if (power_up) {
    alarmed = grbl_locked = alarm_exit = false;  // power-on: Idle (no homing lock modelled)
  } else if (alarmed) {
    alarmed = false;  // an alarm outlives a reset: locked until $X
    grbl_locked = true;
  } else if (r.in_motion) {
    send("ALARM:3\r\n");  // grbl: reset while in motion, position may be lost
    grbl_locked = true;
  }
  booting_until = t + cfg.boot_s;
}

void SimController::Impl::boot_done() {
  booting_until.reset();
  // A banner sent while the port is closed, or before a sender opened it, is lost.
  if (!port.is_open() || open_count == 0) ++log.banners_lost;
  send(std::string("\r\n") + kGrblBanner + "\r\n");
  if (grbl_locked) send("[MSG:'$H'|'$X' to unlock]\r\n");
  ++log.banners_sent;
}

}  // namespace ncd::comms
