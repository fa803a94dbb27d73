// grbl start-up: nothing is sent before the controller has spoken (banner, status, or its answer
// to the half-line flush), and no block before its state says it can take one.
// The algorithm: the top of dnc_sender.cpp; docs/dnc-link.md, "Start-up".
#include "link/dnc_session.hpp"

namespace ncd::comms::dnc_detail {

// A line from the controller before the job has started.
void Session::startup_line(const std::string& line) {
  if (is_banner(line)) {
    if (opened_once_before_) {
      controller_reset("the controller reset while the link was down (its banner '" + line +
                       "' came on the new connection)");
      return;
    }
    report_.startup = "banner";
    track_ok_ = true;  // the banner that opens the job, not a reset in it
    start_.spoke = true;
    // A reset cleared its buffers (and any wake-up line).
    start_.woke = start_.wake_pending = false;
    status_.have = false;  // its state now: ask again
    status_.next_poll_s = now_s();
    emit(SenderEvent::Kind::Opened, resume_point(), "the controller said '" + line + "'");
    return;
  }
  const bool answer = line == "ok" || line.rfind("error:", 0) == 0;
  if (answer && start_.wake_pending) {
    // The wake-up line is the half-line flush: refused (error:N) as it should be, or `ok`
    // when it completed a half line ending in a `;` comment an earlier connection left.
    start_.wake_pending = false;
    start_.spoke = true;
    if (report_.startup != "banner") report_.startup = "woken";
    if (line == "ok") {
      report_.notes.push_back(
          "the wake-up line completed a half line ending in a ';' comment that an earlier "
          "connection had left in the controller's line buffer; the controller queued it");
    }
    emit(SenderEvent::Kind::Opened, resume_point(), "the controller answered the wake-up line");
  } else if (answer && start_.unlock_pending) {
    start_.unlock_pending = false;
    if (line == "ok") {
      report_.notes.push_back("the controller's alarm lock was cleared with $X (--unlock)");
    } else {
      report_.failure = "the controller refused $X with " + line + "; nothing was sent";
    }
  } else if (line.front() == '[') {
    report_.notes.push_back("the controller said " + line);  // [MSG:…]: informative
  } else {
    noise(line.size() + 1, '\0');
  }
}

// Start-up: never send before the controller has spoken, and never a block before its state
// is known to take one (docs/dnc-link.md, "Start-up"). Without a banner within banner_wait_s,
// ask `?` (a real-time byte, no line); without a status either, wake it with the half-line
// flush and wait for its answer. Then, with status polling, read its state: Idle goes on;
// Alarm ends the job before any block (or, with `unlock`, sends `$X`); a hold (held at rest, its
// protocol loop reads no line) is brought to a safe halt; Run and the rest end the job.
void Session::startup() {
  if (opened_once_before_) {
    // After a lost link: a banner means a reset (handled in ack_line). Without one, hold and
    // ask where the controller is.
    if (now_s() - phase_t0_ >= std::min(s_.banner_wait_s, 1.0)) {
      phase_ = Phase::Recovering;
      phase_t0_ = now_s();
      status_.have = false;
      write_raw("!?");
      status_.next_poll_s = now_s() + 0.2;
    }
    return;
  }
  const double since = now_s() - phase_t0_;
  const bool ask = s_.status_hz > 0.0;
  if (!start_.spoke) {
    if (since >= s_.startup_timeout_s) {
      report_.failure = "the controller on " + s_.line.device + " did not speak within " +
                        fixed(s_.startup_timeout_s, 1) +
                        " s (no banner, no status report, no answer to a line it must "
                        "refuse): check that it is powered, the port, the baud rate and the "
                        "frame (" +
                        describe(s_.line) + "), or raise --startup-timeout";
      return;
    }
    if (since < s_.banner_wait_s) return;
    if (ask && !start_.asked) {
      start_.asked = true;
      emit(SenderEvent::Kind::Opened, resume_point(),
           "no banner within " + fixed(s_.banner_wait_s, 1) + " s: asking its status ('?')");
      write_raw("?");
    } else if (!start_.woke && (!ask || since >= s_.banner_wait_s + 0.5)) {
      emit(SenderEvent::Kind::Opened, resume_point(),
           "no banner and no status: waking the controller with a line it must refuse");
      wake();
    }
    return;
  }
  if (start_.wake_pending || start_.unlock_pending) return;  // their answers come first
  if (!ask) {
    if (!start_.woke && report_.startup != "banner") return wake();
    phase_ = Phase::Ready;
    return;
  }
  if (!status_.have) {
    if (now_s() >= status_.next_poll_s) {
      if (++start_.polls > 8) {  // 2 s without a status: a controller without `?`
        report_.notes.push_back(
            "the controller answered no status report at start-up: its state (alarm, hold) "
            "was not checked");
        if (!start_.woke && report_.startup != "banner") return wake();
        phase_ = Phase::Ready;
        return;
      }
      write_raw("?");
      status_.next_poll_s = now_s() + 0.25;
    }
    return;
  }
  start_state(status_.last->state);
}

// The first line after opening: the half-line flush, which grbl must refuse (or which ends a
// half line inside a `;` comment an earlier connection left: then that block is queued).
void Session::wake() {
  start_.woke = start_.wake_pending = true;
  wrote_line_ = true;
  write_raw(std::string(kFlushText) + "\n");
}

// What the controller's state at start-up allows.
void Session::start_state(std::string state) {  // a copy: the halt below reads new statuses
  report_.controller_state = state;
  if (state == "Idle") {
    // A half line an earlier connection left is flushed before the first block; a banner
    // (a reset) has cleared it.
    if (!start_.woke && report_.startup != "banner") return wake();
    phase_ = Phase::Ready;
    return;
  }
  if (state == "Alarm") {
    report_.position_may_be_lost = true;
    if (!s_.unlock || start_.unlock_tried) {
      report_.failure = start_.unlock_tried
                            ? std::string(
                                  "the controller stays in alarm after $X (grbl keeps "
                                  "a hard-limit or door alarm until "
                                  "the cause is cleared); nothing was sent")
                            : "the controller is in alarm (locked: grbl refuses every "
                              "line with error:9 until $X); "
                              "nothing was sent";
      return;
    }
    if (!start_.woke && report_.startup != "banner") return wake();
    start_.unlock_pending = start_.unlock_tried = true;
    wrote_line_ = true;
    emit(SenderEvent::Kind::Opened, resume_point(),
         "the controller is in alarm: unlocking it with $X (--unlock)");
    write_raw("$X\n");
    status_.have = false;
    status_.next_poll_s = now_s() + 0.25;
    return;
  }
  if (state.rfind("Hold", 0) == 0 && !start_.halted) {
    // Held: grbl reads no line until `~` or a reset, and `~` would run what it still holds.
    start_.halted = true;
    emit(SenderEvent::Kind::Opened, resume_point(),
         "the controller is held (" + state + "): bringing it to a safe halt before sending");
    const HaltReport h = safe_halt();
    if (!h.ok() && !(h.reset && h.alarm)) {
      report_.failure = "the controller was held (" + state +
                        ") and could not be brought to a safe halt: " + halt_text(h) +
                        "; nothing was sent";
      return;
    }
    report_.notes.push_back("the controller was held (" + state + ") at start-up; ncd halted " +
                            "it (" + halt_text(h) + ") before sending");
    // The reset cleared its buffers: no half line is left.
    start_.woke = start_.wake_pending = false;
    report_.startup = "banner";
    status_.have = false;
    status_.next_poll_s = now_s();
    return;
  }
  report_.failure =
      "the controller is not ready for a program: its state is " + state +
      (state == "Run" || state == "Jog" || state == "Home"
           ? " (it is moving: it still runs blocks it was sent before; wait until it is Idle)"
           : "") +
      "; nothing was sent";
}

}  // namespace ncd::comms::dnc_detail
