// The RS-274/NGC interpreter: M70-M73, LinuxCNC's saved modal state (its manual, "M70 Save
// Modal State"). M70 saves the modes at the current call level, M71 forgets that save (and
// M73's), M72 restores it (and keeps it for another M72), M73 saves them in a subroutine and
// restores them when it returns. Saved: units, plane, lathe diameter mode (G7/G8), cutter
// compensation, distance and arc distance modes, feed mode, coordinate system, tool length offset,
// retract mode, path control, F, S, spindle direction, mist and flood. The motion mode is not (nor
// in LinuxCNC). A restore emits what the codes it stands for would: the units, offset, path
// control, spindle and coolant events. ncd does not switch cutter compensation on or off by a
// restore: a restore that would is refused, naming the way out.
#include "gcode/ngc/interp.hpp"

namespace ncd::toolpath::ngc {

Interpreter::SavedModes Interpreter::current_modes() const {
  SavedModes m;
  m.units = units_;
  m.plane = plane_;
  m.incremental = incremental_;
  m.ijk_absolute = ijk_absolute_;
  m.retract_r = retract_r_;
  m.feed_mode = feed_mode_;
  m.coord_sys = coord_sys_;
  m.length_on = length_offset_on_;
  m.tool_offset = tool_offset_;
  m.tool_offset_h = tool_offset_h_;
  m.comp = comp_.side();
  m.control = control_;
  m.feed = feed_;
  m.speed = speed_;
  m.spindle = spindle_;
  m.mist = mist_;
  m.flood = flood_;
  m.diameter_mode = diameter_mode_;
  return m;
}

void Interpreter::restore_modes(const SavedModes& m, const char* code) {
  if (m.comp != comp_.side()) {
    fail(std::string(code) + " would switch cutter compensation on or off (saved with it " +
         (m.comp == CutterComp::Side::off ? "off" : "on") +
         "); ncd does not: program G40, G41 or G42 yourself before it");
  }
  if (m.units != units_) {
    units_ = m.units;
    emit(UnitsEvent{units_});
  }
  plane_ = m.plane;
  diameter_mode_ = m.diameter_mode;
  incremental_ = m.incremental;
  ijk_absolute_ = m.ijk_absolute;
  retract_r_ = m.retract_r;
  feed_mode_ = m.feed_mode;
  if (m.coord_sys != coord_sys_) {
    select_coordinate_system(coord_system_code(m.coord_sys));
  }
  if (m.length_on != length_offset_on_ || m.tool_offset != tool_offset_) {
    pos_ += tool_offset_ - m.tool_offset;
    tool_offset_ = m.tool_offset;
    length_offset_on_ = m.length_on;
    tool_offset_h_ = m.tool_offset_h;
    emit(ToolOffsetEvent{tool_offset_ / k(), units_, tool_offset_h_});
  }
  if (m.control.mode != control_.mode || m.control.p != control_.p || m.control.q != control_.q) {
    control_ = m.control;
    emit(control_);
  }
  feed_ = m.feed;
  const bool spindle_changed =
      m.spindle != spindle_ || (m.speed != speed_ && m.spindle != SpindleDir::off);
  speed_ = m.speed;
  spindle_ = m.spindle;
  if (spindle_changed) emit(SpindleEvent{spindle_, speed_});
  // Coolant as LinuxCNC restores it: by its codes, M9 if both were off, else M7 and/or M8, which
  // add to what is on (rs274: saved flood alone, restored over mist, leaves both on).
  const bool mist = m.mist || m.flood ? mist_ || m.mist : false;
  const bool flood = m.mist || m.flood ? flood_ || m.flood : false;
  if (mist != mist_ || flood != flood_) {
    mist_ = mist;
    flood_ = flood;
    emit(CoolantEvent{mist_, flood_});
  }
}

void Interpreter::save_restore_modes(const Block& b) {
  Frame& fr = frames_.back();
  if (b.has_m(70)) fr.m70 = current_modes();
  if (b.has_m(71)) {  // forgets the level's save, M70's or M73's: a later M72 fails
    fr.m70.reset();
    fr.m73.reset();
  }
  if (b.has_m(72)) {
    const std::optional<SavedModes>& saved = fr.m70 ? fr.m70 : fr.m73;
    if (!saved) fail("M72 with no state saved (M70) at this call level; save it with M70 first");
    restore_modes(*saved, "M72");
  }
  if (b.has_m(73)) {
    if (frames_.size() == 1) fail("M73 outside a subroutine; use M70 and M72 at the top level");
    fr.m73 = current_modes();
  }
}

}  // namespace ncd::toolpath::ngc
