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
// A `;` that grbl reads as a comment to the end of the line (not inside `( )`).
bool has_semicolon_comment(std::string_view text);

}  // namespace ncd::comms::dnc_detail
