// The block encoder's figures (docs/block-encoder.md): the ranges of blocks whose feed the link's
// budget lowered (with their cause and numbers), the model of the controller's queue that the
// blocks fill and drain, and the statistics as JSON.
#include <algorithm>
#include <cmath>
#include <string>

#include "core/number_text.hpp"
#include "link/block_encoder.hpp"

namespace ncd::comms {

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
