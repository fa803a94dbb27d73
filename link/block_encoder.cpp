// The block encoder (block_encoder.hpp).
//
// The picture: setpoints (·) of one period each, merged into blocks (straight written moves
// between rounded end points, ○) that stay within the chord tolerance ε of every setpoint.
//
//        anchor A (exact) / Aw (written)                              end q / Wq = round(q)
//        ○─────────·──────·───────·───────·───────·───────·──────·──────○
//                     \___ every setpoint within ε of the segment Aw–Wq ___/
//
// One block at a time, setpoint by setpoint. The open block runs from its anchor (the written
// end of the block before: where the controller will stand) to the last setpoint pushed. A new
// setpoint q extends it unless one of these closes it first, in this order:
//   1. Turn: the move into q points back (dot product < 0 with the last move longer than 0):
//      a cusp or a reversal. The block ends at the turning point.
//   2. Cap: the buffer of the open block is full (max_setpoints_per_block), or Duration: the
//      block would last longer than max_block_s (when set: a live stream cannot wait for
//      blocks of any length).
//   3. Chord: some setpoint of the block, or q, would be farther than ε from the segment
//      Aw–round(q). The ends are the ROUNDED ones, as written, so the rounding (at most
//      ρ = √3/2·10^-decimals) is part of the error; ε < ρ is refused by validate().
//   4. Feed band: the planned feed over the block (anchor and every setpoint) would leave
//      ±feed_band of the block's mean feed (planned arc / planned time): a ramp becomes several
//      blocks with their own F. The band gives way to the link: a block is only closed for the
//      band once it is long enough for the link at its own feed (below); until then it goes on
//      (counted as band_waived). So the ramp out of rest is a few blocks the link can carry,
//      not a dozen 4 ms blocks of a micrometre each at crawling feeds.
// A block always takes at least its first setpoint: one setpoint against the segment to its
// own rounding is within ρ ≤ ε, so the encoder always makes progress.
//
// The chord test without rescanning the block for every setpoint. For the exact ends A (the
// setpoint the block starts at) and q, with the block's setpoints p_i:
//   dist(p_i, [Aw, Wq]) ≤ dist(p_i, [A, q]) + max(|Aw − A|, |Wq − q|)
// (every point of the written segment is within that of the point of the exact segment at the
// same fraction). And if e is the block's last setpoint, u and w the unit directions A→e and
// A→q, and |A−q| ≥ |A−e|, the point of [A, e] nearest to p_i at distance r ≤ |A−e| from A has
// a partner on [A, q] at the same distance, within r·|u − w|; so
//   max_i dist(p_i, [A, q]) ≤ B + |A−e|·|u − w|,   B = the same bound for [A, e],
// and the previous end e itself is measured exactly. B is kept as a running bound: on a
// straight line it stays at float noise, so long blocks cost O(1) a setpoint. When the bound
// (plus the rounding slack) passes ε, or q is nearer to A than e, the block is scanned exactly
// against the rounded segment and the bound reset to the exact value. Worst case (a curve
// with a tolerance just above ρ) O(n) a setpoint for a block of n setpoints.
//
// The feed of a block is its written length over the time the interpolator took, ×60 mm/min,
// rounded to feed_decimals: the controller, moving at F, then takes the interpolator's time.
// The rounding of the end points alone moves that by up to 2ρ/L (0.3 % on a 0.6 mm block), and
// an F word costs 6–8 characters, so the modal F is kept while it is within the feed band of
// the block's planned feed and the controller's summed time stays within time_tolerance_s (one
// period) of the plan; otherwise a new F is written.
// The budget (docs/block-encoder.md): a block of c characters (text + end of block) at b bits each
// takes c·b/baud s on the wire; the sender may use link_margin of the line, so the block must
// last at least c·b/(baud·margin) s, i.e.
//   F ≤ F_max = L · baud · margin · 60 / (c · b)   (L mm, F mm/min).
// Above F_max the feed is lowered to F_max rounded down (the F word changes c, so this is
// repeated until it holds) and the block is marked; consecutive lowered blocks are collected
// into ranges with the cause (what made the blocks short) and the numbers.
//
// A block is written compactly: N on every block (a repeated N is how a controller recognises
// a block it already has when the sender resumes after a lost link), G1 and F modal (written
// when they change), an axis only when its written value changes, decimal points always (a
// Fanuc reads "X10" as 10 least increments), trailing zeros dropped: "N12X10.366Y0.002F207.8".
// The first block is "N1G21G90G94G0X…Y…Z…": absolute mm, feed per minute, and the start of
// the path stated as a positioning move (the machine stands there already: the path starts at
// rest at the first setpoint), so the program is self-contained and reads back in our reader,
// which wants X, Y and Z known before the first G1.
//
// A block whose rounded end equals its rounded start cannot be written: the encoder keeps
// extending it, and at the cap (or max_block_s) drops its setpoints (all within ε of the start)
// while keeping its start time, so the next block's feed takes the standstill into account.
#include "link/block_encoder.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "core/error.hpp"
#include "core/number_text.hpp"

namespace ncd::comms {
namespace {

constexpr double kTinyMoveMm = 1e-9;  // moves shorter than this carry no direction
constexpr double kMaxCoordMm = 1e9;   // beyond this a coordinate is not a machine's

double pow10(int n) {
  double s = 1.0;
  for (int i = 0; i < n; ++i) s *= 10.0;
  return s;
}

// Distance from p to the segment [a, b] (to a when the segment is a point).
double dist_to_segment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double l2 = ab.squaredNorm();
  if (l2 == 0.0) return (p - a).norm();
  const double t = std::clamp((p - a).dot(ab) / l2, 0.0, 1.0);
  return (a + t * ab - p).norm();
}

// units · 10^-decimals written with a decimal point, no trailing zeros: 10366 → "10.366",
// 10000 → "10.", −500 → "-0.5", 0 → "0.".
void append_fixed(std::string& out, std::int64_t units, int decimals) {
  if (units < 0) {
    out.push_back('-');
    units = -units;
  }
  std::int64_t scale = 1;
  for (int i = 0; i < decimals; ++i) scale *= 10;
  const std::int64_t ip = units / scale;
  std::int64_t frac = units % scale;
  char digits[24];
  const int n = std::snprintf(digits, sizeof digits, "%lld", static_cast<long long>(ip));
  out.append(digits, static_cast<std::size_t>(n));
  out.push_back('.');
  if (frac == 0) return;
  int width = decimals;
  while (frac % 10 == 0) {
    frac /= 10;
    --width;
  }
  const int m = std::snprintf(digits, sizeof digits, "%0*lld", width, static_cast<long long>(frac));
  out.append(digits, static_cast<std::size_t>(m));
}

void append_number(std::string& out, long n) {
  char digits[24];
  const int k = std::snprintf(digits, sizeof digits, "%ld", n);
  out.append(digits, static_cast<std::size_t>(k));
}

}  // namespace

void apply_dialect(EncoderSettings& settings, Dialect dialect) {
  const DialectRules& r = rules(dialect);
  settings.numbers = r.n_numbers;
  settings.comments = r.paren_comments;
  settings.path_blending = r.path_blending;
  settings.length_offsets = r.length_offsets;
  if (r.max_line_chars > 0) settings.max_comment_chars = static_cast<std::size_t>(r.max_line_chars);
}

double rounding_error_mm(int decimals) {
  return 0.5 * std::sqrt(3.0) / pow10(decimals);
}

const char* to_string(BlockClose reason) {
  switch (reason) {
    case BlockClose::Start:
      return "start";
    case BlockClose::Chord:
      return "chord";
    case BlockClose::FeedBand:
      return "feed_band";
    case BlockClose::Turn:
      return "turn";
    case BlockClose::Cap:
      return "cap";
    case BlockClose::Duration:
      return "duration";
    case BlockClose::End:
      return "end";
    case BlockClose::Rapid:
      return "rapid";
    case BlockClose::Words:
      return "words";
    case BlockClose::Comment:
      return "comment";
  }
  return "?";
}

void validate(const EncoderSettings& s) {
  if (s.decimals < 0 || s.decimals > 6) {
    throw InputError("encoder decimals = " + std::to_string(s.decimals) +
                     " is out of range: write 0 to 6 decimals of mm (3: micrometres)");
  }
  if (s.feed_decimals < 0 || s.feed_decimals > 3) {
    throw InputError("encoder feed_decimals = " + std::to_string(s.feed_decimals) +
                     " is out of range: write 0 to 3 decimals of mm/min");
  }
  require_positive("encoder chord_tolerance_mm", s.chord_tolerance_mm);
  const double rho = rounding_error_mm(s.decimals);
  if (s.chord_tolerance_mm < rho) {
    throw InputError("encoder chord_tolerance_mm = " + text::sig(s.chord_tolerance_mm) +
                     " mm is below the rounding error of " + std::to_string(s.decimals) +
                     " decimals (sqrt(3)/2 * 10^-" + std::to_string(s.decimals) + " = " +
                     text::sig(rho) +
                     " mm): the written end points alone may be that far from the path; raise the "
                     "tolerance to at least " +
                     text::sig(rho) + " mm or write more decimals");
  }
  if (!std::isfinite(s.feed_band) || s.feed_band <= 0.0 || s.feed_band >= 1.0) {
    throw InputError("encoder feed_band = " + text::sig(s.feed_band) +
                     " is out of range: give the relative band around a block's mean feed, "
                     "greater than 0 and below 1 (0.05 for ±5 %)");
  }
  if (!std::isfinite(s.link_margin) || s.link_margin <= 0.0 || s.link_margin > 1.0) {
    throw InputError("encoder link_margin = " + text::sig(s.link_margin) +
                     " is out of range: give the share of the line's capacity the program may "
                     "use, greater than 0 and at most 1 (0.8 for 80 %)");
  }
  if (s.number_start < 0) {
    throw InputError("encoder number_start = " + std::to_string(s.number_start) +
                     " is invalid: block numbers start at 0 or above");
  }
  if (s.number_step < 1) {
    throw InputError("encoder number_step = " + std::to_string(s.number_step) +
                     " is invalid: block numbers must grow, by 1 or more");
  }
  if (!std::isfinite(s.time_tolerance_s) || s.time_tolerance_s < 0.0) {
    throw InputError("encoder time_tolerance_s = " + text::sig(s.time_tolerance_s) +
                     " is invalid: give how far the controller's time may run from the plan "
                     "before F is written again, 0 or more (one period, 0.004 s, by default)");
  }
  if (!std::isfinite(s.max_block_s) || s.max_block_s < 0.0) {
    throw InputError("encoder max_block_s = " + text::sig(s.max_block_s) +
                     " is invalid: give the longest block in seconds, or 0 for no limit");
  }
  if (s.max_setpoints_per_block < 2 || s.max_setpoints_per_block > (1u << 20)) {
    throw InputError(
        "encoder max_setpoints_per_block = " + std::to_string(s.max_setpoints_per_block) +
        " is out of range: give 2 to 1048576 (4096 is 16 s at 4 ms)");
  }
  if (s.rx_buffer_bytes < 1 || s.rx_buffer_bytes > (1 << 20)) {
    throw InputError("link rx_buffer_bytes = " + std::to_string(s.rx_buffer_bytes) +
                     " is out of range: give the controller's receive buffer, 1 to 1048576 "
                     "bytes (256 is common)");
  }
  check_baud(s.line.baud);
}

BlockEncoder::BlockEncoder(const EncoderSettings& settings,
                           std::function<void(const EncodedBlock&)> sink)
    : settings_(settings), sink_(std::move(sink)) {
  validate(settings_);
  scale_ = pow10(settings_.decimals);
  feed_scale_ = pow10(settings_.feed_decimals);
  rounding_mm_ = rounding_error_mm(settings_.decimals);
  bits_ = bits_per_char(settings_.line);
  eob_chars_ = static_cast<int>(std::char_traits<char>::length(eob_text(settings_.line.eob)));
  next_number_ = settings_.number_start;
  pending_.reserve(settings_.max_setpoints_per_block);
  queue_.resize(static_cast<std::size_t>(settings_.rx_buffer_bytes) + 1);
  block_.text.reserve(96);
  stats_.chord_tolerance_mm = settings_.chord_tolerance_mm;
  stats_.rounding_error_mm = rounding_mm_;
  stats_.link_margin = settings_.link_margin;
  stats_.chars_per_s = chars_per_s(settings_.line);
  stats_.rx_buffer_bytes = settings_.rx_buffer_bytes;
  stats_.line = describe(settings_.line);
}

// q: the written coordinates (the planned ones less the offset) in units of 10^-decimals mm.
void BlockEncoder::quantize(const Vec3& p, std::int64_t q[3]) const {
  for (int a = 0; a < 3; ++a) q[a] = std::llround((p[a] - offset_[a]) * scale_);
}

// Where the written q puts the tool, in the planned coordinates.
Vec3 BlockEncoder::written(const std::int64_t q[3]) const {
  return Vec3(static_cast<double>(q[0]) / scale_, static_cast<double>(q[1]) / scale_,
              static_cast<double>(q[2]) / scale_) +
         offset_;
}

void BlockEncoder::set_offset(const Vec3& offset_mm) {
  if (finished_) throw std::logic_error("BlockEncoder::set_offset after finish()");
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(offset_mm[a]) || std::abs(offset_mm[a]) > kMaxCoordMm) {
      throw InputError("tool length offset " + text::sig(offset_mm[a]) +
                       " mm: the block encoder needs a finite offset within 1e9 mm");
    }
  }
  close_open();
  offset_ = offset_mm;
  // The tool stands where it stood; its written coordinates change with the offset.
  quantize(anchor_.written, anchor_.q);
  for (bool& w : axis_written_) w = false;
}

void BlockEncoder::push(const motion::Setpoint& sp) {
  if (finished_) throw std::logic_error("BlockEncoder::push after finish()");
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(sp.p[a]) || std::abs(sp.p[a]) > kMaxCoordMm) {
      throw InputError("setpoint at t = " + text::fixed(sp.t_s, 6) + " s has coordinate " +
                       text::sig(sp.p[a]) +
                       " mm: the block encoder needs finite positions "
                       "within 1e9 mm");
    }
  }
  if (!std::isfinite(sp.t_s) || (started_ && sp.t_s <= end_.t_s)) {
    throw InputError("setpoint time " + text::sig(sp.t_s, 9) + " s does not follow " +
                     text::sig(end_.t_s, 9) +
                     " s: the block encoder needs setpoints in strictly increasing time");
  }
  ++stats_.setpoints;
  if (!started_) {
    started_ = true;
    emit_positioning(sp);
    return;
  }
  const Vec3 step = sp.p - last_p_;
  bool turn = false;
  if (step.norm() > kTinyMoveMm) {
    turn = last_step_.squaredNorm() > 0.0 && step.dot(last_step_) < 0.0;
    last_step_ = step;
  }
  last_p_ = sp.p;
  double bound = 0.0;    // for the block with q appended, when the chord test ran
  bool measure = false;  // a close was refused: measure the bound with q appended
  if (!pending_.empty()) {
    if (turn) {
      measure = !close(BlockClose::Turn);
    } else if (pending_.size() >= settings_.max_setpoints_per_block) {
      measure = !close(BlockClose::Cap);
    } else if (settings_.max_block_s > 0.0 && sp.t_s - anchor_.t_s > settings_.max_block_s) {
      measure = !close(BlockClose::Duration);
    } else if (!accept_chord(sp.p, bound)) {
      measure = !close(BlockClose::Chord);
    } else if (!in_band(sp.v_mm_per_s, sp.t_s, sp.s_mm)) {
      if (long_enough_for_link()) {
        measure = !close(BlockClose::FeedBand);
      } else {
        ++stats_.band_waived;
      }
    }
  }
  if (measure) bound = exact_bound(sp.p);
  if (pending_.empty()) bound = 0.0;  // a block of q alone: q lies on [A, q]
  pending_.push_back(sp.p);
  bound_mm_ = bound;
  end_ = {sp.p, sp.t_s, sp.s_mm, sp.v_mm_per_s};
  v_min_ = std::min(v_min_, sp.v_mm_per_s);
  v_max_ = std::max(v_max_, sp.v_mm_per_s);
}

double BlockEncoder::exact_bound(const Vec3& q) const {
  double b = 0.0;
  for (const Vec3& p : pending_) b = std::max(b, dist_to_segment(p, anchor_.exact, q));
  return b;
}

bool BlockEncoder::accept_chord(const Vec3& q, double& bound_out) {
  const double tol = settings_.chord_tolerance_mm;
  const Vec3& a = anchor_.exact;
  const Vec3& e = end_.p;
  std::int64_t qq[3];
  quantize(q, qq);
  const Vec3 wq = written(qq);
  const double slack = std::max(anchor_.rounding_mm, (wq - q).norm());
  const double r_e = (e - a).norm();
  const double r = (q - a).norm();
  if (r >= r_e && r > 0.0) {
    const double inc = r_e > 0.0 ? r_e * ((e - a) / r_e - (q - a) / r).norm() : 0.0;
    const double b = std::max(bound_mm_ + inc, dist_to_segment(e, a, q));
    if (b + slack <= tol) {
      bound_out = b;
      return true;
    }
  }
  // The exact test against the written segment; the bound reset on the way.
  const Vec3& aw = anchor_.written;
  double b = 0.0;
  for (const Vec3& p : pending_) {
    if (dist_to_segment(p, aw, wq) > tol) return false;
    b = std::max(b, dist_to_segment(p, a, q));
  }
  bound_out = b;
  return true;
}

bool BlockEncoder::in_band(double v, double t_s, double s_mm) const {
  const double mean = (s_mm - anchor_.s_mm) / (t_s - anchor_.t_s);
  const double lo = std::min(v_min_, v), hi = std::max(v_max_, v);
  constexpr double kEps = 1e-9;  // mm/s
  return hi <= (1.0 + settings_.feed_band) * mean + kEps &&
         lo >= (1.0 - settings_.feed_band) * mean - kEps;
}

BlockEncoder::Feed BlockEncoder::feed_for(const std::int64_t q[3], double length_mm,
                                          double planned_s, bool lower) {
  Feed f;
  f.planned_mm_per_min = length_mm / planned_s * 60.0;
  const double capacity = static_cast<double>(settings_.line.baud) * settings_.link_margin;
  const auto carried = [&](std::int64_t units) {  // text with this feed; true if the link can
    f.chars = format_motion(q, units);
    f.max_mm_per_min = length_mm * capacity * 60.0 / (f.chars * bits_);
    return static_cast<double>(units) / feed_scale_ <= f.max_mm_per_min;
  };
  // 1. The modal F, when it is within the feed band of the planned one and the controller's
  // time stays within time_tolerance_s of the plan.
  if (written_feed_ > 0) {
    const double held = static_cast<double>(written_feed_) / feed_scale_;
    const double held_s = length_mm / held * 60.0;
    if (std::abs(held - f.planned_mm_per_min) <= settings_.feed_band * f.planned_mm_per_min &&
        std::abs(time_drift_s_ + held_s - planned_s) <= settings_.time_tolerance_s &&
        carried(written_feed_)) {
      f.units = written_feed_;
      f.needed_length_mm = f.planned_mm_per_min * f.chars * bits_ / (capacity * 60.0);
      return f;
    }
  }
  // 2. The planned feed, rounded up or down, whichever brings the controller's summed time
  // nearer to the plan (so the rounding does not add up block after block).
  const double exact_units = f.planned_mm_per_min * feed_scale_;
  std::int64_t down = static_cast<std::int64_t>(std::floor(exact_units));
  if (down < 1) {
    down = 1;
    f.clamped = exact_units < 0.5;
  }
  const std::int64_t up = std::max(down, static_cast<std::int64_t>(std::ceil(exact_units)));
  const auto drift_after = [&](std::int64_t units) {
    return std::abs(time_drift_s_ + length_mm / static_cast<double>(units) * feed_scale_ * 60.0 -
                    planned_s);
  };
  f.units = drift_after(up) < drift_after(down) ? up : down;
  if (f.units == up && up != down && !carried(up)) f.units = down;
  const std::int64_t planned_units = down;
  // 3. Lowered: the largest feed on the grid that the link carries. The F word's length
  // depends on the feed (its digits, trailing zeros dropped; no word at all for the modal F),
  // so the candidates are, for every length of the word, the largest feed that F_max allows
  // at that length, and the feeds below it that are written shorter (fewer decimals; 9…9 with
  // fewer integer digits); the largest one carried wins.
  if (!carried(f.units)) {
    if (!lower) {
      f.lowered = true;
      return f;
    }
    const int base = format_motion(q, written_feed_);  // the text without an F word
    std::int64_t best = 0;
    const auto consider = [&](std::int64_t u) {
      if (u > best && u < planned_units && carried(u)) best = u;
    };
    if (written_feed_ > 0) consider(written_feed_);
    std::int64_t fs = 1;
    for (int k = 0; k < settings_.feed_decimals; ++k) fs *= 10;
    for (int word = 2; word <= 16; ++word) {
      const double fmax = length_mm * capacity * 60.0 / ((base + word) * bits_);
      const double bound_units = std::floor(fmax * feed_scale_);
      if (bound_units < 1.0) break;
      const auto bound =
          std::min(planned_units - 1, static_cast<std::int64_t>(std::min(bound_units, 9e15)));
      for (std::int64_t step = 1; step <= fs; step *= 10) consider(bound - bound % step);
      for (std::int64_t nines = 10 * fs - 1; nines < bound; nines = 10 * nines + 9) {
        for (std::int64_t step = 1; step <= fs; step *= 10) consider(nines - nines % step);
      }
    }
    f.units = std::max<std::int64_t>(best, 1);
    f.over_budget = !carried(f.units);  // also the text and chars of the feed chosen
  }
  f.lowered = f.units < planned_units;
  f.needed_length_mm = f.planned_mm_per_min * f.chars * bits_ / (capacity * 60.0);
  return f;
}

bool BlockEncoder::long_enough_for_link() {
  std::int64_t q[3];
  quantize(end_.p, q);
  if (q[0] == anchor_.q[0] && q[1] == anchor_.q[1] && q[2] == anchor_.q[2]) return false;
  const double length = (written(q) - anchor_.written).norm();
  return !feed_for(q, length, end_.t_s - anchor_.t_s, false).lowered;
}

bool BlockEncoder::close(BlockClose reason) {
  std::int64_t q[3];
  quantize(end_.p, q);
  if (q[0] == anchor_.q[0] && q[1] == anchor_.q[1] && q[2] == anchor_.q[2]) {
    // Nothing to write yet. Every setpoint of the block is within the tolerance of the anchor
    // (the chord test against a segment of no length is the distance to it), so any block
    // from the anchor keeps them within it: at the cap they may go; otherwise the block goes
    // on.
    if (reason == BlockClose::Cap || reason == BlockClose::Duration) {
      for (const Vec3& p : pending_) {
        carried_error_mm_ = std::max(carried_error_mm_, (p - anchor_.written).norm());
      }
      pending_.clear();
      return true;
    }
    return false;
  }
  emit(reason, q);
  return true;
}

void BlockEncoder::close_open() {
  if (pending_.empty()) return;
  std::int64_t q[3];
  quantize(end_.p, q);
  if (q[0] == anchor_.q[0] && q[1] == anchor_.q[1] && q[2] == anchor_.q[2]) {
    // The stretch ends within the rounding of the last written point.
    stats_.unwritten_tail_s += end_.t_s - anchor_.t_s;
    for (const Vec3& p : pending_) {
      stats_.chord_error_max_mm = std::max(stats_.chord_error_max_mm, (p - anchor_.written).norm());
    }
    pending_.clear();
    anchor_.t_s = end_.t_s;
    anchor_.s_mm = end_.s_mm;
  } else {
    emit(BlockClose::End, q);
  }
}

void BlockEncoder::finish() {
  if (finished_) return;
  finished_ = true;
  close_open();
  flush_lowered_range();
}

void BlockEncoder::check_line_length(const std::string& text) const {
  if (settings_.max_line_chars > 0 && text.size() > settings_.max_line_chars) {
    throw InputError("the line \"" + text + "\" has " + std::to_string(text.size()) +
                     " characters, more than the controller's " +
                     std::to_string(settings_.max_line_chars) +
                     "; use fewer decimals or leave out N numbers and comments");
  }
}

void BlockEncoder::deliver_line(BlockClose kind, double duration_s, bool numbered) {
  check_line_length(block_.text);
  EncodedBlock& b = block_;
  b.number = numbered ? next_number_ : 0;
  b.closed_by = kind;
  b.start_t_s = b.end_t_s = anchor_.t_s;
  b.start_s_mm = b.end_s_mm = anchor_.s_mm;
  b.length_mm = b.feed_mm_per_min = b.planned_feed_mm_per_min = 0.0;
  b.duration_s = b.planned_duration_s = duration_s;
  b.chord_error_mm = 0.0;
  b.chars = static_cast<int>(b.text.size()) + eob_chars_;
  b.setpoints = 0;
  b.end = anchor_.written;
  b.end_v_mm_per_s = 0.0;
  b.positioning = false;
  b.feed_lowered = false;
  if (numbered) {
    if (!numbered_) stats_.first_number = b.number;
    numbered_ = true;
    stats_.last_number = b.number;
    next_number_ += settings_.number_step;
  }
  ++stats_.blocks;
  ++stats_.closed_by[static_cast<int>(kind)];
  stats_.chars += b.chars;
  stats_.wire_s += static_cast<double>(b.chars * bits_) / settings_.line.baud;
  stats_.duration_s += duration_s;
  stats_.planned_duration_s += duration_s;
  flush_lowered_range();
  queue_model(b);
  sink_(b);
}

void BlockEncoder::rapid(const Vec3& end, double t_s, double s_mm,
                         const std::array<bool, 3>& axes) {
  if (finished_) throw std::logic_error("BlockEncoder::rapid after finish()");
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(end[a]) || std::abs(end[a]) > kMaxCoordMm) {
      throw InputError("rapid to a coordinate " + text::sig(end[a]) +
                       " mm: the block encoder needs finite positions within 1e9 mm");
    }
  }
  close_open();
  std::int64_t q[3];
  quantize(end, q);
  std::string& t = block_.text;
  t.clear();
  if (settings_.numbers) {
    t.push_back('N');
    append_number(t, next_number_);
  }
  t += "G0";
  bool any = false;
  for (int a = 0; a < 3; ++a) {
    if (!axes[static_cast<std::size_t>(a)]) continue;
    if (axis_written_[a] && q[a] == written_q_[a]) continue;
    t.push_back("XYZ"[a]);
    append_fixed(t, q[a], settings_.decimals);
    written_q_[a] = q[a];
    axis_written_[a] = true;
    any = true;
  }
  const double from_t_s = anchor_.t_s;
  for (int a = 0; a < 3; ++a) anchor_.q[a] = q[a];
  anchor_.exact = end;
  anchor_.written = written(q);
  anchor_.rounding_mm = (anchor_.written - end).norm();
  anchor_.t_s = t_s;
  anchor_.s_mm = s_mm;
  end_ = {end, t_s, s_mm, 0.0};
  v_min_ = v_max_ = 0.0;
  last_p_ = end;
  last_step_ = Vec3::Zero();
  started_ = true;
  if (!any) return;     // the controller stands there already (as far as it was told)
  g1_written_ = false;  // the next feed block says G1 again
  deliver_line(BlockClose::Rapid, std::max(0.0, t_s - from_t_s), settings_.numbers);
}

void BlockEncoder::words(const std::string& text, double duration_s) {
  if (finished_) throw std::logic_error("BlockEncoder::words after finish()");
  close_open();
  std::string& t = block_.text;
  t.clear();
  if (settings_.numbers) {
    t.push_back('N');
    append_number(t, next_number_);
  }
  t += text;
  deliver_line(BlockClose::Words, duration_s, settings_.numbers);
}

void BlockEncoder::comment(const std::string& text) {
  if (finished_) throw std::logic_error("BlockEncoder::comment after finish()");
  if (!settings_.comments) return;
  close_open();
  // A comment longer than max_comment_chars (parentheses included) goes out as several, broken
  // after a space where one is near the end of the piece.
  const std::size_t room =
      settings_.max_comment_chars > 2 ? settings_.max_comment_chars - 2 : std::string::npos;
  std::size_t from = 0;
  do {
    std::size_t n = std::min(room, text.size() - from);
    if (from + n < text.size()) {
      const std::size_t space = text.rfind(' ', from + n - 1);
      if (space != std::string::npos && space > from + n / 2) n = space + 1 - from;
    }
    std::string& t = block_.text;
    t = "(";
    for (std::size_t i = from; i < from + n; ++i) {
      const char c = text[i];
      t.push_back(c == '(' ? '[' : c == ')' ? ']' : c);
    }
    t.push_back(')');
    deliver_line(BlockClose::Comment, 0.0, false);
    from += n;
  } while (from < text.size());
}

void BlockEncoder::percent_line() {
  if (!settings_.percent) return;
  close_open();
  block_.text = "%";
  deliver_line(BlockClose::Comment, 0.0, false);
}

int BlockEncoder::format_motion(const std::int64_t q[3], std::int64_t feed_units) {
  std::string& t = block_.text;
  t.clear();
  if (settings_.numbers) {
    t.push_back('N');
    append_number(t, next_number_);
  }
  if (!g1_written_) t += "G1";
  for (int a = 0; a < 3; ++a) {
    if (axis_written_[a] && q[a] == written_q_[a]) continue;
    t.push_back("XYZ"[a]);
    append_fixed(t, q[a], settings_.decimals);
  }
  if (feed_units != written_feed_) {
    t.push_back('F');
    append_fixed(t, feed_units, settings_.feed_decimals);
  }
  return static_cast<int>(t.size()) + eob_chars_;
}

void BlockEncoder::emit_positioning(const motion::Setpoint& sp) {
  std::int64_t q[3];
  quantize(sp.p, q);
  std::string& t = block_.text;
  t.clear();
  if (settings_.numbers) {
    t.push_back('N');
    append_number(t, next_number_);
  }
  t += "G21G90G94G0";
  for (int a = 0; a < 3; ++a) {
    t.push_back("XYZ"[a]);
    append_fixed(t, q[a], settings_.decimals);
    written_q_[a] = q[a];
    axis_written_[a] = true;
    anchor_.q[a] = q[a];
  }
  anchor_.exact = sp.p;
  anchor_.written = written(q);
  anchor_.rounding_mm = (anchor_.written - sp.p).norm();
  anchor_.t_s = sp.t_s;
  anchor_.s_mm = sp.s_mm;
  end_ = {sp.p, sp.t_s, sp.s_mm, sp.v_mm_per_s};
  v_min_ = v_max_ = sp.v_mm_per_s;
  last_p_ = sp.p;
  EncodedBlock& b = block_;
  b.number = next_number_;
  b.closed_by = BlockClose::Start;
  b.start_t_s = b.end_t_s = sp.t_s;
  b.start_s_mm = b.end_s_mm = sp.s_mm;
  b.length_mm = b.feed_mm_per_min = b.planned_feed_mm_per_min = 0.0;
  b.duration_s = b.planned_duration_s = 0.0;
  b.chord_error_mm = anchor_.rounding_mm;
  b.chars = static_cast<int>(t.size()) + eob_chars_;
  b.setpoints = 1;
  b.end = anchor_.written;
  b.end_v_mm_per_s = sp.v_mm_per_s;
  b.positioning = true;
  b.feed_lowered = false;
  check_line_length(t);
  if (!numbered_) stats_.first_number = b.number;
  numbered_ = true;
  stats_.last_number = b.number;
  stats_.chord_error_max_mm = std::max(stats_.chord_error_max_mm, b.chord_error_mm);
  ++stats_.blocks;
  ++stats_.closed_by[static_cast<int>(BlockClose::Start)];
  stats_.chars += b.chars;
  stats_.wire_s += static_cast<double>(b.chars * bits_) / settings_.line.baud;
  next_number_ += settings_.number_step;
  queue_model(b);
  sink_(b);
}

void BlockEncoder::emit(BlockClose reason, const std::int64_t q[3]) {
  const Vec3 wend = written(q);
  const Vec3& aw = anchor_.written;
  double chord = carried_error_mm_;
  for (const Vec3& p : pending_) chord = std::max(chord, dist_to_segment(p, aw, wend));
  carried_error_mm_ = 0.0;
  const double length = (wend - aw).norm();
  const double planned_s = end_.t_s - anchor_.t_s;
  const Feed f = feed_for(q, length, planned_s);  // leaves the text in block_.text
  check_line_length(block_.text);
  EncodedBlock& b = block_;
  b.number = next_number_;
  b.closed_by = reason;
  b.start_t_s = anchor_.t_s;
  b.end_t_s = end_.t_s;
  b.start_s_mm = anchor_.s_mm;
  b.end_s_mm = end_.s_mm;
  b.length_mm = length;
  b.feed_mm_per_min = static_cast<double>(f.units) / feed_scale_;
  b.planned_feed_mm_per_min = f.planned_mm_per_min;
  b.duration_s = length / b.feed_mm_per_min * 60.0;
  if (!f.lowered) {  // lowered blocks are slower on purpose, and reported as such
    time_drift_s_ += b.duration_s - planned_s;
    stats_.time_drift_max_s = std::max(stats_.time_drift_max_s, std::abs(time_drift_s_));
  }
  b.planned_duration_s = planned_s;
  b.chord_error_mm = chord;
  b.chars = f.chars;
  b.setpoints = pending_.size();
  b.end = wend;
  b.end_v_mm_per_s = end_.v_mm_per_s;
  b.positioning = false;
  b.feed_lowered = f.lowered;
  // The controller's modal state after this block.
  for (int a = 0; a < 3; ++a) {
    written_q_[a] = q[a];
    axis_written_[a] = true;
  }
  written_feed_ = f.units;
  g1_written_ = true;
  next_number_ += settings_.number_step;
  // Stats.
  EncoderStats& s = stats_;
  ++s.blocks;
  ++s.motion_blocks;
  ++s.closed_by[static_cast<int>(reason)];
  s.last_number = b.number;
  s.chars += b.chars;
  const double wire = static_cast<double>(b.chars * bits_) / settings_.line.baud;
  s.wire_s += wire;
  s.duration_s += b.duration_s;
  s.planned_duration_s += planned_s;
  const double use = wire / b.duration_s;
  s.link_use_sum += use;
  if (use > s.link_use_peak) {
    s.link_use_peak = use;
    s.link_use_peak_block = b.number;
  }
  if (s.motion_blocks == 1 || length < s.length_min_mm) s.length_min_mm = length;
  s.length_max_mm = std::max(s.length_max_mm, length);
  s.length_nm.add(length * 1e6);
  if (chord > s.chord_error_max_mm) {
    s.chord_error_max_mm = chord;
    s.chord_error_max_block = b.number;
  }
  if (f.clamped) ++s.feed_clamped;
  if (f.over_budget) ++s.over_budget_blocks;
  if (b.feed_lowered) {
    ++s.lowered_blocks;
    record_lowered(b, f.needed_length_mm);
  } else {
    flush_lowered_range();
  }
  queue_model(b);
  sink_(b);
  // The next block starts where this one was written to end.
  for (int a = 0; a < 3; ++a) anchor_.q[a] = q[a];
  anchor_.exact = end_.p;
  anchor_.written = wend;
  anchor_.rounding_mm = (wend - end_.p).norm();
  anchor_.t_s = end_.t_s;
  anchor_.s_mm = end_.s_mm;
  pending_.clear();
  bound_mm_ = 0.0;
  v_min_ = v_max_ = end_.v_mm_per_s;
}

void BlockEncoder::record_lowered(const EncodedBlock& b, double needed_length_mm) {
  if (!in_range_) {
    in_range_ = true;
    range_ = LoweredRange{};
    range_.first_block = b.number;
    range_.s_from_mm = b.start_s_mm;
    range_.lowered_feed_min_mm_per_min = b.feed_mm_per_min;
    range_.length_min_mm = b.length_mm;
    std::fill(std::begin(range_reasons_), std::end(range_reasons_), 0);
  }
  range_.last_block = b.number;
  range_.s_to_mm = b.end_s_mm;
  range_.planned_feed_mm_per_min =
      std::max(range_.planned_feed_mm_per_min, b.planned_feed_mm_per_min);
  range_.lowered_feed_min_mm_per_min =
      std::min(range_.lowered_feed_min_mm_per_min, b.feed_mm_per_min);
  range_.length_min_mm = std::min(range_.length_min_mm, b.length_mm);
  range_.length_max_mm = std::max(range_.length_max_mm, b.length_mm);
  range_.needed_length_mm = std::max(range_.needed_length_mm, needed_length_mm);
  ++range_.blocks;
  ++range_reasons_[static_cast<int>(b.closed_by)];
}

void BlockEncoder::flush_lowered_range() {
  if (!in_range_) return;
  in_range_ = false;
  ++stats_.lowered_ranges;
  if (stats_.lowered.size() >= settings_.max_lowered_ranges) return;
  std::string causes;
  for (int k = 0; k < kBlockCloseCount; ++k) {
    if (range_reasons_[k] == 0) continue;
    if (!causes.empty()) causes += ", ";
    switch (static_cast<BlockClose>(k)) {
      case BlockClose::Chord:
        causes += "the chord tolerance of " + text::sig(settings_.chord_tolerance_mm) + " mm";
        break;
      case BlockClose::FeedBand:
        causes += "the feed band";
        break;
      case BlockClose::Turn:
        causes += "a turn of more than 90 degrees";
        break;
      case BlockClose::Cap:
        causes += "the cap of setpoints per block";
        break;
      case BlockClose::Duration:
        causes += "the longest block of " + text::sig(settings_.max_block_s) + " s";
        break;
      case BlockClose::End:
        causes += "the end of a stretch (an event or a rapid follows)";
        break;
      case BlockClose::Start:
      case BlockClose::Rapid:
      case BlockClose::Words:
      case BlockClose::Comment:
        break;
    }
    causes += " (" + std::to_string(range_reasons_[k]) + ")";
  }
  range_.reason = "blocks cut to " + text::fixed(range_.length_min_mm, 4) + "-" +
                  text::fixed(range_.length_max_mm, 4) + " mm by " + causes + ", but the link (" +
                  stats_.line + ", at most " + text::fixed(100.0 * settings_.link_margin, 0) +
                  " % of " + text::fixed(stats_.chars_per_s, 0) +
                  " chars/s) needs blocks of up to " + text::fixed(range_.needed_length_mm, 4) +
                  " mm at the planned feed of up to " +
                  text::fixed(range_.planned_feed_mm_per_min, 1) + " mm/min; feed lowered to " +
                  text::fixed(range_.lowered_feed_min_mm_per_min, 1) + " mm/min at the lowest";
  stats_.lowered.push_back(range_);
}

void BlockEncoder::queue_model(const EncodedBlock& b) {
  QueueModelStats& m = stats_.queue;
  const std::size_t ring = queue_.size();
  const int cap = std::max(settings_.rx_buffer_bytes, b.chars);
  double t = tx_free_s_;
  // Blocks that have left the buffer (started) by the time the sender is free.
  while (queue_size_ > 0 && queue_[queue_head_].start_s <= t) {
    queue_fill_ -= queue_[queue_head_].chars;
    queue_head_ = (queue_head_ + 1) % ring;
    --queue_size_;
  }
  // Flow control: wait for room for the whole block.
  while (queue_fill_ + b.chars > cap && queue_size_ > 0) {
    t = std::max(t, queue_[queue_head_].start_s);
    queue_fill_ -= queue_[queue_head_].chars;
    queue_head_ = (queue_head_ + 1) % ring;
    --queue_size_;
  }
  const double arrival = t + static_cast<double>(b.chars * bits_) / settings_.line.baud;
  tx_free_s_ = arrival;
  queue_fill_ += b.chars;
  m.max_buffer_fill_bytes = std::max(m.max_buffer_fill_bytes, queue_fill_);
  double start = arrival;
  if (stats_.blocks > 1) {  // the first block is waited for by definition
    if (arrival > exec_done_s_) {
      if (prev_moving_) {
        ++m.underruns;
        m.underrun_time_s += arrival - exec_done_s_;
        if (m.first_underrun_block == 0) m.first_underrun_block = b.number;
      } else {
        ++m.waits_at_rest;
      }
    } else {
      start = exec_done_s_;
    }
  }
  exec_done_s_ = start + b.duration_s;
  m.stream_end_s = exec_done_s_;
  prev_moving_ = !b.positioning && b.end_v_mm_per_s > 0.0;  // the machine waits at the start
  if (queue_size_ == ring) {  // cannot happen: every block takes at least one byte
    queue_fill_ -= queue_[queue_head_].chars;
    queue_head_ = (queue_head_ + 1) % ring;
    --queue_size_;
  }
  queue_[(queue_head_ + queue_size_) % ring] = {start, b.chars};
  ++queue_size_;
}

nlohmann::ordered_json to_json(const EncoderStats& s) {
  nlohmann::ordered_json j;
  j["blocks"] = s.blocks;
  j["motion_blocks"] = s.motion_blocks;
  j["numbers"] = {s.first_number, s.last_number};
  j["chars"] = s.chars;
  j["setpoints"] = s.setpoints;
  j["block_length_mm"] = {
      {"min", s.length_min_mm}, {"median", s.length_median_mm()}, {"max", s.length_max_mm}};
  j["chord_error_max_mm"] = s.chord_error_max_mm;
  j["chord_error_max_block"] = s.chord_error_max_block;
  j["chord_tolerance_mm"] = s.chord_tolerance_mm;
  j["rounding_error_mm"] = s.rounding_error_mm;
  j["link"] = {{"line", s.line},
               {"chars_per_s", s.chars_per_s},
               {"margin", s.link_margin},
               {"use_mean", s.link_use_mean()},
               {"use_peak", s.link_use_peak},
               {"use_peak_block", s.link_use_peak_block},
               {"use_overall", s.link_use_overall()},
               {"wire_s", s.wire_s}};
  j["duration_s"] = s.duration_s;
  j["planned_duration_s"] = s.planned_duration_s;
  j["time_drift_max_s"] = s.time_drift_max_s;
  j["unwritten_tail_s"] = s.unwritten_tail_s;
  nlohmann::ordered_json closed;
  for (int k = 1; k < kBlockCloseCount; ++k) {
    closed[to_string(static_cast<BlockClose>(k))] = s.closed_by[k];
  }
  j["closed_by"] = closed;
  j["band_waived_setpoints"] = s.band_waived;
  j["feed_clamped_blocks"] = s.feed_clamped;
  j["over_budget_blocks"] = s.over_budget_blocks;
  nlohmann::ordered_json ranges = nlohmann::ordered_json::array();
  for (const LoweredRange& r : s.lowered) {
    ranges.push_back({{"first_block", r.first_block},
                      {"last_block", r.last_block},
                      {"blocks", r.blocks},
                      {"s_from_mm", r.s_from_mm},
                      {"s_to_mm", r.s_to_mm},
                      {"planned_feed_mm_per_min", r.planned_feed_mm_per_min},
                      {"lowered_feed_min_mm_per_min", r.lowered_feed_min_mm_per_min},
                      {"reason", r.reason}});
  }
  j["feed_lowered"] = {
      {"blocks", s.lowered_blocks}, {"ranges", s.lowered_ranges}, {"range_list", ranges}};
  j["queue_model"] = {{"rx_buffer_bytes", s.rx_buffer_bytes},
                      {"underruns", s.queue.underruns},
                      {"underrun_time_s", s.queue.underrun_time_s},
                      {"first_underrun_block", s.queue.first_underrun_block},
                      {"waits_at_rest", s.queue.waits_at_rest},
                      {"max_buffer_fill_bytes", s.queue.max_buffer_fill_bytes},
                      {"stream_end_s", s.queue.stream_end_s}};
  return j;
}

}  // namespace ncd::comms
