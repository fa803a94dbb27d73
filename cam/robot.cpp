// Robot chamfering of a hole through a cylinder: paper 002 (Asakawa, Toda, Takeuchi) §3–§6,
// with the conventions of docs/robot.md.
//
// Frame (workpiece). The hole (cylinder B of the paper, radius r) runs along z, the base
// cylinder (A, radius R > r) along y, the origin where the axes cross. The edge a of §4.1
// (Fig. 7) where the hole leaves the cylinder on the +z side is
//
//     C(θ) = (r cos θ, r sin θ, h(θ)),   h = sqrt(R² − r² cos² θ)
//
// so that x² + y² = r² and x² + z² = R² hold identically. The paper divides the circle b (the
// hole's cross-section) equally and projects the points onto a along the hole axis (Fig. 8):
// P_n = C(θ_n), θ_n = θ_0 − n Δθ, Δθ = 2π/N. The travel is clockwise seen from +z, from
// outside the hole: it is the direction in which the paper's N_p = D_p × F is the outward
// normal of the flank plane, and then the paper's two rotations (+45° about F, −(n−1)θ about
// D) are right-handed rotations that do what §4.1 and §4.2 say they do.
//
// Workpiece surface data (§3.1, Fig. 4; §4.1, Figs. 8, 9), all unit vectors:
//
//     F   = −C'(θ)/|C'(θ)|               feed vector: the edge tangent along the travel
//     D_p = −(cos θ, sin θ, 0)           from P towards the hole axis = hole wall normal
//                                        (out of the material); D_p · F = 0 exactly
//     N_p = D_p × F                      normal of the flank plane A (Fig. 4), ⟂ the wall,
//                                        out of the material
//     D   = Rot(F, +45°) D_p = (D_p − N_p)/√2    tool axis, towards the bar's tip
//     N   = Rot(F, +45°) N_p = (D_p + N_p)/√2    chamfer normal, out of the material
//
// Seen along F (the normal plane of the edge at P):
//
//            N_p ▲      ▲ N                   the chamfer face is ⟂ N, at 45° to the wall
//     hole       │    ╱                       and to plane A; the bar's axis D lies in it,
//                │  ╱                         its side pushed along T_f = −N
//     D_p ◄──────P─────────── plane A  (≈ the cylinder surface, which is tilted down by δ)
//              ╱ │▓▓▓▓▓▓▓▓▓▓▓
//            ╱   │▓▓ material
//         D ↙    │▓▓▓▓▓▓▓▓▓▓▓
//              wall
//
// Departure 1: the paper's F_n is the chord P_n → P_{n+1}; it leans off the tangent by about
// Δθ/2 (2.5° at N = 72), so D_p would not be ⟂ F and D would not be at 45° to the wall. We use
// the tangent (the chord's limit); the robot still moves along the chords.
//
// The right-angle model and the real part. The paper chamfers a right-angle edge (Fig. 4),
// with plane B = the hole wall and plane A ⟂ the wall through the edge. The cylinder surface
// (normal n_c = (x, 0, z)/R) is not ⟂ the wall: n_c · D_p = −(r/R) cos² θ, so the wall and the
// cylinder meet at 90° − δ, δ = asin((r/R) cos² θ) (30° at θ = 0 for the paper's r/R = 1/2).
// D and T_f are exactly 45° to the wall and to plane A; to the cylinder surface T_f makes
// 45° − δ and D 45° + δ: 45° only where δ = 0 (θ = ±90°, or R → ∞). We follow the paper and
// report the range of T_f's angle to the cylinder in the checks (signed, positive into the
// material). Where r cos² θ > R sin 45° (only possible for r/R > 0.707, near θ = 0 and π) the
// wedge is sharper than 45°: the face at 45° to the wall still cuts it, but T_f then leans out
// through the cylinder surface and the angle is negative.
//
// Tool attitude data (§3.2, Fig. 5; §4.2). T_f = −N pushes the bar's side into the chamfer
// (any direction ⟂ D would cut, so the tool needs 5 degrees of freedom); T_g ⟂ D is the
// geometrical tool vector, parallel to the arm's last axis, fixed by the holder. The robot's
// sixth degree of freedom is the turn ψ of T_g about D:
//
//     T_g = Rot(D, ψ) T_f = cos ψ T_f + sin ψ (D × T_f),   tool frame R = [T_g, D × T_g, D]
//
//   naive       ψ_m = 0: T_g = T_f (Fig. 11); the wrist turns with N, a full turn per loop.
//   paper       ψ_m = −m Δθ, m = 0, 1, … over the whole sequence (the paper's −(n−1)θ at
//               P_n): T_f turns by about Δθ per point about the hole axis, and the turn about D
//               undoes it, so the attitude stays near the first one (Fig. 13). After a loop
//               ψ = −2π: the loop closes on the first attitude exactly.
//   min-change  ψ_m maximises trace(R_{m−1}ᵀ R_m) = x_{m−1}·T_g + y_{m−1}·(D × T_g) + const,
//               ψ = atan2(x·v − y·u, x·u + y·v) with u = T_f, v = D × T_f, (x, y) the previous
//               frame's first two axes: the smallest attitude change from the previous pose.
//               It is never worse than the others step by step: R_m(ψ) = R_m(0) Rz(ψ), and
//               the step of naive (paper) is reproduced by keeping the previous ψ (adding −Δθ),
//               since conjugation by Rz keeps a rotation's angle.
// All three start with T_g = T_f. The attitude change between poses is the rotation angle of
// R_prevᵀ R_next, atan2(|vee(Q − Qᵀ)|/2, (tr Q − 1)/2). For a flat plate (R → ∞) the frames
// turn rigidly by Δθ per point about the hole axis ω (ω · D = 1/√2), which gives closed forms:
// per step naive Δθ, paper 2 acos(cos²(Δθ/2) + sin²(Δθ/2)/√2), min-change
// 2 acos(sqrt(1 − sin²(Δθ/2)/2)), i.e. 360°, 275.5° and 254.5° per loop at N = 72.
//
// Position. The TCP is on the bar's side: p = P + (k d + ρ) T_f on pass k at depth of cut d
// per pass, ρ the bar radius when the TCP is taught on the bar's axis (0 on its side). In the
// right-angle model the chamfer face is then k d from the edge, its legs √2 k d, its width
// 2 k d. Passes follow each other without a retract: the last move of a loop steps in by d.
//
// Matching (§5). Touches pair a reference point of the workpiece with where the sensor found
// it in the robot frame. The rigid transform is Kabsch's: centroids, H = Σ (w − w̄)(m − m̄)ᵀ =
// U S Vᵀ, R = V diag(1, 1, sign det(V Uᵀ)) Uᵀ, t = m̄ − R w̄; exact for exact data (three
// non-collinear points fix it), least squares for more, with the residual of every touch.
//
// Post-processing (§6). Poses go to the robot frame, each attitude to W, P, R (rotations about
// the fixed x, y, z axes, R = Rz(r) Ry(p) Rx(w), Fig. 16); an approach pose and a retract pose
// approach_distance along N from the first and last poses are added, and every move carries its
// mode (moving or chamfering) and speed. W, P, R from a matrix M: r = atan2(M10, M00), then with
// Q = Rz(−r) M: p = atan2(−M20, Q00), w = atan2(−Q12, Q11); where M00 = M10 = 0 (P = ±90°,
// gimbal lock; taken as such below |(M00, M10)| = 1e-13) only w ∓ r is fixed and r = 0 is
// chosen. w is solved for the r actually used, so the round trip stays at rounding level
// (1e-13 at worst, at the lock threshold) everywhere, also at and next to the lock.
#include "cam/robot.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/decimal.hpp"
#include "core/error.hpp"
#include "core/number_text.hpp"

namespace ncd::toolpath {
namespace {

constexpr double kSqrtHalf = 0.70710678118654752440;
constexpr int kChordSamples = 32;      // samples per piece for the chordal deviation
constexpr double kGimbalLock = 1e-13;  // |(M00, M10)| below which P = ±90° is taken as exact

// Angle between the vector v and the plane of unit normal n, in [0, π/2].
double angle_to_plane_rad(const Vec3& v, const Vec3& n) {
  return std::atan2(std::abs(v.dot(n)), v.cross(n).norm());
}

// (−π, π]: atan2 may return −π for a signed zero.
double wrap_rad(double a) {
  return a <= -kPi ? a + 2.0 * kPi : a;
}

// Largest element of |a − b|.
double max_abs_diff(const Mat3& a, const Mat3& b) {
  return (a - b).cwiseAbs().maxCoeff();
}

}  // namespace

std::string to_string(TgRule rule) {
  switch (rule) {
    case TgRule::Paper:
      return "paper";
    case TgRule::MinChange:
      return "min-change";
    case TgRule::Naive:
      return "naive";
  }
  return "?";
}

std::string to_string(MoveMode mode) {
  return mode == MoveMode::Move ? "move" : "cut";
}

void validate(const RobotSpec& s) {
  require_positive("cylinder radius R (--cylinder-radius, mm)", s.cylinder_radius_mm);
  require_positive("hole radius r (--hole-radius, mm)", s.hole_radius_mm);
  require_positive("depth of cut (--depth, mm)", s.depth_mm);
  require_finite("start angle (--start-angle, deg)", s.start_angle_rad);
  if (s.hole_radius_mm >= s.cylinder_radius_mm) {
    throw InputError(
        "hole radius r = " + text::sig(s.hole_radius_mm) +
        " mm must be smaller than the cylinder radius R = " + text::sig(s.cylinder_radius_mm) +
        " mm (a hole as wide as the cylinder cuts it in two, and the edge is not a "
        "closed curve); use a smaller --hole-radius or the right --cylinder-radius");
  }
  if (s.points < RobotLimits::kMinPoints || s.points > RobotLimits::kMaxPoints) {
    throw InputError("points per loop N = " + std::to_string(s.points) + " is outside [" +
                     std::to_string(RobotLimits::kMinPoints) + ", " +
                     std::to_string(RobotLimits::kMaxPoints) + "] (--points); 72 is one per 5°");
  }
  if (s.passes < 1 || s.passes > RobotLimits::kMaxPasses) {
    throw InputError("passes = " + std::to_string(s.passes) + " is outside [1, " +
                     std::to_string(RobotLimits::kMaxPasses) + "] (--passes)");
  }
  if (!std::isfinite(s.bar_radius_mm) || s.bar_radius_mm < 0.0 ||
      s.bar_radius_mm >= s.hole_radius_mm) {
    throw InputError("bar radius = " + text::sig(s.bar_radius_mm) +
                     " mm must lie in [0, r = " + text::sig(s.hole_radius_mm) +
                     ") mm (--bar-radius; 0 when the TCP is taught on the bar's side)");
  }
  const double r = s.hole_radius_mm, big_r = s.cylinder_radius_mm;
  const double wall_mm = std::sqrt((big_r - r) * (big_r + r));  // edge height at θ = 0
  const double limit_mm = RobotLimits::kMaxLegFraction * std::min(r, wall_mm);
  const double leg_mm = std::sqrt(2.0) * s.depth_mm * s.passes;
  if (leg_mm > limit_mm) {
    throw InputError(
        "chamfer leg √2 × depth × passes = " + text::sig(leg_mm) + " mm exceeds " +
        text::sig(RobotLimits::kMaxLegFraction) + " × min(hole radius " + text::sig(r) +
        " mm, edge height at θ = 0 " + text::sig(wall_mm) + " mm) = " + text::sig(limit_mm) +
        " mm, beyond which the paper's planar edge model (§3.1) does not hold; use a smaller "
        "--depth or --chamfer-width, or fewer --passes");
  }
}

RobotEdge::RobotEdge(const RobotSpec& spec) : spec_(spec) {
  validate(spec_);
}

double RobotEdge::step_rad() const {
  return 2.0 * kPi / spec_.points;
}

double RobotEdge::theta_rad(int n) const {
  return spec_.start_angle_rad - n * step_rad();
}

Vec3 RobotEdge::point_mm(double theta) const {
  const double r = spec_.hole_radius_mm, big_r = spec_.cylinder_radius_mm;
  const double c = std::cos(theta), s = std::sin(theta);
  return {r * c, r * s, std::sqrt(big_r * big_r - r * r * c * c)};
}

Vec3 RobotEdge::derivative_mm(double theta) const {
  const double r = spec_.hole_radius_mm, big_r = spec_.cylinder_radius_mm;
  const double c = std::cos(theta), s = std::sin(theta);
  const double h = std::sqrt(big_r * big_r - r * r * c * c);
  return {-r * s, r * c, r * r * c * s / h};
}

SurfacePoint RobotEdge::surface(double theta) const {
  SurfacePoint sp;
  sp.theta_rad = theta;
  sp.p_mm = point_mm(theta);
  sp.f = -derivative_mm(theta).normalized();
  sp.d_p = Vec3(-std::cos(theta), -std::sin(theta), 0.0);
  sp.n_p = sp.d_p.cross(sp.f);
  sp.d = kSqrtHalf * (sp.d_p - sp.n_p);
  sp.n = kSqrtHalf * (sp.d_p + sp.n_p);
  return sp;
}

double RobotEdge::chord_deviation_mm(double theta0, double theta1) const {
  const Vec3 a = point_mm(theta0), b = point_mm(theta1);
  const Vec3 u = (b - a).normalized();
  double worst = 0.0;
  for (int i = 1; i < kChordSamples; ++i) {
    const Vec3 w = point_mm(theta0 + (theta1 - theta0) * i / kChordSamples) - a;
    worst = std::max(worst, (w - w.dot(u) * u).norm());
  }
  return worst;
}

Mat3 ToolPose::rotation() const {
  Mat3 m;
  m.col(0) = tg;
  m.col(1) = d.cross(tg);
  m.col(2) = d;
  return m;
}

Vec3 rotate_about(const Vec3& axis, double angle_rad, const Vec3& v) {
  const double c = std::cos(angle_rad), s = std::sin(angle_rad);
  return c * v + s * axis.cross(v) + (1.0 - c) * axis.dot(v) * axis;
}

double min_change_turn_rad(const Mat3& prev, const Vec3& d, const Vec3& tf) {
  const Vec3 u = tf, v = d.cross(tf);
  const Vec3 x = prev.col(0), y = prev.col(1);
  return std::atan2(x.dot(v) - y.dot(u), x.dot(u) + y.dot(v));
}

double attitude_change_rad(const Mat3& a, const Mat3& b) {
  const Mat3 q = a.transpose() * b;
  const Vec3 vee(q(2, 1) - q(1, 2), q(0, 2) - q(2, 0), q(1, 0) - q(0, 1));
  return std::atan2(0.5 * vee.norm(), 0.5 * (q.trace() - 1.0));
}

AttitudeStats attitude_stats(const std::vector<Mat3>& rotations) {
  AttitudeStats s;
  for (std::size_t i = 1; i < rotations.size(); ++i) {
    const double step = attitude_change_rad(rotations[i - 1], rotations[i]);
    s.total_rad += step;
    s.max_rad = std::max(s.max_rad, step);
    s.excursion_max_rad =
        std::max(s.excursion_max_rad, attitude_change_rad(rotations.front(), rotations[i]));
  }
  return s;
}

Mat3 wpr_to_matrix(const Wpr& a) {
  const double cw = std::cos(a.w_rad), sw = std::sin(a.w_rad);
  const double cp = std::cos(a.p_rad), sp = std::sin(a.p_rad);
  const double cr = std::cos(a.r_rad), sr = std::sin(a.r_rad);
  Mat3 m;
  m << cr * cp, cr * sp * sw - sr * cw, cr * sp * cw + sr * sw,  //
      sr * cp, sr * sp * sw + cr * cw, sr * sp * cw - cr * sw,   //
      -sp, cp * sw, cp * cw;
  return m;
}

Wpr matrix_to_wpr(const Mat3& m) {
  Wpr a;
  a.r_rad = std::hypot(m(0, 0), m(1, 0)) < kGimbalLock ? 0.0 : std::atan2(m(1, 0), m(0, 0));
  const double cr = std::cos(a.r_rad), sr = std::sin(a.r_rad);
  // Q = Rz(−r) M = Ry(p) Rx(w): Q00 = cos p, Q20 = −sin p, Q11 = cos w, Q12 = −sin w.
  const double q00 = cr * m(0, 0) + sr * m(1, 0);
  const double q11 = cr * m(1, 1) - sr * m(0, 1);
  const double q12 = cr * m(1, 2) - sr * m(0, 2);
  a.p_rad = std::clamp(std::atan2(-m(2, 0), q00), -0.5 * kPi, 0.5 * kPi);
  a.w_rad = wrap_rad(std::atan2(-q12, q11));
  a.r_rad = wrap_rad(a.r_rad);
  return a;
}

TouchFit fit_touch_points(const std::vector<TouchPoint>& touches) {
  const std::size_t n = touches.size();
  if (n < 3) {
    throw InputError("matching needs at least 3 touch points, got " + std::to_string(n) +
                     "; touch three or more points that are not on one line (--touch-points)");
  }
  const auto check_side = [&](const char* side, auto get) {
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t j = i + 1; j < n; ++j) {
        const double dist = (get(touches[i]) - get(touches[j])).norm();
        if (!(dist >= TouchLimits::kMinSeparationMm)) {
          throw InputError("touch points " + std::to_string(i + 1) + " and " +
                           std::to_string(j + 1) + " are " + text::sig(dist) + " mm apart in the " +
                           side + " frame, less than " + text::sig(TouchLimits::kMinSeparationMm) +
                           " mm: the same point twice; touch distinct points or remove one");
        }
      }
    }
    Vec3 mean = Vec3::Zero();
    for (const auto& t : touches) mean += get(t);
    mean /= static_cast<double>(n);
    Mat3 cov = Mat3::Zero();
    for (const auto& t : touches) cov += (get(t) - mean) * (get(t) - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Mat3> eig(cov, Eigen::EigenvaluesOnly);
    const double off_line = std::max(0.0, cov.trace() - eig.eigenvalues()(2));
    const double spread_mm = std::sqrt(off_line / static_cast<double>(n));
    if (!(spread_mm >= TouchLimits::kMinSpreadMm)) {
      throw InputError("the touch points are collinear in the " + std::string(side) +
                       " frame: their RMS distance from the best-fit line is " +
                       text::sig(spread_mm) + " mm, less than " +
                       text::sig(TouchLimits::kMinSpreadMm) +
                       " mm, so the turn about that line is not determined; touch a point off "
                       "the line");
    }
    return mean;
  };
  const Vec3 w_mean = check_side("workpiece", [](const TouchPoint& t) { return t.workpiece_mm; });
  const Vec3 m_mean = check_side("robot", [](const TouchPoint& t) { return t.robot_mm; });
  Mat3 h = Mat3::Zero();
  for (const auto& t : touches) h += (t.workpiece_mm - w_mean) * (t.robot_mm - m_mean).transpose();
  const Eigen::JacobiSVD<Mat3> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Mat3 u = svd.matrixU(), v = svd.matrixV();
  Eigen::Vector3d sign(1.0, 1.0, (v * u.transpose()).determinant() < 0.0 ? -1.0 : 1.0);
  TouchFit fit;
  fit.transform.rotation = v * sign.asDiagonal() * u.transpose();
  fit.transform.translation_mm = m_mean - fit.transform.rotation * w_mean;
  double sum_sq = 0.0;
  for (const auto& t : touches) {
    const double e = (fit.transform.point(t.workpiece_mm) - t.robot_mm).norm();
    fit.residual_mm.push_back(e);
    sum_sq += e * e;
    fit.max_mm = std::max(fit.max_mm, e);
  }
  fit.rms_mm = std::sqrt(sum_sq / static_cast<double>(n));
  return fit;
}

const AttitudeStats& RobotPath::chosen() const {
  switch (spec.rule) {
    case TgRule::Paper:
      return paper;
    case TgRule::MinChange:
      return min_change;
    case TgRule::Naive:
      return naive;
  }
  return paper;
}

void apply_rule(TgRule rule, double step_rad, std::vector<ToolPose>& poses) {
  for (std::size_t m = 0; m < poses.size(); ++m) {
    ToolPose& p = poses[m];
    double turn_rad = 0.0;
    if (m > 0 && rule == TgRule::Paper) turn_rad = -static_cast<double>(m) * step_rad;
    if (m > 0 && rule == TgRule::MinChange) {
      turn_rad = min_change_turn_rad(poses[m - 1].rotation(), p.d, p.tf);
    }
    p.tg = std::cos(turn_rad) * p.tf + std::sin(turn_rad) * p.d.cross(p.tf);
  }
}

RobotPath generate_robot_path(const RobotSpec& spec) {
  const RobotEdge edge(spec);
  RobotPath path;
  path.spec = spec;
  const int n_points = spec.points;
  const auto pose_at = [&](int n, int pass) {
    const SurfacePoint sp = edge.surface(edge.theta_rad(n));
    ToolPose p;
    p.theta_rad = sp.theta_rad;
    p.pass = pass;
    p.edge_mm = sp.p_mm;
    p.f = sp.f;
    p.d = sp.d;
    p.tf = -sp.n;
    p.p_mm = sp.p_mm + (pass * spec.depth_mm + spec.bar_radius_mm) * p.tf;
    return p;
  };
  for (int k = 1; k <= spec.passes; ++k) {
    for (int n = 0; n < n_points; ++n) path.poses.push_back(pose_at(n, k));
  }
  path.poses.push_back(pose_at(0, spec.passes));  // the loop closes on its first point

  const auto stats_of = [&](TgRule rule) {
    apply_rule(rule, edge.step_rad(), path.poses);
    std::vector<Mat3> rotations;
    rotations.reserve(path.poses.size());
    for (const auto& p : path.poses) rotations.push_back(p.rotation());
    return attitude_stats(rotations);
  };
  path.naive = stats_of(TgRule::Naive);
  path.min_change = stats_of(TgRule::MinChange);
  path.paper = stats_of(TgRule::Paper);
  apply_rule(spec.rule, edge.step_rad(), path.poses);

  RobotChecks& ck = path.checks;
  ck.wall_angle_min_rad = ck.tf_cylinder_angle_min_rad = kPi;
  const double r = spec.hole_radius_mm, big_r = spec.cylinder_radius_mm;
  for (const auto& p : path.poses) {
    const Vec3& e = p.edge_mm;
    ck.surface_residual_mm =
        std::max({ck.surface_residual_mm, std::abs(std::hypot(e.x(), e.y()) - r),
                  std::abs(std::hypot(e.x(), e.z()) - big_r)});
    const Vec3 wall = Vec3(e.x(), e.y(), 0.0).normalized();
    const Vec3 cyl = Vec3(e.x(), 0.0, e.z()).normalized();
    for (const Vec3* v : {&p.d, &p.tf}) {
      const double a = angle_to_plane_rad(*v, wall);
      ck.wall_angle_min_rad = std::min(ck.wall_angle_min_rad, a);
      ck.wall_angle_max_rad = std::max(ck.wall_angle_max_rad, a);
    }
    const double a_cyl = std::atan2(-p.tf.dot(cyl), p.tf.cross(cyl).norm());  // signed
    ck.tf_cylinder_angle_min_rad = std::min(ck.tf_cylinder_angle_min_rad, a_cyl);
    ck.tf_cylinder_angle_max_rad = std::max(ck.tf_cylinder_angle_max_rad, a_cyl);
    const Mat3 rot = p.rotation();
    ck.frame_error =
        std::max({ck.frame_error, max_abs_diff(rot.transpose() * rot, Mat3::Identity()),
                  std::abs(rot.determinant() - 1.0), std::abs(p.tg.dot(p.d))});
  }
  for (int n = 0; n < n_points; ++n) {
    ck.chord_deviation_mm = std::max(
        ck.chord_deviation_mm, edge.chord_deviation_mm(edge.theta_rad(n), edge.theta_rad(n + 1)));
  }
  return path;
}

RobotProgram make_robot_program(const RobotPath& path, const RigidTransform& transform,
                                const RobotProgramOptions& o) {
  require_positive("speed (--speed, mm/s)", o.speed_mm_per_s);
  require_positive("move speed (--move-speed, mm/s)", o.move_speed_mm_per_s);
  require_positive("spindle speed (--spindle, rpm)", o.spindle_rpm);
  require_positive("approach distance (--approach-distance, mm)", o.approach_distance_mm);
  if (path.poses.empty()) throw InputError("the robot path has no poses");
  const auto to_robot = [&](const ToolPose& w) {
    ToolPose p = w;
    p.edge_mm = transform.point(w.edge_mm);
    p.p_mm = transform.point(w.p_mm);
    p.f = transform.vector(w.f);
    p.d = transform.vector(w.d);
    p.tf = transform.vector(w.tf);
    p.tg = transform.vector(w.tg);
    return p;
  };
  const auto away = [&](ToolPose p) {  // along N = −T_f, clear of the chamfer and the wall
    p.p_mm -= o.approach_distance_mm * p.tf;
    p.pass = 0;
    return p;
  };
  RobotProgram prog;
  prog.options = o;
  const auto add = [&](MoveMode mode, const ToolPose& p, double speed) {
    RobotMove mv;
    mv.mode = mode;
    mv.pose = p;
    const Mat3 rot = p.rotation();
    mv.wpr = matrix_to_wpr(rot);
    mv.speed_mm_per_s = speed;
    prog.wpr_roundtrip_error =
        std::max(prog.wpr_roundtrip_error, max_abs_diff(wpr_to_matrix(mv.wpr), rot));
    if (!prog.moves.empty()) {
      const ToolPose& prev = prog.moves.back().pose;
      mv.attitude_change_rad = attitude_change_rad(prev.rotation(), rot);
      const double len = (p.p_mm - prev.p_mm).norm();
      (mode == MoveMode::Cut ? prog.cut_length_mm : prog.move_length_mm) += len;
      prog.duration_s += len / speed;
    }
    prog.moves.push_back(mv);
  };
  add(MoveMode::Move, away(to_robot(path.poses.front())), o.move_speed_mm_per_s);
  for (const auto& p : path.poses) add(MoveMode::Cut, to_robot(p), o.speed_mm_per_s);
  add(MoveMode::Move, away(to_robot(path.poses.back())), o.move_speed_mm_per_s);
  return prog;
}

std::vector<TouchPoint> parse_touch_points(const std::string& text, const std::string& name) {
  std::vector<TouchPoint> touches;
  std::istringstream in(text);
  std::string line;
  for (int line_no = 1; std::getline(in, line); ++line_no) {
    if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
    for (char& c : line) {
      if (c == ',') c = ' ';
    }
    const std::string where = name + ":" + std::to_string(line_no);
    std::istringstream words(line);
    std::vector<double> values;
    for (std::string word; words >> word;) {
      const DecimalResult r = parse_decimal(word);
      if (!r) {
        throw InputError(where + ": '" + word + "' " + decimal_error_text(r.error) +
                         "; a touch line reads x_w y_w z_w x_r y_r z_r in mm (workpiece frame, "
                         "then robot frame)");
      }
      values.push_back(r.value);
    }
    if (values.empty()) continue;
    if (values.size() != 6) {
      throw InputError(where + ": " + std::to_string(values.size()) +
                       " numbers where a touch line has 6: x_w y_w z_w x_r y_r z_r in mm "
                       "(workpiece frame, then robot frame)");
    }
    touches.push_back(
        {Vec3(values[0], values[1], values[2]), Vec3(values[3], values[4], values[5])});
  }
  return touches;
}

}  // namespace ncd::toolpath
