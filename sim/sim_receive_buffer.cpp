// The simulated controller's receive buffer (the model: sim_controller.cpp, 2 and 4): each
// character taken in, lines completed and judged (parse_sim_block or grbl's check), alarms.

#include "sim/sim_impl.hpp"

#include <algorithm>

#include "core/number_text.hpp"

namespace ncd::comms {

void SimController::Impl::on_byte(char c, double t) {
  ++log.bytes_received;
  log.last_byte_t_s = t;
  if (cfg.line.data_bits == 7) c = static_cast<char>(c & 0x7F);
  if (!drip) {
    if (booting_until) {  // the controller is not listening yet
      ++log.bytes_before_banner;
      return;
    }
    if (c == kGrblStatus) {
      send(status_report(t));
      ++log.status_reports;
      executed_at_last_report = log.blocks_executed;
      return;
    }
    if (c == kGrblHold) return feed_hold(t);
    if (c == kGrblResume) return cycle_start(t);
    if (c == kGrblReset) return reset(t, "soft_reset");
    if (c == '\r') c = '\n';  // grbl ends a line at CR and at LF
  }
  if (alarmed) {
    ++log.bytes_after_alarm;
    if (!drip && c == '\n') {  // grbl: locked out until the alarm is cleared
      send("error:" + std::to_string(kErrAlarmLock) + "\r\n");
    }
    return;
  }
  if (c == '\0') {
    ++log.nul_received;
    return;
  }
  if (discarding_long) {
    if (c == '\n') {
      discarding_long = false;
      ++log.lines_received;
      Line line;
      line.kind = Kind::Error;
      line.error = kErrLineOverflow;
      line.epoch = rx_epoch;
      line.ready_t = t;
      log.errors.push_back({t, log.lines_received, kErrLineOverflow, "",
                            "more than " + std::to_string(max_block) + " characters"});
      ++log.blocks_rejected;
      queue_line(std::move(line), t);
    }
    return;
  }
  if (fill >= cfg.buffer_bytes) {
    raise_alarm(t, "overflow",
                "a character arrived with the " + std::to_string(cfg.buffer_bytes) +
                    "-byte receive buffer full");
    return;
  }
  partial += c;
  ++fill;
  ++ring_in;
  if (cfg.faults.drop_link_after_chars == static_cast<long>(ring_in) && log.link_drops == 0) {
    drop_pending = true;  // after this character: the rest of the line is lost in the cut
  }
  log.max_buffer_fill = std::max(log.max_buffer_fill, fill);
  if (c == '\n') {
    complete_line(t);
    return;
  }
  if (c != '\r' && ++partial_chars > max_block) {
    if (drip) {
      raise_alarm(t, "block_too_long",
                  "a block longer than " + std::to_string(max_block) + " characters");
    } else {
      fill -= static_cast<int>(partial.size());
      partial.clear();
      partial_chars = 0;
      discarding_long = true;
    }
  }
}

void SimController::Impl::complete_line(double t) {
  ++log.lines_received;
  Line line;
  line.size = static_cast<int>(partial.size());
  line.epoch = rx_epoch;
  line.ready_t = t;
  const std::string text = line_text(partial);
  partial.clear();
  partial_chars = 0;
  if (text.empty() || text == "%") {
    ++log.framing_lines;
    line.kind = Kind::Framing;
    if (text == "%" && !end_received && blocks_in_epoch > 0) {  // else it opens
      line.kind = Kind::End;
      receive_end(t);
    }
    queue_line(std::move(line), t);
    return;
  }
  if (!drip && text[0] == '$') {  // a grbl system command: acted on when it is read
    line.kind = Kind::System;
    line.text = text;
    queue_line(std::move(line), t);
    return;
  }
  if (!drip && grbl_locked) {  // grbl: g-code is locked out until $X (or $H)
    line.kind = Kind::Error;
    line.error = kErrAlarmLock;
    log.errors.push_back({t, log.lines_received, line.error, text, "locked by an alarm: send $X"});
    ++log.blocks_rejected;
    queue_line(std::move(line), t);
    return;
  }
  SimModal modal_after = modal;
  GrblState grbl_after = grbl_state;
  SimParse p;
  if (cfg.dialect == Dialect::grbl) {
    p = parse_grbl(text, grbl_after);
  } else if (!drip && grbl_line_chars(text) > kGrblLineChars) {  // grbl checks this first
    p.error = kErrLineOverflow;
    p.message = std::to_string(grbl_line_chars(text)) + " characters without spaces and " +
                "comments, more than grbl's " + std::to_string(kGrblLineChars);
  } else {
    DialectState ds;
    const auto v = cfg.dialect ? check_line(*cfg.dialect, text, ds) : std::nullopt;
    if (v) {
      p.error = kErrUnsupported;
      p.message = describe(*v, *cfg.dialect);
    } else {
      p = parse_sim_block(text, modal_after, cfg.rapid_mm_per_min);
      if (p.block.tool_change) p.block.duration_s += cfg.tool_change_s;
    }
  }
  if (p.error != 0) {
    ++log.blocks_rejected;
    if (drip) {
      raise_alarm(t, "bad_block", "'" + text + "': " + p.message);
      return;
    }
    line.kind = Kind::Error;
    line.error = p.error;
    log.errors.push_back({t, log.lines_received, p.error, text, p.message});
    queue_line(std::move(line), t);
    return;
  }
  if (cfg.dialect && !end_received) {
    const int spindle = cfg.dialect == Dialect::grbl ? grbl_after.spindle : modal_after.spindle;
    if (cfg.machine_safety && p.block.feed_move && spindle == 5) {
      raise_alarm(t, "spindle_stopped",
                  "'" + text + "': a feed move with the spindle stopped (machine safety; " +
                      "start it with M3 S… first)");
      return;
    }
    if (p.block.probe_must_touch) {
      raise_alarm(t, "probe_fail",
                  "'" + text + "': the probe found no contact (a simulation has no probe)");
      return;
    }
  }
  if (drip && cfg.skip_duplicate_n && p.block.n && log.last_n && *p.block.n <= *log.last_n) {
    ++log.duplicates_discarded;
    ++blocks_in_epoch;
    line.kind = Kind::Duplicate;
  } else if (end_received) {
    ++log.lines_after_end;
    line.kind = Kind::AfterEnd;
    grbl_state = grbl_after;  // grbl reads on after M2/M30; its verdicts follow its state
  } else {
    modal = modal_after;
    grbl_state = grbl_after;
    line.block = p.block;
    line.text = text;
    accept(text, p.block, t);
    line.seq = log.blocks_received;
  }
  queue_line(std::move(line), t);
}

// grbl's verdict on a line (comms/dialect) and what it executes, as a SimBlock.
SimParse SimController::Impl::parse_grbl(const std::string& text, GrblState& st) const {
  SimParse r;
  GrblBlock g;
  if (const auto v = check_grbl_line(text, st, &g)) {
    r.error = v->grbl_error;
    r.message = describe(*v, Dialect::grbl);
    return r;
  }
  SimBlock& b = r.block;
  b.n = g.n;
  b.spindle_rpm = g.spindle_rpm;
  b.spindle = g.spindle;
  b.coolant = g.flood;
  b.tool = g.tool;
  b.pause = g.pause;
  b.optional_stop = g.optional_stop;
  b.program_end = g.program_end;
  if (g.dwell_s) {
    b.dwell = true;
    b.duration_s = *g.dwell_s;
  }
  if (g.motion >= 0) {
    b.move = true;
    b.to = g.to;
    b.path_mm = g.path_mm;
    b.g = g.motion >= 380 && g.motion < 390 ? 38 : g.motion / 10;
    b.feed_move = !g.rapid && b.g != 38;  // a probe moves at F but cuts nothing
    b.probe_must_touch = g.motion == 382 || g.motion == 384;
    if (g.rapid) {
      b.feed_mm_per_min = cfg.rapid_mm_per_min;
    } else if (g.inverse_time_min > 0.0) {
      b.feed_mm_per_min = g.path_mm / g.inverse_time_min;
    } else {
      b.feed_mm_per_min = g.feed_mm_per_min;
    }
    b.duration_s += g.inverse_time_min > 0.0 ? g.inverse_time_min * 60.0
                                             : g.path_mm / (b.feed_mm_per_min / 60.0);
  }
  return r;
}

void SimController::Impl::accept(const std::string& text, const SimBlock& b, double t) {
  ++log.blocks_received;
  ++blocks_in_epoch;
  if (b.n) {
    if (!log.first_n) log.first_n = b.n;
    log.last_n = b.n;
  }
  sha.update(text);
  sha.update("\n");
  if (b.program_end) receive_end(t);
  const SimFaults& f = cfg.faults;
  const long k = log.blocks_received;
  if (f.drop_link_after_blocks == k && log.link_drops == 0) drop_pending = true;
  if (f.hold_after_blocks == k && log.holds == 0) {
    ++log.holds;
    hold_until = t + f.hold_s;
    event("holding the sender with DC3 for " + text::sig(f.hold_s) + " s (fault injection)");
  }
  if (f.alarm_after_blocks == k) {
    alarm_pending = true;  // after the line is queued
  }
  if (f.reset_after_blocks == k && log.resets.empty()) reset_pending = true;
  if (f.restart_after_blocks == k && !restarted) {
    restarted = true;
    drop_pending = true;  // the USB link goes with the power: cut after this line
    restart_pending = true;
  }
}

void SimController::Impl::receive_end(double t) {
  end_received = true;
  end_received_t = t;
  log.program_end_received = true;
}

void SimController::Impl::queue_line(Line line, double t) {
  rx.push_back(std::move(line));
  if (!drip) pump_planner(t);
  if (reset_pending) {
    reset_pending = false;
    reset(t, "injected");
  }
  if (alarm_pending) {
    alarm_pending = false;
    raise_alarm(t, "injected",
                "alarm after " + std::to_string(log.blocks_received) + " blocks (fault injection)");
  }
}

void SimController::Impl::raise_alarm(double t, const std::string& code,
                                      const std::string& detail) {
  if (alarmed) return;
  alarmed = true;
  alarm_exit = true;
  alarm_t = t;
  late_written_end = 0;  // what follows is read, and counted as after the alarm
  log.alarms.push_back({t, code, log.blocks_received, log.last_n, detail});
  if (drip) {
    send_flow(true);
    send(std::string(1, kNak));
  } else {
    // grbl's numbers where grbl has the alarm (ALARM:5 probe fail); 9 for an injected one, 1
    // for the simulation's own (overflow, spindle_stopped), which grbl does not raise.
    const char* number = code == "injected" ? "9" : code == "probe_fail" ? "5" : "1";
    send(std::string("ALARM:") + number + "\r\n");
  }
  event("alarm (" + code + "): " + detail + "; stopped");
  busy = false;
  pausing = false;
  rx.clear();
  planner.clear();
  partial.clear();
  partial_chars = 0;
  discarding_long = false;
  fill = 0;
}

}  // namespace ncd::comms
