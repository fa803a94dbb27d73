// The simulated controller: a CNC's DNC port on a pseudo-terminal, one thread, one loop, on the
// wall clock or on a clock the caller injects (SimControllerConfig::clock, a ManualClock in the
// tests), so that pacing, execution and faults can be tested in simulated time. The protocols
// and what each guarantees are described in docs/dnc-link.md.
//
//   sender ─► pty slave ═ kernel ═► master ─► wire ─► receive buffer ─► (ack: planner) ─► executor
//                                  ≤ chars_per_s    buffer_bytes        planner_blocks   real time
//          ◄─ DC1 / DC3, NAK (drip)      ◄─ ok / error:N / ALARM:N (ack)
//
// 1. The wire. A pty has no baud rate, so the master is read no faster than the line would
//    deliver: chars_per_s(line) characters a second, each taken at the end of its frame. A
//    credit grows at chars_per_s while characters wait and drops to zero when the line goes
//    idle, so an idle line banks nothing and the first character after a pause costs a whole
//    character time; while the line is busy the credit is not capped, so a late wake-up of this
//    loop catches up as a UART's FIFO would, and never exceeds the line's rate overall. In drip
//    mode each character of such a burst keeps its own arrival time and the executor and the
//    flow control run between characters, as the controller's receive interrupt would have
//    them. A DC3 that was due more than kLateFlowS before the loop could send it, or before its
//    write reached the pty (the loop's thread kept from running in between) (xoff_late), holds
//    what the sender wrote before it could see it (the rest of the burst and what waits in
//    the kernel, no more than the line could carry meanwhile) until DC1, and those characters obey
//    every DC3 until they have all been read, as the sender's flow control would have had them: the
//    simulation's lateness is never blamed on the sender. A pty carries no framing, no parity and
//    no CTS: parity and stop bits only lengthen the character time, 7-bit frames are emulated by
//    masking the 8th bit, and --flow rtscts cannot stop the sender (there is no CTS line), so it
//    behaves as --flow none and the buffer can overflow.
// 2. The receive buffer holds the line being received and the complete lines not yet taken out,
//    CR and LF included; NULs (leader) are dropped on arrival, as a tape reader skips them. A
//    character that finds the buffer full is an overflow: alarm. A line longer than
//    max_block_chars is an error (ack: error:11) or an alarm (drip).
// 3. Drip: DC3 when the fill reaches xoff_at, DC1 when it falls to xon_at; a sender that
//    connects gets the current state first (DC1, ready, at the start); XOFF storms, holds and
//    alarms also assert DC3.
//    Ack (grbl 1.1): CR and LF each end a line (so CR LF is a line and an empty line, two oks).
//    A line is answered when it leaves the receive buffer: `ok` when a move enters the planner
//    queue (planner_blocks, 15 as grbl's, the executing block included), `ok` for a block
//    without motion once the planner has run empty and the block took effect (grbl
//    synchronises for M codes and G4; it does not for pure setup blocks, which the simulation
//    makes wait as well), `error:N` when it does not parse, `error:11` when more than 79
//    characters are left after removing spaces and comments. A sender counting characters
//    never overflows the buffer; one that does broke the rule: alarm. No DC1/DC3 in ack mode.
//    Real-time bytes are taken out of the stream as they arrive, like grbl's serial interrupt:
//    `?` answers `<State|MPos:x,y,z|Bf:free blocks,free bytes[|Ln:n]|FS:feed,0>` as grbl counts
//    (stepper.c, planner.c, serial.c): a move leaves the planner, and Bf:'s count and Ln:, when
//    its last 10 ms segment is prepared, up to 5 segments before the motion gets there (this
//    also frees its slot for the next line); the byte count is grbl's serial ring, which holds
//    only the bytes behind a line waiting for the planner (docs/dnc-link.md); the status mask
//    ($10, status_mask) chooses MPos or WPos and whether Bf: is there, FS: gives the spindle's
//    speed (0 when stopped), WCO: the work offset on the first report after a reset and every
//    10th (idle) or 30th (busy). `!` decelerates the move at hold_accel (Hold:1; a move that
//    cannot stop within itself runs to its end) and holds it at rest (Hold:0), when grbl's
//    protocol loop is suspended: no line is read until `~` (ignored before Hold:0) or a reset.
//    0x18 resets. A reset (also the injected fault, a power cycle, and with reset_on_open a
//    sender opening the port) aborts the block executing, throws away the planner, the receive
//    buffer and a partial line, stops the spindle and coolant, returns the parser to its
//    power-on modes at the machine's position (which a power-up restarts at 0), and after
//    boot_s (bytes received meanwhile are lost, counted as bytes_before_banner) sends the
//    banner, lost if the port is closed then; a reset in motion (before Hold:0) first says
//    ALARM:3 and locks the controller (error:9 for every g-code line) until `$X`. `$10=N` sets
//    the mask (error:8 unless Idle). N numbers are ignored.
// 4. Lines. LF ends a line; CR and NUL are removed, spaces and tabs trimmed at both ends. Empty
//    lines and `%` lines are framing: a `%` after a block on the current connection ends the
//    program; any other `%` opens it (again, from a sender that reconnected).
//    Every other line is a block, comments included. A repeated block is executed again; only
//    with skip_duplicate_n (drip) is a block whose N is not above the last accepted N
//    discarded, as a controller documented to skip repeated sequence numbers would. Accepted
//    blocks are hashed (SHA-256, each with one LF); M2/M30 end the program too. Lines after the
//    end are counted and ignored (ack: answered ok). Each block executed to its end is logged
//    (`executed`), so a test can compare what ran with the program.
// 5. Execution starts when the buffer is primed (ack: at once, as grbl's auto cycle start): the
//    fill reaches xoff_at, the program end has arrived, or prime_idle_s passed without a
//    character while a block waits. Then each block runs for its time (distance / F for G1, the
//    rapid rate for G0, P seconds for G4, none for the rest) back to back on exact times, so the
//    jitter of this loop does not accumulate. A block's characters leave the buffer when it starts
//    (drip). When the executor is free and the next block arrives later, before the program end
//    has, the tool dwells: an underrun, counted once per dry spell longer than underrun_grace_s.
//    Dry spells before the first move are not counted: the tool is not on the path yet, the
//    controller is reading the program's header (comment lines execute in no time).
//    Once started, execution never waits to be primed again.
// 6. Connections. The slave is watched with inotify. When the last sender closes it, what it
//    wrote is still read at line speed, then its unfinished line is discarded and replies owed
//    to it are dropped; a sender that connects gets a clean input queue and the flow state
//    first. A link drop (fault injection, after N blocks or N characters of lines) does the
//    same at once, and the bytes in flight are lost with the old pty. In ack (grbl) mode the
//    unfinished line is kept instead: grbl's UART knows nothing of the PC's port, and the next
//    characters, from any connection, complete it.
// 7. Dialects (config.dialect, docs/dnc-link.md "Dialects"). grbl: each line's verdict and
//    error number come from comms/dialect's check_grbl_line on the controller's own grbl state
//    (the sender's pre-check runs the same function), and the block executes as grbl would
//    (arcs timed by their helix length, G91, G20, offsets, G28/G30, G93); grbl reads no line
//    while a G4 or an M0 runs. iso/linuxcnc: a refused line is an alarm. Events (S, T, M6,
//    M3/M4/M5, M8/M9, G4 before the motion; M0/M1 after it; the program end) are logged at the
//    controller's times. M0 holds until cycle start (`~`, or cycle_start()); M6 takes
//    tool_change_s. Machine safety: a feed move with the spindle stopped is an alarm when it is
//    received (grbl has no such check).
#include "sim/sim_controller.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstring>
#include <deque>
#include <random>

#include "core/error.hpp"
#include "core/number_text.hpp"
#include "link/program_file.hpp"
#include "link/pty.hpp"
#include "link/sha256.hpp"

namespace ncd::comms {

using Json = nlohmann::json;

namespace {

using Clock = std::chrono::steady_clock;

constexpr int kMaxBlockChars = 255;
constexpr double kLoopPeriodS = 0.001;  // longest wait of the loop
// A DC3 sent this much after it was due (a late wake-up of the loop) pauses the wire until it
// has gone out (drip), so that the loop's own lateness is never blamed on the sender.
constexpr double kLateFlowS = 0.002;
constexpr std::size_t kMaxOutQueue = 4096;  // beyond this, noise is not generated
constexpr double kReceivingS = 0.1;         // "while receiving": a byte within this long
// grbl 1.1's step segment buffer (stepper.c): SEGMENT_BUFFER_SIZE 6, of which 5 hold segments,
// each at most DT_SEGMENT = 1/(ACCELERATION_TICKS_PER_SECOND·60) min = 10 ms of motion.
constexpr int kGrblSegments = 5;
constexpr double kGrblSegmentS = 0.01;

// Throws the InputError for a setting out of range.
[[noreturn]] void bad(const std::string& what, const std::string& way_out) {
  throw InputError(what + ": " + way_out);
}

// Reads a number at text[i] ([+-] digits [. digits] or . digits); advances i. False if none.
bool read_number(std::string_view text, std::size_t& i, double& value) {
  std::size_t j = i;
  bool negative = false;
  if (j < text.size() && (text[j] == '+' || text[j] == '-')) negative = text[j++] == '-';
  const std::size_t start = j;
  bool digits = false;
  while (j < text.size() && std::isdigit(static_cast<unsigned char>(text[j]))) {
    ++j;
    digits = true;
  }
  if (j < text.size() && text[j] == '.') {
    ++j;
    while (j < text.size() && std::isdigit(static_cast<unsigned char>(text[j]))) {
      ++j;
      digits = true;
    }
  }
  if (!digits) return false;
  double v = 0.0;
  const auto r = std::from_chars(text.data() + start, text.data() + j, v);
  if (r.ec != std::errc() || !std::isfinite(v)) return false;
  value = negative ? -v : v;
  i = j;
  return true;
}

double distance(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
}

}  // namespace

// ---- Config ----

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

// ---- Block parsing ----

SimParse parse_sim_block(std::string_view text, SimModal& modal, double rapid_mm_per_min) {
  SimParse r;
  const auto fail = [&r](int code, std::string message) {
    r.error = code;
    r.message = std::move(message);
    r.block = SimBlock{};
    return r;
  };
  struct Word {
    char letter;
    double value;
  };
  std::vector<Word> words;
  for (std::size_t i = 0; i < text.size();) {
    const char c = text[i];
    if (c == ' ' || c == '\t') {
      ++i;
    } else if (c == '(') {
      const auto close = text.find(')', i);
      if (close == std::string_view::npos) break;  // an unclosed comment runs to the end
      i = close + 1;
    } else if (c == ';') {
      break;
    } else if (std::isalpha(static_cast<unsigned char>(c))) {
      const char letter = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
      ++i;
      while (i < text.size() && (text[i] == ' ' || text[i] == '\t')) ++i;
      double v = 0.0;
      if (!read_number(text, i, v)) {
        return fail(kErrBadNumber, std::string("the word ") + letter + " has no valid number");
      }
      words.push_back({letter, v});
    } else {
      return fail(kErrExpectedLetter, std::string("'") + c + "' is not a word letter");
    }
  }

  SimModal next = modal;
  SimBlock b;
  std::array<std::optional<double>, 3> axis;
  std::optional<double> p_word;
  std::optional<int> motion;  // 0, 1 or 80 given in this block
  bool dwell = false, g64 = false, g43 = false;
  std::optional<double> h_word;
  std::string seen;  // letters that may not repeat
  for (const Word& w : words) {
    const bool integer = w.value == std::floor(w.value);
    if (w.letter != 'G' && w.letter != 'M') {
      if (seen.find(w.letter) != std::string::npos) {
        return fail(kErrRepeatedWord, std::string("the word ") + w.letter + " appears twice");
      }
      seen += w.letter;
    }
    switch (w.letter) {
      case 'N':
        if (!integer) return fail(kErrNotInteger, "N " + text::sig(w.value) + " is not an integer");
        if (w.value < 0.0 || w.value > 99999999.0) {
          return fail(kErrBadLineNumber, "N " + text::sig(w.value) + " is outside 0 … 99999999");
        }
        b.n = static_cast<long>(w.value);
        break;
      case 'G': {
        const long code10 = std::lround(w.value * 10.0);
        if (std::abs(w.value * 10.0 - static_cast<double>(code10)) > 1e-6) {
          return fail(kErrUnsupported, "G" + text::sig(w.value) + " is not a G code");
        }
        if (code10 == 0 || code10 == 10 || code10 == 800) {
          if (motion) return fail(kErrModalGroup, "two motion codes in one block");
          motion = static_cast<int>(code10 / 10);
        } else if (code10 == 40) {
          dwell = true;
          b.dwell = true;
        } else if (code10 == 640) {
          g64 = true;
        } else if (code10 == 430) {
          g43 = true;
        } else if (code10 == 910) {
          return fail(kErrUnsupported,
                      "G91 (incremental) is not supported: send absolute coordinates (G90)");
        } else if (code10 == 200) {
          return fail(kErrUnsupported, "G20 (inch) is not supported: send mm (G21)");
        } else if (code10 == 20 || code10 == 30) {
          return fail(kErrUnsupported, "G2/G3 arcs are not supported: send G1 segments");
        } else if (code10 != 170 && code10 != 210 && code10 != 400 && code10 != 490 &&
                   code10 != 540 && code10 != 610 && code10 != 611 && code10 != 800 &&
                   code10 != 900 && code10 != 940) {
          return fail(kErrUnsupported, "G" + text::sig(w.value) +
                                           " is not supported: use G0 G1 G4, or the setup codes "
                                           "G17 G21 G40 G43 G49 G54 G61 G61.1 G64 G80 G90 G94");
        }
        break;
      }
      case 'M': {
        if (!integer) return fail(kErrNotInteger, "M" + text::sig(w.value) + " is not an integer");
        const int m = static_cast<int>(w.value);
        if (m == 2 || m == 30) {
          b.program_end = true;
        } else if (m == 0) {
          b.pause = true;
        } else if (m == 1) {
          b.optional_stop = true;
        } else if (m == 3 || m == 4 || m == 5) {
          b.spindle = m;
        } else if (m == 6) {
          b.tool_change = true;
        } else if (m == 8 || m == 9) {
          b.coolant = m == 8;
        } else {
          return fail(kErrUnsupported, "M" + std::to_string(m) +
                                           " is not supported: use M0 M1 M2 M3 M4 M5 M6 M8 M9 M30");
        }
        break;
      }
      case 'X':
      case 'Y':
      case 'Z':
        axis[static_cast<std::size_t>(w.letter - 'X')] = w.value;
        break;
      case 'F':
        if (w.value < 0.0) return fail(kErrNegative, "F " + text::sig(w.value) + " is negative");
        next.feed_mm_per_min = w.value;
        break;
      case 'S':
        if (w.value < 0.0) return fail(kErrNegative, "S " + text::sig(w.value) + " is negative");
        b.spindle_rpm = w.value;
        break;
      case 'T':
        if (!integer) return fail(kErrNotInteger, "T " + text::sig(w.value) + " is not an integer");
        if (w.value < 0.0) return fail(kErrNegative, "T " + text::sig(w.value) + " is negative");
        b.tool = static_cast<int>(w.value);
        break;
      case 'P':
        if (w.value < 0.0) return fail(kErrNegative, "P " + text::sig(w.value) + " is negative");
        p_word = w.value;
        break;
      case 'H':
        if (!integer) return fail(kErrNotInteger, "H " + text::sig(w.value) + " is not an integer");
        if (w.value < 0.0) return fail(kErrNegative, "H " + text::sig(w.value) + " is negative");
        h_word = w.value;
        break;
      default:
        return fail(kErrUnsupported, std::string("the word ") + w.letter +
                                         " is not supported: use N G X Y Z F S M T P H");
    }
  }
  // G43 H n: the length of tool n from the controller's table, which this model holds as 0
  // for every tool: the programmed point is the one the blocks drive.
  if (g43 && !h_word) return fail(kErrMissingValue, "G43 needs H, the tool table's entry");
  if (h_word && !g43) return fail(kErrUnsupported, "an H word needs G43 (tool length offset)");
  if (p_word && !dwell && !g64) {
    return fail(kErrUnsupported, "a P word needs G4 (dwell) or G64 (blending tolerance)");
  }
  if (motion) next.motion = *motion;
  if (b.spindle) next.spindle = *b.spindle;
  if (b.program_end) next.spindle = 5;
  const bool has_axis = axis[0] || axis[1] || axis[2];
  if (dwell) {
    if (motion || has_axis) return fail(kErrModalGroup, "G4 with a motion in the same block");
    if (!p_word) return fail(kErrMissingValue, "G4 needs P, the dwell in seconds");
    b.duration_s = *p_word;
  } else if (has_axis) {
    if (next.motion == 80) return fail(kErrUnsupported, "axis words after G80 (no motion mode)");
    for (std::size_t k = 0; k < 3; ++k) b.to[k] = axis[k].value_or(modal.position[k]);
    b.move = true;
    b.g = next.motion;
    b.feed_move = b.g == 1;
    if (b.g == 1) {
      if (next.feed_mm_per_min <= 0.0) {
        return fail(kErrUndefinedFeed, "G1 without a feed: give F in mm/min");
      }
      b.feed_mm_per_min = next.feed_mm_per_min;
    } else {
      b.feed_mm_per_min = rapid_mm_per_min;
    }
    b.duration_s = distance(modal.position, b.to) / (b.feed_mm_per_min / 60.0);
    next.position = b.to;
  }
  modal = next;
  r.block = b;
  return r;
}

// ---- The controller ----

struct SimController::Impl {
  enum class Kind { Block, End, Framing, Duplicate, AfterEnd, Error, System };
  struct Line {
    Kind kind = Kind::Block;
    int size = 0;             // characters it holds in the receive buffer
    std::uint64_t epoch = 0;  // the connection it came on
    double ready_t = 0.0;     // when the executor may have it
    SimBlock block;
    int error = 0;
    std::string text;  // the block, for the executed log
    long seq = 0;      // blocks accepted when it was (1-based)
  };

  explicit Impl(SimControllerConfig c)
      : cfg(checked(std::move(c))),
        drip(cfg.line.protocol == Protocol::Drip),
        xon_xoff(drip && cfg.line.flow == Flow::XonXoff),
        cps(chars_per_s(cfg.line)),
        xoff_at(*cfg.xoff_at),
        xon_at(*cfg.xon_at),
        max_block(max_block_chars(cfg)),
        rng(cfg.seed),
        pty(cfg.line.device) {
    if (::pipe2(wake.data(), O_NONBLOCK | O_CLOEXEC) != 0) {
      throw std::system_error(errno, std::generic_category(), "pipe2");
    }
    log.config = cfg;
    // The injected clock's zero is taken here, not in run(): a caller that advances the clock
    // right after construction must not race the thread that starts run().
    if (cfg.clock) clock_t0 = cfg.clock->now_s();
  }

  ~Impl() {
    ::close(wake[0]);
    ::close(wake[1]);
  }

  // ---- time and output ----

  double now_s() const {
    if (cfg.clock) return cfg.clock->now_s() - clock_t0;
    return std::chrono::duration<double>(Clock::now() - t0).count();
  }

  void event(const std::string& text) {
    if (cfg.on_event) cfg.on_event(text);
  }

  void link_event(double t, const std::string& what) {
    log.link_events.push_back({t, what, pty.device()});
  }

  // Queues bytes for the sender (dropped while the link is down).
  void send(std::string_view bytes) {
    if (pty.is_open()) out.append(bytes);
  }

  void send_flow(bool xoff) {
    send(std::string(1, xoff ? kXoff : kXon));
    ++(xoff ? log.xoff_sent : log.xon_sent);
    told_xoff = xoff;
  }

  // A reply to `line`, unless it came on a connection that has since gone.
  void reply(const Line& line, std::string_view text) {
    if (line.epoch == reply_epoch) send(text);
  }

  void flush_out() {
    if (out.empty() || !pty.is_open()) return;
    const ssize_t n = ::write(pty.master(), out.data(), out.size());
    if (n > 0) {
      out.erase(0, static_cast<std::size_t>(n));
      bytes_sent += static_cast<std::uint64_t>(n);
      if (xoff_at_out) {
        if (*xoff_at_out < static_cast<std::size_t>(n)) {
          xoff_written(now_s());
        } else {
          *xoff_at_out -= static_cast<std::size_t>(n);
        }
      }
    } else if (n < 0 && errno != EAGAIN && errno != EINTR) {
      out.clear();
      xoff_at_out.reset();
    }
  }

  // Drip: the flow control's DC3 has reached the sender, at t. A loop kept from running between
  // the DC3's decision (at xoff_due_t) and its write (a loaded machine) let the sender go on
  // writing meanwhile, which it could not have helped: a UART sends DC3 within a character
  // time. What it wrote meanwhile waits until DC1, as its own flow control would have held it
  // (the same rule as a DC3 found late while reading a burst, in receive()).
  void xoff_written(double t) {
    xoff_at_out.reset();
    if (alarmed || !told_xoff) return;
    const double late_s = t - xoff_due_t;
    if (late_s <= kLateFlowS) return;
    hold_late_written(late_s);
  }

  // The characters the sender wrote while a DC3 was late by late_s (no more than the line could
  // have carried meanwhile: a sender writing faster than the line gets no pass for the excess)
  // obey DC3 until they have all been read.
  void hold_late_written(double late_s) {
    int in_kernel = 0;
    if (::ioctl(pty.master(), FIONREAD, &in_kernel) != 0) in_kernel = 0;
    const std::size_t waiting = backlog.size() + static_cast<std::size_t>(in_kernel);
    const auto could_send = static_cast<std::size_t>(late_s * cps) + 1;
    late_written_end = std::max(late_written_end, taken + std::min(waiting, could_send));
    ++log.xoff_late;
  }

  // ---- connections ----

  void on_slave_events(double t) {
    for (const Pty::SlaveEvent ev : pty.take_slave_events()) {
      if (ev == Pty::SlaveEvent::Opened) {
        if (open_count++ == 0) sender_connected(t);
      } else if (open_count > 0 && --open_count == 0) {
        sender_disconnected(t);
      }
    }
  }

  void sender_connected(double t) {
    ++log.sender_connects;
    link_event(t, "sender_connected");
    ::tcflush(pty.held_slave(), TCIFLUSH);  // nothing stale for the new sender
    out.clear();
    xoff_at_out.reset();
    if (xon_xoff) send_flow(told_xoff);
    if (!drip && cfg.reset_on_open) reset(t, "port_opened");
  }

  void sender_disconnected(double t) {
    ++log.sender_disconnects;
    link_event(t, "sender_disconnected");
    ::tcflush(pty.held_slave(), TCIFLUSH);
    out.clear();
    xoff_at_out.reset();
    ++reply_epoch;
    // What it wrote is in the kernel; read it all now (a read, unlike FIONREAD, also waits for
    // the pty's flip buffer), so that the new sender's bytes, which follow, are told apart.
    for (;;) {
      const ssize_t n = ::read(pty.master(), buf.data(), buf.size());
      if (n <= 0) break;
      backlog.append(buf.data(), static_cast<std::size_t>(n));
    }
    marker = taken + backlog.size();
    if (backlog.empty()) apply_marker();
  }

  // The bytes of a sender that went away have all been read: forget its unfinished line.
  void apply_marker() {
    // grbl's UART knows nothing of the other end: a half line stays in its line buffer, and the
    // next bytes, from whichever connection, complete it (docs/dnc-link.md, "A half line").
    if (drip) discard_partial();
    rx_epoch = reply_epoch;
    blocks_in_epoch = 0;
    marker.reset();
  }

  void discard_partial() {
    if (!partial.empty()) ++log.partial_lines_discarded;
    fill -= static_cast<int>(partial.size());
    partial.clear();
    discarding_long = false;
  }

  void drop_link(double t) {
    drop_pending = false;
    link_event(t, "down");
    pty.close();
    ++log.link_drops;
    event("link down after " + std::to_string(log.blocks_received) + " blocks (fault injection); " +
          cfg.line.device + " back in " + text::sig(cfg.faults.down_s) + " s");
    down_until = t + cfg.faults.down_s;
    out.clear();
    xoff_at_out.reset();
    backlog.clear();  // in flight when the line went down
    late_written_end = 0;
    ++reply_epoch;
    open_count = 0;
    rx_idle = true;
    credit = 0.0;
    apply_marker();
  }

  void restore_link(double t) {
    down_until.reset();
    pty.open();
    link_event(t, "up");
    event(cfg.line.device + " -> " + pty.device() + " again");
  }

  // ---- reception ----

  void receive(double t, bool readable) {
    if (!pty.is_open()) return;
    if (marker && taken >= *marker) apply_marker();
    if (told_xoff && taken < late_written_end) {  // held as the sender would have held it
      credit = 0.0;
      credit_t = t;
      return;
    }
    if (rx_idle) {
      if (!readable && backlog.empty()) return;
      rx_idle = false;  // the first character's frame starts now
      credit = 0.0;
      credit_t = t;
      if (log.bytes_received == 0) log.first_byte_t_s = t;
      return;
    }
    const double credit_0 = credit, credit_t0 = credit_t;  // for each character's own time
    credit += (t - credit_t) * cps;
    credit_t = t;
    if (credit < 1.0) return;
    std::size_t want = std::min(buf.size(), static_cast<std::size_t>(credit));
    if (marker) want = std::min<std::size_t>(want, *marker - taken);
    if (want == 0) {
      apply_marker();
      return;
    }
    std::size_t got = std::min(want, backlog.size());
    if (got > 0) {
      std::copy_n(backlog.begin(), got, buf.begin());
      backlog.erase(0, got);
    }
    if (got < want) {
      const ssize_t n = ::read(pty.master(), buf.data() + got, want - got);
      got += n > 0 ? static_cast<std::size_t>(n) : 0;
    }
    credit -= static_cast<double>(got);
    taken += got;
    for (std::size_t i = 0; i < got && !drop_pending; ++i) {
      if (!drip) {
        on_byte(buf[i], t);
        continue;
      }
      // Drip: the characters of a late wake-up arrived one frame apart, and the controller ran
      // and flowed meanwhile, as a UART's interrupt would have had it (the jitter of this loop is
      // the simulation's, not the controller's).
      const double t_i = std::min(t, credit_t0 + (static_cast<double>(i) + 1.0 - credit_0) / cps);
      execute(t_i);
      on_byte(buf[i], t_i);
      const bool was_xoff = told_xoff;
      flow(t_i);
      const std::uint64_t taken_here = taken - got + i + 1;
      const bool late = t - t_i > kLateFlowS;
      if (told_xoff && !was_xoff && (late || taken_here < late_written_end)) {
        // The DC3 was due at t_i and goes out only now: the sender could not have stopped. What
        // it wrote before it could see the DC3 waits, as its own flow control would have held
        // it, and obeys each DC3 until it has all been read.
        const std::size_t rest = got - i - 1;
        backlog.insert(0, buf.data() + i + 1, rest);
        taken = taken_here;
        credit = 0.0;
        if (late) hold_late_written(t - t_i);
        xoff_due_t = t;  // the rest of its lateness, until the write, is the write's
        break;
      }
    }
    if (drop_pending) {
      drop_link(t);
      if (restart_pending) {
        restart_pending = false;
        reset(t, "power_cycle");  // its banner goes out while the port is closed
      }
      return;
    }
    if (marker && taken >= *marker) apply_marker();
    if (got < want) {  // drained: the line is idle until the next character
      rx_idle = true;
      credit = 0.0;
    }
  }

  void on_byte(char c, double t) {
    ++log.bytes_received;
    log.last_byte_t_s = t;
    if (cfg.line.data_bits == 7) c = static_cast<char>(c & 0x7F);
    if (!drip) {
      if (booting_until) {  // the controller is not listening yet
        ++log.bytes_before_banner;
        return;
      }
      if (c == kGrblStatus) {
        send(status_report(t));
        ++log.status_reports;
        executed_at_last_report = log.blocks_executed;
        return;
      }
      if (c == kGrblHold) return feed_hold(t);
      if (c == kGrblResume) return cycle_start(t);
      if (c == kGrblReset) return reset(t, "soft_reset");
      if (c == '\r') c = '\n';  // grbl ends a line at CR and at LF
    }
    if (alarmed) {
      ++log.bytes_after_alarm;
      if (!drip && c == '\n') {  // grbl: locked out until the alarm is cleared
        send("error:" + std::to_string(kErrAlarmLock) + "\r\n");
      }
      return;
    }
    if (c == '\0') {
      ++log.nul_received;
      return;
    }
    if (discarding_long) {
      if (c == '\n') {
        discarding_long = false;
        ++log.lines_received;
        Line line;
        line.kind = Kind::Error;
        line.error = kErrLineOverflow;
        line.epoch = rx_epoch;
        line.ready_t = t;
        log.errors.push_back({t, log.lines_received, kErrLineOverflow, "",
                              "more than " + std::to_string(max_block) + " characters"});
        ++log.blocks_rejected;
        queue_line(std::move(line), t);
      }
      return;
    }
    if (fill >= cfg.buffer_bytes) {
      raise_alarm(t, "overflow",
                  "a character arrived with the " + std::to_string(cfg.buffer_bytes) +
                      "-byte receive buffer full");
      return;
    }
    partial += c;
    ++fill;
    ++ring_in;
    if (cfg.faults.drop_link_after_chars == static_cast<long>(ring_in) && log.link_drops == 0) {
      drop_pending = true;  // after this character: the rest of the line is lost in the cut
    }
    log.max_buffer_fill = std::max(log.max_buffer_fill, fill);
    if (c == '\n') {
      complete_line(t);
      return;
    }
    if (c != '\r' && ++partial_chars > max_block) {
      if (drip) {
        raise_alarm(t, "block_too_long",
                    "a block longer than " + std::to_string(max_block) + " characters");
      } else {
        fill -= static_cast<int>(partial.size());
        partial.clear();
        partial_chars = 0;
        discarding_long = true;
      }
    }
  }

  void complete_line(double t) {
    ++log.lines_received;
    Line line;
    line.size = static_cast<int>(partial.size());
    line.epoch = rx_epoch;
    line.ready_t = t;
    const std::string text = line_text(partial);
    partial.clear();
    partial_chars = 0;
    if (text.empty() || text == "%") {
      ++log.framing_lines;
      line.kind = Kind::Framing;
      if (text == "%" && !end_received && blocks_in_epoch > 0) {  // else it opens
        line.kind = Kind::End;
        receive_end(t);
      }
      queue_line(std::move(line), t);
      return;
    }
    if (!drip && text[0] == '$') {  // a grbl system command: acted on when it is read
      line.kind = Kind::System;
      line.text = text;
      queue_line(std::move(line), t);
      return;
    }
    if (!drip && grbl_locked) {  // grbl: g-code is locked out until $X (or $H)
      line.kind = Kind::Error;
      line.error = kErrAlarmLock;
      log.errors.push_back(
          {t, log.lines_received, line.error, text, "locked by an alarm: send $X"});
      ++log.blocks_rejected;
      queue_line(std::move(line), t);
      return;
    }
    SimModal modal_after = modal;
    GrblState grbl_after = grbl_state;
    SimParse p;
    if (cfg.dialect == Dialect::grbl) {
      p = parse_grbl(text, grbl_after);
    } else if (!drip && grbl_line_chars(text) > kGrblLineChars) {  // grbl checks this first
      p.error = kErrLineOverflow;
      p.message = std::to_string(grbl_line_chars(text)) + " characters without spaces and " +
                  "comments, more than grbl's " + std::to_string(kGrblLineChars);
    } else {
      DialectState ds;
      const auto v = cfg.dialect ? check_line(*cfg.dialect, text, ds) : std::nullopt;
      if (v) {
        p.error = kErrUnsupported;
        p.message = describe(*v, *cfg.dialect);
      } else {
        p = parse_sim_block(text, modal_after, cfg.rapid_mm_per_min);
        if (p.block.tool_change) p.block.duration_s += cfg.tool_change_s;
      }
    }
    if (p.error != 0) {
      ++log.blocks_rejected;
      if (drip) {
        raise_alarm(t, "bad_block", "'" + text + "': " + p.message);
        return;
      }
      line.kind = Kind::Error;
      line.error = p.error;
      log.errors.push_back({t, log.lines_received, p.error, text, p.message});
      queue_line(std::move(line), t);
      return;
    }
    if (cfg.dialect && !end_received) {
      const int spindle = cfg.dialect == Dialect::grbl ? grbl_after.spindle : modal_after.spindle;
      if (cfg.machine_safety && p.block.feed_move && spindle == 5) {
        raise_alarm(t, "spindle_stopped",
                    "'" + text + "': a feed move with the spindle stopped (machine safety; " +
                        "start it with M3 S… first)");
        return;
      }
      if (p.block.probe_must_touch) {
        raise_alarm(t, "probe_fail",
                    "'" + text + "': the probe found no contact (a simulation has no probe)");
        return;
      }
    }
    if (drip && cfg.skip_duplicate_n && p.block.n && log.last_n && *p.block.n <= *log.last_n) {
      ++log.duplicates_discarded;
      ++blocks_in_epoch;
      line.kind = Kind::Duplicate;
    } else if (end_received) {
      ++log.lines_after_end;
      line.kind = Kind::AfterEnd;
      grbl_state = grbl_after;  // grbl reads on after M2/M30; its verdicts follow its state
    } else {
      modal = modal_after;
      grbl_state = grbl_after;
      line.block = p.block;
      line.text = text;
      accept(text, p.block, t);
      line.seq = log.blocks_received;
    }
    queue_line(std::move(line), t);
  }

  // grbl's verdict on a line (comms/dialect) and what it executes, as a SimBlock.
  SimParse parse_grbl(const std::string& text, GrblState& st) const {
    SimParse r;
    GrblBlock g;
    if (const auto v = check_grbl_line(text, st, &g)) {
      r.error = v->grbl_error;
      r.message = describe(*v, Dialect::grbl);
      return r;
    }
    SimBlock& b = r.block;
    b.n = g.n;
    b.spindle_rpm = g.spindle_rpm;
    b.spindle = g.spindle;
    b.coolant = g.flood;
    b.tool = g.tool;
    b.pause = g.pause;
    b.optional_stop = g.optional_stop;
    b.program_end = g.program_end;
    if (g.dwell_s) {
      b.dwell = true;
      b.duration_s = *g.dwell_s;
    }
    if (g.motion >= 0) {
      b.move = true;
      b.to = g.to;
      b.path_mm = g.path_mm;
      b.g = g.motion >= 380 && g.motion < 390 ? 38 : g.motion / 10;
      b.feed_move = !g.rapid && b.g != 38;  // a probe moves at F but cuts nothing
      b.probe_must_touch = g.motion == 382 || g.motion == 384;
      if (g.rapid) {
        b.feed_mm_per_min = cfg.rapid_mm_per_min;
      } else if (g.inverse_time_min > 0.0) {
        b.feed_mm_per_min = g.path_mm / g.inverse_time_min;
      } else {
        b.feed_mm_per_min = g.feed_mm_per_min;
      }
      b.duration_s += g.inverse_time_min > 0.0 ? g.inverse_time_min * 60.0
                                               : g.path_mm / (b.feed_mm_per_min / 60.0);
    }
    return r;
  }

  void accept(const std::string& text, const SimBlock& b, double t) {
    ++log.blocks_received;
    ++blocks_in_epoch;
    if (b.n) {
      if (!log.first_n) log.first_n = b.n;
      log.last_n = b.n;
    }
    sha.update(text);
    sha.update("\n");
    if (b.program_end) receive_end(t);
    const SimFaults& f = cfg.faults;
    const long k = log.blocks_received;
    if (f.drop_link_after_blocks == k && log.link_drops == 0) drop_pending = true;
    if (f.hold_after_blocks == k && log.holds == 0) {
      ++log.holds;
      hold_until = t + f.hold_s;
      event("holding the sender with DC3 for " + text::sig(f.hold_s) + " s (fault injection)");
    }
    if (f.alarm_after_blocks == k) {
      alarm_pending = true;  // after the line is queued
    }
    if (f.reset_after_blocks == k && log.resets.empty()) reset_pending = true;
    if (f.restart_after_blocks == k && !restarted) {
      restarted = true;
      drop_pending = true;  // the USB link goes with the power: cut after this line
      restart_pending = true;
    }
  }

  void receive_end(double t) {
    end_received = true;
    end_received_t = t;
    log.program_end_received = true;
  }

  void queue_line(Line line, double t) {
    rx.push_back(std::move(line));
    if (!drip) pump_planner(t);
    if (reset_pending) {
      reset_pending = false;
      reset(t, "injected");
    }
    if (alarm_pending) {
      alarm_pending = false;
      raise_alarm(
          t, "injected",
          "alarm after " + std::to_string(log.blocks_received) + " blocks (fault injection)");
    }
  }

  // Ack: answers the lines at the head of the receive buffer, moving blocks into the planner.
  // Blocks in grbl's planner: the queue and the move executing.
  std::size_t planner_count() const { return planner.size() + (busy && !sync_busy ? 1 : 0); }

  // grbl's stepper prepares up to kGrblSegments segments of kGrblSegmentS ahead of the motion
  // and discards a planner block once its last segment is prepared (st_prep_buffer): the blocks
  // counted here (the executing one first, then the queue) have left the planner while their
  // motion still runs. None while held (grbl re-plans a hold's remainder) or idle.
  std::size_t prepared(double t) const {
    if (!busy || sync_busy || held || !current.move) return 0;
    const auto segments = [](double s) {
      return std::max(1, static_cast<int>(std::ceil(s / kGrblSegmentS - 1e-9)));
    };
    int used = segments(busy_end - t);
    if (used > kGrblSegments) return 0;
    std::size_t n = 1;
    for (const Line& l : planner) {
      used += l.block.move ? segments(l.block.duration_s) : 0;
      if (used > kGrblSegments) break;
      ++n;
    }
    return n;
  }
  // Blocks in grbl's planner ring (what Bf: counts and what bounds it): not yet prepared.
  std::size_t planner_held(double t) const { return planner_count() - prepared(t); }
  // grbl's serial ring (serial.c): the protocol loop takes characters out as they come, into its
  // line buffer, except while a complete line waits for room in the planner (or for it to run
  // empty): the bytes behind that line stay in the ring. A line being assembled is not in it.
  int ring_used() const { return rx.empty() ? 0 : std::max(0, fill - rx.front().size); }
  // serial_get_rx_buffer_available(): RX_BUFFER_SIZE − used with the head at or past the tail,
  // one less once the head has wrapped behind it.
  int ring_available() const {
    const int size = cfg.buffer_bytes;
    const auto head = static_cast<int>(ring_in % static_cast<std::uint64_t>(size));
    const auto tail = static_cast<int>((ring_in - static_cast<std::uint64_t>(ring_used())) %
                                       static_cast<std::uint64_t>(size));
    return head >= tail ? size - (head - tail) : tail - head - 1;
  }

  // A grbl `$` line as system.c executes it, when the protocol loop reads it: `$X` clears an
  // alarm lock (and does nothing otherwise), `$10=N` sets the status report mask (Idle or Alarm
  // only: error:8 while the machine runs or holds). Others are not modelled: error:1.
  std::string system_command(const std::string& text, double t) {
    std::string up = text;
    for (char& c : up) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    const auto fail = [&](int code, const std::string& why) {
      log.errors.push_back({t, log.lines_received, code, text, why});
      ++log.blocks_rejected;
      return "error:" + std::to_string(code) + "\r\n";
    };
    if (up == "$X") {
      if (grbl_locked) {
        grbl_locked = false;
        alarm_exit = false;
        ++log.unlocks;
        send("[MSG:Caution: Unlocked]\r\n");
        event("unlocked ($X)");
      }
      return "ok\r\n";
    }
    if (up.rfind("$10=", 0) == 0) {
      int mask = -1;
      const auto r = std::from_chars(up.data() + 4, up.data() + up.size(), mask);
      if (r.ec != std::errc() || r.ptr != up.data() + up.size() || mask < 0 || mask > 255) {
        return fail(3, "$10 takes a number from 0 to 255");
      }
      if (busy || !planner.empty() || held || pausing) {
        return fail(kErrIdle, "$10= while the machine runs or holds (grbl wants Idle)");
      }
      status_mask = mask;
      return "ok\r\n";
    }
    return fail(kErrExpectedLetter, "not a block (only $X and $10= are modelled)");
  }

  void pump_planner(double t) {
    // grbl executes G4 and M0 inside gc_execute_line (mc_dwell, the suspend loop): it reads no
    // further line until they are over.
    // A complete hold suspends grbl's protocol loop (protocol_exec_rt_suspend): no line is read
    // until cycle start or a reset.
    if (hold_complete(t)) return;
    while (!rx.empty() && !alarmed && !(busy && sync_busy)) {
      Line& line = rx.front();
      if (line.kind == Kind::Block && !line.block.move) {
        // grbl synchronises: the block waits for the planner to run empty, then takes effect.
        if (!planner.empty() || busy || held || pausing) return;
        if (!started) {
          started = true;
          log.execution_start_t_s = t;
        }
        fill -= line.size;
        if (line.block.dwell || pauses(line.block) || line.block.tool_change) {
          // answered once the dwell, the stop or the tool change is over
          start_block(line, t);
          sync_busy = true;
          rx.pop_front();
          return;
        }
        current = line.block;
        current_text = line.text;
        current_seq = line.seq;
        block_events(line, t);
        finish(t);
        reply(line, "ok\r\n");
        rx.pop_front();
        continue;
      }
      if (line.kind == Kind::Block || line.kind == Kind::End) {
        if (planner_held(t) >= static_cast<std::size_t>(cfg.planner_blocks)) return;
        line.ready_t = t;
        reply(line, "ok\r\n");
        fill -= line.size;
        planner.push_back(std::move(line));
        log.max_planner_blocks =
            std::max(log.max_planner_blocks, static_cast<long>(planner_held(t)));
      } else if (line.kind == Kind::System) {
        reply(line, system_command(line.text, t));
        fill -= line.size;
      } else {
        reply(line, line.kind == Kind::Error ? "error:" + std::to_string(line.error) + "\r\n"
                                             : std::string("ok\r\n"));
        fill -= line.size;
      }
      rx.pop_front();
    }
  }

  // ---- alarms ----

  void raise_alarm(double t, const std::string& code, const std::string& detail) {
    if (alarmed) return;
    alarmed = true;
    alarm_exit = true;
    alarm_t = t;
    late_written_end = 0;  // what follows is read, and counted as after the alarm
    log.alarms.push_back({t, code, log.blocks_received, log.last_n, detail});
    if (drip) {
      send_flow(true);
      send(std::string(1, kNak));
    } else {
      // grbl's numbers where grbl has the alarm (ALARM:5 probe fail); 9 for an injected one, 1
      // for the simulation's own (overflow, spindle_stopped), which grbl does not raise.
      const char* number = code == "injected" ? "9" : code == "probe_fail" ? "5" : "1";
      send(std::string("ALARM:") + number + "\r\n");
    }
    event("alarm (" + code + "): " + detail + "; stopped");
    busy = false;
    pausing = false;
    rx.clear();
    planner.clear();
    partial.clear();
    partial_chars = 0;
    discarding_long = false;
    fill = 0;
  }

  // ---- grbl's real-time commands and resets ----

  // The position of the move executing at time s, at full speed.
  std::array<double, 3> along(double s) const {
    const double span = cur_t1 - cur_t0;
    const double f = span > 0.0 ? std::clamp((s - cur_t0) / span, 0.0, 1.0) : 1.0;
    std::array<double, 3> p{};
    for (std::size_t k = 0; k < 3; ++k) p[k] = cur_from[k] + f * (current.to[k] - cur_from[k]);
    return p;
  }

  std::array<double, 3> position_at(double t) const {
    if (!busy || !current.move) return position;
    if (held && !hold_to_end) {
      if (t >= hold_done_t) return hold_pos;
      // Decelerating at a = v/τ: after σ the move has covered v·(σ − σ²/2τ), what full speed
      // covers in σ − σ²/2τ.
      const double sigma = std::max(0.0, t - hold_t), tau = hold_done_t - hold_t;
      return along(hold_t + sigma - sigma * sigma / (2.0 * tau));
    }
    return along(t);
  }

  // A hold has brought the motion to rest (grbl's SUSPEND_HOLD_COMPLETE): Hold:0.
  bool hold_complete(double t) const { return held && t >= hold_done_t; }

  // The machine moves at t: a move executing, not yet at rest in a hold. A reset now is a reset
  // in motion (grbl's mc_reset: ALARM:3).
  bool moving(double t) const {
    return busy && current.move && !sync_busy && t < busy_end && !hold_complete(t);
  }

  // grbl's work coordinate offset (report.c): the coordinate system in use, G92 and the tool
  // length offset on Z. Zero without the grbl dialect (the transport parser has no offsets).
  std::array<double, 3> wco() const {
    std::array<double, 3> w{};
    if (cfg.dialect != Dialect::grbl) return w;
    const auto& cs = grbl_state.coord_system[static_cast<std::size_t>(grbl_state.coord_select)];
    for (std::size_t k = 0; k < 3; ++k) w[k] = cs[k] + grbl_state.g92[k];
    w[2] += grbl_state.tool_length_mm;
    return w;
  }

  std::string status_report(double t) {
    std::string s = "<";
    if (alarmed || grbl_locked) {
      s += "Alarm";
    } else if (held) {
      s += hold_complete(t) ? "Hold:0" : "Hold:1";  // 1: decelerating; 0: at rest, can resume
    } else if (busy && pausing && busy_end <= t) {
      s += "Hold:0";
    } else {
      s += busy || !planner.empty() ? "Run" : "Idle";
    }
    // $10 bit 0: MPos, else WPos (the machine position less the work offset); bit 1: Bf:.
    auto p = position_at(t);
    const auto w = wco();
    const bool mpos = (status_mask & 1) != 0;
    if (!mpos) {
      for (std::size_t k = 0; k < 3; ++k) p[k] -= w[k];
    }
    std::array<char, 96> text{};
    std::snprintf(text.data(), text.size(), "|%s:%.3f,%.3f,%.3f", mpos ? "MPos" : "WPos", p[0],
                  p[1], p[2]);
    s += text.data();
    if ((status_mask & 2) != 0) {
      std::snprintf(text.data(), text.size(), "|Bf:%d,%d",
                    cfg.planner_blocks - static_cast<int>(planner_held(t)), ring_available());
      s += text.data();
    }
    // grbl reports the line number of the planner's current block: the first not prepared.
    if (cfg.report_line_numbers && planner_held(t) > 0) {
      const std::size_t k = prepared(t);
      const bool executing = busy && !sync_busy;
      const SimBlock& b = k == 0 && executing ? current : planner[k - (executing ? 1 : 0)].block;
      if (b.n && *b.n > 0) s += "|Ln:" + std::to_string(*b.n);
    }
    // FS: the feed now (falling during a hold's deceleration) and the spindle's speed (0 when
    // stopped: sys.spindle_speed).
    double feed = 0.0;
    if (busy && current.move && !sync_busy && t < busy_end && !held) {
      feed = current.feed_mm_per_min;
    } else if (held && !hold_complete(t) && busy && current.move) {
      feed = hold_to_end ? current.feed_mm_per_min
                         : current.feed_mm_per_min * (1.0 - (t - hold_t) / (hold_done_t - hold_t));
    }
    std::snprintf(text.data(), text.size(), "|FS:%.0f,%.0f", feed,
                  exec_spindle != 5 ? exec_rpm : 0.0);
    s += text.data();
    // WCO: on the first report after a reset, then every 10th (idle) or 30th (busy), as grbl.
    if (wco_countdown > 0) {
      --wco_countdown;
    } else {
      wco_countdown = busy || held ? 29 : 9;
      std::snprintf(text.data(), text.size(), "|WCO:%.3f,%.3f,%.3f", w[0], w[1], w[2]);
      s += text.data();
    }
    return s + ">\r\n";
  }

  // `!`: grbl decelerates a move along its path (Hold:1) and holds at rest (Hold:0); idle, or
  // in a dwell, the hold is complete at once. This model slows down within the move executing:
  // a move that cannot stop before its end runs to its end at its feed and holds there (grbl
  // would decelerate through the next blocks, a difference that only moves where it stops).
  void feed_hold(double t) {
    ++log.feed_holds;
    if (held || alarmed || grbl_locked) return;  // grbl ignores a hold in alarm
    const bool was_moving = moving(t);
    held = true;
    hold_t = t;
    hold_to_end = false;
    hold_done_t = t;
    if (was_moving) {
      const double v_mm_per_s = current.feed_mm_per_min / 60.0;
      const double tau = v_mm_per_s / cfg.hold_accel_mm_per_s2;  // time to stop
      const double left_s = busy_end - t;                        // at full speed
      if (tau / 2.0 >= left_s) {
        hold_to_end = true;
        hold_done_t = busy_end;
      } else {
        hold_done_t = t + tau;
        hold_pos = along(t + tau / 2.0);  // stopping covers what full speed covers in τ/2
        remaining_s = left_s - tau / 2.0;
      }
    } else {
      hold_pos = position_at(t);
      remaining_s = busy ? std::max(0.0, busy_end - t) : 0.0;
    }
    log.events.push_back({t, current_seq, current.n, "feed_hold", 0.0});  // the hold begins
    event("feed hold");
  }

  void cycle_start(double t) {
    if (pausing && !held) {  // M0: the program goes on
      ++log.cycle_starts;
      pausing = false;
      busy_end = cur_t1 = std::max(busy_end, t);
      log.events.push_back({t, current_seq, current.n, "resume", 0.0});
      event("cycle start: resumed after the program stop");
      return;
    }
    if (!hold_complete(t)) return;  // grbl resumes a hold only once it is complete
    ++log.cycle_starts;
    held = false;
    if (busy && !hold_to_end) {
      cur_from = hold_pos;
      cur_t0 = t;
      busy_end = cur_t1 = t + remaining_s;
    } else if (!busy) {
      free_at = std::max(free_at, t);
    }
    hold_to_end = false;
    event("cycle start");
    pump_planner(t);
  }

  // A controller reset (soft reset 0x18, the injected fault, the port opened with reset_on_open,
  // a power cycle): the motion stops where it is, the queue is lost, the spindle and coolant
  // stop (grbl's mc_reset), the parser returns to its power-on modes (gc_init: the coordinate
  // systems are kept, G92 and the tool length offset are not) at the machine's position, which
  // a power-up (power_cycle, port_opened: a hardware reset) restarts at 0.
  void reset(double t, const std::string& cause) {
    const bool power_up = cause == "power_cycle" || cause == "port_opened";
    SimReset r;
    r.t_s = t;
    r.cause = cause;
    r.in_motion = moving(t) && !power_up;
    if (busy) {
      position = position_at(t);
      r.aborted = current_text;
    }
    r.position = position;
    for (const Line& l : planner) r.blocks_lost += l.kind == Kind::Block ? 1 : 0;
    for (const Line& l : rx) r.blocks_lost += l.kind == Kind::Block ? 1 : 0;
    r.executed_at_last_report = executed_at_last_report;
    const long seq = current_seq;
    busy = sync_busy = held = pausing = hold_to_end = false;
    rx.clear();
    planner.clear();
    partial.clear();
    partial_chars = 0;
    discarding_long = false;
    fill = 0;
    free_at = t;
    if (exec_spindle != 5) log.events.push_back({t, seq, std::nullopt, "spindle_stop", 0.0});
    if (exec_coolant) log.events.push_back({t, seq, std::nullopt, "coolant_off", 0.0});
    exec_spindle = 5;
    exec_coolant = false;
    log.resets.push_back(r);
    event("reset (" + cause + ")" + (r.aborted ? ": aborted '" + *r.aborted + "'" : "") + ", " +
          std::to_string(r.blocks_lost) + " queued blocks lost, " +
          (power_up ? "position restarts at 0" : "position kept") +
          (r.in_motion && !drip ? "; in motion: ALARM:3, locked until $X" : ""));
    if (drip) {  // a Fanuc-type control: DC3 then SYN, ready again at low water
      send_flow(true);
      send(std::string(1, kSyn));
      return;
    }
    if (power_up) position = {0.0, 0.0, 0.0};
    GrblState fresh;  // gc_init, then gc_sync_position
    fresh.coord_system = grbl_state.coord_system;
    fresh.position = position;
    grbl_state = fresh;
    modal = SimModal{};
    modal.position = position;
    end_received = false;
    blocks_in_epoch = 0;
    wco_countdown = 0;
    if (power_up) {
      alarmed = grbl_locked = alarm_exit = false;  // power-on: Idle (no homing lock modelled)
    } else if (alarmed) {
      alarmed = false;  // an alarm outlives a reset: locked until $X
      grbl_locked = true;
    } else if (r.in_motion) {
      send("ALARM:3\r\n");  // grbl: reset while in motion, position may be lost
      grbl_locked = true;
    }
    booting_until = t + cfg.boot_s;
  }

  void boot_done() {
    booting_until.reset();
    // A banner sent while the port is closed, or before a sender opened it, is lost.
    if (!pty.is_open() || open_count == 0) ++log.banners_lost;
    send(std::string("\r\n") + kGrblBanner + "\r\n");
    if (grbl_locked) send("[MSG:'$H'|'$X' to unlock]\r\n");
    ++log.banners_sent;
  }

  // ---- execution ----

  bool primed(double t) const {
    const auto& q = drip ? rx : planner;
    const bool has_block = std::any_of(q.begin(), q.end(), [](const Line& l) {
      return l.kind == Kind::Block || l.kind == Kind::End;
    });
    if (!has_block) return false;
    if (!drip) return true;  // grbl starts a cycle as soon as a move is planned
    if (end_received || fill >= xoff_at) return true;
    if (!drip && planner.size() >= static_cast<std::size_t>(cfg.planner_blocks)) return true;
    return t - log.last_byte_t_s >= cfg.prime_idle_s;
  }

  void execute(double t) {
    if (alarmed) return;
    if (!started) {
      if (!primed(t)) return;
      started = true;
      free_at = t;
      log.execution_start_t_s = t;
    }
    if (!drip) pump_planner(t);
    for (;;) {
      if (busy) {
        // held: at rest mid-move; a hold that runs to the block's end lets the block finish
        if ((held && !hold_to_end) || busy_end > t || pausing) return;
        const bool answer = sync_busy;
        finish(busy_end);
        if (answer) send("ok\r\n");  // a dwell is answered when it is over
        if (!drip) pump_planner(busy_end);
        if (busy) continue;
      }
      if (held) return;
      auto& q = drip ? rx : planner;
      if (q.empty()) return;
      Line line = std::move(q.front());
      q.pop_front();
      if (drip) fill -= line.size;
      const double start = std::max(free_at, line.ready_t);
      if (moved && start - free_at > cfg.underrun_grace_s &&
          (!end_received || free_at < end_received_t)) {
        add_underrun(free_at, start);
      }
      free_at = start;
      if (line.kind == Kind::Block) {
        start_block(line, start);
      } else if (line.kind == Kind::End) {
        end_executed(start);
      }
    }
  }

  void start_block(const Line& line, double start) {
    busy = true;
    sync_busy = false;
    moved = moved || line.block.move;
    busy_end = start + line.block.duration_s;
    current = line.block;
    current_text = line.text;
    current_seq = line.seq;
    cur_from = position;
    cur_t0 = start;
    cur_t1 = busy_end;
    block_events(line, start);
  }

  // M0, or M1 with the optional-stop switch on (grbl ignores M1: "not supported" in gcode.c).
  bool pauses(const SimBlock& b) const {
    return b.pause || (b.optional_stop && cfg.optional_stop && cfg.dialect != Dialect::grbl);
  }

  // The events a block executes before its motion (and, for a stop, after it).
  void block_events(const Line& line, double t) {
    const SimBlock& b = line.block;
    const auto add = [&](const char* kind, double value, double at) {
      log.events.push_back({at, line.seq, b.n, kind, value});
    };
    if (b.spindle_rpm) {
      exec_rpm = *b.spindle_rpm;
      add("speed", exec_rpm, t);
    }
    if (b.tool) add("tool", *b.tool, t);
    if (b.tool_change) add("tool_change", cfg.tool_change_s, t);
    if (b.spindle && *b.spindle != exec_spindle) {
      exec_spindle = *b.spindle;
      add(exec_spindle == 3   ? "spindle_cw"
          : exec_spindle == 4 ? "spindle_ccw"
                              : "spindle_stop",
          exec_rpm, t);
    }
    if (b.coolant) {
      exec_coolant = *b.coolant;
      add(*b.coolant ? "coolant_on" : "coolant_off", 0.0, t);
    }
    if (b.dwell) add("dwell", b.duration_s, t);
    if (pauses(b)) {
      pausing = true;
      add("pause", 0.0, busy_end);
      event("program stop (M" + std::string(b.pause ? "0" : "1") + "): waiting for cycle start");
    } else if (b.optional_stop) {
      add("optional_stop_skipped", 0.0, busy_end);
    }
  }

  void finish(double t) {
    busy = false;
    sync_busy = false;
    free_at = t;
    ++log.blocks_executed;
    log.executed.push_back({current_seq, current.n, current_text, t});
    if (current.n) last_exec_n = current.n;
    if (current.program_end) {
      if (exec_spindle != 5) log.events.push_back({t, current_seq, current.n, "spindle_stop", 0.0});
      exec_spindle = 5;
      log.events.push_back({t, current_seq, current.n, "program_end", 0.0});
    }
    if (current.move) {
      log.path_length_mm +=
          current.path_mm > 0.0 ? current.path_mm : distance(position, current.to);
      position = current.to;
      log.moves.push_back(
          {current.to, current.feed_mm_per_min, current.g, current.n, t, current_seq});
    }
    if (current.program_end) end_executed(t);
  }

  void end_executed(double t) {
    if (log.program_end_executed) return;
    log.program_end_executed = true;
    log.execution_end_t_s = t;
    event("program end executed");
  }

  void add_underrun(double from, double to) {
    ++log.underruns;
    log.dwell_s += to - from;
    log.underrun_events.push_back({from, log.blocks_executed, last_exec_n, to - from});
  }

  // ---- faults ----

  double uniform(double lo, double hi) { return std::uniform_real_distribution<>(lo, hi)(rng); }

  void faults(double t) {
    const SimFaults& f = cfg.faults;
    if (hold_until && t >= *hold_until) hold_until.reset();
    if (f.xoff_storm && pty.is_open()) {
      if (storm_until && t >= *storm_until) {
        storm_until.reset();
        next_storm = t + uniform(0.05, 0.5);
      }
      if (!storm_until && t >= next_storm) {
        const bool receiving = log.bytes_received > 0 && t - log.last_byte_t_s < kReceivingS;
        if (receiving && !end_received && !alarmed) {
          storm_until = t + uniform(0.02, 0.3);
          ++log.xoff_storms;
        } else {
          next_storm = t + uniform(0.05, 0.5);
        }
      }
    }
    while (f.noise_bytes_per_s > 0.0 && open_count > 0 && t >= next_noise) {
      const std::size_t n = drip ? static_cast<std::size_t>(uniform(1.0, 5.0))
                                 : static_cast<std::size_t>(uniform(4.0, 25.0));
      if (out.size() < kMaxOutQueue) {
        const std::string noise = drip ? noise_bytes(n) : noise_line(n);
        send(noise);
        log.noise_bytes_sent += noise.size();
      }
      // From the last due time, not from now: a late loop catches up instead of thinning out.
      next_noise = std::max(next_noise, t - 1.0) +
                   std::exponential_distribution<>(f.noise_bytes_per_s /
                                                   static_cast<double>(n + (drip ? 0 : 2)))(rng);
    }
  }

  // Random bytes that are none of DC1, DC3, NAK, SYN, LF, CR (7 bits on a 7-bit line).
  std::string noise_bytes(std::size_t n) {
    std::string s;
    const int top = cfg.line.data_bits == 7 ? 0x7F : 0xFF;
    while (s.size() < n) {
      const char c = static_cast<char>(std::uniform_int_distribution<>(0, top)(rng));
      if (c != kXon && c != kXoff && c != kNak && c != kSyn && c != '\n' && c != '\r') s += c;
    }
    return s;
  }

  // A printable garbage line (with CR LF) that is no ok, error or ALARM line.
  std::string noise_line(std::size_t n) {
    static constexpr char kChars[] =
        "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789 :<>|.,=[]-";
    for (;;) {
      std::string s;
      while (s.size() < n) {
        s += kChars[std::uniform_int_distribution<std::size_t>(0, sizeof kChars - 2)(rng)];
      }
      std::string lower = s;
      for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      if (lower.rfind("ok", 0) != 0 && lower.rfind("error", 0) != 0 &&
          lower.rfind("alarm", 0) != 0) {
        return s + "\r\n";
      }
    }
  }

  // The flow control at t: DC3 at high water (and in storms and holds), DC1 at low water.
  void flow(double t) {
    if (!xon_xoff || !pty.is_open() || alarmed) return;
    if (!fill_xoff && fill >= xoff_at) fill_xoff = true;
    if (fill_xoff && fill <= xon_at) fill_xoff = false;
    const bool want = fill_xoff || storm_until.has_value() || hold_until.has_value();
    if (want == told_xoff) return;
    send_flow(want);
    xoff_at_out.reset();
    if (want && !out.empty()) {  // its write is timed (flush_out)
      xoff_at_out = out.size() - 1;
      xoff_due_t = t;
    }
  }

  // ---- the loop ----

  // Seconds until something is due, at most kLoopPeriodS.
  double timeout(double t) const {
    double due = t + kLoopPeriodS;
    if (pty.is_open() && !rx_idle) due = std::min(due, credit_t + (1.0 - credit) / cps);
    if (pty.is_open() && rx_idle && !backlog.empty()) due = t;
    if (busy && !held) due = std::min(due, busy_end);
    if (booting_until) due = std::min(due, *booting_until);
    const double prime_t = log.last_byte_t_s + cfg.prime_idle_s;
    if (!started && prime_t > t) due = std::min(due, prime_t);
    if (down_until) due = std::min(due, *down_until);
    return std::max(0.0, due - t);
  }

  bool should_exit(double t) const {
    if (stop.load()) return true;
    if (!cfg.exit_at_end) return false;
    if (alarmed || alarm_exit) return t - alarm_t >= cfg.alarm_linger_s;
    // ack: the sender polls status until it has seen the end executed; wait for it to leave
    if (!drip && open_count > 0) return false;
    return log.program_end_executed && t - log.last_byte_t_s >= cfg.exit_quiet_s && out.empty();
  }

  void run() {
    t0 = Clock::now();
    link_event(0.0, "created");  // DC1 (ready) goes to each sender as it connects
    next_storm = uniform(0.05, 0.5);
    if (cfg.faults.noise_bytes_per_s > 0.0) {
      next_noise = std::exponential_distribution<>(cfg.faults.noise_bytes_per_s)(rng);
    }
    bool readable = false;
    for (;;) {
      double t = now_s();
      if (should_exit(t)) break;
      if (down_until && t >= *down_until) restore_link(t);
      if (booting_until && t >= *booting_until) boot_done();
      if (cycle_start_request.exchange(false)) cycle_start(t);
      if (pty.is_open()) on_slave_events(t);
      receive(t, readable);
      flow(t);  // DC3 when the fill reached high water, before a block starting now frees room
      execute(t);
      faults(t);
      flow(t);
      publish();  // before the bytes go out, so a sender reading them sees this state
      flush_out();

      std::array<pollfd, 3> fds{};
      fds[0] = {wake[0], POLLIN, 0};
      nfds_t nfds = 1;
      if (pty.is_open()) {
        short ev = 0;
        if (rx_idle) ev |= POLLIN;
        if (!out.empty()) ev |= POLLOUT;
        fds[1] = {pty.watch_fd(), POLLIN, 0};
        fds[2] = {pty.master(), ev, 0};
        nfds = 3;
      }
      t = now_s();
      const double wait = timeout(t);
      timespec ts{};
      ts.tv_sec = static_cast<time_t>(wait);
      ts.tv_nsec = static_cast<long>((wait - static_cast<double>(ts.tv_sec)) * 1e9);
      readable = false;
      if (::ppoll(fds.data(), nfds, &ts, nullptr) > 0) {
        if (fds[0].revents & POLLIN) {
          std::array<char, 64> drain{};
          while (::read(wake[0], drain.data(), drain.size()) > 0) {
          }
        }
        readable = nfds == 3 && (fds[2].revents & POLLIN) != 0;
      }
    }
    finalize(now_s());
  }

  void finalize(double t) {
    if (stop.load()) {
      log.stop_reason = "stop_requested";
    } else {
      log.stop_reason = alarmed || alarm_exit ? "alarm" : "program_end";
    }
    const auto& q = drip ? rx : planner;
    if (moved && !alarmed && !busy && q.empty() && !end_received &&
        t - free_at > cfg.underrun_grace_s) {
      add_underrun(free_at, t);  // still dry when stopped
    }
    log.duration_s = t;
    log.program_sha256 = sha.hex();
    if (log.bytes_received > 0) {
      log.reception_s = log.last_byte_t_s - log.first_byte_t_s;
      log.bytes_per_s = static_cast<double>(log.bytes_received) / log.reception_s;
      log.link_use = log.bytes_per_s / cps;
    }
    pty.close();
    publish();
  }

  void publish() {
    live_bytes.store(log.bytes_received, std::memory_order_relaxed);
    live_blocks.store(log.blocks_received, std::memory_order_relaxed);
    live_executed.store(log.blocks_executed, std::memory_order_relaxed);
    live_drops.store(log.link_drops, std::memory_order_relaxed);
    live_alarms.store(static_cast<long>(log.alarms.size()), std::memory_order_relaxed);
    live_fill.store(fill, std::memory_order_relaxed);
    live_end_received.store(end_received, std::memory_order_relaxed);
    live_noise.store(log.noise_bytes_sent, std::memory_order_relaxed);
    live_sent.store(bytes_sent, std::memory_order_relaxed);
    live_t.store(now_s(), std::memory_order_relaxed);
    live_resets.store(static_cast<long>(log.resets.size()), std::memory_order_relaxed);
    const std::array<double, 3> p = position_at(now_s());
    for (std::size_t k = 0; k < 3; ++k) live_position[k].store(p[k], std::memory_order_relaxed);
    live_end_executed.store(log.program_end_executed, std::memory_order_release);
  }

  const SimControllerConfig cfg;
  const bool drip, xon_xoff;
  const double cps;
  const int xoff_at, xon_at, max_block;
  std::mt19937_64 rng;
  Pty pty;
  std::array<int, 2> wake{-1, -1};
  std::atomic<bool> stop{false};
  std::atomic<bool> cycle_start_request{false};
  Clock::time_point t0 = Clock::now();
  double clock_t0 = 0.0;
  SimLog log;
  std::uint64_t bytes_sent = 0;
  Sha256 sha;
  std::string out;

  // connection
  int open_count = 0;
  std::uint64_t rx_epoch = 0, reply_epoch = 0;
  std::optional<std::uint64_t> marker;  // bytes taken when the last sender's bytes are all read
  std::optional<double> down_until;
  bool drop_pending = false, alarm_pending = false, reset_pending = false;
  bool restart_pending = false, restarted = false;

  // wire
  std::array<char, 4096> buf{};
  bool rx_idle = true;
  double credit = 0.0, credit_t = 0.0;
  std::uint64_t taken = 0;
  std::string backlog;  // read off the pty ahead of the wire (a sender that left), taken first

  // receive buffer and parser
  std::string partial;
  int partial_chars = 0;  // without CR
  bool discarding_long = false;
  int fill = 0;
  std::uint64_t ring_in = 0;  // ack: characters put into grbl's serial ring, ever
  std::deque<Line> rx, planner;
  SimModal modal;
  GrblState grbl_state;
  bool end_received = false;
  double end_received_t = 0.0;
  long blocks_in_epoch = 0;

  // flow and faults
  bool fill_xoff = false, told_xoff = false;
  // Drip: the end (in bytes taken) of what the sender wrote before it could see a DC3 the loop
  // sent late; up to there the wire obeys DC3 as the sender would have.
  std::uint64_t late_written_end = 0;
  // Drip: where in `out` the last DC3 waits to be written, and when it was due.
  std::optional<std::size_t> xoff_at_out;
  double xoff_due_t = 0.0;
  std::optional<double> storm_until, hold_until;
  double next_storm = 0.0, next_noise = 0.0;
  bool alarmed = false;
  bool alarm_exit = false;  // with exit_at_end: an alarm was raised and not unlocked since
  double alarm_t = 0.0;
  std::optional<long> executed_at_last_report;  // blocks executed when the last report was sent

  // executor
  bool started = false, busy = false, moved = false;  // moved: a move has started
  double busy_end = 0.0, free_at = 0.0;
  SimBlock current;
  std::array<double, 3> position{0.0, 0.0, 0.0};
  std::optional<long> last_exec_n;
  std::string current_text;
  long current_seq = 0;
  std::array<double, 3> cur_from{}, hold_pos{};  // the move executing: from, and where held
  double cur_t0 = 0.0, cur_t1 = 0.0, remaining_s = 0.0;
  bool sync_busy = false;    // ack: the executor runs a dwell outside the planner
  bool held = false;         // ack: feed hold (!), decelerating or at rest
  bool hold_to_end = false;  // the held move cannot stop before its end: it runs to it
  double hold_t = 0.0, hold_done_t = 0.0;  // the `!`, and when the motion is at rest
  bool pausing = false;                    // a program stop (M0) waits for cycle start
  int exec_spindle = 5;                    // the spindle as executed: 3, 4 or 5
  bool exec_coolant = false;
  double exec_rpm = 0.0;
  bool grbl_locked = false;           // ack: alarm state after a reset in motion, until $X
  int status_mask = cfg.status_mask;  // grbl's $10
  int wco_countdown = 0;              // status reports until the next WCO: field
  std::optional<double> booting_until;

  // live view
  std::atomic<std::uint64_t> live_bytes{0};
  std::atomic<long> live_blocks{0}, live_executed{0}, live_drops{0}, live_alarms{0};
  std::atomic<int> live_fill{0};
  std::atomic<bool> live_end_received{false}, live_end_executed{false};
  std::atomic<std::uint64_t> live_noise{0}, live_sent{0};
  std::atomic<double> live_t{0.0};
  std::atomic<long> live_resets{0};
  std::array<std::atomic<double>, 3> live_position{};
};

SimController::SimController(SimControllerConfig config)
    : impl_(std::make_unique<Impl>(std::move(config))) {}

SimController::~SimController() = default;

const SimControllerConfig& SimController::config() const {
  return impl_->cfg;
}

std::string SimController::device() const {
  return impl_->pty.device();
}

void SimController::run() {
  impl_->run();
}

void SimController::request_stop() noexcept {
  impl_->stop.store(true);
  const char c = 's';
  [[maybe_unused]] const ssize_t n = ::write(impl_->wake[1], &c, 1);
}

void SimController::cycle_start() noexcept {
  impl_->cycle_start_request.store(true);
  const char c = 'c';
  [[maybe_unused]] const ssize_t n = ::write(impl_->wake[1], &c, 1);
}

SimProgress SimController::progress() const noexcept {
  SimProgress p;
  p.program_end_executed = impl_->live_end_executed.load(std::memory_order_acquire);
  p.bytes_received = impl_->live_bytes.load(std::memory_order_relaxed);
  p.blocks_received = impl_->live_blocks.load(std::memory_order_relaxed);
  p.blocks_executed = impl_->live_executed.load(std::memory_order_relaxed);
  p.link_drops = impl_->live_drops.load(std::memory_order_relaxed);
  p.alarms = impl_->live_alarms.load(std::memory_order_relaxed);
  p.buffer_fill = impl_->live_fill.load(std::memory_order_relaxed);
  p.program_end_received = impl_->live_end_received.load(std::memory_order_relaxed);
  p.noise_bytes_sent = impl_->live_noise.load(std::memory_order_relaxed);
  p.bytes_sent = impl_->live_sent.load(std::memory_order_relaxed);
  p.t_s = impl_->live_t.load(std::memory_order_relaxed);
  p.resets = impl_->live_resets.load(std::memory_order_relaxed);
  for (std::size_t k = 0; k < 3; ++k) {
    p.position_mm[k] = impl_->live_position[k].load(std::memory_order_relaxed);
  }
  return p;
}

const SimLog& SimController::log() const {
  return impl_->log;
}

// ---- JSON ----

namespace {

Json optional_json(const std::optional<long>& v) {
  return v ? Json(*v) : Json(nullptr);
}

}  // namespace

Json settings_json(const SimControllerConfig& c) {
  const SimFaults& f = c.faults;
  return Json{{"link", c.line.device},
              {"baud", c.line.baud},
              {"frame", frame_text(c.line)},
              {"bits_per_char", bits_per_char(c.line)},
              {"chars_per_s", chars_per_s(c.line)},
              {"flow", to_string(c.line.flow)},
              {"protocol", to_string(c.line.protocol)},
              {"eob", c.line.eob == EndOfBlock::CrLf ? "crlf" : "lf"},
              {"buffer_bytes", c.buffer_bytes},
              {"xoff_at", c.xoff_at.value_or(0)},
              {"xon_at", c.xon_at.value_or(0)},
              {"max_block_chars", max_block_chars(c)},
              {"planner_blocks", c.planner_blocks},
              {"rapid_mm_per_min", c.rapid_mm_per_min},
              {"prime_idle_s", c.prime_idle_s},
              {"underrun_grace_s", c.underrun_grace_s},
              {"exit_at_end", c.exit_at_end},
              {"seed", c.seed},
              {"skip_duplicate_n", c.skip_duplicate_n},
              {"reset_on_open", c.reset_on_open},
              {"boot_s", c.boot_s},
              {"report_line_numbers", c.report_line_numbers},
              {"status_mask", c.status_mask},
              {"hold_accel_mm_per_s2", c.hold_accel_mm_per_s2},
              {"dialect", c.dialect ? Json(to_string(*c.dialect)) : Json(nullptr)},
              {"machine_safety", c.machine_safety},
              {"tool_change_s", c.tool_change_s},
              {"optional_stop", c.optional_stop},
              {"clock", c.clock ? "injected" : "wall"},
              {"faults",
               {{"drop_link_after_blocks", f.drop_link_after_blocks},
                {"drop_link_after_chars", f.drop_link_after_chars},
                {"down_s", f.down_s},
                {"xoff_storm", f.xoff_storm},
                {"hold_after_blocks", f.hold_after_blocks},
                {"hold_s", f.hold_s},
                {"noise_bytes_per_s", f.noise_bytes_per_s},
                {"alarm_after_blocks", f.alarm_after_blocks},
                {"reset_after_blocks", f.reset_after_blocks},
                {"restart_after_blocks", f.restart_after_blocks}}}};
}

Json to_json(const SimLog& l) {
  Json moves = Json::array();
  for (const SimMove& m : l.moves) {
    moves.push_back({{"p", {m.p[0], m.p[1], m.p[2]}},
                     {"feed_mm_per_min", m.feed_mm_per_min},
                     {"g", m.g},
                     {"n", optional_json(m.n)},
                     {"t_s", m.t_s},
                     {"seq", m.seq}});
  }
  Json underruns = Json::array();
  for (const SimUnderrun& u : l.underrun_events) {
    underruns.push_back(
        {{"t_s", u.t_s}, {"block", u.block}, {"n", optional_json(u.n)}, {"dwell_s", u.dwell_s}});
  }
  Json alarms = Json::array();
  for (const SimAlarm& a : l.alarms) {
    alarms.push_back({{"t_s", a.t_s},
                      {"code", a.code},
                      {"block", a.block},
                      {"n", optional_json(a.n)},
                      {"detail", a.detail}});
  }
  Json errors = Json::array();
  for (const SimErrorReply& e : l.errors) {
    errors.push_back({{"t_s", e.t_s},
                      {"line", e.line},
                      {"code", e.code},
                      {"text", e.text},
                      {"message", e.message}});
  }
  Json executed = Json::array();
  for (const SimExecuted& e : l.executed) {
    executed.push_back(
        {{"seq", e.seq}, {"n", optional_json(e.n)}, {"text", e.text}, {"t_s", e.t_s}});
  }
  Json events = Json::array();
  for (const SimEvent& e : l.events) {
    events.push_back({{"t_s", e.t_s},
                      {"seq", e.seq},
                      {"n", optional_json(e.n)},
                      {"kind", e.kind},
                      {"value", e.value}});
  }
  Json resets = Json::array();
  for (const SimReset& r : l.resets) {
    resets.push_back({{"t_s", r.t_s},
                      {"cause", r.cause},
                      {"in_motion", r.in_motion},
                      {"aborted", r.aborted ? Json(*r.aborted) : Json(nullptr)},
                      {"position", {r.position[0], r.position[1], r.position[2]}},
                      {"blocks_lost", r.blocks_lost},
                      {"executed_at_last_report", optional_json(r.executed_at_last_report)}});
  }
  Json links = Json::array();
  for (const SimLinkEvent& e : l.link_events) {
    links.push_back({{"t_s", e.t_s}, {"event", e.event}, {"device", e.device}});
  }
  return Json{{"settings", settings_json(l.config)},
              {"stop_reason", l.stop_reason},
              {"duration_s", l.duration_s},
              {"lines_received", l.lines_received},
              {"blocks_received", l.blocks_received},
              {"blocks_executed", l.blocks_executed},
              {"framing_lines", l.framing_lines},
              {"duplicates_discarded", l.duplicates_discarded},
              {"blocks_rejected", l.blocks_rejected},
              {"lines_after_end", l.lines_after_end},
              {"partial_lines_discarded", l.partial_lines_discarded},
              {"program_sha256", l.program_sha256},
              {"program_end_received", l.program_end_received},
              {"program_end_executed", l.program_end_executed},
              {"first_n", optional_json(l.first_n)},
              {"last_n", optional_json(l.last_n)},
              {"bytes_received", l.bytes_received},
              {"nul_received", l.nul_received},
              {"bytes_after_alarm", l.bytes_after_alarm},
              {"first_byte_t_s", l.first_byte_t_s},
              {"last_byte_t_s", l.last_byte_t_s},
              {"reception_s", l.reception_s},
              {"bytes_per_s", l.bytes_per_s},
              {"chars_per_s", chars_per_s(l.config.line)},
              {"link_use", l.link_use},
              {"buffer_bytes", l.config.buffer_bytes},
              {"max_buffer_fill", l.max_buffer_fill},
              {"max_planner_blocks", l.max_planner_blocks},
              {"execution_start_t_s", l.execution_start_t_s},
              {"execution_end_t_s", l.execution_end_t_s},
              {"underruns", l.underruns},
              {"underrun_events", underruns},
              {"dwell_s", l.dwell_s},
              {"alarms", alarms},
              {"errors", errors},
              {"xoff_sent", l.xoff_sent},
              {"xoff_late", l.xoff_late},
              {"xon_sent", l.xon_sent},
              {"xoff_storms", l.xoff_storms},
              {"holds", l.holds},
              {"noise_bytes_sent", l.noise_bytes_sent},
              {"link_drops", l.link_drops},
              {"sender_connects", l.sender_connects},
              {"sender_disconnects", l.sender_disconnects},
              {"link_events", links},
              {"path_length_mm", l.path_length_mm},
              {"moves", moves},
              {"executed", executed},
              {"events", events},
              {"resets", resets},
              {"status_reports", l.status_reports},
              {"feed_holds", l.feed_holds},
              {"cycle_starts", l.cycle_starts},
              {"bytes_before_banner", l.bytes_before_banner},
              {"banners_sent", l.banners_sent},
              {"banners_lost", l.banners_lost},
              {"unlocks", l.unlocks}};
}

}  // namespace ncd::comms
