// Program model helpers and the conversion to the planner's Path (docs/ngc-interpreter.md).
//
// Arcs become rational quadratic Bézier pieces joined in one degree-2 NURBS (Piegl & Tiller,
// The NURBS Book, §7.3): a piece of angle Δ ≤ 90° about centre c with radius r has the control
// points P0 = c + r·u(θ0), P1 = c + (r / cos(Δ/2))·u(θ0 + Δ/2), P2 = c + r·u(θ0 + Δ), weights
// 1, cos(Δ/2), 1; knots 0,0,0,1,1,2,2,…,n,n,n. For a circle this is exact. A helix (axis
// coordinate linear in the angle) or a spiral (radius linear in the angle, as LinuxCNC allows
// when start and end radii differ slightly) puts P1 at the mean radius and mean height: the
// piece then deviates from the exact curve, the deviation is measured at 15 interior
// parameters per piece and the pieces are halved until it is at most the stated tolerance.
#include "gcode/program.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>

#include "core/error.hpp"
#include "core/number_text.hpp"

namespace ncd::toolpath {

PlaneAxes plane_axes(Plane plane) {
  switch (plane) {
    case Plane::xz:
      return {2, 0, 1};
    case Plane::yz:
      return {1, 2, 0};
    case Plane::xy:
    default:
      return {0, 1, 2};
  }
}

ArcGeometry arc_geometry(const Vec3& start, const ArcMove& arc) {
  const PlaneAxes ax = plane_axes(arc.plane);
  const double s1 = start[ax.first] - arc.centre[ax.first];
  const double s2 = start[ax.second] - arc.centre[ax.second];
  const double e1 = arc.end[ax.first] - arc.centre[ax.first];
  const double e2 = arc.end[ax.second] - arc.centre[ax.second];
  const double a0 = std::atan2(s2, s1);
  const double a1 = std::atan2(e2, e1);
  constexpr double kTwoPi = 2.0 * kPi;
  // LinuxCNC's rule: an end within 1e-9 of the start's angle is a full turn.
  double sweep = a1 - a0;
  const int n = std::abs(arc.turns);
  if (arc.turns > 0) {
    if (sweep < 1e-12) sweep += kTwoPi;
    sweep += (n - 1) * kTwoPi;
  } else {
    if (sweep > -1e-12) sweep -= kTwoPi;
    sweep -= (n - 1) * kTwoPi;
  }
  ArcGeometry g;
  g.radius = std::hypot(s1, s2);
  g.sweep_rad = sweep;
  g.rise = arc.end[ax.axis] - start[ax.axis];
  return g;
}

Vec3 motion_end(const Motion& m) {
  return std::visit(
      [&](const auto& g) -> Vec3 {
        using T = std::decay_t<decltype(g)>;
        if constexpr (std::is_same_v<T, LineMove> || std::is_same_v<T, ArcMove>) {
          return g.end;
        } else if constexpr (std::is_same_v<T, NurbsMove>) {
          return g.curve.points().back();
        } else {
          return g.polyline.points.empty() ? m.start : g.polyline.points.back();
        }
      },
      m.geometry);
}

namespace {

// Arc length of a spiral-helix: radius r0 → r1 and rise h linear in the angle over `sweep`;
// Simpson's rule on 64 panels (exact for the circle and the helix, whose speed is constant).
double arc_length(double r0, double r1, double sweep, double rise) {
  const double a = std::abs(sweep);
  if (a == 0.0) return std::abs(rise);
  const double dr = (r1 - r0) / a;
  const double dh = rise / a;
  const auto speed = [&](double t) {
    const double r = r0 + dr * t;
    return std::sqrt(r * r + dr * dr + dh * dh);
  };
  constexpr int kPanels = 64;
  const double step = a / kPanels;
  double sum = speed(0.0) + speed(a);
  for (int i = 1; i < kPanels; ++i) sum += speed(i * step) * (i % 2 ? 4.0 : 2.0);
  return sum * step / 3.0;
}

double end_radius(const Vec3& centre, const ArcMove& arc) {
  const PlaneAxes ax = plane_axes(arc.plane);
  return std::hypot(arc.end[ax.first] - centre[ax.first], arc.end[ax.second] - centre[ax.second]);
}

}  // namespace

double motion_length(const Motion& m) {
  return std::visit(
      [&](const auto& g) -> double {
        using T = std::decay_t<decltype(g)>;
        if constexpr (std::is_same_v<T, LineMove>) {
          return (g.end - m.start).norm();
        } else if constexpr (std::is_same_v<T, ArcMove>) {
          const ArcGeometry a = arc_geometry(m.start, g);
          return arc_length(a.radius, end_radius(g.centre, g), a.sweep_rad, a.rise);
        } else if constexpr (std::is_same_v<T, NurbsMove>) {
          // Chord sum on a fine sampling: enough for a summary and for inverse-time feeds.
          const NurbsCurve& c = g.curve;
          const std::vector<double> br = c.breakpoints();
          double len = 0.0;
          Vec3 prev = c.eval(c.u_begin()).p;
          for (std::size_t k = 0; k + 1 < br.size(); ++k) {
            constexpr int kSteps = 64;
            for (int i = 1; i <= kSteps; ++i) {
              const Vec3 p = c.eval(br[k] + (br[k + 1] - br[k]) * i / kSteps).p;
              len += (p - prev).norm();
              prev = p;
            }
          }
          return len;
        } else {
          return length_mm(g.polyline);
        }
      },
      m.geometry);
}

namespace {

constexpr double kMinMoveMm = 1e-9;  // shorter moves add no geometry (see docs)

// The arc in machine mm as one degree-2 NURBS, see the top of this file.
NurbsCurve arc_nurbs(const Motion& m, const ArcMove& arc, double tol_mm,
                     const std::string& where_arc) {
  const double k = mm_per_unit(m.units);
  const PlaneAxes ax = plane_axes(arc.plane);
  const ArcGeometry g = arc_geometry(m.start, arc);
  const double r0 = g.radius * k;
  const double r1 = end_radius(arc.centre, arc) * k;
  const Vec3 c = (arc.centre + m.offset) * k;
  const double h0 = (m.start[ax.axis] + m.offset[ax.axis]) * k;
  const double rise = g.rise * k;
  const double a0 = std::atan2(m.start[ax.second] - arc.centre[ax.second],
                               m.start[ax.first] - arc.centre[ax.first]);
  const double sweep = g.sweep_rad;
  const auto point = [&](double radius, double angle, double h) {
    Vec3 p;
    p[ax.first] = c[ax.first] + radius * std::cos(angle);
    p[ax.second] = c[ax.second] + radius * std::sin(angle);
    p[ax.axis] = h;
    return p;
  };
  // Exact point at fraction f of the sweep.
  const auto exact = [&](double f) {
    return point(r0 + (r1 - r0) * f, a0 + sweep * f, h0 + rise * f);
  };
  int pieces = std::max(1, static_cast<int>(std::ceil(std::abs(sweep) / (kPi / 2.0) - 1e-12)));
  for (;;) {
    std::vector<Vec3> pts;
    std::vector<double> w;
    std::vector<double> knots{0, 0, 0};
    const double d = sweep / pieces;
    const double half_cos = std::cos(d / 2.0);
    pts.push_back(exact(0.0));
    w.push_back(1.0);
    for (int i = 0; i < pieces; ++i) {
      const double fm = (i + 0.5) / pieces;
      pts.push_back(point((r0 + (r1 - r0) * fm) / half_cos, a0 + sweep * fm, h0 + rise * fm));
      w.push_back(half_cos);
      pts.push_back(exact(static_cast<double>(i + 1) / pieces));
      w.push_back(1.0);
      knots.push_back(i + 1.0);
      knots.push_back(i + 1.0);
    }
    knots.push_back(pieces);
    pts.back() = (arc.end + m.offset) * k;  // the programmed end, not its recomputation
    NurbsCurve curve(2, knots, pts, w);
    const bool exact_circle = rise == 0.0 && r0 == r1;
    if (exact_circle) return curve;
    // Deviation from the exact spiral-helix: the angle of each sampled point says where on it
    // the point should be.
    double dev = 0.0;
    for (int i = 0; i < pieces && dev <= tol_mm; ++i) {
      for (int s = 1; s < 16; ++s) {
        const Vec3 p = curve.eval(i + s / 16.0).p;
        double ang = std::atan2(p[ax.second] - c[ax.second], p[ax.first] - c[ax.first]);
        const double base = a0 + sweep * i / pieces;
        ang = base + std::remainder(ang - base, 2.0 * kPi);
        const double f = (ang - a0) / sweep;
        dev = std::max(dev, (p - exact(f)).norm());
      }
    }
    if (dev <= tol_mm) return curve;
    if (pieces >= (1 << 16)) {
      throw InputError(where_arc + ": the helix deviates " + std::to_string(dev * 1e3) +
                       " um from its rational-quadratic form even in 65536 pieces; split it into "
                       "shorter arcs");
    }
    pieces *= 2;
  }
}

NurbsCurve to_machine(const NurbsCurve& c, const Vec3& offset, double k) {
  std::vector<Vec3> pts;
  pts.reserve(c.points().size());
  for (const Vec3& p : c.points()) pts.push_back((p + offset) * k);
  return NurbsCurve(c.degree(), c.knots(), pts, c.rational() ? c.weights() : std::vector<double>{});
}

}  // namespace

std::string where(const Program& p, const SourceRef& s) {
  const std::string file = s.file >= 0 && static_cast<std::size_t>(s.file) < p.files.size()
                               ? p.files[static_cast<std::size_t>(s.file)]
                               : "?";
  return file + ":" + std::to_string(s.line);
}

// A tool change leaves the length offset of the tool before in force (LinuxCNC and Fanuc alike);
// until a G43 H (or a G49, the programmer's word that no offset is wanted) the controlled point
// is the old tool's. A feed, or a rapid that moves Z, before it drives the new tool by the wrong
// length: by its whole length when no offset was on (G49, the preamble of most programs).
std::optional<std::string> change_without_length_offset(const Program& program) {
  std::optional<std::size_t> change;  // the step of the last tool change not yet followed
  for (std::size_t i = 0; i < program.steps.size(); ++i) {
    const Step& step = program.steps[i];
    if (const auto* ev = std::get_if<Event>(&step.item)) {
      if (std::holds_alternative<ToolChangeEvent>(*ev)) change = i;
      if (std::holds_alternative<ToolOffsetEvent>(*ev)) change.reset();
      continue;
    }
    if (!change) continue;
    const Motion& m = std::get<Motion>(step.item);
    const bool moves_z =
        m.start_known ? std::abs(motion_end(m).z() - m.start.z()) > 0.0 : m.end_known[2];
    if (m.rapid && !moves_z) continue;
    const Step& c = program.steps[*change];
    const int tool = std::get<ToolChangeEvent>(std::get<Event>(c.item)).tool;
    const std::string t = std::to_string(tool);
    return where(program, c.src) + ": the tool change to T" + t + " is followed by " +
           (m.rapid ? "a rapid in Z" : "a feed move") + " at " + where(program, m.src) +
           " with no tool length offset for it: the controller would drive the spindle's gauge "
           "line (or the tool before's length) where the program means the tool's point, "
           "which runs the tool into the part by its length. Add G43 H" +
           t +
           " after the M6 (the controller's tool table gives the length), or G49 after it "
           "if the tool's length is set in the work offset";
  }
  return std::nullopt;
}

namespace {

// What to_path carries from step to step.
struct PathState {
  Path path;
  bool stop_pending = false;
  bool open = false;  // path.segments.back() is a Polyline the next line may extend
  PathControl control = PathControl::blend;
  std::optional<double> blend_mm, smooth_mm;
  // Where the machine stands (mm, machine coordinates): the end of the last motion, or the
  // program's start while none has been made (zero-length ones included).
  std::optional<Vec3> machine_at;
  bool tool_changed = false;         // a tool change since that motion
  std::vector<RotaryIndex> indexes;  // made since the last segment, at rest before the next
  int event_line = 0;                // the source line of the event being applied
};

// Every event ends the run: it happens at a segment boundary, which corner blending moves with
// the corner (ProgramBlocks finds it there).
void apply_event(const Event& ev, PathState& st) {
  st.open = false;
  std::visit(
      [&](const auto& e) {
        using T = std::decay_t<decltype(e)>;
        if constexpr (std::is_same_v<T, PathControlEvent>) {
          st.control = e.mode;
          const double k = mm_per_unit(e.units);
          st.blend_mm = e.p ? std::optional<double>(*e.p * k) : std::nullopt;
          st.smooth_mm = e.q ? std::optional<double>(*e.q * k) : std::nullopt;
        } else if constexpr (std::is_same_v<T, RotaryIndexMove>) {
          st.stop_pending = true;  // X, Y, Z at rest while the part turns
          RotaryIndex ix{e.axis, e.from_deg, e.to_deg, std::nullopt, st.event_line};
          if (!e.rapid) ix.feed_deg_per_min = e.feed_deg_per_min;
          st.indexes.push_back(ix);
        } else if constexpr (std::is_same_v<T, DwellEvent> || std::is_same_v<T, ToolChangeEvent> ||
                             std::is_same_v<T, StopEvent> || std::is_same_v<T, SpindleEvent>) {
          st.stop_pending = true;
          if constexpr (std::is_same_v<T, ToolChangeEvent>) st.tool_changed = true;
        }
      },
      ev);
}

// The start of a motion in mm, machine coordinates. A tool change with its length offset on the
// same line (T3 M6 G43 H3): LinuxCNC re-reads the position after the change, so the program
// position stays and the offset moves the machine's (rs274 shows it so, and the interpreter
// follows). The machine does not jump: the next move starts where it stands. A line or a rapid
// is taken from there; an arc or a curve is defined from the program position and would not
// start on the machine's.
Vec3 motion_start_mm(const Program& program, const Motion& m, double k, PathState& st) {
  Vec3 start_mm = (m.start + m.offset) * k;
  const std::optional<Vec3>& at = st.machine_at;
  const bool jumps = at && (start_mm - *at).norm() > 1e-9 * std::max(1.0, at->norm());
  if (jumps && st.tool_changed) {
    if (!std::holds_alternative<LineMove>(m.geometry)) {
      throw InputError(where(program, m.src) +
                       ": an arc or curve right after a tool change whose length offset was "
                       "set on the change's own line starts " +
                       std::to_string((start_mm - *at).norm()) +
                       " mm from where the machine stands; move to its start with G0 or G1 "
                       "first, or give G43 H on the line after M6");
    }
    start_mm = *at;
  }
  st.tool_changed = false;
  st.machine_at = (motion_end(m) + m.offset) * k;
  return start_mm;
}

// A line that extends the open polyline (same feed and spindle, no stop between): true if taken.
bool extend_polyline(const Motion& m, const Vec3& end_mm, const std::optional<double>& feed,
                     const std::optional<double>& spindle, PathState& st) {
  // Each rapid is its own segment (ProgramBlocks).
  if (!st.open || st.stop_pending || m.rapid) return false;
  PathSegment& last = st.path.segments.back();
  if (last.rapid != m.rapid || last.feed_mm_per_min != feed || last.spindle_rpm != spindle ||
      m.feed_mode != FeedMode::per_minute) {
    return false;
  }
  std::get<Polyline>(last.geometry).points.push_back(end_mm);
  return true;
}

// The geometry of a motion as a new segment, in mm and machine coordinates.
std::variant<Polyline, NurbsCurve> motion_geometry(const Program& program, const Motion& m,
                                                   const Vec3& start_mm, double k,
                                                   const ToPathOptions& options) {
  if (const auto* line = std::get_if<LineMove>(&m.geometry)) {
    return Polyline{{start_mm, (line->end + m.offset) * k}, {}};
  }
  if (const auto* arc = std::get_if<ArcMove>(&m.geometry)) {
    return arc_nurbs(m, *arc, options.helix_tolerance_mm, where(program, m.src));
  }
  if (const auto* nm = std::get_if<NurbsMove>(&m.geometry)) {
    return to_machine(nm->curve, m.offset, k);
  }
  Polyline out = std::get<PolylineMove>(m.geometry).polyline;
  for (Vec3& p : out.points) p = (p + m.offset) * k;
  return out;
}

// The tool in the spindle as the program's tool list describes it.
CutterTool cutter_tool(const Program& program, int number) {
  CutterTool t;
  t.number = number;
  t.kind = ToolKind::unknown;
  if (const auto it = program.tools.find(number); it != program.tools.end()) {
    t.kind = it->second.kind;
    t.radius_mm = it->second.radius_mm;
    t.teeth = it->second.teeth;
  }
  return t;
}

}  // namespace

Path to_path(const Program& program, const ToPathOptions& options) {
  PathState st;
  st.machine_at = program.start_machine_mm;
  st.path.source = program.files.empty() ? std::string() : program.files.front();
  st.path.rotary_axis = program.rotary_axis;
  st.path.rotary_start_deg = program.rotary_start_deg;
  std::vector<std::size_t>* place = options.segment_of_step;
  if (place) place->assign(program.steps.size(), kNoSegment);
  for (std::size_t i = 0; i < program.steps.size(); ++i) {
    const Step& step = program.steps[i];
    if (const auto* ev = std::get_if<Event>(&step.item)) {
      if (place) (*place)[i] = st.path.segments.size();
      st.event_line = step.src.line;
      apply_event(*ev, st);
      continue;
    }
    const Motion& m = std::get<Motion>(step.item);
    if (!m.start_known) {
      if (m.rapid) continue;  // positions the machine from wherever it is: nothing to plan
      throw InputError(where(program, m.src) +
                       ": a feed move from an unknown position (X, Y and Z not all programmed "
                       "yet); give where the machine stands (ncd replay --start X,Y,Z in machine "
                       "mm, \"start_mm\" in an ncd serve submit, or start_mm in the machine file's "
                       "[program] table), or start the "
                       "program with a G0 to X, Y and Z");
    }
    const double k = mm_per_unit(m.units);
    const Vec3 start_mm = motion_start_mm(program, m, k, st);
    // The length where the machine goes, not where the program's words go: after a tool
    // change with its offset on the same line a line to the same program point moves the
    // machine by the offset (and an inverse-time feed times that move).
    const auto* line = std::get_if<LineMove>(&m.geometry);
    const double len_mm =
        line ? ((line->end + m.offset) * k - start_mm).norm() : motion_length(m) * k;
    if (len_mm < kMinMoveMm) continue;
    std::optional<double> feed;
    if (!m.rapid) {
      feed = m.feed_mode == FeedMode::per_minute ? m.feed * k : m.feed * len_mm;
      if (!(*feed > 0.0) || !std::isfinite(*feed)) {
        throw InputError(where(program, m.src) + ": a feed move without a positive feed; add F");
      }
    }
    const std::optional<double> spindle =
        m.spindle == SpindleDir::off ? std::nullopt : std::optional<double>(m.spindle_rpm);
    if (line) {
      if (extend_polyline(m, (line->end + m.offset) * k, feed, spindle, st)) {
        if (place) (*place)[i] = st.path.segments.size() - 1;
        continue;
      }
    }
    PathSegment seg;
    seg.geometry = motion_geometry(program, m, start_mm, k, options);
    st.open = std::holds_alternative<LineMove>(m.geometry) && m.feed_mode == FeedMode::per_minute;
    if (place) (*place)[i] = st.path.segments.size();
    seg.feed_mm_per_min = feed;
    seg.spindle_rpm = spindle;
    seg.rapid = m.rapid;
    seg.source_line = m.src.line;
    seg.path_control = st.control;
    seg.blend_tolerance_mm = st.blend_mm;
    seg.smoothing_tolerance_mm = st.smooth_mm;
    seg.stop_before = st.stop_pending;
    seg.tool = cutter_tool(program, m.tool);
    seg.indexes_before = std::move(st.indexes);
    st.indexes.clear();
    st.stop_pending = false;
    st.path.segments.push_back(std::move(seg));
  }
  st.path.indexes_at_end = std::move(st.indexes);
  return std::move(st.path);
}

namespace {

const char* units_name(Units u) {
  return u == Units::inch ? "in" : "mm";
}
const char* spindle_name(SpindleDir d) {
  return d == SpindleDir::cw ? "cw" : d == SpindleDir::ccw ? "ccw" : "off";
}
const char* plane_name(Plane p) {
  return p == Plane::xz ? "G18" : p == Plane::yz ? "G19" : "G17";
}

std::string xyz(const Vec3& p) {
  return "X" + text::trimmed(p.x(), 6, 1) + " Y" + text::trimmed(p.y(), 6, 1) + " Z" +
         text::trimmed(p.z(), 6, 1);
}

// A straight move's line, the common case of long programs, without an allocation per number.
void write_line_move(std::string& line, const Motion& m, const LineMove& g) {
  line += m.rapid ? "RAPID X" : "LINE X";
  text::append_trimmed(line, g.end.x(), 6, 1);
  line += " Y";
  text::append_trimmed(line, g.end.y(), 6, 1);
  line += " Z";
  text::append_trimmed(line, g.end.z(), 6, 1);
}

}  // namespace

// The dense G1 lines of long programs are written into one text buffer, handed to the stream
// 64 KB at a time (a write per line costs the stream's locking each time); every other step
// goes through the stream after the buffer, in order.
void write_canonical(std::ostream& out, const Program& program) {
  std::string text;
  const auto write_text = [&] {
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
    text.clear();
  };
  static const std::string unknown_file = "?";
  for (const Step& step : program.steps) {
    const std::size_t f = static_cast<std::size_t>(step.src.file);
    const std::string& file = f < program.files.size() ? program.files[f] : unknown_file;
    const auto* m = std::get_if<Motion>(&step.item);
    const auto* straight = m ? std::get_if<LineMove>(&m->geometry) : nullptr;
    if (straight && !m->rapid && m->spindle == SpindleDir::off && m->tool == 0 && m->start_known &&
        m->feed_mode == FeedMode::per_minute) {
      // The same text as below.
      text += file;
      text += ':';
      char number[16];
      text.append(number, std::to_chars(number, number + sizeof number, step.src.line).ptr);
      text += ' ';
      write_line_move(text, *m, *straight);
      text += " F";
      text::append_trimmed(text, m->feed, 6, 1);
      text += ' ';
      text += units_name(m->units);
      text += '\n';
      if (text.size() >= 65536) write_text();
      continue;
    }
    write_text();
    out << file << ':' << step.src.line << ' ';
    if (m) {
      std::visit(
          [&](const auto& g) {
            using T = std::decay_t<decltype(g)>;
            if constexpr (std::is_same_v<T, LineMove>) {
              out << (m->rapid ? "RAPID " : "LINE ") << xyz(g.end);
            } else if constexpr (std::is_same_v<T, ArcMove>) {
              const ArcGeometry a = arc_geometry(m->start, g);
              out << "ARC " << plane_name(g.plane) << ' ' << xyz(g.end) << " centre "
                  << xyz(g.centre) << " turns " << g.turns << " radius "
                  << text::trimmed(a.radius, 6, 1) << " sweep_deg "
                  << text::trimmed(rad_to_deg(a.sweep_rad), 6, 1) << " rise "
                  << text::trimmed(a.rise, 6, 1);
            } else if constexpr (std::is_same_v<T, NurbsMove>) {
              out << "NURBS degree " << g.curve.degree() << " points " << g.curve.points().size()
                  << " end " << xyz(g.curve.points().back());
            } else {
              out << "POLYLINE points " << g.polyline.points.size() << " end "
                  << xyz(g.polyline.points.empty() ? m->start : g.polyline.points.back());
            }
          },
          m->geometry);
      if (!m->rapid) {
        out << (m->feed_mode == FeedMode::inverse_time ? " F1/min " : " F")
            << text::trimmed(m->feed, 6, 1);
      }
      out << ' ' << units_name(m->units);
      if (m->spindle != SpindleDir::off)
        out << " S" << text::trimmed(m->spindle_rpm, 6, 1) << ' ' << spindle_name(m->spindle);
      if (m->tool != 0) out << " T" << m->tool;
      if (!m->start_known) out << " from-unknown-position";
      out << '\n';
      continue;
    }
    std::visit(
        [&](const auto& e) {
          using T = std::decay_t<decltype(e)>;
          if constexpr (std::is_same_v<T, SpindleEvent>) {
            out << "SPINDLE " << spindle_name(e.dir) << " S" << text::trimmed(e.rpm, 6, 1);
          } else if constexpr (std::is_same_v<T, CoolantEvent>) {
            out << "COOLANT mist " << (e.mist ? "on" : "off") << " flood "
                << (e.flood ? "on" : "off");
          } else if constexpr (std::is_same_v<T, DwellEvent>) {
            out << "DWELL " << text::trimmed(e.seconds, 6, 1) << " s";
          } else if constexpr (std::is_same_v<T, ToolChangeEvent>) {
            out << "TOOL_CHANGE T" << e.tool << " length " << text::trimmed(e.length, 6, 1);
          } else if constexpr (std::is_same_v<T, ToolOffsetEvent>) {
            out << "TOOL_OFFSET " << xyz(e.offset);
          } else if constexpr (std::is_same_v<T, StopEvent>) {
            out << (e.kind == StopKind::program_stop    ? "STOP M0"
                    : e.kind == StopKind::optional_stop ? "OPTIONAL_STOP M1"
                                                        : "PALLET_SHUTTLE M60");
          } else if constexpr (std::is_same_v<T, EndEvent>) {
            out << "END M" << e.m;
          } else if constexpr (std::is_same_v<T, MessageEvent>) {
            out << "MESSAGE \"" << e.text << "\"";
          } else if constexpr (std::is_same_v<T, PathControlEvent>) {
            out << (e.mode == PathControl::exact_path   ? "PATH_CONTROL G61"
                    : e.mode == PathControl::exact_stop ? "PATH_CONTROL G61.1"
                                                        : "PATH_CONTROL G64");
            if (e.p) out << " P" << text::trimmed(*e.p, 6, 1);
            if (e.q) out << " Q" << text::trimmed(*e.q, 6, 1);
          } else if constexpr (std::is_same_v<T, RotaryIndexMove>) {
            out << "INDEX " << static_cast<char>(std::toupper(e.axis)) << " from "
                << text::trimmed(e.from_deg, 6, 1) << " to " << text::trimmed(e.to_deg, 6, 1)
                << " deg";
            if (!e.rapid) out << " F" << text::trimmed(e.feed_deg_per_min, 6, 1);
          } else {
            out << "UNITS " << units_name(e.units);
          }
        },
        std::get<Event>(step.item));
    out << '\n';
  }
  write_text();
}

}  // namespace ncd::toolpath
