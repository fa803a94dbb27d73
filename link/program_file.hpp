// An NC program on disk as a block source for the sender: read lazily line by line, so a
// program of any length is sent in constant memory. Empty lines, `%` lines and NUL leader are
// framing, not blocks; the sender adds its own framing and end of block.
#pragma once

#include <cstdint>
#include <fstream>
#include <string>
#include <string_view>

#include "link/dnc_sender.hpp"

namespace ncd::comms {

struct ProgramSummary {
  std::int64_t blocks = 0;
  std::int64_t bytes = 0;      // blocks with one LF each
  std::string sha256;          // of the blocks, each ended by one LF
  bool numbered = true;        // every block starts with an N word
  int longest_block = 0;       // characters, without end of block
  int longest_kept = 0;        // grbl_line_chars of the longest block by that count
  long longest_kept_line = 0;  // its line in the file (1-based)
};

// grbl 1.1 keeps 79 characters of a line (LINE_BUFFER_SIZE 80) after removing spaces, control
// characters and comments; a longer line is answered error:11.
inline constexpr int kGrblLineChars = 79;
// The characters grbl keeps of a line (spaces, control characters, `(…)` and `;…` removed);
// grbl 1.1 refuses a line that keeps more than 79 with error:11.
int grbl_line_chars(std::string_view text);

// Reads the whole program once to check and summarise it; throws InputError naming the file and
// line of a character a 7-bit line cannot carry or a block longer than max_block_chars.
ProgramSummary scan_program(const std::string& path, int data_bits, int max_block_chars);

class ProgramFile : public BlockSource {
 public:
  explicit ProgramFile(const std::string& path);  // throws InputError if it cannot be read
  BlockStatus next(std::string& text) override;

 private:
  std::ifstream in_;
};

// A raw line as text: CR, LF and NULs removed, spaces and tabs trimmed at both ends.
std::string line_text(std::string_view raw);
// The program's block text for a raw line: line_text, empty for framing (`%`) lines.
std::string block_of_line(const std::string& line);

}  // namespace ncd::comms
