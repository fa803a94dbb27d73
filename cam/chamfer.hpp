// Constant-width chamfer of a drilled hole in a pipe (paper 000, Sato, Sato, Maekawa 2016), for
// any drilled hole: inclined, eccentric, in cylinder or cone pipes (docs/chamfer.md). The
// algorithm is explained once, in chamfer.cpp.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "core/geometry.hpp"
#include "core/periodic_series.hpp"

namespace ncd::toolpath {

enum class Edge { Inner, Outer };
enum class Side { Upper, Lower };
// How the edge curve is obtained: by intersecting the drill cylinder with the pipe surface
// numerically (any geometry), or by the paper's eq. (4)/(5) (its geometry only: no tilt, no
// eccentricity, a cylinder), kept as the reference the numerical curve is tested against.
enum class EdgeCurve { Numerical, ClosedForm };

std::string to_string(Edge edge);
std::string to_string(Side side);

// Everything that defines one chamfer job. Lengths in mm, angles in rad.
//
// The pipe frame: pipe axis = Y, origin O at the foot on the pipe axis of the common
// perpendicular of pipe and drill axes, Z towards the drill's entry side. The drill axis has the
// direction d = (sin τ sin φ, sin τ cos φ, cos τ) (tilt τ from Z, azimuth φ from +Y towards +X)
// and passes through e·n̂, n̂ = Y × d / |Y × d| (e = eccentricity). With τ = e = ψ = 0 this is the
// paper's set-up. The model works in the drill frame (drill axis = z), see DrillPlacement.
struct ChamferSpec {
  double pipe_radius_mm = 18.0;   // radius at O of the pipe surface carrying the edge (R or R_I)
  double drill_radius_mm = 13.0;  // r
  double ball_radius_mm = 3.0;    // R_B
  double width_mm = 0.7;          // W = |AB|
  double tolerance_mm = 0.01;     // chordal tolerance ε of the segmentation
  Edge edge = Edge::Inner;
  Side side = Side::Upper;
  std::optional<double> rod_radius_mm;        // R_od of the cutter rod
  std::optional<double> non_knife_angle_rad;  // 2β, the non-cutting cap of the ball
  bool avoid = true;                          // false: keep α = 1 and only report interference
  int initial_segments = 60;                  // N of the equal-arc-length start (eq. 29)
  double drill_tilt_rad = 0.0;                // τ, in [0, 90°)
  double drill_azimuth_rad = 0.0;             // φ: 0 tilts along the pipe (a lateral)
  double eccentricity_mm = 0.0;               // e, signed offset of the drill axis along n̂
  double pipe_half_angle_rad = 0.0;  // ψ of a cone pipe, radius growing along +Y; 0 = cylinder
  std::optional<double> pipe_thickness_mm;  // wall thickness normal to the surface; when given,
                                            // the drill must pierce the other surface too
  EdgeCurve edge_curve = EdgeCurve::Numerical;
  // The spindle's direction (from the ball up the rod) in the drill frame, for the global check
  // only (the cutter locations do not depend on it): none is +z for an upper edge and −z for a
  // lower one (the part turned over), the single hole's set-up. A part indexed on a rotary axis
  // (cam/part.hpp) gives the machine's vertical where it is not the drill axis (a lateral). With
  // it given, the checks' max/min_minus_ez are of −e along it (sign as for −e_z).
  std::optional<Vec3> tool_axis;
};

// A pipe surface (cylinder or cone) in the drill frame: the points whose distance from the axis
// line p0 + s a is ρ(s) = radius + s tan ψ > 0. f(x) = |w|² − (w·a)² − ρ(w·a)², w = x − p0, is
// the implicit form whose gradient is the normal pointing away from the axis (eq. 16).
struct PipeSurface {
  Vec3 axis_point;         // p0, the image of the pipe frame's origin O
  Vec3 axis_direction;     // a, unit, the image of +Y
  double radius_mm = 0.0;  // ρ at p0
  double slope = 0.0;      // tan ψ
  double implicit(const Vec3& x) const;
  Vec3 gradient(const Vec3& x) const;
  double axial_radius(const Vec3& x) const;  // ρ at the station of x
};

// Where the drill frame (in which the model works and the default program is written) sits in
// the pipe frame: z along the drill axis d, origin at e·n̂, y along the part of +Y normal to d,
// x = y × z = n̂. For τ = e = 0 it is the pipe frame itself.
struct DrillPlacement {
  Vec3 origin;   // drill-frame origin in pipe coordinates
  Vec3 x, y, z;  // drill-frame axes in pipe coordinates
  Vec3 to_pipe(const Vec3& p) const { return origin + p.x() * x + p.y() * y + p.z() * z; }
  Vec3 direction_to_pipe(const Vec3& v) const { return v.x() * x + v.y() * y + v.z() * z; }
  Vec3 to_drill(const Vec3& p) const;
};

DrillPlacement drill_placement(const ChamferSpec& spec);
// The pipe surface of the given radius at O (the spec's cone angle and placement), drill frame.
PipeSurface pipe_surface(const ChamferSpec& spec, double radius_mm);
// Radius at O of the other wall surface when the thickness is known (inner ↔ outer).
std::optional<double> companion_radius_mm(const ChamferSpec& spec);

// Limits that make a ChamferSpec valid, shared by validation and its error messages.
struct ChamferLimits {
  static constexpr double kMinToleranceMm = 1e-5;  // below any machine's resolution
  static constexpr double kMaxToleranceMm = 1.0;
  static constexpr int kMinInitialSegments = 4;
  static constexpr int kMaxInitialSegments = 100000;
  static constexpr std::size_t kMaxPoints = 2000000;
};

// Throws InputError naming the offending value, the limit and a way out.
void validate(const ChamferSpec& spec);

// The local geometry at θ: reference point, Frenet data and the two tangent lines of the
// normal plane T (eqs. 6–17).
struct EdgeFrame {
  double theta_rad = 0.0;
  Vec3 xp;         // x_p = C(θ)
  Vec3 t;          // unit tangent (eq. 6)
  Vec3 k;          // curvature vector κ n (eq. 10), 1/mm
  Vec3 t1;         // along the hole surface into the wall (eq. 14, signed)
  Vec3 t2;         // along the pipe surface away from the hole (eq. 15, signed)
  double c = 0.0;  // t1 · t2
};

// The cutter at θ for a given α and its feed δ (eqs. 18–26, 37).
struct CutterPose {
  double theta_rad = 0.0;
  double alpha = 1.0;
  double delta_mm = 0.0;
  Vec3 xp;                          // reference point on the edge
  Vec3 e;                           // unit vector from the ball centre to the contact point
  Vec3 cl;                          // cutter location = ball centre (eq. 19)
  Vec3 a;                           // point A on r1 (eq. 21)
  Vec3 b;                           // point B on r2 (eq. 24)
  double width_mm = 0.0;            // |AB|
  double projected_width_mm = 0.0;  // |AB| seen from +z
  double inv_ke_mm = 0.0;           // 1/|k_e| (eq. 36); +inf where k ⟂ e
  double minus_ez = 0.0;            // −e_z (global check)
  double cl_radius_mm = 0.0;        // distance of CL from the drill axis
};

// Open interval of α for which a chamfer of width W exists (e·t1 > 0 and e·t2 > 0) intersected
// with the global-interference bound (eq. 41 generalised to every edge); hi may be +inf.
struct AlphaRange {
  double lo = 0.0;
  double hi = 0.0;
};

// F(α) = |CL_xy| − R_R at one α (with its δ) and dF/dα along δ(α), where G(δ, α) = 0.
struct RodInterference {
  double value_mm = 0.0;
  double slope_mm = 0.0;  // dF/dα
};

// Outcome of Algorithm 1 at one θ.
struct RodAvoidance {
  double alpha = 1.0;
  double delta_mm = 0.0;  // δ at that α, the one the CL radius was checked with
  bool adjusted = false;  // α moved away from 1
  bool cleared = true;    // the CL radius is within the rod limit
};

// The edge curve and every per-θ quantity of the paper for one ChamferSpec.
class ChamferModel {
 public:
  explicit ChamferModel(const ChamferSpec& spec);  // validates; throws InputError

  const ChamferSpec& spec() const { return spec_; }
  Vec3 point(double theta) const;              // C(θ), eqs. (4)/(5)
  Vec3 derivative(double theta) const;         // dC/dθ
  Vec3 second_derivative(double theta) const;  // d²C/dθ²
  double speed(double theta) const;            // |dC/dθ| = ds/dθ
  EdgeFrame frame(double theta) const;         // eqs. (6)–(17)
  AlphaRange alpha_range(const EdgeFrame& f) const;
  // Solves G(δ) = 0 (eq. 27) by bracketed Newton from guess (default W/4, the paper's start);
  // nullopt when W does not fit at this α.
  std::optional<double> solve_delta(const EdgeFrame& f, double alpha,
                                    std::optional<double> guess_mm = std::nullopt) const;
  // The same root at α = 1 in closed form (docs/chamfer.md): ζ = η = W / sqrt(2 − 2c), so
  // δ = (W²/4) / (R_B + sqrt(R_B² − W²/4)) + (W/2) sqrt((1 + c)/(1 − c)); nullopt exactly where
  // solve_delta(f, 1) is.
  std::optional<double> delta_at_bisector(const EdgeFrame& f) const;
  // Largest width the wedge can take at this α (δ → 2 R_B).
  double max_width(const EdgeFrame& f, double alpha) const;
  CutterPose pose(const EdgeFrame& f, double alpha, double delta) const;
  // pose() with δ solved (in closed form at α = 1); throws InputError naming θ when no chamfer
  // of width W exists.
  CutterPose pose_at(double theta, double alpha) const;
  CutterPose pose_at(const EdgeFrame& f, double alpha) const;
  // R_R = min(r − R_B sin β, r − R_od) over the limits given; nullopt if none applies.
  std::optional<double> rod_limit_radius_mm() const;
  // |CL_xy| − R_R, of the sign of F(α) in eq. (46): > 0 means the rod (or cap) interferes.
  double rod_interference(const EdgeFrame& f, double alpha, double delta) const;
  // The same F with its derivative in α, δ following α (implicit differentiation of eq. 27).
  RodInterference rod_interference_and_slope(const EdgeFrame& f, double alpha, double delta) const;
  // Algorithm 1: the smallest α ≥ 1 that keeps the CL within R_R.
  RodAvoidance avoid_rod(const EdgeFrame& f) const;
  // The same, Newton started at alpha_hint (the neighbouring point's α) where it lies inside
  // (1, the admissible bound): one end of the bracket; F at the bound is then only evaluated
  // where the hint leaves the root's side unbounded (F(hint) > 0).
  RodAvoidance avoid_rod(const EdgeFrame& f, double alpha_hint) const;
  // Arc length of C over [theta0, theta1] by Gauss–Legendre (eq. 28).
  double arc_length(double theta0, double theta1) const;
  // The Fourier series of the speed |C'(θ)| (core/periodic_series.hpp); nullopt where its
  // coefficients do not fall to 1e-14 of the mean within 4096 samples (a nearly grazing drill).
  std::optional<PeriodicSeries> speed_series() const;
  // θ_0 = 0 < θ_1 < … < θ_N = 2π cutting C into N = initial_segments arcs of equal length
  // (eqs. 29–33): Newton on the series' antiderivative, or by quadrature where there is none.
  std::vector<double> equal_arc_starts() const;
  // The same by composite Gauss–Legendre and Newton on each piece's integral (the fallback, and
  // the reference the series is tested against).
  std::vector<double> equal_arc_starts_by_quadrature() const;
  // Reference parameters: N equal arcs refined by midpoint splits until every chordal
  // deviation is ≤ ε (eqs. 29–34). Starts at 0, excludes 2π (the loop closes on θ = 0).
  std::vector<double> segment() const;
  // frame(θ) at each θ of segment(), from the curve derivatives the segmentation evaluated.
  std::vector<EdgeFrame> segment_frames() const;
  // Largest distance between C on [theta0, theta1] and the chord joining its ends.
  double chord_deviation(double theta0, double theta1) const;
  // The same with the end points C(theta0), C(theta1) given.
  double chord_deviation(double theta0, const Vec3& p0, double theta1, const Vec3& p1) const;
  const PipeSurface& surface() const { return surface_; }
  const DrillPlacement& placement() const { return placement_; }

 private:
  struct Jet {
    Vec3 c, d1, d2;  // C, dC/dθ, d²C/dθ²
  };
  struct Knot {
    double theta = 0.0;
    Jet jet;
  };
  Jet jet(double theta) const;
  EdgeFrame frame(double theta, const Jet& j) const;
  std::vector<Knot> knots() const;  // segment() with the jets at its θ
  // Whether the piece's chordal deviation exceeds ε: chord_deviation's Newton, stopped as soon
  // as the answer is certain; `mid` receives the jet at the piece's midpoint.
  bool exceeds_tolerance(double theta0, const Jet& j0, double theta1, const Jet& j1,
                         Jet& mid) const;
  // F(α) and dF/dα as rod_interference_and_slope, with dδ/dα (the predictor of the next δ).
  struct RodTerms {
    RodInterference f;
    double delta_slope_mm = 0.0;
  };
  RodTerms rod_terms(const EdgeFrame& f, double alpha, double delta) const;
  ChamferSpec spec_;
  DrillPlacement placement_;
  PipeSurface surface_;
  double sign_z_;                       // +1 upper, −1 lower
  double sign_t1_;                      // s1 of the spec
  double sign_t2_;                      // s2 of the spec
  std::optional<double> rod_limit_mm_;  // rod_limit(), computed once
  std::optional<double> rod_limit() const;
};

// A closed θ interval, from one path point to another, where a check fails.
struct ThetaRange {
  double from_rad = 0.0;
  double to_rad = 0.0;
};

struct ChamferChecks {
  std::vector<ThetaRange> local_fail, global_fail, rod_fail;  // where each check fails
  bool local_ok = true;
  double min_inv_ke_mm = 0.0;
  bool global_ok = true;
  double max_minus_ez = 0.0;
  double min_minus_ez = 0.0;
  bool rod_applies = false;  // inner edges only: the rod passes through the hole
  bool rod_ok = true;
  std::optional<double> limit_radius_mm;
  double max_cl_radius_mm = 0.0;
  int adjusted_points = 0;
  std::vector<double> uncleared_theta_rad;  // θ where no admissible α clears the rod
};

struct ChamferPath {
  ChamferSpec spec;
  std::vector<CutterPose> points;  // closed loop; the first point is not repeated
  ChamferChecks checks;
};

// The whole pipeline: segmentation, δ, Algorithm 1, checks. Throws InputError when the
// geometry cannot be chamfered (the message names θ, the value and the limit).
ChamferPath generate_chamfer(const ChamferSpec& spec);

// Why a ball reaching down +z cannot cut this edge as computed: every failed check with its θ
// ranges and what it means; empty when all checks pass.
std::string interference_reasons(const ChamferPath& path);

}  // namespace ncd::toolpath
