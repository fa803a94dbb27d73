// The checks every consumer of a path runs before any motion (docs/hardening.md): the chamfer's
// own checks and tool, the machine's travel envelope, and an estimate of the run's duration and
// output size. `ncd replay` and the service's submit call the same functions.
#pragma once

#include <cstdint>
#include <string>

#include "geometry/path.hpp"
#include "service/machine_config.hpp"

namespace ncd::service {

// What a consumer must state when it runs a chamfer whose checks failed.
struct ChamferAcceptance {
  bool interference_allowed = false;  // the checks failed and the user allowed it
  std::string note;                   // one line for the output, empty otherwise
};

// For the JSON of `ncd chamfer` (path.chamfer set):
//   - checks failed: InputError naming them, unless allow_interference (`allow_flag` names how
//     to say so: "--allow-interference" or "\"allow_interference\": true");
//   - ball radius: a machine read from a file whose [cutting] ball_radius_mm differs from the
//     chamfer's by more than 1e-9 mm is an InputError naming both values; a machine on the
//     documented defaults takes the chamfer's ball radius and a single pass (pick feed 0).
// Other paths: nothing to do.
ChamferAcceptance accept_chamfer(const toolpath::Path& path, MachineConfig& machine,
                                 bool allow_interference, const std::string& allow_flag);

// Throws InputError naming the segment, its source line, the point and the axis limit when a
// point of the path lies outside the machine's [envelope]. NURBS: the control points bound the
// curve (convex hull, positive weights); if one lies outside, the curve itself is sampled.
void check_envelope(const toolpath::Path& path, const MachineConfig& machine);

// A lower bound of the run: every segment at its programmed feed (or the machine's maximum,
// whichever is lower; rapids at the maximum), no acceleration.
struct RunEstimate {
  double length_mm = 0.0;
  double duration_s = 0.0;
  std::int64_t periods = 0;
  std::int64_t setpoint_bytes = 0;  // the --setpoints CSV at kSetpointRowBytes a row
};
inline constexpr double kMaxRunS = 24.0 * 3600.0;                         // refused above: 24 h
inline constexpr std::int64_t kMaxSetpointBytes = std::int64_t{4} << 30;  // 4 GiB
inline constexpr std::int64_t kSetpointRowBytes = 64;

RunEstimate estimate_run(const toolpath::Path& path, const MachineConfig& machine);
// Throws InputError (exit 2) naming the estimate and the limit when the run would last longer
// than kMaxRunS, or (with_setpoints) its setpoints file would exceed kMaxSetpointBytes.
void check_estimate(const RunEstimate& estimate, bool with_setpoints);

}  // namespace ncd::service
