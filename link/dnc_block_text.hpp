// The small text helpers of the DNC sender: a block's N word, and whether grbl reads a `;`
// comment in it. Private to link/.
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace ncd::comms::dnc_detail {

// The block starts with an N word (after spaces and tabs).
bool starts_with_n_word(const std::string& text);
// The number of the block's N word, if it starts with one.
std::optional<long> n_word(const std::string& text);
// How long the block makes the controller wait, s: G4 P (seconds), M6 (tool_change_s), M0, M1,
// M60 (the operator: infinity); the sum when there are several; 0 for none.
double wait_of_block(std::string_view text, double tool_change_s);
// A `;` that grbl reads as a comment to the end of the line (not inside `( )`).
bool has_semicolon_comment(std::string_view text);

}  // namespace ncd::comms::dnc_detail
