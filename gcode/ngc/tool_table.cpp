// The tool table and the tool catalogue (tool_table.hpp). The words before ';' are LinuxCNC's
// (T, P, Z, D, Q and the others it stores, each LETTER NUMBER); after it, tokens of the form
// key=value with key kind or teeth are ncd's, everything else is free text.
#include "gcode/ngc/tool_table.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>
#include <type_traits>

#include "core/error.hpp"
#include "core/number_text.hpp"

namespace ncd::toolpath {
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// kind= and teeth= in the comment of one entry.
void read_comment(const std::string& comment, const std::string& where, ToolTableEntry& e) {
  std::istringstream ws(comment);
  std::string w;
  while (ws >> w) {
    const auto eq = w.find('=');
    if (eq == std::string::npos) continue;
    const std::string key = lower(w.substr(0, eq)), value = w.substr(eq + 1);
    if (key == "kind") {
      const auto kind = tool_kind_from_text(lower(value));
      if (!kind) {
        throw InputError(where + ": kind=" + value + " is not a tool kind; write one of " +
                         kToolKindsText +
                         " (kind=flat) in the comment after ';', or leave kind= out: a tool "
                         "of no stated kind runs at its programmed feed");
      }
      e.kind = *kind;
    } else if (key == "teeth") {
      int n = 0;
      const auto r = std::from_chars(value.data(), value.data() + value.size(), n);
      if (r.ec != std::errc() || r.ptr != value.data() + value.size() || n < 1 || n > 1000) {
        throw InputError(where + ": teeth=" + value +
                         " is not a number of cutting edges from 1 to 1000; write teeth=2 for a "
                         "two-flute cutter, or leave it out (the machine file's [cutting] teeth)");
      }
      e.teeth = n;
    }
  }
}

}  // namespace

std::vector<ToolTableEntry> parse_tool_table(const std::string& text, const std::string& name) {
  std::vector<ToolTableEntry> out;
  std::istringstream in(text);
  std::string line;
  int no = 0;
  while (std::getline(in, line)) {
    ++no;
    const std::string where = name + ":" + std::to_string(no);
    std::string comment;
    if (const auto semi = line.find(';'); semi != std::string::npos) {
      comment = line.substr(semi + 1);
      line.resize(semi);
    }
    std::istringstream ws(line);
    std::string w;
    ToolTableEntry e;
    e.tool = -1;
    e.line = no;
    double q = 0.0;
    while (ws >> w) {
      const char c = static_cast<char>(std::toupper(static_cast<unsigned char>(w[0])));
      double v = 0.0;
      const char* b = w.c_str() + 1;
      if (*b == '+') ++b;
      const auto r = std::from_chars(b, w.c_str() + w.size(), v);
      if (r.ec != std::errc() || r.ptr != w.c_str() + w.size() || !std::isfinite(v)) {
        throw InputError(where + ": malformed word '" + w +
                         "'; write LETTER NUMBER such as T1 P1 Z0.5 D6");
      }
      if (c == 'T') e.tool = static_cast<int>(v);
      if (c == 'Z') e.z = v;
      if (c == 'D') e.diameter = v;
      if (c == 'Q') q = v;
    }
    if (e.tool < 0) continue;
    e.orientation = static_cast<int>(q);
    read_comment(comment, where, e);
    out.push_back(e);
  }
  return out;
}

std::vector<ToolTableEntry> read_tool_table(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw InputError(path +
                     ": cannot open the tool table; check the path in the machine file's "
                     "[program] table");
  }
  std::ostringstream s;
  s << in.rdbuf();
  return parse_tool_table(s.str(), path);
}

namespace {

// One field stated by the table (a) and the machine file (b): the one stated, or both equal.
template <typename T>
bool same(T a, T b) {
  if constexpr (std::is_floating_point_v<T>) {
    return std::abs(a - b) <= 1e-9 * std::max(std::abs(a), std::abs(b));  // inch tables
  } else {
    return a == b;
  }
}
template <typename T>
T merged(T a, T b, const char* field, const std::string& a_where, const std::string& b_where,
         int tool, const std::string& a_text, const std::string& b_text) {
  if (b == T{}) return a;
  if (a == T{} || same(a, b)) return b;
  throw InputError("tool T" + std::to_string(tool) + ": " + a_where + " states " + field + " " +
                   a_text + ", " + b_where + " states " + b_text +
                   "; make them agree, or state it in one place only");
}

}  // namespace

std::map<int, ToolSpec> tool_catalogue(const InterpretOptions& o) {
  std::map<int, ToolSpec> tools;
  if (!o.tool_table.empty()) {
    const double k = mm_per_unit(o.machine_units);
    for (const ToolTableEntry& e : read_tool_table(o.tool_table)) {
      tools[e.tool] = ToolSpec{e.kind, 0.5 * std::abs(e.diameter) * k, e.teeth,
                               o.tool_table + ":" + std::to_string(e.line)};
    }
  }
  for (const auto& [n, d] : o.declared_tools) {
    const auto it = tools.find(n);
    if (it == tools.end()) {
      tools[n] = d;
      continue;
    }
    ToolSpec& t = it->second;
    t.kind =
        merged(t.kind, d.kind, "kind", t.where, d.where, n, to_string(t.kind), to_string(d.kind));
    t.radius_mm = merged(t.radius_mm, d.radius_mm, "radius", t.where, d.where, n,
                         text::sig(t.radius_mm) + " mm", text::sig(d.radius_mm) + " mm");
    t.teeth = merged(t.teeth, d.teeth, "teeth", t.where, d.where, n, std::to_string(t.teeth),
                     std::to_string(d.teeth));
    t.where += " and " + d.where;
  }
  for (const int n : o.machine_tools) {
    if (!tools.count(n)) tools[n] = ToolSpec{ToolKind::ball, 0.0, 0, "the machine file's [tool]"};
  }
  return tools;
}

}  // namespace ncd::toolpath
