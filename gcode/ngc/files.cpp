// The RS-274/NGC interpreter: source files, the tool table and the parameter file. The reading and
// execution order is in interpreter.cpp.
#include "gcode/ngc/interp.hpp"
#include "gcode/ngc/tool_table.hpp"

namespace ncd::toolpath::ngc {

void Interpreter::split_lines(SourceFile& f) {
  std::string_view t(f.text);
  f.lines.reserve(static_cast<std::size_t>(std::count(t.begin(), t.end(), '\n')) + 1);
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

std::string Interpreter::read_file(const std::string& path, const char* what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw InputError(path + ": cannot open the " + std::string(what) +
                     "; check the path in the machine file's [program] table");
  }
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// LinuxCNC tool.tbl (tool_table.hpp): each entry's length, diameter and orientation; the
// kinds and teeth go to the program's tool list (tool_catalogue). The machine file's [tool] and
// [tools.N] tools are held too, of zero length and diameter where the table has no entry.
void Interpreter::load_tool_table() {
  for (const int t : opt_.machine_tools) tools_[t] = {0.0, 0.0, 0};
  for (const auto& declared : opt_.declared_tools) tools_[declared.first] = {0.0, 0.0, 0};
  if (opt_.tool_table.empty()) return;
  for (const ToolTableEntry& e : read_tool_table(opt_.tool_table)) {
    tools_[e.tool] = {e.z, e.diameter, e.orientation};
  }
}

// LinuxCNC's .var: lines "NUMBER VALUE" in strictly ascending order (LinuxCNC refuses a file
// out of order); other lines (comments, blanks) are skipped and kept for the write-back. A
// missing file is no error: every parameter starts at 0 and the write-back creates it, as
// LinuxCNC does.
void Interpreter::load_parameters() {
  if (opt_.parameter_file.empty()) return;
  std::error_code ec;
  if (!std::filesystem::exists(opt_.parameter_file, ec)) {
    if (ec) {
      throw InputError(opt_.parameter_file + ": cannot check the parameter file (" + ec.message() +
                       "); check the path in the machine file's [program] table");
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

// The parameter file after the program (Program::parameter_file_text): the old file's lines
// in place, each parameter line with the parameter's value now, and every persistent
// parameter the file lacked inserted where its number belongs.
std::string Interpreter::parameter_file_text() const {
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

// LinuxCNC's persistent parameters (its `required_parameters`): G28 and G30 homes
// 5161-5169 and 5181-5189, the G92 flag and offsets 5210-5219, the coordinate system 5220
// and the nine systems 5221-5230 ... 5381-5390 (X Y Z A B C U V W and the XY rotation).
const std::vector<int>& Interpreter::persistent_parameters() {
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
std::string Interpreter::format_parameter(double v) {
  if (v == 0.0) v = 0.0;  // no "-0.000000"
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6f", v);
  if (std::strtod(buf, nullptr) == v) return buf;
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

double Interpreter::param_len(int index) const {
  return params_[static_cast<std::size_t>(index)] * machine_k_;
}

}  // namespace ncd::toolpath::ngc
