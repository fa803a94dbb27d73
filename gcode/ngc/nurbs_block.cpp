// The RS-274/NGC interpreter: G5.2/G5.3 NURBS blocks. The reading and execution order is in
// interpreter.cpp.
#include "gcode/ngc/interp.hpp"

namespace ncd::toolpath::ngc {

void Interpreter::open_nurbs(const Block& b) {
  require_feed(b, "G5.2");
  refuse_with_comp("use G5.2 NURBS");
  if (plane_ != Plane::xy) fail("G5.2 outside the XY plane; select G17 first");
  nurbs_ = {};
  nurbs_.line = static_cast<int>(cur_line_ + 1);
  nurbs_.start = pos_;
  nurbs_.points.push_back(pos_);
  nurbs_.weights.push_back(1.0);
  nurbs_open_ = true;
  if (b.has('p') && !b.has('x') && !b.has('y')) {
    if (b.v('p') <= 0.0)
      fail("weight P" + text::sig(b.v('p')) + " of the first control point must be > 0");
    nurbs_.weights[0] = b.v('p');
    if (b.has('l')) nurbs_order(b);
    return;
  }
  nurbs_point(b);
}

void Interpreter::nurbs_order(const Block& b) {
  const double l = b.v('l');
  if (l != std::floor(l) || l < 3 || l > NurbsCurve::kMaxDegree + 1) {
    fail("NURBS order L" + text::sig(l) + " is out of range: L must be a whole number from 3 to " +
         std::to_string(NurbsCurve::kMaxDegree + 1) + "; for straight moves use G1");
  }
  nurbs_.order = static_cast<int>(l);
}

void Interpreter::nurbs_point(const Block& b) {
  if (b.has('z'))
    fail("Z in a G5.2 block: the NURBS lies in the XY plane at the current Z; move Z before G5.2");
  if (b.has('l')) nurbs_order(b);
  if (b.has('x') != b.has('y')) fail("a control point needs both X and Y; add the missing one");
  if (!b.has('x')) {
    if (b.has('p'))
      fail("P without X and Y is only allowed on the opening G5.2 line; give X and Y");
    return;
  }
  if (!b.has('p')) fail("control point without a weight; add P (P1 for an ordinary point)");
  if (b.v('p') <= 0.0) fail("weight P" + text::sig(b.v('p')) + " must be greater than 0");
  Vec3 p(len_word(b, 'x'), len_word(b, 'y'), nurbs_.start.z());
  if (incremental_)
    p = Vec3(nurbs_.points.back().x() + p.x(), nurbs_.points.back().y() + p.y(), p.z());
  nurbs_.points.push_back(p);
  nurbs_.weights.push_back(b.v('p'));
}

void Interpreter::nurbs_line(const Block& b, int motion_word) {
  if (motion_word == 53) {
    if (b.has('x') || b.has('y') || b.has('z') || b.has('p') || b.has('l')) {
      fail("G5.3 closes the block and takes no X, Y, Z, P or L; put them on the line before");
    }
    close_nurbs();
    return;
  }
  if ((motion_word >= 0 && motion_word != 52) || b.ng > (motion_word >= 0 ? 1 : 0) || b.nm > 0 ||
      b.has('s') || b.has('t') || b.has('i') || b.has('j') || b.has('k') || b.has('r') ||
      b.has('q')) {
    fail("only X, Y, P, L and F may appear inside the G5.2 block opened at line " +
         std::to_string(nurbs_.line) + "; close the block with G5.3 first");
  }
  if (b.has('f')) feed_ = b.v('f');
  nurbs_point(b);
}

void Interpreter::close_nurbs() {
  const std::size_t kk = static_cast<std::size_t>(nurbs_.order);
  const std::size_t count = nurbs_.points.size();
  if (count < kk) {
    fail("the G5.2 block opened at line " + std::to_string(nurbs_.line) + " has " +
         std::to_string(count) + " control points (the start included), fewer than its order L = " +
         std::to_string(kk) + "; add control points or lower L");
  }
  const std::size_t n = count - 1;
  std::vector<double> knots(n + kk + 1);
  for (std::size_t i = 0; i <= n + kk; ++i) {
    knots[i] = i < kk   ? 0.0
               : i <= n ? static_cast<double>(i - kk + 1)
                        : static_cast<double>(n - kk + 2);
  }
  std::vector<Vec3> pts;
  for (const Vec3& p : nurbs_.points) pts.push_back(p / k());
  Motion m = base_motion(false);
  m.start = nurbs_.start / k();
  try {
    m.geometry =
        NurbsMove{NurbsCurve(nurbs_.order - 1, std::move(knots), std::move(pts), nurbs_.weights)};
  } catch (const InputError& e) {
    fail("the G5.2 block opened at line " + std::to_string(nurbs_.line) +
         " is not a valid NURBS: " + e.what());
  }
  m.src = SourceRef{static_cast<int>(cur_file_), nurbs_.line};
  Step st;
  st.src = m.src;
  st.item = std::move(m);
  program_.steps.push_back(std::move(st));
  pos_ = nurbs_.points.back();
  settle_known();
  nurbs_open_ = false;
  motion_mode_ = -1;
}

void Interpreter::finish() {
  if (nurbs_open_) {
    cur_line_ = static_cast<std::size_t>(nurbs_.line - 1);
    fail("the G5.2 block opened here is not closed; add G5.3 after its last control point");
  }
}

}  // namespace ncd::toolpath::ngc
