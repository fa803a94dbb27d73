// One motion job: a Path walked period by period, one stretch between full stops at a time
// (see job.cpp). Each step() feeds the look-ahead planner
// from the limit sampler as far as it wants, takes one period of planned motion, and walks the
// path by the planned arc length. The same object runs against the simulated clock of replay
// and the wall clock of the service; it knows no clock itself.
#pragma once

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "feed/corner_blend.hpp"
#include "feed/limit_sampler.hpp"
#include "feed/path_walker.hpp"
#include "feed/polyline_fit.hpp"
#include "motion/corner_overlap.hpp"
#include "motion/planner.hpp"
#include "motion/rotary_index.hpp"
#include "motion/step_guard.hpp"

namespace ncd::motion {

struct JobConfig {
  feed::MachineLimits limits;
  feed::CuttingParams cutting;
  feed::SamplerConfig sampler;
  std::size_t window_capacity = 4096;  // planner look-ahead samples
};

// The setpoint of one period and what it took to make it.
struct Setpoint {
  double t_s = 0.0;
  Vec3 p = Vec3::Zero();        // position, mm
  double s_mm = 0.0;            // planned arc length from the start
  double v_mm_per_s = 0.0;      // planned feed at the end of the period
  double a_mm_per_s2 = 0.0;     // tangential acceleration at the end of the period
  double j_mm_per_s3 = 0.0;     // jerk during the period
  std::uint8_t limit_id = 0;    // feed::FeedLimit, or the planner's kLimitId*
  double planned_ds_mm = 0.0;   // s(t+T) − s(t)
  double travelled_mm = 0.0;    // true arc length walked
  double chord_error_mm = 0.0;  // path against the chord of this period
  int iterations = 0;           // walker corrections
  bool converged = true;
  bool done = false;  // at rest at the end of the path
  // The step rule (step_guard.hpp): not None, this setpoint broke it and must not be emitted;
  // the job is over (every later step repeats the fault).
  StepFault fault = StepFault::None;
  // The feed laws' limit at s, at 100 % override, whichever limit binds (the planner's limit
  // curve there, MotionSample::v_limit_mm_per_s): the feed's ceiling, mm/s.
  double feed_limit_mm_per_s = 0.0;
  std::size_t segment = 0;  // the segment of path() the setpoint belongs to
  // The period that ends here ran the end of one move and the start of the next at once, at a
  // sharp corner passed without its stop (docs/planner.md §3b): p lies within the move's G64 P
  // of the programmed corner, off path() but for the last such setpoint; s sums the two moves'
  // progress, v is the speed, a and j the larger of the two moves' own.
  bool overlapped = false;
  // The rotary index axis (docs/planner.md §3g), where the path has one: its position at the end
  // of the period, machine degrees, and whether it is turning (an index: X, Y, Z stand still at
  // p, v = 0, and the period is not at rest until the index has landed).
  double rotary_deg = 0.0;
  bool indexing = false;
};

// What passing sharp corners without their stops did (docs/planner.md §3b).
struct OverlapReport {
  std::size_t corners = 0;        // corners overlapped
  std::size_t periods_saved = 0;  // setpoints fewer than with their stops
  double max_deviation_mm = 0.0;  // farthest superposed setpoint from its corner's pieces
};

// The planner-side limit id of a period spent indexing the rotary axis (Setpoint::indexing).
inline constexpr std::uint8_t kLimitIdIndex = 0xF8;

// One rotary index of the path at the place the motion rests for it (docs/planner.md §3g).
struct IndexAt {
  double s_mm = 0.0;  // on path(): a stop, the start or the end
  IndexProfile profile;
  int source_line = 0;
};

// "roughness", …, "corner" for feed laws; "tangential_accel", "tangential_jerk", "path_end",
// "lookahead", "hold" for the planner's own.
const char* limit_name(std::uint8_t limit_id);

class Job {
 public:
  // Copies the path with its corners blended under G64 P (feed/corner_blend.hpp): the
  // setpoints' arc length s runs along that blended path. Throws InputError on bad limits.
  Job(const toolpath::Path& path, const JobConfig& config);

  // Look-ahead: feeds the planner from the limit sampler as far as it wants (the planner
  // thread's work); with a line of setpoints (delay_periods() > 0) also plans the periods that
  // fill it. Never throws: false when the look-ahead cannot go on (a zero limit inside a
  // stretch, a sample the planner refuses); the job is then over, step() returns a setpoint
  // with StepFault::Plan and fault_message() says why.
  bool prepare();
  // One period of the cycle: planner step and path walk, checked by the step rule (see
  // Setpoint::fault); call prepare() before each. Never throws, never allocates.
  Setpoint step();
  bool done() const { return raw_done() && line_n_ == 0; }
  // Where the motion comes to rest inside the path (LimitSampler::stops_mm), mm.
  const std::vector<double>& stops_mm() const { return sampler_.stops_mm(); }
  // Feed override as a fraction (0..2), for the planner and the step rule's speed bound.
  // False (nothing changes) outside 0..2: the caller checks the value at its edge.
  bool set_override(double fraction);
  // The first fault: the look-ahead's (StepFault::Plan), else the step rule's, if any.
  const StepFaultInfo& fault() const {
    return plan_fault_.fault != StepFault::None ? plan_fault_ : guard_.info();
  }
  // That fault in words (what, where, the measured and the allowed value); allocates.
  std::string fault_message() const;
  double length_mm() const { return walker_.length_mm(); }
  const JobConfig& config() const { return config_; }
  Planner& planner() { return planner_; }
  const Planner& planner() const { return planner_; }
  const feed::PathWalker& walker() const { return walker_; }
  const feed::LimitSampler& sampler() const { return sampler_; }
  // The path walked (the program's, with its blended corners) and what the blending did.
  const toolpath::Path& path() const { return path_; }
  const feed::BlendReport& blend_report() const { return blend_; }
  // The sharp corners passed without their stops so far.
  const OverlapReport& overlap_report() const { return overlap_; }
  // The most setpoints the job computes ahead of the one it emits: 0 unless a sharp corner may
  // be overlapped. Then feed override and hold act up to this many periods later, but only
  // within line_depth_within_mm() of a stop (at most: it scales with each stretch's feed);
  // elsewhere they act at once.
  std::size_t delay_periods() const { return line_cap_ == 0 ? 0 : line_cap_ - 1; }
  double line_depth_within_mm() const {
    return deep_within_mm_.empty()
               ? 0.0
               : *std::max_element(deep_within_mm_.begin(), deep_within_mm_.end());
  }
  // Setpoints computed ahead of the one emitted next, now.
  std::size_t line_depth() const { return line_n_; }
  // Where each segment of the path given to the job starts on path(), mm, and its length last
  // (segments + 1 values; a segment that the fit split starts where its first piece starts).
  std::vector<double> segment_starts_mm() const;
  // The rotary indexes in path order, each with its profile (empty without a rotary axis).
  const std::vector<IndexAt>& indexes() const { return indexes_; }
  // The rotary axis's position now (the last setpoint's), machine degrees.
  double rotary_deg() const { return rotary_deg_; }
  // What the smoothing of dense polylines under G64 Q did (feed/polyline_fit.hpp); a
  // segment with fitted runs is split, fit_report().source_segment maps path() to the program's.
  const feed::FitReport& fit_report() const { return fit_; }
  // The feed limit of the continuous laws at the current position (no corners), mm/s.
  feed::FeedLimitResult limit_here() const;
  // The roughness model's R_max at the current position for feed v (Choi, eqs. 2–3), µm;
  // on a polyline piece the worse of its two ends.
  // 0 on a rapid (G0 does not cut) and for a tool the law does not model (geometry/tool.hpp).
  double roughness_here_um(double v_mm_per_s) const;

 private:
  // One setpoint waiting to be emitted, with where the walker stood for it.
  struct Pending {
    Setpoint sp;
    std::size_t piece = 0;
    double curve_u = 0.0;
    bool rest = false;  // the planner rests here between two stretches (not yet decided)
    bool raw = true;    // the planner's own setpoint, not part of an overlap
    // A period of an overlapped corner: the length of the superposed motion's planned step,
    // |Δs_in d_in + Δs_out d_out|, which the step rule takes as its Δs (its s sums both moves'
    // progress, up to twice as much at a turn of more than 90°); < 0 elsewhere.
    double superposed_step_mm = -1.0;
  };
  bool raw_done() const {
    return planner_.done() && run_ + 2 == bounds_.size() && !indexing_ &&
           next_index_ == indexes_.size();
  }
  Setpoint index_step();  // one period of the index under way
  bool feed_planner();    // the planner's look-ahead from the sampler
  bool plan_failed(const LimitSample& sample, PushResult why, std::uint8_t law);
  std::string plan_fault_message() const;
  void fill_line();                 // planner steps into the line of setpoints, overlaps decided
  std::size_t line_target() const;  // how deep fill_line() fills the line now
  Setpoint raw_step();
  Setpoint delayed_step();
  Pending& line_at(std::size_t i) { return line_[(line_head_ + i) % line_.size()]; }
  void line_push(const Setpoint& sp, bool rest);
  void try_overlap(std::size_t rest);
  const feed::SharpCorner* corner_at(std::size_t rest);
  // Where the last emitted setpoint stands on path(): the walker's place, or the line's.
  struct Place {
    std::size_t segment, piece;
    double curve_u;
  };
  Place place() const;

  feed::BlendReport blend_;
  feed::FitReport fit_;
  toolpath::Path path_;  // the program's, dense runs fitted (G64 Q), corners blended
  JobConfig config_;
  feed::PathWalker walker_;
  feed::LimitSampler sampler_;
  std::vector<double> bounds_;  // 0, the stops, L: the planner plans one stretch at a time
  Planner planner_;
  std::size_t run_ = 0;            // the stretch [bounds_[run_], bounds_[run_ + 1]] being planned
  LimitSample carry_[2]{};         // samples of the next stretch read before it began
  bool stop_taken_early_ = false;  // the last stretch ended on a node short of its stop
  JerkVectorSpan last_span_;       // the curve span of the last node pushed (its interval)
  feed::AxisScales last_axis_{};   // the axis scales of the last node pushed
  std::size_t carry_n_ = 0;
  StepGuard guard_;
  // The look-ahead's fault (fault() == Plan): where, and the sample refused and why (a zero
  // limit: PushResult::SpeedInvalid with the law that set it in plan_law_).
  StepFaultInfo plan_fault_;
  LimitSample plan_sample_{};
  PushResult plan_why_ = PushResult::Ok;
  std::uint8_t plan_law_ = 0;
  bool sampler_done_ = false;
  double last_s_mm_ = 0.0;
  // The overlap's line of setpoints (a ring of fixed size; empty when no corner may overlap).
  std::vector<Pending> line_;
  std::vector<OverlapSample> window_;  // scratch: the line as the overlap reads it
  std::vector<Pending> line_scratch_;  // scratch: an overlap's new entries
  std::size_t line_head_ = 0, line_n_ = 0, line_cap_ = 0;
  // Per stretch: the line is filled to line_cap_ within this of the stretch's stop, mm.
  std::vector<double> deep_within_mm_;
  int overlap_max_ = 0;
  OverlapLimits overlap_limits_;
  std::size_t corner_next_ = 0;  // the first of blend_.sharp not yet passed
  std::int64_t emitted_ = 0;
  double emitted_s_mm_ = 0.0;
  bool rest_ = false;  // the last raw_step ended a stretch at rest (not the path's end)
  Pending here_;       // the last setpoint emitted
  OverlapReport overlap_;
  // Rotary indexes (docs/planner.md §3g): made at rest, one period at a time, while the planner
  // waits; its clock is behind the setpoints' by the periods spent indexing.
  std::vector<IndexAt> indexes_;
  std::size_t next_index_ = 0;
  bool indexing_ = false;
  bool at_rest_ = true;     // the last raw step left the motion at rest (or none was made)
  double index_t_s_ = 0.0;  // time into the index under way
  std::int64_t index_periods_ = 0;
  double planner_t_s_ = 0.0;  // the planner's clock at its last step
  double rotary_deg_ = 0.0;
};

}  // namespace ncd::motion
