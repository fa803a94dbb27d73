// The block encoder's settings (docs/block-encoder.md): what a controller's dialect sets, the
// rounding of a written coordinate, the names of the reasons a block closes, and the checks of
// the settings with the words of each refusal.
#include <cctype>
#include <cmath>
#include <string>

#include "core/error.hpp"
#include "core/number_text.hpp"
#include "link/block_encoder.hpp"
#include "link/block_encoder_detail.hpp"

namespace ncd::comms {

using namespace encoder_detail;

void apply_dialect(EncoderSettings& settings, Dialect dialect) {
  const DialectRules& r = rules(dialect);
  settings.numbers = settings.numbers_wanted.value_or(r.n_numbers);
  settings.comments = r.paren_comments;
  settings.path_blending = r.path_blending;
  settings.length_offsets = r.length_offsets;
  settings.rotary_words = r.rotary_axis;
  if (r.max_line_chars > 0) settings.max_comment_chars = static_cast<std::size_t>(r.max_line_chars);
}

std::string rotary_refusal(const EncoderSettings& s, char axis) {
  const std::string w(1, static_cast<char>(std::toupper(axis)));
  if (s.rotary_axis == 0) {
    return "the program indexes " + w +
           ", but the machine file declares no rotary axis; add an [axis." + std::string(1, axis) +
           "] table";
  }
  if (s.rotary_axis != axis) {
    return "the program indexes " + w + ", but the machine's rotary axis is " +
           std::string(1, static_cast<char>(std::toupper(s.rotary_axis)));
  }
  if (!s.rotary_words) {
    return "the program indexes " + w +
           ", but the controller's dialect has no rotary axis (stock grbl 1.1 drives X, Y, Z "
           "only and answers error:20 to an " +
           w +
           " word); stream it to a controller of the linuxcnc or iso dialect ([link] dialect); "
           "ncd does not drive a grblHAL's fourth axis";
  }
  return {};
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

}  // namespace ncd::comms
