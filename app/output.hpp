// Writing results: to stdout, or to a file that appears whole or not at all.
#pragma once

#include <string>

namespace ncd::app {

// Writes text to path atomically (temporary file in the same folder, then rename), or to
// stdout when path is empty or "-". Throws std::runtime_error naming the path on failure.
void write_output(const std::string& path, const std::string& text);

}  // namespace ncd::app
