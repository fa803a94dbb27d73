// Tool kinds as text (tool.hpp).
#include "geometry/tool.hpp"

namespace ncd::toolpath {

const char* to_string(ToolKind kind) {
  switch (kind) {
    case ToolKind::ball:
      return "ball";
    case ToolKind::flat:
      return "flat";
    case ToolKind::bull_nose:
      return "bull_nose";
    case ToolKind::drill:
      return "drill";
    case ToolKind::unknown:
      break;
  }
  return "unknown";
}

std::optional<ToolKind> tool_kind_from_text(std::string_view text) {
  for (const ToolKind k : {ToolKind::ball, ToolKind::flat, ToolKind::bull_nose, ToolKind::drill}) {
    if (text == to_string(k)) return k;
  }
  return std::nullopt;
}

}  // namespace ncd::toolpath
