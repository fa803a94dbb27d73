// The ways an ack (grbl) job stops: ending early (end_with: hold, reset at rest, the job's
// ending lines), grbl's safe halt (`!`, at rest, 0x18), a reset seen, an error or alarm, a lost
// link given up, and the report of what the reset dropped.
// The algorithm: the top of dnc_sender.cpp; docs/dnc-link.md, "A safe halt", "Ending early".
#include "link/dnc_session.hpp"
#include "link/held_position.hpp"

namespace ncd::comms::dnc_detail {

void Session::begin_ending() {
  EndingReport& e = report_.ending;
  e.requested = true;
  e.request_t_s = now_s();
  source_done_ = true;  // no more program blocks
  // The lines not yet written (a half-written one too: the reset clears grbl's line buffer).
  const std::size_t keep = sent_items_;
  while (items_.size() > keep) items_.pop_back();
  cur_off_ = 0;
  if (!motion_written_) {
    end_.step = Ending::NotNeeded;
    e.not_needed = true;
    emit(SenderEvent::Kind::Ending, report_.blocks,
         "ending the job: no move had been sent, the controller never moved");
    return;
  }
  end_.step = Ending::Holding;
  end_.t0_s = now_s();
  status_.have = false;
  write_raw("!?");
  status_.next_poll_s = now_s() + 0.1;
  emit(SenderEvent::Kind::Ending, report_.blocks,
       "ending the job: feed hold (!), waiting for Hold:0 before the reset");
}

void Session::ending_step() {
  const double now = now_s();
  if (end_.step == Ending::Holding) {
    if (status_.have && status_.last) {
      const std::string& state = status_.last->state;
      if (state == "Hold:0") {
        report_.ending.held = true;
        report_.ending.held_t_s = now;
        report_.ending.held_at_mm = status_.position;
        report_.ending.position_doubt = held_position_doubt(status_.position);
        if (!report_.ending.position_doubt.empty()) report_.position_may_be_lost = true;
        reset_for_ending();
        return;
      }
      if (state.rfind("Alarm", 0) == 0) {
        fail_ending("the controller is in alarm (its status says " + state +
                    "): it takes no line until it is unlocked");
        return;
      }
    }
    if (now - end_.t0_s > kEndingHoldTimeoutS) {
      fail_ending("after the feed hold (!) the controller did not report Hold:0 within " +
                  fixed(kEndingHoldTimeoutS, 0) + " s" +
                  (status_.last ? " (last status " + status_.last->state + ")" : ""));
      return;
    }
    if (now >= status_.next_poll_s) {
      status_.next_poll_s = now + 0.1;
      write_raw("?");
    }
    return;
  }
  if (now - end_.t0_s > s_.startup_timeout_s) {  // Resetting
    fail_ending("no banner within " + fixed(s_.startup_timeout_s, 1) +
                " s after the soft reset (0x18)");
  }
}

// Hold:0: what grbl queued is not known executed; the reset drops it.
void Session::reset_for_ending() {
  dropped_note(first_unexecuted());
  end_.first_unexecuted = first_unexecuted();
  write_raw(std::string(1, '\x18'));
  end_.step = Ending::Resetting;
  end_.t0_s = now_s();
  items_.clear();
  queued_.clear();
  sent_items_ = 0;
  cur_off_ = 0;
  unacked_bytes_ = 0;
  line_.clear();
}

// A line while holding or resetting for the ending.
void Session::ending_line(const std::string& line) {
  if (line.rfind("ALARM", 0) == 0) {
    fail_ending("the controller raised " + line +
                (end_.step == Ending::Resetting ? " on the reset: it is locked until $X" : ""));
  } else if (is_banner(line)) {
    if (end_.step == Ending::Holding) {
      fail_ending("the controller reset by itself before its hold was complete ('" + line + "')");
      return;
    }
    report_.ending.reset = true;
    send_ending();
  } else if (line == "ok" && end_.step == Ending::Holding && sent_items_ > 0) {
    take_ok();  // a line written before the hold, queued: the reset drops it
  }
}

// The held position against the moves the controller may have (link/held_position.hpp).
std::string Session::held_position_doubt(const Xyz& pos) const {
  std::vector<HeldCandidate> moves;
  for (const Item* it : resume_candidates().items) moves.push_back({it->geo, it->bytes});
  return comms::held_position_doubt(pos, last_end_, moves, kPositionTolMm);
}

void Session::send_ending() {
  // A held position that is not trusted gives the ending no position: it then moves nothing.
  const std::optional<std::array<double, 3>> at =
      report_.ending.position_doubt.empty() ? report_.ending.held_at_mm : std::nullopt;
  const std::vector<std::string> lines = ending_fn_ ? ending_fn_(at) : std::vector<std::string>{};
  report_.ending.lines = lines;
  ProgramModal modal;
  for (const std::string& l : lines) {
    Item it;
    it.index = kEnding;
    it.bytes = l + eob_text(s_.line.eob);
    it.geo = modal.apply(l);
    items_.push_back(std::move(it));
  }
  end_.step = Ending::Sending;
  track_ok_ = true;
  status_.have = false;
  status_.next_poll_s = 0.0;
  emit(SenderEvent::Kind::Ending, report_.blocks,
       "the controller was held and reset; sending the ending (" + std::to_string(lines.size()) +
           " lines)");
}

void Session::fail_ending(const std::string& why) {
  report_.ending.failure = why;
  report_.alarms.push_back(why);
  emit(SenderEvent::Kind::Alarm, resume_point(), "the ending could not be sent: " + why);
  interrupt("the ending could not be sent: " + why);
}

// A reset, seen: nothing to stop, the queue is gone. Never resume past it. Its state (an
// alarm lock after a reset in motion) is read for the advice.
void Session::controller_reset(const std::string& why) {
  const std::int64_t first = first_unexecuted();
  dropped_note(first);
  read_state();
  interrupt(why);
}

// An error reply or an alarm: bring grbl to a safe halt so that nothing queued after it runs.
void Session::stop_controller(const std::string& why) {
  report_.alarms.push_back(why);
  emit(SenderEvent::Kind::Alarm, resume_point(), why);
  if (why.find("ALARM:3") != std::string::npos) report_.position_may_be_lost = true;
  if (s_.reset_on_error && link_) {
    const HaltReport h = safe_halt();
    report_.notes.push_back("after the failure the controller was " + halt_text(h));
  }
  dropped_note(first_unexecuted());
  interrupt(why);
}

// A lost link that cannot be resumed: ncd had held the controller (`!`) to read where it is;
// it must not be left held (its protocol loop reads no line then, and a `~` would run what it
// still holds), so the hold is completed with a reset.
void Session::give_up(const std::string& why) {
  // What the controller holds is not proven (it may even have restarted): its status counts
  // nothing executed from here on.
  track_ok_ = false;
  if (link_ && s_.reset_on_error) {
    const HaltReport h = safe_halt();
    report_.notes.push_back("the controller, held to read its position, was " + halt_text(h));
  }
  dropped_note(first_unexecuted());
  interrupt(why);
}

// DncSender::request_halt, or a stop with halt_on_stop.
void Session::halt_on_request() {
  if (!wrote_line_ && report_.blocks_sent == 0) return;  // nothing sent: nothing to stop
  if (!link_) {
    report_.halt.attempted = true;
    report_.halt.detail = "the port was closed: the controller could not be held";
    return;
  }
  const HaltReport h = safe_halt();
  report_.notes.push_back("stopped: the controller was " + halt_text(h));
  dropped_note(first_unexecuted());
}

bool Session::at_rest(const std::string& state) {
  return state == "Idle" || state == "Hold:0" || state == "Alarm" || state == "Sleep" ||
         state == "Check" || state == "Door:0" || state == "Door:1";
}

// What the halt did, for notes and messages.
std::string Session::halt_text(const HaltReport& h) {
  if (!h.detail.empty()) return "not brought to a safe halt: " + h.detail;
  std::string t = "held (!), at rest after " + fixed(h.rest_s, 2) + " s, reset (0x18)";
  return t + (h.alarm ? "; it is in alarm (locked until $X)" : "; now " + h.state);
}

// grbl's safe halt (its manual: a feed hold, then a reset once the hold is complete): `!`,
// `?` every 50 ms until the state is at rest (Hold:0, Idle, Alarm), which tracks the blocks
// executed exactly (at rest nothing lags), then 0x18, its banner, and a status to confirm the
// state. A reset while the hold decelerates (Hold:1) would be a reset in motion (ALARM:3, the
// position may be lost), so without a status at rest there is no reset: the controller stays
// held and the report says why.
HaltReport Session::safe_halt() {
  HaltReport h;
  h.attempted = true;
  stopping_ = true;
  reset_seen_ = false;
  try {
    const double t0 = now_s();
    const long reports0 = report_.status_reports;
    write_raw("!");
    double next_ask = t0;
    std::optional<GrblStatus> rest;
    while (now_s() - t0 < s_.halt_timeout_s) {
      if (now_s() >= next_ask) {
        status_.have = false;
        write_raw("?");
        next_ask = now_s() + 0.05;
      }
      read_input();
      if (status_.have && status_.last && at_rest(status_.last->state)) {
        rest = status_.last;
        break;
      }
      if (report_.status_reports == reports0 && now_s() - t0 > 2.0) break;
      link_->wait(5, false);
    }
    h.rest_s = now_s() - t0;
    if (!rest) {
      h.state = status_.last && report_.status_reports > reports0 ? status_.last->state : "";
      h.detail = report_.status_reports == reports0
                     ? "it answers no status report, so whether its motion has stopped "
                       "cannot be told; it was held (!) and not reset (a reset in motion "
                       "loses the position): reset it by hand once the machine has stopped"
                     : "its motion was not at rest after " + fixed(s_.halt_timeout_s, 0) +
                           " s (state " + h.state +
                           "); it was held (!) and not reset (a reset in motion loses the "
                           "position): reset it by hand once the machine has stopped";
      report_.halt = h;
      report_.controller_state = h.state;
      stopping_ = false;
      return h;
    }
    h.at_rest = true;
    write_raw(std::string(1, kResetByte));
    const double t1 = now_s();
    while (!reset_seen_ && now_s() - t1 < 3.0) {
      read_input();
      link_->wait(5, false);
    }
    h.reset = reset_seen_;
    if (!h.reset) h.detail = "no banner came back within 3 s of the reset (0x18)";
    read_state();
    h.state = report_.controller_state;
    h.alarm = h.state == "Alarm";
  } catch (const LinkError& e) {
    h.detail = std::string("the link failed during the halt: ") + e.what();
  }
  stopping_ = false;
  report_.halt = h;
  return h;
}

// Asks one status (up to 1 s) and records the controller's state for the report and advice.
void Session::read_state() {
  if (!link_) return;
  try {
    status_.have = false;
    const double t0 = now_s();
    double next_ask = t0;
    while (!status_.have && now_s() - t0 < 1.0) {
      if (now_s() >= next_ask) {
        write_raw("?");
        next_ask = now_s() + 0.25;
      }
      read_input();
      if (!status_.have) link_->wait(5, false);
    }
    if (status_.have && status_.last) report_.controller_state = status_.last->state;
    if (report_.controller_state == "Alarm") report_.position_may_be_lost = true;
  } catch (const LinkError&) {
  }
}

void Session::dropped_note(std::int64_t first) {
  // The queued blocks as ranges (the rejected block, answered error:N, is not among them).
  std::string queued;
  std::int64_t lo = -1, hi = -1, in_flight = 0;
  const auto flush_range = [&] {
    if (lo < 0) return;
    queued += (queued.empty() ? "" : ", ") + std::to_string(lo + 1) +
              (hi > lo ? "-" + std::to_string(hi + 1) : std::string());
    lo = hi = -1;
  };
  for (const Item& it : queued_) {
    if (it.index < 0) continue;
    if (lo >= 0 && it.index != hi + 1) flush_range();
    if (lo < 0) lo = it.index;
    hi = it.index;
  }
  flush_range();
  for (std::size_t i = 0; i < sent_items_ && i < items_.size(); ++i) {
    if (items_[i].index >= 0) ++in_flight;
  }
  std::string d;
  if (!queued.empty()) {
    d = "blocks " + queued + " were queued in the controller and not known executed";
  }
  if (in_flight > 0) {
    d += (d.empty() ? "" : "; ") + std::to_string(in_flight) + " more were sent and not answered";
  }
  if (report_.rejected_block >= 0) {
    d += (d.empty() ? "" : "; ") + std::string("block ") +
         std::to_string(report_.rejected_block + 1) + " was refused (" + rejected_reply_ + ")";
  }
  report_.dropped = d.empty() ? "nothing was queued beyond block " + std::to_string(first) : d;
}

}  // namespace ncd::comms::dnc_detail
