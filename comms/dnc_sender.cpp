// DNC sender (spec/dnc.md). Blocks go out as a byte stream; what matters is how far ahead of
// the controller the sender may be and how it knows what the controller has.
//
//   source ──► [ window: resend window | written, unconfirmed | not yet written ] ──► link
//                ▲ first block to resend (journal)
//
// Drip feed. The controller paces with DC1/DC3 (or CTS). The sender keeps at most
// max_queued_chars ahead of the wire, so that after a DC3 it stops within that many
// characters. "Ahead of the wire" is the larger of the kernel's output queue (TIOCOUTQ, true on
// a UART) and a wire model: bytes written minus the bytes the line can have carried since,
// at pacing_fraction of its capacity (a pseudo-terminal has no output queue to ask). A block is
// delivered when the model and the kernel both say its last byte has left. Drip feed has no
// confirmation, so after a lost link the sender goes back a resend window of characters before
// the first block it cannot vouch for; blocks carry N numbers and the controller discards an N
// it already has (a Fanuc-style sequence-number restart). Without N numbers the report says a
// resume may repeat blocks.
//
// Acknowledged streaming (grbl). Each line is answered `ok` or `error:N`; character counting
// keeps the sum of unanswered lines within the controller's receive buffer. A block is
// confirmed by its `ok`; after a lost link every unanswered block is sent again.
//
// Faults. A hang-up or I/O error closes the port; it is reopened with back-off (0.1 s doubling
// to 2 s) for up to reconnect_max_s, then the transfer resumes as above. A hold (XOFF or CTS)
// longer than xoff_timeout_s is reported and raises the hold callback, which a live job uses to
// bring the motion to a planned stop. NAK or SYN (drip), `error:N` or `ALARM` (ack) stop the
// transfer with the block named. Other bytes are noise: counted, logged, ignored. The journal
// records the first block to resend, so a restarted ncd resumes there.
#include "comms/dnc_sender.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <memory>
#include <optional>
#include <thread>

#include "comms/serial_link.hpp"
#include "comms/sha256.hpp"
#include "comms/transfer_journal.hpp"

namespace ncd::comms {
namespace {

using Clock = std::chrono::steady_clock;

struct Item {
  std::int64_t index = -1;  // program block, or -1 for framing
  bool closing = false;     // the closing `%`
  std::string bytes;        // with end of block
  double end_mark = -1.0;   // bytes written on this connection when its last byte went out
};

bool starts_with_n_word(const std::string& text) {
  const auto p = text.find_first_not_of(" \t");
  return p != std::string::npos && (text[p] == 'N' || text[p] == 'n') && p + 1 < text.size() &&
         std::isdigit(static_cast<unsigned char>(text[p + 1])) != 0;
}

class Session {
 public:
  Session(const SenderSettings& s, BlockSource& source, const DncSender::EventFn& on_event,
          const DncSender::HoldFn& on_hold, TransferJournal* journal, std::int64_t first_block)
      : s_(s),
        source_(source),
        on_event_(on_event),
        on_hold_(on_hold),
        journal_(journal),
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
  }

  SenderReport run(const std::atomic<bool>& stop) {
    t0_ = Clock::now();
    last_tick_ = t0_;
    next_progress_s_ = s_.progress_period_s;
    while (true) {
      if (stop.load(std::memory_order_relaxed)) {
        report_.stopped = true;
        break;
      }
      if (!link_ && !reopen(stop)) break;
      try {
        if (!step()) break;
      } catch (const LinkError& e) {
        lost_link(e.what());
      }
    }
    finish();
    return report_;
  }

 private:
  double now_s() const { return std::chrono::duration<double>(Clock::now() - t0_).count(); }

  void emit(SenderEvent::Kind kind, std::int64_t block, std::string text) {
    if (on_event_) on_event_(SenderEvent{kind, now_s(), block, std::move(text)});
  }

  void set_hold(bool hold) {
    if (hold == holding_) return;
    holding_ = hold;
    if (on_hold_) on_hold_(hold);
  }

  // One pass: read, account, write, confirm. False when the transfer is over.
  bool step() {
    read_input();
    if (!report_.failure.empty()) return false;
    advance_model();
    watch_hold();
    if (ack_) {
      write_ack();
    } else {
      write_drip();
      confirm_drip();
    }
    if (!report_.failure.empty()) return false;
    progress();
    if (done()) {
      report_.completed = true;
      return false;
    }
    link_->wait(wait_ms(), false);
    return true;
  }

  int wait_ms() const { return source_waiting_ ? 5 : 1; }

  bool done() const {
    if (!source_done_) return false;
    if (ack_) return items_.empty();
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
    while (true) {
      const std::size_t n = link_->read_some(buf, sizeof buf);
      if (n == 0) return;
      for (std::size_t i = 0; i < n; ++i) ack_ ? ack_byte(buf[i]) : drip_byte(buf[i]);
    }
  }

  void drip_byte(char c) {
    if (c == kXoff) {
      if (xon_) {
        xon_ = false;
        xoff_since_s_ = now_s();
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
    const double held = now_s() - xoff_since_s_;
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
    if (line.empty()) return;
    if (line == "ok") {
      acknowledge();
    } else if (line.rfind("error:", 0) == 0) {
      const std::int64_t block = items_.empty() ? next_index_ : items_.front().index;
      alarm("the controller rejected block " + std::to_string(block + 1) + " with " + line +
            (items_.empty() ? "" : " ('" + trim_eob(items_.front().bytes) + "')"));
    } else if (line.rfind("ALARM", 0) == 0) {
      alarm("the controller raised " + line);
    } else {
      noise(line.size() + 1, '\0');
    }
  }

  static std::string trim_eob(std::string s) {
    while (!s.empty() && (s.back() == '\n' || s.back() == '\r')) s.pop_back();
    return s;
  }

  void acknowledge() {
    if (sent_items_ == 0) {
      noise(3, '\0');  // an `ok` for nothing we sent
      return;
    }
    unacked_bytes_ -= static_cast<int>(items_.front().bytes.size());
    items_.pop_front();
    --sent_items_;
    confirm_journal();
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
    report_.failure = text;
    emit(SenderEvent::Kind::Alarm, resume_point(), text);
  }

  void watch_hold() {
    const double now = now_s();
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
      sha_.update(text);
      sha_.update("\n");
      const std::int64_t index = next_index_++;
      ++report_.blocks;
      report_.program_bytes += static_cast<std::int64_t>(text.size() + 1);
      if (!starts_with_n_word(text)) numbered_ = false;
      if (index < skip_until_) continue;
      Item it;
      it.index = index;
      it.bytes = text + eob_text(s_.line.eob);
      items_.push_back(std::move(it));
      return true;
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
        ++sent_items_;
        cur_off_ = 0;
      }
    }
  }

  void write_ack() {
    if (s_.line.flow == Flow::XonXoff && !xon_) return;
    while (true) {
      if (sent_items_ == items_.size() && !pull()) return;
      Item& it = items_[sent_items_];
      const int size = static_cast<int>(it.bytes.size());
      if (size > s_.rx_buffer_bytes) {
        alarm("block " + std::to_string(it.index + 1) + " has " + std::to_string(size) +
              " characters, more than the controller's " + std::to_string(s_.rx_buffer_bytes) +
              "-byte receive buffer: raise --rx-buffer to the controller's size or shorten the "
              "block");
        return;
      }
      if (cur_off_ == 0 && unacked_bytes_ + size > s_.rx_buffer_bytes) return;
      if (cur_off_ == 0) unacked_bytes_ += size;
      report_.max_unacked_bytes = std::max(report_.max_unacked_bytes, unacked_bytes_);
      const std::size_t n = link_->write_some(std::string_view(it.bytes).substr(cur_off_));
      conn_written_ += static_cast<std::int64_t>(n);
      report_.bytes_written += static_cast<std::int64_t>(n);
      cur_off_ += n;
      if (cur_off_ < it.bytes.size()) return;
      it.end_mark = static_cast<double>(conn_written_);
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
    while (sent_items_ > 0 && items_.front().end_mark <= have &&
           (items_.front().index < 0 || confirmed_bytes_after_front >= window_)) {
      if (sent_items_ > 1) {
        confirmed_bytes_after_front -= static_cast<std::int64_t>(items_[1].bytes.size());
      }
      items_.pop_front();
      --sent_items_;
    }
    confirm_journal();
  }

  // The first block that would be sent again after a lost link.
  std::int64_t resume_point() const {
    for (const Item& it : items_) {
      if (it.index >= 0) return it.index;
    }
    return std::max(next_index_, skip_until_);
  }

  void confirm_journal() {
    if (journal_ == nullptr) return;
    const double now = now_s();
    const std::int64_t point = resume_point();
    if (point == journaled_ || (now - journal_at_s_ < 0.02 && !source_done_)) return;
    journal_->confirm(point);
    journaled_ = point;
    journal_at_s_ = now;
  }

  void lost_link(const std::string& why) {
    link_.reset();
    ++report_.reconnects;
    set_hold(true);
    if (!ack_ && !numbered_) {
      emit(SenderEvent::Kind::LinkLost, resume_point(),
           "the blocks carry no N numbers, so the controller cannot discard repeats: the resume "
           "may repeat up to " +
               std::to_string(window_) + " characters of blocks");
    }
    // Everything still in the window goes again, except the opening framing.
    std::erase_if(items_, [](const Item& it) { return it.index < 0 && !it.closing; });
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
         why + "; will resume at block " + std::to_string(resume_point() + 1));
  }

  // Opens (or reopens) the port with back-off; false if it could not be opened in time.
  bool reopen(const std::atomic<bool>& stop) {
    const double start = now_s();
    double backoff = 0.1;
    std::string last_error;
    while (!stop.load(std::memory_order_relaxed)) {
      try {
        link_ = std::make_unique<SerialLink>(s_.line);
        last_tick_ = Clock::now();
        if (opened_once_) {
          emit(SenderEvent::Kind::Reopened, resume_point(),
               "reopened " + s_.line.device + " after " + fixed(now_s() - start, 1) +
                   " s; resuming at block " + std::to_string(resume_point() + 1));
        } else {
          emit(SenderEvent::Kind::Opened, resume_point(),
               "opened " + s_.line.device + " at " + describe(s_.line));
        }
        opened_once_ = true;
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
    report_.failure =
        (opened_once_ ? "gave up reopening the link after " : "cannot open the link: ") +
        (opened_once_ ? fixed(s_.reconnect_max_s, 0) + " s: " : std::string()) + last_error;
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
             " % of the line" + (xon_ ? "" : ", held by XOFF"));
  }

  static std::string fixed(double v, int decimals) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
    return buf;
  }

  void finish() {
    if (!xon_) end_xoff();
    report_.duration_s = now_s();
    report_.link_use = report_.duration_s > 0.0 ? static_cast<double>(report_.bytes_written) /
                                                      (report_.duration_s * cps_)
                                                : 0.0;
    report_.blocks_confirmed = report_.completed ? report_.blocks : resume_point();
    report_.program_sha256 = sha_.hex();
    if (journal_ != nullptr) {
      if (report_.completed) {
        journal_->complete();
      } else {
        journal_->confirm(resume_point());
      }
    }
    link_.reset();
  }

  const SenderSettings& s_;
  BlockSource& source_;
  const DncSender::EventFn& on_event_;
  const DncSender::HoldFn& on_hold_;
  TransferJournal* journal_;
  const bool ack_;
  const double cps_;
  const int window_;

  std::unique_ptr<SerialLink> link_;
  std::deque<Item> items_;
  std::size_t sent_items_ = 0;  // items at the front fully written on this connection
  std::size_t cur_off_ = 0;     // bytes of items_[sent_items_] written
  std::int64_t conn_written_ = 0;
  double model_delivered_ = 0.0;
  int outq_ = 0;
  int unacked_bytes_ = 0;
  std::string line_;
  std::int64_t next_index_ = 0;
  std::int64_t skip_until_ = 0;
  bool source_done_ = false;
  bool source_waiting_ = false;
  bool numbered_ = true;
  std::int64_t noise_events_ = 0;
  bool xon_ = true;
  double xoff_since_s_ = 0.0;
  bool xoff_reported_ = false;
  bool cts_low_ = false;
  double cts_low_since_s_ = 0.0;
  bool holding_ = false;
  bool opened_once_ = false;
  std::int64_t journaled_ = -1;
  double journal_at_s_ = -1.0;
  double next_progress_s_ = 1.0;
  Clock::time_point t0_, last_tick_;
  Sha256 sha_;
  SenderReport report_;
};

}  // namespace

DncSender::DncSender(const SenderSettings& settings, BlockSource& source, EventFn on_event)
    : settings_(settings), source_(source), on_event_(std::move(on_event)) {}

void DncSender::resume_from(std::int64_t first_block) {
  first_block_ = first_block;
}

SenderReport DncSender::run(const std::atomic<bool>& stop) {
  Session session(settings_, source_, on_event_, on_hold_, journal_, first_block_);
  return session.run(stop);
}

}  // namespace ncd::comms
