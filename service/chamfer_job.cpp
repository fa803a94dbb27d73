// The chamfer job's path: see chamfer_job.hpp. The loop is closed by repeating its first pose;
// each cutter location carries the tool axis −e (toolpath/path_io.cpp reads the JSON the same
// way). The checks are named in the order the JSON reader reports them (global, local, rod).
#include "service/chamfer_job.hpp"

#include <string>

#include "core/decimal.hpp"
#include "core/error.hpp"
#include "core/input_ranges.hpp"

namespace ncd::service {

toolpath::Path chamfer_path(const toolpath::ChamferPath& chamfer, double feed_mm_per_min,
                            double spindle_rpm) {
  checked_range(feed_mm_per_min, ranges::kProgramFeedMmPerMin.lo, ranges::kProgramFeedMmPerMin.hi,
                "the chamfer's feed", ranges::kProgramFeedMmPerMin.unit, "give the feed in mm/min");
  checked_range(spindle_rpm, ranges::kProgramSpindleRpm.lo, ranges::kProgramSpindleRpm.hi,
                "the chamfer's spindle speed", ranges::kProgramSpindleRpm.unit,
                "give the spindle speed in rpm");
  if (chamfer.points.size() < 2) {
    throw InputError("the chamfer has " + std::to_string(chamfer.points.size()) +
                     " point(s); a chamfer loop needs at least 2");
  }
  toolpath::Polyline pl;
  for (const auto& p : chamfer.points) {
    pl.points.push_back(p.cl);
    pl.normals.push_back(-p.e);
  }
  pl.points.push_back(pl.points.front());
  pl.normals.push_back(pl.normals.front());
  toolpath::validate(pl, "chamfer job: the cutter loop");
  toolpath::PathSegment seg;
  seg.geometry = std::move(pl);
  seg.feed_mm_per_min = feed_mm_per_min;
  seg.spindle_rpm = spindle_rpm;
  toolpath::Path path;
  path.source = "chamfer job";
  path.segments.push_back(std::move(seg));
  toolpath::ChamferOrigin origin;
  origin.ball_radius_mm = chamfer.spec.ball_radius_mm;
  const toolpath::ChamferChecks& ck = chamfer.checks;
  for (const auto& [name, ok] : {std::pair{"global", ck.global_ok}, std::pair{"local", ck.local_ok},
                                 std::pair{"rod", ck.rod_ok}}) {
    if (ok) continue;
    origin.checks_ok = false;
    origin.failed_checks += (origin.failed_checks.empty() ? "" : ", ") + std::string(name);
  }
  path.chamfer = origin;
  return path;
}

toolpath::Path chamfer_job_path(const ChamferJob& job) {
  require_positive("feed", job.feed_mm_per_min);
  return chamfer_path(toolpath::generate_chamfer(job.spec), job.feed_mm_per_min, job.spindle_rpm);
}

}  // namespace ncd::service
