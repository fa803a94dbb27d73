// The machine of the planner tests: the JobConfig defaults (100 mm/s, 1000 mm/s², 2e4 mm/s³,
// 4 ms, chord 1 µm) with the roughness law out of the way (no pick feed, a 1 mm target), so
// that the motion limits alone bind.
#pragma once

#include "motion/job.hpp"

namespace ncd::test {

inline motion::JobConfig planner_machine() {
  motion::JobConfig c;
  c.cutting.pick_feed_mm = 0.0;
  c.cutting.roughness_target_um = 1000.0;
  return c;
}

}  // namespace ncd::test
