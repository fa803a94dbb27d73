// A chamfer job of the service as plain data, and the path it runs (docs/service.md, "Jobs").
// The path is built from the chamfer's cutter poses directly, with the same content as the
// JSON file `ncd chamfer` writes and `ncd replay` reads (the closed loop of cutter locations,
// the tool axis at each, the feed and spindle speed, the tool and the checks), so a job and a
// replay of the same parameters walk the same path bit for bit.
#pragma once

#include <optional>

#include "toolpath/chamfer.hpp"
#include "toolpath/path.hpp"

namespace ncd::service {

struct ChamferJob {
  toolpath::ChamferSpec spec;
  double feed_mm_per_min = 300.0;  // `ncd chamfer --feed`
  double spindle_rpm = 3000.0;     // `ncd chamfer --spindle`
};

// The chamfer's cutter loop as a one-segment path, its ChamferOrigin set (ball radius, checks).
// Throws InputError for a geometry that cannot be chamfered or a feed or speed out of range.
toolpath::Path chamfer_job_path(const ChamferJob& job);

// The same from a chamfer already computed.
toolpath::Path chamfer_path(const toolpath::ChamferPath& chamfer, double feed_mm_per_min,
                            double spindle_rpm);

}  // namespace ncd::service
