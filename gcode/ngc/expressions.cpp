// The RS-274/NGC interpreter: expressions: parameters, operators and functions. The reading and
// execution order is in interpreter.cpp.
#include "gcode/ngc/interp.hpp"

namespace ncd::toolpath::ngc {

double Interpreter::read_number(const std::string& s, std::size_t& i) {
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

double Interpreter::read_value(const std::string& s, std::size_t& i) {
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

int Interpreter::precedence(int op) {
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
int Interpreter::read_operator(const std::string& s, std::size_t& i) {
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

double Interpreter::apply(int op, double a, double b) {
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
double Interpreter::read_expression(const std::string& s, std::size_t& i) {
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

double Interpreter::read_function(const std::string& s, std::size_t& i) {
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

int Interpreter::param_index(const std::string& s, std::size_t& i) {
  const double v = read_value(s, i);
  const double r = std::round(v);
  if (std::abs(v - r) > 1e-4 || r < 1 || r > kMaxParam) {
    fail("parameter number " + text::sig(v) + " is out of range; use #1 to #5602");
  }
  return static_cast<int>(r);
}

std::string Interpreter::read_name(const std::string& s, std::size_t& i) {
  const std::size_t close = s.find('>', i);
  if (close == std::string::npos) fail("named parameter without a closing '>'; write #<name>");
  std::string name = s.substr(i + 1, close - i - 1);
  if (name.empty()) fail("empty parameter name #<>; give it a name");
  i = close + 1;
  return name;
}

bool Interpreter::named_exists(const std::string& name) const {
  if (!name.empty() && name[0] == '_') return globals_.count(name) || predefined(name, nullptr);
  return frames_.back().locals.count(name) > 0;
}

// LinuxCNC's read-only named parameters (its manual, "Predefined Named Parameters"): the
// modal state as numbers, G codes times ten (G1 gives 10, G17 170, G55 550, G59.3 593), flags
// 1 or 0, the position in program units. The values are rs274's at start (its 2.9 reads
// _vmajor 2.9, _vminor 0): overrides and feed hold enabled (M48, M53), adaptive feed off,
// radius mode (G8, a mill's); axes A to W, which ncd does not have, read 0.
// tests/gcode/predefined_params_rs274_test.cpp holds every value against rs274.
bool Interpreter::predefined(const std::string& name, double* out) const {
  const double k = mm_per_unit(units_);
  const auto flag = [](bool b) { return b ? 1.0 : 0.0; };
  const auto comp = [&] {
    switch (comp_.side()) {
      case CutterComp::Side::left:
        return 410.0;
      case CutterComp::Side::right:
        return 420.0;
      default:
        return 400.0;
    }
  };
  const std::map<std::string_view, double> table{
      {"_vmajor", 2.9},
      {"_vminor", 0.0},
      {"_line", static_cast<double>(cur_line_ + 1)},
      {"_motion_mode", motion_mode_ < 0 ? 800.0 : motion_mode_ * 1.0},
      {"_plane", plane_ == Plane::xy   ? 170.0
                 : plane_ == Plane::xz ? 180.0
                                       : 190.0},
      {"_ccomp", comp()},
      {"_metric", flag(units_ == Units::mm)},
      {"_imperial", flag(units_ == Units::inch)},
      {"_absolute", flag(!incremental_)},
      {"_incremental", flag(incremental_)},
      {"_inverse_time", flag(feed_mode_ == FeedMode::inverse_time)},
      {"_units_per_minute", flag(feed_mode_ == FeedMode::per_minute)},
      {"_units_per_rev", 0.0},
      {"_coord_system", static_cast<double>(coord_system_code(coord_sys_))},
      {"_tool_offset", flag(length_offset_on_)},
      {"_retract_r_plane", flag(retract_r_)},
      {"_retract_old_z", flag(!retract_r_)},
      {"_spindle_rpm_mode", 1.0},
      {"_spindle_css_mode", 0.0},
      {"_ijk_absolute_mode", flag(ijk_absolute_)},
      {"_lathe_diameter_mode", flag(diameter_mode_)},
      {"_lathe_radius_mode", flag(!diameter_mode_)},
      {"_spindle_on", flag(spindle_ != SpindleDir::off)},
      {"_spindle_cw", flag(spindle_ == SpindleDir::cw)},
      {"_mist", flag(mist_)},
      {"_flood", flag(flood_)},
      {"_speed_override", 1.0},
      {"_feed_override", 1.0},
      {"_adaptive_feed", 0.0},
      {"_feed_hold", 1.0},
      {"_feed", feed_},
      {"_rpm", speed_},
      {"_x", pos_.x() / k},
      {"_y", pos_.y() / k},
      {"_z", pos_.z() / k},
      {"_a", 0.0},
      {"_b", 0.0},
      {"_c", 0.0},
      {"_u", 0.0},
      {"_v", 0.0},
      {"_w", 0.0},
      {"_current_tool", static_cast<double>(tool_)},
      {"_selected_tool", static_cast<double>(selected_tool_)},
      {"_call_level", static_cast<double>(frames_.size() - 1)},
      {"_value", value_},
      {"_value_returned", flag(value_returned_)},
  };
  const auto it = table.find(name);
  if (it == table.end()) return false;
  if (out) *out = it->second;
  return true;
}

double Interpreter::read_parameter(const std::string& s, std::size_t& i) {
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

}  // namespace ncd::toolpath::ngc
