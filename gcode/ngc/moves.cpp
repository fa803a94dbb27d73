// The RS-274/NGC interpreter: the motion of a block (LinuxCNC's convert_straight and
// convert_arc with find_ends): where X, Y, Z take the position (incremental or absolute, G53,
// polar @ and ^, the programmed point under cutter compensation), lines and arcs with the feed
// they need, and the motions and events they emit. The reading and execution order is in
// interpreter.cpp.
#include <numbers>

#include "gcode/ngc/interp.hpp"

namespace ncd::toolpath::ngc {

// While a compensated move waits (docs/ngc-interpreter.md, "Cutter radius compensation"),
// events wait behind it, as LinuxCNC queues them; messages go out at once, as in LinuxCNC.
void Interpreter::emit(Event e) {
  const bool message = std::holds_alternative<MessageEvent>(e);
  Step st;
  st.item = std::move(e);
  st.src = src();
  if (comp_.pending() && !message) {
    comp_.event(std::move(st));
  } else {
    program_.steps.push_back(std::move(st));
  }
}

// LinuxCNC refuses these while compensation is on (G41/G42 even with a radius of 0).
void Interpreter::refuse_with_comp(const std::string& what) const {
  if (comp_.on()) {
    fail("cannot " + what +
         " with cutter radius compensation on (LinuxCNC refuses it too); turn it off with G40 "
         "first");
  }
}

SourceRef Interpreter::src() const {
  return SourceRef{static_cast<int>(cur_file_), static_cast<int>(cur_line_ + 1)};
}

void Interpreter::emit_motion(Motion&& m) {
  m.src = src();
  if (start_override_mm_) {  // the first move after G40 starts where the tool stands
    m.start = *start_override_mm_ / k();
    start_override_mm_.reset();
  }
  Step st;
  st.src = m.src;
  st.item = std::move(m);
  program_.steps.push_back(std::move(st));
}

Motion Interpreter::base_motion(bool rapid) const {
  Motion m;
  const double kk = k();
  m.start = pos_ / kk;
  m.units = units_;
  m.rapid = rapid;
  m.feed_mode = feed_mode_;
  m.feed = rapid ? 0.0 : feed_;
  m.spindle = spindle_;
  m.spindle_rpm = speed_;
  m.tool = tool_;
  m.offset = total_offset() / kk;
  m.start_known = known_[0] && known_[1] && known_[2];
  for (std::size_t a = 0; a < 3; ++a) m.end_known[a] = known_[a] || pending_known_[a];
  return m;
}

// Axes programmed by the move just emitted are known from now on (its own start was not).
void Interpreter::settle_known() {
  for (std::size_t a = 0; a < 3; ++a) {
    known_[a] = known_[a] || pending_known_[a];
    pending_known_[a] = false;
  }
}

void Interpreter::line_to(const Vec3& end_mm, bool rapid) {
  if (comp_.offsetting()) {
    Motion m = base_motion(rapid);
    m.src = src();
    comp_call([&] { comp_.line(end_mm, m); });
    pos_ = comp_.tool();
    settle_known();
    return;
  }
  Motion m = base_motion(rapid);
  m.geometry = LineMove{end_mm / k()};
  emit_motion(std::move(m));
  pos_ = end_mm;
  settle_known();
}
// Where X, Y, Z words take the position (incremental or absolute, G53 machine coordinates).
// With compensation moving the tool, positions are taken from the programmed point (as
// LinuxCNC's find_ends does).
Vec3 Interpreter::from() const {
  return comp_.offsetting() && !comp_.first_move() ? comp_.programmed() : pos_;
}

Vec3 Interpreter::target(const Block& b, bool g53) {
  const Vec3 base = from();
  Vec3 t = base;
  for (int a = 0; a < 3; ++a) {
    const char c = static_cast<char>('x' + a);
    if (!b.has(c)) continue;
    const double v = len_word(b, c);
    if (g53) {
      t[a] = v - total_offset()[a];
    } else {
      t[a] = incremental_ ? base[a] + v : v;
    }
    if (!incremental_ || g53) pending_known_[static_cast<std::size_t>(a)] = true;
  }
  if (b.has_polar()) polar_target(b, base, t);
  return t;
}

// Polar coordinates (LinuxCNC's find_ends): in the XY plane, no X or Y word. Absolute: @ and ^
// give the point from the origin; @ alone keeps the angle of the position, ^ alone its
// distance from the origin (0 at the origin). Incremental: @ adds to the distance from the
// origin, ^ to the angle; neither has a meaning at the origin, nor @ alone in G90.
void Interpreter::check_polar(const Block& b, int motion, int nonmodal) const {
  if (b.has('x') || b.has('y')) {
    fail("X or Y with polar coordinates (@ radius, ^ angle); give one or the other");
  }
  if (plane_ != Plane::xy) fail("polar coordinates (@, ^) work in the G17 plane only; add G17");
  const bool cycle = motion == 730 || (motion >= 810 && motion <= 890);
  if (nonmodal >= 0 || b.has_g(530) ||
      (motion != 0 && motion != 10 && motion != 20 && motion != 30 && !cycle)) {
    fail(
        "polar coordinates (@, ^) are taken on G0 G1 G2 G3 moves and drilling cycles only; "
        "write X and Y");
  }
}

void Interpreter::polar_target(const Block& b, const Vec3& base, Vec3& t) {
  polar_point(b, base, t);
  pending_known_[0] = pending_known_[1] = true;
}

void Interpreter::polar_point(const Block& b, const Vec3& base, Vec3& t) const {
  constexpr double kDegToRad = std::numbers::pi / 180.0;
  const double x = base.x(), y = base.y();
  const bool at_origin = x == 0.0 && y == 0.0;
  double radius = std::hypot(x, y), angle = std::atan2(y, x);
  const bool both = b.polar_radius && b.polar_angle_deg;
  if (!both || incremental_) {
    if (!known_[0] || !known_[1]) {
      fail(
          "polar coordinates from an unknown position: give both @ and ^ in G90, or move "
          "to a known X Y first");
    }
    if (at_origin && (incremental_ || !b.polar_angle_deg)) {
      fail(
          "polar coordinates at the origin need both @ and ^ in G90 (the angle of the origin "
          "is not defined)");
    }
  }
  if (b.polar_radius) {
    const double r = *b.polar_radius * k();
    radius = incremental_ ? radius + r : r;
  }
  if (b.polar_angle_deg) {
    const double a = *b.polar_angle_deg * kDegToRad;
    angle = incremental_ ? angle + a : a;
  }
  t.x() = radius * std::cos(angle);
  t.y() = radius * std::sin(angle);
  if (std::abs(t.x()) > kMaxCoordMm || std::abs(t.y()) > kMaxCoordMm) {
    fail("polar coordinates give X Y beyond ±" + text::sig(kMaxCoordMm) + " mm; check @ and ^");
  }
}

void Interpreter::motion(Block& b, int code, bool g53) {
  if (code != motion_mode_ && !(code >= 730 && code <= 890)) cycle_il_known_ = false;
  if (code < 730 || code > 890) cycle_il_known_ = false;
  if (g53 && code != 0 && code != 10) fail("G53 only works with G0 or G1; remove G53 or use G0/G1");
  if (g53 && incremental_) fail("G53 in incremental mode (G91); switch to G90 first");
  if (g53 && comp_.offsetting())
    fail("G53 with cutter radius compensation on (LinuxCNC refuses it too); G40 first");
  if ((code == 20 || code == 30) && arc_not_allowed_) {
    fail(
        "the move just after turning cutter compensation off (G40) must be straight, not an arc "
        "(as in LinuxCNC); program a G1 exit move first");
  }
  if (code != 0 && code != 10) refuse_rotary_with(b, code);
  switch (code) {
    case 0:
    case 10: {
      arc_not_allowed_ = false;
      if (code == 10) require_feed(b, "G1");
      const Vec3 t = target(b, g53);
      motion_mode_ = code;
      if (index_rotary(b, code, g53, t)) {  // the part turns, X, Y, Z stand still
        settle_known();
        return;
      }
      line_to(t, code == 0);
      motion_mode_ = code;
      return;
    }
    case 20:
    case 30:
      arc(b, code);
      motion_mode_ = code;
      return;
    case 52:
      open_nurbs(b);
      return;
    case 53:
      fail("G5.3 without an open G5.2 block; open the block with G5.2 first");
    default:
      cycle(b, code);
      return;
  }
}

void Interpreter::require_feed(const Block& b, const char* what) {
  if (feed_mode_ == FeedMode::inverse_time) {
    if (!b.has('f'))
      fail(std::string(what) + " in inverse time mode (G93) without F on the line; add F");
    if (feed_ == 0.0) fail(std::string(what) + " with inverse time F0; F must be positive");
  } else if (feed_ == 0.0) {
    fail(std::string("cannot do ") + what + " with zero feed rate; add an F word");
  }
}

void Interpreter::arc(Block& b, int code) {
  require_feed(b, code == 20 ? "G2" : "G3");
  const PlaneAxes ax = plane_axes(plane_);
  const char names[3] = {'x', 'y', 'z'};
  const char offs[3] = {'i', 'j', 'k'};
  const bool ijk = b.has('i') || b.has('j') || b.has('k');
  const bool r_form = b.has('r');
  if (!ijk && !r_form) fail("arc without R or I, J, K; give the centre (I J K) or the radius (R)");
  if (ijk && r_form) fail("arc with both R and I, J, K; keep one form");
  if (ijk && b.has(offs[ax.axis])) {
    fail(std::string(1, static_cast<char>(std::toupper(offs[ax.axis]))) +
         " word given for an arc in the " +
         (plane_ == Plane::xy   ? "XY"
          : plane_ == Plane::xz ? "XZ"
                                : "YZ") +
         " plane; use the plane's two offsets");
  }
  if (ijk && ijk_absolute_ && (!b.has(offs[ax.first]) || !b.has(offs[ax.second]))) {
    fail("absolute arc centre (G90.1) needs both offsets of the plane");
  }
  if (!ijk && !b.has(names[ax.first]) && !b.has(names[ax.second])) {
    fail("R-form arc without an end point in the plane; give the plane's axis words");
  }
  const Vec3 end = target(b, false);
  const double kk = k();
  const Vec3 start = from();
  const double c1 = start[ax.first], c2 = start[ax.second];
  const double e1 = end[ax.first], e2 = end[ax.second];
  int p = 1;
  if (b.has('p')) {
    const double pv = b.v('p');
    if (pv < 1 || pv > kMaxTurns || std::abs(pv - std::round(pv)) > 1e-6) {
      fail("arc P" + text::sig(pv) + " (turns) must be a whole number from 1 to " +
           std::to_string(kMaxTurns));
    }
    p = static_cast<int>(std::lround(pv));
  }
  double cx = 0.0, cy = 0.0;
  const double radius_tol = 0.00005 * kMmPerInch;  // RADIUS_TOLERANCE, same in both units
  if (r_form) {
    const double r = len_word(b, 'r');
    if (e1 == c1 && e2 == c2)
      fail("R-form arc whose end is its start; use the I J K form for a full circle");
    const double abs_r = std::abs(r);
    const double m1 = (e1 + c1) / 2.0, m2 = (e2 + c2) / 2.0;
    double half = std::hypot(m1 - e1, m2 - e2);
    if (half - abs_r > radius_tol) {
      fail("arc radius R" + text::sig(b.v('r')) +
           " is too small to reach the end point; increase R");
    }
    if (half / abs_r > 1 - 1e-12) half = abs_r;
    const double theta =
        std::atan2(e2 - c2, e1 - c1) + (((code == 20) == (r > 0)) ? -kPi / 2 : kPi / 2);
    const double turn2 = std::asin(half / abs_r);
    const double off = abs_r * std::cos(turn2);
    cx = m1 + off * std::cos(theta);
    cy = m2 + off * std::sin(theta);
  } else {
    const double i1 = b.has(offs[ax.first]) ? len_word(b, offs[ax.first]) : 0.0;
    const double i2 = b.has(offs[ax.second]) ? len_word(b, offs[ax.second]) : 0.0;
    cx = ijk_absolute_ ? i1 : c1 + i1;
    cy = ijk_absolute_ ? i2 : c2 + i2;
    const double r1 = std::hypot(cx - c1, cy - c2);
    const double r2 = std::hypot(cx - e1, cy - e2);
    if (r1 < radius_tol || r2 < radius_tol) fail("zero-radius arc; check I, J, K");
    const double spiral_abs = (units_ == Units::inch ? 2 * 0.001 * std::sqrt(2.0) * kMmPerInch
                                                     : 2 * 0.01 * std::sqrt(2.0));
    const double abs_err = std::abs(r1 - r2);
    const double rel_err = abs_err / std::max(r1, r2);
    if (abs_err > spiral_abs * 100.0 || (rel_err > 0.001 && abs_err > spiral_abs)) {
      fail("radius to end of arc (" + text::sig(r2 / kk) + ") differs from radius to start (" +
           text::sig(r1 / kk) + "); correct the end point or I, J, K");
    }
  }
  Motion m = base_motion(false);
  if (comp_.offsetting()) {
    m.src = src();
    comp_call([&] { comp_.arc(end, cx, cy, code == 20 ? -p : p, m); });
    pos_ = comp_.tool();
    settle_known();
    return;
  }
  ArcMove a;
  a.end = end / kk;
  Vec3 c = pos_;
  c[ax.first] = cx;
  c[ax.second] = cy;
  a.centre = c / kk;
  a.plane = plane_;
  a.turns = code == 20 ? -p : p;
  m.geometry = a;
  emit_motion(std::move(m));
  pos_ = end;
  settle_known();
}

}  // namespace ncd::toolpath::ngc
