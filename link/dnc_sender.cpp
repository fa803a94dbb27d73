// DNC sender (docs/dnc-link.md). Blocks go out as a byte stream; what matters is how far ahead
// of the controller the sender may be and what it knows about what the controller has.
//
//   source ──► [ queued (ack: ok'd, not known executed) | written, unanswered | not written ]
//                ▲ first block not known executed (journal)
//
// Drip feed. The controller paces with DC1/DC3 (or CTS). The sender keeps at most
// max_queued_chars ahead of the wire, so that after a DC3 it stops within that many
// characters. "Ahead of the wire" is the larger of the kernel's output queue (TIOCOUTQ, true on
// a UART) and a wire model: bytes written minus the bytes the line can have carried since,
// at pacing_fraction of its capacity (a pseudo-terminal has no output queue to ask). A block is
// delivered when the model and the kernel both say its last byte has left. Drip feed has no
// confirmation and no report: "sent" is all that is known, and the report says so. After a
// lost link the sender cannot tell which blocks arrived, and a controller executes a block it
// receives twice; so it resends (a resend window of characters before the first block it
// cannot vouch for) only when the controller is documented to discard a repeated N
// (controller_skips_repeated_n, numbered blocks). Otherwise the job stops as interrupted.
//
// Acknowledged streaming (grbl 1.1). Nothing is sent before the controller has spoken: the
// sender waits banner_wait_s for the banner ("Grbl 1.1h ['$' for help]"), else asks `?` (a
// real-time byte), else wakes it with the half-line flush and waits for its answer, up to
// startup_timeout_s. Then a status says whether it can take a program: Idle goes on (after the
// flush, when there was no banner); Alarm ends the job before any line (with `unlock`, `$X`
// first); a hold (grbl reads no line while held at rest) is brought to a safe halt; Run and the
// rest end the job. Each line is answered `ok` (queued) or `error:N`; character counting keeps
// the sum of unanswered lines within the receive buffer.
// `?` is polled at status_hz; each status report says which of the queued blocks are done:
//   Idle      all done;
//   Ln:n      the moves before block n have left grbl's planner;
//   Bf:b,r    the planner holds planner_blocks − b moves: the older queued moves have left it;
// a move leaves grbl's planner when its last segment is prepared, and up to kGrblSegments (5)
// of those may still run, so all but the last 5 that left are done (all, in Hold:0); and if the
// reported position lies on exactly one of the moves that may run, the ones before it are done.
// A block without motion takes effect when the moves before it are done. A report that
// comes after an `ok` in the stream was made after that block was queued, so the counts agree.
// A banner, `[MSG:Reset to continue]` or ALARM mid-program is a reset: the job is interrupted,
// the report names the last block known executed and the first not known executed, and ncd
// does not resume past it. On error:N or ALARM, on a stop with halt_on_stop, and on
// request_halt the sender brings grbl to a safe halt: `!`, then `?` until the state is at rest
// (Hold:0, Idle, Alarm: a reset during the hold's deceleration, Hold:1, is a reset in motion,
// which raises ALARM:3 and locks grbl), then 0x18, its banner, and a status for the state left
// (the report's controller_state; Alarm means `$X` is needed). It reports what the reset
// dropped; the rejected line itself is neither queued nor credited with the oks that follow.
//
// A lost link (ack). The port is reopened with back-off (0.1 s doubling to 2 s, for up to
// reconnect_max_s). A banner on the new connection is a reset: interrupted. Otherwise the
// sender holds (`!`) and reads status until the controller is held or idle. A restart can hide
// here, its banner sent while the port was closed: a spindle stopped (FS:…,0) where the program
// has it turning, or a position that is no candidate's, tells it. The sender resumes only
// if the position proves what the controller holds: the receive buffer is empty (Bf), and
// either the planner is empty and the position is the end point of exactly one candidate move
// (queued or sent), or the position lies inside exactly one candidate move's segment and the
// planner holds that move and the P − 1 after it. The moves up to the last one held are then
// queued; the ones sent after it were lost and go again, after the half-line flush (kFlushText)
// and its answer: a half line the cut left in grbl's line buffer is refused whole with it, or,
// cut inside its `;` comment, queued (ok), and then not sent again. Anything else (no Bf, a
// non-empty buffer, a full planner, a position that matches none or several, a block without
// motion right after the last one held) stops as interrupted, and the controller, held to be
// asked, is not left held: the safe halt completes the hold with a reset.
//
// Ending early (ack, end_with; docs/dnc-link.md "Ending early"). A job that stops, fails or is
// shut down mid-program must not leave grbl running the blocks it queued, which can be seconds
// of cutting ahead of the stop. Once the link is ready the sender takes no more program blocks,
// drops those not yet written, writes `!` (grbl decelerates on the path at once) and polls `?`
// until the state is Hold:0: the hold is complete, and a soft reset now raises no ALARM:3 (grbl
// clears its hold flag when the hold completes; only a reset in motion loses the position). It
// then writes 0x18: grbl drops its planner and receive buffer, stops the spindle and the
// coolant, keeps the position and sends its banner. After the banner the lines of the job's
// ending, made for the position the hold left (the status's work position), go out as any lines
// do, each answered ok, and are followed to Idle. An alarm, a missing Hold:0 within 5 s or a
// missing banner within startup_timeout_s ends the transfer with the ending not sent.
//
// Faults. A hang-up or I/O error closes the port. A hold (XOFF or CTS) longer than
// xoff_timeout_s is reported and raises the hold callback, which a live job uses to bring the
// motion to a planned stop. NAK or SYN (drip) stop the transfer with the block named. Other
// bytes are noise: counted, logged, ignored. The journal records the first block not known
// executed (ack) or sent (drip: carried by the line), so a restarted ncd resumes there, and a
// bound on the blocks written (raised 32 blocks at a time, before the block goes out), so that
// after ncd was killed the blocks grbl may have run on with are known: match_position finds the
// one its position lies on, and probe_grbl asks grbl where it is with `?` alone.
//
// Live counters (docs/dnc-link.md, "Live counters"). After each pass of the loop, and at the
// end, the session stores what it has done so far into relaxed atomics (SenderCounters), read
// by the owner without a lock. An underrun is counted when a dry spell begins: everything
// written, the source not ready and not over, the controller not holding, after the first
// block, and not while the owner holds the motion feeding the source (set_source_held) or in
// the dry spell that continues after such a hold.
//
// Where it lives. This file: the public API and the run loop (one pass: read, account, write,
// confirm), taking blocks from the source, the live counters and the report. The session's
// state: dnc_session.hpp. Drip feed, DC1/DC3 and CTS: dnc_drip.cpp. Acknowledged streaming
// (answers, character counting, status tracking): dnc_ack.cpp; its start-up: dnc_startup.cpp. A
// lost link, resuming and the journal: dnc_resume.cpp. Ending early and the safe halt:
// dnc_ending.cpp. The N-word and `;` text helpers: dnc_block_text.cpp.
#include "link/dnc_sender.hpp"

#include "link/dnc_session.hpp"
#include "link/thread_priority.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "core/error.hpp"
#include "link/dnc_block_text.hpp"
#include "link/program_file.hpp"
#include "link/transfer_journal.hpp"

namespace ncd::comms::dnc_detail {

Session::Session(const SenderSettings& s, BlockSource& source, const DncSender::EventFn& on_event,
                 const DncSender::HoldFn& on_hold, TransferJournal* journal,
                 std::int64_t first_block, SenderCounters& counters, ControllerReportBox& reports,
                 const std::atomic<bool>& halt_request, const std::atomic<bool>& end_requested,
                 const DncSender::EndingFn& ending, const std::atomic<bool>& source_held)
    : s_(s),
      source_(source),
      on_event_(on_event),
      on_hold_(on_hold),
      journal_(journal),
      counters_(counters),
      reports_(reports),
      halt_request_(halt_request),
      end_requested_(end_requested),
      ending_fn_(ending),
      source_held_(source_held),
      ack_(s.line.protocol == Protocol::Ack),
      cps_(chars_per_s(s.line)),
      window_(s.resend_window_chars >= 0
                  ? s.resend_window_chars
                  : s.max_queued_chars + static_cast<int>(std::ceil(0.25 * cps_))) {
  report_.first_block = first_block;
  skip_until_ = first_block;
  if (!ack_ && s.line.percent_framing && first_block == 0) {
    Item open;
    open.bytes =
        std::string(static_cast<std::size_t>(s.line.nul_leader), '\0') + "%" + eob_text(s.line.eob);
    items_.push_back(open);
  }
  ProgramModal pre;
  for (const std::string& line : s.preamble) {
    Item it;
    it.index = kPreamble;
    it.bytes = line + eob_text(s.line.eob);
    it.geo = pre.apply(line);
    it.spindle_on = spins(pre.state());
    items_.push_back(std::move(it));
  }
  report_.startup = ack_ ? "none" : "";
  if (!ack_) {
    report_.execution_basis = "not known: drip feed has no reply; sent is all that is known";
  } else if (s.status_hz <= 0.0) {
    report_.execution_basis = "not known: status polling is off";
  }
}

SenderReport Session::run(const std::atomic<bool>& stop) {
  t0_ = Clock::now();
  last_tick_s_ = wire_now_s();
  next_progress_s_ = s_.progress_period_s;
  while (true) {
    const bool halt = halt_request_.load() || (s_.halt_on_stop && stop.load());
    if (halt || stop.load(std::memory_order_relaxed)) {
      report_.stopped = true;
      if (halt && ack_) halt_on_request();
      if (!ack_) drain_on_stop();
      break;
    }
    if (!link_ && !reopen(stop)) break;
    try {
      if (!step()) break;
    } catch (const LinkError& e) {
      lost_link(e.what());
    }
    publish();
  }
  finish();
  publish();
  return report_;
}

// The live counters (SenderCounts), stored once per pass: plain reads of the session's own
// state and relaxed atomic stores.
void Session::publish() {
  SenderCounts c;
  c.bytes_written = report_.bytes_written;
  c.blocks_taken = report_.blocks;
  c.blocks_written = report_.blocks_sent;
  c.blocks_acked = ack_ ? report_.blocks_queued : -1;
  c.blocks_executed = ack_ && status_known() ? executed_count_ : -1;
  c.xoff_count = report_.xoff_count;
  c.xoff_held = !xon_ || cts_low_;
  if (ack_) {
    c.buffer_bytes = unacked_bytes_;
    c.buffer_limit_bytes = s_.rx_buffer_bytes;
  } else {
    const double ahead =
        std::max(static_cast<double>(outq_), static_cast<double>(conn_written_) - delivered());
    c.buffer_bytes = link_ ? static_cast<int>(std::ceil(std::max(ahead, 0.0))) : 0;
    c.buffer_limit_bytes = s_.max_queued_chars;
  }
  c.underruns = underruns_;
  c.reconnects = report_.reconnects;
  c.link_losses = report_.link_losses;
  counters_.store(c);
}

// An underrun begins when the sender has written everything it has, the source has nothing
// yet and the program is not over, while the controller does not hold the line (a hold is
// the controller's own wish) and after the first block went out (before it, nothing runs).
void Session::watch_underrun() {
  // While the motion feeding the source is held (the operator's hold), or in the dry spell
  // that goes on after it until the next block, nothing starves: the tool is at rest.
  if (source_held_.load(std::memory_order_relaxed)) {
    dry_ = true;
    return;
  }
  const bool nothing = source_waiting_ && !source_done_ && sent_items_ == items_.size();
  const bool held = !xon_ || cts_low_;
  const bool dry = nothing && !held && report_.blocks_sent > 0 && (!ack_ || phase_ == Phase::Ready);
  if (dry && !dry_) ++underruns_;
  dry_ = dry;
}

void Session::emit(SenderEvent::Kind kind, std::int64_t block, std::string text) {
  if (on_event_) on_event_(SenderEvent{kind, now_s(), block, std::move(text)});
}

void Session::set_hold(bool hold) {
  if (hold == holding_) return;
  holding_ = hold;
  if (on_hold_) on_hold_(hold);
}

// One pass: read, account, write, confirm. False when the transfer is over.
bool Session::step() {
  read_input();
  if (over()) return false;
  advance_model();
  watch_hold();
  if (ack_) {
    if (phase_ == Phase::Startup) startup();
    if (phase_ == Phase::Recovering) recovering();
    if (phase_ == Phase::Ready && end_.step == Ending::None &&
        end_requested_.load(std::memory_order_acquire)) {
      begin_ending();
    }
    if (end_.step == Ending::Holding || end_.step == Ending::Resetting) {
      ending_step();
    } else if (phase_ == Phase::Ready) {
      write_ack();
      poll_status();
    }
  } else {
    write_drip();
    confirm_drip();
  }
  if (over()) return false;
  watch_underrun();
  progress();
  if (done()) {
    if (end_.step == Ending::Sending) {  // the ending, not the program, went to its end
      report_.ending.sent = true;
      report_.ending.executed = status_known();
      emit(SenderEvent::Kind::Ending, report_.blocks,
           std::string("the ending was ") +
               (status_known() ? "executed (the controller is idle)" : "queued"));
    } else if (end_.step == Ending::None) {
      // Only a transfer from the start: a controller resumed or restarted mid-program (a
      // journal, --restart-from) is already in receive mode and owes no new DC1.
      const bool from_start = report_.first_block == 0 && s_.preamble.empty();
      if (!heard_ && from_start) wait_for_a_word();
      if (over()) return false;
      report_.completed = true;
      report_.controller_silent = !heard_ && from_start;
    }
    return false;
  }
  link_->wait(wait_ms(), false);
  return true;
}

int Session::wait_ms() const {
  return source_waiting_ ? 5 : 1;
}

bool Session::done() const {
  if (end_.step == Ending::NotNeeded) return true;
  if (end_.step == Ending::Holding || end_.step == Ending::Resetting) return false;
  if (!source_done_) return false;
  if (ack_) return phase_ == Phase::Ready && items_.empty() && (queued_.empty() || !status_known());
  return std::all_of(items_.begin(), items_.end(), [&](const Item& it) {
    return it.end_mark >= 0.0 && it.end_mark <= delivered();
  });
}

void Session::read_input() {
  char buf[256];
  while (link_) {
    const std::size_t n = link_->read_some(buf, sizeof buf);
    if (n == 0) return;
    heard_ = true;
    for (std::size_t i = 0; i < n; ++i) ack_ ? ack_byte(buf[i]) : drip_byte(buf[i]);
  }
}

// Ends the job as interrupted. The report names the last block known executed and the first
// not known executed; what to do next is the caller's (ncd stream prints it).
void Session::interrupt(const std::string& why) {
  report_.interrupted = true;
  const std::int64_t first = first_unexecuted();
  std::string where;
  if (ack_ && status_known()) {
    where = "; last block known executed: " +
            (last_executed_ >= 0 ? std::to_string(last_executed_ + 1) : std::string("none")) +
            ", first block not known executed: " + std::to_string(first + 1) + "; not resuming";
  } else {
    where = "; first block not sent: " + std::to_string(first + 1) +
            " (which blocks arrived and executed is not known on this link)";
  }
  report_.failure = why + where;
}

void Session::noise(std::size_t bytes, char c) {
  report_.noise_bytes += static_cast<std::int64_t>(bytes);
  if (++noise_events_ <= 10 || noise_events_ % 100 == 0) {
    emit(SenderEvent::Kind::Noise, resume_point(),
         ack_ ? "ignored an unexpected line from the controller"
              : "ignored an unexpected byte 0x" + hex_byte(c) + " from the controller");
  }
}

std::string Session::hex_byte(char c) {
  static constexpr char kHex[] = "0123456789abcdef";
  const auto u = static_cast<unsigned char>(c);
  return std::string{kHex[u >> 4], kHex[u & 0xF]};
}

// Pulls the next block from the source into the window; false if none is ready.
bool Session::pull() {
  if (source_done_) return false;
  std::string text;
  while (true) {
    const BlockStatus st = source_.next(text);
    if (st == BlockStatus::NotYet) {
      source_waiting_ = true;
      return false;
    }
    source_waiting_ = false;
    if (st == BlockStatus::End) {
      source_done_ = true;
      if (!ack_ && s_.line.percent_framing) {
        Item close;
        close.closing = true;
        close.bytes = std::string("%") + eob_text(s_.line.eob);
        items_.push_back(close);
        return true;
      }
      return false;
    }
    if (s_.dialect) {
      if (const auto v = check_line(*s_.dialect, text, dialect_state_)) {
        report_.failure = "block " + std::to_string(next_index_ + 1) +
                          " refused before it was sent: " + describe(*v, *s_.dialect);
        source_done_ = true;
        return false;
      }
    }
    sha_.update(text);
    sha_.update("\n");
    const std::int64_t index = next_index_++;
    ++report_.blocks;
    report_.program_bytes += static_cast<std::int64_t>(text.size() + 1);
    const BlockMotion geo = modal_.apply(text);
    if (index < skip_until_) {
      last_spindle_on_ = spins(modal_.state());  // a restart's preamble sets this state again
      continue;
    }
    Item it;
    it.index = index;
    it.bytes = text + eob_text(s_.line.eob);
    it.geo = geo;
    it.n = n_word(text);
    it.spindle_on = spins(modal_.state());
    it.wait_s = wait_of_block(text, s_.tool_change_s);
    items_.push_back(std::move(it));
    return true;
  }
}

void Session::written(const Item& it) {
  motion_written_ = motion_written_ || it.geo.motion;
  if (it.wait_s > 0.0) waits_.push_back({report_.bytes_written, it.wait_s});
  if (it.index >= 0 && it.index >= sent_high_) {
    sent_high_ = it.index + 1;
    ++report_.blocks_sent;
  }
}

// Opens (or reopens) the port with back-off; false if it could not be opened in time.
bool Session::reopen(const std::atomic<bool>& stop) {
  if (over()) return false;
  const double start = now_s();
  // The window is timed on the hold clock (the controller's, in a simulated-time test), so a
  // loaded test thread does not see the sender give up before the controller's time allows.
  const double window_start = hold_now_s();
  double backoff = 0.1;
  std::string last_error;
  while (!stop.load(std::memory_order_relaxed)) {
    try {
      link_ = std::make_unique<SerialLink>(s_.line);
      last_tick_s_ = wire_now_s();
      if (opened_once_) {
        emit(SenderEvent::Kind::Reopened, resume_point(),
             "reopened " + s_.line.device + " after " + fixed(now_s() - start, 1) + " s");
        if (!ack_) ++report_.reconnects;
      } else {
        emit(SenderEvent::Kind::Opened, resume_point(),
             "opened " + s_.line.device + " at " + describe(s_.line));
      }
      opened_once_ = true;
      phase_ = Phase::Startup;
      phase_t0_ = now_s();
      status_.have = false;
      status_.next_poll_s = 0.0;
      set_hold(false);
      return true;
    } catch (const LinkError& e) {
      last_error = e.what();
    }
    if (hold_now_s() - window_start > s_.reconnect_max_s) break;
    std::this_thread::sleep_for(std::chrono::duration<double>(backoff));
    backoff = std::min(2.0, backoff * 2.0);
  }
  if (stop.load(std::memory_order_relaxed)) {
    report_.stopped = true;
    return false;
  }
  std::error_code ec;
  const bool gone = !std::filesystem::exists(s_.line.device, ec);
  const std::string reason = gone ? s_.line.device + " does not exist (no such file)" : last_error;
  if (opened_once_) {
    interrupt("the port went away and did not come back within " + fixed(s_.reconnect_max_s, 0) +
              " s: " + reason);
  } else {
    report_.failure = "cannot open the link: " + reason;
  }
  return false;
}

void Session::progress() {
  const double now = now_s();
  if (now < next_progress_s_) return;
  next_progress_s_ = now + s_.progress_period_s;
  emit(SenderEvent::Kind::Progress, report_.blocks,
       std::to_string(report_.blocks) + " blocks taken, " + std::to_string(report_.bytes_written) +
           " bytes written, " +
           fixed(100.0 * static_cast<double>(report_.bytes_written - bytes_in_flight()) /
                     (now * cps_),
                 0) +
           " % of the line" + (xon_ ? "" : ", held by XOFF") +
           (ack_ && phase_ == Phase::Startup ? ", waiting for the controller to speak" : ""));
}

// drip, every block delivered and nothing heard yet: a DC1 may be in flight; wait for a byte
// (or CTS asserted) up to silence_grace_s.
void Session::wait_for_a_word() {
  const double until = now_s() + s_.silence_grace_s;
  try {
    while (!heard_ && link_ && now_s() < until && !over()) {
      link_->wait(20, false);
      read_input();
      if (s_.line.flow == Flow::RtsCts) {
        const auto cts = link_->cts();
        if (cts && *cts) heard_ = true;
      }
    }
  } catch (const LinkError&) {  // the port went away after the last block: still nothing heard
  }
}

// Written and not known to have left on the line (SenderReport::bytes_in_flight).
std::int64_t Session::bytes_in_flight() const {
  if (ack_) {
    std::int64_t unwritten = 0;  // of a line begun: counted in unacked_bytes_, not written
    if (cur_off_ > 0 && sent_items_ < items_.size()) {
      unwritten = static_cast<std::int64_t>(items_[sent_items_].bytes.size() - cur_off_);
    }
    return std::max<std::int64_t>(0, unacked_bytes_ - unwritten);
  }
  const double ahead = static_cast<double>(conn_written_) - delivered();
  return std::max<std::int64_t>(0, static_cast<std::int64_t>(std::ceil(ahead)));
}

void Session::finish() {
  if (!xon_) end_xoff();
  report_.duration_s = now_s();
  report_.bytes_in_flight = report_.completed ? 0 : bytes_in_flight();
  report_.link_use = report_.duration_s > 0.0
                         ? static_cast<double>(report_.bytes_written - report_.bytes_in_flight) /
                               (report_.duration_s * cps_)
                         : 0.0;
  if (report_.link_use > 1.0) {
    report_.notes.push_back("the link carried more than its nominal " + fixed(cps_, 0) +
                            " characters/s: the port ignores the baud rate (USB or virtual)");
  }
  if (report_.completed && ack_ && status_known()) pop_done(queued_moves());
  report_.blocks_confirmed = report_.completed ? report_.blocks : first_unexecuted();
  if (end_.step == Ending::Sending || end_.step == Ending::NotNeeded) {
    report_.blocks_confirmed =
        end_.first_unexecuted >= 0 ? end_.first_unexecuted : report_.blocks_confirmed;
  }
  if (report_.ending.requested && !report_.ending.sent && !report_.ending.not_needed &&
      report_.ending.failure.empty()) {
    report_.ending.failure =
        report_.failure.empty() ? "the transfer was stopped first" : report_.failure;
  }
  if (ack_ && status_known()) report_.blocks_executed = executed_count_;
  if (ack_ && report_.controller_state.empty() && status_.last) {
    report_.controller_state = status_.last->state;
  }
  if (ack_ && !status_known() && report_.execution_basis.empty()) {
    report_.execution_basis = "not known";
  }
  report_.program_sha256 = sha_.hex();
  if (journal_ != nullptr) {
    if (report_.completed) {
      journal_->complete();
    } else {
      journal_->confirm(first_unexecuted());
    }
  }
  link_.reset();
}

}  // namespace ncd::comms::dnc_detail

namespace ncd::comms {

using dnc_detail::Session;

DncSender::DncSender(const SenderSettings& settings, BlockSource& source, EventFn on_event)
    : settings_(settings), source_(source), on_event_(std::move(on_event)) {
  // Before the run: nothing done yet, the buffer's limit and the protocol's unknowns already.
  SenderCounts c;
  const bool ack = settings.line.protocol == Protocol::Ack;
  c.blocks_acked = ack ? 0 : -1;
  c.buffer_limit_bytes = ack ? settings.rx_buffer_bytes : settings.max_queued_chars;
  counters_.store(c);
}

void DncSender::resume_from(std::int64_t first_block) {
  first_block_ = first_block;
}

void ControllerReportBox::publish(const ControllerReport& r) {
  std::lock_guard lock(mutex_);
  last_ = r;
}

std::optional<ControllerReport> ControllerReportBox::last() const {
  std::lock_guard lock(mutex_);
  return last_;
}

SenderCounts SenderCounters::load() const {
  constexpr auto r = std::memory_order_relaxed;
  SenderCounts c;
  c.bytes_written = bytes_written_.load(r);
  c.blocks_taken = blocks_taken_.load(r);
  c.blocks_written = blocks_written_.load(r);
  c.blocks_acked = blocks_acked_.load(r);
  c.blocks_executed = blocks_executed_.load(r);
  c.xoff_count = xoff_count_.load(r);
  c.xoff_held = xoff_held_.load(r);
  c.buffer_bytes = buffer_bytes_.load(r);
  c.buffer_limit_bytes = buffer_limit_bytes_.load(r);
  c.underruns = underruns_.load(r);
  c.reconnects = reconnects_.load(r);
  c.link_losses = link_losses_.load(r);
  return c;
}

void SenderCounters::store(const SenderCounts& c) {
  constexpr auto r = std::memory_order_relaxed;
  bytes_written_.store(c.bytes_written, r);
  blocks_taken_.store(c.blocks_taken, r);
  blocks_written_.store(c.blocks_written, r);
  blocks_acked_.store(c.blocks_acked, r);
  blocks_executed_.store(c.blocks_executed, r);
  xoff_count_.store(c.xoff_count, r);
  xoff_held_.store(c.xoff_held, r);
  buffer_bytes_.store(c.buffer_bytes, r);
  buffer_limit_bytes_.store(c.buffer_limit_bytes, r);
  underruns_.store(c.underruns, r);
  reconnects_.store(c.reconnects, r);
  link_losses_.store(c.link_losses, r);
}

void DncSender::end_with(EndingFn ending) {
  if (ending_claimed_.exchange(true)) return;
  ending_ = std::move(ending);
  end_requested_.store(true, std::memory_order_release);
}

SenderReport DncSender::run(const std::atomic<bool>& stop) {
  // Real-time scheduling only where the line's time is the wall clock's: on a simulated clock
  // nothing is late, and a thread that polls for a clock another thread moves must not take the
  // CPU from it.
  const bool wall = !settings_.hold_clock && !settings_.wire_clock;
  const FifoPriority priority(wall ? settings_.fifo_priority : 0);
  Session session(settings_, source_, on_event_, on_hold_, journal_, first_block_, counters_,
                  reports_, halt_request_, end_requested_, ending_, source_held_);
  session.on_executed(on_executed_);
  SenderReport report = session.run(stop);
  report.scheduling = priority.description();
  return report;
}

std::optional<Violation> check_program_file(const std::string& path, Dialect dialect) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError("cannot read the program " + path + ": give a readable NC file");
  if (dialect == Dialect::linuxcnc) {
    std::ostringstream text;
    text << in.rdbuf();
    return check_program(dialect, text.str());
  }
  DialectState state;
  std::string raw;
  long number = 0;
  while (std::getline(in, raw)) {
    ++number;
    const std::string block = block_of_line(line_text(raw));
    if (block.empty()) continue;  // framing: not sent as a block
    if (auto v = check_line(dialect, block, state)) {
      // The column in the raw line: the block is the line trimmed at its start.
      const auto lead = raw.find_first_not_of(std::string(" \t\0", 3));
      v->column += static_cast<int>(lead == std::string::npos ? 0 : lead);
      v->line = number;
      return v;
    }
  }
  return std::nullopt;
}

}  // namespace ncd::comms
