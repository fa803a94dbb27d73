// The block encoder: the interpolator's setpoints in, RS-274 blocks for a DNC link out.
//
// A 4 ms setpoint is too short for a block on an RS-232 line (docs/block-encoder.md, "The bandwidth
// budget"): a block of c characters at b bits each over `baud` takes c·b/baud s on the wire, so
// at feed F it must be at least F·c·b/baud long or the controller starves. The encoder merges
// consecutive setpoints into straight G1 blocks, as long as the written program stays within a
// chord tolerance of the interpolated path, and gives each block the feed that makes the
// controller take the time the interpolator took. Where the tolerance forces blocks shorter
// than the link can carry at that feed, the feed is lowered until it can, and the stats say
// where and why. The algorithm is explained once, at the top of block_encoder.cpp.
//
// Streaming, constant memory: the setpoints of the open block live in a buffer of a fixed
// capacity (max_setpoints_per_block); a block is handed to the sink as soon as it is closed.
// push() does not allocate once the block text has reached its longest (the block is reused),
// except when a lowered range is recorded.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/geometry.hpp"
#include "core/histogram.hpp"
#include "gcode/dialect/dialect.hpp"
#include "link/line_settings.hpp"
#include "motion/job.hpp"

namespace ncd::comms {

struct EncoderSettings {
  // The written program.
  double chord_tolerance_mm = 0.002;  // every setpoint within this of its written block
  double feed_band = 0.05;            // planned feed within ±5 % of the block's mean feed
  int decimals = 3;                   // X Y Z decimals (3: µm); the rounding counts as chord error
  int feed_decimals = 1;              // F decimals
  double time_tolerance_s = 0.004;    // keep the modal F while the time stays this near the plan
  long number_start = 1;              // N of the first block
  long number_step = 1;               // N increment
  std::size_t max_setpoints_per_block = 4096;  // the buffer of the open block (fixed memory)
  // Longest block, s; 0: no limit. A block reaches the sink only once it is closed, so when
  // streaming live the controller may wait up to this long for the next one: keep it below
  // the cycle's lead over the controller.
  double max_block_s = 0.0;
  // The link the program must fit (from the machine file's [link]).
  double link_margin = 0.8;               // use at most this share of the line's capacity
  LineSettings line;                      // baud, frame and end of block set the budget
  int rx_buffer_bytes = 256;              // the controller's receive buffer, for the queue model
  std::size_t max_lowered_ranges = 1000;  // ranges kept in the stats (all are counted)
  // Framing knobs (docs/block-encoder.md, "Whole programs"); a controller dialect maps onto them.
  bool numbers = true;  // N words on the blocks
  // The machine file's [encoder] numbers: wins over the dialect's default in apply_dialect
  // (grbl built with USE_LINE_NUMBERS reports the executing block's N as Ln:).
  std::optional<bool> numbers_wanted;
  bool comments = true;            // comment lines "(...)"; false: comments are left out
  bool percent = false;            // "%" lines open and close the program (begin() and end())
  std::size_t max_line_chars = 0;  // longest line without end of block; 0: no limit
  // Longest comment line; a longer comment is split over several lines. 0: no limit. grbl's
  // character-counting link cannot send a line longer than its receive buffer.
  std::size_t max_comment_chars = 0;
  // The controller takes G64 P: the preamble bounds its blending by chord_tolerance_mm, so that
  // a plain G64 (LinuxCNC: no bound) cannot round the written vertices further.
  bool path_blending = true;
  // The controller takes G43 H n (a tool table): comms::ProgramBlocks writes each tool length
  // offset of the program as G43 H n and the coordinates without the length (the controller
  // adds its own). False (grbl): no G43 H; the coordinates hold the length the program's
  // interpreter applied, and the header says how the tool's length is set.
  bool length_offsets = true;
  // The rotary index axis the setpoints may turn ('a', 'b'; 0: none; the machine file's
  // [axis.a] or [axis.b], docs/planner.md §3g) and whether the controller takes its word: the
  // dialect's (iso, linuxcnc: yes; grbl: no).
  char rotary_axis = 0;
  bool rotary_words = true;
};

// The controller dialect's rules (gcode/dialect/dialect.hpp, the one place for them) as the
// encoder's framing knobs: N numbers and comments as the dialect takes them. `%` framing stays with
// the streamer, and line lengths are checked on the written lines by check_line (grbl counts the
// characters it keeps, without spaces and comments, which a raw length cannot).
void apply_dialect(EncoderSettings& settings, Dialect dialect);

// Largest distance between a point and its rounding to `decimals`: √3/2 · 10^-decimals mm.
double rounding_error_mm(int decimals);

// Throws InputError naming the value, the limit and a way out: a tolerance below the rounding
// error, a band outside (0, 1), a margin outside (0, 1], decimals outside 0–6 (feed 0–3), a
// negative start number, a step below 1, a negative time tolerance, fewer than 2 setpoints per
// block, a bad baud.
void validate(const EncoderSettings& settings);

// Why a block ended where it did.
enum class BlockClose : std::uint8_t {
  Start,     // the positioning block at the start of the path (G0, no motion of its own)
  Chord,     // the next setpoint would take the path out of the chord tolerance
  FeedBand,  // the planned feed would leave the band around the block's mean
  Turn,      // the path turns by more than 90° (a cusp or a reversal)
  Cap,       // the buffer of the open block is full
  Duration,  // the block would last longer than max_block_s
  End,       // finish(): the end of the path
  Rapid,     // rapid(): a G0 move at the machine's rapid rate, never merged with feed blocks
  Words,     // words(): a block of its own (M3 S…, G4 P…, M5, M2), the tool at rest
  Comment,   // comment() and the % lines: no motion, no N
};
inline constexpr int kBlockCloseCount = 10;
const char* to_string(BlockClose reason);

struct EncodedBlock {
  std::string text;  // without end of block, e.g. "N12X10.366Y0.002F207.8"
  long number = 0;   // the N word
  BlockClose closed_by = BlockClose::End;
  double start_t_s = 0.0, end_t_s = 0.0;    // planned times of the setpoints it joins
  double start_s_mm = 0.0, end_s_mm = 0.0;  // planned arc length at its ends
  double length_mm = 0.0;                   // between the written end points (the move made)
  double feed_mm_per_min = 0.0;             // as written (0 for the positioning block)
  double planned_feed_mm_per_min = 0.0;     // length / planned duration · 60
  double duration_s = 0.0;                  // length / written feed (what the controller takes)
  double planned_duration_s = 0.0;          // end_t_s − start_t_s
  double chord_error_mm = 0.0;  // largest distance of its setpoints from the written segment
  int chars = 0;                // text plus end of block: what it costs on the wire
  std::size_t setpoints = 0;    // setpoints it joins
  Vec3 end = Vec3::Zero();      // written end point, mm
  double end_v_mm_per_s = 0.0;  // planned feed at its end (0: the tool stops there)
  bool positioning = false;     // the G0 at the start
  bool feed_lowered = false;    // the link could not carry it at the planned feed
};

// Consecutive lowered blocks, collapsed.
struct LoweredRange {
  long first_block = 0, last_block = 0;  // N words
  double s_from_mm = 0.0, s_to_mm = 0.0;
  double planned_feed_mm_per_min = 0.0;  // the highest planned over the range
  double lowered_feed_min_mm_per_min = 0.0;
  double length_min_mm = 0.0, length_max_mm = 0.0;
  double needed_length_mm = 0.0;  // the longest block the link needed at the planned feeds
  std::int64_t blocks = 0;
  std::string reason;
};

// A model of the controller's receive buffer, fed block by block: the sender writes at line
// speed while the buffer has room (flow control stops it otherwise); the controller takes a
// block out of the buffer when it starts to execute it, as soon as it is whole and the block
// before is done, and executes it at its written feed. An underrun is a wait for the next block
// while the tool is moving (the block before did not end at rest): the tool would dwell.
struct QueueModelStats {
  std::int64_t underruns = 0;
  double underrun_time_s = 0.0;  // summed waits while moving
  long first_underrun_block = 0;
  std::int64_t waits_at_rest = 0;  // waits where the tool stands anyway (after the G0, a stop)
  int max_buffer_fill_bytes = 0;
  double stream_end_s = 0.0;  // the last block done, from the first character sent
};

struct EncoderStats {
  std::int64_t blocks = 0;  // including the positioning block
  std::int64_t motion_blocks = 0;
  std::int64_t chars = 0;  // with end of block
  std::int64_t setpoints = 0;
  long first_number = 0, last_number = 0;
  double length_min_mm = 0.0, length_max_mm = 0.0;  // motion blocks
  LogHistogram length_nm;                           // for the median
  double length_median_mm() const { return length_nm.quantile(0.5) * 1e-6; }
  double chord_error_max_mm = 0.0;  // every setpoint against its written block, ends rounded
  long chord_error_max_block = 0;
  double chord_tolerance_mm = 0.0;
  double rounding_error_mm = 0.0;
  double wire_s = 0.0;              // Σ c·b/baud
  double duration_s = 0.0;          // Σ execution time at the written feeds
  double planned_duration_s = 0.0;  // Σ planned
  double time_drift_max_s = 0.0;    // largest |Σ written − planned duration|, unlowered blocks
  double unwritten_tail_s = 0.0;    // the end of the path within the rounding of the last block
  double link_use_overall() const { return duration_s > 0.0 ? wire_s / duration_s : 0.0; }
  double link_use_sum = 0.0;  // Σ per-block wire / execution time, motion blocks
  double link_use_mean() const {
    return motion_blocks > 0 ? link_use_sum / static_cast<double>(motion_blocks) : 0.0;
  }
  double link_use_peak = 0.0;
  long link_use_peak_block = 0;
  std::int64_t closed_by[kBlockCloseCount] = {};  // by BlockClose
  std::int64_t band_waived = 0;         // setpoints joined outside the band: block too short
  std::int64_t feed_clamped = 0;        // feeds that rounded to 0, written at one unit
  std::int64_t over_budget_blocks = 0;  // too short for the link even at one unit of feed
  std::int64_t lowered_blocks = 0;
  std::int64_t lowered_ranges = 0;  // all of them; the first max_lowered_ranges are kept
  std::vector<LoweredRange> lowered;
  QueueModelStats queue;
  // The settings the numbers are against.
  double link_margin = 0.0;
  double chars_per_s = 0.0;
  std::string line;  // "19200 7E2 xonxoff drip LF"
  int rx_buffer_bytes = 0;
};

class BlockEncoder {
 public:
  // Throws InputError (validate()). The sink gets every block as soon as it is closed; the
  // reference is valid for the call only.
  BlockEncoder(const EncoderSettings& settings, std::function<void(const EncodedBlock&)> sink);

  // The first setpoint is the start of the path, where the machine stands at rest (push the
  // state at t = 0 before the first period); it becomes the positioning block. Throws
  // InputError on a non-finite position or a time that goes back, std::logic_error after
  // finish().
  void push(const motion::Setpoint& setpoint);
  // Whole programs (docs/whole-program.md). Each closes the open block first (its setpoints end
  // where the tool stands), then writes its own line. Throw InputError on a line longer than
  // max_line_chars or a non-finite position, std::logic_error after finish().
  // A G0 to `end` (mm), reached at t_s / s_mm of the plan; the next push() starts from there.
  // Only the axes of `axes` are written (a rapid from an unknown position names the axes its
  // program gave, no others), each only when the controller does not hold it already; with
  // none to write, no line is written.
  void rapid(const Vec3& end, double t_s, double s_mm,
             const std::array<bool, 3>& axes = {true, true, true});
  // The coordinates written from now on are the planned ones less offset_mm: the tool length
  // the controller adds itself after a G43 H (docs/whole-program.md, "Tool length"). Closes
  // the open block; the next block writes every axis (the controller's program position
  // changed with the offset, not the tool).
  void set_offset(const Vec3& offset_mm);
  const Vec3& offset() const { return offset_; }
  // A rotary index (docs/planner.md §3g): closes the open block, then "G0A90." (or B) as a block
  // of its own, the tool at rest, taking duration_s (its planned time); nothing when the
  // controller holds that angle already. push() writes it itself from the setpoints of an index
  // (motion::kLimitIdIndex): at the period that lands it, with the time the periods took.
  // Throws InputError (rotary_refusal) where the settings have no such axis or the dialect
  // cannot write it.
  void index(char axis, double to_deg, double duration_s = 0.0);
  // A block of words other than motion, e.g. "M3S3000", "G4P1.5", "M5", "M2"; N numbered.
  void words(const std::string& text, double duration_s = 0.0);
  // "(text)" when comments are on; parentheses in text become brackets.
  void comment(const std::string& text);
  // "%" when percent is on: at the start of the program and after its end.
  void percent_line();
  // Closes the open block at its last setpoint without ending the program: the blocks then end
  // where the tool stands (a job ending early writes its own ending after them). No-op after
  // finish().
  void close_block() {
    if (!finished_) close_open();
  }
  // Closes the open block. Idempotent.
  void finish();
  bool finished() const { return finished_; }

  const EncoderStats& stats() const { return stats_; }
  const EncoderSettings& settings() const { return settings_; }

 private:
  struct Anchor {                   // where the open block starts
    Vec3 exact = Vec3::Zero();      // the setpoint the block before ended at
    Vec3 written = Vec3::Zero();    // its rounding, as written: where the controller stands
    std::int64_t q[3] = {0, 0, 0};  // the same in units of 10^-decimals mm
    double rounding_mm = 0.0;       // |written − exact|
    double t_s = 0.0, s_mm = 0.0;
  };
  struct End {  // the last setpoint of the open block
    Vec3 p = Vec3::Zero();
    double t_s = 0.0, s_mm = 0.0, v_mm_per_s = 0.0;
  };
  struct Feed {  // the feed of a block to write, after the budget
    double planned_mm_per_min = 0.0;
    double max_mm_per_min = 0.0;    // what the link carries for this block
    double needed_length_mm = 0.0;  // the length the link needs at the planned feed
    std::int64_t units = 0;         // as written, in 10^-feed_decimals mm/min
    int chars = 0;                  // of the text with this feed, end of block included
    bool lowered = false, clamped = false;
    bool over_budget = false;  // not carried even at the lowest feed written
  };
  void quantize(const Vec3& p, std::int64_t q[3]) const;
  Vec3 written(const std::int64_t q[3]) const;
  bool accept_chord(const Vec3& q, double& bound_out);
  double exact_bound(const Vec3& q) const;
  bool in_band(double v_mm_per_s, double t_s, double s_mm) const;
  bool long_enough_for_link();
  // The feed of the open block ending at q; lower = false only says whether it must be.
  Feed feed_for(const std::int64_t q[3], double length_mm, double planned_s, bool lower = true);
  // Writes the open block up to its last setpoint; false (nothing done) when it would have no
  // written length and may go on.
  bool close(BlockClose reason);
  void emit_positioning(const motion::Setpoint& sp);
  // Closes the open block at its last setpoint (or drops a tail within the rounding).
  void close_open();
  // The open block's text cleared to its N word (where numbered) and G0.
  std::string& begin_rapid_block();
  // Hands a non-feed line in block_.text to the sink with its stats.
  void deliver_line(BlockClose kind, double duration_s, bool numbered);
  void check_line_length(const std::string& text) const;
  void emit(BlockClose reason, const std::int64_t q[3]);
  // The text of a motion block to q at feed units into block_.text; its length with end of
  // block.
  int format_motion(const std::int64_t q[3], std::int64_t feed_units);
  void record_lowered(const EncodedBlock& b, double needed_length_mm);
  void flush_lowered_range();
  void queue_model(const EncodedBlock& b);

  EncoderSettings settings_;
  std::function<void(const EncodedBlock&)> sink_;
  EncoderStats stats_;
  double scale_ = 1000.0;     // 10^decimals
  double feed_scale_ = 10.0;  // 10^feed_decimals
  double rounding_mm_ = 0.0;  // rounding_error_mm(decimals)
  int bits_ = 11;
  int eob_chars_ = 1;
  bool started_ = false, finished_ = false;
  bool numbered_ = false;  // a block with an N word was written
  long next_number_ = 1;
  // What the controller holds modally after the blocks written so far.
  std::int64_t written_q_[3] = {0, 0, 0};
  bool axis_written_[3] = {false, false, false};  // written_q_[a] is what the controller holds
  Vec3 offset_ = Vec3::Zero();                    // set_offset()
  std::int64_t written_feed_ = -1;                // feed units; −1: none yet
  bool g1_written_ = false;
  double time_drift_s_ = 0.0;  // Σ (written − planned duration) of the unlowered blocks
  // The open block.
  Anchor anchor_;
  std::vector<Vec3> pending_;  // its setpoints, the last one is its end (capacity fixed)
  End end_;
  double bound_mm_ = 0.0;          // upper bound of the setpoints' distance to [anchor, end], exact
  double carried_error_mm_ = 0.0;  // of setpoints dropped at the cap, for the next block
  double v_min_ = 0.0, v_max_ = 0.0;  // planned feed over the block, anchor included
  Vec3 last_step_ = Vec3::Zero();     // the last setpoint-to-setpoint move longer than 0
  Vec3 last_p_ = Vec3::Zero();
  // The block handed to the sink, reused.
  EncodedBlock block_;
  // The lowered range being collected.
  bool in_range_ = false;
  LoweredRange range_;
  std::int64_t range_reasons_[kBlockCloseCount] = {};
  // The queue model's state: blocks in the controller's buffer (start time, chars).
  struct Queued {
    double start_s;
    int chars;
  };
  std::vector<Queued> queue_;  // a ring, at most rx_buffer_bytes entries
  std::size_t queue_head_ = 0, queue_size_ = 0;
  int queue_fill_ = 0;
  double tx_free_s_ = 0.0, exec_done_s_ = 0.0;
  bool prev_moving_ = false;
  // Rotary indexes: the angle the controller holds (NaN: none written), and the index under way
  // in push() (its periods are not written; the block comes at the landing).
  double rotary_written_deg_ = std::numeric_limits<double>::quiet_NaN();
  bool index_open_ = false;
  double index_from_t_s_ = 0.0;
};

// Why the encoder cannot write an index of `axis` under these settings (empty: it can): no
// rotary axis in the machine file, another one, or a dialect without it (grbl), each with the
// way out.
std::string rotary_refusal(const EncoderSettings& settings, char axis);

// The stats as the reports print them (units in the names).
nlohmann::ordered_json to_json(const EncoderStats& stats);

}  // namespace ncd::comms
