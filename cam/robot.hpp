// Robot chamfering of a hole through a cylinder by a 6-axis robot holding a rotary bar (paper
// 002, Asakawa, Toda, Takeuchi; docs/robot.md). Pure geometry: the edge curve, the workpiece
// surface data (§3.1, §4.1), the tool attitude data and the rules for T_g (§3.2, §4.2), the
// touch-point matching (§5), and the robot's W, P, R attitude form (§6). The algorithm and
// every definition are explained once, in robot.cpp.
#pragma once

#include <string>
#include <vector>

#include "core/geometry.hpp"

namespace ncd::toolpath {

using Mat3 = Eigen::Matrix3d;

// How the geometrical tool vector T_g is chosen about the tool axis D (§4.2).
enum class TgRule {
  Paper,      // T_g = T_f turned about D by −(n−1)θ at the n-th point (the paper's method)
  MinChange,  // the turn about D that minimises the attitude change from the previous pose
  Naive,      // T_g = T_f (the paper's "simple method", Fig. 11)
};
std::string to_string(TgRule rule);

// One chamfer job in the workpiece frame: hole axis = z, cylinder axis = y, origin where they
// cross; the edge chamfered is where the hole leaves the cylinder on the +z side.
struct RobotSpec {
  double cylinder_radius_mm = 30.0;  // R, the paper's 60 mm cylinder
  double hole_radius_mm = 15.0;      // r, the paper's 30 mm hole
  int points = 72;                   // N chamfering points per loop (equal steps θ = 2π/N)
  double start_angle_rad = 0.0;      // θ of the first point, from +x towards +y
  double depth_mm = 0.1;             // depth of cut per pass along T_f (the paper: 0.1 mm)
  int passes = 1;                    // loops, each depth_mm deeper than the last
  double bar_radius_mm = 0.0;        // 0: TCP on the bar's side; > 0: TCP on the bar's axis
  TgRule rule = TgRule::Paper;
};

// Limits that make a RobotSpec valid, shared by validation and its error messages.
struct RobotLimits {
  static constexpr int kMinPoints = 8;
  static constexpr int kMaxPoints = 100000;
  static constexpr int kMaxPasses = 1000;
  // The chamfer leg (√2 × total depth) must stay below this share of the hole radius and of
  // the wall height at θ = 0: the paper's planar edge model (§3.1) is local.
  static constexpr double kMaxLegFraction = 0.1;
};

// Throws InputError naming the offending value, the limit and a way out.
void validate(const RobotSpec& spec);

// Workpiece surface data at one chamfering point (§3.1, §4.1); unit vectors unless stated.
struct SurfacePoint {
  double theta_rad = 0.0;
  Vec3 p_mm;  // P: the chamfering point on the edge
  Vec3 f;     // F: feed vector, unit tangent of the edge in the direction of travel
  Vec3 d_p;   // D_p: from P towards the hole axis, perpendicular to it (the hole wall normal)
  Vec3 n_p;   // N_p = D_p × F: normal of the flank plane A
  Vec3 d;     // D = D_p turned by +45° about F: tool axis, towards the bar's tip
  Vec3 n;     // N = N_p turned by +45° about F: normal of the chamfer, out of the material
};

// The edge and its surface data for one spec (validated on construction).
class RobotEdge {
 public:
  explicit RobotEdge(const RobotSpec& spec);  // throws InputError
  const RobotSpec& spec() const { return spec_; }
  double step_rad() const;                       // θ = 2π/N, the angular step
  double theta_rad(int n) const;                 // θ of point n (0-based), travel clockwise
  Vec3 point_mm(double theta_rad) const;         // edge curve C(θ)
  Vec3 derivative_mm(double theta_rad) const;    // dC/dθ
  SurfacePoint surface(double theta_rad) const;  // P, F, D_p, N_p, D, N at θ
  double chord_deviation_mm(double theta0_rad, double theta1_rad) const;  // sampled

 private:
  RobotSpec spec_;
};

// Tool attitude data of one pose (§3.2): where the TCP goes and how the tool is turned.
struct ToolPose {
  double theta_rad = 0.0;
  int pass = 0;           // 1-based; 0 for approach and retract
  Vec3 edge_mm;           // P on the edge
  Vec3 p_mm;              // TCP position
  Vec3 f;                 // F
  Vec3 d;                 // D, tool axis (tool frame +z)
  Vec3 tf;                // T_f = −N, pushing direction
  Vec3 tg;                // T_g ⟂ D, geometrical tool vector (tool frame +x)
  Mat3 rotation() const;  // tool frame [T_g, D × T_g, D] in the pose's frame
};

// Rotation of v about the unit axis by angle (right-handed), Rodrigues' formula.
Vec3 rotate_about(const Vec3& axis, double angle_rad, const Vec3& v);

// Turn ψ about D of T_g = cos ψ T_f + sin ψ (D × T_f) that brings the tool frame closest to
// prev (the largest trace of prevᵀ R, i.e. the smallest rotation angle).
double min_change_turn_rad(const Mat3& prev, const Vec3& d, const Vec3& tf);

// Rotation angle of aᵀ b in [0, π]: the attitude change from a to b.
double attitude_change_rad(const Mat3& a, const Mat3& b);

// Attitude changes along a sequence of poses.
struct AttitudeStats {
  double total_rad = 0.0;          // sum of the changes between consecutive poses
  double max_rad = 0.0;            // largest change between consecutive poses
  double excursion_max_rad = 0.0;  // largest change from the first pose
};
AttitudeStats attitude_stats(const std::vector<Mat3>& rotations);

// The robot's attitude form (§6, Fig. 16): W, P, R about the fixed x, y, z axes, applied in
// that order, R = Rz(r) Ry(p) Rx(w).
struct Wpr {
  double w_rad = 0.0;  // (−π, π]
  double p_rad = 0.0;  // [−π/2, π/2]
  double r_rad = 0.0;  // (−π, π]; 0 at P = ±90° (gimbal lock), where W carries the turn
};
Mat3 wpr_to_matrix(const Wpr& wpr);
Wpr matrix_to_wpr(const Mat3& rotation);

// Rigid motion x_robot = rotation x_workpiece + translation.
struct RigidTransform {
  Mat3 rotation = Mat3::Identity();
  Vec3 translation_mm = Vec3::Zero();
  Vec3 point(const Vec3& x_mm) const { return rotation * x_mm + translation_mm; }
  Vec3 vector(const Vec3& v) const { return rotation * v; }
};

// One touch: a reference point of the workpiece and where the touch sensor found it.
struct TouchPoint {
  Vec3 workpiece_mm;
  Vec3 robot_mm;
};

struct TouchLimits {
  static constexpr double kMinSeparationMm = 1.0;  // two touches closer are one point
  static constexpr double kMinSpreadMm = 1.0;      // RMS distance from the best-fit line
};

// Touch-point file: one touch per line, "x_w y_w z_w x_r y_r z_r" in mm (workpiece frame, then
// robot frame), separated by spaces, tabs or commas; '#' starts a comment; blank lines skipped.
// Numbers follow the decimal grammar of core/decimal.hpp (no hexadecimal, no "+-1"). Throws
// InputError naming `name`, the line and the word.
std::vector<TouchPoint> parse_touch_points(const std::string& text, const std::string& name);

// Matching (§5): the rigid transform that best maps the workpiece points onto the robot
// points (Kabsch: SVD of the cross-covariance; exact for exact data, least squares for more
// than three), and the residual of each touch.
struct TouchFit {
  RigidTransform transform;
  std::vector<double> residual_mm;  // |T(workpiece) − robot| per touch
  double rms_mm = 0.0;
  double max_mm = 0.0;
};
// Throws InputError for fewer than three touches, duplicates or (nearly) collinear points.
TouchFit fit_touch_points(const std::vector<TouchPoint>& touches);

// Checks of a path against the geometry, computed from the poses.
struct RobotChecks {
  double surface_residual_mm = 0.0;  // edge points off the cylinder or the hole wall
  double wall_angle_min_rad = 0.0;   // D and T_f to the hole wall (45° by construction)
  double wall_angle_max_rad = 0.0;
  // T_f to the cylinder surface, 45° − δ, signed: > 0 into the material, < 0 out of it
  double tf_cylinder_angle_min_rad = 0.0;
  double tf_cylinder_angle_max_rad = 0.0;
  double frame_error = 0.0;         // max |RᵀR − I|, |det R − 1|, |T_g · D|
  double chord_deviation_mm = 0.0;  // edge against the chords between its points, sampled
};

// The cutting poses of a job in the workpiece frame, the loop closed back on its first point
// (passes × N + 1 poses), T_g by the spec's rule, and the attitude figures of every rule.
struct RobotPath {
  RobotSpec spec;
  std::vector<ToolPose> poses;
  AttitudeStats paper, min_change, naive;
  const AttitudeStats& chosen() const;  // the figures of spec.rule
  RobotChecks checks;
};

// T_g of every pose of the sequence by one rule (T_g of the first pose is T_f).
void apply_rule(TgRule rule, double step_rad, std::vector<ToolPose>& poses);

RobotPath generate_robot_path(const RobotSpec& spec);

enum class MoveMode { Move, Cut };
std::string to_string(MoveMode mode);

struct RobotProgramOptions {
  double speed_mm_per_s = 1.0;         // chamfering speed (the paper: 1.0 mm/s)
  double move_speed_mm_per_s = 20.0;   // positioning
  double spindle_rpm = 35000.0;        // the paper's rotary bar
  double approach_distance_mm = 10.0;  // approach and retract along N from the first/last pose
};

// One move of the program: it ends at pose, at speed, in mode. Pose in the robot frame.
struct RobotMove {
  MoveMode mode = MoveMode::Cut;
  ToolPose pose;
  Wpr wpr;
  double speed_mm_per_s = 0.0;
  double attitude_change_rad = 0.0;  // from the previous move's pose
};

// Post-processing (§6): the path in the robot frame with approach and retract poses.
struct RobotProgram {
  RobotProgramOptions options;
  std::vector<RobotMove> moves;      // approach, the cut (passes × N + 1), retract
  double cut_length_mm = 0.0;        // TCP travel in Cut moves
  double move_length_mm = 0.0;       // TCP travel in Move moves after the first
  double duration_s = 0.0;           // from the approach pose to the retract pose
  double wpr_roundtrip_error = 0.0;  // max |wpr_to_matrix(matrix_to_wpr(R)) − R| over moves
};

// Throws InputError when an option is out of range.
RobotProgram make_robot_program(const RobotPath& path, const RigidTransform& transform,
                                const RobotProgramOptions& options);

}  // namespace ncd::toolpath
