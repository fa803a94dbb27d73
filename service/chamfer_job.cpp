// The chamfer job's path: see chamfer_job.hpp. The loop is closed by repeating its first pose;
// each cutter location carries the tool axis −e (gcode/path_io.cpp reads the JSON the same
// way). The checks are named in the order the JSON reader reports them (global, local, rod).
#include "service/chamfer_job.hpp"

#include <string>

#include "core/decimal.hpp"
#include "core/error.hpp"
#include "core/input_ranges.hpp"

namespace ncd::service {

toolpath::Path chamfer_path(const toolpath::ChamferPath& chamfer, const toolpath::NgcOptions& ngc) {
  const double feed_mm_per_min = ngc.feed_mm_per_min, spindle_rpm = ngc.spindle_rpm;
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
  origin.inner_edge = chamfer.spec.edge == toolpath::Edge::Inner;
  origin.lower_side = chamfer.spec.side == toolpath::Side::Lower;
  origin.safe_z_mm = ngc.safe_z_mm;
  origin.safe_z_for_tip = ngc.point == toolpath::ProgramPoint::Tip;
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
  toolpath::NgcOptions ngc;
  ngc.feed_mm_per_min = job.feed_mm_per_min;
  ngc.spindle_rpm = job.spindle_rpm;
  ngc.point = job.point;
  if (job.safe_z_mm) require_finite("the chamfer's safe Z (mm)", *job.safe_z_mm);
  const toolpath::ChamferPath chamfer = toolpath::generate_chamfer(job.spec);  // checks the spec
  ngc.safe_z_mm = job.safe_z_mm.value_or(toolpath::default_safe_z_mm(job.spec));
  return chamfer_path(chamfer, ngc);
}

}  // namespace ncd::service
