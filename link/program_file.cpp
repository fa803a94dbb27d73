// Program file: blocks from an NC program on disk.
#include "link/program_file.hpp"

#include <algorithm>
#include <cctype>

#include "core/error.hpp"
#include "core/input_file.hpp"
#include "gcode/lexer.hpp"
#include "link/sha256.hpp"

namespace ncd::comms {

std::string line_text(std::string_view raw) {
  std::string s;
  s.reserve(raw.size());
  for (char c : raw) {
    if (c != '\r' && c != '\n' && c != '\0') s += c;
  }
  const auto first = s.find_first_not_of(" \t");
  if (first == std::string::npos) return {};
  const auto last = s.find_last_not_of(" \t");
  return s.substr(first, last - first + 1);
}

int grbl_line_chars(std::string_view text) {
  int n = 0;
  gcode::Lexer lex(text);
  for (gcode::Token t = lex.next(); t.kind != gcode::Token::Kind::End; t = lex.next()) {
    if (t.kind == gcode::Token::Kind::Comment) continue;
    for (std::size_t i = t.at; i < t.end; ++i) {
      const auto c = static_cast<unsigned char>(text[i]);
      if (c > ' ' && c != '/') ++n;
    }
  }
  return n;
}

std::string block_of_line(const std::string& line) {
  std::string s = line_text(line);
  return s == "%" ? std::string() : s;
}

ProgramSummary scan_program(const std::string& path, int data_bits, int max_block_chars) {
  require_regular_file(path, "NC program");  // a FIFO or a device would block or never end
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError("cannot read the NC program " + path + ": check the path");
  ProgramSummary sum;
  Sha256 sha;
  std::string line;
  long number = 0;
  while (std::getline(in, line)) {
    ++number;
    const std::string block = block_of_line(line);
    if (block.empty()) continue;
    for (char c : block) {
      const auto u = static_cast<unsigned char>(c);
      if (u >= (data_bits == 7 ? 0x80U : 0x100U) || (u < 0x20 && c != '\t') || c == 0x7F) {
        throw InputError(path + ":" + std::to_string(number) + ": character code " +
                         std::to_string(u) + " cannot go over the line (" +
                         std::to_string(data_bits) +
                         " data bits, printable ASCII only): remove it from the program");
      }
    }
    if (static_cast<int>(block.size()) > max_block_chars) {
      throw InputError(path + ":" + std::to_string(number) + ": a block of " +
                       std::to_string(block.size()) + " characters is longer than the " +
                       std::to_string(max_block_chars) +
                       " the controller accepts: split the block or raise the limit");
    }
    ++sum.blocks;
    sum.bytes += static_cast<std::int64_t>(block.size() + 1);
    sum.longest_block = std::max(sum.longest_block, static_cast<int>(block.size()));
    const int kept = grbl_line_chars(block);
    if (kept > sum.longest_kept) {
      sum.longest_kept = kept;
      sum.longest_kept_line = number;
    }
    if (!(block.size() > 1 && (block[0] == 'N' || block[0] == 'n') &&
          std::isdigit(static_cast<unsigned char>(block[1])) != 0)) {
      sum.numbered = false;
    }
    sha.update(block);
    sha.update("\n");
  }
  if (sum.blocks == 0) {
    throw InputError("the NC program " + path + " has no blocks: nothing to send");
  }
  sum.sha256 = sha.hex();
  return sum;
}

ProgramFile::ProgramFile(const std::string& path)
    : in_((require_regular_file(path, "NC program"), path), std::ios::binary) {
  if (!in_) throw InputError("cannot read the NC program " + path + ": check the path");
}

BlockStatus ProgramFile::next(std::string& text) {
  std::string line;
  while (std::getline(in_, line)) {
    text = block_of_line(line);
    if (!text.empty()) return BlockStatus::Ready;
  }
  return BlockStatus::End;
}

}  // namespace ncd::comms
