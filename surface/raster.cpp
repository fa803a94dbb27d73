// See raster.hpp. A raster case: the nominal surface is the plane z = tan α · x, the initial one
// lies `stock` above it (normal to it), and the ball's centre runs at r above the nominal
// surface, so its lowest point touches it. The feed per tooth is measured along the path (on the
// slope), F = f_t z N, so each pass takes its 3-D length / F (docs/surface-simulation.md §5).
#include "surface/raster.hpp"

#include <charconv>
#include <cmath>
#include <string>

#include "core/error.hpp"
#include "core/number_text.hpp"

namespace ncd::surface {

RasterRun make_raster(const RasterSpec& spec, const BallEndMill& tool) {
  validate(tool);
  require_positive("pick_feed_mm", spec.pick_feed_mm);
  require_positive("feed_per_tooth_mm", spec.feed_per_tooth_mm);
  require_positive("stock_mm", spec.stock_mm);
  const double r = tool.radius_mm;
  if (spec.pick_feed_mm >= 2.0 * r) {
    throw InputError("pick_feed_mm = " + text::sig(spec.pick_feed_mm) +
                     " is not below the ball's diameter " + text::sig(2.0 * r) +
                     " mm: the passes would leave uncut ribs; reduce the pick feed");
  }
  if (spec.stock_mm >= r) {
    throw InputError("stock_mm = " + text::sig(spec.stock_mm) + " is not below the ball radius " +
                     text::sig(r) + " mm: the simulation models the ball, not the shank");
  }
  if (!std::isfinite(spec.inclination_deg) || std::abs(spec.inclination_deg) >= 60.0) {
    throw InputError("inclination_deg = " + text::sig(spec.inclination_deg) +
                     " is outside (-60, 60): the ball's hemisphere must reach the slope");
  }
  const double ft = spec.feed_per_tooth_mm, fp = spec.pick_feed_mm;
  const double cell = spec.cell_mm > 0.0 ? spec.cell_mm : ft / 100.0;
  require_positive("cell_mm", cell);
  const double px = spec.patch_x_mm > 0.0 ? spec.patch_x_mm : 2.0 * tool.teeth * ft;
  const double py = spec.patch_y_mm > 0.0 ? spec.patch_y_mm : 2.0 * fp;
  require_positive("patch_x_mm", px);
  require_positive("patch_y_mm", py);

  const double alpha = deg_to_rad(spec.inclination_deg);
  const double g = std::tan(alpha);
  RasterRun run;
  run.grid = {0.0, px, 0.0, py, cell};
  run.nominal = {0.0, g, 0.0};
  run.initial.z0_mm = spec.stock_mm / std::cos(alpha);
  run.initial.grad_x = g;
  // Reach of a pass beyond its centre line: the cap of the ball below the initial surface.
  const double beta = std::acos(1.0 - spec.stock_mm / r);
  const double reach = r * std::sin(std::abs(alpha)) + 2.0 * r * std::sin(0.5 * beta) + 2 * cell;
  const double x_start = -reach, x_end = px + reach;
  const int j_first = static_cast<int>(std::floor(-reach / fp)) - 1;
  const int j_last = static_cast<int>(std::ceil((py + reach) / fp)) + 1;
  run.feed_mm_per_min = ft * tool.teeth * tool.spindle_rpm;
  const double v_mm_per_s = run.feed_mm_per_min / 60.0;
  const double lift = r / std::cos(alpha) - r;  // tip above the nominal surface
  double t = 0.0;
  for (int j = j_first; j <= j_last; ++j) {
    const double y = j * fp;
    Vec3 a(x_start, y, g * x_start + lift), b(x_end, y, g * x_end + lift);
    if (spec.zigzag && (j - j_first) % 2 == 1) std::swap(a, b);
    const double dur = (b - a).norm() / v_mm_per_s;
    Move m;
    m.from_mm = a;
    m.to_mm = b;
    m.t0_s = t;
    m.t1_s = t + dur;
    m.spindle0_rad = deg_to_rad(spec.phase_step_deg) * (j - j_first);
    run.moves.push_back(m);
    t += dur + 1.0;  // a second between passes: the return move, which does not cut
  }
  run.passes = static_cast<int>(run.moves.size());
  return run;
}

std::vector<Move> read_setpoints_csv(std::istream& in, const std::string& name,
                                     const BallEndMill& tool) {
  validate(tool);
  std::string line;
  if (!std::getline(in, line) || line.rfind("t_s,x_mm,y_mm,z_mm", 0) != 0) {
    throw InputError(name + ":1: expected the header t_s,x_mm,y_mm,z_mm,... of `ncd replay " +
                     "--setpoints`");
  }
  const double omega = 2.0 * kPi * tool.spindle_rpm / 60.0 * (tool.clockwise ? -1.0 : 1.0);
  std::vector<Move> moves;
  bool have_prev = false;
  double t_prev = 0.0, t_first = 0.0;
  Vec3 p_prev = Vec3::Zero();
  int line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty()) continue;
    double v[4];
    const char* p = line.data();
    const char* end = line.data() + line.size();
    for (int k = 0; k < 4; ++k) {
      const auto res = std::from_chars(p, end, v[k]);
      if (res.ec != std::errc() || !std::isfinite(v[k]) ||
          (k < 3 && (res.ptr == end || *res.ptr != ','))) {
        throw InputError(name + ":" + std::to_string(line_no) +
                         ": expected four numbers t_s,x_mm,y_mm,z_mm at the start of the row");
      }
      p = (res.ptr == end) ? end : res.ptr + 1;
    }
    const Vec3 pos(v[1], v[2], v[3]);
    if (have_prev) {
      if (v[0] < t_prev) {
        throw InputError(name + ":" + std::to_string(line_no) + ": t_s = " + text::sig(v[0]) +
                         " is before the previous row's " + text::sig(t_prev) +
                         ": the setpoints must be in time order");
      }
      Move m;
      m.from_mm = p_prev;
      m.to_mm = pos;
      m.t0_s = t_prev;
      m.t1_s = v[0];
      m.spindle0_rad = std::fmod(omega * (t_prev - t_first), 2.0 * kPi);
      moves.push_back(m);
    } else {
      t_first = v[0];
    }
    have_prev = true;
    t_prev = v[0];
    p_prev = pos;
  }
  if (moves.empty()) {
    throw InputError(name + ": fewer than two setpoints: nothing moves");
  }
  return moves;
}

}  // namespace ncd::surface
