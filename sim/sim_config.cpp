// The simulated controller's settings checked (each out-of-range value named with its limit and a
// way out) and the defaults filled in; the longest block the receive buffer takes.
#include <algorithm>
#include <cmath>
#include <string>

#include "core/error.hpp"
#include "core/number_text.hpp"
#include "sim/sim_controller.hpp"

namespace ncd::comms {

namespace {

constexpr int kMaxBlockChars = 255;

// Throws the InputError for a setting out of range.
[[noreturn]] void bad(const std::string& what, const std::string& way_out) {
  throw InputError(what + ": " + way_out);
}

}  // namespace

SimControllerConfig checked(SimControllerConfig c) {
  check_baud(c.line.baud);
  if (c.line.device.empty()) bad("no link path", "give --link PATH, e.g. /tmp/cnc0");
  const bool ack = c.line.protocol == Protocol::Ack;
  if (c.buffer_bytes == 0) c.buffer_bytes = ack ? 128 : 256;
  if (c.buffer_bytes < 64 || c.buffer_bytes > (1 << 20)) {
    bad("--buffer " + std::to_string(c.buffer_bytes) + " is out of range",
        "use 64 to 1048576 bytes (grbl has 128, grblHAL 1024, a Fanuc some 256)");
  }
  if (!c.xoff_at) c.xoff_at = c.buffer_bytes - std::min(64, c.buffer_bytes / 4);
  if (!c.xon_at) c.xon_at = *c.xoff_at / 2;
  if (*c.xoff_at < 2 || *c.xoff_at > c.buffer_bytes) {
    bad("--xoff-at " + std::to_string(*c.xoff_at) + " is out of range",
        "use 2 to the buffer size " + std::to_string(c.buffer_bytes) +
            ", leaving room for the characters a sender sends after DC3 (default buffer − 64)");
  }
  if (*c.xon_at < 0 || *c.xon_at >= *c.xoff_at) {
    bad("--xon-at " + std::to_string(*c.xon_at) + " is out of range",
        "use 0 to " + std::to_string(*c.xoff_at - 1) + ", below --xoff-at " +
            std::to_string(*c.xoff_at));
  }
  if (c.planner_blocks < 1 || c.planner_blocks > 1000) {
    bad("--planner-blocks " + std::to_string(c.planner_blocks) + " is out of range",
        "use 1 to 1000 (grbl 1.1 has 15)");
  }
  if (!std::isfinite(c.rapid_mm_per_min) || c.rapid_mm_per_min <= 0.0) {
    bad("--rapid " + text::sig(c.rapid_mm_per_min) + " mm/min is invalid", "use a rate above 0");
  }
  if (!(c.prime_idle_s > 0.0) || !(c.underrun_grace_s >= 0.0) || !(c.exit_quiet_s >= 0.0) ||
      !(c.alarm_linger_s >= 0.0)) {
    bad("a controller timing is negative or not a number", "use finite times of 0 s or more");
  }
  SimFaults& f = c.faults;
  const bool xon_xoff = c.line.protocol == Protocol::Drip && c.line.flow == Flow::XonXoff;
  if (!std::isfinite(c.boot_s) || c.boot_s < 0.0 || c.boot_s > 60.0) {
    bad("--boot-s " + text::sig(c.boot_s) + " is out of range",
        "use 0 to 60 s (an Arduino's bootloader takes about 1 to 2 s)");
  }
  if ((c.reset_on_open || c.report_line_numbers) && !ack) {
    bad(std::string(c.reset_on_open ? "--reset-on-open" : "--report-line-numbers") +
            " is a grbl behaviour",
        "use --protocol ack");
  }
  if (c.dialect && (*c.dialect == Dialect::grbl) != ack) {
    bad(std::string("--dialect ") + to_string(*c.dialect) + " does not go with --protocol " +
            (ack ? "ack" : "drip"),
        "use --dialect grbl with --protocol ack, iso or linuxcnc with --protocol drip");
  }
  if (!std::isfinite(c.tool_change_s) || c.tool_change_s < 0.0 || c.tool_change_s > 600.0) {
    bad("--tool-change-s " + text::sig(c.tool_change_s) + " is out of range", "use 0 to 600 s");
  }
  if (c.skip_duplicate_n && ack) {
    bad("--skip-duplicate-n is not a grbl behaviour (grbl ignores N numbers)",
        "use --protocol drip, or leave it out");
  }
  if (c.status_mask < 0 || c.status_mask > 3) {
    bad("--status-mask " + std::to_string(c.status_mask) + " is out of range",
        "use grbl's $10: 0 (WPos), 1 (MPos, grbl's default), 2 (WPos and Bf:) or 3 (MPos and Bf:)");
  }
  if (!std::isfinite(c.hold_accel_mm_per_s2) || c.hold_accel_mm_per_s2 <= 0.0) {
    bad("--accel " + text::sig(c.hold_accel_mm_per_s2) + " mm/s² is invalid",
        "use an acceleration above 0 (grbl's default $120 is 10 mm/s²)");
  }
  if (f.restart_after_blocks != 0 && !ack) {
    bad("--restart-after-blocks is a grbl behaviour (its banner after a power-up)",
        "use --protocol ack, or --reset-after-blocks");
  }
  if (f.drop_link_after_blocks < 0 || f.hold_after_blocks < 0 || f.alarm_after_blocks < 0 ||
      f.reset_after_blocks < 0 || f.drop_link_after_chars < 0 || f.restart_after_blocks < 0) {
    bad("a fault's block count is negative", "use a count of 1 or more, or 0 for none");
  }
  if (!std::isfinite(f.down_s) || f.down_s < 0.0 || f.down_s > 3600.0) {
    bad("--down-s " + text::sig(f.down_s) + " is out of range", "use 0 to 3600 s");
  }
  if (f.hold_after_blocks > 0 && (!std::isfinite(f.hold_s) || f.hold_s <= 0.0)) {
    bad("--hold-s " + text::sig(f.hold_s) + " is invalid", "use a hold longer than 0 s");
  }
  if ((f.xoff_storm || f.hold_after_blocks > 0) && !xon_xoff) {
    bad(std::string(f.xoff_storm ? "--xoff-storm" : "--hold-after-blocks") +
            " needs DC1/DC3 flow control",
        "use --protocol drip --flow xonxoff");
  }
  const double cps = chars_per_s(c.line);
  if (!std::isfinite(f.noise_bytes_per_s) || f.noise_bytes_per_s < 0.0 ||
      f.noise_bytes_per_s > cps) {
    bad("--noise-bytes-per-s " + text::sig(f.noise_bytes_per_s) + " is out of range",
        "use 0 to the line's " + text::sig(std::floor(cps)) + " characters per second");
  }
  return c;
}

int max_block_chars(const SimControllerConfig& c) {
  const bool xon_xoff = c.line.protocol == Protocol::Drip && c.line.flow == Flow::XonXoff;
  const int room = xon_xoff ? c.xoff_at.value_or(c.buffer_bytes) : c.buffer_bytes;
  return std::max(1, std::min(kMaxBlockChars, room - 2));
}

}  // namespace ncd::comms
