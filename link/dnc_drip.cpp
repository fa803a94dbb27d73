// Drip feed (Fanuc-type DNC): the wire model that keeps at most max_queued_chars ahead of the
// line, DC1/DC3 and CTS flow control (also obeyed on an ack link), and what is known delivered.
// The algorithm: the top of dnc_sender.cpp.
#include "link/dnc_session.hpp"

#include "link/serial_link.hpp"
#include "link/transfer_journal.hpp"

namespace ncd::comms::dnc_detail {

// Bytes of this connection the controller has, by the wire model and the kernel's queue.
double Session::delivered() const {
  return std::min(model_delivered_, static_cast<double>(conn_written_ - outq_));
}

void Session::advance_model() {
  const double now = wire_now_s();
  const double dt = now - last_tick_s_;
  last_tick_s_ = now;
  model_delivered_ = std::min(static_cast<double>(conn_written_),
                              model_delivered_ + dt * cps_ * s_.pacing_fraction);
  outq_ = link_->output_queue();
  report_.max_output_queue = std::max(report_.max_output_queue, outq_);
}

void Session::drip_byte(char c) {
  if (c == kXoff) {
    if (xon_) {
      xon_ = false;
      xoff_since_s_ = hold_now_s();
      ++report_.xoff_count;
    }
  } else if (c == kXon) {
    if (!xon_) end_xoff();
  } else if (c == kNak || c == kSyn) {
    alarm(std::string("the controller sent ") + (c == kNak ? "NAK" : "SYN") +
          " (a reset or an alarm on the machine)");
  } else {
    noise(1, c);
  }
}

void Session::end_xoff() {
  const double held = hold_now_s() - xoff_since_s_;
  xon_ = true;
  report_.xoff_total_s += held;
  report_.xoff_longest_s = std::max(report_.xoff_longest_s, held);
  if (xoff_reported_) {
    emit(SenderEvent::Kind::XoffEnd, resume_point(),
         "the controller released the hold (DC1) after " + fixed(held, 1) + " s");
    xoff_reported_ = false;
  } else if (held > s_.xoff_timeout_s) {
    ++report_.holds_explained;
    emit(SenderEvent::Kind::XoffEnd, resume_point(),
         "the controller released the hold (DC1) after " + fixed(held, 1) +
             " s, within the wait of the tool change, dwell or stop it was sent");
  }
}

// The wait the program explains for a hold now: the waits of the blocks written within the
// last wait_window_chars characters (a controller's buffer holds fewer), older ones dropped.
double Session::explained_wait_s() {
  const std::int64_t window = s_.wait_window_chars;
  while (!waits_.empty() && report_.bytes_written - waits_.front().at_byte > window) {
    waits_.pop_front();
  }
  double wait_s = 0.0;
  for (const WaitMark& w : waits_) wait_s += w.wait_s;
  return wait_s;
}

void Session::alarm(const std::string& text) {
  report_.alarms.push_back(text);
  emit(SenderEvent::Kind::Alarm, resume_point(), text);
  interrupt(text);
}

void Session::watch_hold() {
  const double now = hold_now_s();
  bool held = !xon_;
  double since = xoff_since_s_;
  if (s_.line.flow == Flow::RtsCts) {
    const auto cts = link_->cts();
    if (cts && *cts) heard_ = true;  // something on the other end drives CTS
    if (cts && !*cts) {
      if (!cts_low_) {
        cts_low_ = true;
        cts_low_since_s_ = now;
      }
      held = true;
      since = cts_low_since_s_;
    } else {
      cts_low_ = false;
    }
  }
  if (held && !xoff_reported_ && now - since > s_.xoff_timeout_s) {
    const double explained_s = explained_wait_s();
    if (now - since > s_.xoff_timeout_s + explained_s) {
      xoff_reported_ = true;
      ++report_.xoff_timeouts;
      emit(SenderEvent::Kind::XoffLong, resume_point(),
           "the controller has held the link for more than " +
               fixed(s_.xoff_timeout_s + explained_s, 1) + " s at block " +
               std::to_string(resume_point() + 1) +
               (explained_s > 0.0
                    ? " (" + fixed(s_.xoff_timeout_s, 1) + " s plus " + fixed(explained_s, 1) +
                          " s for the tool change or dwell it was sent)"
                    : std::string()) +
               "; waiting");
    }
  }
  set_hold(xoff_reported_ && held);
}

void Session::write_drip() {
  const bool cts_ok = !(s_.line.flow == Flow::RtsCts && cts_low_);
  const bool may_send = cts_ok && (s_.line.flow != Flow::XonXoff || xon_);
  if (!may_send) return;
  const double ahead =
      std::max(static_cast<double>(outq_), static_cast<double>(conn_written_) - delivered());
  report_.max_queued_estimate =
      std::max(report_.max_queued_estimate, static_cast<int>(std::ceil(ahead)));
  auto room = static_cast<std::int64_t>(std::floor(s_.max_queued_chars - ahead));
  while (room > 0) {
    if (draining_ && cur_off_ == 0) return;  // a stop: only the block begun is finished
    if (sent_items_ == items_.size() && !pull()) return;
    Item& it = items_[sent_items_];
    if (cur_off_ == 0 && journal_ != nullptr && it.index >= 0) journal_->note_writing(it.index);
    const std::size_t take =
        std::min<std::size_t>(static_cast<std::size_t>(room), it.bytes.size() - cur_off_);
    const std::size_t n = link_->write_some(std::string_view(it.bytes).substr(cur_off_, take));
    if (n == 0) return;
    conn_written_ += static_cast<std::int64_t>(n);
    report_.bytes_written += static_cast<std::int64_t>(n);
    room -= static_cast<std::int64_t>(n);
    cur_off_ += n;
    if (cur_off_ == it.bytes.size()) {
      it.end_mark = static_cast<double>(conn_written_);
      written(it);
      ++sent_items_;
      cur_off_ = 0;
    }
  }
}

// Drops delivered items that have left the resend window; updates the journal.
void Session::confirm_drip() {
  const double have = delivered();
  std::int64_t confirmed_bytes_after_front = 0;
  for (std::size_t i = 1; i < sent_items_; ++i) {
    if (items_[i].end_mark > have) break;
    confirmed_bytes_after_front += static_cast<std::int64_t>(items_[i].bytes.size());
  }
  const std::int64_t keep = s_.controller_skips_repeated_n ? window_ : 0;
  while (sent_items_ > 0 && items_.front().end_mark <= have &&
         (items_.front().index < 0 || confirmed_bytes_after_front >= keep)) {
    if (sent_items_ > 1) {
      confirmed_bytes_after_front -= static_cast<std::int64_t>(items_[1].bytes.size());
    }
    items_.pop_front();
    --sent_items_;
  }
  confirm_journal();
}

// A stop (drip): the block being written is finished and what was written is let reach the
// line, within stop_drain_s, so that the controller holds whole blocks only and the first
// block not sent is exact. A block that could not be finished (held by the controller) is
// named: the controller holds part of it.
void Session::drain_on_stop() {
  if (!link_ || over()) return;
  draining_ = true;
  const double until = now_s() + s_.stop_drain_s;
  try {
    while (now_s() < until) {
      read_input();
      if (over()) return;
      advance_model();
      watch_hold();
      write_drip();
      confirm_drip();
      if (cur_off_ == 0 && static_cast<double>(conn_written_) <= delivered()) break;
      link_->wait(5, false);
    }
  } catch (const LinkError& e) {
    report_.notes.push_back("the link failed while the block begun was finished: " +
                            std::string(e.what()));
  }
  if (cur_off_ > 0 && sent_items_ < items_.size()) {
    report_.cut_block = items_[sent_items_].index;
    report_.notes.push_back(
        "block " + std::to_string(report_.cut_block + 1) + " was cut after " +
        std::to_string(cur_off_) + " of its " + std::to_string(items_[sent_items_].bytes.size()) +
        " characters (the controller held the line): the controller holds part of it; clear "
        "its input (reset) before sending again");
  }
}

}  // namespace ncd::comms::dnc_detail
