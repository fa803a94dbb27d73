// Controller dialects: the one place for the rules of what a controller takes over the link
// (`[link] dialect`). The writer, the block encoder, the sender's pre-check (`ncd stream`) and
// the simulated controller all use these functions, so that they can never disagree.
//
//   iso       Fanuc-style drip feed: `%` framing, N numbers, LF as end of block, the address
//             letters A–Z with plain numbers and `(…)` comments; no `#` variables, no `[…]`
//             expressions, no `;` (in ISO code the end of block is LF).
//   grbl      grbl 1.1h as built by default (config.h): its parser (gcode.c) and its line
//             reader (protocol.c), modelled word by word with grbl's own error numbers.
//   linuxcnc  RS-274/NGC as ncd's interpreter (toolpath/ngc_interpreter) reads it.
//
// The grbl model and its sources are described in docs/dnc-link.md, "Dialects".
#pragma once

#include <array>
#include <optional>
#include <string>
#include <string_view>

namespace ncd::comms {

enum class Dialect { iso, grbl, linuxcnc };

// "iso", "grbl" or "linuxcnc"; throws InputError naming the value and the choices.
Dialect parse_dialect(std::string_view text);
const char* to_string(Dialect dialect);

// What a writer or encoder must produce for the dialect.
struct DialectRules {
  bool percent_framing = false;     // the program opens and closes with a `%` line
  bool n_numbers = false;           // blocks carry N sequence numbers
  const char* eob = "\n";           // end of block
  int max_line_chars = 0;           // characters a line may keep, 0: no limit
  bool paren_comments = true;       // `(…)` comments are taken (and ignored)
  bool semicolon_comments = false;  // `;` to the end of the line is a comment
  bool expressions = false;         // `#` parameters and `[…]` expressions
  bool o_words = false;             // O-word subroutines and loops
  bool tool_change = true;          // M6
  bool path_blending = true;        // G64 (P tolerance)
  // G43 H n: the controller adds tool n's length from its own tool table (grbl has no table,
  // only G43.1 Z<length>, and loses it at reset).
  bool length_offsets = true;
  // A fourth, rotary axis word (A or B) on the controller: stock grbl 1.1 has three axes
  // (a grblHAL built with A or B has four; ncd does not drive it).
  bool rotary_axis = true;
};
const DialectRules& rules(Dialect dialect);

// A line the dialect cannot take: the first word that breaks a rule.
struct Violation {
  long line = 0;       // 1-based line of the program, 0 when one line was checked
  int column = 0;      // 1-based column of the word in the raw line
  std::string word;    // the word as written (e.g. "G64"), or the character
  int grbl_error = 0;  // grbl's `error:N` for this line (grbl dialect), 0 otherwise
  std::string reason, way_out;
};
// "line 3, column 1, 'G64': … (grbl error:20); …"
std::string describe(const Violation& v, Dialect dialect);

// ---- grbl 1.1 ----

// grbl 1.1h status codes (report.h) that its parser returns for a line.
enum GrblError : int {
  kGrblExpectedLetter = 1,
  kGrblBadNumber = 2,
  kGrblNegative = 4,
  kGrblOverflow = 11,
  kGrblUnsupported = 20,
  kGrblModalGroup = 21,
  kGrblUndefinedFeed = 22,
  kGrblNotInteger = 23,
  kGrblAxisConflict = 24,
  kGrblRepeated = 25,
  kGrblNoAxisWords = 26,
  kGrblLineNumber = 27,
  kGrblValueMissing = 28,
  kGrblCoordSystem = 29,
  kGrblG53Motion = 30,
  kGrblAxisWordsExist = 31,
  kGrblNoAxisInPlane = 32,
  kGrblInvalidTarget = 33,
  kGrblArcRadius = 34,
  kGrblNoOffsetsInPlane = 35,
  kGrblUnusedWords = 36,
  kGrblG43Axis = 37,
  kGrblMaxValue = 38,
};

// grbl's parser state (gc_state) as far as its checks and a simulation need it. Positions are
// machine coordinates in mm; the stored coordinate systems and G28/G30 positions start at zero
// (a fresh EEPROM).
struct GrblState {
  int motion = 0;  // G code × 10: 0, 10, 20, 30, 382 … 385, 800
  bool inverse_time = false, inches = false, incremental = false;
  int plane = 0;         // 0 XY (G17), 1 ZX (G18), 2 YZ (G19)
  int coord_select = 0;  // 0 … 5: G54 … G59
  double feed = 0.0;     // mm/min (G94) or 1/min (G93); 0: undefined
  double spindle_rpm = 0.0;
  int spindle = 5;  // 3, 4 or 5
  bool flood = false;
  int tool = 0;
  std::array<double, 3> position{};
  std::array<std::array<double, 3>, 6> coord_system{};
  std::array<double, 3> g92{}, g28{}, g30{};
  double tool_length_mm = 0.0;  // G43.1 Z
};

// What an accepted line does, in grbl's order of execution (gcode.c step 4).
struct GrblBlock {
  bool empty = true;                  // no words (empty or comment line)
  std::optional<long> n;              // N given
  std::optional<double> spindle_rpm;  // S given
  std::optional<int> spindle;         // M3, M4 or M5 given
  std::optional<bool> flood;          // M8 / M9
  std::optional<int> tool;            // T given
  std::optional<double> dwell_s;      // G4 P
  int motion = -1;                    // G code × 10 of the motion executed, −1 none
  bool rapid = false;                 // G0, G28, G30 (at the rapid rate)
  std::array<double, 3> to{};         // end of the motion, machine mm
  double path_mm = 0.0;               // length of the motion (arcs: the helix)
  double feed_mm_per_min = 0.0;       // G94 feed of a feed motion
  double inverse_time_min = 0.0;      // G93: the motion's time in minutes
  bool pause = false;                 // M0
  bool optional_stop = false;         // M1 (grbl ignores it)
  bool program_end = false;           // M2 or M30
};

// Checks one line as grbl 1.1 would receive it (protocol.c then gcode.c) against `state`.
// Returns the first violation (grbl_error set) and leaves `state` unchanged, or nullopt, updates
// `state` and fills `block` (may be null). Lines starting with `$` are grbl system commands, not
// program blocks: refused (error:3 would be grbl's answer to most).
std::optional<Violation> check_grbl_line(std::string_view line, GrblState& state,
                                         GrblBlock* block = nullptr);

// ---- any dialect ----

// A dialect's running state over a program (grbl is modal; the others are checked line by line).
struct DialectState {
  GrblState grbl;
};

// One line (without end of block) against the dialect; `%` lines are framing in iso and
// linuxcnc. For linuxcnc one line is checked only for characters a serial line cannot carry;
// the program is read by the interpreter in check_program.
std::optional<Violation> check_line(Dialect dialect, std::string_view line, DialectState& state);
// A whole program text (lines ended by LF, CR LF or CR): the first violation with its line.
std::optional<Violation> check_program(Dialect dialect, std::string_view text);

}  // namespace ncd::comms
