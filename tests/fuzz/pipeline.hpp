// The whole motion pipeline under a fuzzer (tests/fuzz/pipeline_fuzz.cpp) and under GoogleTest
// (tests/motion/fuzz_findings_test.cpp): one input becomes a machine and an RS-274/NGC program,
// the program is interpreted, made a Path and a motion::Job, and EVERY period of the job is
// walked (prepare(), step()) and checked. The first violation is returned as a sentence.
//
// The input. A text starting with "(fuzz" is a program as it is, its first line naming the
// machine (parse_machine_line; the line is an NGC comment, so the file is a program LinuxCNC
// and `ncd check` read as well). Anything else is bytes: the first eight choose the machine,
// the rest drive a generator of short programs (Generator): G0/G1/G2/G3 with small, large and
// degenerate coordinates, F words of 0.1 to 20000 mm/min under G94 and G93 inverse time,
// G17/G18/G19, G20/G21, G61/G61.1/G64 P Q, G90/G91, dwells, M3/M5, T M6 with G43, helices,
// arcs with R, full circles with P turns, 1 µm moves, reversals and dense runs of 1 µm-rounded
// points. Generated programs are valid by construction (the positions are tracked), so that the
// fuzzer spends its time in the planner, not in the interpreter's refusals; a reproducer is
// written as text (machine_line() + the program) so that it outlives changes of the generator.
//
// The machine: maximum feed 60-20000 mm/min, acceleration 50-5000 mm/s², jerk 500-100000
// mm/s³, period 1-8 ms, chord tolerance 0.1 µm-0.1 mm, blend tolerance 0-1 mm, jerk bound
// tangential or vector, the roughness law off (planner_machine) or the defaults' (10 µm).
//
// What is checked, per period (Checker::period), against the limits and the programmed
// geometry, never against the job's own reports of itself beyond its setpoint:
//   - every number of the setpoint is finite; no StepFault;
//   - the planned speed within the limit curve at 100 % (the setpoint's feed_limit_mm_per_s)
//     and the machine's maximum feed, × (1 + 1e-6); within the F word of the walked move (not
//     at a superposed corner setpoint, which sums two moves); |Δp|/T within the maximum feed;
//   - the tangential acceleration and jerk from the second and third differences of the planned
//     s (as tests/motion/property_test.cpp; not across a superposed corner, whose s sums two
//     moves' progress), plus the rounding of s. (Not the acceleration vector |Δ²p|/T²: the
//     corner law, grbl's junction deviation with the chord law (docs/planner.md §2), lets the
//     velocity turn within one period by up to min(sqrt(8 a_max ε_c), 4 ε_c / T), which can be
//     above √2 a_max T when ε_c > √2 a_max T²/4: the setpoints' acceleration there is the
//     law's, not a fault of the walk);
//   - the chord error within the chord tolerance × (1 + 1e-6);
//   - the position inside the bounding box of the program's geometry (polyline points and NURBS
//     control points: a NURBS with positive weights lies in their hull), grown by the largest
//     tolerance a setpoint may take from it (G64 P, the machine's blend tolerance, G64 Q);
//   - progress: never 2 s without 0.1 µm of planned s; the walk ends within bound_periods()
//     (4 × a stop-and-go time at every vertex + 10 000 periods; an input whose bound, weighted
//     by walk_cost_factor(), exceeds kMaxPeriods is refused before the job is built, to keep
//     an input's time in hand for the fuzzer);
//   - at the end: at rest (v = a = 0) at the path's end point within 1e-6 mm;
//   - memory: no allocation in any period after the first prepare() (the caller counts them).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <numbers>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <unistd.h>

#include "core/error.hpp"
#include "feed/feed_limits.hpp"
#include "gcode/ngc/interpreter.hpp"
#include "gcode/program.hpp"
#include "motion/job.hpp"

namespace ncd::fuzz::pipeline {

// The longest walk an input may ask for (bound_periods() × walk_cost_factor()): longer ones are
// refused unwalked. Under ASan a period costs 30-700 µs (the planner's rollouts grow with the
// braking horizon), so this keeps an input within about a minute; LinuxCNC's flowsnake.ngc on
// its machine (a bound of 5.9e5 periods, 56 000 walked) fits.
inline constexpr double kMaxPeriods = 7e5;
// Blocks the interpreter executes at most: a fuzzed endless loop ends after them
// (flowsnake.ngc executes between 50 000 and 100 000).
inline constexpr long kMaxBlocks = 100000;
inline constexpr double kPi = std::numbers::pi;

// ---------------------------------------------------------------------------------------------
// The machine.

struct Machine {
  double feed_mm_per_min = 6000.0;  // F
  double accel = 1000.0;            // A, mm/s²
  double jerk = 20000.0;            // J, mm/s³
  double period_ms = 4.0;           // T
  double chord_mm = 0.001;          // C
  double blend_mm = 0.01;           // B
  int vector = 0;                   // V: 0 tangential, 1 vector
  int roughness = 0;                // R: 0 off (the planner tests' machine), 1 the defaults'
};

inline double clamp_finite(double v, double lo, double hi, double fallback) {
  if (!std::isfinite(v)) return fallback;
  return std::min(hi, std::max(lo, v));
}

// Every value into its range (a fuzzed header line may say anything).
inline Machine clamped(Machine m) {
  m.feed_mm_per_min = clamp_finite(m.feed_mm_per_min, 60.0, 20000.0, 6000.0);
  m.accel = clamp_finite(m.accel, 50.0, 5000.0, 1000.0);
  m.jerk = clamp_finite(m.jerk, 500.0, 100000.0, 20000.0);
  m.period_ms = clamp_finite(m.period_ms, 1.0, 8.0, 4.0);
  m.chord_mm = clamp_finite(m.chord_mm, 1e-4, 0.1, 0.001);
  m.blend_mm = clamp_finite(m.blend_mm, 0.0, 1.0, 0.01);
  m.vector = m.vector != 0 ? 1 : 0;
  m.roughness = m.roughness != 0 ? 1 : 0;
  return m;
}

inline motion::JobConfig job_config(const Machine& m) {
  motion::JobConfig c;
  c.limits.max_feed_mm_per_min = m.feed_mm_per_min;
  c.limits.max_accel_mm_per_s2 = m.accel;
  c.limits.max_jerk_mm_per_s3 = m.jerk;
  c.limits.period_s = m.period_ms / 1000.0;
  c.limits.chord_tolerance_mm = m.chord_mm;
  c.limits.blend_tolerance_mm = m.blend_mm;
  c.limits.jerk_bound = m.vector ? feed::JerkBound::vector : feed::JerkBound::tangential;
  if (!m.roughness) {
    c.cutting.pick_feed_mm = 0.0;
    c.cutting.roughness_target_um = 1000.0;
  }
  return c;
}

// "(fuzz F6000 A1000 J20000 T4 C0.001 B0.01 V0 R0)": the first line of a text input.
inline std::string machine_line(const Machine& m) {
  char text[200];
  std::snprintf(text, sizeof text, "(fuzz F%.17g A%.17g J%.17g T%.17g C%.17g B%.17g V%d R%d)",
                m.feed_mm_per_min, m.accel, m.jerk, m.period_ms, m.chord_mm, m.blend_mm, m.vector,
                m.roughness);
  return text;
}

// Reads the letters of machine_line() in any order; a missing or garbled value keeps its default.
inline Machine parse_machine_line(const std::string& line) {
  Machine m;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char key = line[i];
    if (!std::strchr("FAJTCBVR", key) || key == '\0') continue;
    const std::string rest = line.substr(i + 1, 40);
    char* end = nullptr;
    const double v = std::strtod(rest.c_str(), &end);
    if (end == rest.c_str()) continue;
    switch (key) {
      case 'F':
        m.feed_mm_per_min = v;
        break;
      case 'A':
        m.accel = v;
        break;
      case 'J':
        m.jerk = v;
        break;
      case 'T':
        m.period_ms = v;
        break;
      case 'C':
        m.chord_mm = v;
        break;
      case 'B':
        m.blend_mm = v;
        break;
      case 'V':
        m.vector = v != 0.0 ? 1 : 0;
        break;
      case 'R':
        m.roughness = v != 0.0 ? 1 : 0;
        break;
      default:
        break;
    }
  }
  return clamped(m);
}

// ---------------------------------------------------------------------------------------------
// The generator.

// Bytes from the front; zeros once they run out.
class Bytes {
 public:
  Bytes(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  std::uint8_t byte() { return at_ < size_ ? data_[at_++] : 0; }
  bool empty() const { return at_ >= size_; }
  int pick(int n) { return static_cast<int>(byte()) % n; }
  double unit() {  // [0, 1], 16 bits
    const int hi = byte(), lo = byte();
    return static_cast<double>(hi * 256 + lo) / 65535.0;
  }
  double uni(double a, double b) { return a + (b - a) * unit(); }
  double log_uni(double a, double b) { return a * std::pow(b / a, unit()); }

 private:
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t at_ = 0;
};

inline Machine machine_from_bytes(Bytes& b) {
  Machine m;
  m.feed_mm_per_min = 60.0 * std::pow(20000.0 / 60.0, b.byte() / 255.0);
  m.accel = 50.0 * std::pow(100.0, b.byte() / 255.0);
  m.jerk = 500.0 * std::pow(200.0, b.byte() / 255.0);
  m.period_ms = 1.0 + 7.0 * b.byte() / 255.0;
  m.chord_mm = 1e-4 * std::pow(1000.0, b.byte() / 255.0);
  const int blend = b.byte();
  m.blend_mm = blend < 16 ? 0.0 : 1e-4 * std::pow(1e4, (blend - 16) / 239.0);
  const int flags = b.byte();
  m.vector = flags & 1;
  m.roughness = (flags >> 1) & 1;
  return clamped(m);
}

// Writes a short RS-274/NGC program from the bytes, tracking the position so that every arc is
// well formed. Positions are kept in mm, absolute (no offsets but G43's, which only moves Z of
// the machine and not the program's coordinates).
class Generator {
 public:
  explicit Generator(Bytes& b) : b_(b) {}

  std::string program() {
    out_ = "G21 G90 G94 G17 G64\n";
    feed_mm_per_min_ = 1000.0;
    out_ += "F1000\n";
    // A known position first: a feed move from an unknown one is refused (to_path).
    pos_ = {coord(), coord(), coord()};
    line("G0" + xyz(pos_, /*absolute*/ true));
    const int statements = 1 + b_.pick(48);
    for (int i = 0; i < statements && !b_.empty(); ++i) statement();
    out_ += "M5\nM2\n";
    return out_;
  }

 private:
  using V3 = std::array<double, 3>;

  // A coordinate for a target: small, medium, large or 0, in mm. Large ones are rare: a walk of
  // a metre takes seconds under the sanitizers, and the fuzzer is best at short inputs.
  double coord() {
    switch (b_.pick(16)) {
      case 0:
        return 0.0;
      case 1:
      case 2:
        return b_.uni(-1.0, 1.0);
      case 3:
        return b_.uni(-1000.0, 1000.0);
      default:
        return b_.uni(-20.0, 20.0);
    }
  }
  // A length: 1 µm, small, medium, large.
  double length() {
    switch (b_.pick(16)) {
      case 0:
      case 1:
        return 0.001;
      case 2:
      case 3:
        return b_.log_uni(0.001, 0.1);
      case 4:
        return b_.log_uni(50.0, 1000.0);
      default:
        return b_.log_uni(0.1, 20.0);
    }
  }
  V3 direction() {
    V3 d{b_.uni(-1, 1), b_.uni(-1, 1), b_.uni(-1, 1)};
    const int axis = b_.pick(8);
    if (axis < 3) d = {0, 0, 0}, d[static_cast<std::size_t>(axis)] = 1.0;  // along an axis
    double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (n < 1e-3) d = {1, 0, 0}, n = 1.0;
    return {d[0] / n, d[1] / n, d[2] / n};
  }

  double scale() const { return inch_ ? 1.0 / 25.4 : 1.0; }  // mm → program units
  // A value in program units, rounded as written (1 nm in mm, 0.1 µinch in inch).
  double rounded(double mm) const {
    const double q = inch_ ? 1e7 : 1e6;
    return std::round(mm * scale() * q) / q;
  }
  std::string num(double program_units) const {
    char t[64];
    std::snprintf(t, sizeof t, inch_ ? "%.7f" : "%.6f", program_units);
    std::string s = t;
    while (s.size() > 1 && s.back() == '0') s.pop_back();
    if (s.back() == '.') s.pop_back();
    if (s == "-0") s = "0";
    return s;
  }
  // X Y Z of a target in mm, written for the distance mode; pos_ becomes the target as read.
  std::string xyz(const V3& target_mm, bool force_absolute = false) {
    static const char* const kAxis[] = {" X", " Y", " Z"};
    std::string s;
    V3 now = pos_;
    for (std::size_t k = 0; k < 3; ++k) {
      if (incremental_ && !force_absolute) {
        const double d = rounded(target_mm[k] - pos_[k]);
        s += kAxis[k] + num(d);
        now[k] = pos_[k] + d / scale();
      } else {
        const double a = rounded(target_mm[k]);
        s += kAxis[k] + num(a);
        now[k] = a / scale();
      }
    }
    pos_ = now;
    return s;
  }
  void line(const std::string& s) { out_ += s + "\n"; }

  // The F word a feed move needs: none under G94 (the modal one), 1/minutes under G93.
  std::string feed_word(double length_mm) const {
    if (!inverse_time_) return "";
    const double minutes = std::max(length_mm, 1e-6) / feed_mm_per_min_;
    char t[64];
    std::snprintf(t, sizeof t, " F%.9g", 1.0 / minutes);
    return t;
  }
  double pick_feed() {
    switch (b_.pick(16)) {
      case 0:
        return b_.log_uni(0.1, 1.0);
      case 1:
      case 2:
        return b_.log_uni(1.0, 100.0);
      case 3:
        return 20000.0;
      default:
        return b_.log_uni(100.0, 20000.0);
    }
  }

  void move(const V3& target_mm, bool rapid) {
    const V3 from = pos_;
    const std::string w = xyz(target_mm);
    const double d =
        std::sqrt(sq(pos_[0] - from[0]) + sq(pos_[1] - from[1]) + sq(pos_[2] - from[2]));
    line((rapid ? "G0" : "G1") + w + (rapid ? "" : feed_word(d)));
  }
  static double sq(double v) { return v * v; }

  // Plane axes (first, second, normal) as LinuxCNC: XY; ZX; YZ.
  std::array<std::size_t, 3> axes() const {
    if (plane_ == 18) return {2, 0, 1};
    if (plane_ == 19) return {1, 2, 0};
    return {0, 1, 2};
  }

  // An arc (or helix, or full circle with turns) of the current plane: IJK or R.
  void arc(int kind) {
    const auto [a, b, n] = axes();
    static const char* const kOffset[] = {" I", " J", " K"};
    const double r = length();
    const double phi0 = b_.uni(0.0, 2.0 * kPi);
    const bool ccw = b_.pick(2) == 0;
    // The centre offset from the start, rounded as written: the radius is the rounded one.
    V3 off{0, 0, 0};
    off[a] = rounded(-r * std::cos(phi0)) / scale();
    off[b] = rounded(-r * std::sin(phi0)) / scale();
    const double rr = std::hypot(off[a], off[b]);
    if (rr < 1e-4) return;  // too small to be written as an arc
    const V3 centre{pos_[0] + off[0], pos_[1] + off[1], pos_[2] + off[2]};
    const double start_angle = std::atan2(pos_[b] - centre[b], pos_[a] - centre[a]);
    double sweep = 0.0;
    int turns = 1;
    V3 target = pos_;
    if (kind == 0) {  // a partial arc
      sweep = b_.uni(0.01, 2.0 * kPi - 0.01);
    } else if (kind == 1) {  // a full circle, more turns sometimes
      sweep = 2.0 * kPi;
      turns = 1 + b_.pick(3);
    } else {  // a tiny sweep
      sweep = b_.log_uni(1e-4, 0.05);
    }
    if (kind != 1) {
      const double end = start_angle + (ccw ? sweep : -sweep);
      target[a] = centre[a] + rr * std::cos(end);
      target[b] = centre[b] + rr * std::sin(end);
    }
    const bool helix = b_.pick(3) == 0;
    if (helix) target[n] = pos_[n] + (b_.pick(2) ? 1.0 : -1.0) * length();
    const double len = std::hypot(rr * sweep * turns, target[n] - pos_[n]);
    std::string w = ccw ? "G3" : "G2";
    const V3 from = pos_;
    w += xyz(target);
    const bool use_r = kind == 0 && b_.pick(3) == 0;
    if (use_r) {
      // R: positive up to 180°, negative beyond (LinuxCNC); the radius as it stands.
      const double chord = std::hypot(pos_[a] - from[a], pos_[b] - from[b]);
      if (chord < 1e-3) {  // R cannot place a centre on a vanishing chord: IJ instead
        w += kOffset[a] + num(rounded(off[a])) + kOffset[b] + num(rounded(off[b]));
      } else {
        w += " R" + num(rounded(sweep > kPi ? -rr : rr));
      }
    } else {
      w += kOffset[a] + num(rounded(off[a])) + kOffset[b] + num(rounded(off[b]));
    }
    if (turns > 1) w += " P" + std::to_string(turns);
    line(w + feed_word(len));
  }

  // A dense run: points along an arc or a wave, every 0.005-0.05 mm, rounded to 1 µm as CAM
  // writes them.
  void dense_run() {
    const int n = 10 + b_.pick(190);
    const double step = b_.log_uni(0.005, 0.05);
    const double radius = b_.log_uni(0.5, 100.0);
    const bool wave = b_.pick(2) == 0;
    const auto [a, b, nn] = axes();
    const V3 start = pos_;
    const double sign = b_.pick(2) ? 1.0 : -1.0;
    for (int i = 1; i <= n; ++i) {
      const double t = step * i;
      V3 p = start;
      if (wave) {
        p[a] += t;
        p[b] += 0.1 * radius / 100.0 * std::sin(t * 3.0);
        p[nn] += 0.02 * std::sin(t * 7.0);
      } else {
        p[a] += radius * std::sin(t / radius);
        p[b] += sign * radius * (1.0 - std::cos(t / radius));
      }
      for (double& c : p) c = std::round(c * 1000.0) / 1000.0;
      move(p, false);
    }
  }

  void statement() {
    const auto [a, b, n] = axes();
    (void)n;
    switch (b_.pick(24)) {
      case 0:
      case 1:
      case 2: {  // a line to a target
        move({coord(), coord(), coord()}, false);
        break;
      }
      case 3:
      case 4: {  // a line of a given length in a direction
        const V3 d = direction();
        const double l = length();
        move({pos_[0] + l * d[0], pos_[1] + l * d[1], pos_[2] + l * d[2]}, false);
        break;
      }
      case 5:
        move({coord(), coord(), coord()}, true);
        break;
      case 6:
      case 7:
        arc(0);
        break;
      case 8:
        arc(1);
        break;
      case 9:
        arc(2);
        break;
      case 10: {  // a 1 µm move, then maybe back (a reversal)
        const V3 d = direction();
        const V3 from = pos_;
        move({pos_[0] + 0.001 * d[0], pos_[1] + 0.001 * d[1], pos_[2] + 0.001 * d[2]}, false);
        if (b_.pick(2)) move(from, false);
        break;
      }
      case 11: {  // a reversal: out and back along the same line
        const V3 d = direction();
        const double l = length();
        const V3 from = pos_;
        move({pos_[0] + l * d[0], pos_[1] + l * d[1], pos_[2] + l * d[2]}, false);
        move(from, false);
        break;
      }
      case 12:
        dense_run();
        break;
      case 13: {  // a zero-length move
        move(pos_, false);
        break;
      }
      case 14: {  // the feed, and G93/G94
        feed_mm_per_min_ = pick_feed();
        const int mode = b_.pick(4);
        if (mode == 0 && !inverse_time_) {
          inverse_time_ = true;
          line("G93");
        } else if (mode == 1 && inverse_time_) {
          inverse_time_ = false;
          line("G94");
        }
        if (!inverse_time_) line("F" + num(feed_mm_per_min_ * scale()));
        break;
      }
      case 15: {
        static const int kPlane[] = {17, 18, 19};
        plane_ = kPlane[b_.pick(3)];
        line("G" + std::to_string(plane_));
        break;
      }
      case 16: {  // units: the modal F is read in the new units and must be written again
        inch_ = !inch_;
        line(inch_ ? "G20" : "G21");
        if (!inverse_time_) line("F" + num(feed_mm_per_min_ * scale()));
        break;
      }
      case 17: {
        const int m = b_.pick(6);
        if (m == 0) {
          line("G61");
        } else if (m == 1) {
          line("G61.1");
        } else {
          std::string w = "G64";
          if (m >= 3) w += " P" + num(rounded(b_.pick(4) == 0 ? 0.0 : b_.log_uni(1e-4, 1.0)));
          if (m >= 4) w += " Q" + num(rounded(b_.log_uni(1e-4, 0.1)));
          line(w);
        }
        break;
      }
      case 18: {
        incremental_ = !incremental_;
        line(incremental_ ? "G91" : "G90");
        break;
      }
      case 19:
        line("G4 P" + num(b_.uni(0.0, 0.5)));
        break;
      case 20: {
        const int s = 100 + b_.pick(200) * 100;
        line(b_.pick(3) == 0 ? std::string("M5")
                             : (b_.pick(2) ? "M3 S" : "M4 S") + std::to_string(s));
        break;
      }
      case 21: {  // a tool change with its length (the table of tool_table_text())
        static const int kTool[] = {1, 2, 3, 4};
        const int t = kTool[b_.pick(4)];
        line("T" + std::to_string(t) + " M6");
        line(b_.pick(2) ? "G43 H" + std::to_string(t) : "G49");
        break;
      }
      case 22: {  // a run of short lines in one direction with a reversal inside
        const V3 d = direction();
        const int k = 2 + b_.pick(8);
        const double l = length() / k;
        for (int i = 0; i < k; ++i) {
          const double sgn = i == k / 2 ? -1.0 : 1.0;
          move({pos_[0] + sgn * l * d[0], pos_[1] + sgn * l * d[1], pos_[2] + sgn * l * d[2]},
               false);
        }
        break;
      }
      default: {  // a sharp corner in the plane
        V3 p = pos_;
        const double l = length();
        p[a] += l;
        move(p, false);
        p[b] += l * b_.uni(-2.0, 2.0);
        p[a] -= l * b_.uni(0.0, 1.0);
        move(p, false);
        break;
      }
    }
  }

  Bytes& b_;
  std::string out_;
  V3 pos_{0, 0, 0};
  double feed_mm_per_min_ = 1000.0;
  bool inch_ = false, incremental_ = false, inverse_time_ = false;
  int plane_ = 17;
};

// ---------------------------------------------------------------------------------------------
// The input.

struct Input {
  Machine machine;
  std::string program;  // the NGC text, without the machine line
  bool generated = false;
};

inline bool is_text_input(const std::uint8_t* data, std::size_t size) {
  return size >= 5 && std::memcmp(data, "(fuzz", 5) == 0;
}

inline Input decode(const std::uint8_t* data, std::size_t size) {
  Input in;
  if (is_text_input(data, size)) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    const std::size_t eol = text.find('\n');
    in.machine = parse_machine_line(text.substr(0, eol));
    in.program = eol == std::string::npos ? std::string() : text.substr(eol + 1);
    return in;
  }
  Bytes b(data, size);
  in.machine = machine_from_bytes(b);
  in.program = Generator(b).program();
  in.generated = true;
  return in;
}

// The input as a text reproducer: what a finding is saved as.
inline std::string as_text(const Input& in) {
  return machine_line(in.machine) + "\n" + in.program;
}

// The tools the programs may select (the table of tests/motion/no_alloc_test.cpp, LinuxCNC's
// sim table's kind: lengths up to 100 mm, diameters up to 1 mm for cutter compensation), written
// once per process to a temporary file for InterpretOptions::tool_table.
inline const std::string& tool_table_file() {
  static const std::string path = [] {
    char name[] = "/tmp/ncd_fuzz_tools_XXXXXX";
    const int fd = mkstemp(name);
    if (fd >= 0) {
      const char table[] =
          "T1 P1 Z75.5 D0.25\nT2 P2 Z-0.25 D0.5\nT3 P3 Z28.575 D0.125\n"
          "T4 P4 Z19.05 D0.375\nT5 P5 Z50 D0.1\nT7 P7 Z60 D0.2\n"
          "T10 P10 Z100 D0.3\nT20 P20 Z50.8 D1\n";
      const ssize_t n = write(fd, table, sizeof table - 1);
      (void)n;
      close(fd);
    }
    static const std::string kept = name;
    std::atexit([] { std::remove(kept.c_str()); });
    return std::string(name);
  }();
  return path;
}

// ---------------------------------------------------------------------------------------------
// The bound on the walk.

// Where the path ends.
inline Vec3 end_point(const toolpath::Path& p) {
  const auto& g = p.segments.back().geometry;
  if (const auto* l = std::get_if<toolpath::Polyline>(&g)) return l->points.back();
  const auto& c = std::get<toolpath::NurbsCurve>(g);
  return c.eval(c.u_end()).p;
}

// The time of a rest-to-rest move over d at a cruise of at most v (a, j the limits): a motion
// that accelerates to v' ≤ v in v'/a + a/j, cruises and brakes the same takes d/v' + 2(v'/a +
// a/j) at most (at d = v' t_a it is exactly 2 t_a); the best of a halving ladder of v'.
inline double rest_to_rest_s(double d, double v, double a, double j) {
  double best = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 40 && v > 1e-12; ++k, v *= 0.5)
    best = std::min(best, d / v + 2.0 * (v / a + a / j));
  return best;
}

// A bound on the periods the walk of `path` on `c` takes: 4 × the time of a stop-and-go walk
// (every polyline vertex and every knot a full stop, each piece at the lowest speed the laws
// allow on it: the F word, the maximum feed, and on a curve the chord, centripetal
// acceleration and jerk laws at its sampled largest curvature, halved; the roughness law at its
// floor, halved), + 10 000 periods. Under the jerk-vector bound the tangential limits are
// taken at the lowest scale the sampler may ask (kTangentialScaleFloor).
inline double bound_periods(const toolpath::Path& path, const motion::JobConfig& c) {
  const auto& l = c.limits;
  const double scale_floor =
      l.jerk_bound == feed::JerkBound::vector ? feed::kTangentialScaleFloor : 1.0;
  const double a = l.max_accel_mm_per_s2 * scale_floor, j = l.max_jerk_mm_per_s3 * scale_floor;
  const double v_machine = l.max_feed_mm_per_min / 60.0;
  double v_rough = std::numeric_limits<double>::infinity();
  for (int k = 0; k <= 64; ++k) {
    v_rough = std::min(v_rough, feed::roughness_feed_mm_per_s(c.cutting, k * kPi / 128.0));
  }
  v_rough *= 0.5;
  double t = 0.0;
  for (const auto& seg : path.segments) {
    double v = std::min(v_machine, v_rough);
    if (!seg.rapid && seg.feed_mm_per_min) v = std::min(v, *seg.feed_mm_per_min / 60.0);
    if (const auto* pl = std::get_if<toolpath::Polyline>(&seg.geometry)) {
      for (std::size_t i = 0; i + 1 < pl->points.size(); ++i) {
        t += rest_to_rest_s((pl->points[i + 1] - pl->points[i]).norm(), v, a, j);
      }
      continue;
    }
    const auto& curve = std::get<toolpath::NurbsCurve>(seg.geometry);
    const std::vector<double> bp = curve.breakpoints();
    for (std::size_t i = 0; i + 1 < bp.size(); ++i) {
      double kappa = 0.0, sampled = 0.0;
      Vec3 prev = curve.eval(bp[i]).p;
      for (int k = 0; k <= 64; ++k) {
        const toolpath::CurvePoint q = curve.eval(bp[i] + (bp[i + 1] - bp[i]) * k / 64.0);
        const double kq = feed::curvature_per_mm(q);
        kappa = std::max(kappa, std::isfinite(kq) ? kq : 1e12);
        sampled += (q.p - prev).norm();
        prev = q.p;
      }
      double vc = v;
      if (kappa > 0.0) {
        vc = std::min({vc, 0.5 * feed::chord_feed_mm_per_s(kappa, l.chord_tolerance_mm, l.period_s),
                       0.5 * feed::centripetal_accel_feed_mm_per_s(kappa, a),
                       0.5 * feed::centripetal_jerk_feed_mm_per_s(kappa, j)});
      }
      t += rest_to_rest_s(1.05 * sampled, vc, a, j);
    }
  }
  return 4.0 * t / l.period_s + 10000.0;
}

// What a period costs the harness, relative to a machine that stops within a few periods: the
// planner's rollouts run over the braking horizon, (v_max / a_max + a_max / j_max) / T periods
// (37 at the defaults, 6 770 at 20 000 mm/min, 50 mm/s², 500 mm/s³ and 1 ms, where a period
// costs 20 times more). Only to keep an input's time in hand; nothing is checked with it.
inline double walk_cost_factor(const motion::JobConfig& c) {
  const auto& l = c.limits;
  const double horizon_s = l.max_feed_mm_per_min / 60.0 / l.max_accel_mm_per_s2 +
                           l.max_accel_mm_per_s2 / l.max_jerk_mm_per_s3;
  return 1.0 + horizon_s / l.period_s / 300.0;
}

// ---------------------------------------------------------------------------------------------
// The walk.

struct Outcome {
  enum Kind { Refused, Walked, Violation } kind = Refused;
  std::string message;  // why refused, or the violation
  std::int64_t periods = 0;
  double bound = 0.0;
};

// Allocations counted by the caller (a malloc hook under libFuzzer, a replaced operator new in
// a GoogleTest binary); null: not checked.
using AllocationCount = long (*)();

// printf into a string (the formats are checked by the compiler).
__attribute__((format(printf, 1, 2))) inline std::string fmt(const char* f, ...) {
  char t[400];
  va_list args;
  va_start(args, f);
  std::vsnprintf(t, sizeof t, f, args);
  va_end(args);
  return t;
}

inline bool finite(const motion::Setpoint& sp) {
  return sp.p.allFinite() && std::isfinite(sp.s_mm) && std::isfinite(sp.v_mm_per_s) &&
         std::isfinite(sp.a_mm_per_s2) && std::isfinite(sp.j_mm_per_s3) &&
         std::isfinite(sp.planned_ds_mm) && std::isfinite(sp.travelled_mm) &&
         std::isfinite(sp.chord_error_mm) && std::isfinite(sp.feed_limit_mm_per_s) &&
         std::isfinite(sp.t_s);
}

// The bounding box of the programmed geometry, grown by the largest tolerance a setpoint may
// take from it.
struct Box {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 hi = -Vec3::Constant(std::numeric_limits<double>::infinity());
  void add(const Vec3& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  bool holds(const Vec3& p) const {
    return (p.array() >= lo.array()).all() && (p.array() <= hi.array()).all();
  }
};

inline Box envelope(const toolpath::Path& path, const motion::JobConfig& c) {
  Box box;
  double margin = c.limits.blend_tolerance_mm;
  for (const auto& seg : path.segments) {
    if (const auto* pl = std::get_if<toolpath::Polyline>(&seg.geometry)) {
      for (const Vec3& p : pl->points) box.add(p);
    } else {
      for (const Vec3& p : std::get<toolpath::NurbsCurve>(seg.geometry).points()) box.add(p);
    }
    margin = std::max(
        {margin, seg.blend_tolerance_mm.value_or(0.0), seg.smoothing_tolerance_mm.value_or(0.0)});
  }
  const double scale = std::max(box.lo.cwiseAbs().maxCoeff(), box.hi.cwiseAbs().maxCoeff());
  const Vec3 grow = Vec3::Constant(margin + 1e-6 + 1e-12 * scale);
  box.lo -= grow;
  box.hi += grow;
  return box;
}

// Walks every period of the job and checks it; the first violation.
inline std::string walk(motion::Job& job, const toolpath::Path& path, double bound,
                        std::int64_t& periods, AllocationCount allocations) {
  const auto& l = job.config().limits;
  const double T = l.period_s, a_max = l.max_accel_mm_per_s2, j_max = l.max_jerk_mm_per_s3;
  const double v_cap = l.max_feed_mm_per_min / 60.0, eps = l.chord_tolerance_mm;
  const double rel = 1.0 + 1e-6;
  const Box box = envelope(path, job.config());
  const Vec3 end = end_point(path);
  // The last four setpoints (positions and planned s): the differences.
  std::array<Vec3, 4> p{};
  std::array<double, 4> s{};
  p.fill(job.walker().position());
  s.fill(0.0);
  std::int64_t k = 0;        // setpoints so far
  int since_overlap = 1000;  // setpoints since the last superposed one
  std::int64_t still = 0;    // periods without progress
  double still_s = 0.0;
  if (!job.prepare()) return "the first look-ahead failed: " + job.fault_message();
  const long before = allocations ? allocations() : 0;
  const auto at = [&](const motion::Setpoint& sp) {
    return fmt(" (period %.0f, s = %.9g mm, v = %.9g mm/s, segment %.0f)", static_cast<double>(k),
               sp.s_mm, sp.v_mm_per_s, static_cast<double>(sp.segment));
  };
  for (;;) {
    if (static_cast<double>(k) > bound)
      return fmt("not done after %.0f periods (the bound)", bound);
    job.prepare();
    const motion::Setpoint sp = job.step();
    ++k;
    if (sp.fault != motion::StepFault::None) {
      return std::string("fault ") + motion::to_string(sp.fault) + ": " + job.fault_message();
    }
    if (!finite(sp)) return "a number of the setpoint is not finite" + at(sp);
    since_overlap = sp.overlapped ? 0 : since_overlap + 1;
    for (std::size_t i = 3; i > 0; --i) p[i] = p[i - 1], s[i] = s[i - 1];
    p[0] = sp.p;
    s[0] = sp.s_mm;
    if (!(sp.v_mm_per_s <= sp.feed_limit_mm_per_s * rel + 1e-12)) {
      return fmt("planned speed %.9g mm/s above the limit curve %.9g mm/s (limit ", sp.v_mm_per_s,
                 sp.feed_limit_mm_per_s) +
             motion::limit_name(sp.limit_id) + ")" + at(sp);
    }
    if (!(sp.v_mm_per_s <= v_cap * rel)) {
      return fmt("planned speed %.9g mm/s above the maximum feed %.9g mm/s", sp.v_mm_per_s, v_cap) +
             at(sp);
    }
    const double step = (p[0] - p[1]).norm();
    if (!(step <= v_cap * T * rel + 1e-9)) {
      return fmt("step %.9g mm in a period: %.9g mm/s above the maximum feed", step, step / T) +
             at(sp);
    }
    const auto& walked = job.path().segments[sp.segment];
    if (!sp.overlapped && !walked.rapid && walked.feed_mm_per_min &&
        !(sp.v_mm_per_s <= *walked.feed_mm_per_min / 60.0 * rel + 1e-12)) {
      return fmt("planned speed %.9g mm/s above the programmed F%.9g mm/min", sp.v_mm_per_s,
                 *walked.feed_mm_per_min) +
             at(sp);
    }
    if (!(sp.chord_error_mm <= eps * rel + 1e-12)) {
      return fmt("chord error %.9g mm above the tolerance %.9g mm", sp.chord_error_mm, eps) +
             at(sp);
    }
    if (!box.holds(sp.p)) {
      return fmt("position (%.9g, %.9g, %.9g) outside the program's envelope", sp.p.x(), sp.p.y(),
                 sp.p.z()) +
             at(sp);
    }
    // The rounding of s in the differences: a few ulps of s, over T² and T³.
    const double ulps =
        16.0 * std::numeric_limits<double>::epsilon() * std::max(1.0, std::abs(s[0]));
    if (k >= 2) {
      const double at_s = (s[0] - 2.0 * s[1] + s[2]) / (T * T);
      if (since_overlap > 2 && std::abs(at_s) > a_max * rel + ulps / (T * T)) {
        return fmt("tangential acceleration %.9g mm/s^2 above %.9g", at_s, a_max) + at(sp);
      }
    }
    if (k >= 3) {
      const double jt = (s[0] - 3.0 * s[1] + 3.0 * s[2] - s[3]) / (T * T * T);
      if (since_overlap > 3 && std::abs(jt) > j_max * rel + 1e-3 + ulps / (T * T * T)) {
        return fmt("tangential jerk %.9g mm/s^3 above %.9g", jt, j_max) + at(sp);
      }
    }
    if (sp.s_mm > still_s + 1e-4 || sp.done) {
      still_s = sp.s_mm;
      still = 0;
    } else if (static_cast<double>(++still) * T > 2.0) {
      return std::string("stall: 2 s without 0.1 um of progress (limit ") +
             motion::limit_name(sp.limit_id) + ")" + at(sp);
    }
    if (sp.done) {
      periods = k;
      if (sp.v_mm_per_s != 0.0 || sp.a_mm_per_s2 != 0.0) return "not at rest at the end" + at(sp);
      const double miss = (sp.p - end).norm();
      if (!(miss <= 1e-6)) return fmt("ends %.9g mm from the programmed end point", miss) + at(sp);
      if (!job.done()) return "the last setpoint says done, the job does not";
      break;
    }
  }
  if (allocations && allocations() != before) {
    return fmt("%.0f allocations during %.0f periods", static_cast<double>(allocations() - before),
               static_cast<double>(k));
  }
  return {};
}

// Interprets, builds and walks one input. Refused: the interpreter, to_path or the job's
// construction refused the program (an InputError), it moves nothing, or its bound is above
// kMaxPeriods.
inline Outcome run(const Input& in, AllocationCount allocations = nullptr) {
  Outcome o;
  toolpath::Path path;
  try {
    toolpath::InterpretOptions opt;
    opt.max_blocks = kMaxBlocks;
    opt.tool_table = tool_table_file();
    path = toolpath::to_path(toolpath::interpret_ngc(in.program, "fuzz.ngc", opt));
  } catch (const InputError& e) {
    o.message = e.what();
    return o;
  }
  if (path.segments.empty()) {
    o.message = "no motion";
    return o;
  }
  const motion::JobConfig cfg = job_config(in.machine);
  o.bound = bound_periods(path, cfg);
  if (!(o.bound * walk_cost_factor(cfg) <= kMaxPeriods)) {
    o.message = fmt("the walk's bound %.3g periods (x %.3g for the braking horizon) is above %.3g",
                    o.bound, walk_cost_factor(cfg), kMaxPeriods);
    return o;
  }
  std::optional<motion::Job> job;
  try {
    job.emplace(path, cfg);
  } catch (const InputError& e) {
    o.message = e.what();
    return o;
  }
  o.message = walk(*job, path, o.bound, o.periods, allocations);
  o.kind = o.message.empty() ? Outcome::Walked : Outcome::Violation;
  return o;
}

}  // namespace ncd::fuzz::pipeline
