// What the program commands where the motion stands (docs/web-dashboard.md, "The machine
// state"): for each segment of a job's path, the modal state the program set before it (units,
// work offset, tool length offset, tool, spindle, coolant), read once at submit from the whole
// program (toolpath::Program) that the path was made of; and, while a job streams, the trace of
// the blocks queued for the controller (each block's N word, arc length, planned time and
// characters), from which the service tells which source line the controller executes (grbl's
// Ln:, or its executed blocks) or was last sent (drip), and how far it runs behind ncd's
// commanded motion. All of it lives on the service's owner thread; nothing here is the cycle's.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/geometry.hpp"
#include "gcode/program.hpp"

namespace ncd::service {

// The program's modal state over one path segment. Offsets in mm, in the path's frame (the
// machine coordinates the planner walks): work = path − work_offset − tool_length.
struct CommandedModal {
  toolpath::Units units = toolpath::Units::mm;
  Vec3 work_offset_mm = Vec3::Zero();  // G5x + G92 (the motion's offset less the tool length)
  Vec3 tool_length_mm = Vec3::Zero();  // G43 / G43.1 in force; zero after G49
  int tool_length_h = -1;              // G43 H n; -1: G43.1, G49 or none
  int tool = 0;                        // the tool in the spindle (0: none)
  toolpath::SpindleDir spindle = toolpath::SpindleDir::off;
  double spindle_rpm = 0.0;  // the programmed S
  bool mist = false, flood = false;
  int line = 0;  // the source line of the move (main program only; 0: none known)
};

// The program's state move by move: where each motion starts on the path (its segment of
// toolpath::to_path(program), and the arc length into that segment, by the program's own move
// lengths) and the state over it, its source line included (0 for a move of another file than
// the main program's: a subroutine's). Moves in a row at one feed make one path segment; this
// keeps their lines apart.
class CommandedTable {
 public:
  CommandedTable() = default;
  explicit CommandedTable(const toolpath::Program& program);
  std::size_t segments() const { return segments_; }
  bool empty() const { return entries_.empty(); }
  // The state at `within_mm` into segment `segment`: the last move starting at or before it.
  const CommandedModal& at(std::size_t segment, double within_mm) const;

 private:
  struct Entry {
    std::size_t segment = 0;
    double from_mm = 0.0;
    CommandedModal modal;
  };
  std::vector<Entry> entries_;
  std::size_t segments_ = 0;
};

// A block queued for the controller while a job streams.
struct QueuedBlock {
  long number = 0;  // its N word; 0 when it has none (comments, framing)
  double start_s_mm = 0.0, end_s_mm = 0.0;
  double start_t_s = 0.0, end_t_s = 0.0;  // the planned motion times at its ends
  std::int64_t chars_through = 0;         // characters of this block and every one before it
};

// The blocks in the order they were queued, and where the controller stands among them.
class BlockTrace {
 public:
  void add(long number, double start_s_mm, double end_s_mm, double start_t_s, double end_t_s,
           int chars);
  std::size_t size() const { return blocks_.size(); }
  const QueuedBlock& operator[](std::size_t k) const { return blocks_[k]; }
  // The last block queued with N word `number` (grbl's Ln:); none if no block has it.
  std::optional<std::size_t> with_number(long number) const;
  // How many of the first `written` blocks the line has carried in full when `in_flight` of
  // the characters written have not left yet (drip: the sender's wire model).
  std::size_t carried(std::int64_t written, std::int64_t in_flight) const;

 private:
  std::vector<QueuedBlock> blocks_;
};

}  // namespace ncd::service
