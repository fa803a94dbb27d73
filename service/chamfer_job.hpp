// A chamfer job of the service as plain data, and the path it runs (docs/service.md, "Jobs").
// The path is built from the chamfer's cutter poses directly, with the same content as the
// JSON file `ncd chamfer` writes and `ncd replay` reads (the closed loop of cutter locations,
// the tool axis at each, the feed and spindle speed, the tool, the checks, the edge, the side
// and the clearance plane), so a job and a
// replay of the same parameters walk the same path bit for bit.
#pragma once

#include <optional>

#include "cam/chamfer.hpp"
#include "cam/chamfer_ngc.hpp"
#include "geometry/path.hpp"

namespace ncd::service {

struct ChamferJob {
  toolpath::ChamferSpec spec;
  double feed_mm_per_min = 300.0;  // `ncd chamfer --feed`
  double spindle_rpm = 3000.0;     // `ncd chamfer --spindle`
  // The point the machine's programs drive ([tool] programmed_point) and the clearance plane
  // (`ncd chamfer --safe-z`; none: toolpath::default_safe_z_mm), as `ncd chamfer --machine`
  // writes them into its JSON.
  toolpath::ProgramPoint point = toolpath::ProgramPoint::Tip;
  std::optional<double> safe_z_mm;
};

// The chamfer's cutter loop as a one-segment path, its ChamferOrigin set (ball radius, checks,
// edge, side, clearance plane). Throws InputError for a geometry that cannot be chamfered or a
// feed or speed out of range.
toolpath::Path chamfer_job_path(const ChamferJob& job);

// The same from a chamfer already computed, with the options `ncd chamfer` writes into its JSON
// (feed, spindle speed, programmed point, safe Z; app::chamfer_json).
toolpath::Path chamfer_path(const toolpath::ChamferPath& chamfer, const toolpath::NgcOptions& ngc);

}  // namespace ncd::service
