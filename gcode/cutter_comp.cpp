// Cutter radius compensation as LinuxCNC 2.9's interpreter does it (docs/ngc-interpreter.md,
// "Cutter radius compensation"; the manual's "G41, G42"). Written from a reading of LinuxCNC's
// behaviour, not from its code; the conformance suite compares the moves with `rs274`.
//
// Names (written for G17; G18 reads (Z, X) for (X, Y)): r the tool radius, s = +1 for G41
// (tool left of the path), −1 for G42; P the programmed point the last move ended at, T the
// tool's (compensated) position there, u(φ) = (cos φ, sin φ). In the plane every programmed
// element is offset by r to side s. All lengths are mm.
//
// The one-move delay. A compensated move's end cannot be known until the next move is read
// (an inside corner shortens it), so every compensated move waits in a queue; spindle, coolant
// and dwell events read while it waits wait behind it (messages do not: LinuxCNC prints them at
// once). A later move either writes the queue as it is, or first moves the end of every queued
// move to a new point and then writes it. Moving a queued end is checked against gouging: a
// straight move must not reverse (its programmed direction · (new end − anchor) ≥ 0, the anchor
// being the start of the first queued move), an arc's sweep must not grow by more than
// 0.001 rad in inch programs, 0.0254 in mm programs (LinuxCNC adds its length tolerance to the
// angle). A move with no motion in the plane (Z only in G17) joins the queue behind the
// pending one and gets its new end in the plane too.
//
// Entry (first move after G41/G42, from T = P):
// - straight: the end E = P' + r·u(α + s·π/2), α the direction from T to the programmed end P'
//   (the tool touches the line that passes P' tangent to the tool at T). Refused when
//   |P' − T| ≤ r.
// - arc: the programmed arc from T to P' (its centre C), the end moved by r along the radius at
//   P' (towards C when the tool is inside the arc, away when outside), then the centre that
//   makes an arc through T and the new end with its centre on the line from the new end to C:
//   half the chord over the cosine of the angle between chord and that line. Refused when
//   |P' − T| ≤ r, when the tool is inside an arc of radius ≤ r, or when that cosine is below
//   1e-6.
//
// Later moves: θ, the direction of the tool seen from P, and the new element's start tangent α
// give the turn β between the old and the new element (β in [−π/2, 3π/2), measured so that
// β > 0 turns away from the tool). With ε = 0.05 rad (LinuxCNC's TOLERANCE_CONCAVE_CORNER):
// - β > π + ε or β < −ε: an inside (concave) corner. The queued move's end goes back to where
//   the two offset elements meet:
//     line→line: back along the old line by r / tan((β + π)/2);
//     arc→line: on the old offset arc, where it meets the new offset line (solved with the
//       old arc's programmed radius and the distance of its centre from the new line);
//     line→arc: on the new offset circle, where it meets the old offset line;
//     arc→arc: where the two offset circles meet (law of cosines in the triangle of the two
//       centres).
//   No such point (|cos| or |sin| > 1) is a gouge and refused, as LinuxCNC refuses it.
//   A straight move after an arc that left the tool on the far side of the path (the top of an
//   "h" shape: β within ε of π) and an arc after anything, with β within ε of π and the tool
//   outside the new arc, are taken as inside corners too, as LinuxCNC does.
// - ε < β ≤ π + ε otherwise: an outside (convex) corner. The queue is written as it is, then
//   an arc of radius r about P from T to P + r·u(start normal of the new element), turning
//   clockwise for G41 and counter-clockwise for G42 (a G0 goes there straight: there is no
//   rapid arc), then the new element.
// - |β| ≤ ε: tangent; the queue is written, the new element follows from T.
// The new element itself: a line to P' + r·u(α + s·π/2); an arc about its programmed centre to
// its end moved by r along the end radius (inside: towards the centre, refused when the arc's
// radius is ≤ r).
//
// G40 writes the queue; the next move starts from the tool's position but the interpreter
// takes the programmed point as the current one (so an incremental exit move is measured from
// the programmed point), and that move must be straight.
//
// Planes: G17 works on (X, Y), G18 on (Z, X), as LinuxCNC does (its ARC_FEED axes); G19 is
// refused, as in LinuxCNC. Decisions: mill tools only (a lathe tool orientation, which makes
// LinuxCNC offset the tool's origin as well, is refused by the interpreter). A concave
// corner found right after a stop (M0/M1/M60) that emptied the queue is refused: LinuxCNC reads
// a queue entry that is not there in that case.
#include "gcode/cutter_comp.hpp"

#include <cmath>

#include "core/geometry.hpp"

namespace ncd::toolpath {
namespace {

constexpr double kCornerTol = 0.05;  // rad, LinuxCNC's TOLERANCE_CONCAVE_CORNER
constexpr double kCosTol = 1e-6;     // LinuxCNC's TOLERANCE_EQUAL
// Growth of a queued arc's sweep (rad) taken as a gouge: LinuxCNC adds 0.001 in inch programs
// and 0.0254 in mm programs (a length tolerance it adds to an angle).
constexpr double kSweepTolInchProgram = 0.001;
constexpr double kSweepTolMmProgram = 0.0254;
constexpr double kRadiusBugTolUnits = 0.01;

double heading(double dx, double dy) {
  return std::atan2(dy, dx);
}

// LinuxCNC's signed sweep of an arc from (x1, y1) to (x2, y2) about (cx, cy) with `turns`
// (+n counter-clockwise, −n clockwise; 0 gives 0); a zero-length arc is a full turn.
double sweep_of(double x1, double y1, double cx, double cy, int turns, double x2, double y2) {
  if (turns == 0) return 0.0;
  const double a0 = heading(x1 - cx, y1 - cy);
  const double a1 = heading(x2 - cx, y2 - cy);
  if (turns > 0) {
    const double d = a1 > a0 ? a1 - a0 : a1 - a0 + 2 * kPi;
    return d + (turns - 1) * 2 * kPi;
  }
  const double d = a0 > a1 ? a1 - a0 : a1 - a0 - 2 * kPi;
  return d + (turns + 1) * 2 * kPi;
}

// The tool is inside an arc of this turning direction: left of a counter-clockwise arc, right
// of a clockwise one.
bool inside_arc(CutterComp::Side side, int turns) {
  return (side == CutterComp::Side::left && turns > 0) ||
         (side == CutterComp::Side::right && turns < 0);
}

[[noreturn]] void refuse(std::string what) {
  throw CutterCompError{std::move(what)};
}

}  // namespace

void CutterComp::start(Side side, double radius_mm, const Vec3& at_mm, double mm_per_unit,
                       Plane plane) {
  plane_ = plane;
  ax_ = plane_axes(plane);
  if (radius_mm < 0.0) {
    radius_mm = -radius_mm;
    side = side == Side::left ? Side::right : Side::left;
  }
  side_ = side;
  radius_mm_ = radius_mm;
  mm_per_unit_ = mm_per_unit;
  first_ = true;
  prog_ = tool_ = written_ = to_local(at_mm);
}

Vec3 CutterComp::stop() {
  if (offsetting() && !first_) {
    move_end_and_write(tool_.x(), tool_.y());
    write_queue();
  }
  side_ = Side::off;
  first_ = true;
  return to_global(tool_);
}

void CutterComp::flush() {
  if (offsetting() && !first_) move_end_and_write(tool_.x(), tool_.y());
  write_queue();
}

void CutterComp::event(Step s) {
  if (queue_.empty()) {
    out_->push_back(std::move(s));
    return;
  }
  Entry e;
  e.step = std::move(s);
  queue_.push_back(std::move(e));
}

const CutterComp::Entry* CutterComp::front_move() const {
  return queue_.empty() ? nullptr : &queue_.front();
}

void CutterComp::enqueue_line(const Vec3& end_mm, double dir_x, double dir_y, const Motion& m) {
  Entry e;
  e.is_move = true;
  e.motion = m;
  e.end_mm = end_mm;
  e.dir_x = dir_x;
  e.dir_y = dir_y;
  queue_.push_back(std::move(e));
}

void CutterComp::enqueue_arc(const Vec3& end_mm, double cx, double cy, int turns, double sweep,
                             const Motion& m) {
  Entry e;
  e.is_move = true;
  e.arc = true;
  e.motion = m;
  e.end_mm = end_mm;
  e.cx = cx;
  e.cy = cy;
  e.turns = turns;
  e.sweep = sweep;
  queue_.push_back(std::move(e));
}

void CutterComp::write_queue() {
  anchor_valid_ = false;
  for (Entry& e : queue_) {
    if (!e.is_move) {
      out_->push_back(std::move(e.step));
      continue;
    }
    Motion m = std::move(e.motion);
    const double k = mm_per_unit(m.units);
    m.start = to_global(written_) / k;
    if (e.arc) {
      ArcMove a;
      a.end = to_global(e.end_mm) / k;
      a.centre = to_global(Vec3(e.cx, e.cy, written_.z())) / k;
      a.plane = plane_;
      a.turns = e.turns;
      m.geometry = a;
    } else {
      m.geometry = LineMove{to_global(e.end_mm) / k};
    }
    written_ = e.end_mm;
    Step st;
    st.src = m.src;
    st.item = std::move(m);
    out_->push_back(std::move(st));
  }
  queue_.clear();
}

void CutterComp::move_end_and_write(double x, double y) {
  if (queue_.empty()) return;
  for (Entry& e : queue_) {
    if (!e.is_move) continue;
    if (e.arc) {
      const double r_old = std::hypot(e.end_mm.x() - e.cx, e.end_mm.y() - e.cy);
      const double r_new = std::hypot(x - e.cx, y - e.cy);
      if (std::abs(r_old - r_new) > kRadiusBugTolUnits * mm_per_unit_) {
        refuse("cutter compensation made an arc whose radii differ (" +
               std::to_string(r_old / mm_per_unit_) + ", " + std::to_string(r_new / mm_per_unit_) +
               "), as LinuxCNC reports it; change the path near this corner");
      }
      const double grown = sweep_of(anchor_x_, anchor_y_, e.cx, e.cy, e.turns, x, y);
      const double tol = mm_per_unit_ == 1.0 ? kSweepTolMmProgram : kSweepTolInchProgram;
      if (e.sweep != 0.0 && anchor_valid_ && std::abs(grown) > std::abs(e.sweep) + tol) {
        refuse(
            "arc move in a concave corner cannot be reached by the tool without gouging (as in "
            "LinuxCNC); use a smaller tool or open the corner");
      }
    } else {
      const double dot = e.dir_x * (x - anchor_x_) + e.dir_y * (y - anchor_y_);
      if (anchor_valid_ && dot < 0.0) {
        refuse(std::string(e.motion.rapid ? "straight traverse" : "straight feed") +
               " in a concave corner cannot be reached by the tool without gouging (the move is "
               "shorter than the tool needs to back up, as LinuxCNC finds); use a smaller tool or "
               "lengthen the move");
      }
    }
    e.end_mm.x() = x;
    e.end_mm.y() = y;
  }
  write_queue();
  set_anchor(x, y);
}

void CutterComp::line(const Vec3& end_global_mm, Motion m) {
  const Vec3 end_mm = to_local(end_global_mm);
  const double r = radius_mm_;
  const double s = side_ == Side::left ? 1.0 : -1.0;
  const double px = end_mm.x(), py = end_mm.y();
  if (first_) {
    const double dist = std::hypot(px - tool_.x(), py - tool_.y());
    if (dist <= r) {
      refuse("the cutter compensation entry move is not longer than the tool radius (" +
             std::to_string(r / mm_per_unit_) +
             "): LinuxCNC refuses it; start the entry move farther from the contour");
    }
    const double a = heading(px - tool_.x(), py - tool_.y()) + s * kPi / 2;
    set_anchor(tool_.x(), tool_.y());
    enqueue_line(Vec3(px + r * std::cos(a), py + r * std::sin(a), end_mm.z()), std::cos(a),
                 std::sin(a), m);
    first_ = false;
    tool_ = Vec3(px + r * std::cos(a), py + r * std::sin(a), end_mm.z());
    prog_ = end_mm;
    return;
  }
  const double ox = prog_.x(), oy = prog_.y();
  if (px == ox && py == oy) {  // no motion in the plane: joins the queue
    enqueue_line(Vec3(tool_.x(), tool_.y(), end_mm.z()), 0.0, 0.0, m);
    tool_.z() = end_mm.z();
    prog_ = end_mm;
    return;
  }
  // θ: where the tool stands seen from P; α: the new direction; β: the turn (see the top).
  double theta = heading(tool_.x() - ox, tool_.y() - oy);
  double alpha = heading(px - ox, py - oy);
  double beta = 0.0;
  if (side_ == Side::left) {
    if (theta < alpha) theta += 2 * kPi;
    beta = theta - alpha - kPi / 2;
  } else {
    if (alpha < theta) alpha += 2 * kPi;
    beta = alpha - theta - kPi / 2;
  }
  const double normal = alpha + s * kPi / 2;
  const Vec3 end(px + r * std::cos(normal), py + r * std::sin(normal), end_mm.z());
  const double mid_x = ox + r * std::cos(normal), mid_y = oy + r * std::sin(normal);
  const Entry* prev = front_move();
  const bool h_shape = beta > kPi - kCornerTol && prev != nullptr && prev->arc &&
                       !inside_arc(side_, prev->turns) && prev->turns != 0;
  const bool concave = beta < -kCornerTol || beta > kPi + kCornerTol || h_shape;
  if (!concave && beta > kCornerTol) {  // outside corner: an arc (a G0: a straight traverse)
    move_end_and_write(tool_.x(), tool_.y());
    Motion corner = m;
    if (m.rapid) {
      enqueue_line(Vec3(mid_x, mid_y, tool_.z()), 0.0, 0.0, corner);
    } else {
      enqueue_arc(Vec3(mid_x, mid_y, tool_.z()), ox, oy, side_ == Side::left ? -1 : 1, 0.0, corner);
    }
    write_queue();
    set_anchor(mid_x, mid_y);
  } else if (concave) {
    if (prev == nullptr) {
      refuse(
          "inside corner with cutter compensation right after a stop (M0/M1/M60): LinuxCNC's "
          "result is undefined here; move the stop before G41/G42 or after G40");
    }
    if (!prev->arc) {  // line → line: back along the old line
      const double half = (beta + kPi) / 2.0;
      if (half == 0.0)
        refuse("zero-degree inside corner with cutter compensation; change the path");
      const double back = r / std::tan(half);
      const double bx = tool_.x() + back * std::cos(theta + s * kPi / 2);
      const double by = tool_.y() + back * std::sin(theta + s * kPi / 2);
      move_end_and_write(bx, by);
    } else {  // arc → line: the old offset arc meets the new offset line
      const double rad_tool = std::hypot(prev->cx - prev->end_mm.x(), prev->cy - prev->end_mm.y());
      const double base = heading(px - ox, py - oy);
      const double n = prev->turns > 0 ? base + kPi / 2 : base - kPi / 2;
      const double phi = heading(prev->cx - ox, prev->cy - oy);
      const bool inside = inside_arc(side_, prev->turns);
      const double rad_prog = inside ? rad_tool + r : rad_tool - r;
      const double d = rad_prog * std::cos(n - phi);  // old centre's distance from the new line
      const double l = (inside ? d - r : d + r) / rad_tool;
      if (l > 1.0 || l < -1.0) {
        refuse(
            "arc to straight motion makes a corner the compensated tool cannot fit in without "
            "gouging (as in LinuxCNC); use a smaller tool or open the corner");
      }
      const double sign = (prev->turns > 0) == inside ? -1.0 : 1.0;
      const double at = n + kPi + sign * std::acos(l);
      move_end_and_write(prev->cx + rad_tool * std::cos(at), prev->cy + rad_tool * std::sin(at));
    }
  } else {  // tangent or straight on
    write_queue();
    set_anchor(tool_.x(), tool_.y());
  }
  enqueue_line(end, px - ox, py - oy, m);
  tool_ = end;
  prog_ = end_mm;
}

// The first move after G41/G42 as an arc (LinuxCNC's convert_arc_comp1): an entry arc from
// the tool's position to the offset end, about a new centre.
void CutterComp::entry_arc(const Vec3& end_mm, double cx, double cy, int turns, const Motion& m) {
  const double r = radius_mm_;
  const double px = end_mm.x(), py = end_mm.y();
  const bool inside = inside_arc(side_, turns);
  if (std::hypot(px - tool_.x(), py - tool_.y()) <= r) {
    refuse("the cutter compensation entry arc ends within the tool radius (" +
           std::to_string(r / mm_per_unit_) +
           ") of its start: LinuxCNC refuses it; start the entry farther from the contour");
  }
  if (inside && std::hypot(cx - tool_.x(), cy - tool_.y()) <= r) {
    refuse("the tool radius (" + std::to_string(r / mm_per_unit_) +
           ") is not less than the arc's radius with the tool inside the arc; use a smaller "
           "tool or a larger arc");
  }
  const double tx = tool_.x(), ty = tool_.y();
  const double g = inside ? heading(cx - px, cy - py) : heading(px - cx, py - cy);
  const double ex = px + r * std::cos(g), ey = py + r * std::sin(g);
  // The new centre: on the line from the new end towards C, at half the chord over the cosine
  // of the angle between that line and the chord.
  const double half_chord = std::hypot(ty - ey, tx - ex) / 2.0;
  const double towards = heading(cx - ex, cy - ey);
  const double ang = heading(tx - ex, ty - ey) - towards;
  if (std::abs(std::cos(ang)) < kCosTol) {
    refuse(
        "the cutter compensation entry arc cannot be made (the tool radius is not less than "
        "the arc's radius); use a smaller tool or a larger arc");
  }
  const double dist = half_chord / std::cos(ang);
  const double ncx = ex + dist * std::cos(towards), ncy = ey + dist * std::sin(towards);
  const double spiral_tol =
      mm_per_unit_ == 1.0 ? 2 * 0.01 * std::sqrt(2.0) : 2 * 0.001 * std::sqrt(2.0) * mm_per_unit_;
  if (std::abs(std::hypot(ncx - ex, ncy - ey) - std::hypot(ncx - tx, ncy - ty)) > spiral_tol) {
    refuse("cutter compensation entry arc: the radii to its ends differ; change the entry");
  }
  enqueue_arc(Vec3(ex, ey, end_mm.z()), ncx, ncy, turns, sweep_of(tx, ty, ncx, ncy, turns, ex, ey),
              m);
  first_ = false;
  prog_ = end_mm;
  tool_ = Vec3(ex, ey, end_mm.z());
}

// An arc in a concave corner (LinuxCNC's convert_arc_comp2): the tool stops where its offset
// path meets the new offset circle, from a line (offset line) or an arc (offset circle).
void CutterComp::concave_arc_corner(const Entry& prev_entry, double cx, double cy, int turns,
                                    bool inside, double arc_r, double theta, double beta) {
  const Entry* prev = &prev_entry;
  const double r = radius_mm_;
  if (!prev->arc) {  // line → arc: the new offset circle meets the old offset line
    const double off_line = arc_r * std::sin(beta - kPi / 2);
    const double dist = inside ? arc_r - r : arc_r + r;
    const double l = (inside ? off_line + r : off_line - r) / dist;
    if (l > 1.0 || l < -1.0) {
      refuse(
          "arc move in a concave corner cannot be reached by the tool without gouging (as in "
          "LinuxCNC); use a smaller tool or open the corner");
    }
    const double at = inside ? theta + (turns > 0 ? 1.0 : -1.0) * std::asin(l)
                             : theta + kPi - (turns > 0 ? 1.0 : -1.0) * std::asin(l);
    move_end_and_write(cx + dist * std::cos(at), cy + dist * std::sin(at));
  } else {  // arc → arc: the two offset circles meet
    const double r_old = std::hypot(prev->cx - prev->end_mm.x(), prev->cy - prev->end_mm.y());
    const double r_new = inside ? arc_r - r : arc_r + r;
    const double cc = std::hypot(prev->cx - cx, prev->cy - cy);
    if (r_old == 0.0 || cc == 0.0) {
      refuse(
          "arc to arc motion with cutter compensation: the arcs have the same centre (LinuxCNC "
          "refuses it); put a straight move between them");
    }
    const double c = (r_old * r_old + cc * cc - r_new * r_new) / (2 * r_old * cc);
    if (c > 1.0 || c < -1.0) {
      refuse(
          "arc to arc motion makes a corner the compensated tool cannot fit in without gouging "
          "(as in LinuxCNC); use a smaller tool or open the corner");
    }
    const double back = std::acos(c);
    const double towards = heading(cx - prev->cx, cy - prev->cy);
    const bool same = inside_arc(side_, prev->turns) == (turns > 0);
    const double at = towards + (same ? back : -back);
    move_end_and_write(prev->cx + r_old * std::cos(at), prev->cy + r_old * std::sin(at));
  }
}

void CutterComp::arc(const Vec3& end_global_mm, double cx, double cy, int turns, Motion m) {
  const Vec3 end_mm = to_local(end_global_mm);
  const double r = radius_mm_;
  const double px = end_mm.x(), py = end_mm.y();
  const bool inside = inside_arc(side_, turns);
  const double arc_r = std::hypot(cx - px, cy - py);
  if (first_) {
    entry_arc(end_mm, cx, cy, turns, m);
    return;
  }
  const double ox = prog_.x(), oy = prog_.y();
  const double s = side_ == Side::left ? 1.0 : -1.0;
  const double theta = heading(tool_.x() - ox, tool_.y() - oy) - s * kPi / 2;  // old tangent
  double delta = heading(cx - ox, cy - oy);
  const double alpha = turns > 0 ? delta - kPi / 2 : delta + kPi / 2;  // new start tangent
  double beta = side_ == Side::left ? theta - alpha : alpha - theta;
  if (beta > 1.5 * kPi) beta -= 2 * kPi;
  if (beta < -kPi / 2) beta += 2 * kPi;
  double g = 0.0;
  if (inside) {
    g = heading(cx - px, cy - py);
    if (arc_r <= r) {
      refuse("the tool radius (" + std::to_string(r / mm_per_unit_) +
             ") is not less than the arc's radius (" + std::to_string(arc_r / mm_per_unit_) +
             ") with the tool inside the arc; use a smaller tool or a larger arc");
    }
  } else {
    g = heading(px - cx, py - cy);
    delta += kPi;
  }
  const Vec3 end(px + r * std::cos(g), py + r * std::sin(g), end_mm.z());
  const double sweep = sweep_of(ox, oy, cx, cy, turns, px, py);
  const bool concave = beta < -kCornerTol || beta > kPi + kCornerTol ||
                       (std::abs(beta - kPi) < kCornerTol && !inside);
  if (concave) {
    const Entry* prev = front_move();
    if (prev == nullptr) {
      refuse(
          "inside corner with cutter compensation right after a stop (M0/M1/M60): LinuxCNC's "
          "result is undefined here; move the stop before G41/G42 or after G40");
    }
    concave_arc_corner(*prev, cx, cy, turns, inside, arc_r, theta, beta);
    enqueue_arc(end, cx, cy, turns, sweep, m);
  } else if (beta > kCornerTol) {  // outside corner: an arc about P first
    const double mid_x = ox + r * std::cos(delta), mid_y = oy + r * std::sin(delta);
    write_queue();
    enqueue_arc(Vec3(mid_x, mid_y, tool_.z()), ox, oy, side_ == Side::left ? -1 : 1, 0.0, m);
    write_queue();
    set_anchor(mid_x, mid_y);
    enqueue_arc(end, cx, cy, turns, sweep, m);
  } else {
    write_queue();
    set_anchor(tool_.x(), tool_.y());
    enqueue_arc(end, cx, cy, turns, sweep, m);
  }
  prog_ = end_mm;
  tool_ = end;
}

}  // namespace ncd::toolpath
