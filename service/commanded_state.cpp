// The program's modal state move by move and the trace of queued blocks (commanded_state.hpp).
// The modal state is a walk over the program's steps in order, keeping the last spindle,
// coolant, tool change and tool length offset seen, and recording it, with the motion's own
// units, offset and line, where each motion starts: its segment (toolpath::to_path's
// segment_of_step) and the summed lengths of the moves before it in that segment. A motion's offset
// is its work offset, G92 and tool length together, in its units; the tool length, from the last
// G43/G43.1/G49 in its own units, is taken out of it, so that the work offset is shown apart from
// the length.
#include "service/commanded_state.hpp"

#include <algorithm>
#include <iterator>
#include <utility>
#include <variant>

namespace ncd::service {

CommandedTable::CommandedTable(const toolpath::Program& program) {
  std::vector<std::size_t> segment_of_step;
  toolpath::ToPathOptions options;
  options.segment_of_step = &segment_of_step;
  segments_ = toolpath::to_path(program, options).segments.size();
  CommandedModal now;
  std::size_t segment = toolpath::kNoSegment;
  double within_mm = 0.0;
  for (std::size_t i = 0; i < program.steps.size(); ++i) {
    const toolpath::Step& step = program.steps[i];
    if (const auto* event = std::get_if<toolpath::Event>(&step.item)) {
      if (const auto* sp = std::get_if<toolpath::SpindleEvent>(event)) {
        now.spindle = sp->dir;
        now.spindle_rpm = sp->rpm;
      } else if (const auto* c = std::get_if<toolpath::CoolantEvent>(event)) {
        now.mist = c->mist;
        now.flood = c->flood;
      } else if (const auto* t = std::get_if<toolpath::ToolChangeEvent>(event)) {
        now.tool = t->tool;
      } else if (const auto* o = std::get_if<toolpath::ToolOffsetEvent>(event)) {
        now.tool_length_mm = o->offset * toolpath::mm_per_unit(o->units);
        now.tool_length_h = o->h;
      }
      continue;
    }
    const auto& m = std::get<toolpath::Motion>(step.item);
    const double mm = toolpath::mm_per_unit(m.units);
    now.units = m.units;
    now.spindle = m.spindle;
    now.spindle_rpm = m.spindle_rpm;
    now.tool = m.tool;
    now.work_offset_mm = m.offset * mm - now.tool_length_mm;
    now.line = step.src.file == 0 ? step.src.line : 0;
    const std::size_t seg = i < segment_of_step.size() ? segment_of_step[i] : toolpath::kNoSegment;
    if (seg == toolpath::kNoSegment || seg >= segments_) continue;
    if (seg != segment) {
      segment = seg;
      within_mm = 0.0;
    }
    entries_.push_back({seg, within_mm, now});
    within_mm += toolpath::motion_length(m) * mm;
  }
}

const CommandedModal& CommandedTable::at(std::size_t segment, double within_mm) const {
  // The first entry after (segment, within_mm), then one back.
  const auto after = std::upper_bound(
      entries_.begin(), entries_.end(), std::pair(segment, within_mm),
      [](const std::pair<std::size_t, double>& key, const Entry& e) {
        return key.first < e.segment || (key.first == e.segment && key.second < e.from_mm);
      });
  return after == entries_.begin() ? entries_.front().modal : std::prev(after)->modal;
}

void BlockTrace::add(long number, double start_s_mm, double end_s_mm, double start_t_s,
                     double end_t_s, int chars) {
  const std::int64_t before = blocks_.empty() ? 0 : blocks_.back().chars_through;
  blocks_.push_back({number, start_s_mm, end_s_mm, start_t_s, end_t_s, before + chars});
}

std::optional<std::size_t> BlockTrace::with_number(long number) const {
  if (number <= 0) return std::nullopt;
  for (std::size_t k = blocks_.size(); k-- > 0;) {
    if (blocks_[k].number == number) return k;
  }
  return std::nullopt;
}

std::size_t BlockTrace::carried(std::int64_t written, std::int64_t in_flight) const {
  const std::size_t n = std::min<std::size_t>(
      static_cast<std::size_t>(std::max<std::int64_t>(written, 0)), blocks_.size());
  if (n == 0) return 0;
  const std::int64_t left = blocks_[n - 1].chars_through - std::max<std::int64_t>(in_flight, 0);
  // The blocks whose last character has left: chars_through ≤ left.
  const auto end =
      std::upper_bound(blocks_.begin(), blocks_.begin() + static_cast<std::ptrdiff_t>(n), left,
                       [](std::int64_t v, const QueuedBlock& b) { return v < b.chars_through; });
  return static_cast<std::size_t>(end - blocks_.begin());
}

}  // namespace ncd::service
