// The replay's tool use (motion/tool_use.cpp) on a program whose dense run the fit splits into
// several walked segments (docs/planner.md §3d): a move is a segment of the program, so the
// counts are those of the program with the fit off, and the tool's length is the walked length
// of its moves (not the program's segment starts indexed by walked segments, which read past
// their end once the fit had split a segment).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "motion/job.hpp"
#include "motion/tool_use.hpp"
#include "tests/common/shape_bound.hpp"
#include "tests/motion/planner_machine.hpp"

namespace ncd::motion {
namespace {

using toolpath::Path;
using toolpath::PathSegment;
using toolpath::Polyline;

// A rapid down to the start, issue 34's sine with a real 90° corner in its middle (two fitted
// runs, so the segment is split into curve, polyline part and curve), and a 5 mm line at
// another feed.
Path program() {
  Path p;
  PathSegment rapid;
  rapid.geometry = Polyline{{Vec3(0, 0, 5), Vec3(0, 0, 0)}, {}};
  rapid.rapid = true;
  p.segments.push_back(rapid);
  std::vector<Vec3> pts;
  for (int i = 0; i <= 1500; ++i) {
    const double x = 0.01 * i;
    pts.emplace_back(test::round_to(x, 4), test::round_to(5.0 * std::sin(x / 3.0), 4), 0.0);
  }
  const Vec3 corner = pts.back();
  for (int i = 1; i <= 1500; ++i) {
    const double y = 0.01 * i;
    pts.emplace_back(test::round_to(corner.x() + 0.2 * std::sin(y / 2.0), 4),
                     test::round_to(corner.y() - y, 4), 0.0);
  }
  p.segments.push_back(test::dense_segment(pts, 3000.0, 0.01));
  p.segments[1].source_line = 2;
  PathSegment line = test::dense_segment({pts.back(), pts.back() + Vec3(5, 0, 0)}, 1200.0, 0.01);
  line.source_line = 3;
  p.segments.push_back(line);
  return p;
}

nlohmann::ordered_json tool_use(const Path& path, bool fit, std::size_t* walked_segments) {
  JobConfig cfg = test::planner_machine();
  cfg.limits.fit_dense_runs = fit;
  Job job(path, cfg);
  *walked_segments = job.path().segments.size();
  ToolUse use(job);
  while (!job.done()) {
    job.prepare();
    use.add(job.step());
  }
  return use.to_json(job);
}

TEST(ToolUse, AFittedSegmentIsOneMoveOfItsWalkedLength) {
  const Path path = program();
  std::size_t walked_fit = 0, walked_raw = 0;
  const auto fit = tool_use(path, true, &walked_fit);
  const auto raw = tool_use(path, false, &walked_raw);
  EXPECT_GT(walked_fit, walked_raw);  // the fit split the dense segment
  ASSERT_EQ(fit["tools"].size(), 1u);
  ASSERT_EQ(raw["tools"].size(), 1u);
  EXPECT_EQ(fit["tools"][0]["moves"], 2);  // the dense segment and the line; the rapid cuts nothing
  EXPECT_EQ(raw["tools"][0]["moves"], 2);
  EXPECT_EQ(fit["tool_runs"], raw["tool_runs"]);
  // The programmed length of the two feed moves (the fitted curve is shorter by the rounding's
  // zig-zag and the corner is passed within P: both well under 0.1 %).
  const auto& pts = std::get<Polyline>(path.segments[1].geometry).points;
  double programmed = 5.0;
  for (std::size_t i = 0; i + 1 < pts.size(); ++i) programmed += (pts[i + 1] - pts[i]).norm();
  EXPECT_NEAR(fit["tools"][0]["length_mm"].get<double>(), programmed, 1e-3 * programmed);
  EXPECT_NEAR(raw["tools"][0]["length_mm"].get<double>(), programmed, 1e-3 * programmed);
}

}  // namespace
}  // namespace ncd::motion
