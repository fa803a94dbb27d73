// What kind of cutter a move cuts with, as far as the feed laws care (docs/feedrate.md §1.5).
// Choi's roughness law (feed/roughness.hpp, paper 004) models a ball-end mill finishing a
// surface; it caps the feed of moves cut by a tool known to be a ball end and of no other: a flat
// or bull-nose end mill, a drill, or a tool whose kind nobody stated runs at its programmed feed
// within the machine's limits. The kind comes from the tool table's comment (`;kind=flat
// teeth=4`, which LinuxCNC ignores), the machine file's [tools.N] tables, or the generator: every
// path ncd makes (chamfer, path files) is cut by the machine file's [tool], a ball end.
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace ncd::toolpath {

enum class ToolKind { unknown, ball, flat, bull_nose, drill };

// "unknown", "ball", "flat", "bull_nose", "drill".
const char* to_string(ToolKind kind);
// The kinds a file may state ("ball", "flat", "bull_nose", "drill"); nullopt for anything else.
std::optional<ToolKind> tool_kind_from_text(std::string_view text);
// "ball, flat, bull_nose, drill": for messages.
inline constexpr const char* kToolKindsText = "ball, flat, bull_nose, drill";

// A tool as declared: what a tool table entry or [tools.N] states. 0 for a number not stated.
struct ToolSpec {
  ToolKind kind = ToolKind::unknown;
  double radius_mm = 0.0;  // cutter radius; for a ball, the ball radius R of the law
  int teeth = 0;           // cutting edges z
  std::string where;       // "tool.tbl:3", "machine.toml [tools.1]": where it was declared
};

// The tool a path segment is cut with. Default: the ball end of the machine file's [cutting]
// (every path ncd generates); to_path() sets each segment's tool from its program.
struct CutterTool {
  int number = 0;  // T in the spindle (0: none changed to)
  ToolKind kind = ToolKind::ball;
  double radius_mm = 0.0;  // 0: not stated, the [cutting] ball_radius_mm
  int teeth = 0;           // 0: not stated, the [cutting] teeth
  // The roughness law caps this tool's feed (and predicts its R_max): a ball end only.
  bool roughness_law() const { return kind == ToolKind::ball; }
};

}  // namespace ncd::toolpath
