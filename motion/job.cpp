// The job loop of one period: limit sampler → planner → path walker (see job.hpp).
//
// Stretches (docs/planner.md §3): the path is cut at the sampler's stops into stretches
//
//     0 ────────── stop ────── stop ──────────── L
//       stretch 0       1            2
//
// The planner plans one stretch at a time in its own arc length, from rest to rest exactly at
// its end; Planner::restart then starts the next (no allocation). Setpoints carry the arc
// length from the path start, and the walker walks the whole path.
#include "motion/job.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

#include "core/error.hpp"

namespace ncd::motion {
namespace {

PlannerLimits planner_limits(const JobConfig& c) {
  PlannerLimits p;
  p.a_max_mm_per_s2 = c.limits.max_accel_mm_per_s2;
  p.j_max_mm_per_s3 = c.limits.max_jerk_mm_per_s3;
  p.period_s = c.limits.period_s;
  p.window_capacity = c.window_capacity;
  // Under the jerk-vector bound the sampler asks for tangential scales down to this.
  p.min_tangential_scale = c.limits.jerk_bound == interpolator::JerkBound::vector
                               ? interpolator::kTangentialScaleFloor
                               : 1.0;
  return p;
}

interpolator::WalkerConfig walker_config(const JobConfig& c) {
  interpolator::WalkerConfig w;
  w.tolerance_rel = c.limits.feed_tolerance_rel;
  return w;
}

// 0, every stop, L: the stretches the planner plans from rest to rest.
std::vector<double> stretch_bounds(const interpolator::LimitSampler& sampler, double length_mm) {
  std::vector<double> b{0.0};
  for (const double s : sampler.stops_mm()) b.push_back(s);
  b.push_back(length_mm);
  return b;
}

std::vector<double> segment_starts(const interpolator::PathWalker& w, std::size_t segments) {
  std::vector<double> s;
  for (std::size_t k = 0; k <= segments; ++k) s.push_back(w.segment_start_mm(k));
  return s;
}

// The limits are checked first: blending computes with them. Dense runs under G64 Q are fitted
// first (docs/planner.md §3b); the corners left between polyline parts are then blended.
toolpath::Path blended_path(const toolpath::Path& path, const JobConfig& c,
                            interpolator::FitReport* fit, interpolator::BlendReport* report) {
  interpolator::validate(c.limits);
  return interpolator::blend_corners(interpolator::fit_polylines(path, c.limits, fit), c.limits,
                                     report);
}

StepBounds step_bounds(const JobConfig& c) {
  StepBounds b;
  b.max_feed_mm_per_s = c.limits.max_feed_mm_per_min / 60.0;
  b.max_accel_mm_per_s2 = c.limits.max_accel_mm_per_s2;
  b.period_s = c.limits.period_s;
  return b;
}

}  // namespace

const char* to_string(StepFault fault) {
  switch (fault) {
    case StepFault::None:
      return "none";
    case StepFault::Speed:
      return "speed";
    case StepFault::Acceleration:
      return "acceleration";
    case StepFault::Walk:
      return "walk";
  }
  return "none";
}

const char* limit_name(std::uint8_t id) {
  switch (id) {
    case kLimitIdAcceleration:
      return "tangential_accel";
    case kLimitIdJerk:
      return "tangential_jerk";
    case kLimitIdPathEnd:
      return "path_end";
    case kLimitIdLookahead:
      return "lookahead";
    case kLimitIdHold:
      return "hold";
    default:
      break;
  }
  if (id < interpolator::kFeedLimitCount) {
    return interpolator::to_string(static_cast<interpolator::FeedLimit>(id));
  }
  return "unknown";
}

Job::Job(const toolpath::Path& path, const JobConfig& config)
    : path_(blended_path(path, config, &fit_, &blend_)),
      config_(config),
      walker_(path_, walker_config(config)),
      sampler_(path_, segment_starts(walker_, path_.segments.size()), config.limits, config.cutting,
               config.sampler),
      bounds_(stretch_bounds(sampler_, walker_.length_mm())),
      planner_(planner_limits(config), bounds_[1] - bounds_[0]),
      guard_(step_bounds(config), walker_.position()) {
  interpolator::validate(config.limits);
  interpolator::validate(config.cutting);
  // Every limit is capped by the machine's maximum feed: size the planner for it now, so
  // that nothing allocates once the cycle runs.
  planner_.reserve_for_speed(config.limits.max_feed_mm_per_min / 60.0);
}

// Feeds the planner the nodes of the current stretch, in its own arc length (from the
// stretch's start). The node at a stop ends the stretch with the limit of the interval before
// it; the next stretch begins there, at s = 0, with the limit of the interval after it.
void Job::prepare() {
  const double start = bounds_[run_], end = bounds_[run_ + 1];
  const bool last = run_ + 2 == bounds_.size();
  const double tol = 1e-9 * std::max(1.0, end);
  const auto check = [&](double s_mm, double v_mm_per_s, interpolator::FeedLimit limit) {
    if (!(v_mm_per_s > 0.0) || !std::isfinite(v_mm_per_s)) {
      throw InputError(
          "the path needs a full stop at s = " + std::to_string(start + s_mm) + " mm (" +
          interpolator::to_string(limit) +
          " limit is 0 there: a cusp of a curve, where its parametric speed vanishes inside "
          "it); split the curve there into two segments");
    }
  };
  const auto push = [&](double s_mm, double v_mm_per_s, interpolator::FeedLimit limit,
                        const JerkVectorSpan& span) {
    check(s_mm, v_mm_per_s, limit);
    planner_.push({s_mm, v_mm_per_s, static_cast<std::uint8_t>(limit), span});
  };
  while (planner_.wants_samples()) {
    if (carry_n_ > 0) {
      planner_.push(carry_[0]);
      carry_[0] = carry_[1];
      --carry_n_;
      continue;
    }
    if (sampler_done_) break;
    interpolator::LimitNode node;
    if (!sampler_.next(node)) {
      sampler_done_ = true;
      break;
    }
    // The sampler's node on a segment end can follow one that falls within tol short of it
    // (its interval ends are summed apart from the walker's segment starts): that one ended
    // the last stretch, and this twin on the stop would repeat s = 0 here. The next node's
    // limit covers the interval after the stop.
    if (std::exchange(stop_taken_early_, false) && node.s_mm - start <= tol) continue;
    if (!last && node.s_mm >= end - tol) {
      const double length = end - start;
      const double left = node.s_mm > end + tol ? node.feed_mm_per_s : node.left_mm_per_s;
      // The stretch ends here: no interval of it starts at this node. The next stretch starts
      // with the interval after the node (or, where the node lies past the stop, with the
      // interval of the node before, which holds the stop).
      const bool past = node.s_mm > end + tol;
      const JerkVectorSpan span = node.jerk_span, first = past ? last_span_ : span;
      push(length, left, node.limit, JerkVectorSpan{});
      const double right = past ? left : node.right_mm_per_s;
      check(length, right, node.limit);
      carry_[0] = {0.0, right, static_cast<std::uint8_t>(node.limit), first};
      carry_n_ = 1;
      stop_taken_early_ = node.s_mm < end;
      if (past) {  // no node fell on the stop: keep this one for the next
        carry_[1] = {node.s_mm - end, node.feed_mm_per_s, static_cast<std::uint8_t>(node.limit),
                     span};
        carry_n_ = 2;
      }
      break;  // the planner has its end
    }
    push(node.s_mm - start, node.feed_mm_per_s, node.limit, node.jerk_span);
    last_span_ = node.jerk_span;
  }
}

Setpoint Job::step() {
  const MotionSample m = planner_.step();
  const bool last = run_ + 2 == bounds_.size();
  const double s_mm = m.done ? bounds_[run_ + 1] : bounds_[run_] + m.s_mm;
  if (m.done && !last) {  // at rest at a stop: the next stretch starts from here
    ++run_;
    planner_.restart(bounds_[run_ + 1] - bounds_[run_]);
  }
  Setpoint sp;
  sp.t_s = m.t_s;
  sp.s_mm = s_mm;
  sp.v_mm_per_s = m.v_mm_per_s;
  sp.a_mm_per_s2 = m.a_mm_per_s2;
  sp.j_mm_per_s3 = m.j_mm_per_s3;
  sp.limit_id = m.limit_id;
  sp.feed_limit_mm_per_s = m.v_limit_mm_per_s;
  sp.planned_ds_mm = s_mm - last_s_mm_;
  last_s_mm_ = s_mm;
  const interpolator::WalkStep w = walker_.advance(sp.planned_ds_mm);
  sp.p = w.p;
  sp.travelled_mm = w.travelled_mm;
  sp.chord_error_mm = w.chord_error_mm;
  sp.iterations = w.iterations;
  sp.converged = w.converged;
  sp.done = m.done && last;
  sp.fault = guard_.check(sp.t_s, sp.s_mm, sp.planned_ds_mm, sp.p);
  return sp;
}

void Job::set_override(double fraction) {
  planner_.set_override(fraction);
  guard_.set_override(fraction);
}

std::string Job::fault_message() const {
  const StepFaultInfo& f = guard_.info();
  if (f.fault == StepFault::None) return {};
  static const char* const kWhat[] = {
      "", "the planned step is faster than the machine's maximum feed",
      "the planned step changes faster than the maximum acceleration allows",
      "the position jumps farther than the planned arc length"};
  char text[512];
  std::snprintf(text, sizeof text,
                "step rule (%s): %s at period %lld (t = %.4f s, s = %.4f mm): from (%.4f, %.4f, "
                "%.4f) to (%.4f, %.4f, %.4f) mm, %.6g mm against at most %.6g mm; the setpoint was "
                "not emitted and the job stopped there (see docs/hardening.md, \"The step rule\")",
                to_string(f.fault), kWhat[static_cast<int>(f.fault)],
                static_cast<long long>(f.period), f.t_s, f.s_mm, f.from_mm.x(), f.from_mm.y(),
                f.from_mm.z(), f.to_mm.x(), f.to_mm.y(), f.to_mm.z(), f.value, f.allowed);
  return text;
}

std::vector<double> Job::segment_starts_mm() const {
  const std::vector<double> walked = segment_starts(walker_, path_.segments.size());
  std::vector<double> starts;  // per segment of the path given: the first piece of each
  for (std::size_t j = 0; j < path_.segments.size(); ++j) {
    const std::size_t k = j < fit_.source_segment.size() ? fit_.source_segment[j] : j;
    if (k == starts.size()) starts.push_back(walked[j]);
  }
  starts.push_back(walked.back());
  return starts;
}

interpolator::FeedLimitResult Job::limit_here() const {
  const std::size_t seg = walker_.segment();
  if (std::holds_alternative<toolpath::NurbsCurve>(path_.segments[seg].geometry)) {
    return sampler_.limit_on_curve(seg, walker_.curve_u());
  }
  return sampler_.limit_on_piece(seg, walker_.piece());
}

double Job::roughness_here_um(double v_mm_per_s) const {
  const auto& k = config_.cutting;
  const double ft_mm = v_mm_per_s * 60.0 / (k.teeth * k.spindle_rpm);
  const auto r_um = [&](double alpha) {
    return 1000.0 * interpolator::roughness_mm(k.ball_radius_mm, k.pick_feed_mm, ft_mm, alpha);
  };
  if (path_.segments[walker_.segment()].rapid) return 0.0;  // a G0 does not cut
  const auto& g = path_.segments[walker_.segment()].geometry;
  if (const auto* c = std::get_if<toolpath::NurbsCurve>(&g)) {
    return r_um(
        interpolator::inclination_from_tangent_rad(c->eval(walker_.curve_u()).d1.normalized()));
  }
  const auto& line = std::get<toolpath::Polyline>(g);
  const std::size_t i = walker_.piece();
  const Vec3 dir = (line.points[i + 1] - line.points[i]).normalized();
  if (line.normals.empty()) return r_um(interpolator::inclination_from_tangent_rad(dir));
  return std::max(r_um(interpolator::inclination_from_normal_rad(line.normals[i], dir)),
                  r_um(interpolator::inclination_from_normal_rad(line.normals[i + 1], dir)));
}

}  // namespace ncd::motion
