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
//
// Rotary indexes (docs/planner.md §3g): each is made where the motion rests for it (the segment
// after it has stop_before, so its start is a stop; or the path's start or end). There the job
// emits the index's periods (rotary_index.hpp: X, Y, Z at rest, the rotary axis on its double-S
// profile) before the planner's next step; the profiles are made at the start, so a period of
// an index is a closed-form evaluation.
#include "motion/job.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <string>
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
  p.min_tangential_scale =
      c.limits.jerk_bound == feed::JerkBound::vector ? feed::kTangentialScaleFloor : 1.0;
  // With per-axis limits, down to the axes' lowest share of a_max and j_max (§3f).
  if (c.limits.has_axis_limits()) {
    const feed::AxisScales floor = feed::axis_scale_floor(c.limits);
    p.min_tangential_scale = std::min({p.min_tangential_scale, floor.accel, floor.jerk});
    // Under axis jerk limits a curve may lower the acceleration scale further (§3f).
    if (c.limits.has_axis_jerk()) {
      p.min_tangential_scale =
          std::min(p.min_tangential_scale, floor.accel * feed::kMinAxisAccelFactor);
    }
  }
  return p;
}

feed::WalkerConfig walker_config(const JobConfig& c) {
  feed::WalkerConfig w;
  w.tolerance_rel = c.limits.feed_tolerance_rel;
  return w;
}

// 0, every stop, L: the stretches the planner plans from rest to rest.
std::vector<double> stretch_bounds(const feed::LimitSampler& sampler, double length_mm) {
  std::vector<double> b{0.0};
  for (const double s : sampler.stops_mm()) b.push_back(s);
  b.push_back(length_mm);
  return b;
}

std::vector<double> segment_starts(const feed::PathWalker& w, std::size_t segments) {
  std::vector<double> s;
  for (std::size_t k = 0; k <= segments; ++k) s.push_back(w.segment_start_mm(k));
  return s;
}

// The path's rotary indexes at their places on the walked path, each with its profile. Every
// place must be where the motion rests (a stretch bound): an index anywhere else would turn the
// part under a moving tool. Throws InputError where the machine has no rotary axis, or another.
std::vector<IndexAt> plan_indexes(const toolpath::Path& path, const feed::PathWalker& w,
                                  const std::vector<double>& bounds_mm,
                                  const feed::MachineLimits& l) {
  std::vector<IndexAt> out;
  if (!path.has_indexes()) return out;
  const feed::RotaryLimits& r = l.rotary;
  const auto add = [&](const toolpath::RotaryIndex& ix, double s_mm) {
    const std::string axis(1, static_cast<char>(std::toupper(ix.axis)));
    if (!r.present() || r.axis != ix.axis) {
      throw InputError(
          (path.source.empty() ? std::string() : path.source + ": ") + "line " +
          std::to_string(ix.source_line) + " turns " + axis + ", but the machine file declares " +
          (r.present() ? "the rotary axis " + std::string(1, r.axis) : "no rotary axis") +
          "; add an [axis." + std::string(1, ix.axis) + "] table to the machine file");
    }
    if (ix.from_deg == ix.to_deg) return;
    const IndexLimits lim = index_limits(r, ix.feed_deg_per_min);
    const double tol = 1e-6 * std::max(1.0, s_mm);
    const bool at_rest = std::any_of(bounds_mm.begin(), bounds_mm.end(),
                                     [&](double b) { return std::abs(b - s_mm) <= tol; });
    if (!at_rest) {
      throw std::logic_error("rotary index of line " + std::to_string(ix.source_line) + " at s = " +
                             std::to_string(s_mm) + " mm, where the motion does not rest");
    }
    out.push_back({s_mm, IndexProfile(ix.from_deg, ix.to_deg, lim), ix.source_line});
  };
  for (std::size_t k = 0; k < path.segments.size(); ++k) {
    for (const toolpath::RotaryIndex& ix : path.segments[k].indexes_before) {
      add(ix, w.segment_start_mm(k));
    }
  }
  for (const toolpath::RotaryIndex& ix : path.indexes_at_end) add(ix, w.length_mm());
  return out;
}

// Every number of the path the job will read in its periods, checked at its start: a feed
// that is not a positive finite number, a tolerance that is negative or not finite, a point
// that is not finite. (Inside the periods a bad number could only end the job in a fault.)
void validate_path(const toolpath::Path& path) {
  const auto where = [&path](std::size_t k) {
    const auto& seg = path.segments[k];
    return (path.source.empty() ? std::string() : path.source + ": ") + "segment " +
           std::to_string(k + 1) +
           (seg.source_line > 0 ? " (line " + std::to_string(seg.source_line) + ")" : "");
  };
  const auto finite = [](const Vec3& p) { return p.allFinite(); };
  for (std::size_t k = 0; k < path.segments.size(); ++k) {
    const auto& seg = path.segments[k];
    if (seg.feed_mm_per_min &&
        !(*seg.feed_mm_per_min > 0.0 && std::isfinite(*seg.feed_mm_per_min))) {
      throw InputError(where(k) + ": feed " + std::to_string(*seg.feed_mm_per_min) +
                       " mm/min is invalid: a feed must be a finite number > 0; program an F "
                       "word above 0");
    }
    for (const auto& tol : {seg.blend_tolerance_mm, seg.smoothing_tolerance_mm}) {
      if (tol && !(*tol >= 0.0 && std::isfinite(*tol))) {
        throw InputError(where(k) + ": G64 tolerance " + std::to_string(*tol) +
                         " mm is invalid: it must be finite and >= 0");
      }
    }
    bool ok = true;
    if (const auto* line = std::get_if<toolpath::Polyline>(&seg.geometry)) {
      for (const Vec3& p : line->points) ok = ok && finite(p);
    } else {
      for (const Vec3& p : std::get<toolpath::NurbsCurve>(seg.geometry).points())
        ok = ok && finite(p);
    }
    if (!ok) throw InputError(where(k) + ": a point is not a finite number");
  }
}

// The limits are checked first: blending computes with them. Dense runs under G64 Q are fitted
// first (docs/planner.md §3d); the corners left between polyline parts are then blended.
toolpath::Path blended_path(const toolpath::Path& path, const JobConfig& c, feed::FitReport* fit,
                            feed::BlendReport* report) {
  feed::validate(c.limits);
  validate_path(path);
  return feed::blend_corners(feed::fit_polylines(path, c.limits, fit), c.limits, report);
}

StepBounds step_bounds(const JobConfig& c) {
  StepBounds b;
  b.max_feed_mm_per_s = c.limits.max_feed_mm_per_min / 60.0;
  b.max_accel_mm_per_s2 = c.limits.max_accel_mm_per_s2;
  b.period_s = c.limits.period_s;
  return b;
}

// Planner steps per prepare() while the line of setpoints fills: it grows by two a period.
constexpr int kLineStepsPerPrepare = 3;

// The planner steps before a rest that fill the line to its capacity in time (docs/planner.md
// §3b): from n steps before it the line grows by (r − 1)/r of them, and the rest's decision
// waits ⌈(m + 4)/r⌉ periods more for the m + 4 setpoints after it while the head moves on; the
// longest overlap m then still has its m + 3 setpoints before the rest:
// n ≥ r/(r − 1) · (m + 4 + ⌈(m + 4)/r⌉), one more for rounding.
int line_deep_steps(int overlap_max) {
  const int r = kLineStepsPerPrepare, after = overlap_max + 4;
  return (r * (after + (after + r - 1) / r) + r - 2) / (r - 1) + 1;
}

// Per stretch between stops, the distance before its stop within which the line is deep, mm:
// n periods at the fastest the stretch may go, 200 % of the highest programmed feed of the
// segments it touches (the override's top), at most the machine's maximum feed (and that on
// rapids and segments without a feed).
std::vector<double> line_deep_within_mm(const toolpath::Path& path,
                                        const std::vector<double>& segment_start_mm,
                                        const std::vector<double>& bounds_mm,
                                        const feed::MachineLimits& l, int steps) {
  const double v_max = l.max_feed_mm_per_min / 60.0;
  std::vector<double> within(bounds_mm.size() - 1, 0.0);
  std::size_t first = 0;  // the first segment that ends at or after the stretch's start
  for (std::size_t k = 0; k + 1 < bounds_mm.size(); ++k) {
    while (first < path.segments.size() && segment_start_mm[first + 1] < bounds_mm[k]) ++first;
    double v = 0.0;
    for (std::size_t j = first; j < path.segments.size() && segment_start_mm[j] <= bounds_mm[k + 1];
         ++j) {
      const auto& seg = path.segments[j];
      const bool fed = !seg.rapid && seg.feed_mm_per_min.has_value();
      v = std::max(v, fed ? std::min(v_max, 2.0 * *seg.feed_mm_per_min / 60.0) : v_max);
    }
    within[k] = steps * v * l.period_s;
  }
  return within;
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
    case StepFault::Plan:
      return "plan";
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
    case kLimitIdOverlap:
      return "corner_overlap";
    case kLimitIdIndex:
      return "rotary_index";
    default:
      break;
  }
  if (id < feed::kFeedLimitCount) {
    return feed::to_string(static_cast<feed::FeedLimit>(id));
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
  feed::validate(config.limits);
  feed::validate(config.cutting);
  // Every limit is capped by the machine's maximum feed: size the planner for it now, so
  // that nothing allocates once the cycle runs.
  planner_.reserve_for_speed(config.limits.max_feed_mm_per_min / 60.0);
  // Sharp corners that may be passed without their stops (docs/planner.md §3b): the setpoints
  // then wait in a line long enough to hold a whole overlap and three setpoints on each side.
  if (!blend_.sharp.empty()) {
    const auto& l = config.limits;
    overlap_max_ = overlap_periods_max(l.max_accel_mm_per_s2, l.max_jerk_mm_per_s3, l.period_s);
    line_cap_ = 2 * static_cast<std::size_t>(overlap_max_) + 8;
    line_.resize(line_cap_);
    window_.resize(line_cap_);
    line_scratch_.resize(static_cast<std::size_t>(overlap_max_));
    overlap_limits_.period_s = l.period_s;
    overlap_limits_.max_feed_mm_per_s = l.max_feed_mm_per_min / 60.0;
    overlap_limits_.max_accel_mm_per_s2 = l.max_accel_mm_per_s2;
    overlap_limits_.max_jerk_vector_mm_per_s3 = l.jerk_bound == feed::JerkBound::vector
                                                    ? l.max_jerk_mm_per_s3
                                                    : std::sqrt(2.0) * l.max_jerk_mm_per_s3;
    overlap_limits_.chord_tolerance_mm = l.chord_tolerance_mm;
    for (std::size_t i = 0; i < 3; ++i) {
      overlap_limits_.axis_feed_mm_per_s[i] = l.axes[i].max_feed_mm_per_min / 60.0;
      overlap_limits_.axis_accel_mm_per_s2[i] = l.axes[i].max_accel_mm_per_s2;
      overlap_limits_.axis_jerk_mm_per_s3[i] = l.axes[i].max_jerk_mm_per_s3;
    }
    deep_within_mm_ = line_deep_within_mm(path_, segment_starts(walker_, path_.segments.size()),
                                          bounds_, l, line_deep_steps(overlap_max_));
  }
  indexes_ = plan_indexes(path_, walker_, bounds_, config.limits);
  rotary_deg_ = path_.rotary_start_deg;
  here_.sp.p = walker_.position();
  here_.sp.rotary_deg = rotary_deg_;
}

bool Job::prepare() {
  if (plan_fault_.fault != StepFault::None) return false;
  if (line_cap_ == 0) return feed_planner();
  fill_line();
  return plan_fault_.fault == StepFault::None;
}

// Records why the look-ahead cannot go on (the first reason only); the job is then over.
bool Job::plan_failed(const LimitSample& sample, PushResult why, std::uint8_t law) {
  if (plan_fault_.fault != StepFault::None) return false;
  plan_fault_.fault = StepFault::Plan;
  plan_fault_.period = emitted_;
  plan_fault_.t_s = static_cast<double>(emitted_) * config_.limits.period_s;
  plan_fault_.s_mm = bounds_[run_] + sample.s_mm;
  plan_fault_.from_mm = plan_fault_.to_mm = here_.sp.p;
  plan_fault_.value = sample.v_max_mm_per_s;
  plan_sample_ = sample;
  plan_why_ = why;
  plan_law_ = law;
  return false;
}

// Feeds the planner the nodes of the current stretch, in its own arc length (from the
// stretch's start). The node at a stop ends the stretch with the limit of the interval before
// it; the next stretch begins there, at s = 0, with the limit of the interval after it.
bool Job::feed_planner() {
  if (plan_fault_.fault != StepFault::None) return false;
  const double start = bounds_[run_], end = bounds_[run_ + 1];
  const bool last = run_ + 2 == bounds_.size();
  const double tol = 1e-9 * std::max(1.0, end);
  const auto id = [](feed::FeedLimit limit) { return static_cast<std::uint8_t>(limit); };
  // A sample to the planner; false (and the fault recorded) if it is refused.
  const auto take = [&](const LimitSample& q) {
    const PushResult r = planner_.push(q);
    return r == PushResult::Ok || plan_failed(q, r, q.limit_id);
  };
  // A node and the interval after it (the sampler's minimum there; +inf at a stretch's end).
  const auto push = [&](double s_mm, double v_mm_per_s, feed::FeedLimit limit,
                        const JerkVectorSpan& span, double v_after_mm_per_s, feed::FeedLimit after,
                        const feed::AxisScales& axis) {
    return take(
        {s_mm, v_mm_per_s, id(limit), span, v_after_mm_per_s, id(after), axis.accel, axis.jerk});
  };
  while (planner_.wants_samples()) {
    if (carry_n_ > 0) {
      if (!take(carry_[0])) return false;
      carry_[0] = carry_[1];
      --carry_n_;
      continue;
    }
    if (sampler_done_) break;
    feed::LimitNode node;
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
      if (!push(length, left, node.limit, JerkVectorSpan{}, kInf, node.limit, {})) return false;
      const double right = past ? left : node.right_mm_per_s;
      const feed::AxisScales axis = past ? last_axis_ : node.axis_scale;
      carry_[0] = {
          0.0,        right,    id(node.limit), first, past ? kInf : right, id(node.right_limit),
          axis.accel, axis.jerk};
      // (A zero limit after the stop is refused when the next stretch takes it.)
      carry_n_ = 1;
      stop_taken_early_ = node.s_mm < end;
      if (past) {  // no node fell on the stop: keep this one for the next
        carry_[1] = {
            node.s_mm - end,     node.feed_mm_per_s,   id(node.limit),        span,
            node.right_mm_per_s, id(node.right_limit), node.axis_scale.accel, node.axis_scale.jerk};
        carry_n_ = 2;
      }
      break;  // the planner has its end
    }
    if (!push(node.s_mm - start, node.feed_mm_per_s, node.limit, node.jerk_span,
              node.right_mm_per_s, node.right_limit, node.axis_scale)) {
      return false;
    }
    last_span_ = node.jerk_span;
    last_axis_ = node.axis_scale;
  }
  return true;
}

Setpoint Job::step() {
  if (plan_fault_.fault != StepFault::None) {  // the job is over: nothing more is emitted
    Setpoint sp = here_.sp;
    sp.fault = StepFault::Plan;
    return sp;
  }
  Setpoint sp = line_cap_ == 0 ? raw_step() : delayed_step();
  if (plan_fault_.fault != StepFault::None) sp.fault = StepFault::Plan;  // in this step's fill
  if (sp.fault != StepFault::None) return sp;
  // The step rule's Δs: the planned step of the motion the setpoint makes (at an overlapped
  // corner the superposed one, not the sum of both moves' progress).
  const double step_ds_mm = line_cap_ != 0 && here_.superposed_step_mm >= 0.0
                                ? here_.superposed_step_mm
                                : sp.planned_ds_mm;
  sp.fault = guard_.check(sp.t_s, sp.s_mm, step_ds_mm, sp.p);
  return sp;
}

// One period of the rotary index under way: X, Y, Z at rest where the motion stopped, the rotary
// axis on its profile; the last period lands it and ends the index.
Setpoint Job::index_step() {
  const IndexAt& ix = indexes_[next_index_];
  index_t_s_ += config_.limits.period_s;
  ++index_periods_;
  const bool landed = index_t_s_ >= ix.profile.duration_s();
  rotary_deg_ = landed ? ix.profile.to_deg() : ix.profile.position_deg(index_t_s_);
  if (landed) {
    indexing_ = false;
    ++next_index_;
  }
  rest_ = false;  // the rest before the index was the planner's; no corner to decide here
  Setpoint sp;
  sp.t_s = planner_t_s_ + static_cast<double>(index_periods_) * config_.limits.period_s;
  sp.p = walker_.position();
  sp.s_mm = last_s_mm_;
  sp.limit_id = kLimitIdIndex;
  sp.segment = walker_.segment();
  sp.rotary_deg = rotary_deg_;
  sp.indexing = !landed;
  sp.done = raw_done();
  return sp;
}

// One period of the planner and the walker, or of an index where the motion rests for one.
Setpoint Job::raw_step() {
  if (!indexing_ && at_rest_ && next_index_ < indexes_.size() &&
      indexes_[next_index_].s_mm <= last_s_mm_ + 1e-6 * std::max(1.0, last_s_mm_)) {
    indexing_ = true;
    index_t_s_ = 0.0;
  }
  if (indexing_) return index_step();
  const MotionSample m = planner_.step();
  at_rest_ = m.done;
  planner_t_s_ = m.t_s;
  const bool last = run_ + 2 == bounds_.size();
  const double s_mm = m.done ? bounds_[run_ + 1] : bounds_[run_] + m.s_mm;
  rest_ = m.done && !last;
  if (rest_) {  // at rest at a stop: the next stretch starts from here
    ++run_;
    if (!planner_.restart(bounds_[run_ + 1] - bounds_[run_])) {
      plan_failed(LimitSample{bounds_[run_ + 1] - bounds_[run_], 0.0}, PushResult::NotIncreasing,
                  0);
    }
  }
  Setpoint sp;
  sp.t_s = m.t_s + static_cast<double>(index_periods_) * config_.limits.period_s;
  sp.rotary_deg = rotary_deg_;
  sp.s_mm = s_mm;
  sp.v_mm_per_s = m.v_mm_per_s;
  sp.a_mm_per_s2 = m.a_mm_per_s2;
  sp.j_mm_per_s3 = m.j_mm_per_s3;
  sp.limit_id = m.limit_id;
  sp.feed_limit_mm_per_s = m.v_limit_mm_per_s;
  sp.planned_ds_mm = s_mm - last_s_mm_;
  last_s_mm_ = s_mm;
  const feed::WalkStep w = walker_.advance(sp.planned_ds_mm);
  sp.p = w.p;
  sp.travelled_mm = w.travelled_mm;
  sp.chord_error_mm = w.chord_error_mm;
  sp.iterations = w.iterations;
  sp.converged = w.converged;
  sp.segment = walker_.segment();
  sp.done = m.done && last && next_index_ == indexes_.size();
  return sp;
}

// The line of setpoints (docs/planner.md §3b), filled by prepare(): within deep_within_mm_ of
// the stretch's stop, or while a rest waits for its decision, the planner runs up to line_cap_
// periods ahead (kLineStepsPerPrepare steps a period at most), so that at each rest on a sharp
// corner the motion after it is known while the motion before it is still in the line; the overlap
// then replaces both ends. Elsewhere the line holds the one setpoint emitted next, and a hold or an
// override acts at once.
void Job::fill_line() {
  for (int n = 0; n < kLineStepsPerPrepare && line_n_ < line_target() && !raw_done(); ++n) {
    if (!feed_planner()) return;
    const Setpoint r = raw_step();
    line_push(r, rest_);
    // A rest with the whole window behind and ahead of it in the line is decided now.
    for (std::size_t i = 0; i < line_n_; ++i) {
      Pending& e = line_at(i);
      if (e.rest && (i + static_cast<std::size_t>(overlap_max_) + 3 < line_n_ || raw_done())) {
        e.rest = false;
        try_overlap(i);
      }
    }
  }
}

std::size_t Job::line_target() const {
  if (bounds_[run_ + 1] - last_s_mm_ <= deep_within_mm_[run_]) return line_cap_;
  for (std::size_t i = 0; i < line_n_; ++i) {  // a rest waiting for its decision
    if (line_[(line_head_ + i) % line_.size()].rest) return line_cap_;
  }
  return 1;
}

Setpoint Job::delayed_step() {
  if (line_n_ == 0) fill_line();  // prepare() was not called
  if (line_n_ == 0) {             // done: repeat the end
    here_.sp.t_s = static_cast<double>(++emitted_) * config_.limits.period_s;
    here_.sp.planned_ds_mm = 0.0;
    here_.superposed_step_mm = -1.0;
    return here_.sp;
  }
  here_ = line_at(0);
  line_head_ = (line_head_ + 1) % line_.size();
  --line_n_;
  Setpoint sp = here_.sp;
  sp.t_s = static_cast<double>(++emitted_) * config_.limits.period_s;
  sp.planned_ds_mm = sp.s_mm - emitted_s_mm_;
  emitted_s_mm_ = sp.s_mm;
  sp.done = sp.done && line_n_ == 0;
  here_.sp = sp;
  return sp;
}

void Job::line_push(const Setpoint& sp, bool rest) {
  Pending& e = line_[(line_head_ + line_n_) % line_.size()];
  e.sp = sp;
  e.piece = walker_.piece();
  e.curve_u = walker_.curve_u();
  e.rest = rest;
  e.raw = true;
  e.superposed_step_mm = -1.0;
  ++line_n_;
}

// The sharp corner the motion rests on at line entry `rest`, if any: the next ones of
// blend_.sharp in the moves around it, at its position, entered along its piece.
const feed::SharpCorner* Job::corner_at(std::size_t rest) {
  if (rest == 0) return nullptr;
  const Setpoint& at = line_at(rest).sp;
  const Vec3 in = at.p - line_at(rest - 1).sp.p;
  const std::size_t seg = at.segment;
  while (corner_next_ < blend_.sharp.size() && blend_.sharp[corner_next_].segment + 1 < seg) {
    ++corner_next_;
  }
  for (std::size_t i = corner_next_; i < blend_.sharp.size() && blend_.sharp[i].segment <= seg;
       ++i) {
    const feed::SharpCorner& c = blend_.sharp[i];
    const double scale = 1e-9 * std::max(1.0, c.vertex_mm.norm());
    if ((c.vertex_mm - at.p).norm() <= 1e-7 + scale && in.norm() > 0.0 &&
        in.normalized().dot(c.d_in) > 1.0 - 1e-6) {
      corner_next_ = i + 1;
      return &c;
    }
  }
  return nullptr;
}

// Overlaps the rest at line entry `rest` with the motion after it as far as the limits allow
// (corner_overlap.hpp), in place: the 2m entries after rest − m become m.
void Job::try_overlap(std::size_t rest) {
  const feed::SharpCorner* c = corner_at(rest);
  if (!c) return;
  // The feed limits at 100 %, raised by an override above it (the planner's limit curve then).
  const double over = std::max(1.0, planner_.override_fraction());
  for (std::size_t i = 0; i < line_n_; ++i) {
    const Pending& e = line_at(i);
    window_[i] = {e.sp.p,
                  e.sp.s_mm,
                  e.sp.v_mm_per_s,
                  e.sp.a_mm_per_s2,
                  e.sp.j_mm_per_s3,
                  e.sp.feed_limit_mm_per_s * over,
                  e.raw};
  }
  const std::span<const OverlapSample> w(window_.data(), line_n_);
  const int m = longest_overlap(*c, overlap_limits_, w, rest, overlap_max_);
  if (m == 0) return;
  const auto mu = static_cast<std::size_t>(m);
  std::array<OverlapSample, kMaxOverlapPeriods> out;
  overlap_setpoints(*c, config_.limits.period_s, w, rest, m,
                    std::span<OverlapSample>(out.data(), mu));
  for (std::size_t k = 1; k <= mu; ++k) {
    const Pending &in = line_at(rest - mu + k), &go = line_at(rest + k);
    Pending e = in;
    const OverlapSample& o = out[k - 1];
    e.sp.p = o.p_mm;
    e.sp.s_mm = o.s_mm;
    e.sp.v_mm_per_s = o.v_mm_per_s;
    e.sp.a_mm_per_s2 = o.a_mm_per_s2;
    e.sp.j_mm_per_s3 = o.j_mm_per_s3;
    e.sp.travelled_mm = in.sp.travelled_mm + go.sp.travelled_mm;
    e.sp.chord_error_mm = o.chord_error_mm;
    e.sp.iterations = std::max(in.sp.iterations, go.sp.iterations);
    e.sp.converged = in.sp.converged && go.sp.converged;
    e.sp.overlapped = true;
    e.sp.limit_id = kLimitIdOverlap;
    e.sp.feed_limit_mm_per_s = std::min(in.sp.feed_limit_mm_per_s, go.sp.feed_limit_mm_per_s);
    e.rest = false;
    e.raw = false;
    if (k == mu) {  // back on the path: the head's own setpoint, after a period of both moves
      e = Pending{go.sp, go.piece, go.curve_u, false, false};
      e.sp.travelled_mm = in.sp.travelled_mm + go.sp.travelled_mm;
      e.sp.chord_error_mm = o.chord_error_mm;
      e.sp.overlapped = true;
    }
    const double ds_in = in.sp.s_mm - line_at(rest - mu + k - 1).sp.s_mm;
    const double ds_out = go.sp.s_mm - line_at(rest + k - 1).sp.s_mm;
    e.superposed_step_mm = (ds_in * c->d_in + ds_out * c->d_out).norm();
    line_scratch_[k - 1] = e;
    overlap_.max_deviation_mm = std::max(overlap_.max_deviation_mm, corner_distance_mm(*c, o.p_mm));
  }
  // Entries rest − m + 1 … rest + m become the m new ones; the rest of the line moves up by m.
  for (std::size_t k = 0; k < mu; ++k) line_at(rest - mu + 1 + k) = line_scratch_[k];
  for (std::size_t i = rest + 1; i + mu < line_n_; ++i) line_at(i) = line_at(i + mu);
  line_n_ -= mu;
  ++overlap_.corners;
  overlap_.periods_saved += mu;
}

bool Job::set_override(double fraction) {
  if (!planner_.set_override(fraction)) return false;
  guard_.set_override(fraction);
  return true;
}

std::string Job::fault_message() const {
  if (plan_fault_.fault != StepFault::None) return plan_fault_message();
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

// The look-ahead's fault in words: a zero limit is a stop the sampler did not place (a cusp of a
// curve); anything else is a sample the planner refused, which is an internal error.
std::string Job::plan_fault_message() const {
  const double s_mm = plan_fault_.s_mm;
  const std::string where = "at s = " + std::to_string(s_mm) + " mm of " +
                            std::to_string(length_mm()) + " mm (period " +
                            std::to_string(plan_fault_.period) + ")";
  if (plan_why_ == PushResult::SpeedInvalid && !(plan_sample_.v_max_mm_per_s > 0.0)) {
    return "the path needs a full stop " + where + " (" + limit_name(plan_law_) +
           " limit is 0 there: a cusp of a curve, where its parametric speed vanishes inside "
           "it); split the curve there into two segments";
  }
  if (plan_why_ == PushResult::NotIncreasing && plan_sample_.v_max_mm_per_s == 0.0) {
    return "the planner could not start the stretch of " + std::to_string(plan_sample_.s_mm) +
           " mm " + where +
           "; the motion was stopped (an internal error; please report it with "
           "the program)";
  }
  return "the look-ahead refused a feed limit " + where + ": " +
         describe(plan_why_, plan_sample_, planner_.reserved_speed_mm_per_s()) +
         "; the motion was stopped (an internal error; please report it with the program)";
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

Job::Place Job::place() const {
  if (line_cap_ == 0) return {walker_.segment(), walker_.piece(), walker_.curve_u()};
  return {here_.sp.segment, here_.piece, here_.curve_u};
}

feed::FeedLimitResult Job::limit_here() const {
  const Place at = place();
  if (std::holds_alternative<toolpath::NurbsCurve>(path_.segments[at.segment].geometry)) {
    return sampler_.limit_on_curve(at.segment, at.curve_u);
  }
  return sampler_.limit_on_piece(at.segment, at.piece);
}

double Job::roughness_here_um(double v_mm_per_s) const {
  const Place at = place();
  // A G0 does not cut; a tool the law does not model (not a ball end) has no prediction.
  const feed::CuttingParams* cutting = sampler_.cutting_of(at.segment);
  if (cutting == nullptr) return 0.0;
  const auto& k = *cutting;
  const double ft_mm = v_mm_per_s * 60.0 / (k.teeth * k.spindle_rpm);
  const auto r_um = [&](double alpha) {
    return 1000.0 * feed::roughness_mm(k.ball_radius_mm, k.pick_feed_mm, ft_mm, alpha);
  };
  const auto& g = path_.segments[at.segment].geometry;
  if (const auto* c = std::get_if<toolpath::NurbsCurve>(&g)) {
    return r_um(feed::inclination_from_tangent_rad(c->eval(at.curve_u).d1.normalized()));
  }
  const auto& line = std::get<toolpath::Polyline>(g);
  const std::size_t i = at.piece;
  const Vec3 dir = (line.points[i + 1] - line.points[i]).normalized();
  if (line.normals.empty()) return r_um(feed::inclination_from_tangent_rad(dir));
  return std::max(r_um(feed::inclination_from_normal_rad(line.normals[i], dir)),
                  r_um(feed::inclination_from_normal_rad(line.normals[i + 1], dir)));
}

}  // namespace ncd::motion
