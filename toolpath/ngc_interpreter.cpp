// RS-274/NGC interpreter, LinuxCNC 2.9 dialect (docs/ngc-interpreter.md has the full list of
// what is read and refused, and how the output was checked against LinuxCNC's `rs274`).
//
// Each line goes through:
// 1. Normalisation: comments taken out (the last "( )" comment of a line is the one that counts,
//    as in LinuxCNC; "(MSG," makes a message), whitespace removed, letters lower-cased.
// 2. Reading: words letter + real value, where a real value is a number, a parameter #n,
//    #<name>, a unary function NAME[..] or a bracketed expression [..]. Binary operators
//    group left to right in five precedence levels (LinuxCNC's manual, "Expressions"):
//      **  >  * / MOD  >  + -  >  EQ NE GT GE LT LE  >  AND OR XOR
//    Parameter assignments on a line take effect after the whole line is read.
// 3. Execution in LinuxCNC's order: message, feed mode, F, S, T, M6, M3/M4/M5, M7/M8/M9, G4,
//    plane, units, cutter compensation, tool length offset, coordinate system, path control,
//    distance modes, retract mode, G10/G28/G30/G92, motion (G53 applied), M0/M1/M2/M30/M60.
//
// Every length is kept in mm inside; the program model gets program units (what LinuxCNC's
// canonical commands carry), the stored parameters and the tool table are in machine units.
// Control flow (O-words) works on the file's lines held in memory: a false `if`, a finished
// loop or a `break` scans forward to the line with the same label and the wanted keyword.
#include "toolpath/ngc_interpreter.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <string_view>
#include <unordered_map>

#include "core/error.hpp"
#include "core/number_text.hpp"
#include "toolpath/cutter_comp.hpp"

namespace ncd::toolpath {
namespace {

constexpr int kMaxParam = 5602;
constexpr double kTolEqual = 1e-6;  // LinuxCNC's TOLERANCE_EQUAL for EQ/NE and friends
// Bounds on what a program may ask for (mm, mm/min, rpm, s): beyond them the value is a typo.
constexpr double kMaxCoordMm = 1e6;
constexpr double kMinFeedMmPerMin = 1e-3;
constexpr double kMaxFeedMmPerMin = 1e6;
constexpr double kMaxSpindleRpm = 1e6;
constexpr double kMaxDwellS = 1e5;
constexpr int kMaxTurns = 10000;
constexpr int kMaxCallDepth = 100;

struct Fail {
  std::string what;
};

[[noreturn]] void fail(std::string what) {
  throw Fail{std::move(what)};
}

std::string g_name(int code10) {
  return "G" + std::to_string(code10 / 10) + (code10 % 10 ? "." + std::to_string(code10 % 10) : "");
}

struct SourceFile {
  std::string name;
  std::string text;
  std::vector<std::string_view> lines;
};

// One O-word line.
struct OLine {
  std::string label;
  std::string keyword;
  std::size_t args_at = 0;  // position in the normalised line after the keyword
};

struct Block {
  std::array<double, 26> val{};
  std::uint32_t mask = 0;
  std::array<int, 16> g{};
  int ng = 0;
  std::array<int, 8> m{};
  int nm = 0;
  bool has_message = false;
  std::string message;
  bool has(char c) const { return (mask & (1u << (c - 'a'))) != 0; }
  double v(char c) const { return val[static_cast<std::size_t>(c - 'a')]; }
  bool has_g(int code) const {
    for (int i = 0; i < ng; ++i) {
      if (g[static_cast<std::size_t>(i)] == code) return true;
    }
    return false;
  }
  bool has_m(int code) const {
    for (int i = 0; i < nm; ++i) {
      if (m[static_cast<std::size_t>(i)] == code) return true;
    }
    return false;
  }
};

// Modal group of a G code ×10 (LinuxCNC's table), −1 when unknown.
int g_group(int c) {
  switch (c) {
    case 40:
    case 100:
    case 280:
    case 281:
    case 300:
    case 301:
    case 530:
    case 920:
    case 921:
    case 922:
    case 923:
      return 0;
    case 0:
    case 10:
    case 20:
    case 30:
    case 50:
    case 51:
    case 52:
    case 53:
    case 330:
    case 331:
    case 382:
    case 383:
    case 384:
    case 385:
    case 730:
    case 740:
    case 760:
    case 800:
    case 810:
    case 820:
    case 830:
    case 840:
    case 850:
    case 860:
    case 870:
    case 880:
    case 890:
      return 1;
    case 170:
    case 171:
    case 180:
    case 181:
    case 190:
    case 191:
      return 2;
    case 900:
    case 910:
      return 3;
    case 901:
    case 911:
      return 4;
    case 930:
    case 940:
    case 950:
      return 5;
    case 200:
    case 210:
      return 6;
    case 400:
    case 410:
    case 411:
    case 420:
    case 421:
      return 7;
    case 430:
    case 431:
    case 432:
    case 490:
      return 8;
    case 980:
    case 990:
      return 10;
    case 540:
    case 550:
    case 560:
    case 570:
    case 580:
    case 590:
    case 591:
    case 592:
    case 593:
      return 12;
    case 610:
    case 611:
    case 640:
      return 13;
    case 960:
    case 970:
      return 14;
    case 70:
    case 80:
      return 15;
    case 520:
      return 0;
    default:
      return -1;
  }
}

int m_group(int c) {
  switch (c) {
    case 0:
    case 1:
    case 2:
    case 30:
    case 60:
      return 4;
    case 6:
    case 61:
      return 6;
    case 3:
    case 4:
    case 5:
    case 19:
      return 7;
    case 7:
    case 8:
    case 9:
      return 8;
    case 48:
    case 49:
    case 50:
    case 51:
    case 52:
    case 53:
      return 9;
    default:
      return c >= 62 && c <= 199 ? 10 : -1;
  }
}

// Out-of-scope G codes: the refusal text (construct and way out); empty when supported.
std::string g_refusal(int c) {
  switch (c) {
    case 330:
    case 331:
    case 760:
      return g_name(c) +
             " (spindle-synchronised motion, threading) is not supported; ncd drives "
             "no spindle encoder: remove the threading pass";
    case 382:
    case 383:
    case 384:
    case 385:
      return g_name(c) + " (probing) is not supported; probe on the controller, not in the program";
    case 70:
    case 80:
      return g_name(c) + " (lathe diameter/radius mode) is not supported; ncd is for mills";
    case 740:
    case 840:
    case 860:
    case 870:
    case 880:
      return g_name(c) +
             " (tapping/boring cycle needing spindle control) is not supported; use G81, G82, "
             "G83, G85 or G89, or write the moves out";
    case 50:
    case 51:
      return g_name(c) + " (spline) is not supported; use G5.2/G5.3 NURBS, G2/G3 or G1";
    case 950:
      return "G95 (feed per revolution) is not supported; use G94 with F in units per minute";
    case 960:
      return "G96 (constant surface speed) is not supported; use G97 with S in rpm";
    case 171:
    case 181:
    case 191:
      return g_name(c) + " (UVW plane) is not supported; use G17, G18 or G19";
    case 432:
      return "G43.2 (additional tool length offset) is not supported; use G43 H or G43.1";
    case 520:
      return "G52 (local offset) is not supported; use G92 or G10 L2 with G54-G59.3";
    default:
      return {};
  }
}

std::string m_refusal(int c) {
  if (c >= 100 && c <= 199) {
    return "M" + std::to_string(c) +
           " (user M code) is not supported; ncd runs no user "
           "programs: remove it or handle it on the controller";
  }
  switch (c) {
    case 19:
      return "M19 (spindle orient) is not supported; remove it";
    case 61:
      return "M61 (set current tool without a change) is not supported; use T M6";
    case 48:
    case 49:
    case 50:
    case 51:
    case 52:
    case 53:
      return "M" + std::to_string(c) + " (override control) is not supported; remove it";
    default:
      return "M" + std::to_string(c) + " is not supported (I/O, modal state or remap); remove it";
  }
}

class Interpreter {
 public:
  Interpreter(const InterpretOptions& o) : opt_(o) {
    params_.assign(kMaxParam + 1, 0.0);
    param_given_.assign(kMaxParam + 1, false);
    machine_k_ = mm_per_unit(opt_.machine_units);
    units_ = opt_.default_units;
    program_.units = units_;
    // LinuxCNC 2.9's peck clearance: 0.010 inch whatever the units.
    params_[5220] = 1.0;
    params_[5599] = 1.0;  // (DEBUG,) messages on, as LinuxCNC starts
  }

  Program run(const std::string& text, const std::string& name) {
    load_tool_table();
    load_parameters();
    files_.push_back(std::make_unique<SourceFile>());
    SourceFile& f = *files_.back();
    f.name = name;
    f.text = text;
    split_lines(f);
    program_.files.push_back(name);
    scan_subs(0);
    coord_sys_ = std::clamp(static_cast<int>(std::lround(params_[5220])), 1, 9);
    g92_ = params_[5210] != 0.0 ? Vec3(param_len(5211), param_len(5212), param_len(5213))
                                : Vec3(0, 0, 0);
    pos_ = -(g5x() + g92_);  // the machine starts at its origin
    execute_all();
    comp_call([&] { comp_.flush(); });  // a file that ends without M2 writes its last move
    return std::move(program_);
  }

  // Error position of the line being executed.
  std::string where() const {
    return files_[cur_file_]->name + ":" + std::to_string(cur_line_ + 1);
  }
  std::string line_text() const {
    if (cur_file_ >= files_.size()) return {};
    const auto& lines = files_[cur_file_]->lines;
    return cur_line_ < lines.size() ? std::string(lines[cur_line_]) : std::string();
  }

 private:
  // ---- files, tool table, parameters -------------------------------------------------------
  static void split_lines(SourceFile& f) {
    std::string_view t(f.text);
    std::size_t at = 0;
    while (at < t.size()) {
      std::size_t nl = t.find('\n', at);
      if (nl == std::string_view::npos) nl = t.size();
      std::string_view line = t.substr(at, nl - at);
      if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
      f.lines.push_back(line);
      at = nl + 1;
    }
  }

  static std::string read_file(const std::string& path, const char* what) {
    std::ifstream in(path, std::ios::binary);
    if (!in) {
      throw InputError(path + ": cannot open the " + std::string(what) +
                       "; check the path in the machine file's [program] table");
    }
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
  }

  // LinuxCNC tool.tbl: "T<n> P<pocket> Z<offset> D<diameter> ; comment", values in machine units.
  void load_tool_table() {
    for (const int t : opt_.machine_tools) tools_[t] = {0.0, 0.0, 0};
    if (opt_.tool_table.empty()) return;
    const std::string text = read_file(opt_.tool_table, "tool table");
    std::istringstream in(text);
    std::string line;
    int no = 0;
    while (std::getline(in, line)) {
      ++no;
      const auto semi = line.find(';');
      if (semi != std::string::npos) line.resize(semi);
      std::istringstream ws(line);
      std::string w;
      int tool = -1;
      double z = 0.0, d = 0.0, q = 0.0;
      while (ws >> w) {
        const char c = static_cast<char>(std::toupper(static_cast<unsigned char>(w[0])));
        double v = 0.0;
        const char* b = w.c_str() + 1;
        if (*b == '+') ++b;
        const auto r = std::from_chars(b, w.c_str() + w.size(), v);
        if (r.ec != std::errc() || r.ptr != w.c_str() + w.size() || !std::isfinite(v)) {
          throw InputError(opt_.tool_table + ":" + std::to_string(no) + ": malformed word '" + w +
                           "'; write LETTER NUMBER such as T1 P1 Z0.5 D6");
        }
        if (c == 'T') tool = static_cast<int>(v);
        if (c == 'Z') z = v;
        if (c == 'D') d = v;
        if (c == 'Q') q = v;
      }
      if (tool < 0) continue;
      tools_[tool] = {z, d, static_cast<int>(q)};
    }
  }

  // LinuxCNC's .var: lines "NUMBER VALUE" in strictly ascending order (LinuxCNC refuses a file
  // out of order); other lines (comments, blanks) are skipped and kept for the write-back. A
  // missing file is no error: every parameter starts at 0 and the write-back creates it, as
  // LinuxCNC does.
  void load_parameters() {
    if (opt_.parameter_file.empty()) return;
    std::error_code ec;
    if (!std::filesystem::exists(opt_.parameter_file, ec)) {
      if (ec) {
        throw InputError(opt_.parameter_file + ": cannot check the parameter file (" +
                         ec.message() + "); check the path in the machine file's [program] table");
      }
      return;
    }
    if (std::filesystem::is_directory(opt_.parameter_file, ec)) {
      throw InputError(opt_.parameter_file +
                       " (parameter file) is a directory; give a file name, such as " +
                       (std::filesystem::path(opt_.parameter_file) / "ncd.var").string());
    }
    const std::string text = read_file(opt_.parameter_file, "parameter file");
    std::istringstream in(text);
    std::string line;
    int no = 0;
    long last = 0;
    while (std::getline(in, line)) {
      ++no;
      if (!line.empty() && line.back() == '\r') line.pop_back();
      std::istringstream ls(line);
      long index = 0;
      double value = 0.0;
      if (!(ls >> index)) {  // blank or comment line
        var_lines_.push_back({0, line});
        continue;
      }
      if (!(ls >> value) || index < 1 || index > kMaxParam || !std::isfinite(value)) {
        throw InputError(opt_.parameter_file + ":" + std::to_string(no) +
                         ": expected 'NUMBER VALUE' with NUMBER from 1 to 5602; fix the line");
      }
      if (index <= last) {
        throw InputError(opt_.parameter_file + ":" + std::to_string(no) + ": parameter " +
                         std::to_string(index) + " comes after " + std::to_string(last) +
                         "; LinuxCNC wants the numbers in ascending order, each once: sort the "
                         "file and remove the duplicate");
      }
      last = index;
      params_[static_cast<std::size_t>(index)] = value;
      param_given_[static_cast<std::size_t>(index)] = true;
      var_lines_.push_back({static_cast<int>(index), line});
    }
  }

 public:
  // The parameter file after the program (Program::parameter_file_text): the old file's lines
  // in place, each parameter line with the parameter's value now, and every persistent
  // parameter the file lacked inserted where its number belongs.
  std::string parameter_file_text() const {
    if (opt_.parameter_file.empty()) return {};
    std::string out;
    std::size_t next_required = 0;
    const auto& req = persistent_parameters();
    const auto put = [&](int n) {
      out += std::to_string(n);
      out += '\t';
      out += format_parameter(params_[static_cast<std::size_t>(n)]);
      out += '\n';
    };
    for (const auto& [n, text] : var_lines_) {
      if (n == 0) {
        out += text;
        out += '\n';
        continue;
      }
      while (next_required < req.size() && req[next_required] < n) put(req[next_required++]);
      if (next_required < req.size() && req[next_required] == n) ++next_required;
      put(n);
    }
    while (next_required < req.size()) put(req[next_required++]);
    return out;
  }

 private:
  // LinuxCNC's persistent parameters (its `required_parameters`): G28 and G30 homes
  // 5161-5169 and 5181-5189, the G92 flag and offsets 5210-5219, the coordinate system 5220
  // and the nine systems 5221-5230 ... 5381-5390 (X Y Z A B C U V W and the XY rotation).
  static const std::vector<int>& persistent_parameters() {
    static const std::vector<int> list = [] {
      std::vector<int> v;
      for (int n = 5161; n <= 5169; ++n) v.push_back(n);
      for (int n = 5181; n <= 5189; ++n) v.push_back(n);
      for (int n = 5210; n <= 5220; ++n) v.push_back(n);
      for (int base = 5221; base <= 5381; base += 20) {
        for (int n = base; n < base + 10; ++n) v.push_back(n);
      }
      return v;
    }();
    return list;
  }

  // "%.6f" as LinuxCNC writes when that keeps the value exactly, else the shortest text that
  // reads back to the same double (rs274 reads either with "%lf").
  static std::string format_parameter(double v) {
    if (v == 0.0) v = 0.0;  // no "-0.000000"
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.6f", v);
    if (std::strtod(buf, nullptr) == v) return buf;
    const auto r = std::to_chars(buf, buf + sizeof buf, v);
    return std::string(buf, r.ptr);
  }

  double param_len(int index) const {
    return params_[static_cast<std::size_t>(index)] * machine_k_;
  }

  // ---- O-word scanning ---------------------------------------------------------------------
  // The normalised text of a line (lower case, no spaces, comments out) into `out`; the last
  // comment's text into `comment`. Returns false for a line with an unclosed comment.
  static void normalise(std::string_view line, std::string& out, std::string* comment,
                        bool* has_comment) {
    out.clear();
    for (std::size_t i = 0; i < line.size(); ++i) {
      const char c = line[i];
      if (c == ';') break;
      if (c == '(') {
        const std::size_t close = line.find(')', i + 1);
        if (close == std::string_view::npos)
          fail("comment '(' is not closed on this line; add ')'");
        const std::size_t nested = line.find('(', i + 1);
        if (nested < close) fail("nested '(' inside a comment; remove the inner '('");
        if (comment) {
          *comment = std::string(line.substr(i + 1, close - i - 1));
          *has_comment = true;
        }
        i = close;
        continue;
      }
      if (c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f') continue;
      out.push_back(c >= 'A' && c <= 'Z' ? static_cast<char>(c - 'A' + 'a') : c);
    }
  }

  // O-word of a normalised line (after an optional '/' and N number), or false.
  static bool parse_oline(const std::string& s, OLine& o) {
    std::size_t i = 0;
    if (i < s.size() && s[i] == '/') ++i;
    if (i < s.size() && s[i] == 'n') {
      ++i;
      while (i < s.size() && (std::isdigit(static_cast<unsigned char>(s[i])) || s[i] == '.')) ++i;
    }
    if (i >= s.size() || s[i] != 'o') return false;
    ++i;
    if (i < s.size() && s[i] == '<') {
      const std::size_t close = s.find('>', i);
      if (close == std::string::npos) fail("O-word name without a closing '>'; write o<name>");
      o.label = s.substr(i + 1, close - i - 1);
      i = close + 1;
    } else {
      const std::size_t b = i;
      while (i < s.size() && std::isdigit(static_cast<unsigned char>(s[i]))) ++i;
      if (i == b) fail("O-word without a number or <name>; write o100 or o<name>");
      // The number as written without its leading zeros (o010 is o10); any length.
      std::size_t z = b;
      while (z + 1 < i && s[z] == '0') ++z;
      o.label = s.substr(z, i - z);
    }
    const std::size_t kb = i;
    while (i < s.size() && std::isalpha(static_cast<unsigned char>(s[i]))) ++i;
    o.keyword = s.substr(kb, i - kb);
    o.args_at = i;
    return true;
  }

  bool oline_at(std::size_t file, std::size_t line, OLine& o) {
    const std::string_view l = files_[file]->lines[line];
    std::size_t i = 0;
    while (i < l.size() && (l[i] == ' ' || l[i] == '\t')) ++i;
    if (i >= l.size()) return false;
    const char c = l[i];
    if (c != 'o' && c != 'O' && c != 'n' && c != 'N' && c != '/') return false;
    std::string s;
    normalise(l, s, nullptr, nullptr);
    return parse_oline(s, o);
  }

  // Subroutine definitions of a file: label → line of its "sub".
  void scan_subs(std::size_t file) {
    const auto& lines = files_[file]->lines;
    OLine o;
    for (std::size_t i = 0; i < lines.size(); ++i) {
      try {
        if (oline_at(file, i, o) && o.keyword == "sub") subs_.try_emplace(o.label, file, i);
      } catch (const Fail&) {
        // reported when the line is executed
      }
    }
  }

  // Next line after `from` in the current file with `label` and one of the keywords.
  std::size_t seek(const std::string& label, std::initializer_list<const char*> keywords,
                   std::string& found) {
    const auto& lines = files_[cur_file_]->lines;
    OLine o;
    for (std::size_t i = cur_line_ + 1; i < lines.size(); ++i) {
      if (!oline_at(cur_file_, i, o) || o.label != label) continue;
      for (const char* k : keywords) {
        if (o.keyword == k) {
          found = o.keyword;
          return i;
        }
      }
    }
    std::string list;
    for (const char* k : keywords) list += std::string(list.empty() ? "" : " or ") + k;
    fail("o" + label + " has no matching " + list + " after it in the file; add it");
  }

  // ---- expressions -------------------------------------------------------------------------
  double read_number(const std::string& s, std::size_t& i) {
    const std::size_t b = i;
    if (i < s.size() && (s[i] == '+' || s[i] == '-')) ++i;
    const std::size_t digits_at = i;
    bool dot = false, digit = false;
    while (i < s.size()) {
      if (std::isdigit(static_cast<unsigned char>(s[i]))) {
        digit = true;
      } else if (s[i] == '.' && !dot) {
        dot = true;
      } else {
        break;
      }
      ++i;
    }
    if (!digit) {
      fail("expected a number at '" + s.substr(b, 12) + "'; write digits such as 1.5");
    }
    if (i < s.size() && (s[i] == '.' || std::isdigit(static_cast<unsigned char>(s[i])))) {
      fail("malformed number '" + s.substr(b, i - b + 1) + "...'; write one decimal point");
    }
    double v = 0.0;
    const auto r = std::from_chars(s.data() + digits_at, s.data() + i, v);
    if (r.ec != std::errc() || r.ptr != s.data() + i) {
      fail("number '" + s.substr(b, i - b) + "' is out of the range of a double; shorten it");
    }
    return s[b] == '-' ? -v : v;
  }

  double read_value(const std::string& s, std::size_t& i) {
    if (i >= s.size()) fail("a value is missing at the end of the line");
    const char c = s[i];
    double v = 0.0;
    if (c == '[') {
      v = read_expression(s, i);
    } else if (c == '#') {
      v = read_parameter(s, i);
    } else if ((c == '+' || c == '-') && i + 1 < s.size() &&
               !std::isdigit(static_cast<unsigned char>(s[i + 1])) && s[i + 1] != '.') {
      ++i;
      v = read_value(s, i);
      if (c == '-') v = -v;
    } else if (c >= 'a' && c <= 'z') {
      v = read_function(s, i);
    } else {
      v = read_number(s, i);
    }
    if (std::isnan(v)) fail("calculation resulted in 'not a number'");
    if (std::isinf(v)) fail("calculation resulted in infinity");
    return v;
  }

  static int precedence(int op) {
    switch (op) {
      case 0:
        return 6;  // **
      case 1:
      case 2:
      case 3:
        return 5;  // * / mod
      case 4:
      case 5:
        return 4;  // + -
      case 6:
      case 7:
      case 8:
      case 9:
      case 10:
      case 11:
        return 3;  // eq ne gt ge lt le
      default:
        return 2;  // and or xor
    }
  }

  // Binary operator at i (advances), or −1 for ']'.
  int read_operator(const std::string& s, std::size_t& i) {
    static constexpr std::array<const char*, 15> names = {
        "**", "*", "/", "mod", "+", "-", "eq", "ne", "gt", "ge", "lt", "le", "and", "or", "xor"};
    if (i < s.size() && s[i] == ']') {
      ++i;
      return -1;
    }
    for (std::size_t k = 0; k < names.size(); ++k) {
      const std::size_t n = std::char_traits<char>::length(names[k]);
      if (s.compare(i, n, names[k]) == 0) {
        i += n;
        return static_cast<int>(k);
      }
    }
    if (i >= s.size()) fail("expression not closed; add ']'");
    fail("unknown operator at '" + s.substr(i, 8) +
         "'; use ** * / MOD + - EQ NE GT GE LT LE AND OR XOR");
  }

  static double apply(int op, double a, double b) {
    switch (op) {
      case 0: {
        if (a < 0.0 && std::floor(b) != b)
          fail("attempt to raise a negative number to a non-integer power");
        return std::pow(a, b);
      }
      case 1:
        return a * b;
      case 2:
        if (b == 0.0) fail("attempt to divide by zero");
        return a / b;
      case 3: {
        if (b == 0.0) fail("attempt to take MOD 0");
        double r = std::fmod(a, b);
        if (r < 0.0) r += std::abs(b);
        return r;
      }
      case 4:
        return a + b;
      case 5:
        return a - b;
      case 6:
        return std::abs(a - b) < kTolEqual ? 1.0 : 0.0;
      case 7:
        return std::abs(a - b) >= kTolEqual ? 1.0 : 0.0;
      case 8:
        return a > b && std::abs(a - b) >= kTolEqual ? 1.0 : 0.0;
      case 9:
        return a > b || std::abs(a - b) < kTolEqual ? 1.0 : 0.0;
      case 10:
        return a < b && std::abs(a - b) >= kTolEqual ? 1.0 : 0.0;
      case 11:
        return a < b || std::abs(a - b) < kTolEqual ? 1.0 : 0.0;
      case 12:
        return (a != 0.0 && b != 0.0) ? 1.0 : 0.0;
      case 13:
        return (a != 0.0 || b != 0.0) ? 1.0 : 0.0;
      default:
        return ((a != 0.0) != (b != 0.0)) ? 1.0 : 0.0;
    }
  }

  // '[' value (op value)* ']' with the precedence of the top of this file, left to right.
  double read_expression(const std::string& s, std::size_t& i) {
    ++i;  // '['
    std::array<double, 8> vals{};
    std::array<int, 8> ops{};
    int top = 0;
    vals[0] = read_value(s, i);
    for (;;) {
      const int op = read_operator(s, i);
      while (top > 0 &&
             (op < 0 || precedence(op) <= precedence(ops[static_cast<std::size_t>(top - 1)]))) {
        const auto t = static_cast<std::size_t>(top);
        vals[t - 1] = apply(ops[t - 1], vals[t - 1], vals[t]);
        --top;
      }
      if (op < 0) return vals[0];
      ops[static_cast<std::size_t>(top)] = op;
      ++top;
      vals[static_cast<std::size_t>(top)] = read_value(s, i);
    }
  }

  double read_function(const std::string& s, std::size_t& i) {
    const std::size_t b = i;
    while (i < s.size() && s[i] >= 'a' && s[i] <= 'z') ++i;
    const std::string name = s.substr(b, i - b);
    if (i >= s.size() || s[i] != '[') {
      fail("'" + name +
           "' is not a function followed by '['; functions are ABS ACOS ASIN ATAN "
           "COS EXP EXISTS FIX FUP LN ROUND SIN SQRT TAN");
    }
    if (name == "exists") {
      ++i;
      if (s.compare(i, 2, "#<") != 0) fail("EXISTS takes a named parameter: EXISTS[#<name>]");
      const std::size_t close = s.find('>', i);
      if (close == std::string::npos || close + 1 >= s.size() || s[close + 1] != ']') {
        fail("EXISTS[#<name>] is not closed; add '>]'");
      }
      const std::string pname = s.substr(i + 2, close - i - 2);
      i = close + 2;
      return named_exists(pname) ? 1.0 : 0.0;
    }
    const double a = read_expression(s, i);
    constexpr double kDeg = 180.0 / kPi;
    if (name == "atan") {
      if (i >= s.size() || s[i] != '/' || i + 1 >= s.size() || s[i + 1] != '[') {
        fail("ATAN needs two arguments: ATAN[y]/[x]");
      }
      ++i;
      const double x = read_expression(s, i);
      return std::atan2(a, x) * kDeg;
    }
    if (name == "abs") return std::abs(a);
    if (name == "acos") {
      if (a < -1.0 || a > 1.0) fail("argument " + text::sig(a) + " of ACOS is out of [-1, 1]");
      return std::acos(a) * kDeg;
    }
    if (name == "asin") {
      if (a < -1.0 || a > 1.0) fail("argument " + text::sig(a) + " of ASIN is out of [-1, 1]");
      return std::asin(a) * kDeg;
    }
    if (name == "cos") return std::cos(a / kDeg);
    if (name == "sin") return std::sin(a / kDeg);
    if (name == "tan") return std::tan(a / kDeg);
    if (name == "exp") return std::exp(a);
    if (name == "fix") return std::floor(a);
    if (name == "fup") return std::ceil(a);
    if (name == "round") return std::round(a);
    if (name == "ln") {
      if (a <= 0.0) fail("argument " + text::sig(a) + " of LN is not greater than 0");
      return std::log(a);
    }
    if (name == "sqrt") {
      if (a < 0.0) fail("argument " + text::sig(a) + " of SQRT is negative");
      return std::sqrt(a);
    }
    fail("unknown function '" + name +
         "'; functions are ABS ACOS ASIN ATAN COS EXP EXISTS FIX "
         "FUP LN ROUND SIN SQRT TAN");
  }

  int param_index(const std::string& s, std::size_t& i) {
    const double v = read_value(s, i);
    const double r = std::round(v);
    if (std::abs(v - r) > 1e-4 || r < 1 || r > kMaxParam) {
      fail("parameter number " + text::sig(v) + " is out of range; use #1 to #5602");
    }
    return static_cast<int>(r);
  }

  std::string read_name(const std::string& s, std::size_t& i) {
    const std::size_t close = s.find('>', i);
    if (close == std::string::npos) fail("named parameter without a closing '>'; write #<name>");
    std::string name = s.substr(i + 1, close - i - 1);
    if (name.empty()) fail("empty parameter name #<>; give it a name");
    i = close + 1;
    return name;
  }

  bool named_exists(const std::string& name) const {
    if (!name.empty() && name[0] == '_') return globals_.count(name) || predefined(name, nullptr);
    return frames_.back().locals.count(name) > 0;
  }

  bool predefined(const std::string& name, double* out) const {
    const double k = mm_per_unit(units_);
    if (name == "_x" || name == "_y" || name == "_z") {
      if (out) *out = pos_[name[1] - 'x'] / k;
      return true;
    }
    if (name == "_value" || name == "_value_returned") {
      if (out) *out = name == "_value" ? value_ : (value_returned_ ? 1.0 : 0.0);
      return true;
    }
    return false;
  }

  double read_parameter(const std::string& s, std::size_t& i) {
    ++i;  // '#'
    if (i < s.size() && s[i] == '<') {
      const std::string name = read_name(s, i);
      double v = 0.0;
      if (name[0] == '_') {
        const auto it = globals_.find(name);
        if (it != globals_.end()) return it->second;
        if (predefined(name, &v)) return v;
      } else {
        const auto& locals = frames_.back().locals;
        const auto it = locals.find(name);
        if (it != locals.end()) return it->second;
      }
      fail("named parameter #<" + name + "> is not defined; assign it first");
    }
    return params_[static_cast<std::size_t>(param_index(s, i))];
  }

  // ---- reading a line ----------------------------------------------------------------------
  struct Assign {
    int index = 0;     // numbered, or 0 for named
    std::string name;  // named
    double value = 0.0;
  };

  void read_block(const std::string& s, std::size_t i, Block& b) {
    assigns_.clear();
    while (i < s.size()) {
      const char c = s[i];
      if (c == '#') {
        Assign a;
        ++i;
        if (i < s.size() && s[i] == '<') {
          a.name = read_name(s, i);
        } else {
          a.index = param_index(s, i);
        }
        if (i >= s.size() || s[i] != '=') fail("parameter setting without '='; write #1=2");
        ++i;
        a.value = read_value(s, i);
        assigns_.push_back(std::move(a));
        continue;
      }
      if (c == '@' || c == '^') {
        fail("polar coordinates (@ radius, ^ angle) are not supported; write X and Y");
      }
      if (c < 'a' || c > 'z') {
        fail("unexpected character '" + std::string(1, c) + "'; expected a word such as X1.5");
      }
      ++i;
      if (c == 'n') fail("N line number must come first on the line; move it");
      if (c == 'o') fail("an O-word must start the line (after N); put it on its own line");
      const double v = read_value(s, i);
      if (c == 'g') {
        const double scaled = v * 10.0;
        const double code = std::round(scaled);
        if (std::abs(scaled - code) > 1e-3 || code < 0 || code > 9999) {
          fail("G" + text::sig(v) + " is not a G code");
        }
        if (b.ng >= 16) fail("too many G codes on one line; split it");
        b.g[static_cast<std::size_t>(b.ng++)] = static_cast<int>(code);
        continue;
      }
      if (c == 'm') {
        const double code = std::round(v);
        if (std::abs(v - code) > 1e-3 || code < 0 || code > 9999) {
          fail("M" + text::sig(v) + " is not an M code");
        }
        if (b.nm >= 8) fail("too many M codes on one line; split it");
        b.m[static_cast<std::size_t>(b.nm++)] = static_cast<int>(code);
        continue;
      }
      if (b.has(c)) {
        fail("word " + std::string(1, static_cast<char>(c - 'a' + 'A')) +
             " appears twice on the line; keep one");
      }
      b.mask |= 1u << (c - 'a');
      b.val[static_cast<std::size_t>(c - 'a')] = v;
    }
    for (const Assign& a : assigns_) {
      if (a.index) {
        params_[static_cast<std::size_t>(a.index)] = a.value;
        param_given_[static_cast<std::size_t>(a.index)] = true;
      } else if (a.name[0] == '_') {
        globals_[a.name] = a.value;
      } else {
        frames_.back().locals[a.name] = a.value;
      }
    }
  }

  // ---- the main loop -----------------------------------------------------------------------
  struct Loop {
    enum Kind { while_loop, do_loop, repeat_loop } kind = while_loop;
    std::size_t start = 0;
    long remaining = 0;
  };
  struct Frame {
    std::size_t file = 0;
    std::size_t return_line = 0;
    std::string sub;
    std::unordered_map<std::string, double> locals;
    std::array<double, 30> saved{};
    std::map<std::string, Loop> loops;
  };

  void execute_all() {
    frames_.push_back(Frame{});
    cur_file_ = 0;
    cur_line_ = 0;
    bool first_content = true;
    std::string comment;
    while (!ended_) {
      const auto& lines = files_[cur_file_]->lines;
      if (cur_line_ >= lines.size()) {
        if (frames_.size() > 1) {
          fail("end of file inside subroutine o" + frames_.back().sub + "; add its endsub");
        }
        if (!frames_.back().loops.empty()) {
          const auto& [label, loop] = *frames_.back().loops.begin();
          cur_line_ = loop.start;
          fail("the loop o" + label +
               " opened here is not closed before the end of the file; "
               "add its end (endwhile, while or endrepeat)");
        }
        if (opened_by_percent_) {
          cur_line_ = lines.empty() ? 0 : lines.size() - 1;
          fail("the program opens with % but has neither a closing % line nor M2/M30; add one");
        }
        break;  // a program that just ends: treated as ended (LinuxCNC wants M2 or %)
      }
      if (++blocks_ > opt_.max_blocks) {
        fail("the program ran " + std::to_string(opt_.max_blocks) +
             " blocks without ending; a loop that never ends? check its condition");
      }
      const std::size_t this_line = cur_line_;
      bool has_comment = false;
      normalise(lines[cur_line_], norm_, &comment, &has_comment);
      next_line_ = cur_line_ + 1;
      if (norm_ == "%") {
        if (cur_file_ == 0 && first_content && frames_.size() == 1) {
          first_content = false;
          opened_by_percent_ = true;
          cur_line_ = next_line_;
          continue;
        }
        break;  // closing %: the end
      }
      if (!norm_.empty() || has_comment) first_content = false;
      execute_line(has_comment ? &comment : nullptr);
      (void)this_line;
      cur_line_ = next_line_;
    }
  }

  void execute_line(const std::string* comment) {
    const std::string& s = norm_;
    std::size_t i = 0;
    if (i < s.size() && s[i] == '/') {
      if (opt_.block_delete) return;
      ++i;
    }
    if (i < s.size() && s[i] == 'n') {
      ++i;
      const std::size_t b = i;
      while (i < s.size() && (std::isdigit(static_cast<unsigned char>(s[i])) || s[i] == '.')) ++i;
      if (i == b) fail("N without a line number; write N10 or remove it");
    }
    if (i < s.size() && s[i] == 'o') {
      OLine o;
      parse_oline(s, o);
      execute_oword(o);
      return;
    }
    if (skipping_sub_) return;
    Block b;
    read_block(s, i, b);
    if (comment && comment_is(*comment, "msg,")) {
      b.has_message = true;
      b.message = comment->substr(comment->find(',') + 1);
    } else if (comment && comment_is(*comment, "debug,") && params_[5599] > 0.0) {
      b.has_message = true;
      b.message = expand_debug(comment->substr(comment->find(',') + 1));
    }
    if (b.ng == 0 && b.nm == 0 && b.mask == 0 && !b.has_message) return;
    execute_block(b);
  }

  static bool comment_is(const std::string& c, const std::string& tag) {
    std::size_t i = 0;
    while (i < c.size() && std::isspace(static_cast<unsigned char>(c[i]))) ++i;
    if (c.size() < i + tag.size()) return false;
    for (std::size_t k = 0; k < tag.size(); ++k) {
      if (std::tolower(static_cast<unsigned char>(c[i + k])) != tag[k]) return false;
    }
    return true;
  }

  // (DEBUG, text): #n and #<name> replaced by their values in the format of the last %d, %f
  // or %.Nf (LinuxCNC's convert_param_comment; default six decimals), ###### when undefined.
  std::string expand_debug(const std::string& text) const {
    std::string out;
    int decimals = 6;
    for (std::size_t i = 0; i < text.size();) {
      const char c = text[i];
      if (c == '%') {
        if (i + 1 < text.size() && text[i + 1] == 'd') {
          decimals = 0;
          i += 2;
        } else if (i + 1 < text.size() && text[i + 1] == 'f') {
          decimals = 4;
          i += 2;
        } else if (i + 3 < text.size() && text[i + 1] == '.' &&
                   std::isdigit(static_cast<unsigned char>(text[i + 2])) && text[i + 3] == 'f') {
          decimals = text[i + 2] - '0';
          i += 4;
        } else {
          out.push_back('%');
          ++i;
        }
        continue;
      }
      if (c != '#') {
        out.push_back(c);
        ++i;
        continue;
      }
      ++i;
      bool found = false;
      double value = 0.0;
      if (i < text.size() && std::isdigit(static_cast<unsigned char>(text[i]))) {
        long n = 0;
        while (i < text.size() && std::isdigit(static_cast<unsigned char>(text[i]))) {
          n = std::min(n * 10 + (text[i] - '0'), 100000L);
          ++i;
        }
        if (n >= 0 && n <= kMaxParam) {
          value = params_[static_cast<std::size_t>(n)];
          found = true;
        }
      } else if (i < text.size() && text[i] == '<') {
        std::string name;
        ++i;
        while (i < text.size() && text[i] != '>') {
          if (!std::isspace(static_cast<unsigned char>(text[i]))) {
            name.push_back(static_cast<char>(std::tolower(static_cast<unsigned char>(text[i]))));
          }
          ++i;
        }
        if (i >= text.size()) fail("named parameter in a DEBUG comment without '>'; close it");
        ++i;
        if (!name.empty() && name[0] == '_') {
          const auto it = globals_.find(name);
          if (it != globals_.end()) {
            value = it->second;
            found = true;
          } else {
            found = predefined(name, &value);
            if (!found) {
              fail("#<" + name +
                   "> in a DEBUG comment is not defined; ncd knows no LinuxCNC "
                   "predefined parameters but _x _y _z _value _value_returned: remove it");
            }
          }
        } else {
          const auto& locals = frames_.back().locals;
          const auto it = locals.find(name);
          if (it != locals.end()) {
            value = it->second;
            found = true;
          }
        }
      } else {
        out.push_back('#');
        continue;
      }
      if (found) {
        char buf[64];
        const int n = std::snprintf(buf, sizeof buf, "%.*f", decimals,
                                    std::abs(value) < kTolEqual ? 0.0 : value);
        out += n > 0 && n < static_cast<int>(sizeof buf) ? std::string(buf) : "######";
      } else {
        out += "######";
      }
    }
    return out;
  }

  bool condition(const OLine& o) {
    std::size_t i = o.args_at;
    if (i >= norm_.size() || norm_[i] != '[')
      fail("o" + o.label + " " + o.keyword + " needs a condition [..]");
    return read_expression(norm_, i) != 0.0;
  }

  void execute_oword(const OLine& o) {
    const std::string& k = o.keyword;
    Frame& fr = frames_.back();
    std::string found;
    if (k == "sub") {
      // Definition met in the flow: skip its body.
      const std::size_t end = seek(o.label, {"endsub"}, found);
      next_line_ = end + 1;
      return;
    }
    if (k == "endsub" || k == "return") {
      if (frames_.size() == 1) fail("o" + o.label + " " + k + " outside a subroutine; remove it");
      std::size_t i = o.args_at;
      double returned = 0.0;
      value_returned_ = false;
      if (i < norm_.size() && norm_[i] == '[') {
        returned = read_expression(norm_, i);
        value_returned_ = true;
      }
      value_ = returned;
      for (std::size_t p = 0; p < 30; ++p) params_[p + 1] = fr.saved[p];
      const std::size_t ret_file = fr.file, ret_line = fr.return_line;
      frames_.pop_back();
      cur_file_ = ret_file;
      next_line_ = ret_line;
      return;
    }
    if (k == "call") {
      std::array<double, 30> args{};
      std::size_t i = o.args_at;
      std::size_t n = 0;
      while (i < norm_.size() && norm_[i] == '[') {
        if (n >= 30) fail("more than 30 arguments to o" + o.label + " call");
        args[n++] = read_expression(norm_, i);
      }
      if (i != norm_.size())
        fail("unexpected '" + norm_.substr(i) + "' after o" + o.label + " call arguments");
      auto it = subs_.find(o.label);
      if (it == subs_.end()) it = load_sub_file(o.label);
      if (frames_.size() > kMaxCallDepth) {
        fail("subroutine calls nested deeper than " + std::to_string(kMaxCallDepth) +
             "; a recursion that never ends?");
      }
      Frame nf;
      nf.file = cur_file_;
      nf.return_line = next_line_;
      nf.sub = o.label;
      for (std::size_t p = 0; p < 30; ++p) {
        nf.saved[p] = params_[p + 1];
        params_[p + 1] = args[p];
      }
      frames_.push_back(std::move(nf));
      cur_file_ = it->second.first;
      next_line_ = it->second.second + 1;
      return;
    }
    if (k == "if") {
      if (condition(o)) return;
      branch_skip(o.label);
      return;
    }
    if (k == "elseif" || k == "else") {
      // Reached in the flow: the branch before was taken.
      next_line_ = seek(o.label, {"endif"}, found) + 1;
      return;
    }
    if (k == "endif") return;
    if (k == "do") {
      fr.loops[o.label] = Loop{Loop::do_loop, cur_line_, 0};
      return;
    }
    if (k == "while") {
      const auto it = fr.loops.find(o.label);
      if (it != fr.loops.end() && it->second.kind == Loop::do_loop) {
        if (condition(o)) {
          next_line_ = it->second.start + 1;
        } else {
          fr.loops.erase(it);
        }
        return;
      }
      if (condition(o)) {
        fr.loops[o.label] = Loop{Loop::while_loop, cur_line_, 0};
      } else {
        fr.loops.erase(o.label);
        next_line_ = seek(o.label, {"endwhile"}, found) + 1;
      }
      return;
    }
    if (k == "endwhile") {
      const auto it = fr.loops.find(o.label);
      if (it == fr.loops.end()) fail("o" + o.label + " endwhile without its while; add it");
      next_line_ = it->second.start;
      return;
    }
    if (k == "repeat") {
      std::size_t i = o.args_at;
      if (i >= norm_.size() || norm_[i] != '[') fail("o" + o.label + " repeat needs a count [n]");
      const double n = read_expression(norm_, i);
      if (n > 1e9) fail("repeat count " + text::sig(n) + " is absurd; at most 1e9");
      const long count = static_cast<long>(std::round(n));
      if (count <= 0) {
        next_line_ = seek(o.label, {"endrepeat"}, found) + 1;
      } else {
        fr.loops[o.label] = Loop{Loop::repeat_loop, cur_line_, count};
      }
      return;
    }
    if (k == "endrepeat") {
      const auto it = fr.loops.find(o.label);
      if (it == fr.loops.end()) fail("o" + o.label + " endrepeat without its repeat; add it");
      if (--it->second.remaining > 0) {
        next_line_ = it->second.start + 1;
      } else {
        fr.loops.erase(it);
      }
      return;
    }
    if (k == "break" || k == "continue") {
      const auto it = fr.loops.find(o.label);
      if (it == fr.loops.end()) fail("o" + o.label + " " + k + " outside its loop");
      const Loop loop = it->second;
      if (loop.kind == Loop::do_loop && k == "continue") {
        fail("o" + o.label +
             " continue inside a do loop: LinuxCNC leaves the loop there, "
             "which is rarely meant; use a while loop");
      }
      if (loop.kind == Loop::repeat_loop) {
        fail("o" + o.label + " " + k + " inside a repeat loop: LinuxCNC allows " + k +
             " only in while and do loops; use a while loop with a counter");
      }
      const std::size_t end = loop.kind == Loop::while_loop ? seek(o.label, {"endwhile"}, found)
                              : loop.kind == Loop::do_loop  ? seek(o.label, {"while"}, found)
                                                            : seek(o.label, {"endrepeat"}, found);
      if (k == "break") {
        fr.loops.erase(o.label);
        next_line_ = end + 1;
      } else {
        next_line_ = loop.kind == Loop::while_loop ? loop.start : end;
      }
      return;
    }
    fail("unknown O-word keyword '" + k +
         "'; use sub endsub call return if elseif else endif "
         "while endwhile do repeat endrepeat break continue");
  }

  // A false if/elseif: on to the next elseif (evaluated), else or endif of the label.
  void branch_skip(const std::string& label) {
    std::string found;
    for (;;) {
      const std::size_t at = seek(label, {"elseif", "else", "endif"}, found);
      if (found != "elseif") {
        next_line_ = at + 1;
        return;
      }
      cur_line_ = at;
      normalise(files_[cur_file_]->lines[at], norm_, nullptr, nullptr);
      OLine o;
      parse_oline(norm_, o);
      if (condition(o)) {
        next_line_ = at + 1;
        return;
      }
    }
  }

  std::unordered_map<std::string, std::pair<std::size_t, std::size_t>>::iterator load_sub_file(
      const std::string& label) {
    for (const std::string& dir : opt_.subroutine_path) {
      const std::string path = (std::filesystem::path(dir) / (label + ".ngc")).string();
      std::ifstream in(path, std::ios::binary);
      if (!in) continue;
      std::ostringstream t;
      t << in.rdbuf();
      files_.push_back(std::make_unique<SourceFile>());
      SourceFile& f = *files_.back();
      f.name = path;
      f.text = t.str();
      split_lines(f);
      program_.files.push_back(path);
      scan_subs(files_.size() - 1);
      const auto it = subs_.find(label);
      if (it != subs_.end()) return it;
      fail(path + " has no o<" + label + "> sub; define it there");
    }
    fail("subroutine o" + label + " is not defined in the file nor found as " + label +
         ".ngc on the subroutine path; define it or set [program] subroutine_path");
  }

  // ---- execution of a block ----------------------------------------------------------------
  double k() const { return mm_per_unit(units_); }
  Vec3 g5x() const {
    const int base = 5201 + 20 * coord_sys_;
    return Vec3(param_len(base), param_len(base + 1), param_len(base + 2));
  }
  Vec3 total_offset() const { return g5x() + g92_ + tool_offset_; }

  void check_block(const Block& b) {
    std::array<int, 16> gg;
    gg.fill(-1);
    for (int n = 0; n < b.ng; ++n) {
      const int c = b.g[static_cast<std::size_t>(n)];
      const int grp = g_group(c);
      if (grp < 0)
        fail(g_name(c) + " is not supported (unknown, or a lathe/remap code); remove it");
      const std::string r = g_refusal(c);
      if (!r.empty()) fail(r);
      auto& slot = gg[static_cast<std::size_t>(grp)];
      if (slot >= 0 && grp != 0) {
        fail(g_name(slot) + " and " + g_name(c) + " are in the same modal group; keep one");
      }
      if (grp == 0 && slot >= 0 && !(slot == 530 || c == 530)) {
        fail(g_name(slot) + " and " + g_name(c) +
             " are both non-modal codes; put them on two lines");
      }
      if (grp == 0 && c == 530) continue;
      slot = c;
    }
    std::array<int, 11> mg;
    mg.fill(-1);
    for (int n = 0; n < b.nm; ++n) {
      const int c = b.m[static_cast<std::size_t>(n)];
      const int grp = m_group(c);
      if (grp < 0) fail("M" + std::to_string(c) + " is not supported (unknown M code); remove it");
      if (grp >= 9 || c == 19 || c == 61) fail(m_refusal(c));
      auto& slot = mg[static_cast<std::size_t>(grp)];
      if (slot >= 0) {
        fail("M" + std::to_string(slot) + " and M" + std::to_string(c) +
             " are in the same modal group; keep one");
      }
      slot = c;
    }
    for (const char c : {'a', 'b', 'c', 'u', 'v', 'w'}) {
      if (b.has(c) && b.v(c) != 0.0) {
        fail(std::string(1, static_cast<char>(std::toupper(c))) + text::sig(b.v(c)) +
             ": axes other than X, Y, Z are not supported; ncd drives three axes: remove the word");
      }
    }
    if (b.has('e')) fail("E word is not supported (it belongs to G76/M66); remove it");
    if (b.has('d') && !b.has_g(410) && !b.has_g(420) && !b.has_g(411) && !b.has_g(421)) {
      fail("D" + text::sig(b.v('d')) +
           " without G41/G42 (D is the cutter compensation tool or diameter); remove it or add "
           "G41/G42");
    }
  }

  // A word no code on the line (or the modal motion) reads is an error, as in LinuxCNC.
  void check_words_used(const Block& b, int motion_word, int nonmodal) const {
    const bool axes = b.has('x') || b.has('y') || b.has('z');
    const int mm = motion_word >= 0 ? motion_word : (axes && nonmodal < 0 ? motion_mode_ : -1);
    const bool arc = mm == 20 || mm == 30;
    const bool cyc = mm == 730 || mm == 810 || mm == 820 || mm == 830 || mm == 850 || mm == 890;
    const bool nurbs = mm == 52;
    const bool g64 = b.has_g(640);
    const auto need = [&](char c, bool ok, const char* users) {
      if (b.has(c) && !ok) {
        fail(std::string(1, static_cast<char>(std::toupper(c))) + text::sig(b.v(c)) +
             " with no code that uses it (" + users + "); remove it");
      }
    };
    need('i', arc, "G2/G3");
    need('j', arc, "G2/G3");
    need('k', arc, "G2/G3");
    need('r', arc || cyc || nonmodal == 100, "G2/G3 R, canned cycles, G10");
    need('p', arc || cyc || nurbs || g64 || nonmodal == 40 || nonmodal == 100,
         "G4, G10, G64, G82, G89, G2/G3 turns, G5.2 weights");
    need('q', g64 || mm == 730 || mm == 830, "G64, G73, G83");
    need('l', cyc || nurbs || nonmodal == 100 || b.has_g(411) || b.has_g(421),
         "G10, canned cycles, G5.2, G41.1/G42.1");
  }

  double len_word(const Block& b, char c) const {
    const double v = b.v(c) * k();
    if (std::abs(v) > kMaxCoordMm) {
      fail(std::string(1, static_cast<char>(std::toupper(c))) + text::sig(b.v(c)) + " is beyond ±" +
           text::sig(kMaxCoordMm) + " mm; check the number");
    }
    return v;
  }

  // While a compensated move waits (docs/ngc-interpreter.md, "Cutter radius compensation"),
  // events wait behind it, as LinuxCNC queues them; messages go out at once, as in LinuxCNC.
  void emit(Event e) {
    const bool message = std::holds_alternative<MessageEvent>(e);
    Step st;
    st.item = std::move(e);
    st.src = src();
    if (comp_.pending() && !message) {
      comp_.event(std::move(st));
    } else {
      program_.steps.push_back(std::move(st));
    }
  }

  template <class F>
  void comp_call(F&& f) {
    try {
      f();
    } catch (const CutterCompError& e) {
      fail(e.what);
    }
  }

  // LinuxCNC refuses these while compensation is on (G41/G42 even with a radius of 0).
  void refuse_with_comp(const std::string& what) const {
    if (comp_.on()) {
      fail("cannot " + what +
           " with cutter radius compensation on (LinuxCNC refuses it too); turn it off with G40 "
           "first");
    }
  }
  SourceRef src() const {
    return SourceRef{static_cast<int>(cur_file_), static_cast<int>(cur_line_ + 1)};
  }

  void emit_motion(Motion&& m) {
    m.src = src();
    if (start_override_mm_) {  // the first move after G40 starts where the tool stands
      m.start = *start_override_mm_ / k();
      start_override_mm_.reset();
    }
    Step st;
    st.src = m.src;
    st.item = std::move(m);
    program_.steps.push_back(std::move(st));
  }

  Motion base_motion(bool rapid) const {
    Motion m;
    const double kk = k();
    m.start = pos_ / kk;
    m.units = units_;
    m.rapid = rapid;
    m.feed_mode = feed_mode_;
    m.feed = rapid ? 0.0 : feed_;
    m.spindle = spindle_;
    m.spindle_rpm = speed_;
    m.tool = tool_;
    m.offset = total_offset() / kk;
    m.start_known = known_[0] && known_[1] && known_[2];
    for (std::size_t a = 0; a < 3; ++a) m.end_known[a] = known_[a] || pending_known_[a];
    return m;
  }

  // Axes programmed by the move just emitted are known from now on (its own start was not).
  void settle_known() {
    for (std::size_t a = 0; a < 3; ++a) {
      known_[a] = known_[a] || pending_known_[a];
      pending_known_[a] = false;
    }
  }

  void line_to(const Vec3& end_mm, bool rapid) {
    if (comp_.offsetting()) {
      Motion m = base_motion(rapid);
      m.src = src();
      comp_call([&] { comp_.line(end_mm, m); });
      pos_ = comp_.tool();
      settle_known();
      return;
    }
    Motion m = base_motion(rapid);
    m.geometry = LineMove{end_mm / k()};
    emit_motion(std::move(m));
    pos_ = end_mm;
    settle_known();
  }

  void execute_block(Block& b) {
    check_block(b);
    const auto group_code = [&](int grp) {
      for (int n = 0; n < b.ng; ++n) {
        if (g_group(b.g[static_cast<std::size_t>(n)]) == grp &&
            b.g[static_cast<std::size_t>(n)] != 530)
          return b.g[static_cast<std::size_t>(n)];
      }
      return -1;
    };
    const int motion_word = group_code(1);
    const int nonmodal = group_code(0);
    if (nurbs_open_) {
      nurbs_line(b, motion_word);
      return;
    }
    check_words_used(b, motion_word, nonmodal);
    // 1. message
    if (b.has_message) emit(MessageEvent{b.message});
    // 2. feed mode
    if (b.has_g(930)) {
      if (comp_.on())
        fail(
            "G93 (inverse time) with cutter radius compensation on is not supported: LinuxCNC "
            "times the compensated moves by the programmed lengths; use G94");
      feed_mode_ = FeedMode::inverse_time;
    }
    if (b.has_g(940)) {
      feed_mode_ = FeedMode::per_minute;
      feed_ = 0.0;
    }
    // 3. F
    if (b.has('f')) {
      const double f = b.v('f');
      if (f < 0.0) fail("negative feed F" + text::sig(f) + "; F must be positive");
      const double f_mm = feed_mode_ == FeedMode::per_minute ? f * k() : f;
      if (f != 0.0 && (f_mm < kMinFeedMmPerMin || f_mm > kMaxFeedMmPerMin)) {
        fail("feed F" + text::sig(f) + " is outside " + text::sig(kMinFeedMmPerMin) + " to " +
             text::sig(kMaxFeedMmPerMin) +
             (feed_mode_ == FeedMode::per_minute ? " mm/min" : " 1/min") +
             "; check the number and the units (G20/G21)");
      }
      feed_ = f;
    }
    // 4. S
    bool spindle_changed = false;
    if (b.has('s')) {
      double s = b.v('s');
      if (s < 0.0) fail("negative spindle speed S" + text::sig(s) + "; S must be 0 or more");
      if (s > kMaxSpindleRpm)
        fail("spindle speed S" + text::sig(s) + " is above " + text::sig(kMaxSpindleRpm) + " rpm");
      s = s + 0.0;  // S-0 is 0
      if (s != speed_) spindle_changed = spindle_ != SpindleDir::off;
      speed_ = s;
    }
    // 5. T
    if (b.has('t')) {
      const double t = b.v('t');
      if (t < 0 || t != std::floor(t) || t > 99999)
        fail("tool number T" + text::sig(t) + " must be a whole number ≥ 0");
      const int tn = static_cast<int>(t);
      if (tn != 0 && !tools_.count(tn)) {
        fail("tool T" + std::to_string(tn) + " is not in the tool table" +
             (opt_.tool_table.empty() ? std::string(" (none given)") : " " + opt_.tool_table) +
             "; add it to the tool table ([program] tool_table)");
      }
      selected_tool_ = tn;
    }
    // 6. M6
    if (b.has_m(6)) {
      refuse_with_comp("change tools (M6)");
      if (selected_tool_ < 0) fail("M6 without a T word before it; select the tool with T");
      if (spindle_ != SpindleDir::off) {
        spindle_ = SpindleDir::off;
        emit(SpindleEvent{SpindleDir::off, speed_});
        spindle_changed = false;
      }
      tool_ = selected_tool_;
      const auto it = tools_.find(tool_);
      const double length = it == tools_.end() ? 0.0 : it->second.z * machine_k_ / k();
      emit(ToolChangeEvent{tool_, length});
    }
    // 7. spindle
    if (b.has_m(3) || b.has_m(4) || b.has_m(5)) {
      const SpindleDir d = b.has_m(3)   ? SpindleDir::cw
                           : b.has_m(4) ? SpindleDir::ccw
                                        : SpindleDir::off;
      if (d != spindle_) spindle_changed = true;
      spindle_ = d;
    }
    if (spindle_changed) emit(SpindleEvent{spindle_, speed_});
    // 8. coolant
    if (b.has_m(7) || b.has_m(8) || b.has_m(9)) {
      if (b.has_m(9)) mist_ = flood_ = false;
      if (b.has_m(7)) mist_ = true;
      if (b.has_m(8)) flood_ = true;
      emit(CoolantEvent{mist_, flood_});
    }
    // 10. dwell
    if (nonmodal == 40) {
      if (!b.has('p')) fail("G4 without P; give the dwell time in seconds, P0.5");
      const double p = b.v('p');
      if (p < 0.0 || p > kMaxDwellS)
        fail("dwell G4 P" + text::sig(p) + " must be from 0 to " + text::sig(kMaxDwellS) + " s");
      emit(DwellEvent{p});
    }
    // 11. plane
    if ((b.has_g(170) && plane_ != Plane::xy) || (b.has_g(180) && plane_ != Plane::xz) ||
        b.has_g(190)) {
      refuse_with_comp("change the plane (or use G19)");
    }
    if (b.has_g(170)) plane_ = Plane::xy;
    if (b.has_g(180)) plane_ = Plane::xz;
    if (b.has_g(190)) plane_ = Plane::yz;
    // 12. units
    if (b.has_g(200) || b.has_g(210)) {
      const Units u = b.has_g(200) ? Units::inch : Units::mm;
      if (u != units_) refuse_with_comp("change units");
      if (u != units_) {
        units_ = u;
        emit(UnitsEvent{u});
      }
    }
    // 13. cutter radius compensation
    if (const int cc = group_code(7); cc >= 0) cutter_comp(b, cc);
    // 14. tool length offset
    if (b.has_g(430) || b.has_g(431) || b.has_g(490)) {
      refuse_with_comp("change the tool length offset");
      Vec3 off(0, 0, 0);
      int h = -1;
      if (b.has_g(430)) {
        h = tool_;
        if (b.has('h')) {
          const double hv = b.v('h');
          if (hv < 0 || hv != std::floor(hv))
            fail("G43 H" + text::sig(hv) + ": H must be a tool number");
          h = static_cast<int>(hv);
        }
        if (h != 0) {
          const auto it = tools_.find(h);
          if (it == tools_.end())
            fail("G43 H" + std::to_string(h) + ": tool " + std::to_string(h) +
                 " is not in the tool table; add it");
          off.z() = it->second.z * machine_k_;
        }
      } else if (b.has_g(431)) {
        if (b.has('z')) off.z() = len_word(b, 'z');
        if (b.has('x')) off.x() = len_word(b, 'x');
        if (b.has('y')) off.y() = len_word(b, 'y');
      }
      // With M6 on the same line LinuxCNC re-reads the position after the change, before the
      // offset shifts it: the program position stays (rs274 shows it so).
      if (!b.has_m(6)) pos_ += tool_offset_ - off;
      tool_offset_ = off;
      emit(ToolOffsetEvent{off / k(), units_, h});
    } else if (b.has('h')) {
      fail("H word without G43; write G43 H" + text::sig(b.v('h')));
    }
    // 15. coordinate system
    if (const int cs = group_code(12); cs >= 0) {
      refuse_with_comp("change the coordinate system");
      const int n = cs < 590 ? (cs - 540) / 10 + 1 : 6 + (cs - 590);
      const Vec3 old = g5x();
      coord_sys_ = n;
      params_[5220] = n;
      pos_ += old - g5x();
    }
    // 16. path control
    if (const int pc = group_code(13); pc >= 0) {
      refuse_with_comp("change the path control mode");
      PathControlEvent e;
      e.mode = pc == 610   ? PathControl::exact_path
               : pc == 611 ? PathControl::exact_stop
                           : PathControl::blend;
      if (pc == 640) {
        if (b.has('p')) {
          if (b.v('p') < 0.0)
            fail("G64 P" + text::sig(b.v('p')) +
                 ": the blend tolerance must be 0 or more (LinuxCNC would take it as 0); write P0 "
                 "or a positive tolerance");
          e.p = b.v('p');
        }
        if (b.has('q')) {
          if (b.v('q') < 0.0)
            fail("G64 Q" + text::sig(b.v('q')) +
                 ": the naive-CAM tolerance must be 0 or more; write Q0 or a positive tolerance");
          if (!b.has('p')) fail("G64 Q without P; give P as well");
          e.q = b.v('q');
        }
      }
      e.units = units_;
      control_ = e;
      emit(e);
    }
    // 17. distance modes
    if (b.has_g(900)) incremental_ = false;
    if (b.has_g(910)) incremental_ = true;
    if (b.has_g(901)) ijk_absolute_ = true;
    if (b.has_g(911)) ijk_absolute_ = false;
    // 18. retract mode
    if (b.has_g(980) || b.has_g(990)) refuse_with_comp("change the retract mode (G98/G99)");
    if (b.has_g(980)) retract_r_ = false;
    if (b.has_g(990)) retract_r_ = true;
    if (b.has_g(970)) { /* rpm mode: the default */
    }
    // 19. non-modal
    bool axes_used = b.has_g(431);
    if (nonmodal == 100 || nonmodal == 280 || nonmodal == 300 || nonmodal == 281 ||
        nonmodal == 301 || (nonmodal >= 920 && nonmodal <= 923)) {
      refuse_with_comp("use " + g_name(nonmodal));
    }
    switch (nonmodal) {
      case 100:
        g10(b);
        axes_used = true;
        break;
      case 280:
      case 300:
        home(b, nonmodal == 280 ? 5161 : 5181);
        axes_used = true;
        break;
      case 281:
      case 301:
        store_home(nonmodal == 281 ? 5161 : 5181);
        break;
      case 920:
        g92(b);
        axes_used = true;
        break;
      case 921:
      case 922:
        pos_ += g92_;
        g92_ = Vec3(0, 0, 0);
        if (nonmodal == 921) {
          for (int p = 5210; p <= 5219; ++p) params_[static_cast<std::size_t>(p)] = 0.0;
        }
        break;
      case 923: {
        const Vec3 n(param_len(5211), param_len(5212), param_len(5213));
        pos_ += g92_ - n;
        g92_ = n;
        params_[5210] = 1.0;
        break;
      }
      default:
        break;
    }
    // 20. motion
    const bool g53 = b.has_g(530);
    const bool axis_words = b.has('x') || b.has('y') || b.has('z');
    if (motion_word >= 0) {
      if (motion_word == 800) {
        if (axis_words && !axes_used)
          fail(
              "G80 with X, Y or Z: G80 cancels motion, the axes have no meaning here; remove them");
        motion_mode_ = -1;
        cycle_il_known_ = false;
      } else {
        motion(b, motion_word, g53);
      }
    } else if (axis_words && !axes_used) {
      if (motion_mode_ < 0)
        fail(
            "X, Y or Z with no motion mode active (after G80 or G5.3); program G0 or G1 on this "
            "line");
      motion(b, motion_mode_, g53);
    } else if (g53) {
      fail("G53 without G0 or G1 on the line; write G53 G0 X...");
    }
    // 21. stops
    for (int n = 0; n < b.nm; ++n) {
      const int c = b.m[static_cast<std::size_t>(n)];
      if (c == 0 || c == 1 || c == 60 || c == 2 || c == 30) {
        // LinuxCNC writes the waiting compensated move before a stop; the end turns it off.
        comp_call([&] {
          if (c == 2 || c == 30) {
            (void)comp_.stop();
          } else {
            comp_.flush();
          }
        });
      }
      if (c == 0) emit(StopEvent{StopKind::program_stop});
      if (c == 1) emit(StopEvent{StopKind::optional_stop});
      if (c == 60) emit(StopEvent{StopKind::pallet_shuttle});
      if (c == 2 || c == 30) {
        emit(EndEvent{c});
        ended_ = true;
        // LinuxCNC's program end selects G54 again (convert_stop): the saved 5220 is 1.
        coord_sys_ = 1;
        params_[5220] = 1.0;
      }
    }
  }

  // Where X, Y, Z words take the position (incremental or absolute, G53 machine coordinates).
  // G40, G41, G42, G41.1, G42.1 (LinuxCNC's convert_cutter_compensation; the algorithm:
  // toolpath/cutter_comp.cpp).
  void cutter_comp(const Block& b, int code) {
    if (code == 400) {
      if (comp_.offsetting() && !comp_.first_move()) {
        Vec3 tool{0, 0, 0};
        comp_call([&] { tool = comp_.stop(); });
        // LinuxCNC takes the programmed point as the current one from here (an incremental
        // exit move counts from it); the exit move itself starts where the tool stands.
        pos_ = comp_.programmed();
        if ((tool - pos_).norm() > 0.0) start_override_mm_ = tool;
        arc_not_allowed_ = true;
      } else {
        (void)comp_.stop();
      }
      return;
    }
    const std::string name = g_name(code);
    if (plane_ == Plane::yz) {
      fail(name +
           " in the YZ plane: compensation works in G17 and G18 only (as in LinuxCNC); "
           "select G17 or G18 first");
    }
    if (comp_.on()) fail(name + " with cutter radius compensation already on; add G40 first");
    if (feed_mode_ == FeedMode::inverse_time) {
      fail(name +
           " in inverse time mode (G93) is not supported: LinuxCNC times the compensated moves "
           "by the programmed lengths; use G94");
    }
    double radius_mm = 0.0;
    if (code == 411 || code == 421) {
      if (!b.has('d')) fail(name + " with no D word; give the tool diameter, D6 for 6 mm");
      if (b.has('l')) {
        fail(plane_ == Plane::xy
                 ? name +
                       " with an L word, but the plane is not G18 (L is a lathe tool's "
                       "orientation, as LinuxCNC says); remove L"
                 : name +
                       " with an L word (a lathe tool's orientation): ncd compensates for mill "
                       "tools only; remove L");
      }
      radius_mm = b.v('d') * k() / 2.0;
      if (std::abs(radius_mm) > kMaxCoordMm) {
        fail(name + " D" + text::sig(b.v('d')) + " is beyond ±" + text::sig(kMaxCoordMm) +
             " mm; check the number");
      }
    } else {
      int t = tool_;
      if (b.has('d')) {
        const double d = b.v('d');
        if (std::abs(d - std::round(d)) >= 1e-4) {
          fail(name + " D" + text::sig(d) +
               ": D must be a whole number (a tool of the tool table); write D" +
               text::sig(std::round(d)) + ", or G" + std::to_string(code / 10) +
               ".1 D for a diameter");
        }
        if (d < 0) fail(name + " D" + text::sig(d) + ": D must be a tool number, 0 or more");
        t = static_cast<int>(std::lround(d));
        if (t == 0) t = tool_;  // D0 is the tool in the spindle, as in LinuxCNC
        if (t != 0 && !tools_.count(t)) {
          fail(name + " D" + std::to_string(t) + ": tool " + std::to_string(t) +
               " is not in the tool table; add it ([program] tool_table) or give G" +
               std::to_string(code / 10) + ".1 D with the diameter");
        }
      }
      const auto it = tools_.find(t);
      if (it != tools_.end()) {
        if (it->second.orientation != 0 && it->second.orientation != 9) {
          fail(name + " with lathe tool " + std::to_string(t) + " (orientation Q" +
               std::to_string(it->second.orientation) +
               (plane_ == Plane::xy ? "), but the plane is not G18 (as LinuxCNC says)"
                                    : "): ncd compensates for mill tools only") +
               "; use a mill tool");
        }
        radius_mm = it->second.diameter * machine_k_ / 2.0;
      }
    }
    comp_.start(code == 410 || code == 411 ? CutterComp::Side::left : CutterComp::Side::right,
                radius_mm, pos_, k(), plane_);
    if (start_override_mm_ && comp_.offsetting()) {  // G40 then G41 with no move between
      comp_.first_written_from(*start_override_mm_);
      start_override_mm_.reset();
    }
  }

  // With compensation moving the tool, positions are taken from the programmed point (as
  // LinuxCNC's find_ends does).
  Vec3 from() const {
    return comp_.offsetting() && !comp_.first_move() ? comp_.programmed() : pos_;
  }

  Vec3 target(const Block& b, bool g53) {
    const Vec3 base = from();
    Vec3 t = base;
    for (int a = 0; a < 3; ++a) {
      const char c = static_cast<char>('x' + a);
      if (!b.has(c)) continue;
      const double v = len_word(b, c);
      if (g53) {
        t[a] = v - total_offset()[a];
      } else {
        t[a] = incremental_ ? base[a] + v : v;
      }
      if (!incremental_ || g53) pending_known_[static_cast<std::size_t>(a)] = true;
    }
    return t;
  }

  void motion(Block& b, int code, bool g53) {
    if (code != motion_mode_ && !(code >= 730 && code <= 890)) cycle_il_known_ = false;
    if (code < 730 || code > 890) cycle_il_known_ = false;
    if (g53 && code != 0 && code != 10)
      fail("G53 only works with G0 or G1; remove G53 or use G0/G1");
    if (g53 && incremental_) fail("G53 in incremental mode (G91); switch to G90 first");
    if (g53 && comp_.offsetting())
      fail("G53 with cutter radius compensation on (LinuxCNC refuses it too); G40 first");
    if ((code == 20 || code == 30) && arc_not_allowed_) {
      fail(
          "the move just after turning cutter compensation off (G40) must be straight, not an arc "
          "(as in LinuxCNC); program a G1 exit move first");
    }
    switch (code) {
      case 0:
      case 10: {
        arc_not_allowed_ = false;
        if (code == 10) require_feed(b, "G1");
        const Vec3 t = target(b, g53);
        line_to(t, code == 0);
        motion_mode_ = code;
        return;
      }
      case 20:
      case 30:
        arc(b, code);
        motion_mode_ = code;
        return;
      case 52:
        open_nurbs(b);
        return;
      case 53:
        fail("G5.3 without an open G5.2 block; open the block with G5.2 first");
      default:
        cycle(b, code);
        return;
    }
  }

  void require_feed(const Block& b, const char* what) {
    if (feed_mode_ == FeedMode::inverse_time) {
      if (!b.has('f'))
        fail(std::string(what) + " in inverse time mode (G93) without F on the line; add F");
      if (feed_ == 0.0) fail(std::string(what) + " with inverse time F0; F must be positive");
    } else if (feed_ == 0.0) {
      fail(std::string("cannot do ") + what + " with zero feed rate; add an F word");
    }
  }

  void arc(Block& b, int code) {
    require_feed(b, code == 20 ? "G2" : "G3");
    const PlaneAxes ax = plane_axes(plane_);
    const char names[3] = {'x', 'y', 'z'};
    const char offs[3] = {'i', 'j', 'k'};
    const bool ijk = b.has('i') || b.has('j') || b.has('k');
    const bool r_form = b.has('r');
    if (!ijk && !r_form)
      fail("arc without R or I, J, K; give the centre (I J K) or the radius (R)");
    if (ijk && r_form) fail("arc with both R and I, J, K; keep one form");
    if (ijk && b.has(offs[ax.axis])) {
      fail(std::string(1, static_cast<char>(std::toupper(offs[ax.axis]))) +
           " word given for an arc in the " +
           (plane_ == Plane::xy   ? "XY"
            : plane_ == Plane::xz ? "XZ"
                                  : "YZ") +
           " plane; use the plane's two offsets");
    }
    if (ijk && ijk_absolute_ && (!b.has(offs[ax.first]) || !b.has(offs[ax.second]))) {
      fail("absolute arc centre (G90.1) needs both offsets of the plane");
    }
    if (!ijk && !b.has(names[ax.first]) && !b.has(names[ax.second])) {
      fail("R-form arc without an end point in the plane; give the plane's axis words");
    }
    const Vec3 end = target(b, false);
    const double kk = k();
    const Vec3 start = from();
    const double c1 = start[ax.first], c2 = start[ax.second];
    const double e1 = end[ax.first], e2 = end[ax.second];
    int p = 1;
    if (b.has('p')) {
      const double pv = b.v('p');
      if (pv < 1 || pv > kMaxTurns || std::abs(pv - std::round(pv)) > 1e-6) {
        fail("arc P" + text::sig(pv) + " (turns) must be a whole number from 1 to " +
             std::to_string(kMaxTurns));
      }
      p = static_cast<int>(std::lround(pv));
    }
    double cx = 0.0, cy = 0.0;
    const double radius_tol = 0.00005 * kMmPerInch;  // RADIUS_TOLERANCE, same in both units
    if (r_form) {
      const double r = len_word(b, 'r');
      if (e1 == c1 && e2 == c2)
        fail("R-form arc whose end is its start; use the I J K form for a full circle");
      const double abs_r = std::abs(r);
      const double m1 = (e1 + c1) / 2.0, m2 = (e2 + c2) / 2.0;
      double half = std::hypot(m1 - e1, m2 - e2);
      if (half - abs_r > radius_tol) {
        fail("arc radius R" + text::sig(b.v('r')) +
             " is too small to reach the end point; increase R");
      }
      if (half / abs_r > 1 - 1e-12) half = abs_r;
      const double theta =
          std::atan2(e2 - c2, e1 - c1) + (((code == 20) == (r > 0)) ? -kPi / 2 : kPi / 2);
      const double turn2 = std::asin(half / abs_r);
      const double off = abs_r * std::cos(turn2);
      cx = m1 + off * std::cos(theta);
      cy = m2 + off * std::sin(theta);
    } else {
      const double i1 = b.has(offs[ax.first]) ? len_word(b, offs[ax.first]) : 0.0;
      const double i2 = b.has(offs[ax.second]) ? len_word(b, offs[ax.second]) : 0.0;
      cx = ijk_absolute_ ? i1 : c1 + i1;
      cy = ijk_absolute_ ? i2 : c2 + i2;
      const double r1 = std::hypot(cx - c1, cy - c2);
      const double r2 = std::hypot(cx - e1, cy - e2);
      if (r1 < radius_tol || r2 < radius_tol) fail("zero-radius arc; check I, J, K");
      const double spiral_abs = (units_ == Units::inch ? 2 * 0.001 * std::sqrt(2.0) * kMmPerInch
                                                       : 2 * 0.01 * std::sqrt(2.0));
      const double abs_err = std::abs(r1 - r2);
      const double rel_err = abs_err / std::max(r1, r2);
      if (abs_err > spiral_abs * 100.0 || (rel_err > 0.001 && abs_err > spiral_abs)) {
        fail("radius to end of arc (" + text::sig(r2 / kk) + ") differs from radius to start (" +
             text::sig(r1 / kk) + "); correct the end point or I, J, K");
      }
    }
    Motion m = base_motion(false);
    if (comp_.offsetting()) {
      m.src = src();
      comp_call([&] { comp_.arc(end, cx, cy, code == 20 ? -p : p, m); });
      pos_ = comp_.tool();
      settle_known();
      return;
    }
    ArcMove a;
    a.end = end / kk;
    Vec3 c = pos_;
    c[ax.first] = cx;
    c[ax.second] = cy;
    a.centre = c / kk;
    a.plane = plane_;
    a.turns = code == 20 ? -p : p;
    m.geometry = a;
    emit_motion(std::move(m));
    pos_ = end;
    settle_known();
  }

  // ---- canned cycles (LinuxCNC's convert_cycle_xy and its plane variants) -------------------
  void cycle(Block& b, int code) {
    refuse_with_comp("use canned cycles");
    if (code != 730 && code != 810 && code != 820 && code != 830 && code != 850 && code != 890) {
      fail(g_name(code) + " is not supported; use G73 G81 G82 G83 G85 G89");
    }
    if (feed_ == 0.0) fail("canned cycle " + g_name(code) + " with zero feed rate; add F");
    if (feed_mode_ == FeedMode::inverse_time)
      fail("canned cycle in inverse time mode (G93); use G94");
    const PlaneAxes ax = plane_axes(plane_);
    const char depth_word = static_cast<char>('x' + ax.axis);
    double r_val = 0.0;
    if (b.has('r')) {
      r_val = len_word(b, 'r');
    } else if (motion_mode_ == code) {
      r_val = cycle_r_;
    } else {
      fail(g_name(code) + " without R (the retract plane) the first time; add R");
    }
    long repeats = 1;
    if (b.has('l')) {
      const double l = b.v('l');
      if (l < 1 || l > 100000 || l != std::floor(l))
        fail("cycle L" + text::sig(l) + " must be a whole number from 1 to 100000");
      repeats = static_cast<long>(l);
    }
    if (motion_mode_ != code && !b.has(depth_word)) {
      fail(g_name(code) + " without " +
           std::string(1, static_cast<char>(std::toupper(depth_word))) +
           " (the bottom) the first time; add it");
    }
    const double depth_val = b.has(depth_word) ? len_word(b, depth_word) : cycle_cc_;
    double p_val = 0.0, q_val = 0.0;
    if (code == 820 || code == 890) {
      if (!b.has('p') && motion_mode_ != code)
        fail(g_name(code) + " without P (dwell) the first time; add P");
      p_val = b.has('p') ? b.v('p') : cycle_p_;
      if (p_val < 0 || p_val > kMaxDwellS)
        fail("dwell P" + text::sig(p_val) + " must be from 0 to " + text::sig(kMaxDwellS) + " s");
    }
    if (code == 730 || code == 830) {
      if (!b.has('q') && motion_mode_ != code)
        fail(g_name(code) + " without Q (peck) the first time; add Q");
      q_val = b.has('q') ? len_word(b, 'q') : cycle_q_;
      if (q_val <= 0.0)
        fail(g_name(code) + " Q" + text::sig(q_val / k()) + ": the peck must be positive");
    }
    if (b.has('p') && code != 820 && code != 890) {
      // LinuxCNC ignores P there; so do we, silently as it does.
    }
    const double current_cc0 = pos_[ax.axis];
    if (!cycle_il_known_) {
      cycle_il_ = current_cc0;
      cycle_il_known_ = true;
    }
    double old_cc = cycle_il_;
    double current_cc = current_cc0;
    double aa = pos_[ax.first], bb = pos_[ax.second];
    double aa_inc = 0.0, bb_inc = 0.0, r = 0.0, cc = 0.0;
    const char fw = static_cast<char>('x' + ax.first), sw = static_cast<char>('x' + ax.second);
    if (!incremental_) {
      r = r_val;
      cc = depth_val;
      if (b.has(fw)) aa = len_word(b, fw);
      if (b.has(sw)) bb = len_word(b, sw);
      if (b.has(fw)) pending_known_[static_cast<std::size_t>(ax.first)] = true;
      if (b.has(sw)) pending_known_[static_cast<std::size_t>(ax.second)] = true;
      pending_known_[static_cast<std::size_t>(ax.axis)] = true;
    } else {
      if (b.has(fw)) aa_inc = len_word(b, fw);
      if (b.has(sw)) bb_inc = len_word(b, sw);
      r = r_val + old_cc;
      cc = r + depth_val;
    }
    if (r < cc)
      fail("the R plane is below the bottom of the " + g_name(code) + " cycle; R must be above " +
           std::string(1, static_cast<char>(std::toupper(depth_word))));
    const auto at = [&](double a1, double b1, double c1) {
      Vec3 p;
      p[ax.first] = a1;
      p[ax.second] = b1;
      p[ax.axis] = c1;
      return p;
    };
    if (old_cc < r) {
      line_to(at(pos_[ax.first], pos_[ax.second], r), true);
      old_cc = r;
      current_cc = old_cc;
    }
    const double clear_cc = retract_r_ ? r : old_cc;
    const PathControlEvent saved = control_;
    const bool switch_mode = saved.mode != PathControl::exact_path;
    if (switch_mode) {
      PathControlEvent e;
      e.mode = PathControl::exact_path;
      e.units = units_;
      emit(e);
    }
    const double clearance = 0.010 * kMmPerInch;  // LinuxCNC 2.9 G73/G83 rapid clearance
    for (long rep = repeats; rep > 0; --rep) {
      aa += aa_inc;
      bb += bb_inc;
      if (rep == repeats && current_cc > r) {
        line_to(at(aa, bb, current_cc), true);
        line_to(at(aa, bb, r), true);
      } else {
        line_to(at(aa, bb, clear_cc), true);
        if (clear_cc > r) line_to(at(aa, bb, r), true);
      }
      switch (code) {
        case 810:
          line_to(at(aa, bb, cc), false);
          line_to(at(aa, bb, clear_cc), true);
          break;
        case 820:
          line_to(at(aa, bb, cc), false);
          emit(DwellEvent{p_val});
          line_to(at(aa, bb, clear_cc), true);
          break;
        case 730:
        case 830: {
          long pecks = 0;
          for (double d = r - q_val; d > cc; d -= q_val) {
            if (++pecks > 100000)
              fail("peck Q is too small for the depth: more than 100000 pecks; increase Q");
            line_to(at(aa, bb, d), false);
            if (code == 830) line_to(at(aa, bb, r), true);
            line_to(at(aa, bb, d + clearance), true);
          }
          line_to(at(aa, bb, cc), false);
          line_to(at(aa, bb, clear_cc), true);
          break;
        }
        case 850:
          line_to(at(aa, bb, cc), false);
          line_to(at(aa, bb, r), false);
          line_to(at(aa, bb, clear_cc), true);
          break;
        case 890:
          line_to(at(aa, bb, cc), false);
          emit(DwellEvent{p_val});
          line_to(at(aa, bb, clear_cc), false);
          break;
        default:
          break;
      }
    }
    if (switch_mode) emit(saved);
    pos_ = at(aa, bb, clear_cc);
    cycle_cc_ = depth_val;
    cycle_r_ = r_val;
    cycle_p_ = p_val;
    cycle_q_ = q_val;
    motion_mode_ = code;
  }

  // ---- G10, G28/G30, G92 -------------------------------------------------------------------
  void g10(const Block& b) {
    if (!b.has('l')) fail("G10 without L; use G10 L2 or G10 L20");
    const double l = b.v('l');
    if (l != 2 && l != 20)
      fail("G10 L" + text::sig(l) + " is not supported; use L2 or L20 (tool table edits are not)");
    if (!b.has('p')) fail("G10 L" + text::sig(l) + " without P (coordinate system 0-9); add P");
    const double pv = b.v('p');
    if (pv < 0 || pv > 9 || pv != std::floor(pv))
      fail("G10 P" + text::sig(pv) + ": P must be 0 (current) to 9");
    if (b.has('r') && b.v('r') != 0.0)
      fail("G10 R (rotation of the coordinate system) is not supported; remove R");
    const int n = pv == 0 ? coord_sys_ : static_cast<int>(pv);
    const int base = 5201 + 20 * n;
    const Vec3 old = g5x();
    for (int a = 0; a < 3; ++a) {
      const char c = static_cast<char>('x' + a);
      if (!b.has(c)) continue;
      const double v = len_word(b, c);
      const double off = l == 2 ? v : pos_[a] + old[a] - v;
      params_[static_cast<std::size_t>(base + a)] = off / machine_k_;
    }
    if (n == coord_sys_) pos_ += old - g5x();
  }

  // G28 / G30 (LinuxCNC's convert_home): a rapid to the intermediate point the block's words
  // give (in the current frame and distance mode), then a rapid of the block's axes (all three
  // when it names none) to the stored position, parameters base..base+2 in machine coordinates
  // and units, taken back into the program's frame (less the work offset, G92 and the tool
  // length). A stored position nobody gave is refused: every parameter starts at 0, and a move
  // to machine zero is what rs274 would print, but on a machine that has its own G28 position
  // (or a work offset at the part) a rapid there runs into the part.
  void home(const Block& b, int base) {
    const bool any = b.has('x') || b.has('y') || b.has('z');
    for (int a = 0; a < 3; ++a) {
      if ((any && !b.has(static_cast<char>('x' + a))) ||
          param_given_[static_cast<std::size_t>(base + a)]) {
        continue;
      }
      const std::string g = base == 5161 ? "G28" : "G30";
      const std::string from = std::to_string(base) + "-" + std::to_string(base + 2);
      fail(g + " moves " + std::string(1, static_cast<char>('X' + a)) + " to the stored " + g +
           " position, but no parameter " + std::to_string(base + a) + " is known: " +
           (opt_.parameter_file.empty()
                ? std::string("no parameter file is given")
                : "the parameter file " + opt_.parameter_file + " does not hold it") +
           ", and a position of 0 would be a rapid to machine zero, on most set-ups into the "
           "part. Give the machine file's [program] parameter_file a LinuxCNC .var that holds " +
           from + " (the " + g + " position in machine coordinates and machine units, as the " +
           "controller has it), set it in the program (" + g + ".1 or #" + std::to_string(base) +
           "=...), or move with G53 G0 instead");
    }
    const Vec3 mid = target(b, false);
    line_to(mid, true);
    Vec3 home_prog =
        Vec3(param_len(base), param_len(base + 1), param_len(base + 2)) - total_offset();
    Vec3 end = mid;
    for (int a = 0; a < 3; ++a) {
      if (!any || b.has(static_cast<char>('x' + a))) {
        end[a] = home_prog[a];
        pending_known_[static_cast<std::size_t>(a)] = true;
      }
    }
    line_to(end, true);
  }

  void store_home(int base) {
    const Vec3 abs = pos_ + total_offset();
    for (int a = 0; a < 3; ++a) {
      params_[static_cast<std::size_t>(base + a)] = abs[a] / machine_k_;
      param_given_[static_cast<std::size_t>(base + a)] = true;
    }
  }

  void g92(const Block& b) {
    if (!(b.has('x') || b.has('y') || b.has('z')))
      fail("G92 without X, Y or Z; give the axes to set");
    for (int a = 0; a < 3; ++a) {
      const char c = static_cast<char>('x' + a);
      if (!b.has(c)) continue;
      const double v = len_word(b, c);
      const double n = pos_[a] + g92_[a] - v;
      pos_[a] = v;
      g92_[a] = n;
      params_[static_cast<std::size_t>(5211 + a)] = n / machine_k_;
    }
    params_[5210] = 1.0;
  }

  // ---- G5.2 / G5.3 (the block format of the former reader, see docs) -----------------------
  void open_nurbs(const Block& b) {
    require_feed(b, "G5.2");
    refuse_with_comp("use G5.2 NURBS");
    if (plane_ != Plane::xy) fail("G5.2 outside the XY plane; select G17 first");
    nurbs_ = {};
    nurbs_.line = static_cast<int>(cur_line_ + 1);
    nurbs_.start = pos_;
    nurbs_.points.push_back(pos_);
    nurbs_.weights.push_back(1.0);
    nurbs_open_ = true;
    if (b.has('p') && !b.has('x') && !b.has('y')) {
      if (b.v('p') <= 0.0)
        fail("weight P" + text::sig(b.v('p')) + " of the first control point must be > 0");
      nurbs_.weights[0] = b.v('p');
      if (b.has('l')) nurbs_order(b);
      return;
    }
    nurbs_point(b);
  }

  void nurbs_order(const Block& b) {
    const double l = b.v('l');
    if (l != std::floor(l) || l < 3 || l > NurbsCurve::kMaxDegree + 1) {
      fail("NURBS order L" + text::sig(l) +
           " is out of range: L must be a whole number from 3 to " +
           std::to_string(NurbsCurve::kMaxDegree + 1) + "; for straight moves use G1");
    }
    nurbs_.order = static_cast<int>(l);
  }

  void nurbs_point(const Block& b) {
    if (b.has('z'))
      fail(
          "Z in a G5.2 block: the NURBS lies in the XY plane at the current Z; move Z before G5.2");
    if (b.has('l')) nurbs_order(b);
    if (b.has('x') != b.has('y')) fail("a control point needs both X and Y; add the missing one");
    if (!b.has('x')) {
      if (b.has('p'))
        fail("P without X and Y is only allowed on the opening G5.2 line; give X and Y");
      return;
    }
    if (!b.has('p')) fail("control point without a weight; add P (P1 for an ordinary point)");
    if (b.v('p') <= 0.0) fail("weight P" + text::sig(b.v('p')) + " must be greater than 0");
    Vec3 p(len_word(b, 'x'), len_word(b, 'y'), nurbs_.start.z());
    if (incremental_)
      p = Vec3(nurbs_.points.back().x() + p.x(), nurbs_.points.back().y() + p.y(), p.z());
    nurbs_.points.push_back(p);
    nurbs_.weights.push_back(b.v('p'));
  }

  void nurbs_line(const Block& b, int motion_word) {
    if (motion_word == 53) {
      if (b.has('x') || b.has('y') || b.has('z') || b.has('p') || b.has('l')) {
        fail("G5.3 closes the block and takes no X, Y, Z, P or L; put them on the line before");
      }
      close_nurbs();
      return;
    }
    if ((motion_word >= 0 && motion_word != 52) || b.ng > (motion_word >= 0 ? 1 : 0) || b.nm > 0 ||
        b.has('s') || b.has('t') || b.has('i') || b.has('j') || b.has('k') || b.has('r') ||
        b.has('q')) {
      fail("only X, Y, P, L and F may appear inside the G5.2 block opened at line " +
           std::to_string(nurbs_.line) + "; close the block with G5.3 first");
    }
    if (b.has('f')) feed_ = b.v('f');
    nurbs_point(b);
  }

  void close_nurbs() {
    const std::size_t kk = static_cast<std::size_t>(nurbs_.order);
    const std::size_t count = nurbs_.points.size();
    if (count < kk) {
      fail("the G5.2 block opened at line " + std::to_string(nurbs_.line) + " has " +
           std::to_string(count) +
           " control points (the start included), fewer than its order L = " + std::to_string(kk) +
           "; add control points or lower L");
    }
    const std::size_t n = count - 1;
    std::vector<double> knots(n + kk + 1);
    for (std::size_t i = 0; i <= n + kk; ++i) {
      knots[i] = i < kk   ? 0.0
                 : i <= n ? static_cast<double>(i - kk + 1)
                          : static_cast<double>(n - kk + 2);
    }
    std::vector<Vec3> pts;
    for (const Vec3& p : nurbs_.points) pts.push_back(p / k());
    Motion m = base_motion(false);
    m.start = nurbs_.start / k();
    try {
      m.geometry =
          NurbsMove{NurbsCurve(nurbs_.order - 1, std::move(knots), std::move(pts), nurbs_.weights)};
    } catch (const InputError& e) {
      fail("the G5.2 block opened at line " + std::to_string(nurbs_.line) +
           " is not a valid NURBS: " + e.what());
    }
    m.src = SourceRef{static_cast<int>(cur_file_), nurbs_.line};
    Step st;
    st.src = m.src;
    st.item = std::move(m);
    program_.steps.push_back(std::move(st));
    pos_ = nurbs_.points.back();
    settle_known();
    nurbs_open_ = false;
    motion_mode_ = -1;
  }

 public:
  void finish() {
    if (nurbs_open_) {
      cur_line_ = static_cast<std::size_t>(nurbs_.line - 1);
      fail("the G5.2 block opened here is not closed; add G5.3 after its last control point");
    }
  }

 private:
  struct Tool {
    double z = 0.0;  // machine units
    double diameter = 0.0;
    int orientation = 0;  // Q: lathe tool orientation, 0 for mills
  };
  struct NurbsBlock {
    int line = 0;
    int order = 3;
    Vec3 start{0, 0, 0};
    std::vector<Vec3> points;
    std::vector<double> weights;
  };

  InterpretOptions opt_;
  double machine_k_ = 1.0;
  Program program_;
  std::vector<std::pair<int, std::string>> var_lines_;  // the .var's lines: (number or 0, text)
  std::vector<std::unique_ptr<SourceFile>> files_;
  std::unordered_map<std::string, std::pair<std::size_t, std::size_t>> subs_;
  std::vector<Frame> frames_;
  std::size_t cur_file_ = 0;
  std::size_t cur_line_ = 0;
  std::size_t next_line_ = 0;
  long blocks_ = 0;
  bool ended_ = false;
  bool opened_by_percent_ = false;
  bool skipping_sub_ = false;
  std::string norm_;
  std::vector<Assign> assigns_;
  std::vector<double> params_;
  // Parameters given by the parameter file, an assignment or G28.1/G30.1 (not the start's 0).
  std::vector<bool> param_given_;
  std::unordered_map<std::string, double> globals_;
  double value_ = 0.0;
  bool value_returned_ = false;
  std::map<int, Tool> tools_;

  Vec3 pos_{0, 0, 0};  // program coordinates, mm
  std::array<bool, 3> known_{};
  std::array<bool, 3> pending_known_{};
  Units units_ = Units::mm;
  Plane plane_ = Plane::xy;
  bool incremental_ = false;
  bool ijk_absolute_ = false;
  FeedMode feed_mode_ = FeedMode::per_minute;
  double feed_ = 0.0;  // as programmed
  SpindleDir spindle_ = SpindleDir::off;
  double speed_ = 0.0;
  bool mist_ = false, flood_ = false;
  int tool_ = 0;
  int selected_tool_ = -1;
  Vec3 tool_offset_{0, 0, 0};
  int coord_sys_ = 1;
  Vec3 g92_{0, 0, 0};
  int motion_mode_ = -1;   // none, as LinuxCNC starts
  bool retract_r_ = true;  // G99, as rs274 starts
  double cycle_r_ = 0.0, cycle_cc_ = 0.0, cycle_p_ = 0.0, cycle_q_ = 0.0, cycle_il_ = 0.0;
  bool cycle_il_known_ = false;
  PathControlEvent control_{};
  bool nurbs_open_ = false;
  NurbsBlock nurbs_;
  CutterComp comp_{program_.steps};
  bool arc_not_allowed_ = false;           // right after G40 ended a compensated path
  std::optional<Vec3> start_override_mm_;  // where the tool stands after G40
};

}  // namespace

Program interpret_ngc(const std::string& text, const std::string& name,
                      const InterpretOptions& options) {
  Interpreter in(options);
  try {
    Program p = in.run(text, name);
    in.finish();
    p.parameter_file_text = in.parameter_file_text();
    return p;
  } catch (const Fail& f) {
    throw InputError(in.where() + ": " + f.what + " (line: \"" + in.line_text() + "\")");
  }
}

Program interpret_ngc_file(const std::string& path, const InterpretOptions& options) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open; check the path and its permissions");
  std::ostringstream s;
  s << in.rdbuf();
  if (in.bad()) throw InputError(path + ": read error; check the file");
  return interpret_ngc(s.str(), path, options);
}

}  // namespace ncd::toolpath
