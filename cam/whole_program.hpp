// A generated job as a whole NC program (docs/whole-program.md): around the cut, what a
// machinist's program has — units and modes, the tool and its length offset, the spindle at its
// speed (and a dwell for it to get there), the clearance plane reached by rising first, the
// approach (over the start, or down the drill axis and then out to the edge for an inner edge),
// the cut, the retract the same way back, spindle stop and program end. The result is a
// toolpath::Program, so the planner (to_path), the block encoder and the NGC writers all see the
// same events in the same order.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "cam/chamfer.hpp"
#include "cam/chamfer_ngc.hpp"
#include "gcode/program.hpp"
#include "geometry/path.hpp"

namespace ncd::toolpath {

struct JobFrame {
  double feed_mm_per_min = 300.0;  // the cut's feed where its segments give none, and the approach
  double spindle_rpm = 3000.0;
  double spindle_dwell_s = 0.0;  // G4 after M3; 0: none
  int tool = 1;                  // T and H
  // T n M6 at the start; false where the controller has no tool changer (grbl: M6 is its
  // error:20): the operator loads tool n before the start, as the header says.
  bool tool_change = true;
  // G43 H n after the change (or at the start, without one): the controller's tool table gives
  // the tool's length to the programmed point. False where the controller has no tool table
  // (grbl): the operator sets the length in the work offset, as the header says.
  bool length_offset = true;
  double clearance_z_mm = 0.0;   // the clearance plane, in the program's frame and point
  double approach_gap_mm = 1.0;  // the rapid descent stops this far above the feed's start
  // Inner edges: the approach goes down this vertical (the drill axis, X Y) and then feeds out
  // to the cut's start; the retract comes back the same way. None: straight down onto the start.
  std::optional<Vec3> axis_xy;
};

// The whole program around `cut` (its segments in the program's frame and point, mm; feed
// moves at their own feed or frame.feed_mm_per_min). Throws InputError when the clearance plane
// is not above every point of the cut, or a value is out of range.
Program whole_job(const Path& cut, const JobFrame& frame);

// The chamfer job: the loop as chamfer_program() writes it (program frame, programmed point),
// its clearance plane options.safe_z_mm, inner edges approached down the drill axis, the tool,
// its change and the spindle dwell of the options.
Program chamfer_job(const ChamferPath& path, const NgcOptions& options);

// How a job leaves the part when it ends before its own end: stopped, shut down, failed, or cut
// off by its link (docs/whole-program.md, "Ending early"). From wherever the tool stands it
// goes straight up to the clearance plane, never sideways below it, except in the bore of an
// inner edge: there the program's own retract goes horizontally back to the drill axis first
// (the only way out of the bore), and so does the ending. Then M5, M9 and the program end.
struct SafeRetract {
  double clearance_z_mm = 0.0;  // the plane to rise to, the program's frame and point
  std::string clearance_from;   // where that plane comes from, for the log and the status
  // Inner edges: the drill axis (X Y) and the farthest the cut goes from it. Below the plane and
  // within bore_radius_mm (+ 0.01 mm) of the axis the tool is in the bore.
  std::optional<Vec3> axis_xy;
  double bore_radius_mm = 0.0;
  double feed_mm_per_min = 0.0;  // the move back to the axis (the program's approach feed)
  // To turn the spindle again before that move when a controller reset stopped it (grbl, after
  // its feed hold and soft reset): the program's speed and its dwell.
  double spindle_rpm = 0.0;
  double spindle_dwell_s = 0.0;
  int end_m = 2;  // the program end: M2 or M30, as the program ends
};

// The retract of whole_job(cut, frame): its clearance plane, and for an inner edge the drill
// axis and the cut's farthest point from it.
SafeRetract job_retract(const Path& cut, const JobFrame& frame);
// The retract of an RS-274/NGC program planned as `planned` (to_path of it): straight up to the
// highest Z the program reaches (control points of curves included: they bound the curve from
// above), its M2 or M30. Throws InputError when the path has no point.
SafeRetract program_retract(const Program& program, const Path& planned);
// What the operator must do at the machine when the ending could not be sent: stop the motion,
// the spindle and the coolant, and retract the way the ending would have.
std::string retract_advice(const SafeRetract& retract);

// Header lines of a job (without parentheses): the programmed point and the frame.
std::string programmed_point_text(ProgramPoint point, double ball_radius_mm);

}  // namespace ncd::toolpath
