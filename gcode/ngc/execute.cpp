// The RS-274/NGC interpreter: the execution of a block in LinuxCNC's order. The reading and
// execution order is in interpreter.cpp.
#include "gcode/ngc/interp.hpp"

namespace ncd::toolpath::ngc {

double Interpreter::k() const {
  return mm_per_unit(units_);
}

Vec3 Interpreter::g5x() const {
  const int base = 5201 + 20 * coord_sys_;
  return Vec3(param_len(base), param_len(base + 1), param_len(base + 2));
}

Vec3 Interpreter::total_offset() const {
  return g5x() + g92_ + tool_offset_;
}

void Interpreter::check_block(const Block& b) {
  std::array<int, 16> gg;
  gg.fill(-1);
  for (int n = 0; n < b.ng; ++n) {
    const int c = b.g[static_cast<std::size_t>(n)];
    const int grp = g_group(c);
    if (grp < 0) fail(g_name(c) + " is not supported (unknown, or a lathe/remap code); remove it");
    const std::string r = g_refusal(c);
    if (!r.empty()) fail(r);
    auto& slot = gg[static_cast<std::size_t>(grp)];
    if (slot >= 0 && grp != 0) {
      fail(g_name(slot) + " and " + g_name(c) + " are in the same modal group; keep one");
    }
    if (grp == 0 && slot >= 0 && !(slot == 530 || c == 530)) {
      fail(g_name(slot) + " and " + g_name(c) + " are both non-modal codes; put them on two lines");
    }
    if (grp == 0 && c == 530) continue;
    slot = c;
  }
  std::array<int, 11> mg;
  mg.fill(-1);
  for (int n = 0; n < b.nm; ++n) {
    const int c = b.m[static_cast<std::size_t>(n)];
    const int grp = m_group(c);
    if (grp < 0) fail("M" + std::to_string(c) + " is not supported (unknown M code); remove it");
    if ((grp >= 9 && !(c >= 70 && c <= 73)) || c == 19) fail(m_refusal(c));
    auto& slot = mg[static_cast<std::size_t>(grp)];
    if (slot >= 0) {
      fail("M" + std::to_string(slot) + " and M" + std::to_string(c) +
           " are in the same modal group; keep one");
    }
    slot = c;
  }
  check_rotary_words(b);
  if (b.has('e')) fail("E word is not supported (it belongs to G76/M66); remove it");
  if (b.has('d') && !b.has_g(410) && !b.has_g(420) && !b.has_g(411) && !b.has_g(421)) {
    fail("D" + text::sig(b.v('d')) +
         " without G41/G42 (D is the cutter compensation tool or diameter); remove it or add "
         "G41/G42");
  }
}

// A word no code on the line (or the modal motion) reads is an error, as in LinuxCNC.
void Interpreter::check_words_used(const Block& b, int motion_word, int nonmodal) const {
  const bool axes = b.has_xyz_or_polar();
  const int mm = motion_word >= 0 ? motion_word : (axes && nonmodal < 0 ? motion_mode_ : -1);
  if (b.has_polar()) check_polar(b, mm, nonmodal);
  // The words below are read by a few codes only; most lines (G1 X Y) carry none of them.
  constexpr auto bit = [](char c) { return 1u << (c - 'a'); };
  if ((b.mask & (bit('i') | bit('j') | bit('k') | bit('r') | bit('p') | bit('q') | bit('l'))) == 0)
    return;
  const bool arc = mm == 20 || mm == 30;
  const bool cyc = mm == 730 || mm == 810 || mm == 820 || mm == 830 || mm == 850 || mm == 890;
  const bool nurbs = mm == 52;
  const bool g64 = b.has_g(640);
  const auto need = [&](char c, bool ok, const char* users) {
    if (b.has(c) && !ok) {
      fail(std::string(1, static_cast<char>(std::toupper(c))) + text::sig(b.v(c)) +
           " with no code that uses it (" + users + "); remove it");
    }
  };
  need('i', arc, "G2/G3");
  need('j', arc, "G2/G3");
  need('k', arc, "G2/G3");
  need('r', arc || cyc || nonmodal == 100, "G2/G3 R, canned cycles, G10");
  need('p', arc || cyc || nurbs || g64 || nonmodal == 40 || nonmodal == 100,
       "G4, G10, G64, G82, G89, G2/G3 turns, G5.2 weights");
  need('q', g64 || mm == 730 || mm == 830 || b.has_m(61), "G64, G73, G83, M61");
  need('l', cyc || nurbs || nonmodal == 100 || b.has_g(411) || b.has_g(421),
       "G10, canned cycles, G5.2, G41.1/G42.1");
}

double Interpreter::len_word(const Block& b, char c) const {
  const double v = b.v(c) * k();
  if (std::abs(v) > kMaxCoordMm) {
    fail(std::string(1, static_cast<char>(std::toupper(c))) + text::sig(b.v(c)) + " is beyond ±" +
         text::sig(kMaxCoordMm) + " mm; check the number");
  }
  return v;
}

namespace {

// The block's G code of modal group `grp` (G53 aside: it modifies a motion), or -1.
int group_code(const Block& b, int grp) {
  for (int n = 0; n < b.ng; ++n) {
    const int code = b.g[static_cast<std::size_t>(n)];
    if (g_group(code) == grp && code != 530) return code;
  }
  return -1;
}

}  // namespace

// The way out of a tool missing from the table: which table, how to give one, and its format.
std::string Interpreter::missing_tool_way_out(int tool) const {
  const std::string t = std::to_string(tool);
  return (opt_.tool_table.empty()
              ? std::string(" (none is given: pass --tool-table FILE, or set tool_table in the "
                            "machine file's [program] table)")
              : " " + opt_.tool_table) +
         "; add a line for it in LinuxCNC's format, e.g. 'T" + t + " P" + t +
         " Z0 D6 ;length Z and diameter D in machine units'";
}

// A block is executed in LinuxCNC's order (interp_convert.cc, convert_...); the step numbers are
// that order's, and each step is a function below.
void Interpreter::execute_block(Block& b) {
  check_block(b);
  set_lathe_diameter_mode(b);  // before anything reads X (LinuxCNC halves it as it reads it)
  const int motion_word = group_code(b, 1);
  const int nonmodal = group_code(b, 0);
  if (nurbs_open_) {
    nurbs_line(b, motion_word);
    return;
  }
  check_words_used(b, motion_word, nonmodal);
  if (b.has_message) emit(MessageEvent{b.message});  // 1. message
  save_restore_modes(b);         // M70-M73, before this line's own words (modes.cpp)
  set_feed(b);                   // 2. feed mode, 3. F
  set_spindle_and_tool(b);       // 4. S, 5. T, 6. M6, 7. spindle
  set_coolant(b);                // 8. coolant
  if (nonmodal == 40) dwell(b);  // 10. dwell
  set_plane_and_units(b);        // 11. plane, 12. units
  if (const int cc = group_code(b, 7); cc >= 0) cutter_comp(b, cc);  // 13. cutter compensation
  set_tool_length_offset(b);                                         // 14. tool length offset
  if (const int cs = group_code(b, 12); cs >= 0) select_coordinate_system(cs);  // 15.
  if (const int pc = group_code(b, 13); pc >= 0) set_path_control(b, pc);       // 16.
  set_distance_and_retract_modes(b);                      // 17. distance modes, 18. retract mode
  const bool axes_used = execute_non_modal(b, nonmodal);  // 19. non-modal
  execute_motion(b, motion_word, axes_used);              // 20. motion
  execute_stops(b);                                       // 21. stops
  if (b.has_m(6) || b.has_m(61)) reread_position();
}

// After a tool change (M6, M61) LinuxCNC re-reads where the machine stands before the next line
// (toolchange_flag → read_inputs → refresh_actual_position): the current point becomes the end
// of the last move sent. That differs from the programmed point only after G40, where the tool
// stands at its compensated position: the next move then starts there and its words count from
// there, as from any other point (rs274 shows it so: useful-subroutines.ngc, the first G0 Z of
// o200 after o100's G40 and a T0 M6).
void Interpreter::reread_position() {
  if (!start_override_mm_) return;
  pos_ = *start_override_mm_;
  start_override_mm_.reset();
}

// G7 (lathe diameter mode) and G8 (radius mode, the default): in diameter mode every X word is
// a diameter, the point's X its half (LinuxCNC's read_x and convert_lathe_diameter_mode: the
// word is halved as it is read while G7 is on, and a G7 or G8 on the line applies to the line's
// own X). Only X: I, K, R and the other axes stay as written. M2 keeps the mode (as LinuxCNC);
// M70-M73 save and restore it.
void Interpreter::set_lathe_diameter_mode(Block& b) {
  if (b.has_g(70)) diameter_mode_ = true;
  if (b.has_g(80)) diameter_mode_ = false;
  if (diameter_mode_ && b.has('x')) b.val[static_cast<std::size_t>('x' - 'a')] /= 2.0;
}

// 2. feed mode, 3. F
void Interpreter::set_feed(const Block& b) {
  if (b.has_g(930)) {
    if (comp_.on())
      fail(
          "G93 (inverse time) with cutter radius compensation on is not supported: LinuxCNC "
          "times the compensated moves by the programmed lengths; use G94");
    feed_mode_ = FeedMode::inverse_time;
  }
  if (b.has_g(940)) {
    feed_mode_ = FeedMode::per_minute;
    feed_ = 0.0;
  }
  if (b.has('f')) {
    const double f = b.v('f');
    if (f < 0.0) fail("negative feed F" + text::sig(f) + "; F must be positive");
    const double f_mm = feed_mode_ == FeedMode::per_minute ? f * k() : f;
    if (f != 0.0 && (f_mm < kMinFeedMmPerMin || f_mm > kMaxFeedMmPerMin)) {
      fail("feed F" + text::sig(f) + " is outside " + text::sig(kMinFeedMmPerMin) + " to " +
           text::sig(kMaxFeedMmPerMin) +
           (feed_mode_ == FeedMode::per_minute ? " mm/min" : " 1/min") +
           "; check the number and the units (G20/G21)");
    }
    feed_ = f;
  }
}

// 4. S, 5. T, 6. M6, 7. spindle: one spindle event for all four.
void Interpreter::set_spindle_and_tool(const Block& b) {
  // 4. S
  bool spindle_changed = false;
  if (b.has('s')) {
    double s = b.v('s');
    if (s < 0.0) fail("negative spindle speed S" + text::sig(s) + "; S must be 0 or more");
    if (s > kMaxSpindleRpm)
      fail("spindle speed S" + text::sig(s) + " is above " + text::sig(kMaxSpindleRpm) + " rpm");
    s = s + 0.0;  // S-0 is 0
    if (s != speed_) spindle_changed = spindle_ != SpindleDir::off;
    speed_ = s;
  }
  // M61 Q: the tool in the spindle is Q, nothing changes (LinuxCNC's CHANGE_TOOL_NUMBER)
  if (b.has_m(61)) {
    if (!b.has('q')) fail("M61 without Q; give the tool number now in the spindle, M61 Q1");
    const double q = b.v('q');
    if (q < 0 || q != std::floor(q) || q > 99999)
      fail("M61 Q" + text::sig(q) + ": Q must be a whole tool number ≥ 0");
    const int tn = static_cast<int>(q);
    if (tn != 0 && !tools_.count(tn)) {
      fail("M61 Q" + std::to_string(tn) + ": tool " + std::to_string(tn) +
           " is not in the tool table" + missing_tool_way_out(tn));
    }
    tool_ = selected_tool_ = tn;
  }
  // 5. T
  if (b.has('t')) {
    const double t = b.v('t');
    if (t < 0 || t != std::floor(t) || t > 99999)
      fail("tool number T" + text::sig(t) + " must be a whole number ≥ 0");
    const int tn = static_cast<int>(t);
    if (tn != 0 && !tools_.count(tn)) {
      fail("tool T" + std::to_string(tn) + " is not in the tool table" + missing_tool_way_out(tn));
    }
    selected_tool_ = tn;
  }
  // 6. M6
  if (b.has_m(6)) {
    refuse_with_comp("change tools (M6)");
    if (selected_tool_ < 0) fail("M6 without a T word before it; select the tool with T");
    if (spindle_ != SpindleDir::off) {
      spindle_ = SpindleDir::off;
      emit(SpindleEvent{SpindleDir::off, speed_});
      spindle_changed = false;
    }
    tool_ = selected_tool_;
    const auto it = tools_.find(tool_);
    const double length = it == tools_.end() ? 0.0 : it->second.z * machine_k_ / k();
    emit(ToolChangeEvent{tool_, length});
  }
  // 7. spindle
  if (b.has_m(3) || b.has_m(4) || b.has_m(5)) {
    const SpindleDir d = b.has_m(3)   ? SpindleDir::cw
                         : b.has_m(4) ? SpindleDir::ccw
                                      : SpindleDir::off;
    if (d != spindle_) spindle_changed = true;
    spindle_ = d;
  }
  if (spindle_changed) emit(SpindleEvent{spindle_, speed_});
}

// 8. coolant
void Interpreter::set_coolant(const Block& b) {
  if (!b.has_m(7) && !b.has_m(8) && !b.has_m(9)) return;
  if (b.has_m(9)) mist_ = flood_ = false;
  if (b.has_m(7)) mist_ = true;
  if (b.has_m(8)) flood_ = true;
  emit(CoolantEvent{mist_, flood_});
}

// 10. dwell (G4)
void Interpreter::dwell(const Block& b) {
  if (!b.has('p')) fail("G4 without P; give the dwell time in seconds, P0.5");
  const double p = b.v('p');
  if (p < 0.0 || p > kMaxDwellS)
    fail("dwell G4 P" + text::sig(p) + " must be from 0 to " + text::sig(kMaxDwellS) + " s");
  emit(DwellEvent{p});
}

// 11. plane, 12. units
void Interpreter::set_plane_and_units(const Block& b) {
  // 11. plane
  if ((b.has_g(170) && plane_ != Plane::xy) || (b.has_g(180) && plane_ != Plane::xz) ||
      b.has_g(190)) {
    refuse_with_comp("change the plane (or use G19)");
  }
  if (b.has_g(170)) plane_ = Plane::xy;
  if (b.has_g(180)) plane_ = Plane::xz;
  if (b.has_g(190)) plane_ = Plane::yz;
  // 12. units
  if (b.has_g(200) || b.has_g(210)) {
    const Units u = b.has_g(200) ? Units::inch : Units::mm;
    if (u != units_) refuse_with_comp("change units");
    if (u != units_) {
      units_ = u;
      emit(UnitsEvent{u});
    }
  }
}

// 14. tool length offset (G43, G43.1, G49)
void Interpreter::set_tool_length_offset(const Block& b) {
  if (b.has_g(430) || b.has_g(431) || b.has_g(490)) {
    refuse_with_comp("change the tool length offset");
    Vec3 off(0, 0, 0);
    int h = -1;
    if (b.has_g(430)) {
      h = tool_;
      if (b.has('h')) {
        const double hv = b.v('h');
        if (hv < 0 || hv != std::floor(hv))
          fail("G43 H" + text::sig(hv) + ": H must be a tool number");
        h = static_cast<int>(hv);
      }
      if (h != 0) {
        const auto it = tools_.find(h);
        if (it == tools_.end())
          fail("G43 H" + std::to_string(h) + ": tool " + std::to_string(h) +
               " is not in the tool table" + missing_tool_way_out(h));
        off.z() = it->second.z * machine_k_;
      }
    } else if (b.has_g(431)) {
      if (b.has('z')) off.z() = len_word(b, 'z');
      if (b.has('x')) off.x() = len_word(b, 'x');
      if (b.has('y')) off.y() = len_word(b, 'y');
    }
    // With M6 on the same line LinuxCNC re-reads the position after the change, before the
    // offset shifts it: the program position stays (rs274 shows it so).
    if (!b.has_m(6)) pos_ += tool_offset_ - off;
    tool_offset_ = off;
    length_offset_on_ = !b.has_g(490);
    tool_offset_h_ = h;
    emit(ToolOffsetEvent{off / k(), units_, h});
  } else if (b.has('h')) {
    fail("H word without G43; write G43 H" + text::sig(b.v('h')));
  }
}

// 15. coordinate system (G54 … G59.3)
void Interpreter::select_coordinate_system(int cs) {
  refuse_with_comp("change the coordinate system");
  const int n = cs < 590 ? (cs - 540) / 10 + 1 : 6 + (cs - 590);
  const Vec3 old = g5x();
  coord_sys_ = n;
  params_[5220] = n;
  pos_ += old - g5x();
}

// 16. path control (G61, G61.1, G64 P Q)
void Interpreter::set_path_control(const Block& b, int pc) {
  refuse_with_comp("change the path control mode");
  PathControlEvent e;
  e.mode = pc == 610   ? PathControl::exact_path
           : pc == 611 ? PathControl::exact_stop
                       : PathControl::blend;
  if (pc == 640) {
    if (b.has('p')) {
      if (b.v('p') < 0.0)
        fail("G64 P" + text::sig(b.v('p')) +
             ": the blend tolerance must be 0 or more (LinuxCNC would take it as 0); write P0 "
             "or a positive tolerance");
      e.p = b.v('p');
    }
    if (b.has('q')) {
      if (b.v('q') < 0.0)
        fail("G64 Q" + text::sig(b.v('q')) +
             ": the naive-CAM tolerance must be 0 or more; write Q0 or a positive tolerance");
      if (!b.has('p')) fail("G64 Q without P; give P as well");
      e.q = b.v('q');
    }
  }
  e.units = units_;
  control_ = e;
  emit(e);
}

// 17. distance modes, 18. retract mode
void Interpreter::set_distance_and_retract_modes(const Block& b) {
  // 17. distance modes
  if (b.has_g(900)) incremental_ = false;
  if (b.has_g(910)) incremental_ = true;
  if (b.has_g(901)) ijk_absolute_ = true;
  if (b.has_g(911)) ijk_absolute_ = false;
  // 18. retract mode
  if (b.has_g(980) || b.has_g(990)) refuse_with_comp("change the retract mode (G98/G99)");
  if (b.has_g(980)) retract_r_ = false;
  if (b.has_g(990)) retract_r_ = true;
  if (b.has_g(970)) { /* rpm mode: the default */
  }
}

// 19. non-modal codes (G10, G28, G30, G92 …); true when they took the block's axis words.
bool Interpreter::execute_non_modal(const Block& b, int nonmodal) {
  bool axes_used = b.has_g(431);
  if (nonmodal >= 0) refuse_rotary_with(b, nonmodal);
  if (nonmodal == 100 || nonmodal == 280 || nonmodal == 300 || nonmodal == 281 || nonmodal == 301 ||
      (nonmodal >= 920 && nonmodal <= 923)) {
    refuse_with_comp("use " + g_name(nonmodal));
  }
  switch (nonmodal) {
    case 100:
      g10(b);
      axes_used = true;
      break;
    case 280:
    case 300:
      home(b, nonmodal == 280 ? 5161 : 5181);
      axes_used = true;
      break;
    case 281:
    case 301:
      store_home(nonmodal == 281 ? 5161 : 5181);
      break;
    case 920:
      g92(b);
      axes_used = true;
      break;
    case 921:
    case 922:
      pos_ += g92_;
      g92_ = Vec3(0, 0, 0);
      if (nonmodal == 921) {
        for (int p = 5210; p <= 5219; ++p) params_[static_cast<std::size_t>(p)] = 0.0;
      }
      break;
    case 923: {
      const Vec3 n(param_len(5211), param_len(5212), param_len(5213));
      pos_ += g92_ - n;
      g92_ = n;
      params_[5210] = 1.0;
      break;
    }
    default:
      break;
  }
  return axes_used;
}

// 20. motion: the block's motion word, or the modal motion for bare axis words.
void Interpreter::execute_motion(Block& b, int motion_word, bool axes_used) {
  const bool g53 = b.has_g(530);
  const bool axis_words = b.has_xyz_or_polar() || rotary_word(b);
  if (motion_word >= 0) {
    if (motion_word == 800) {
      if (axis_words && !axes_used)
        fail("G80 with X, Y or Z: G80 cancels motion, the axes have no meaning here; remove them");
      motion_mode_ = -1;
      cycle_il_known_ = false;
    } else {
      motion(b, motion_word, g53);
    }
  } else if (axis_words && !axes_used) {
    if (motion_mode_ < 0)
      fail(
          "X, Y or Z with no motion mode active (after G80 or G5.3); program G0 or G1 on this "
          "line");
    motion(b, motion_mode_, g53);
  } else if (g53) {
    fail("G53 without G0 or G1 on the line; write G53 G0 X...");
  }
}

// 21. stops (M0, M1, M60, M2, M30)
void Interpreter::execute_stops(const Block& b) {
  for (int n = 0; n < b.nm; ++n) {
    const int c = b.m[static_cast<std::size_t>(n)];
    if (c == 0 || c == 1 || c == 60 || c == 2 || c == 30) {
      // LinuxCNC writes the waiting compensated move before a stop; the end turns it off.
      comp_call([&] {
        if (c == 2 || c == 30) {
          (void)comp_.stop();
        } else {
          comp_.flush();
        }
      });
    }
    if (c == 0) emit(StopEvent{StopKind::program_stop});
    if (c == 1) emit(StopEvent{StopKind::optional_stop});
    if (c == 60) emit(StopEvent{StopKind::pallet_shuttle});
    if (c == 2 || c == 30) {
      emit(EndEvent{c});
      ended_ = true;
      // LinuxCNC's program end selects G54 again (convert_stop): the saved 5220 is 1.
      coord_sys_ = 1;
      params_[5220] = 1.0;
    }
  }
}

// G40, G41, G42, G41.1, G42.1 (LinuxCNC's convert_cutter_compensation; the algorithm:
// gcode/cutter_comp.cpp).
void Interpreter::cutter_comp(const Block& b, int code) {
  if (code == 400) {
    if (comp_.offsetting() && !comp_.first_move()) {
      Vec3 tool{0, 0, 0};
      comp_call([&] { tool = comp_.stop(); });
      // LinuxCNC takes the programmed point as the current one from here (an incremental
      // exit move counts from it); the exit move itself starts where the tool stands.
      pos_ = comp_.programmed();
      if ((tool - pos_).norm() > 0.0) start_override_mm_ = tool;
      arc_not_allowed_ = true;
    } else {
      (void)comp_.stop();
    }
    return;
  }
  const std::string name = g_name(code);
  if (plane_ == Plane::yz) {
    fail(name +
         " in the YZ plane: compensation works in G17 and G18 only (as in LinuxCNC); "
         "select G17 or G18 first");
  }
  if (comp_.on()) fail(name + " with cutter radius compensation already on; add G40 first");
  if (feed_mode_ == FeedMode::inverse_time) {
    fail(name +
         " in inverse time mode (G93) is not supported: LinuxCNC times the compensated moves "
         "by the programmed lengths; use G94");
  }
  double radius_mm = 0.0;
  if (code == 411 || code == 421) {
    if (!b.has('d')) fail(name + " with no D word; give the tool diameter, D6 for 6 mm");
    if (b.has('l')) {
      fail(plane_ == Plane::xy
               ? name +
                     " with an L word, but the plane is not G18 (L is a lathe tool's "
                     "orientation, as LinuxCNC says); remove L"
               : name +
                     " with an L word (a lathe tool's orientation): ncd compensates for mill "
                     "tools only; remove L");
    }
    radius_mm = b.v('d') * k() / 2.0;
    if (std::abs(radius_mm) > kMaxCoordMm) {
      fail(name + " D" + text::sig(b.v('d')) + " is beyond ±" + text::sig(kMaxCoordMm) +
           " mm; check the number");
    }
  } else {
    int t = tool_;
    if (b.has('d')) {
      const double d = b.v('d');
      if (std::abs(d - std::round(d)) >= 1e-4) {
        fail(name + " D" + text::sig(d) +
             ": D must be a whole number (a tool of the tool table); write D" +
             text::sig(std::round(d)) + ", or G" + std::to_string(code / 10) +
             ".1 D for a diameter");
      }
      if (d < 0) fail(name + " D" + text::sig(d) + ": D must be a tool number, 0 or more");
      t = static_cast<int>(std::lround(d));
      if (t == 0) t = tool_;  // D0 is the tool in the spindle, as in LinuxCNC
      if (t != 0 && !tools_.count(t)) {
        fail(name + " D" + std::to_string(t) + ": tool " + std::to_string(t) +
             " is not in the tool table" + missing_tool_way_out(t) + ", or give G" +
             std::to_string(code / 10) + ".1 D with the diameter");
      }
    }
    const auto it = tools_.find(t);
    if (it != tools_.end()) {
      if (it->second.orientation != 0 && it->second.orientation != 9) {
        fail(name + " with lathe tool " + std::to_string(t) + " (orientation Q" +
             std::to_string(it->second.orientation) +
             (plane_ == Plane::xy ? "), but the plane is not G18 (as LinuxCNC says)"
                                  : "): ncd compensates for mill tools only") +
             "; use a mill tool");
      }
      radius_mm = it->second.diameter * machine_k_ / 2.0;
    }
  }
  comp_.start(code == 410 || code == 411 ? CutterComp::Side::left : CutterComp::Side::right,
              radius_mm, pos_, k(), plane_);
  if (start_override_mm_ && comp_.offsetting()) {  // G40 then G41 with no move between
    comp_.first_written_from(*start_override_mm_);
    start_override_mm_.reset();
  }
}

}  // namespace ncd::toolpath::ngc
