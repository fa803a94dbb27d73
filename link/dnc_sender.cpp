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
#include "link/dnc_sender.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cmath>
#include <deque>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>
#include <thread>

#include "core/error.hpp"
#include "core/number_text.hpp"
#include "gcode/dialect/program_modal.hpp"
#include "link/program_file.hpp"
#include "link/serial_link.hpp"
#include "link/sha256.hpp"
#include "link/transfer_journal.hpp"

namespace ncd::comms {
namespace {

using Clock = std::chrono::steady_clock;
using text::fixed;
using Vec3 = std::array<double, 3>;

constexpr std::int64_t kFraming = -1;        // % and NUL leader
constexpr std::int64_t kPreamble = -2;       // restart lines
constexpr std::int64_t kFlush = -3;          // ack: the line grbl must refuse (error:11)
constexpr std::int64_t kEnding = -4;         // ack: a line of the ending after a reset
constexpr double kEndingHoldTimeoutS = 5.0;  // `!` to Hold:0 at most
constexpr double kPositionTolMm = 0.002;     // grbl reports 3 decimals
// grbl 1.1's step segment buffer holds 5 segments (stepper.c, SEGMENT_BUFFER_SIZE − 1), each of
// one block: up to 5 moves that left the planner (Bf:, Ln:) may still be running.
constexpr std::size_t kGrblSegments = 5;
// The line that ends a half line an earlier connection may have left in grbl's line buffer
// without letting it run: grbl stores `)` as a character (after closing an open `(` comment),
// and a block holding `)` is refused whole (error:1, or error:2 after a letter, error:11 at the
// limit), so nothing of the half line runs. Only a half line inside a `;` comment, whose code
// arrived whole, swallows it and is queued (ok). docs/dnc-link.md, "A half line".
constexpr const char* kFlushText = "))";
constexpr char kResetByte = 0x18;  // grbl's soft reset (real-time)

// The program's spindle turns after a block: M3 or M4 with a speed above 0.
bool spins(const ModalState& m) {
  return m.spindle != 5 && m.speed_rpm.value_or(0.0) > 0.0;
}

struct Item {
  std::int64_t index = kFraming;  // program block, or one of the negative kinds
  bool closing = false;           // the closing `%`
  std::string bytes;              // with end of block
  double end_mark = -1.0;         // bytes written on this connection when its last byte went out
  BlockMotion geo;                // what the block does
  std::optional<long> n;          // its N
  bool spindle_on = false;        // the program's spindle turns (M3/M4 at S > 0) after it
};

bool starts_with_n_word(const std::string& text) {
  const auto p = text.find_first_not_of(" \t");
  return p != std::string::npos && (text[p] == 'N' || text[p] == 'n') && p + 1 < text.size() &&
         std::isdigit(static_cast<unsigned char>(text[p + 1])) != 0;
}

std::optional<long> n_word(const std::string& text) {
  if (!starts_with_n_word(text)) return std::nullopt;
  const auto p = text.find_first_not_of(" \t") + 1;
  long v = 0;
  const auto r = std::from_chars(text.data() + p, text.data() + text.size(), v);
  if (r.ec != std::errc()) return std::nullopt;
  return v;
}

// A `;` that grbl reads as a comment to the end of the line (not inside `( )`).
bool has_semicolon_comment(std::string_view text) {
  bool paren = false;
  for (const char c : text) {
    if (paren) {
      paren = c != ')';
    } else if (c == '(') {
      paren = true;
    } else if (c == ';') {
      return true;
    }
  }
  return false;
}

double dist(const Vec3& a, const Vec3& b) {
  return std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
}

// Distance from p to the segment a–b, and where along it (0 at a, 1 at b).
double to_segment(const Vec3& p, const Vec3& a, const Vec3& b, double& u) {
  Vec3 d{b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double len2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  u = len2 > 0.0 ? ((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1] + (p[2] - a[2]) * d[2]) / len2
                 : 0.0;
  u = std::clamp(u, 0.0, 1.0);
  const Vec3 q{a[0] + u * d[0], a[1] + u * d[1], a[2] + u * d[2]};
  return dist(p, q);
}

std::optional<Vec3> axes(std::string_view v) {
  Vec3 out{};
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
      return k == 2 || k == 1 ? std::optional<Vec3>(out) : std::nullopt;
    v.remove_prefix(comma + 1);
  }
  return out;
}

class Session {
 public:
  Session(const SenderSettings& s, BlockSource& source, const DncSender::EventFn& on_event,
          const DncSender::HoldFn& on_hold, TransferJournal* journal, std::int64_t first_block,
          SenderCounters& counters, const std::atomic<bool>& halt_request,
          const std::atomic<bool>& end_requested, const DncSender::EndingFn& ending,
          const std::atomic<bool>& source_held)
      : s_(s),
        source_(source),
        on_event_(on_event),
        on_hold_(on_hold),
        journal_(journal),
        counters_(counters),
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
      open.bytes = std::string(static_cast<std::size_t>(s.line.nul_leader), '\0') + "%" +
                   eob_text(s.line.eob);
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

  void on_executed(DncSender::ExecutedFn fn) { on_executed_ = std::move(fn); }

  SenderReport run(const std::atomic<bool>& stop) {
    t0_ = Clock::now();
    last_tick_ = t0_;
    next_progress_s_ = s_.progress_period_s;
    while (true) {
      const bool halt = halt_request_.load() || (s_.halt_on_stop && stop.load());
      if (halt || stop.load(std::memory_order_relaxed)) {
        report_.stopped = true;
        if (halt && ack_) halt_on_request();
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

 private:
  enum class Phase { Startup, Ready, Recovering };

  double now_s() const { return std::chrono::duration<double>(Clock::now() - t0_).count(); }
  double hold_now_s() const { return s_.hold_clock ? s_.hold_clock->now_s() : now_s(); }

  // The live counters (SenderCounts), stored once per pass: plain reads of the session's own
  // state and relaxed atomic stores.
  void publish() {
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
  void watch_underrun() {
    // While the motion feeding the source is held (the operator's hold), or in the dry spell
    // that goes on after it until the next block, nothing starves: the tool is at rest.
    if (source_held_.load(std::memory_order_relaxed)) {
      dry_ = true;
      return;
    }
    const bool nothing = source_waiting_ && !source_done_ && sent_items_ == items_.size();
    const bool held = !xon_ || cts_low_;
    const bool dry =
        nothing && !held && report_.blocks_sent > 0 && (!ack_ || phase_ == Phase::Ready);
    if (dry && !dry_) ++underruns_;
    dry_ = dry;
  }

  void emit(SenderEvent::Kind kind, std::int64_t block, std::string text) {
    if (on_event_) on_event_(SenderEvent{kind, now_s(), block, std::move(text)});
  }

  void set_hold(bool hold) {
    if (hold == holding_) return;
    holding_ = hold;
    if (on_hold_) on_hold_(hold);
  }

  bool over() const { return !report_.failure.empty(); }

  // One pass: read, account, write, confirm. False when the transfer is over.
  bool step() {
    read_input();
    if (over()) return false;
    advance_model();
    watch_hold();
    if (ack_) {
      if (phase_ == Phase::Startup) startup();
      if (phase_ == Phase::Recovering) recovering();
      if (phase_ == Phase::Ready && ending_ == Ending::None &&
          end_requested_.load(std::memory_order_acquire)) {
        begin_ending();
      }
      if (ending_ == Ending::Holding || ending_ == Ending::Resetting) {
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
      if (ending_ == Ending::Sending) {  // the ending, not the program, went to its end
        report_.ending.sent = true;
        report_.ending.executed = status_known();
        emit(SenderEvent::Kind::Ending, report_.blocks,
             std::string("the ending was ") +
                 (status_known() ? "executed (the controller is idle)" : "queued"));
      } else if (ending_ == Ending::None) {
        report_.completed = true;
      }
      return false;
    }
    link_->wait(wait_ms(), false);
    return true;
  }

  int wait_ms() const { return source_waiting_ ? 5 : 1; }

  bool status_known() const { return s_.status_hz > 0.0 && status_supported_; }

  bool done() const {
    if (ending_ == Ending::NotNeeded) return true;
    if (ending_ == Ending::Holding || ending_ == Ending::Resetting) return false;
    if (!source_done_) return false;
    if (ack_)
      return phase_ == Phase::Ready && items_.empty() && (queued_.empty() || !status_known());
    return std::all_of(items_.begin(), items_.end(), [&](const Item& it) {
      return it.end_mark >= 0.0 && it.end_mark <= delivered();
    });
  }

  // Bytes of this connection the controller has, by the wire model and the kernel's queue.
  double delivered() const {
    return std::min(model_delivered_, static_cast<double>(conn_written_ - outq_));
  }

  void advance_model() {
    const auto now = Clock::now();
    const double dt = std::chrono::duration<double>(now - last_tick_).count();
    last_tick_ = now;
    model_delivered_ = std::min(static_cast<double>(conn_written_),
                                model_delivered_ + dt * cps_ * s_.pacing_fraction);
    outq_ = link_->output_queue();
    report_.max_output_queue = std::max(report_.max_output_queue, outq_);
  }

  void read_input() {
    char buf[256];
    while (link_) {
      const std::size_t n = link_->read_some(buf, sizeof buf);
      if (n == 0) return;
      for (std::size_t i = 0; i < n; ++i) ack_ ? ack_byte(buf[i]) : drip_byte(buf[i]);
    }
  }

  void drip_byte(char c) {
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

  void end_xoff() {
    const double held = hold_now_s() - xoff_since_s_;
    xon_ = true;
    report_.xoff_total_s += held;
    report_.xoff_longest_s = std::max(report_.xoff_longest_s, held);
    if (xoff_reported_) {
      emit(SenderEvent::Kind::XoffEnd, resume_point(),
           "the controller released the hold (DC1) after " + fixed(held, 1) + " s");
      xoff_reported_ = false;
    }
  }

  void ack_byte(char c) {
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

  static bool is_banner(const std::string& line) { return line.rfind("Grbl ", 0) == 0; }

  void ack_line(const std::string& line) {
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
    if (ending_ == Ending::Holding || ending_ == Ending::Resetting) {
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

  // A line from the controller before the job has started.
  void startup_line(const std::string& line) {
    if (is_banner(line)) {
      if (opened_once_before_) {
        controller_reset("the controller reset while the link was down (its banner '" + line +
                         "' came on the new connection)");
        return;
      }
      report_.startup = "banner";
      track_ok_ = true;  // the banner that opens the job, not a reset in it
      spoke_ = true;
      woke_ = wake_pending_ = false;  // a reset cleared its buffers (and any wake-up line)
      have_status_ = false;           // its state now: ask again
      next_poll_s_ = now_s();
      emit(SenderEvent::Kind::Opened, resume_point(), "the controller said '" + line + "'");
      return;
    }
    const bool answer = line == "ok" || line.rfind("error:", 0) == 0;
    if (answer && wake_pending_) {
      // The wake-up line is the half-line flush: refused (error:N) as it should be, or `ok`
      // when it completed a half line ending in a `;` comment an earlier connection left.
      wake_pending_ = false;
      spoke_ = true;
      if (report_.startup != "banner") report_.startup = "woken";
      if (line == "ok") {
        report_.notes.push_back(
            "the wake-up line completed a half line ending in a ';' comment that an earlier "
            "connection had left in the controller's line buffer; the controller queued it");
      }
      emit(SenderEvent::Kind::Opened, resume_point(), "the controller answered the wake-up line");
    } else if (answer && unlock_pending_) {
      unlock_pending_ = false;
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

  // The flush after a lost link was answered ok: it completed a half line that was inside a `;`
  // comment, so the code of that line had all arrived and is now queued. That line can only be
  // the first one the controller did not receive whole, which heads the lines to send again.
  void half_line_queued() {
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

  static std::string trim_eob(std::string s) {
    while (!s.empty() && (s.back() == '\n' || s.back() == '\r')) s.pop_back();
    return s;
  }

  // The front unanswered line was answered ok: the controller queued it.
  void take_ok() {
    Item it = std::move(items_.front());
    items_.pop_front();
    --sent_items_;
    unacked_bytes_ -= static_cast<int>(it.bytes.size());
    queue_item(std::move(it));
  }

  void queue_item(Item it) {
    if (it.index >= 0) ++report_.blocks_queued;
    if (!it.geo.motion && queued_.empty()) {
      executed(it);
    } else {
      queued_.push_back(std::move(it));
    }
    confirm_journal();
  }

  void executed(const Item& it) {
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
  void pop_done(std::size_t moves) {
    while (!queued_.empty()) {
      if (queued_.front().geo.motion) {
        if (moves == 0) break;
        --moves;
      }
      executed(queued_.front());
      queued_.pop_front();
    }
  }

  std::size_t queued_moves() const {
    return static_cast<std::size_t>(std::count_if(queued_.begin(), queued_.end(),
                                                  [](const Item& it) { return it.geo.motion; }));
  }

  Vec3 work_position(const GrblStatus& st) {
    if (st.wco) wco_ = *st.wco;
    if (st.wpos) return *st.wpos;
    const Vec3 m = st.mpos.value_or(Vec3{});
    return {m[0] - wco_[0], m[1] - wco_[1], m[2] - wco_[2]};
  }

  void on_status(const GrblStatus& st) {
    ++report_.status_reports;
    status_supported_ = true;
    last_status_ = st;
    last_position_ = work_position(st);
    have_status_ = true;
    if (phase_ == Phase::Startup) spoke_ = true;
    if (phase_ != Phase::Ready && !stopping_) return;  // startup and recovery read it themselves
    if (!track_ok_ || st.state == "Alarm") return;
    track(st, last_position_);
  }

  void track(const GrblStatus& st, const Vec3& pos) {
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

  void basis(const char* how) {
    if (report_.execution_basis.empty()) report_.execution_basis = how;
  }

  void poll_status() {
    if (s_.status_hz <= 0.0) return;
    const double now = now_s();
    if (now < next_poll_s_) return;
    next_poll_s_ = now + 1.0 / s_.status_hz;
    write_raw("?");
    if (++polls_ >= 20 && !have_status_ && status_supported_) {
      status_supported_ = false;
      report_.execution_basis = "not known: the controller does not answer '?'";
      report_.notes.push_back(
          "the controller answered no status report: executed blocks are not known; "
          "'completed' means every block was queued (answered ok)");
    }
  }

  void write_raw(std::string_view bytes) {
    std::size_t off = 0;
    const double until = now_s() + 1.0;
    while (off < bytes.size() && now_s() < until) {
      const std::size_t n = link_->write_some(bytes.substr(off));
      off += n;
      report_.bytes_written += static_cast<std::int64_t>(n);
      if (off < bytes.size()) link_->wait(1, true);
    }
  }

  // Start-up: never send before the controller has spoken, and never a block before its state
  // is known to take one (docs/dnc-link.md, "Start-up"). Without a banner within banner_wait_s,
  // ask `?` (a real-time byte, no line); without a status either, wake it with the half-line
  // flush and wait for its answer. Then, with status polling, read its state: Idle goes on;
  // Alarm ends the job before any block (or, with `unlock`, sends `$X`); a hold (held at rest, its
  // protocol loop reads no line) is brought to a safe halt; Run and the rest end the job.
  void startup() {
    if (opened_once_before_) {
      // After a lost link: a banner means a reset (handled in ack_line). Without one, hold and
      // ask where the controller is.
      if (now_s() - phase_t0_ >= std::min(s_.banner_wait_s, 1.0)) {
        phase_ = Phase::Recovering;
        phase_t0_ = now_s();
        have_status_ = false;
        write_raw("!?");
        next_poll_s_ = now_s() + 0.2;
      }
      return;
    }
    const double since = now_s() - phase_t0_;
    const bool ask = s_.status_hz > 0.0;
    if (!spoke_) {
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
      if (ask && !asked_) {
        asked_ = true;
        emit(SenderEvent::Kind::Opened, resume_point(),
             "no banner within " + fixed(s_.banner_wait_s, 1) + " s: asking its status ('?')");
        write_raw("?");
      } else if (!woke_ && (!ask || since >= s_.banner_wait_s + 0.5)) {
        emit(SenderEvent::Kind::Opened, resume_point(),
             "no banner and no status: waking the controller with a line it must refuse");
        wake();
      }
      return;
    }
    if (wake_pending_ || unlock_pending_) return;  // their answers come first
    if (!ask) {
      if (!woke_ && report_.startup != "banner") return wake();
      phase_ = Phase::Ready;
      return;
    }
    if (!have_status_) {
      if (now_s() >= next_poll_s_) {
        if (++start_polls_ > 8) {  // 2 s without a status: a controller without `?`
          report_.notes.push_back(
              "the controller answered no status report at start-up: its state (alarm, hold) "
              "was not checked");
          if (!woke_ && report_.startup != "banner") return wake();
          phase_ = Phase::Ready;
          return;
        }
        write_raw("?");
        next_poll_s_ = now_s() + 0.25;
      }
      return;
    }
    start_state(last_status_->state);
  }

  // The first line after opening: the half-line flush, which grbl must refuse (or which ends a
  // half line inside a `;` comment an earlier connection left: then that block is queued).
  void wake() {
    woke_ = wake_pending_ = true;
    wrote_line_ = true;
    write_raw(std::string(kFlushText) + "\n");
  }

  // What the controller's state at start-up allows.
  void start_state(std::string state) {  // a copy: the halt below reads new statuses
    report_.controller_state = state;
    if (state == "Idle") {
      // A half line an earlier connection left is flushed before the first block; a banner
      // (a reset) has cleared it.
      if (!woke_ && report_.startup != "banner") return wake();
      phase_ = Phase::Ready;
      return;
    }
    if (state == "Alarm") {
      report_.position_may_be_lost = true;
      if (!s_.unlock || unlock_tried_) {
        report_.failure = unlock_tried_ ? std::string(
                                              "the controller stays in alarm after $X (grbl keeps "
                                              "a hard-limit or door alarm until "
                                              "the cause is cleared); nothing was sent")
                                        : "the controller is in alarm (locked: grbl refuses every "
                                          "line with error:9 until $X); "
                                          "nothing was sent";
        return;
      }
      if (!woke_ && report_.startup != "banner") return wake();
      unlock_pending_ = unlock_tried_ = true;
      wrote_line_ = true;
      emit(SenderEvent::Kind::Opened, resume_point(),
           "the controller is in alarm: unlocking it with $X (--unlock)");
      write_raw("$X\n");
      have_status_ = false;
      next_poll_s_ = now_s() + 0.25;
      return;
    }
    if (state.rfind("Hold", 0) == 0 && !start_halted_) {
      // Held: grbl reads no line until `~` or a reset, and `~` would run what it still holds.
      start_halted_ = true;
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
      woke_ = wake_pending_ = false;  // the reset cleared its buffers: no half line is left
      report_.startup = "banner";
      have_status_ = false;
      next_poll_s_ = now_s();
      return;
    }
    report_.failure =
        "the controller is not ready for a program: its state is " + state +
        (state == "Run" || state == "Jog" || state == "Home"
             ? " (it is moving: it still runs blocks it was sent before; wait until it is Idle)"
             : "") +
        "; nothing was sent";
  }

  void recovering() {
    const double now = now_s();
    if (now - phase_t0_ > 5.0) {
      give_up("the controller gave no status within 5 s after the link came back");
      return;
    }
    if (have_status_ && last_status_ &&
        (last_status_->state == "Idle" || last_status_->state == "Hold:0")) {
      decide_resume(*last_status_, last_position_);
      return;
    }
    if (now >= next_poll_s_) {
      next_poll_s_ = now + 0.2;
      write_raw("?");
    }
  }

  // The controller is held or idle after a lost link: resume only if the position proves
  // which blocks it holds (see the top of this file).
  void decide_resume(const GrblStatus& st, const Vec3& pos) {
    const std::string where = " (position " + fixed(pos[0], 3) + ", " + fixed(pos[1], 3) + ", " +
                              fixed(pos[2], 3) + ", " + st.state + ")";
    if (!st.free_blocks) {
      give_up(
          "after the lost link the status has no Bf: field, so the blocks the controller "
          "holds cannot be counted (grbl: $10=2 or 3)" +
          where);
      return;
    }
    if (st.free_bytes && *st.free_bytes < s_.rx_buffer_bytes) {
      give_up("after the lost link the controller's receive buffer still holds " +
              std::to_string(s_.rx_buffer_bytes - *st.free_bytes) +
              " bytes, lines not yet read: which blocks they are cannot be told" + where);
      return;
    }
    // Candidates: queued (ok'd) blocks, then the lines written on the lost connection.
    std::vector<const Item*> cands;
    for (const Item& it : queued_) cands.push_back(&it);
    const std::size_t n_queued = cands.size();
    const std::size_t written = sent_items_ + (cur_off_ > 0 ? 1 : 0);
    for (std::size_t i = 0; i < written && i < items_.size(); ++i) cands.push_back(&items_[i]);
    // A restart (a power-up) stops the spindle; its banner is lost while the port is closed.
    // If the program has the spindle turning before and through every block the controller may
    // hold, a stopped spindle (FS:…,0) tells that the controller reset and lost its queue.
    const bool spindle_steady = std::all_of(cands.begin(), cands.end(), [&](const Item* it) {
      return it->spindle_on == last_spindle_on_;
    });
    if (spindle_steady && last_spindle_on_ && st.spindle_rpm && *st.spindle_rpm <= 0.0) {
      report_.position_may_be_lost = true;
      give_up(
          "after the lost link the controller's spindle is stopped (FS:…,0) while the program "
          "has it turning: the controller has reset (a restart whose banner was sent while the "
          "port was closed), so its queue and its modes are gone" +
          where);
      return;
    }
    cands.resize(n_queued);
    if (*st.free_blocks == 0 && written > 0) {
      // grbl's protocol loop takes a whole line out of the receive ring and then waits for a
      // free planner block: such a line is in neither count of Bf:, and runs when room frees.
      give_up(
          "after the lost link the controller's planner is full, so a line it received may "
          "be waiting for room, counted nowhere: which blocks it holds cannot be told" +
          where);
      return;
    }
    for (std::size_t i = 0; i < written && i < items_.size(); ++i) cands.push_back(&items_[i]);
    const auto held = static_cast<std::size_t>(std::max(0, s_.planner_blocks - *st.free_blocks));
    // The last candidate the controller received: index into cands, or -1 for "none".
    long last = -1;
    if (cands.empty()) {
      if (last_end_ && dist(*last_end_, pos) > kPositionTolMm) {
        give_up(
            "after the lost link the controller is not where the last move known executed "
            "ended, and it holds nothing ncd sent: it has moved or reset meanwhile" +
            where);
        return;
      }
      last = -1;
    } else if (held == 0) {
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
        if (hits == 0 && n_queued == cands.size() && !moves && last_end_ &&
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
          return;
        } else {
          give_up("after the lost link the position matches " + std::to_string(hits) +
                  " end points of the blocks the controller may have" + where);
          return;
        }
      }
    } else {
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
        return;
      }
      // The planner holds `held` moves starting with e (or with the move after e, at its end).
      std::size_t need = at_end ? held : held - 1;
      last = e;
      for (std::size_t i = static_cast<std::size_t>(e) + 1; i < cands.size() && need > 0; ++i) {
        if (cands[i]->geo.motion) {
          --need;
          last = static_cast<long>(i);
        }
      }
      if (need > 0) {
        give_up("after the lost link the controller holds " + std::to_string(held) +
                " moves, more than ncd sent" + where);
        return;
      }
    }
    if (last + 1 < static_cast<long>(n_queued)) {
      give_up(
          "after the lost link the position says the controller lacks blocks it had "
          "queued" +
          where);
      return;
    }
    const std::size_t next = static_cast<std::size_t>(last + 1);
    if (next < cands.size() && !cands[next]->geo.motion) {
      give_up("after the lost link it cannot be told whether block '" +
              trim_eob(cands[next]->bytes) + "' (no motion) reached the controller" + where);
      return;
    }
    // The controller has cands[0 .. last]: queue the written ones it received, resend the rest.
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

  // ---- Ending early (see the top of this file) ----

  void begin_ending() {
    EndingReport& e = report_.ending;
    e.requested = true;
    e.request_t_s = now_s();
    source_done_ = true;  // no more program blocks
    // The lines not yet written (a half-written one too: the reset clears grbl's line buffer).
    const std::size_t keep = sent_items_;
    while (items_.size() > keep) items_.pop_back();
    cur_off_ = 0;
    if (!motion_written_) {
      ending_ = Ending::NotNeeded;
      e.not_needed = true;
      emit(SenderEvent::Kind::Ending, report_.blocks,
           "ending the job: no move had been sent, the controller never moved");
      return;
    }
    ending_ = Ending::Holding;
    ending_t0_ = now_s();
    have_status_ = false;
    write_raw("!?");
    next_poll_s_ = now_s() + 0.1;
    emit(SenderEvent::Kind::Ending, report_.blocks,
         "ending the job: feed hold (!), waiting for Hold:0 before the reset");
  }

  void ending_step() {
    const double now = now_s();
    if (ending_ == Ending::Holding) {
      if (have_status_ && last_status_) {
        const std::string& state = last_status_->state;
        if (state == "Hold:0") {
          report_.ending.held = true;
          report_.ending.held_t_s = now;
          report_.ending.held_at_mm = last_position_;
          reset_for_ending();
          return;
        }
        if (state.rfind("Alarm", 0) == 0) {
          fail_ending("the controller is in alarm (its status says " + state +
                      "): it takes no line until it is unlocked");
          return;
        }
      }
      if (now - ending_t0_ > kEndingHoldTimeoutS) {
        fail_ending("after the feed hold (!) the controller did not report Hold:0 within " +
                    fixed(kEndingHoldTimeoutS, 0) + " s" +
                    (last_status_ ? " (last status " + last_status_->state + ")" : ""));
        return;
      }
      if (now >= next_poll_s_) {
        next_poll_s_ = now + 0.1;
        write_raw("?");
      }
      return;
    }
    if (now - ending_t0_ > s_.startup_timeout_s) {  // Resetting
      fail_ending("no banner within " + fixed(s_.startup_timeout_s, 1) +
                  " s after the soft reset (0x18)");
    }
  }

  // Hold:0: what grbl queued is not known executed; the reset drops it.
  void reset_for_ending() {
    dropped_note(first_unexecuted());
    ending_first_unexecuted_ = first_unexecuted();
    write_raw(std::string(1, '\x18'));
    ending_ = Ending::Resetting;
    ending_t0_ = now_s();
    items_.clear();
    queued_.clear();
    sent_items_ = 0;
    cur_off_ = 0;
    unacked_bytes_ = 0;
    line_.clear();
  }

  // A line while holding or resetting for the ending.
  void ending_line(const std::string& line) {
    if (line.rfind("ALARM", 0) == 0) {
      fail_ending("the controller raised " + line +
                  (ending_ == Ending::Resetting ? " on the reset: it is locked until $X" : ""));
    } else if (is_banner(line)) {
      if (ending_ == Ending::Holding) {
        fail_ending("the controller reset by itself before its hold was complete ('" + line + "')");
        return;
      }
      report_.ending.reset = true;
      send_ending();
    } else if (line == "ok" && ending_ == Ending::Holding && sent_items_ > 0) {
      take_ok();  // a line written before the hold, queued: the reset drops it
    }
  }

  void send_ending() {
    const std::vector<std::string> lines =
        ending_fn_ ? ending_fn_(report_.ending.held_at_mm) : std::vector<std::string>{};
    report_.ending.lines = lines;
    ProgramModal modal;
    for (const std::string& l : lines) {
      Item it;
      it.index = kEnding;
      it.bytes = l + eob_text(s_.line.eob);
      it.geo = modal.apply(l);
      items_.push_back(std::move(it));
    }
    ending_ = Ending::Sending;
    track_ok_ = true;
    have_status_ = false;
    next_poll_s_ = 0.0;
    emit(SenderEvent::Kind::Ending, report_.blocks,
         "the controller was held and reset; sending the ending (" + std::to_string(lines.size()) +
             " lines)");
  }

  void fail_ending(const std::string& why) {
    report_.ending.failure = why;
    report_.alarms.push_back(why);
    emit(SenderEvent::Kind::Alarm, resume_point(), "the ending could not be sent: " + why);
    interrupt("the ending could not be sent: " + why);
  }

  // A reset, seen: nothing to stop, the queue is gone. Never resume past it. Its state (an
  // alarm lock after a reset in motion) is read for the advice.
  void controller_reset(const std::string& why) {
    const std::int64_t first = first_unexecuted();
    dropped_note(first);
    read_state();
    interrupt(why);
  }

  // An error reply or an alarm: bring grbl to a safe halt so that nothing queued after it runs.
  void stop_controller(const std::string& why) {
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
  void give_up(const std::string& why) {
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
  void halt_on_request() {
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

  static bool at_rest(const std::string& state) {
    return state == "Idle" || state == "Hold:0" || state == "Alarm" || state == "Sleep" ||
           state == "Check" || state == "Door:0" || state == "Door:1";
  }

  // What the halt did, for notes and messages.
  static std::string halt_text(const HaltReport& h) {
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
  HaltReport safe_halt() {
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
          have_status_ = false;
          write_raw("?");
          next_ask = now_s() + 0.05;
        }
        read_input();
        if (have_status_ && last_status_ && at_rest(last_status_->state)) {
          rest = last_status_;
          break;
        }
        if (report_.status_reports == reports0 && now_s() - t0 > 2.0) break;
        link_->wait(5, false);
      }
      h.rest_s = now_s() - t0;
      if (!rest) {
        h.state = last_status_ && report_.status_reports > reports0 ? last_status_->state : "";
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
  void read_state() {
    if (!link_) return;
    try {
      have_status_ = false;
      const double t0 = now_s();
      double next_ask = t0;
      while (!have_status_ && now_s() - t0 < 1.0) {
        if (now_s() >= next_ask) {
          write_raw("?");
          next_ask = now_s() + 0.25;
        }
        read_input();
        if (!have_status_) link_->wait(5, false);
      }
      if (have_status_ && last_status_) report_.controller_state = last_status_->state;
      if (report_.controller_state == "Alarm") report_.position_may_be_lost = true;
    } catch (const LinkError&) {
    }
  }

  void dropped_note(std::int64_t first) {
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

  // Ends the job as interrupted. The report names the last block known executed and the first
  // not known executed; what to do next is the caller's (ncd stream prints it).
  void interrupt(const std::string& why) {
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

  void noise(std::size_t bytes, char c) {
    report_.noise_bytes += static_cast<std::int64_t>(bytes);
    if (++noise_events_ <= 10 || noise_events_ % 100 == 0) {
      emit(SenderEvent::Kind::Noise, resume_point(),
           ack_ ? "ignored an unexpected line from the controller"
                : "ignored an unexpected byte 0x" + hex_byte(c) + " from the controller");
    }
  }

  static std::string hex_byte(char c) {
    static constexpr char kHex[] = "0123456789abcdef";
    const auto u = static_cast<unsigned char>(c);
    return std::string{kHex[u >> 4], kHex[u & 0xF]};
  }

  void alarm(const std::string& text) {
    report_.alarms.push_back(text);
    emit(SenderEvent::Kind::Alarm, resume_point(), text);
    interrupt(text);
  }

  void watch_hold() {
    const double now = hold_now_s();
    bool held = !xon_;
    double since = xoff_since_s_;
    if (s_.line.flow == Flow::RtsCts) {
      const auto cts = link_->cts();
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
      xoff_reported_ = true;
      ++report_.xoff_timeouts;
      emit(SenderEvent::Kind::XoffLong, resume_point(),
           "the controller has held the link for more than " + fixed(s_.xoff_timeout_s, 1) +
               " s at block " + std::to_string(resume_point() + 1) + "; waiting");
    }
    set_hold(xoff_reported_ && held);
  }

  // Pulls the next block from the source into the window; false if none is ready.
  bool pull() {
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
      items_.push_back(std::move(it));
      return true;
    }
  }

  void written(const Item& it) {
    motion_written_ = motion_written_ || it.geo.motion;
    if (it.index >= 0 && it.index >= sent_high_) {
      sent_high_ = it.index + 1;
      ++report_.blocks_sent;
    }
  }

  void write_drip() {
    const bool cts_ok = !(s_.line.flow == Flow::RtsCts && cts_low_);
    const bool may_send = cts_ok && (s_.line.flow != Flow::XonXoff || xon_);
    if (!may_send) return;
    const double ahead =
        std::max(static_cast<double>(outq_), static_cast<double>(conn_written_) - delivered());
    report_.max_queued_estimate =
        std::max(report_.max_queued_estimate, static_cast<int>(std::ceil(ahead)));
    auto room = static_cast<std::int64_t>(std::floor(s_.max_queued_chars - ahead));
    while (room > 0) {
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

  void write_ack() {
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

  // Drops delivered items that have left the resend window; updates the journal.
  void confirm_drip() {
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

  // The first block not delivered (drip) or not known queued (ack), for progress lines.
  std::int64_t resume_point() const {
    for (const Item& it : items_) {
      if (it.index >= 0) return it.index;
    }
    return std::max(next_index_, skip_until_);
  }

  // The first block not known executed (ack) or sent (drip).
  std::int64_t first_unexecuted() const {
    if (ack_ && status_known()) {
      for (const Item& it : queued_) {
        if (it.index >= 0) return it.index;
      }
    }
    return resume_point();
  }

  void confirm_journal() {
    if (journal_ == nullptr) return;
    const double now = now_s();
    const std::int64_t point = first_unexecuted();
    if (point == journaled_ || (now - journal_at_s_ < 0.02 && !source_done_)) return;
    journal_->confirm(point);
    journaled_ = point;
    journal_at_s_ = now;
  }

  void lost_link(const std::string& why) {
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
           why + "; the first block not known executed is " +
               std::to_string(first_unexecuted() + 1) +
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

  // Opens (or reopens) the port with back-off; false if it could not be opened in time.
  bool reopen(const std::atomic<bool>& stop) {
    if (over()) return false;
    const double start = now_s();
    double backoff = 0.1;
    std::string last_error;
    while (!stop.load(std::memory_order_relaxed)) {
      try {
        link_ = std::make_unique<SerialLink>(s_.line);
        last_tick_ = Clock::now();
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
        have_status_ = false;
        next_poll_s_ = 0.0;
        set_hold(false);
        return true;
      } catch (const LinkError& e) {
        last_error = e.what();
      }
      if (now_s() - start > s_.reconnect_max_s) break;
      std::this_thread::sleep_for(std::chrono::duration<double>(backoff));
      backoff = std::min(2.0, backoff * 2.0);
    }
    if (stop.load(std::memory_order_relaxed)) {
      report_.stopped = true;
      return false;
    }
    std::error_code ec;
    const bool gone = !std::filesystem::exists(s_.line.device, ec);
    const std::string reason =
        gone ? s_.line.device + " does not exist (no such file)" : last_error;
    if (opened_once_) {
      interrupt("the port went away and did not come back within " + fixed(s_.reconnect_max_s, 0) +
                " s: " + reason);
    } else {
      report_.failure = "cannot open the link: " + reason;
    }
    return false;
  }

  void progress() {
    const double now = now_s();
    if (now < next_progress_s_) return;
    next_progress_s_ = now + s_.progress_period_s;
    emit(SenderEvent::Kind::Progress, report_.blocks,
         std::to_string(report_.blocks) + " blocks taken, " +
             std::to_string(report_.bytes_written) + " bytes written, " +
             fixed(100.0 * static_cast<double>(report_.bytes_written) / (now * cps_), 0) +
             " % of the line" + (xon_ ? "" : ", held by XOFF") +
             (ack_ && phase_ == Phase::Startup ? ", waiting for the controller to speak" : ""));
  }

  void finish() {
    if (!xon_) end_xoff();
    report_.duration_s = now_s();
    report_.link_use = report_.duration_s > 0.0 ? static_cast<double>(report_.bytes_written) /
                                                      (report_.duration_s * cps_)
                                                : 0.0;
    if (report_.completed && ack_ && status_known()) pop_done(queued_moves());
    report_.blocks_confirmed = report_.completed ? report_.blocks : first_unexecuted();
    if (ending_ == Ending::Sending || ending_ == Ending::NotNeeded) {
      report_.blocks_confirmed =
          ending_first_unexecuted_ >= 0 ? ending_first_unexecuted_ : report_.blocks_confirmed;
    }
    if (report_.ending.requested && !report_.ending.sent && !report_.ending.not_needed &&
        report_.ending.failure.empty()) {
      report_.ending.failure =
          report_.failure.empty() ? "the transfer was stopped first" : report_.failure;
    }
    if (ack_ && status_known()) report_.blocks_executed = executed_count_;
    if (ack_ && report_.controller_state.empty() && last_status_) {
      report_.controller_state = last_status_->state;
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

  enum class Ending { None, NotNeeded, Holding, Resetting, Sending };

  const SenderSettings& s_;
  BlockSource& source_;
  const DncSender::EventFn& on_event_;
  const DncSender::HoldFn& on_hold_;
  DncSender::ExecutedFn on_executed_;
  TransferJournal* journal_;
  SenderCounters& counters_;
  const std::atomic<bool>& halt_request_;
  const std::atomic<bool>& end_requested_;
  const DncSender::EndingFn& ending_fn_;
  const std::atomic<bool>& source_held_;
  Ending ending_ = Ending::None;
  double ending_t0_ = 0.0;
  std::int64_t ending_first_unexecuted_ = -1;
  bool motion_written_ = false;  // a line with motion went out
  const bool ack_;
  const double cps_;
  const int window_;

  std::unique_ptr<SerialLink> link_;
  std::deque<Item> items_;      // not yet answered (ack) or delivered (drip), oldest first
  std::deque<Item> queued_;     // ack: answered ok, not known executed
  std::size_t sent_items_ = 0;  // items at the front fully written on this connection
  std::size_t cur_off_ = 0;     // bytes of items_[sent_items_] written
  std::int64_t conn_written_ = 0;
  double model_delivered_ = 0.0;
  int outq_ = 0;
  int unacked_bytes_ = 0;
  std::string line_;
  std::int64_t next_index_ = 0;
  std::int64_t skip_until_ = 0;
  std::int64_t sent_high_ = 0;
  std::int64_t executed_count_ = 0, last_executed_ = -1;
  ProgramModal modal_;
  bool source_done_ = false;
  bool source_waiting_ = false;
  bool dry_ = false;  // in an underrun (watch_underrun)
  std::int64_t underruns_ = 0;
  std::int64_t noise_events_ = 0;
  bool xon_ = true;
  double xoff_since_s_ = 0.0;
  bool xoff_reported_ = false;
  bool cts_low_ = false;
  double cts_low_since_s_ = 0.0;
  bool holding_ = false;
  bool opened_once_ = false;
  bool opened_once_before_ = false;  // ack: a connection carried blocks before this one
  Phase phase_ = Phase::Startup;
  double phase_t0_ = 0.0;
  bool woke_ = false;
  // ack start-up: the controller spoke (banner, status, answer); `?` asked; the wake-up line
  // and `$X` await their answers; status polls; a hold met at start-up was halted; a line
  // (anything but real-time bytes) was written on the first connection.
  bool spoke_ = false, asked_ = false, wake_pending_ = false, unlock_pending_ = false;
  bool unlock_tried_ = false, start_halted_ = false, wrote_line_ = false;
  int start_polls_ = 0;
  std::string rejected_reply_;    // the error:N of the rejected block
  bool last_spindle_on_ = false;  // after the last block known executed
  std::optional<Vec3> last_end_;  // where the last move known executed ended
  bool stopping_ = false, reset_seen_ = false, track_ok_ = true;
  bool status_supported_ = true, have_status_ = false;
  long polls_ = 0;
  double next_poll_s_ = 0.0;
  std::optional<GrblStatus> last_status_;
  Vec3 last_position_{}, wco_{};
  std::int64_t journaled_ = -1;
  double journal_at_s_ = -1.0;
  double next_progress_s_ = 1.0;
  Clock::time_point t0_, last_tick_;
  Sha256 sha_;
  DialectState dialect_state_;
  SenderReport report_;
};

}  // namespace

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
  Session session(settings_, source_, on_event_, on_hold_, journal_, first_block_, counters_,
                  halt_request_, end_requested_, ending_, source_held_);
  session.on_executed(on_executed_);
  return session.run(stop);
}

}  // namespace ncd::comms

namespace ncd::comms {

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

PositionMatch match_position(const std::string& program_path, std::int64_t first, std::int64_t end,
                             const Vec3& position) {
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
  std::optional<Vec3> wco;
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
    p.position = Vec3{(*last->mpos)[0] - (*wco)[0], (*last->mpos)[1] - (*wco)[1],
                      (*last->mpos)[2] - (*wco)[2]};
  }
  return p;
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
