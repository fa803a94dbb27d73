// The one entry to toml11 for the machine file and the service config: the text is checked
// first (core/text_guard.hpp: valid UTF-8, no NUL byte, nesting and dotted keys at most 64
// deep), because toml11 3.7.1 reads out of bounds on invalid UTF-8 in a literal string and
// recurses once per nesting level. See docs/input-ranges.md, "Text checks".
#pragma once

#include <exception>
#include <sstream>
#include <string>
#include <toml.hpp>

#include "core/error.hpp"
#include "core/text_guard.hpp"

namespace ncd {

// Parses TOML text; `name` is the file, `kind` the format ("machine file", "service config").
// Throws InputError naming the file and where.
inline toml::value parse_toml_text(const std::string& text, const std::string& name,
                                   const std::string& kind) {
  require_utf8_text(text, name, kind);
  require_toml_depth(text, name);
  try {
    std::istringstream in(text);
    return toml::parse(in, name);
  } catch (const std::exception& e) {
    throw InputError("cannot read " + kind + " " + name + ": " + e.what());
  }
}

}  // namespace ncd
