// What people type that CLI11 alone answers badly, settled before it parses (README, "The
// commands"):
//   - `ncd help` and `ncd help CMD [SUB]` are `--help` of the command; `-V` is `--version`;
//   - a misspelt command or flag is named, with the nearest known one ("did you mean"), before
//     CLI11 would report a required flag as missing (`--pipe-raduis` gave "--pipe-radius is
//     required").
// "Nearest" is the optimal string alignment distance (Damerau–Levenshtein with adjacent
// transpositions, each edit 1): a suggestion is made within max(2, length/3) edits for a word of
// 3 letters or more (flags compared without their dashes), else a command's message lists the
// commands there are.
#pragma once

#include <CLI/CLI.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace ncd::app {

// The arguments to parse (argv without argv[0]), or an error to print (exit 2).
struct GuidedArgs {
  std::vector<std::string> args;
  std::optional<std::string> error;
};

// Optimal string alignment distance between a and b.
std::size_t edit_distance(std::string_view a, std::string_view b);

// The candidate nearest to word within max(2, |word|/3) edits; none if none is that near, or if
// the word has fewer than 3 letters.
std::optional<std::string> nearest(std::string_view word, const std::vector<std::string>& known);

// `args` rewritten (help, -V) or refused (an unknown command or flag) against the commands and
// flags registered on `app`.
GuidedArgs guide_args(const CLI::App& app, std::vector<std::string> args);

}  // namespace ncd::app
