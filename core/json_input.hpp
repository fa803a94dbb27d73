// The one way ncd parses JSON it did not write itself (path files, control requests, the
// transfer journal), and the one conversion of a JSON number to an integer. See
// docs/input-ranges.md, "Text checks" and "Numbers".
//
// parse_json_input() first scans the text for nesting deeper than kMaxNestingDepth (brackets
// outside strings; one pass, no recursion), so that no recursive code (nlohmann's dump(), the
// destructor, the readers) ever meets a deep document. It then parses with a callback that
// keeps the key path of the value being read ("polyline.points[3][1]"), so that a number
// nlohmann cannot represent (1e400: its out_of_range.406) is an InputError naming the key.
// Invalid UTF-8 in a string is nlohmann's parse_error.101, also an InputError.
#pragma once

#include <cstdint>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "core/decimal.hpp"
#include "core/error.hpp"
#include "core/text_guard.hpp"

namespace ncd {

// Offset of the first '[' or '{' outside strings that opens level max_depth + 1; npos if none.
inline std::size_t find_json_too_deep(std::string_view t, int max_depth) {
  int depth = 0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    const char c = t[i];
    if (c == '"') {
      for (++i; i < t.size() && t[i] != '"'; ++i) {
        if (t[i] == '\\') ++i;
      }
    } else if (c == '[' || c == '{') {
      if (++depth > max_depth) return i;
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
  return std::string_view::npos;
}

namespace detail {

// Where the parser is, as a key path: one frame per open object or array.
struct JsonPath {
  struct Frame {
    bool array = false;
    std::size_t index = 0;  // elements completed so far (arrays)
    std::string key;        // last key read (objects)
  };
  std::vector<Frame> frames;

  void element_done() {
    if (!frames.empty() && frames.back().array) ++frames.back().index;
  }
  std::string text() const {
    std::string out;
    for (const Frame& f : frames) {
      if (f.array) {
        out += "[" + std::to_string(f.index) + "]";
      } else if (!f.key.empty() || &f != &frames.front()) {
        out += (out.empty() ? "" : ".") + f.key;
      }
    }
    return out;
  }
};

}  // namespace detail

// Parses text as JSON for the input `name` (a file name, "request"); throws InputError naming
// the position or the key and the way out. `hint` is appended to syntax errors.
inline nlohmann::json parse_json_input(std::string_view text, const std::string& name,
                                       const std::string& hint = "fix the syntax") {
  if (const std::size_t at = find_json_too_deep(text, kMaxNestingDepth);
      at != std::string_view::npos) {
    throw InputError(text_position(text, at, name) + ": nesting deeper than " +
                     std::to_string(kMaxNestingDepth) +
                     " levels; ncd reads at most that many, flatten the document");
  }
  using nlohmann::json;
  detail::JsonPath path;
  const json::parser_callback_t track = [&path](int, json::parse_event_t event, json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start:
        path.frames.push_back({false, 0, {}});
        break;
      case json::parse_event_t::array_start:
        path.frames.push_back({true, 0, {}});
        break;
      case json::parse_event_t::key:
        if (!path.frames.empty() && parsed.is_string()) {
          path.frames.back().key = parsed.get_ref<const std::string&>();
        }
        break;
      case json::parse_event_t::object_end:
      case json::parse_event_t::array_end:
        if (!path.frames.empty()) path.frames.pop_back();
        path.element_done();
        break;
      case json::parse_event_t::value:
        path.element_done();
        break;
    }
    return true;
  };
  try {
    return json::parse(text.begin(), text.end(), track);
  } catch (const json::out_of_range& e) {
    const std::string key = path.text();
    throw InputError(name + ": " + (key.empty() ? "a number" : "\"" + key + "\"") +
                     " is out of range (" + e.what() +
                     "); numbers must be finite doubles, within ±1.8e308");
  } catch (const json::exception& e) {
    std::string what = e.what();
    if (what.size() > 200) what = what.substr(0, 200) + "...";
    throw InputError(name + ": not valid JSON (" + what + "); " + hint);
  }
}

// A JSON value as a whole number within [lo, hi], or an InputError naming the key (`name`),
// the value and the range. Integral floats (3e2) are accepted; 4.9, 3e9 for an int, strings
// and booleans are not.
inline std::int64_t json_integer(const nlohmann::json& j, std::int64_t lo, std::int64_t hi,
                                 const std::string& name) {
  if (j.is_number_integer() && !j.is_number_unsigned()) {
    return checked_integer(j.get<std::int64_t>(), lo, hi, name);
  }
  if (j.is_number_unsigned()) {
    const std::uint64_t u = j.get<std::uint64_t>();
    if (u > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) {
      return checked_integer(static_cast<double>(u), lo, hi, name);  // out of range: throws
    }
    return checked_integer(static_cast<std::int64_t>(u), lo, hi, name);
  }
  if (j.is_number_float()) return checked_integer(j.get<double>(), lo, hi, name);
  throw InputError(name + " = " + j.dump() + " is not a number; it must be a whole number from " +
                   std::to_string(lo) + " to " + std::to_string(hi));
}

}  // namespace ncd
