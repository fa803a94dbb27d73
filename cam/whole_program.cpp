// Generated jobs as whole programs (whole_program.hpp, docs/whole-program.md).
//
// The sequence, in the program's frame and programmed point (Z up, the part below):
//   G21 (UnitsEvent), T M6 (ToolChangeEvent), G43 H (ToolOffsetEvent with h = the tool and no
//   offset of its own: the path is already in the programmed point), M3 S (SpindleEvent), G4
//   P (DwellEvent); G0 to the clearance plane over the approach point: a rapid from an unknown
//   position, which
//     the writers split into "rise to Z first, then X Y" (the tool never moves sideways below
//     the clearance plane from wherever it stands);
//   G0 down to approach_gap_mm above the feed's start (skipped when that is not below the plane);
//   G1 down to the start height; for an inner edge then G1 out from the drill axis to the edge;
//   the cut;
//   the way back: inner edges G1 back to the axis, then G0 up to the clearance plane;
//   M5 (SpindleEvent off), M2 (EndEvent).
// The spindle event sets stop_before on the first planned move (to_path), so the planner starts
// from rest after it; the rapids are planned at the machine's rapid rate and written as G0.
//
// A job that ends early leaves the part by SafeRetract (job_retract, program_retract): the same
// clearance plane and, for an inner edge, the same way back to the drill axis, from wherever the
// tool stopped (comms::ending_blocks writes it; docs/whole-program.md, "Ending early").
#include "cam/whole_program.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/error.hpp"
#include "core/number_text.hpp"

namespace ncd::toolpath {
namespace {

Vec3 segment_start(const PathSegment& s) {
  if (const auto* p = std::get_if<Polyline>(&s.geometry)) return p->points.front();
  return std::get<NurbsCurve>(s.geometry).points().front();
}
Vec3 segment_end(const PathSegment& s) {
  if (const auto* p = std::get_if<Polyline>(&s.geometry)) return p->points.back();
  return std::get<NurbsCurve>(s.geometry).points().back();
}
double segment_top(const PathSegment& s) {
  double top = -1e300;
  if (const auto* p = std::get_if<Polyline>(&s.geometry)) {
    for (const Vec3& q : p->points) top = std::max(top, q.z());
  } else {
    // The convex hull property: a NURBS curve lies within its control points' hull.
    for (const Vec3& q : std::get<NurbsCurve>(s.geometry).points()) top = std::max(top, q.z());
  }
  return top;
}

class Builder {
 public:
  explicit Builder(const JobFrame& f) : f_(f) {}
  void event(Event e) { p_.steps.push_back({std::move(e), {}}); }
  Motion motion(const Vec3& from, bool rapid, double feed) const {
    Motion m;
    m.start = from;
    m.rapid = rapid;
    m.feed = rapid ? 0.0 : feed;
    m.spindle = spindle_on_ ? SpindleDir::cw : SpindleDir::off;
    m.spindle_rpm = f_.spindle_rpm;
    m.tool = f_.tool;
    return m;
  }
  void line(const Vec3& to, bool rapid, double feed = 0.0, bool start_known = true) {
    Motion m = motion(at_, rapid, feed);
    m.geometry = LineMove{to};
    m.start_known = start_known;
    p_.steps.push_back({std::move(m), {}});
    at_ = to;
  }
  void segment(const PathSegment& s) {
    Motion m = motion(at_, s.rapid, s.feed_mm_per_min.value_or(f_.feed_mm_per_min));
    if (const auto* pl = std::get_if<Polyline>(&s.geometry)) {
      m.geometry = PolylineMove{*pl};
    } else {
      m.geometry = NurbsMove{std::get<NurbsCurve>(s.geometry)};
    }
    p_.steps.push_back({std::move(m), {}});
    at_ = segment_end(s);
  }
  bool spindle_on_ = false;
  Program p_;
  Vec3 at_ = Vec3::Zero();

 private:
  const JobFrame& f_;
};

}  // namespace

std::string programmed_point_text(ProgramPoint point, double ball_radius_mm) {
  return point == ProgramPoint::Tip
             ? "programmed point: ball TIP = centre - " + text::fixed(ball_radius_mm, 4) +
                   " mm in Z; tool length set to the tip"
             : "programmed point: ball CENTRE; tool length set to the ball "
               "centre";
}

Program whole_job(const Path& cut, const JobFrame& f) {
  require_positive("feed (mm/min)", f.feed_mm_per_min);
  require_positive("spindle speed (rpm)", f.spindle_rpm);
  require_finite("clearance Z (mm)", f.clearance_z_mm);
  if (!(f.spindle_dwell_s >= 0.0) || !std::isfinite(f.spindle_dwell_s)) {
    throw InputError("spindle dwell " + text::fixed(f.spindle_dwell_s, 4) +
                     " s must be 0 or more; give the spindle's spin-up time");
  }
  if (!(f.approach_gap_mm > 0.0) || !std::isfinite(f.approach_gap_mm)) {
    throw InputError("approach gap " + text::fixed(f.approach_gap_mm, 4) +
                     " mm must be greater than 0");
  }
  if (cut.segments.empty()) throw InputError(cut.source + ": the job has no motion to wrap");
  double top = -1e300;
  for (const PathSegment& s : cut.segments) top = std::max(top, segment_top(s));
  if (f.clearance_z_mm <= top) {
    throw InputError("the clearance plane Z " + text::fixed(f.clearance_z_mm, 4) +
                     " mm is not above the highest point of the cut (" + text::fixed(top, 4) +
                     " mm); give a larger safe Z");
  }
  Builder b(f);
  b.event(UnitsEvent{Units::mm});
  if (f.tool_change) b.event(ToolChangeEvent{f.tool, 0.0});
  if (f.length_offset) b.event(ToolOffsetEvent{Vec3::Zero(), Units::mm, f.tool});
  b.event(SpindleEvent{SpindleDir::cw, f.spindle_rpm});
  b.spindle_on_ = true;
  if (f.spindle_dwell_s > 0.0) b.event(DwellEvent{f.spindle_dwell_s});
  const Vec3 first = segment_start(cut.segments.front());
  const Vec3 over = f.axis_xy ? Vec3(f.axis_xy->x(), f.axis_xy->y(), f.clearance_z_mm)
                              : Vec3(first.x(), first.y(), f.clearance_z_mm);
  b.line(over, true, 0.0, false);  // from wherever the tool stands: rise first, then X Y
  const Vec3 bottom(over.x(), over.y(), first.z());
  const double gap_z = first.z() + f.approach_gap_mm;
  if (gap_z < f.clearance_z_mm) b.line(Vec3(over.x(), over.y(), gap_z), true);
  b.line(bottom, false, f.feed_mm_per_min);
  if (f.axis_xy && (first - bottom).norm() > 0.0) b.line(first, false, f.feed_mm_per_min);
  for (const PathSegment& s : cut.segments) b.segment(s);
  if (f.axis_xy) {
    const Vec3 back(over.x(), over.y(), b.at_.z());
    if ((back - b.at_).norm() > 0.0) b.line(back, false, f.feed_mm_per_min);
  }
  b.line(Vec3(b.at_.x(), b.at_.y(), f.clearance_z_mm), true);
  b.spindle_on_ = false;
  b.event(SpindleEvent{SpindleDir::off, 0.0});
  b.event(EndEvent{2});
  b.p_.files = {cut.source};
  // Every job ncd generates is cut by the ball end of [cutting] (geometry/tool.hpp): the
  // roughness law caps it.
  b.p_.tools[f.tool] = ToolSpec{ToolKind::ball, 0.0, 0, "the machine file's [tool]"};
  return std::move(b.p_);
}

SafeRetract job_retract(const Path& cut, const JobFrame& f) {
  SafeRetract r;
  r.clearance_z_mm = f.clearance_z_mm;
  r.clearance_from = "the job's clearance plane";
  r.feed_mm_per_min = f.feed_mm_per_min;
  r.spindle_rpm = f.spindle_rpm;
  r.spindle_dwell_s = f.spindle_dwell_s;
  if (f.axis_xy) {
    r.axis_xy = Vec3(f.axis_xy->x(), f.axis_xy->y(), 0.0);
    const auto reach = [&](const Vec3& p) {
      r.bore_radius_mm =
          std::max(r.bore_radius_mm, std::hypot(p.x() - r.axis_xy->x(), p.y() - r.axis_xy->y()));
    };
    for (const PathSegment& s : cut.segments) {
      if (const auto* p = std::get_if<Polyline>(&s.geometry)) {
        for (const Vec3& q : p->points) reach(q);
      } else {
        for (const Vec3& q : std::get<NurbsCurve>(s.geometry).points()) reach(q);
      }
    }
  }
  return r;
}

SafeRetract program_retract(const Program& program, const Path& planned) {
  SafeRetract r;
  double top = -1e300;
  for (const PathSegment& s : planned.segments) top = std::max(top, segment_top(s));
  if (!(top > -1e299)) {
    throw InputError(planned.source + ": the program has no motion, so no clearance plane");
  }
  r.clearance_z_mm = top;
  r.clearance_from = "the highest Z the program reaches";
  for (const Step& step : program.steps) {
    if (const auto* ev = std::get_if<Event>(&step.item)) {
      if (const auto* end = std::get_if<EndEvent>(ev)) r.end_m = end->m == 30 ? 30 : 2;
      if (const auto* sp = std::get_if<SpindleEvent>(ev)) {
        if (sp->dir != SpindleDir::off) r.spindle_rpm = sp->rpm;
      }
    }
  }
  return r;
}

std::string retract_advice(const SafeRetract& r) {
  std::string way =
      "straight up to Z " + text::fixed(r.clearance_z_mm, 3) + " mm (" + r.clearance_from + ")";
  if (r.axis_xy) {
    way = "if the tool is in the bore, first horizontally back to the drill axis (X " +
          text::fixed(r.axis_xy->x(), 3) + " Y " + text::fixed(r.axis_xy->y(), 3) + "), then " +
          way;
  }
  return "at the machine: stop the motion (feed hold, then reset), switch the spindle (M5) and "
         "the coolant (M9) off, and retract the tool " +
         way;
}

Program chamfer_job(const ChamferPath& path, const NgcOptions& o) {
  const ChamferSpec& s = path.spec;
  if (path.points.empty()) throw InputError("the chamfer path has no points");
  Polyline loop;
  for (const CutterPose& pose : path.points) {
    loop.points.push_back(program_point(s, pose, o.point, o.frame));
  }
  loop.points.push_back(loop.points.front());  // closed
  PathSegment seg;
  seg.geometry = std::move(loop);
  seg.feed_mm_per_min = o.feed_mm_per_min;
  Path cut;
  cut.segments.push_back(std::move(seg));
  cut.source = "ncd chamfer";
  JobFrame f;
  f.feed_mm_per_min = o.feed_mm_per_min;
  f.spindle_rpm = o.spindle_rpm;
  f.spindle_dwell_s = o.spindle_dwell_s;
  f.tool = o.tool;
  f.tool_change = o.tool_change;
  f.length_offset = o.length_offset;
  f.clearance_z_mm = o.safe_z_mm;
  if (s.edge == Edge::Inner) f.axis_xy = program_frame_point(s, Vec3::Zero(), o.frame);
  return whole_job(cut, f);
}

}  // namespace ncd::toolpath
