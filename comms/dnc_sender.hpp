// The DNC sender: takes NC blocks from a source (a program file, or the block encoder live from
// the cycle) and sends them over the serial link with one of two protocols, keeping a journal
// so that neither a lost link nor a restarted ncd loses or repeats a block. The algorithm is
// described at the top of dnc_sender.cpp.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "comms/line_settings.hpp"

namespace ncd::comms {

class TransferJournal;

struct SenderSettings {
  LineSettings line;
  int max_queued_chars = 16;      // drip: characters allowed ahead of the wire (stop distance)
  int rx_buffer_bytes = 128;      // ack: controller receive buffer (grbl 128, grblHAL 1024)
  double xoff_timeout_s = 5.0;    // a hold longer than this is reported (and holds the motion)
  double reconnect_max_s = 30.0;  // give up reopening a lost port after this long
  double progress_period_s = 1.0;
  // drip: after a lost link, blocks within this many characters before the first block the
  // wire model cannot vouch for are sent again; the controller discards repeated N numbers.
  // Negative: max_queued_chars + 0.25 s of line.
  int resend_window_chars = -1;
  double pacing_fraction = 0.98;  // drip: pace at this fraction of the line's capacity
};

enum class BlockStatus { Ready, NotYet, End };

// Where blocks come from. next() fills `text` (no end of block) and returns Ready, NotYet when
// a live producer has nothing yet, or End when the program is over.
class BlockSource {
 public:
  virtual ~BlockSource() = default;
  virtual BlockStatus next(std::string& text) = 0;
};

struct SenderEvent {
  enum class Kind { Opened, LinkLost, Reopened, XoffLong, XoffEnd, Noise, Alarm, Progress };
  Kind kind = Kind::Progress;
  double t_s = 0.0;        // since the sender started
  std::int64_t block = 0;  // the block concerned (0-based), or blocks sent for Progress
  std::string text;        // what happened, for the log
};

struct SenderReport {
  bool completed = false;             // the controller has the whole program (confirmed, for ack)
  bool stopped = false;               // stopped on request before the end
  std::string failure;                // alarm or link given up; empty otherwise
  std::int64_t first_block = 0;       // resumed from this block (journal)
  std::int64_t blocks = 0;            // program blocks taken from the source
  std::int64_t blocks_confirmed = 0;  // resume point at the end
  std::int64_t blocks_resent = 0;     // sent again after a lost link
  std::int64_t bytes_written = 0;     // everything written, framing and resends included
  std::int64_t program_bytes = 0;     // the blocks with their end of block, once each
  double duration_s = 0.0;
  double link_use = 0.0;  // bytes_written / (duration · line capacity)
  int xoff_count = 0;
  double xoff_total_s = 0.0;
  double xoff_longest_s = 0.0;
  int xoff_timeouts = 0;
  int reconnects = 0;
  std::int64_t noise_bytes = 0;
  std::vector<std::string> alarms;
  int max_output_queue = 0;     // largest TIOCOUTQ seen
  int max_queued_estimate = 0;  // largest characters ahead of the wire, model or kernel
  int max_unacked_bytes = 0;    // ack: largest sum of unanswered lines
  std::string program_sha256;   // of the blocks, each ended by one LF
};

class DncSender {
 public:
  using EventFn = std::function<void(const SenderEvent&)>;
  using HoldFn = std::function<void(bool hold)>;

  DncSender(const SenderSettings& settings, BlockSource& source, EventFn on_event = {});
  // Resume after a restart: skip (but checksum) the first `first_block` blocks, send no opening
  // framing, and keep `journal` (may be null) up to date.
  void resume_from(std::int64_t first_block);
  void set_journal(TransferJournal* journal) { journal_ = journal; }
  // Called when the link holds the motion (a long XOFF, CTS low, a lost port) and frees it.
  void on_hold(HoldFn fn) { on_hold_ = std::move(fn); }
  // Sends until the program is confirmed, an alarm, the link is given up, or stop is set.
  SenderReport run(const std::atomic<bool>& stop);

 private:
  SenderSettings settings_;
  BlockSource& source_;
  EventFn on_event_;
  HoldFn on_hold_;
  TransferJournal* journal_ = nullptr;
  std::int64_t first_block_ = 0;
};

}  // namespace ncd::comms
