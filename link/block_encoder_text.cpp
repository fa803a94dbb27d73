// The block encoder's text (the top of block_encoder.cpp, "A block is written compactly"): a
// closed block written as N, G1, the axes that change and F, the first block's positioning
// move, rapids, words and comments passed through, the program's % lines, each line checked
// against the controller's line length and handed to the sink.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/error.hpp"
#include "core/number_text.hpp"
#include "link/block_encoder.hpp"
#include "link/block_encoder_detail.hpp"

namespace ncd::comms {

using namespace encoder_detail;

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

std::string& BlockEncoder::begin_rapid_block() {
  std::string& t = block_.text;
  t.clear();
  if (settings_.numbers) {
    t.push_back('N');
    append_number(t, next_number_);
  }
  t += "G0";
  return t;
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
  std::string& t = begin_rapid_block();
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

void BlockEncoder::index(char axis, double to_deg, double duration_s) {
  if (finished_) throw std::logic_error("BlockEncoder::index after finish()");
  if (const std::string why = rotary_refusal(settings_, axis); !why.empty()) throw InputError(why);
  if (!std::isfinite(to_deg) || std::abs(to_deg) > 1e6) {
    throw InputError("index to " + text::sig(to_deg) +
                     " degrees: the block encoder needs a finite angle within 1e6 degrees");
  }
  close_open();
  const double q = std::round(to_deg * scale_);  // degrees at the coordinates' decimals
  if (q == rotary_written_deg_) return;
  rotary_written_deg_ = q;
  std::string& t = begin_rapid_block();
  t.push_back(static_cast<char>(std::toupper(axis)));
  append_fixed(t, static_cast<std::int64_t>(q), settings_.decimals);
  deliver_line(BlockClose::Words, duration_s, settings_.numbers);
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

}  // namespace ncd::comms
