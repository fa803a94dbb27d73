// The RS-274/NGC interpreter: canned cycles (LinuxCNC's convert_cycle_xy and its plane variants).
// The reading and execution order is in interpreter.cpp.
#include "gcode/ngc/interp.hpp"

namespace ncd::toolpath::ngc {

namespace {

Vec3 cycle_point(const PlaneAxes& ax, double a1, double b1, double c1) {
  Vec3 p;
  p[ax.first] = a1;
  p[ax.second] = b1;
  p[ax.axis] = c1;
  return p;
}

}  // namespace

// The words of a canned cycle, checked, with the sticky values of the previous one where the
// block leaves them out (LinuxCNC's convert_cycle).
Interpreter::CycleWords Interpreter::cycle_words(const Block& b, int code) {
  refuse_with_comp("use canned cycles");
  if (code != 730 && code != 810 && code != 820 && code != 830 && code != 850 && code != 890) {
    fail(g_name(code) + " is not supported; use G73 G81 G82 G83 G85 G89");
  }
  if (feed_ == 0.0) fail("canned cycle " + g_name(code) + " with zero feed rate; add F");
  if (feed_mode_ == FeedMode::inverse_time)
    fail("canned cycle in inverse time mode (G93); use G94");
  const char depth_word = static_cast<char>('x' + plane_axes(plane_).axis);
  CycleWords w;
  double& r_val = w.r;
  if (b.has('r')) {
    r_val = len_word(b, 'r');
  } else if (motion_mode_ == code) {
    r_val = cycle_r_;
  } else {
    fail(g_name(code) + " without R (the retract plane) the first time; add R");
  }
  long& repeats = w.repeats;
  if (b.has('l')) {
    const double l = b.v('l');
    if (l < 1 || l > 100000 || l != std::floor(l))
      fail("cycle L" + text::sig(l) + " must be a whole number from 1 to 100000");
    repeats = static_cast<long>(l);
  }
  if (motion_mode_ != code && !b.has(depth_word)) {
    fail(g_name(code) + " without " + std::string(1, static_cast<char>(std::toupper(depth_word))) +
         " (the bottom) the first time; add it");
  }
  w.depth = b.has(depth_word) ? len_word(b, depth_word) : cycle_cc_;
  double& p_val = w.p;
  double& q_val = w.q;
  if (code == 820 || code == 890) {
    if (!b.has('p') && motion_mode_ != code)
      fail(g_name(code) + " without P (dwell) the first time; add P");
    p_val = b.has('p') ? b.v('p') : cycle_p_;
    if (p_val < 0 || p_val > kMaxDwellS)
      fail("dwell P" + text::sig(p_val) + " must be from 0 to " + text::sig(kMaxDwellS) + " s");
  }
  if (code == 730 || code == 830) {
    if (!b.has('q') && motion_mode_ != code)
      fail(g_name(code) + " without Q (peck) the first time; add Q");
    q_val = b.has('q') ? len_word(b, 'q') : cycle_q_;
    if (q_val <= 0.0)
      fail(g_name(code) + " Q" + text::sig(q_val / k()) + ": the peck must be positive");
  }
  // P in other cycles: LinuxCNC ignores it there; so do we, silently as it does.
  return w;
}

void Interpreter::cycle(Block& b, int code) {
  const CycleWords w = cycle_words(b, code);
  const double r_val = w.r, depth_val = w.depth, p_val = w.p, q_val = w.q;
  const long repeats = w.repeats;
  const PlaneAxes ax = plane_axes(plane_);
  const char depth_word = static_cast<char>('x' + ax.axis);
  const double current_cc0 = pos_[ax.axis];
  if (!cycle_il_known_) {
    cycle_il_ = current_cc0;
    cycle_il_known_ = true;
  }
  double old_cc = cycle_il_;
  double current_cc = current_cc0;
  double aa = pos_[ax.first], bb = pos_[ax.second];
  double aa_inc = 0.0, bb_inc = 0.0, r = 0.0, cc = 0.0;
  const char fw = static_cast<char>('x' + ax.first), sw = static_cast<char>('x' + ax.second);
  if (!incremental_) {
    r = r_val;
    cc = depth_val;
    if (b.has(fw)) aa = len_word(b, fw);
    if (b.has(sw)) bb = len_word(b, sw);
    if (b.has(fw)) pending_known_[static_cast<std::size_t>(ax.first)] = true;
    if (b.has(sw)) pending_known_[static_cast<std::size_t>(ax.second)] = true;
    if (b.has_polar()) {  // G17 only (check_polar): the hole from @ and ^
      Vec3 hole = pos_;
      polar_point(b, pos_, hole);
      aa = hole.x();
      bb = hole.y();
      pending_known_[0] = pending_known_[1] = true;
    }
    pending_known_[static_cast<std::size_t>(ax.axis)] = true;
  } else {
    if (b.has(fw)) aa_inc = len_word(b, fw);
    if (b.has(sw)) bb_inc = len_word(b, sw);
    r = r_val + old_cc;
    cc = r + depth_val;
  }
  if (r < cc)
    fail("the R plane is below the bottom of the " + g_name(code) + " cycle; R must be above " +
         std::string(1, static_cast<char>(std::toupper(depth_word))));
  const auto at = [&](double a1, double b1, double c1) { return cycle_point(ax, a1, b1, c1); };
  if (old_cc < r) {
    line_to(at(pos_[ax.first], pos_[ax.second], r), true);
    old_cc = r;
    current_cc = old_cc;
  }
  const double clear_cc = retract_r_ ? r : old_cc;
  const PathControlEvent saved = control_;
  const bool switch_mode = saved.mode != PathControl::exact_path;
  if (switch_mode) {
    PathControlEvent e;
    e.mode = PathControl::exact_path;
    e.units = units_;
    emit(e);
  }
  for (long rep = repeats; rep > 0; --rep) {
    aa += aa_inc;
    bb += bb_inc;
    if (incremental_ && b.has_polar()) {  // each repeat turns or steps out from the last hole
      Vec3 hole(aa, bb, 0.0);
      polar_point(b, Vec3(aa, bb, 0.0), hole);
      aa = hole.x();
      bb = hole.y();
    }
    if (rep == repeats && current_cc > r) {
      line_to(at(aa, bb, current_cc), true);
      line_to(at(aa, bb, r), true);
    } else {
      line_to(at(aa, bb, clear_cc), true);
      if (clear_cc > r) line_to(at(aa, bb, r), true);
    }
    cycle_hole(code, w, ax, aa, bb, r, cc, clear_cc);
  }
  if (switch_mode) emit(saved);
  pos_ = at(aa, bb, clear_cc);
  cycle_cc_ = depth_val;
  cycle_r_ = r_val;
  cycle_p_ = p_val;
  cycle_q_ = q_val;
  motion_mode_ = code;
}

// One hole of a cycle, from the R plane down and back to the clearance (LinuxCNC's
// convert_cycle_g81 … g89).
void Interpreter::cycle_hole(int code, const CycleWords& w, const PlaneAxes& ax, double aa,
                             double bb, double r, double cc, double clear_cc) {
  const double p_val = w.p, q_val = w.q;
  const double clearance = 0.010 * kMmPerInch;  // LinuxCNC 2.9 G73/G83 rapid clearance
  const auto at = [&](double a1, double b1, double c1) { return cycle_point(ax, a1, b1, c1); };
  switch (code) {
    case 810:
      line_to(at(aa, bb, cc), false);
      line_to(at(aa, bb, clear_cc), true);
      break;
    case 820:
      line_to(at(aa, bb, cc), false);
      emit(DwellEvent{p_val});
      line_to(at(aa, bb, clear_cc), true);
      break;
    case 730:
    case 830: {
      long pecks = 0;
      for (double d = r - q_val; d > cc; d -= q_val) {
        if (++pecks > 100000)
          fail("peck Q is too small for the depth: more than 100000 pecks; increase Q");
        line_to(at(aa, bb, d), false);
        if (code == 830) line_to(at(aa, bb, r), true);
        line_to(at(aa, bb, d + clearance), true);
      }
      line_to(at(aa, bb, cc), false);
      line_to(at(aa, bb, clear_cc), true);
      break;
    }
    case 850:
      line_to(at(aa, bb, cc), false);
      line_to(at(aa, bb, r), false);
      line_to(at(aa, bb, clear_cc), true);
      break;
    case 890:
      line_to(at(aa, bb, cc), false);
      emit(DwellEvent{p_val});
      line_to(at(aa, bb, clear_cc), false);
      break;
    default:
      break;
  }
}

}  // namespace ncd::toolpath::ngc
