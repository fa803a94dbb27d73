// Which tool cut each move of a run and which moves the roughness law capped (docs/feedrate.md
// §1.5, docs/cmd-replay.md): accumulated setpoint by setpoint in memory sized before the run,
// for the replay's text and JSON reports. A move is a segment of the job's path (a run of lines
// at one feed, an arc, a curve); the law capped it when it was the binding limit of at least one
// of its periods, and the capped feed is the law's lowest value there.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "motion/job.hpp"

namespace ncd::motion {

class ToolUse {
 public:
  // One entry per segment of job.path() (the only allocation).
  explicit ToolUse(const Job& job);
  // Adds one period (no allocation).
  void add(const Setpoint& sp);

  struct Move {
    double walked_max_mm_per_s = 0.0;  // the largest planned feed of its periods
    double law_min_mm_per_s = 0.0;     // the roughness law's lowest value where it bound
    std::int64_t periods = 0;
    std::int64_t law_periods = 0;  // periods the roughness law bound
  };
  const std::vector<Move>& moves() const { return moves_; }
  std::size_t capped_moves() const;

  // "tools": per tool, its kind, the law's parameters where it caps it, moves, length and
  // the largest walked feed; "tool_runs": consecutive moves of one tool with their source lines;
  // "capped_moves": each move the law capped (at most kListed) and "capped_moves_total".
  nlohmann::ordered_json to_json(const Job& job) const;
  // The summary's lines: one per tool, then the capped moves (the first kShown).
  std::string text(const Job& job) const;

  static constexpr std::size_t kListed = 1000;
  static constexpr std::size_t kShown = 5;

 private:
  std::vector<Move> moves_;
};

}  // namespace ncd::motion
