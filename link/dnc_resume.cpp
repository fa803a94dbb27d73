// A lost link and resuming: the drip feed's resend window, grbl's recovery (the position proves
// which blocks the controller holds, or the job stops), the journal of the first block not known
// executed, and, after ncd was killed, match_position and probe_grbl.
// The algorithm: the top of dnc_sender.cpp; docs/dnc-link.md, "Rules".
#include "link/dnc_session.hpp"

#include "link/program_file.hpp"
#include "link/transfer_journal.hpp"

namespace ncd::comms::dnc_detail {

void Session::recovering() {
  const double now = now_s();
  if (now - phase_t0_ > 5.0) {
    give_up("the controller gave no status within 5 s after the link came back");
    return;
  }
  if (status_.have && status_.last &&
      (status_.last->state == "Idle" || status_.last->state == "Hold:0")) {
    decide_resume(*status_.last, status_.position);
    return;
  }
  if (now >= status_.next_poll_s) {
    status_.next_poll_s = now + 0.2;
    write_raw("?");
  }
}

// The controller is held or idle after a lost link: resume only if the position proves
// which blocks it holds (see the top of dnc_sender.cpp). The steps: the counts of Bf: must be
// readable; a stopped spindle tells a restart; a full planner may hide a line; the position
// then names the last block the controller received; what it lacks of the queued ones, or a
// block without motion right after it, stops the job; else the job resumes after it.
void Session::decide_resume(const GrblStatus& st, const Xyz& pos) {
  const std::string where = " (position " + fixed(pos[0], 3) + ", " + fixed(pos[1], 3) + ", " +
                            fixed(pos[2], 3) + ", " + st.state + ")";
  if (!buffers_countable(st, where)) return;
  const ResumeCandidates c = resume_candidates();
  if (restarted_unseen(c, st, where)) return;
  if (*st.free_blocks == 0 && c.written > 0) {
    // grbl's protocol loop takes a whole line out of the receive ring and then waits for a
    // free planner block: such a line is in neither count of Bf:, and runs when room frees.
    give_up(
        "after the lost link the controller's planner is full, so a line it received may "
        "be waiting for room, counted nowhere: which blocks it holds cannot be told" +
        where);
    return;
  }
  const auto held = static_cast<std::size_t>(std::max(0, s_.planner_blocks - *st.free_blocks));
  const std::optional<long> last = last_received(c, held, pos, where);
  if (!last || !holds_what_was_queued(c, *last, where)) return;
  resume_after(c, *last, held, st, where);
}

// Bf: tells how many blocks the planner holds, and its receive buffer is empty: no line waits
// there unread. Else gives up (false).
bool Session::buffers_countable(const GrblStatus& st, const std::string& where) {
  if (!st.free_blocks) {
    give_up(
        "after the lost link the status has no Bf: field, so the blocks the controller "
        "holds cannot be counted (grbl: $10=2 or 3)" +
        where);
    return false;
  }
  if (st.free_bytes && *st.free_bytes < s_.rx_buffer_bytes) {
    give_up("after the lost link the controller's receive buffer still holds " +
            std::to_string(s_.rx_buffer_bytes - *st.free_bytes) +
            " bytes, lines not yet read: which blocks they are cannot be told" + where);
    return false;
  }
  return true;
}

// Candidates: queued (ok'd) blocks, then the lines written on the lost connection.
Session::ResumeCandidates Session::resume_candidates() const {
  ResumeCandidates c;
  for (const Item& it : queued_) c.items.push_back(&it);
  c.queued = c.items.size();
  c.written = sent_items_ + (cur_off_ > 0 ? 1 : 0);
  for (std::size_t i = 0; i < c.written && i < items_.size(); ++i) c.items.push_back(&items_[i]);
  return c;
}

// A restart (a power-up) stops the spindle; its banner is lost while the port is closed.
// If the program has the spindle turning before and through every block the controller may
// hold, a stopped spindle (FS:…,0) tells that the controller reset and lost its queue. Gives
// up (true) then.
bool Session::restarted_unseen(const ResumeCandidates& c, const GrblStatus& st,
                               const std::string& where) {
  const bool spindle_steady = std::all_of(c.items.begin(), c.items.end(), [&](const Item* it) {
    return it->spindle_on == last_spindle_on_;
  });
  if (spindle_steady && last_spindle_on_ && st.spindle_rpm && *st.spindle_rpm <= 0.0) {
    report_.position_may_be_lost = true;
    give_up(
        "after the lost link the controller's spindle is stopped (FS:…,0) while the program "
        "has it turning: the controller has reset (a restart whose banner was sent while the "
        "port was closed), so its queue and its modes are gone" +
        where);
    return true;
  }
  return false;
}

// The last candidate the controller received: index into c.items, or -1 for "none"; nullopt
// when the position does not prove it (given up).
std::optional<long> Session::last_received(const ResumeCandidates& c, std::size_t held,
                                           const Xyz& pos, const std::string& where) {
  if (c.items.empty()) {
    if (last_end_ && dist(*last_end_, pos) > kPositionTolMm) {
      give_up(
          "after the lost link the controller is not where the last move known executed "
          "ended, and it holds nothing ncd sent: it has moved or reset meanwhile" +
          where);
      return std::nullopt;
    }
    return -1;
  }
  return held == 0 ? last_received_at_rest(c, pos, where)
                   : last_received_in_motion(c, held, pos, where);
}

// The planner is empty: the position is the end point of exactly one candidate move.
std::optional<long> Session::last_received_at_rest(const ResumeCandidates& c, const Xyz& pos,
                                                   const std::string& where) {
  const std::vector<const Item*>& cands = c.items;
  long last = -1;
  int hits = 0;
  for (std::size_t i = 0; i < cands.size(); ++i) {
    if (cands[i]->geo.motion && dist(cands[i]->geo.to_mm, pos) <= kPositionTolMm) {
      ++hits;
      last = static_cast<long>(i);
    }
  }
  const bool moves =
      std::any_of(cands.begin(), cands.end(), [](const Item* it) { return it->geo.motion; });
  if (hits != 1) {
    if (hits == 0 && c.queued == cands.size() && !moves && last_end_ &&
        dist(*last_end_, pos) <= kPositionTolMm) {
      // Nothing in flight and no move queued: the controller is where the last move known
      // executed ended, so all it had ran.
      last = static_cast<long>(cands.size()) - 1;
    } else if (hits == 0) {
      report_.position_may_be_lost = pos[0] == 0.0 && pos[1] == 0.0 && pos[2] == 0.0;
      give_up(
          "after the lost link the controller is at rest where none of the blocks it may "
          "have ends (a controller that restarted, its banner lost while the port was "
          "closed, counts its position from 0 again)" +
          where);
      return std::nullopt;
    } else {
      give_up("after the lost link the position matches " + std::to_string(hits) +
              " end points of the blocks the controller may have" + where);
      return std::nullopt;
    }
  }
  return last;
}

// The planner holds `held` moves: the position lies inside exactly one candidate move's
// segment, and the planner holds that move and the ones after it (or, at its end, the ones
// after it).
std::optional<long> Session::last_received_in_motion(const ResumeCandidates& c, std::size_t held,
                                                     const Xyz& pos, const std::string& where) {
  const std::vector<const Item*>& cands = c.items;
  int hits = 0;
  long e = -1;
  bool at_end = false;
  for (std::size_t i = 0; i < cands.size(); ++i) {
    if (!cands[i]->geo.motion) continue;
    double u = 0.0;
    if (to_segment(pos, cands[i]->geo.from_mm, cands[i]->geo.to_mm, u) <= kPositionTolMm &&
        (u > 0.0 || dist(pos, cands[i]->geo.from_mm) > kPositionTolMm)) {
      ++hits;
      e = static_cast<long>(i);
      at_end = dist(pos, cands[i]->geo.to_mm) <= kPositionTolMm;
    }
  }
  if (hits != 1) {
    give_up("after the lost link the position lies on " + std::to_string(hits) +
            " of the blocks the controller may have" + where);
    return std::nullopt;
  }
  // The planner holds `held` moves starting with e (or with the move after e, at its end).
  std::size_t need = at_end ? held : held - 1;
  long last = e;
  for (std::size_t i = static_cast<std::size_t>(e) + 1; i < cands.size() && need > 0; ++i) {
    if (cands[i]->geo.motion) {
      --need;
      last = static_cast<long>(i);
    }
  }
  if (need > 0) {
    give_up("after the lost link the controller holds " + std::to_string(held) +
            " moves, more than ncd sent" + where);
    return std::nullopt;
  }
  return last;
}

// The controller has every block it had queued, and the block after the last one it received
// is a move (whether a block without motion arrived cannot be told). Else gives up (false).
bool Session::holds_what_was_queued(const ResumeCandidates& c, long last,
                                    const std::string& where) {
  if (last + 1 < static_cast<long>(c.queued)) {
    give_up(
        "after the lost link the position says the controller lacks blocks it had "
        "queued" +
        where);
    return false;
  }
  const std::size_t next = static_cast<std::size_t>(last + 1);
  if (next < c.items.size() && !c.items[next]->geo.motion) {
    give_up("after the lost link it cannot be told whether block '" +
            trim_eob(c.items[next]->bytes) + "' (no motion) reached the controller" + where);
    return false;
  }
  return true;
}

// The controller has c.items[0 .. last]: queue the written ones it received, resend the rest
// after the half-line flush, and go on (cycle start `~` when it was held).
void Session::resume_after(const ResumeCandidates& c, long last, std::size_t held,
                           const GrblStatus& st, const std::string& where) {
  const std::size_t next = static_cast<std::size_t>(last + 1);
  const std::size_t n_queued = c.queued, written = c.written;
  const std::size_t received = next > n_queued ? next - n_queued : 0;
  for (std::size_t i = 0; i < received; ++i) {
    Item it = std::move(items_.front());
    items_.pop_front();
    queue_item(std::move(it));
  }
  std::int64_t resent = 0;
  for (std::size_t i = 0; i + received < written && i < items_.size(); ++i) {
    if (items_[i].index >= 0) ++resent;
  }
  report_.blocks_resent += resent;
  sent_items_ = 0;
  cur_off_ = 0;
  unacked_bytes_ = 0;
  for (Item& it : items_) it.end_mark = -1.0;
  const std::size_t moves = queued_moves();
  if (moves > held) pop_done(moves - held);
  Item flush;
  flush.index = kFlush;
  flush.bytes = std::string(kFlushText) + eob_text(s_.line.eob);
  items_.push_front(std::move(flush));
  ++report_.reconnects;
  phase_ = Phase::Ready;
  if (st.state == "Hold:0") write_raw("~");
  emit(SenderEvent::Kind::Reopened, resume_point(),
       "the position proves what the controller holds" + where + "; resuming with block " +
           std::to_string(resume_point() + 1) +
           (resent > 0 ? " (" + std::to_string(resent) + " lost in the cut go again)"
                       : std::string()));
  confirm_journal();
}

// The first block not delivered (drip) or not known queued (ack), for progress lines.
std::int64_t Session::resume_point() const {
  for (const Item& it : items_) {
    if (it.index >= 0) return it.index;
  }
  return std::max(next_index_, skip_until_);
}

// The first block not known executed (ack) or sent (drip).
std::int64_t Session::first_unexecuted() const {
  if (ack_ && status_known()) {
    for (const Item& it : queued_) {
      if (it.index >= 0) return it.index;
    }
  }
  return resume_point();
}

void Session::confirm_journal() {
  if (journal_ == nullptr) return;
  const double now = now_s();
  const std::int64_t point = first_unexecuted();
  if (point == journaled_ || (now - journal_at_s_ < 0.02 && !source_done_)) return;
  journal_->confirm(point);
  journaled_ = point;
  journal_at_s_ = now;
}

void Session::lost_link(const std::string& why) {
  link_.reset();
  ++report_.link_losses;
  set_hold(true);
  if (ack_) {
    if (phase_ == Phase::Startup && !opened_once_before_ && !wrote_line_) {
      phase_t0_ = -1.0;  // nothing was sent yet: start again
    } else {
      opened_once_before_ = true;
    }
    line_.clear();
    conn_written_ = 0;
    emit(SenderEvent::Kind::LinkLost, first_unexecuted(),
         why + "; the first block not known executed is " + std::to_string(first_unexecuted() + 1) +
             "; on reconnecting ncd holds the controller and resumes only if its position "
             "proves which blocks it has");
    return;
  }
  // The blocks that would go again must carry N, or the controller cannot tell them.
  bool window_numbered = true;
  for (std::size_t i = 0; i < items_.size() && i <= sent_items_; ++i) {
    if (items_[i].index >= 0 && !items_[i].n) window_numbered = false;
  }
  if (!s_.controller_skips_repeated_n || !window_numbered) {
    interrupt(why +
              ": a drip-feed controller executes what it receives and says nothing, so "
              "which blocks arrived cannot be told, and a block sent again would run "
              "twice" +
              std::string(window_numbered ? "" : " (blocks to resend carry no N number)"));
    return;
  }
  // Everything still in the window goes again, except the opening framing.
  std::erase_if(items_, [](const Item& it) { return it.index == kFraming && !it.closing; });
  std::int64_t resent = 0;
  for (std::size_t i = 0; i < items_.size(); ++i) {
    if (items_[i].index >= 0 && (i < sent_items_ || (i == sent_items_ && cur_off_ > 0))) {
      ++resent;
    }
    items_[i].end_mark = -1.0;
  }
  report_.blocks_resent += resent;
  sent_items_ = 0;
  cur_off_ = 0;
  conn_written_ = 0;
  model_delivered_ = 0.0;
  unacked_bytes_ = 0;
  line_.clear();
  if (!xon_) end_xoff();
  xon_ = true;
  cts_low_ = false;
  emit(SenderEvent::Kind::LinkLost, resume_point(),
       why + "; will resume at block " + std::to_string(resume_point() + 1) +
           " (the controller discards the N numbers it already has)");
}

}  // namespace ncd::comms::dnc_detail

namespace ncd::comms {

using dnc_detail::Clock;
using dnc_detail::dist;
using dnc_detail::kPositionTolMm;
using dnc_detail::to_segment;
using dnc_detail::Xyz;
using text::fixed;

PositionMatch match_position(const std::string& program_path, std::int64_t first, std::int64_t end,
                             const Xyz& position) {
  ProgramFile src(program_path);
  ProgramModal modal;
  std::string text;
  std::vector<std::pair<std::int64_t, BlockMotion>> moves;  // candidates, oldest first
  std::optional<std::pair<std::int64_t, BlockMotion>> before;
  for (std::int64_t k = 0; k < end && src.next(text) == BlockStatus::Ready; ++k) {
    const BlockMotion m = modal.apply(text);
    if (!m.motion) continue;
    if (k < first) {
      before = {k, m};
    } else {
      moves.emplace_back(k, m);
    }
  }
  if (before) moves.insert(moves.begin(), *before);
  PositionMatch r;
  int hits = 0;
  for (const auto& [k, m] : moves) {
    double u = 0.0;
    if (to_segment(position, m.from_mm, m.to_mm, u) > kPositionTolMm) continue;
    const bool at_end = dist(position, m.to_mm) <= kPositionTolMm;
    if (!at_end && dist(position, m.from_mm) <= kPositionTolMm) continue;  // the previous's end
    ++hits;
    r.move = k;
    r.at_end = at_end;
  }
  if (hits == 1) {
    r.first_not_done = r.at_end ? r.move + 1 : r.move;
  } else {
    r.why = hits == 0 ? "it lies on none of the moves ncd may have sent"
                      : "it lies on " + std::to_string(hits) + " of the moves ncd may have sent";
  }
  return r;
}

GrblProbe probe_grbl(const SenderSettings& s, double settle_s) {
  GrblProbe p;
  std::unique_ptr<SerialLink> link;
  try {
    link = std::make_unique<SerialLink>(s.line);
  } catch (const LinkError& e) {
    p.failure = std::string("cannot open the link: ") + e.what();
    return p;
  }
  const auto t0 = Clock::now();
  const auto since = [&] { return std::chrono::duration<double>(Clock::now() - t0).count(); };
  std::string line;
  std::optional<GrblStatus> last;
  std::optional<Xyz> wco;
  int reports = 0;
  double next_ask = s.banner_wait_s;
  const auto on_line = [&](const std::string& text) {
    if (text.rfind("Grbl ", 0) == 0) {
      p.banner = true;
      next_ask = std::min(next_ask, since());
    } else if (auto st = parse_grbl_status(text)) {
      ++reports;
      if (st->wco) wco = st->wco;
      last = st;
    }
  };
  try {
    while (since() < s.banner_wait_s + settle_s) {
      char buf[256];
      for (std::size_t n; (n = link->read_some(buf, sizeof buf)) > 0;) {
        for (std::size_t i = 0; i < n; ++i) {
          if (buf[i] == '\n') {
            if (!line.empty() && line.back() == '\r') line.pop_back();
            on_line(line);
            line.clear();
          } else if (line.size() < 256) {
            line += buf[i];
          }
        }
      }
      const bool moving = last && (last->state == "Run" || last->state == "Jog" ||
                                   last->state == "Home" || last->state == "Hold:1");
      // grbl prints WCO: on the first report after a reset and then every 10th or 30th.
      const bool located = last && (last->wpos || wco || reports >= 31);
      if (last && !moving && located) break;
      if (since() >= next_ask) {
        link->write_some("?");
        next_ask = since() + 0.1;
      }
      link->wait(5, false);
    }
  } catch (const LinkError& e) {
    p.failure = std::string("the link failed: ") + e.what();
    return p;
  }
  if (!last) {
    p.failure = "the controller answered no status report ('?') within " +
                fixed(s.banner_wait_s + settle_s, 1) + " s";
    return p;
  }
  p.spoke = true;
  p.state = last->state;
  p.free_blocks = last->free_blocks;
  if (last->wpos) {
    p.position = last->wpos;
  } else if (last->mpos && wco) {
    p.position = Xyz{(*last->mpos)[0] - (*wco)[0], (*last->mpos)[1] - (*wco)[1],
                     (*last->mpos)[2] - (*wco)[2]};
  }
  return p;
}

}  // namespace ncd::comms
