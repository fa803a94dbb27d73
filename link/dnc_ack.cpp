// Acknowledged streaming (grbl 1.1): lines from the controller, `ok` and `error:N`, character
// counting within its receive buffer, and the status reports that tell which queued blocks are
// executed (Ln:, Bf:, the position). The algorithm: the top of dnc_sender.cpp.
#include "link/dnc_session.hpp"

#include <charconv>

#include "link/dnc_block_text.hpp"
#include "link/transfer_journal.hpp"

namespace ncd::comms::dnc_detail {

void Session::ack_byte(char c) {
  if (c == kXoff || c == kXon) {  // some controllers pace with DC1/DC3 on top of the acks
    drip_byte(c);
    return;
  }
  if (c == '\r') return;
  if (c != '\n') {
    if (line_.size() < 256) line_ += c;
    return;
  }
  const std::string line = line_;
  line_.clear();
  if (!line.empty()) ack_line(line);
}

bool Session::is_banner(const std::string& line) {
  return line.rfind("Grbl ", 0) == 0;
}

void Session::ack_line(const std::string& line) {
  if (over()) return;  // the job is over; what still comes is not acted on
  if (line.rfind("ALARM", 0) == 0 || is_banner(line) ||
      line.rfind("[MSG:Reset to continue]", 0) == 0) {
    track_ok_ = false;  // the planner may have been cleared: Bf no longer counts executed
  }
  if (stopping_ && is_banner(line)) reset_seen_ = true;  // the halt's reset, in any phase
  if (auto st = parse_grbl_status(line)) {
    on_status(*st);
    return;
  }
  if (end_.step == Ending::Holding || end_.step == Ending::Resetting) {
    ending_line(line);
    return;
  }
  if (phase_ == Phase::Startup) {
    startup_line(line);
    return;
  }
  if (stopping_) {  // after a hold for an error: account what still comes, nothing else
    if (line == "ok" && sent_items_ > 0) take_ok();
    if (is_banner(line)) reset_seen_ = true;
    return;
  }
  if (line.front() == '[' && line.rfind("[MSG:Reset to continue]", 0) != 0) {
    // grbl's feedback messages ([MSG:…], [GC:…]): informative
    report_.notes.push_back("the controller said " + line);
    return;
  }
  if (line == "ok") {
    if (sent_items_ == 0) {
      noise(3, '\0');  // an `ok` for nothing we sent
      return;
    }
    if (items_.front().index == kFlush) {
      half_line_queued();
      return;
    }
    take_ok();
  } else if (line.rfind("error:", 0) == 0) {
    if (sent_items_ > 0 && items_.front().index == kFlush) {  // refused, as it must be
      unacked_bytes_ -= static_cast<int>(items_.front().bytes.size());
      items_.pop_front();
      --sent_items_;
      return;
    }
    const std::int64_t block = sent_items_ > 0 ? items_.front().index : next_index_;
    const std::string what = sent_items_ > 0 ? " ('" + trim_eob(items_.front().bytes) + "')" : "";
    if (sent_items_ > 0) {
      // The rejected line: grbl did not queue it, and it is not sent again. The oks that come
      // while stopping belong to the lines after it.
      if (block >= 0) {
        report_.rejected_block = block;
        rejected_reply_ = line;
      }
      unacked_bytes_ -= static_cast<int>(items_.front().bytes.size());
      items_.pop_front();
      --sent_items_;
    }
    stop_controller("the controller rejected " +
                    (block >= 0 ? "block " + std::to_string(block + 1) : std::string("a line")) +
                    " with " + line + what);
  } else if (line.rfind("ALARM", 0) == 0) {
    stop_controller("the controller raised " + line);
  } else if (is_banner(line) || line.rfind("[MSG:Reset to continue]", 0) == 0) {
    controller_reset("the controller reset mid-program ('" + line + "')");
  } else {
    noise(line.size() + 1, '\0');
  }
}

// The flush after a lost link was answered ok: it completed a half line that was inside a `;`
// comment, so the code of that line had all arrived and is now queued. That line can only be
// the first one the controller did not receive whole, which heads the lines to send again.
void Session::half_line_queued() {
  unacked_bytes_ -= static_cast<int>(items_.front().bytes.size());
  items_.pop_front();
  --sent_items_;
  if (sent_items_ != 0 || items_.empty() || items_.front().index < 0 ||
      !has_semicolon_comment(items_.front().bytes)) {
    interrupt(
        "the controller accepted the line that should have ended a half line after the link "
        "came back, and the first line to send again has no ';' comment that would explain it; "
        "not sending more");
    return;
  }
  Item it = std::move(items_.front());
  items_.pop_front();
  --report_.blocks_resent;
  report_.notes.push_back("block " + std::to_string(it.index + 1) +
                          " was cut inside its ';' comment by the lost link; the controller "
                          "completed and queued it, so it was not sent again");
  queue_item(std::move(it));
}

std::string Session::trim_eob(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r')) s.pop_back();
  return s;
}

// The front unanswered line was answered ok: the controller queued it.
void Session::take_ok() {
  Item it = std::move(items_.front());
  items_.pop_front();
  --sent_items_;
  unacked_bytes_ -= static_cast<int>(it.bytes.size());
  queue_item(std::move(it));
}

void Session::queue_item(Item it) {
  if (it.index >= 0) ++report_.blocks_queued;
  if (!it.geo.motion && queued_.empty()) {
    executed(it);
  } else {
    queued_.push_back(std::move(it));
  }
  confirm_journal();
}

void Session::executed(const Item& it) {
  last_spindle_on_ = it.spindle_on;
  if (it.geo.motion) last_end_ = it.geo.to_mm;
  if (it.index >= 0) {
    ++executed_count_;
    last_executed_ = it.index;
    if (on_executed_) on_executed_(executed_count_, last_executed_);
  }
}

// Marks the oldest queued blocks done: `moves` moves and the blocks without motion that
// follow them (they took effect once the moves before them were done).
void Session::pop_done(std::size_t moves) {
  while (!queued_.empty()) {
    if (queued_.front().geo.motion) {
      if (moves == 0) break;
      --moves;
    }
    executed(queued_.front());
    queued_.pop_front();
  }
}

std::size_t Session::queued_moves() const {
  return static_cast<std::size_t>(
      std::count_if(queued_.begin(), queued_.end(), [](const Item& it) { return it.geo.motion; }));
}

Xyz Session::work_position(const GrblStatus& st) {
  if (st.wco) status_.wco = *st.wco;
  if (st.wpos) return *st.wpos;
  const Xyz m = st.mpos.value_or(Xyz{});
  return {m[0] - status_.wco[0], m[1] - status_.wco[1], m[2] - status_.wco[2]};
}

void Session::on_status(const GrblStatus& st) {
  ++report_.status_reports;
  status_.supported = true;
  status_.last = st;
  status_.position = work_position(st);
  status_.have = true;
  if (st.wco || st.wpos) status_.wco_known = true;
  ControllerReport published;
  published.status = st;
  published.work_mm = status_.position;
  published.wco_known = status_.wco_known;
  published.received = Clock::now();
  published.reports = report_.status_reports;
  reports_.publish(published);
  if (phase_ == Phase::Startup) start_.spoke = true;
  if (phase_ != Phase::Ready && !stopping_) return;  // startup and recovery read it themselves
  if (!track_ok_ || st.state == "Alarm") return;
  track(st, status_.position);
}

void Session::track(const GrblStatus& st, const Xyz& pos) {
  const std::size_t moves = queued_moves();
  if (st.state == "Idle") {  // everything queued has run, whatever the fields say
    pop_done(moves);
    basis(st.line_number ? "Ln" : st.free_blocks ? "Bf" : "position");
    confirm_journal();
    return;
  }
  // Ln: and Bf: count the planner's blocks, and grbl drops a block from its planner when the
  // stepper has prepared its last segment, up to kGrblSegments segments before the motion
  // gets there: the moves that left the planner are prepared, not known done. Only the last
  // kGrblSegments of them may still run; which one does, the position tells.
  std::optional<std::size_t> left;  // queued moves that have left the planner
  if (st.line_number) {
    const auto at = std::find_if(queued_.begin(), queued_.end(),
                                 [&](const Item& it) { return it.n == st.line_number; });
    if (at != queued_.end()) {
      left = static_cast<std::size_t>(
          std::count_if(queued_.begin(), at, [](const Item& it) { return it.geo.motion; }));
    }
    basis("Ln");
  } else if (st.free_blocks) {
    const auto held = static_cast<std::size_t>(std::max(0, s_.planner_blocks - *st.free_blocks));
    left = moves > held ? moves - held : 0;
    basis("Bf");
  } else {
    basis("position");
  }
  const bool held = st.state.rfind("Hold:0", 0) == 0;  // a finished hold re-plans: no lag
  std::size_t done = left ? (held ? *left : *left - std::min(*left, kGrblSegments)) : 0;
  // The move the position lies on, if exactly one of the moves that may be executing: the
  // ones before it are done. "On" means past its start by more than the tolerance (and short
  // of its end): grbl rounds the position to 3 decimals, so a machine 0.4 µm before the end of
  // a move can report that end, which is the next move's start.
  const std::size_t window = left ? std::min(moves, *left + 1) : moves;
  std::size_t k = 0, hit = 0;
  int hits = 0;
  for (const Item& it : queued_) {
    if (!it.geo.motion) continue;
    if (k >= window) break;
    double u = 0.0;
    if (to_segment(pos, it.geo.from_mm, it.geo.to_mm, u) <= kPositionTolMm && u < 1.0 &&
        dist(pos, it.geo.from_mm) > kPositionTolMm) {
      ++hits;
      hit = k;
    }
    ++k;
  }
  if (hits == 1) done = std::max(done, hit);
  pop_done(done);
  confirm_journal();
}

void Session::basis(const char* how) {
  if (report_.execution_basis.empty()) report_.execution_basis = how;
}

void Session::poll_status() {
  if (s_.status_hz <= 0.0) return;
  const double now = now_s();
  if (now < status_.next_poll_s) return;
  status_.next_poll_s = now + 1.0 / s_.status_hz;
  write_raw("?");
  if (++status_.polls >= 20 && !status_.have && status_.supported) {
    status_.supported = false;
    report_.execution_basis = "not known: the controller does not answer '?'";
    report_.notes.push_back(
        "the controller answered no status report: executed blocks are not known; "
        "'completed' means every block was queued (answered ok)");
  }
}

void Session::write_raw(std::string_view bytes) {
  std::size_t off = 0;
  const double until = now_s() + 1.0;
  while (off < bytes.size() && now_s() < until) {
    const std::size_t n = link_->write_some(bytes.substr(off));
    off += n;
    report_.bytes_written += static_cast<std::int64_t>(n);
    if (off < bytes.size()) link_->wait(1, true);
  }
}

void Session::write_ack() {
  if (s_.line.flow == Flow::XonXoff && !xon_) return;
  while (true) {
    // Nothing after the half-line flush until its reply says whether it completed a block.
    if (sent_items_ > 0 && items_.front().index == kFlush) return;
    if (sent_items_ == items_.size() && !pull()) return;
    Item& it = items_[sent_items_];
    const int size = static_cast<int>(it.bytes.size());
    if (size > s_.rx_buffer_bytes) {
      report_.failure = "block " + std::to_string(it.index + 1) + " has " + std::to_string(size) +
                        " characters, more than the controller's " +
                        std::to_string(s_.rx_buffer_bytes) +
                        "-byte receive buffer: raise --rx-buffer to the controller's size or "
                        "shorten the block";
      return;
    }
    if (cur_off_ == 0 && unacked_bytes_ + size > s_.rx_buffer_bytes) return;
    if (cur_off_ == 0) unacked_bytes_ += size;
    if (cur_off_ == 0 && journal_ != nullptr && it.index >= 0) journal_->note_writing(it.index);
    wrote_line_ = true;
    report_.max_unacked_bytes = std::max(report_.max_unacked_bytes, unacked_bytes_);
    const std::size_t n = link_->write_some(std::string_view(it.bytes).substr(cur_off_));
    conn_written_ += static_cast<std::int64_t>(n);
    report_.bytes_written += static_cast<std::int64_t>(n);
    cur_off_ += n;
    if (cur_off_ < it.bytes.size()) return;
    it.end_mark = static_cast<double>(conn_written_);
    written(it);
    ++sent_items_;
    cur_off_ = 0;
  }
}

}  // namespace ncd::comms::dnc_detail

namespace ncd::comms {
namespace {

using dnc_detail::Xyz;

std::optional<Xyz> axes(std::string_view v) {
  Xyz out{};
  for (std::size_t k = 0; k < 3; ++k) {
    const auto comma = v.find(',');
    const std::string_view part = v.substr(0, comma);
    double x = 0.0;
    const char* first = part.data();
    if (!part.empty() && part[0] == '+') ++first;
    const auto r = std::from_chars(first, part.data() + part.size(), x);
    if (r.ec != std::errc()) return std::nullopt;
    out[k] = x;
    if (comma == std::string_view::npos)
      return k == 2 || k == 1 ? std::optional<Xyz>(out) : std::nullopt;
    v.remove_prefix(comma + 1);
  }
  return out;
}

}  // namespace

std::optional<GrblStatus> parse_grbl_status(std::string_view line) {
  if (line.size() < 3 || line.front() != '<' || line.back() != '>') return std::nullopt;
  line = line.substr(1, line.size() - 2);
  GrblStatus st;
  bool first = true;
  while (!line.empty() || first) {
    const auto bar = line.find('|');
    const std::string_view field = line.substr(0, bar);
    line = bar == std::string_view::npos ? std::string_view() : line.substr(bar + 1);
    if (first) {
      if (field.empty()) return std::nullopt;
      st.state = std::string(field);
      first = false;
      continue;
    }
    const auto colon = field.find(':');
    if (colon == std::string_view::npos) continue;
    const std::string_view key = field.substr(0, colon), value = field.substr(colon + 1);
    if (key == "MPos") {
      st.mpos = axes(value);
      if (!st.mpos) return std::nullopt;
    } else if (key == "WPos") {
      st.wpos = axes(value);
      if (!st.wpos) return std::nullopt;
    } else if (key == "WCO") {
      st.wco = axes(value);
    } else if (key == "Bf") {
      const auto comma = value.find(',');
      int b = 0, r = 0;
      if (comma == std::string_view::npos ||
          std::from_chars(value.data(), value.data() + comma, b).ec != std::errc() ||
          std::from_chars(value.data() + comma + 1, value.data() + value.size(), r).ec !=
              std::errc()) {
        return std::nullopt;
      }
      st.free_blocks = b;
      st.free_bytes = r;
    } else if (key == "FS" || key == "F") {
      const auto comma = value.find(',');
      double f = 0.0, rpm = 0.0;
      const std::string_view fv = value.substr(0, comma);
      if (std::from_chars(fv.data(), fv.data() + fv.size(), f).ec == std::errc()) st.feed = f;
      if (comma != std::string_view::npos &&
          std::from_chars(value.data() + comma + 1, value.data() + value.size(), rpm).ec ==
              std::errc()) {
        st.spindle_rpm = rpm;
      }
    } else if (key == "Ln") {
      long n = 0;
      if (std::from_chars(value.data(), value.data() + value.size(), n).ec == std::errc()) {
        st.line_number = n;
      }
    }
  }
  if (!st.mpos && !st.wpos) return std::nullopt;
  return st;
}

}  // namespace ncd::comms
