// Checks before motion (job_checks.hpp; the rules and their reasons in docs/hardening.md).
#include "service/job_checks.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <variant>

#include "core/error.hpp"
#include "core/number_text.hpp"

namespace ncd::service {
namespace {

constexpr double kBallRadiusMatchMm = 1e-9;
constexpr int kSamplesPerSpan = 64;  // curve samples per knot span (envelope, length)

std::string where(const toolpath::Path& path, std::size_t k) {
  std::string w = path.source + ": segment " + std::to_string(k + 1);
  if (path.segments[k].source_line > 0) {
    w += " (line " + std::to_string(path.segments[k].source_line) + ")";
  }
  return w;
}

// Calls f(point) for the control points of a curve, or for its samples when dense is set.
template <typename F>
void curve_points(const toolpath::NurbsCurve& c, bool dense, F&& f) {
  if (!dense) {
    for (const Vec3& p : c.points()) f(p);
    return;
  }
  const std::vector<double> breaks = c.breakpoints();
  for (std::size_t i = 0; i + 1 < breaks.size(); ++i) {
    for (int k = 0; k <= kSamplesPerSpan; ++k) {
      const double u = breaks[i] + (breaks[i + 1] - breaks[i]) * k / kSamplesPerSpan;
      f(c.eval(u).p);
    }
  }
}

// The first coordinate of p outside the envelope, as a message; empty when inside.
std::string outside(const Vec3& p, const Envelope& e) {
  static const char* const kAxis[] = {"X", "Y", "Z"};
  for (int a = 0; a < 3; ++a) {
    if (!(p[a] >= e.min_mm[a] && p[a] <= e.max_mm[a])) {
      return std::string(kAxis[a]) + " = " + text::sig(p[a]) +
             " mm is outside the machine's travel " + text::sig(e.min_mm[a]) + " .. " +
             text::sig(e.max_mm[a]) + " mm";
    }
  }
  return {};
}

double segment_length_mm(const toolpath::PathSegment& seg) {
  double length = 0.0;
  if (const auto* line = std::get_if<toolpath::Polyline>(&seg.geometry)) {
    for (std::size_t i = 0; i + 1 < line->points.size(); ++i) {
      length += (line->points[i + 1] - line->points[i]).norm();
    }
    return length;
  }
  // A chord polygon of the curve: never longer than the curve, so the estimate stays a bound.
  Vec3 last = Vec3::Zero();
  bool first = true;
  curve_points(std::get<toolpath::NurbsCurve>(seg.geometry), true, [&](const Vec3& p) {
    if (!first) length += (p - last).norm();
    last = p, first = false;
  });
  return length;
}

}  // namespace

ChamferAcceptance accept_chamfer(const toolpath::Path& path, MachineConfig& machine,
                                 bool allow_interference, const std::string& allow_flag) {
  ChamferAcceptance out;
  if (!path.chamfer) return out;
  const toolpath::ChamferOrigin& c = *path.chamfer;
  if (!c.checks_ok) {
    if (!allow_interference) {
      throw InputError(path.source + ": this chamfer failed its interference checks (" +
                       c.failed_checks +
                       "), so it would cut into the part; regenerate it with a smaller "
                       "--ball-radius, or give " +
                       allow_flag + " for a deliberate test cut");
    }
    out.interference_allowed = true;
    out.note = "WARNING: " + path.source + " failed its interference checks (" + c.failed_checks +
               "); run anyway because of " + allow_flag;
  }
  if (c.ball_radius_mm > 0.0) {
    const double machine_mm = machine.cutting.ball_radius_mm;
    if (machine.source == "defaults") {
      // A chamfer brings its tool, cut in a single pass (no pick feed), as the paper's
      // experiments and config/chamfer-exp3.toml are.
      machine.cutting.ball_radius_mm = c.ball_radius_mm;
      machine.cutting.pick_feed_mm = 0.0;
    } else if (std::abs(machine_mm - c.ball_radius_mm) > kBallRadiusMatchMm) {
      throw InputError(path.source + " was made for a ball radius of " +
                       text::sig(c.ball_radius_mm) + " mm, but the machine file " + machine.source +
                       " has [cutting] ball_radius_mm = " + text::sig(machine_mm) +
                       " mm; use the machine file of that tool, or regenerate the chamfer with "
                       "--ball-radius " +
                       text::sig(machine_mm));
    }
  }
  return out;
}

void check_envelope(const toolpath::Path& path, const MachineConfig& machine) {
  const Envelope& e = machine.envelope;
  for (std::size_t k = 0; k < path.segments.size(); ++k) {
    const toolpath::PathSegment& seg = path.segments[k];
    std::string why;
    if (const auto* line = std::get_if<toolpath::Polyline>(&seg.geometry)) {
      for (std::size_t i = 0; i < line->points.size() && why.empty(); ++i) {
        why = outside(line->points[i], e);
        if (!why.empty()) why = "point " + std::to_string(i) + ": " + why;
      }
    } else {
      const auto& curve = std::get<toolpath::NurbsCurve>(seg.geometry);
      bool hull_inside = true;
      curve_points(curve, false, [&](const Vec3& p) { hull_inside &= outside(p, e).empty(); });
      if (!hull_inside) {
        curve_points(curve, true, [&](const Vec3& p) {
          if (why.empty()) why = outside(p, e);
        });
      }
    }
    if (!why.empty()) {
      throw InputError(where(path, k) + ": " + why +
                       "; no motion started. Fix the program, or set the machine file's "
                       "[envelope] (x_min_mm … z_max_mm) to the machine's real travel");
    }
  }
}

RunEstimate estimate_run(const toolpath::Path& path, const MachineConfig& machine) {
  RunEstimate r;
  const double v_max = machine.limits.max_feed_mm_per_min / 60.0;
  for (const toolpath::PathSegment& seg : path.segments) {
    const double length = segment_length_mm(seg);
    double v = v_max;
    if (!seg.rapid && seg.feed_mm_per_min && *seg.feed_mm_per_min > 0.0) {
      v = std::min(v, *seg.feed_mm_per_min / 60.0);
    }
    r.length_mm += length;
    r.duration_s += length / v;
  }
  const double periods = std::ceil(r.duration_s / machine.limits.period_s);
  // Saturated: a runaway estimate must not overflow the integers that report it.
  const double cap = 1e15;
  r.periods = static_cast<std::int64_t>(std::min(periods, cap));
  r.setpoint_bytes =
      static_cast<std::int64_t>(std::min(periods * static_cast<double>(kSetpointRowBytes), cap));
  return r;
}

void check_estimate(const RunEstimate& r, bool with_setpoints) {
  if (!(r.duration_s <= kMaxRunS)) {
    throw InputError("the run would take at least " + text::sig(r.duration_s / 3600.0) + " h (" +
                     text::sig(r.length_mm) +
                     " mm at the programmed feeds), more than the limit of " +
                     text::sig(kMaxRunS / 3600.0) +
                     " h for one job; check the program's coordinates and feeds (F), or split it");
  }
  if (with_setpoints && r.setpoint_bytes > kMaxSetpointBytes) {
    throw InputError("the setpoints file would hold " + std::to_string(r.periods) +
                     " rows, about " + text::sig(static_cast<double>(r.setpoint_bytes) / 1e9) +
                     " GB, more than the limit of " +
                     text::sig(static_cast<double>(kMaxSetpointBytes) / 1e9) +
                     " GB; leave out --setpoints or split the program");
  }
}

}  // namespace ncd::service
