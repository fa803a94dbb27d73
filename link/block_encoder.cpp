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
#include <limits>
#include <stdexcept>

#include "core/error.hpp"
#include "core/number_text.hpp"
#include "link/block_encoder_detail.hpp"

namespace ncd::comms {

using namespace encoder_detail;

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
  if (sp.limit_id == motion::kLimitIdIndex) {  // a rotary index: X, Y, Z stand still
    if (!index_open_) {
      close_open();  // the blocks before end where the tool rests
      index_open_ = true;
      index_from_t_s_ = end_.t_s;
    }
    if (!sp.indexing) {  // landed: one block for the whole index, with the time it took
      index_open_ = false;
      index(settings_.rotary_axis, sp.rotary_deg, sp.t_s - index_from_t_s_);
      anchor_.t_s = end_.t_s = sp.t_s;
    }
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

}  // namespace ncd::comms
