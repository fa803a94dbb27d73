// The feed-limit curve along a whole Path, streamed as nodes (s, v_max) for the look-ahead
// planner. The algorithm is explained in limit_sampler.cpp.
#pragma once

#include <cstddef>
#include <limits>
#include <utility>
#include <vector>

#include "core/jerk_vector.hpp"
#include "feed/feed_limits.hpp"
#include "feed/roughness.hpp"
#include "geometry/path.hpp"

namespace ncd::feed {

struct LimitNode {
  double s_mm = 0.0;           // arc length from the path start
  double feed_mm_per_s = 0.0;  // v_max at the node, see the contract in limit_sampler.cpp
  FeedLimit limit = FeedLimit::MaxFeed;
  // The minimum of the limit over the interval ending at the node and over the one starting
  // there (+inf before the first and after the last); feed_mm_per_s is the smaller. Where the
  // motion comes to rest at a node, each side's planner takes its own side's value.
  double left_mm_per_s = 0.0;
  double right_mm_per_s = 0.0;
  // Under JerkBound::vector (docs/planner.md §3c): the curve of the interval that starts at the
  // node (its largest curvature and curvature turn, and its jerk budget; unlike the speed, a
  // span is exact for its interval, so it is not shared); none under JerkBound::tangential.
  JerkVectorSpan jerk_span;
  FeedLimit right_limit = FeedLimit::MaxFeed;  // the law of right_mm_per_s
  // With per-axis limits (docs/planner.md §3f): the tangential acceleration and jerk the axes
  // allow on the interval that starts at the node, as fractions of a_max and j_max (1: no
  // constraint beyond the path's).
  AxisScales axis_scale{};
};

struct SamplerConfig {
  double spacing_mm = 0.2;  // longest interval between nodes on a curve or a line
  // Skip the search for an interval's minimum where a bound on the curvature proves that the
  // limit is the segment's cap all along (the nodes are the same bit for bit, see
  // limit_sampler.cpp, "Flat intervals"), and, under per-axis jerk limits, the nine-point
  // sampling of an interval's curvature vector where a bound proves the axes' curve-jerk law
  // changes nothing; false searches and samples every interval (the reference).
  bool skip_flat_intervals = true;
};

class LimitSampler {
 public:
  // Keeps a reference to the path and the limits; computes the corner speeds at joints (one
  // per segment) and the breakpoints of every curve: the only allocations. segment_starts_mm are
  // the cumulative segment lengths (PathWalker::segment_start_mm), so that walker and sampler share
  // one arc length.
  LimitSampler(const toolpath::Path& path, std::vector<double> segment_starts_mm,
               const MachineLimits& limits, const CuttingParams& cutting,
               const SamplerConfig& config = {});

  // The next node in increasing s; false once the node at the path end has been given.
  bool next(LimitNode& out);

  // Where the motion must come to rest inside the path (arc length, increasing, each one a
  // node of the stream, 0 and the path end excluded): reversals, zero-length moves, corners
  // under G61, move ends under G61.1, a stop_before, and corners too sharp for blending
  // (corner speed below stop_below_mm_per_s()). No corner zone is applied at a stop.
  const std::vector<double>& stops_mm() const { return stops_mm_; }
  // A blended corner slower than this becomes a full stop: a_max T, the speed one period of
  // full acceleration gives (a crawl through the corner would take as long as a stop).
  double stop_below_mm_per_s() const;

  // Curve intervals streamed so far, and how many of them were flat (no search needed).
  std::size_t curve_intervals() const { return curve_intervals_; }
  std::size_t flat_intervals() const { return flat_intervals_; }
  // Curve intervals whose curve-jerk sampling (per-axis jerk) a bound showed idle.
  std::size_t axis_turn_skips() const { return axis_turn_skips_; }

  // The feed limit at a point of segment `segment` (curve parameter u, or polyline piece and
  // fraction), without corners: what a setpoint there is checked against.
  FeedLimitResult limit_on_curve(std::size_t segment, double u) const;
  FeedLimitResult limit_on_piece(std::size_t segment, std::size_t piece) const;
  // The roughness law's parameters for segment `segment`'s tool (the [cutting] ones with the
  // tool's ball radius and teeth where it states them); nullptr where the law does not cap the
  // tool (not a ball end, geometry/tool.hpp) or the segment is a rapid.
  const CuttingParams* cutting_of(std::size_t segment) const {
    return law_[segment] != 0 ? &seg_cutting_[segment] : nullptr;
  }
  // The corner speed at vertex v of a polyline segment (v = 0 and the last: the joints).
  FeedLimitResult corner_limit(std::size_t segment, std::size_t vertex) const;

 private:
  struct Interval {
    double a_mm, b_mm, v_mm_per_s;
    FeedLimit limit;
    // JerkBound::vector: the largest curvature and curvature turn on the interval, and the
    // share of the jerk budget a corner or curvature jump nearby takes (≤ kJumpJerkShare).
    double kappa_per_mm = 0.0, turn_per_mm2 = 0.0;
    double jump_share = 0.0;  // of j_max, taken by a jump within two periods' travel
    bool rest_speed = false;  // raised to the rest speed (exempt from the curve laws)
    // Per-axis limits: the largest |t_i| on the interval (a sampled curve: with a margin for
    // the tangent's turn) and whether the interval bends (its axes keep a share for the
    // centripetal part, kAxisTangentialShare).
    Vec3 tangent_max = Vec3::Ones();
    bool bends = true;
    // Per-axis jerk limits: the share of each axis's jerk a corner or curvature jump within two
    // periods' travel takes (axis_jump_shares(); the interval keeps the rest).
    Vec3 axis_jump_share = Vec3::Zero();
    // Per-axis jerk limits: the largest |k_i| of the curvature vector and |(dk/ds)_i| of its
    // derivative (curve_turn(); on a dense piece κ on every axis and κ² on every axis).
    Vec3 k_axis = Vec3::Zero(), g_axis = Vec3::Zero();
    // The fraction of its axis acceleration scale the interval asks of the planner (≥
    // kMinAxisAccelFactor; bound_axis_curve_jerk()).
    double axis_accel_factor = 1.0;
  };
  void axis_bound(Interval& iv) const;
  // d1_u0: C'(u0), as NurbsCurve::derivative gives it.
  void curve_tangent_max(const toolpath::NurbsCurve& c, double u0, double u1, const Vec3& d1_u0,
                         Interval& iv) const;
  void bound_jerk_vector(Interval& iv) const;
  void bound_axis_curve_jerk(Interval& iv) const;
  JerkVectorSpan jerk_span_of(const Interval& iv) const;
  void curve_turn(std::size_t segment, double u0, double u1, double speed_u0, Interval& iv) const;
  // The parameter range curve_turn samples for the interval [u0, u1] (within one knot span;
  // speed_u0 = |C'(u0)|).
  std::pair<double, double> turn_range(std::size_t segment, double u0, double u1,
                                       double speed_u0) const;
  // Whether bounds from the span's hodographs prove that bound_axis_curve_jerk, given what
  // curve_turn would sample, changes nothing on the interval (then curve_turn is skipped).
  bool axis_curve_jerk_holds(std::size_t segment, double u0, double u1, double speed_u0,
                             const Interval& iv) const;
  double piece_curvature_per_mm(std::size_t segment, std::size_t piece) const;
  // JerkBound::vector, dense runs: a vertex's discrete curvature vector, and its jump there.
  Vec3 vertex_curvature_vector(std::size_t segment, std::size_t vertex) const;
  double vertex_curvature_jump_per_mm(std::size_t segment, std::size_t vertex) const;
  // Per-axis jerk limits: per axis, the larger jump of the component to a neighbour.
  Vec3 vertex_axis_curvature_jump(std::size_t segment, std::size_t vertex) const;
  bool next_interval(Interval& out);
  // next_interval's steps (limit_sampler.cpp).
  struct RestEnds {  // rest refinement: the interval is the innermost at a rest
    bool innermost = false, at_start = false, at_end = false;
    double d_mm = 0.0;  // its length from (to) the rest
  };
  void next_segment();
  void piece_interval(const toolpath::Polyline& line, Interval& iv);
  void curve_interval(const toolpath::NurbsCurve& c, Interval& iv);
  double curve_step_end_u(const toolpath::NurbsCurve& c, double speed);
  double no_sliver_before_rest(const toolpath::NurbsCurve& c, double u1) const;
  double joint_zone_edge_u(const toolpath::NurbsCurve& c, double u1) const;
  double knot_guard_edge_u(double u1) const;
  void refine_towards_rest_start(const toolpath::NurbsCurve& c, double& u1, RestEnds& rest);
  void refine_near_dips(const toolpath::NurbsCurve& c, double& u1) const;
  bool refine_towards_rest_end(const toolpath::NurbsCurve& c, double& u1, RestEnds& rest);
  FeedLimitResult curve_interval_limit(double u1, double speed, bool open_end);
  bool raise_to_rest_speed(const RestEnds& rest, double u1, bool open_end,
                           FeedLimitResult& v) const;
  void enter_segment();
  FeedLimitResult interval_min_on_curve(std::size_t segment, double u0, double u1,
                                        bool open_end) const;
  bool interval_is_flat(std::size_t segment, double u0, double u1, double speed_u0) const;
  FeedLimitResult segment_cap(std::size_t segment) const;  // max feed, program feed
  // axis_curvature_jump: per axis, the jump of the curvature vector's component there (per-axis
  // jerk limits, axis_jump_feed_mm_per_s).
  FeedLimitResult corner_speed(const Vec3& d_in, const Vec3& d_out, double curvature_per_mm = 0.0,
                               double curvature_jump_per_mm = 0.0,
                               const Vec3& axis_curvature_jump = Vec3::Zero()) const;
  bool must_stop(const Vec3& d_in, const Vec3& d_out, toolpath::PathControl mode,
                 const FeedLimitResult& corner) const;
  bool vertex_is_stop(std::size_t segment, std::size_t vertex) const;
  double next_zone_edge_mm(double c0_mm, double v0, double c1_mm, double v1) const;
  void apply_zones(Interval& iv) const;
  double inner_corner_edge_u(double u1) const;
  // Rest refinement at a point where the motion rests and the curve's limit dips towards 0
  // (a repeated control point: zero parametric speed), see limit_sampler.cpp.
  bool is_rest_mm(double s_mm) const;
  double rest_speed_mm_per_s(double distance_mm) const;
  double rest_uncovered_min_mm_per_s(std::size_t segment, double u_rest, double u_far,
                                     double floor_mm_per_s, bool open_far) const;
  double rest_first_mm() const;
  bool needs_rest_refinement(std::size_t segment, double u) const;
  double u_at_arc(const toolpath::NurbsCurve& c, double u0, double u_hi, double arc_mm) const;
  static void find_dips(const toolpath::NurbsCurve& c, const std::vector<double>& bp,
                        std::vector<double>& out);
  static void refuse_cusp(const toolpath::Path& path, std::size_t k, const toolpath::NurbsCurve& c,
                          double u);
  static constexpr double kDipFirstMm = 1e-4;  // the intervals on each side of a dip's bottom

  const toolpath::Path& path_;
  std::vector<double> starts_mm_;
  MachineLimits limits_;
  CuttingParams cutting_;
  SamplerConfig config_;
  std::vector<FeedLimitResult> joint_corner_;  // at the start of each segment (index 0: none;
                                               // +inf where the motion stops)
  std::vector<double> stops_mm_;
  // Corners inside a NURBS (an interior knot where the tangent turns: full multiplicity, or
  // degree 1), with the parametric speed on each side, per segment in increasing u.
  struct InnerCorner {
    double u, s_mm, speed_in, speed_out;
    FeedLimitResult corner;
    double share = 0.0;              // JerkBound::vector: jump_share() of the corner
    Vec3 axis_share = Vec3::Zero();  // per-axis jerk limits: axis_jump_shares() of the corner
  };
  std::vector<double> joint_share_;     // jump_share() of the corner at each joint
  std::vector<Vec3> joint_axis_share_;  // axis_jump_shares() of the corner at each joint
  // The share of j_max the turn φ and curvature jump Δκ of a corner passed at v_corner take of
  // the setpoints' third difference (at most kJumpJerkShare); 0 under JerkBound::tangential.
  double jump_share(double phi_rad, double curvature_jump_per_mm, double v_corner) const;
  std::vector<std::vector<InnerCorner>> inner_corners_;
  // Where the limit jumps at a tangent joint or a smooth knot (a blend arc meets its lines):
  // the lower side's speed, so that a node at v T from it keeps the slow stretch to one period
  // (+inf: no jump, or a corner or stop handled elsewhere). Per joint, and per breakpoint of
  // each curve with the parametric speed on each side.
  std::vector<double> joint_edge_;
  struct KnotEdge {
    double v_mm_per_s, speed_in, speed_out;
  };
  std::vector<std::vector<KnotEdge>> knot_edges_;
  // Per non-rational C¹ curve of degree ≥ 2 (empty otherwise), per knot span s: the largest
  // |C''| the span can reach (the norm of its second-hodograph control points) and the largest
  // |P_i| of its control points (the scale of the rounding error of eval()).
  struct SpanBound {
    double d2_max, p_max;
  };
  std::vector<std::vector<SpanBound>> span_bounds_;
  // With per-axis limits only (80 B a knot): per axis, the largest |C'_i|, |C''_i| and
  // |C'''_i| on each span, and the largest |C'''| (0 for degree 2), from the hodographs' hulls.
  struct SpanAxisBound {
    Vec3 d1_abs, d2_abs, d3_abs;
    double d3_max;
  };
  std::vector<std::vector<SpanAxisBound>> span_axis_bounds_;
  // Per segment: the law's parameters, whether it caps the segment (1) and its value at α = 0,
  // its minimum over α (+inf where it does not cap).
  std::vector<CuttingParams> seg_cutting_;
  std::vector<unsigned char> law_;
  std::vector<double> roughness_floor_mm_per_s_;
  void set_tool_laws();
  // The constructor's steps (limit_sampler_setup.cpp).
  void add_joint(std::size_t k);
  double summed_turn_rad(std::size_t k, double corner_mm_per_s) const;
  void add_inner_knots(std::size_t k, const toolpath::NurbsCurve& c);
  void add_vertex_stops(std::size_t k, const toolpath::Polyline& line);
  void add_knot_edges(std::size_t k, const toolpath::NurbsCurve& c);
  static void bound_spans(const toolpath::NurbsCurve& c, std::vector<SpanBound>& bounds,
                          std::vector<SpanAxisBound>* axis_bounds);
  void add_joint_edges();
  // The cutting laws at curvature κ and inclination α on segment `segment` (not a rapid).
  FeedLimitResult cutting_limit(std::size_t segment, double curvature_per_mm,
                                double inclination_rad) const;
  FeedLimitResult side_limit(std::size_t segment, bool at_end) const;
  double edge_speed(std::size_t segment, std::size_t vertex) const;
  // Cursor.
  std::size_t segment_ = 0;
  std::size_t piece_ = 0;                         // polyline piece
  std::size_t sub_ = 0;                           // interval within the piece
  double piece_s_ = 0.0;                          // arc length at the start of the piece
  double u_ = 0.0;                                // curve parameter
  std::size_t knot_ = 0;                          // next breakpoint of the curve
  std::vector<std::vector<double>> breakpoints_;  // per segment (empty for polylines)
  // Per segment, the bottoms of deep dips of |C'| inside spans (near-cusps), ascending.
  std::vector<std::vector<double>> dips_;
  double s_ = 0.0;  // arc length reached
  bool started_ = false, finished_ = false;
  std::size_t curve_intervals_ = 0, flat_intervals_ = 0, axis_turn_skips_ = 0;
  double rest_origin_mm_ = -1.0;  // the rest point a geometric run of intervals leaves (< 0: none)
  bool fine_ = false;             // the limit is below the cap and changing: half the spacing
  // The last curve interval's limit (+inf: none yet in this segment).
  double last_curve_v_ = std::numeric_limits<double>::infinity();
  LimitNode pending_;  // the node whose right-hand interval is not known yet
};

}  // namespace ncd::feed
