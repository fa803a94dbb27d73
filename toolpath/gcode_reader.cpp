// RS-274/NGC reader (the dialect is listed in gcode_reader.hpp).
//
// Each line goes through three steps:
// 1. Lexing: comments removed (an unclosed or nested '(' is an error, ';' ends the line),
//    whitespace removed, letters upper-cased, then a sequence of words letter + number
//    ([+-] digits [. digits]). G and M numbers are compared times ten (G5.2 → 52, G61.1 → 611).
// 2. Checks: each letter other than G and M at most once; at most one G or M code per modal
//    group (motion, plane, units, distance, cutter compensation, tool length, path control, feed
//    mode; spindle; stop); only the words a supported code uses.
// 3. Execution in LinuxCNC's order of execution (RS-274/NGC §3.8, LinuxCNC "G-code overview"):
//    F, S, M3/M5, setup codes, motion, M2/M30.
//
// G5.2/G5.3 follows LinuxCNC's interpreter (src/emc/rs274ngc/interp_convert.cc,
// Interp::convert_nurbs) and canon (nurbs_additional_functions.cc, knot_vector_creator):
// - the current position is the first control point, weight 1, or P when the opening G5.2 has
//   P and no X/Y ("Can specify P without X and Y only for the first control point");
// - every further control point is an X Y pair with a weight P > 0 ("Must specify positive
//   weight P for every Control Point"; the manual's "default weight 1" is not what the
//   interpreter does, so a missing P is an error here too); Z is not part of the block, the
//   curve stays at the current Z (XY plane, NURBS_FEED keeps _pos_z);
// - the order k (degree k − 1) is 3 unless an L word greater than 3 raises it; LinuxCNC ignores
//   L ≤ 3, so L1 and L2 are errors here instead of being silently ignored;
// - G5.3 needs at least k control points; with n + 1 points the knot vector has n + k + 1
//   integer knots
//       u_i = 0            for i < k
//       u_i = i − k + 1    for k ≤ i ≤ n
//       u_i = n − k + 2    for i > n
//   i.e. clamped and uniform on [0, n − k + 2];
// - after G5.3 no motion mode is active.
#include "toolpath/gcode_reader.hpp"

#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <map>
#include <optional>
#include <vector>

#include "core/error.hpp"

namespace ncd::toolpath {
namespace {

struct Word {
  char letter;
  double value;
  std::string text;  // as written, for messages
};

// The words of one line after comments and whitespace are removed.
struct Block {
  std::vector<Word> words;
  bool percent = false;  // the line is a % line
};

constexpr int kDegreeMaxOrder = NurbsCurve::kMaxDegree + 1;

enum class Motion { None, Rapid, Feed, Nurbs };

// Modal group of a G code (times ten), or -1 when the code is not supported.
int g_group(int code) {
  switch (code) {
    case 0:
    case 10:
    case 20:
    case 30:
    case 52:
    case 53:
    case 800:
      return 1;  // motion (G2/G3 listed so that they get their own message)
    case 170:
    case 180:
    case 190:
      return 2;  // plane
    case 200:
    case 210:
      return 6;  // units
    case 900:
    case 910:
      return 3;  // distance mode
    case 400:
      return 7;  // cutter compensation
    case 490:
      return 8;  // tool length offset
    case 610:
    case 611:
    case 640:
      return 13;  // path control
    case 940:
      return 5;  // feed mode
    default:
      return -1;
  }
}

int m_group(int code) {
  switch (code) {
    case 3:
    case 5:
      return 7;  // spindle
    case 2:
    case 30:
      return 4;  // stop
    default:
      return -1;
  }
}

std::string g_text(int code10) {
  return "G" + std::to_string(code10 / 10) + (code10 % 10 ? "." + std::to_string(code10 % 10) : "");
}

class Reader {
 public:
  explicit Reader(std::string name) { path_.source = std::move(name); }

  // Whole program: % lines, blank lines, then one block per line until M2/M30 or %.
  Path read(std::istream& in) {
    std::string line;
    bool seen_content = false;
    while (!ended_ && std::getline(in, line)) {
      ++line_no_;
      text_ = line;
      if (!text_.empty() && text_.back() == '\r') text_.pop_back();
      const Block b = lex(text_);
      if (b.percent) {
        if (!seen_content) {
          opened_by_percent_ = true;
          seen_content = true;
          continue;
        }
        finish_program();
        break;
      }
      if (b.words.empty()) continue;
      seen_content = true;
      execute(b);
    }
    if (!ended_ && opened_by_percent_) {
      fail_at_end("the program opens with % but has neither a closing % line nor M2/M30; add one");
    }
    if (!ended_) finish_program();
    if (path_.segments.empty()) {
      throw InputError(path_.source +
                       ": the program contains no move from a known position; it needs a G0 to "
                       "X, Y and Z, then G0/G1/G5.2 moves");
    }
    return std::move(path_);
  }

 private:
  // InputError with the file, the line number and the line text.
  [[noreturn]] void fail(const std::string& what) const {
    throw InputError(path_.source + ":" + std::to_string(line_no_) + ": " + what + " (line: \"" +
                     text_ + "\")");
  }
  [[noreturn]] void fail_at_end(const std::string& what) const {
    throw InputError(path_.source + ": " + what);
  }

  // Step 1 of the top of this file: comments and whitespace out, words in.
  Block lex(const std::string& line) const {
    std::string s;  // without comments and whitespace, upper case
    for (std::size_t i = 0; i < line.size(); ++i) {
      const char c = line[i];
      if (c == ';') break;
      if (c == '(') {
        const std::size_t close = line.find(')', i + 1);
        if (close == std::string::npos) fail("comment '(' is not closed on this line; add ')'");
        if (line.find('(', i + 1) < close) {
          fail("nested '(' inside a comment is not allowed; remove the inner '('");
        }
        i = close;
        continue;
      }
      if (c == ')') fail("')' without an opening '('; remove it or open the comment with '('");
      if (std::isspace(static_cast<unsigned char>(c))) continue;
      s.push_back(static_cast<char>(std::toupper(static_cast<unsigned char>(c))));
    }
    Block b;
    if (s == "%") {
      b.percent = true;
      return b;
    }
    std::size_t i = 0;
    if (!s.empty() && s[0] == '/') fail("block delete '/' is not supported; remove the '/'");
    while (i < s.size()) {
      const char letter = s[i];
      if (letter == '#' || letter == '[' || letter == '<') {
        fail("parameters and expressions ('#', '[ ]') are not supported; write plain numbers");
      }
      if (letter < 'A' || letter > 'Z') {
        fail("unexpected '" + s.substr(i) + "': expected a word, a letter followed by a number");
      }
      std::size_t j = i + 1;
      if (j < s.size() && (s[j] == '+' || s[j] == '-')) ++j;
      const std::size_t digits_begin = j;
      while (j < s.size() && std::isdigit(static_cast<unsigned char>(s[j]))) ++j;
      std::size_t n_digits = j - digits_begin;
      if (j < s.size() && s[j] == '.') {
        ++j;
        const std::size_t frac_begin = j;
        while (j < s.size() && std::isdigit(static_cast<unsigned char>(s[j]))) ++j;
        n_digits += j - frac_begin;
      }
      if (n_digits == 0 || (j < s.size() && s[j] == '.')) {
        std::size_t end = j;
        while (end < s.size() && !std::isalpha(static_cast<unsigned char>(s[end]))) ++end;
        fail("malformed number in word '" + s.substr(i, std::max(end, i + 1) - i) +
             "'; write the letter followed by a number such as " + std::string(1, letter) + "1.5");
      }
      const std::size_t num_begin = s[i + 1] == '+' ? i + 2 : i + 1;
      double value = 0.0;
      const auto r = std::from_chars(s.data() + num_begin, s.data() + j, value);
      if (r.ec != std::errc() || r.ptr != s.data() + j || !std::isfinite(value)) {
        fail("malformed number in word '" + s.substr(i, j - i) + "'");
      }
      b.words.push_back({letter, value, s.substr(i, j - i)});
      i = j;
    }
    return b;
  }

  // Steps 2 and 3: checks, then F, S, M3/M5, motion, M2/M30.
  void execute(const Block& b) {
    std::vector<int> gs, ms;
    std::map<char, const Word*> other;
    std::map<int, int> g_by_group, m_by_group;
    for (std::size_t k = 0; k < b.words.size(); ++k) {
      const Word& w = b.words[k];
      if (w.letter == 'N') {
        if (k != 0) fail("line number " + w.text + " must come first on the line; move it");
        if (w.value < 0 || w.value != std::floor(w.value)) {
          fail("line number " + w.text + " must be a non-negative integer");
        }
        continue;
      }
      if (w.letter == 'G' || w.letter == 'M') {
        const double scaled = w.letter == 'G' ? w.value * 10.0 : w.value;
        const double code = std::round(scaled);
        if (std::abs(scaled - code) > 1e-6 || code < 0 || code > 10000) {
          fail(w.text + " is not a " + std::string(1, w.letter) + " code");
        }
        const int c = static_cast<int>(code);
        if (w.letter == 'G') {
          check_g_supported(c, w.text);
          const int group = g_group(c);
          if (auto [it, fresh] = g_by_group.emplace(group, c); !fresh) {
            fail(g_text(it->second) + " and " + w.text +
                 " are in the same modal group; keep one per line");
          }
          gs.push_back(c);
        } else {
          const int group = m_group(c);
          if (group < 0) {
            fail(w.text +
                 " is not supported: ncd reads M3 (spindle on), M5 (off), M2 and M30 (end); "
                 "remove it or handle it outside the path");
          }
          if (auto [it, fresh] = m_by_group.emplace(group, c); !fresh) {
            fail("M" + std::to_string(it->second) + " and " + w.text +
                 " are in the same modal group; keep one per line");
          }
          ms.push_back(c);
        }
        continue;
      }
      if (std::string("XYZFSPQL").find(w.letter) == std::string::npos) {
        fail("word " + w.text +
             " is not supported: ncd reads G, M, X, Y, Z, F, S, N and P/Q/L "
             "with G64 and G5.2; remove it");
      }
      if (auto [it, fresh] = other.emplace(w.letter, &w); !fresh) {
        fail("word " + std::string(1, w.letter) + " appears twice (" + it->second->text + " and " +
             w.text + "); keep one");
      }
    }
    const auto has_g = [&](int c) {
      const auto it = g_by_group.find(g_group(c));
      return it != g_by_group.end() && it->second == c;
    };
    const auto word = [&](char l) -> const Word* {
      const auto it = other.find(l);
      return it == other.end() ? nullptr : it->second;
    };
    const bool nurbs_line =
        has_g(52) || has_g(53) || (motion_ == Motion::Nurbs && !g_by_group.count(1));
    if (word('Q') && !has_g(640)) fail("Q is only read with G64; remove it");
    if (word('P') && !has_g(640) && !nurbs_line) {
      fail("P is only read with G64 (tolerance) or in a G5.2 block (weight); remove it");
    }
    if (word('L') && !nurbs_line) fail("L is only read in a G5.2 block (order); remove it");
    if (motion_ == Motion::Nurbs) {
      for (const auto& [letter, w] : other) {
        if (std::string("XYPLF").find(letter) == std::string::npos) {
          fail(w->text + " inside the G5.2 block opened at line " + std::to_string(nurbs_.line) +
               ": only X, Y, P, L and F may appear there; close the block with G5.3 first");
        }
      }
      for (const auto& [group, code] : g_by_group) {
        if (code != 52 && code != 53) {
          fail(g_text(code) + " inside the G5.2 block opened at line " +
               std::to_string(nurbs_.line) + "; close the block with G5.3 first");
        }
      }
      if (!ms.empty()) {
        fail("M" + std::to_string(ms.front()) + " inside the G5.2 block opened at line " +
             std::to_string(nurbs_.line) + "; close the block with G5.3 first");
      }
    }

    // 1. Feed, spindle.
    if (const Word* f = word('F')) {
      if (f->value <= 0.0) fail("feed " + f->text + " must be greater than 0 mm/min");
      feed_mm_per_min_ = f->value;
    }
    if (const Word* s = word('S')) {
      if (s->value < 0.0) fail("spindle speed " + s->text + " must not be negative");
      spindle_s_ = s->value;
    }
    for (int m : ms) {
      if (m == 3) spindle_on_ = true;
      if (m == 5) spindle_on_ = false;
    }
    // 2. Setup codes have no effect on the path (G20/G91 were rejected by check_g_supported).
    // 3. Motion.
    const bool axes = word('X') || word('Y') || word('Z');
    if (g_by_group.count(1)) {
      const int c = g_by_group[1];
      if (c == 0) motion_ = Motion::Rapid;
      if (c == 10) motion_ = Motion::Feed;
      if (c == 800) {
        if (axes) fail("G80 cancels the motion mode, so X, Y, Z have no meaning here; remove them");
        motion_ = Motion::None;
      }
      if (c == 52) {
        if (motion_ != Motion::Nurbs) open_nurbs(word('P'), word('X') || word('Y'));
      }
      if (c == 53) {
        if (motion_ != Motion::Nurbs) {
          fail("G5.3 without an open G5.2 block; open the block with G5.2 first");
        }
        if (axes || word('P') || word('L')) {
          fail("G5.3 closes the block and takes no X, Y, Z, P or L; put them on the line before");
        }
        close_nurbs();
        return finish_line(ms);
      }
    }
    if (motion_ == Motion::Nurbs) {
      nurbs_point(word('X'), word('Y'), word('Z'), word('P'), word('L'), has_g(52));
    } else if (axes) {
      if (motion_ == Motion::None) {
        fail("X, Y or Z with no motion mode active; program G0 or G1 on this line");
      }
      Vec3 target;
      std::array<bool, 3> known{};
      for (int a = 0; a < 3; ++a) {
        const auto ua = static_cast<std::size_t>(a);
        const Word* w = word("XYZ"[a]);
        known[ua] = w || pos_[ua].has_value();
        target[a] = w ? w->value : pos_[ua].value_or(0.0);
      }
      move(target, known);
    }
    finish_line(ms);
  }

  // M2 and M30 end the program after the rest of the line.
  void finish_line(const std::vector<int>& ms) {
    for (int m : ms) {
      if (m == 2 || m == 30) finish_program();
    }
  }

  // The named errors for G20, G91, G2/G3, G18/G19 and any other unsupported G code.
  void check_g_supported(int c, const std::string& text) const {
    if (c == 200) {
      fail(
          "G20 (inch units) is not supported: ncd reads mm only; post-process the program in "
          "mm with G21");
    }
    if (c == 910) {
      fail(
          "G91 (incremental distance mode) is not supported: ncd reads absolute coordinates "
          "only; post-process the program with G90");
    }
    if (c == 20 || c == 30) {
      fail(text +
           " (circular arc) is not supported; post-process the program with arcs "
           "linearised into G1 moves, or as a NURBS (G5.2)");
    }
    if (c == 180 || c == 190) {
      fail(text + " selects a plane other than XY, which is not supported; use G17");
    }
    if (g_group(c) < 0) {
      fail(text +
           " is not supported: ncd reads G0, G1, G5.2/G5.3 and the setup codes G17 G21 G40 G49 "
           "G61 G61.1 G64 G80 G90 G94; remove it or post-process the program without it");
    }
  }

  // G0/G1 to target: extends the open polyline, or starts a segment where a property changes.
  void move(const Vec3& target, const std::array<bool, 3>& known_after) {
    const bool start_known = pos_[0] && pos_[1] && pos_[2];
    const bool rapid = motion_ == Motion::Rapid;
    if (!start_known) {
      if (!rapid) {
        fail(
            "G1 move from an unknown position (X, Y and Z not all programmed yet); start the "
            "program with a G0 to X, Y and Z");
      }
      for (std::size_t a = 0; a < 3; ++a) {
        if (known_after[a]) pos_[a] = target[static_cast<Eigen::Index>(a)];
      }
      open_ = false;
      return;
    }
    const Vec3 start(*pos_[0], *pos_[1], *pos_[2]);
    if (!rapid && !feed_mm_per_min_) fail("G1 move with no feed programmed; add an F word");
    for (std::size_t a = 0; a < 3; ++a) pos_[a] = target[static_cast<Eigen::Index>(a)];
    if (target == start) return;  // a move to the current position adds nothing
    const std::optional<double> feed = rapid ? std::nullopt : feed_mm_per_min_;
    const std::optional<double> spindle = spindle_rpm();
    if (open_) {
      PathSegment& last = path_.segments.back();
      if (last.rapid == rapid && last.feed_mm_per_min == feed && last.spindle_rpm == spindle) {
        std::get<Polyline>(last.geometry).points.push_back(target);
        return;
      }
    }
    PathSegment seg;
    seg.geometry = Polyline{{start, target}, {}};
    seg.feed_mm_per_min = feed;
    seg.spindle_rpm = spindle;
    seg.rapid = rapid;
    seg.source_line = line_no_;
    path_.segments.push_back(std::move(seg));
    open_ = true;
  }

  // The speed a segment carries: S while M3 is in effect, none after M5 or before M3.
  std::optional<double> spindle_rpm() const {
    return spindle_on_ ? std::optional<double>(spindle_s_) : std::nullopt;
  }

  // G5.2 outside a block: the current position becomes the first control point.
  void open_nurbs(const Word* p, bool has_xy) {
    if (!(pos_[0] && pos_[1] && pos_[2])) {
      fail(
          "G5.2 from an unknown position (X, Y and Z not all programmed yet); the current "
          "position is the first control point, so move there with G0 first");
    }
    if (!feed_mm_per_min_) fail("G5.2 with no feed programmed; add an F word");
    double w0 = 1.0;
    if (p && !has_xy) {
      if (p->value <= 0.0) fail("weight " + p->text + " of the first control point must be > 0");
      w0 = p->value;
    }
    nurbs_ = NurbsBlock{};
    nurbs_.line = line_no_;
    nurbs_.z_mm = *pos_[2];
    nurbs_.points.push_back(Vec3(*pos_[0], *pos_[1], *pos_[2]));
    nurbs_.weights.push_back(w0);
    nurbs_.first_line = true;
    motion_ = Motion::Nurbs;
    open_ = false;
  }

  // One line inside a G5.2 block: order L, and a control point X Y with weight P.
  void nurbs_point(const Word* x, const Word* y, const Word* z, const Word* p, const Word* l,
                   bool opening_line) {
    const bool first_line = nurbs_.first_line && opening_line;
    nurbs_.first_line = false;
    if (z) {
      fail(
          "Z in a G5.2 block: LinuxCNC's NURBS lies in the XY plane at the current Z; move Z "
          "before G5.2");
    }
    if (l) {
      if (l->value != std::floor(l->value) || l->value < 3 || l->value > kDegreeMaxOrder) {
        fail("order " + l->text + " is out of range: L must be an integer from 3 to " +
             std::to_string(kDegreeMaxOrder) + " (degree 2 to " +
             std::to_string(NurbsCurve::kMaxDegree) +
             "; LinuxCNC ignores L below 3); for straight moves use G1");
      }
      nurbs_.order = static_cast<int>(l->value);
    }
    if (static_cast<bool>(x) != static_cast<bool>(y)) {
      fail("a control point needs both X and Y; add the missing one");
    }
    if (!x) {
      if (p && !first_line) {
        fail(
            "P without X and Y is only allowed on the opening G5.2 line (weight of the first "
            "control point); give X and Y");
      }
      return;
    }
    if (!p) fail("control point without a weight; add P (P1 for an ordinary point)");
    if (p->value <= 0.0) fail("weight " + p->text + " must be greater than 0");
    nurbs_.points.push_back(Vec3(x->value, y->value, nurbs_.z_mm));
    nurbs_.weights.push_back(p->value);
  }

  // G5.3: LinuxCNC's knot vector and one NurbsCurve segment.
  void close_nurbs() {
    const std::size_t k = static_cast<std::size_t>(nurbs_.order);
    const std::size_t count = nurbs_.points.size();
    if (count < k) {
      fail("the G5.2 block opened at line " + std::to_string(nurbs_.line) + " has " +
           std::to_string(count) +
           " control points (the start position included), fewer than "
           "its order L = " +
           std::to_string(k) + "; add control points or lower L");
    }
    // knot_vector_creator(n, k) of LinuxCNC, see the top of this file.
    const std::size_t n = count - 1;
    std::vector<double> knots(n + k + 1);
    for (std::size_t i = 0; i <= n + k; ++i) {
      knots[i] = i < k    ? 0.0
                 : i <= n ? static_cast<double>(i - k + 1)
                          : static_cast<double>(n - k + 2);
    }
    PathSegment seg;
    try {
      seg.geometry = NurbsCurve(nurbs_.order - 1, std::move(knots), nurbs_.points, nurbs_.weights);
    } catch (const InputError& e) {
      fail("the G5.2 block opened at line " + std::to_string(nurbs_.line) +
           " is not a valid NURBS: " + e.what());
    }
    seg.feed_mm_per_min = feed_mm_per_min_;
    seg.spindle_rpm = spindle_rpm();
    seg.source_line = nurbs_.line;
    path_.segments.push_back(std::move(seg));
    const Vec3& last = nurbs_.points.back();
    pos_ = {last.x(), last.y(), last.z()};
    motion_ = Motion::None;
    open_ = false;
  }

  // End of program: no open G5.2 block, every polyline valid.
  void finish_program() {
    if (motion_ == Motion::Nurbs) {
      fail_at_end("the G5.2 block opened at line " + std::to_string(nurbs_.line) +
                  " is not closed; add G5.3 after its last control point");
    }
    for (std::size_t i = 0; i < path_.segments.size(); ++i) {
      if (const auto* pl = std::get_if<Polyline>(&path_.segments[i].geometry)) {
        validate(*pl, path_.source + ":" + std::to_string(path_.segments[i].source_line));
      }
    }
    ended_ = true;
  }

  struct NurbsBlock {
    int line = 0;
    int order = 3;
    double z_mm = 0.0;
    bool first_line = false;
    std::vector<Vec3> points;
    std::vector<double> weights;
  };

  Path path_;
  int line_no_ = 0;
  std::string text_;
  bool opened_by_percent_ = false;
  bool ended_ = false;
  std::array<std::optional<double>, 3> pos_{};
  Motion motion_ = Motion::None;
  std::optional<double> feed_mm_per_min_;
  double spindle_s_ = 0.0;
  bool spindle_on_ = false;
  bool open_ = false;  // path_.segments.back() is a Polyline that the next move may extend
  NurbsBlock nurbs_;
};

}  // namespace

Path read_gcode(std::istream& in, const std::string& name) {
  return Reader(name).read(in);
}

}  // namespace ncd::toolpath
